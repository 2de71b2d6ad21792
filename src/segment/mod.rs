//! Level-set image segmentation (issue 14): feature images, seeded noisy phantoms and overlap metrics (placeholder: replaced when the flows are merged).

pub mod features;
pub mod metrics;
pub mod phantom;
