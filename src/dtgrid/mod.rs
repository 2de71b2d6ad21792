//! DT-Grid (being written).
