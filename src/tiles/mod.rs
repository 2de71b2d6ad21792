//! The Sorted Tile List (being written).
