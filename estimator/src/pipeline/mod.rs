//! The streaming estimator: configuration, initialization and the per-frame
//! pipeline (IMU prediction → de-skew → features → scan-to-map matching →
//! sliding-window smoothing → local-map update).

mod config;
mod estimate;
mod estimator;
mod initialization;
mod objects;

pub use config::{EstimatorConfig, Mode, ParseVariantError, Variant};
pub use estimate::{DeskewedSweep, FrameEstimate, ModuleTimings, ScanMatchSummary};
pub use estimator::{Estimator, EstimatorError, Footprint};
pub use objects::{ObjectEstimate, ObjectGraph, ObjectGraphConfig};
