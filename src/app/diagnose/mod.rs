//! `kinescan diagnose`: where a survey departs from its model, which catalogue effect causes
//! it, and how far the gap shrinks once that effect is added (docs/diagnosis.md).

pub mod analysis;
pub mod fit;
pub mod locate;
pub mod metrics;
pub mod model;
pub mod observe;
pub mod plots;
pub mod report;
pub mod reprocess;
pub mod select;
