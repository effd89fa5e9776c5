//! The streaming estimator: configuration, initialization and the per-frame
//! pipeline (IMU prediction → de-skew → features → scan-to-map matching →
//! sliding-window smoothing → local-map update).

pub mod config;
pub mod estimate;
pub mod estimator;
pub mod initialization;
pub mod objects;

pub use config::{EstimatorConfig, Mode, Variant};
pub use estimate::{FrameEstimate, ModuleTimings, ScanMatchSummary};
pub use estimator::{Estimator, EstimatorError, Footprint};
pub use objects::{ObjectEstimate, ObjectGraphConfig};
