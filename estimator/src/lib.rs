//! LIMOT estimator: pure estimation, no simulator, no file formats.
//!
//! Everything a source (simulator or KITTI reader) delivers is described by
//! [`input`]; the estimator never knows which source fed it. The entry point
//! is [`Estimator`], configured by [`EstimatorConfig`] (sensors: [`Mode`];
//! treatment of objects: [`Variant`]).
//!
//! Concept modules: [`input`] (what a source delivers), [`pipeline`] (the
//! streaming estimator), [`graph`] (factor graph, solver, sliding window),
//! [`object_removal`] (dropping object features from a sweep), and the
//! building blocks [`imu`], [`lidar`], [`tracking`], [`geometry`] (the angle
//! wrap and the oriented box every crate shares), [`lie`], [`eigen3`],
//! [`polygon`].

#![warn(missing_docs)]

pub mod eigen3;
pub mod geometry;
pub mod graph;
pub mod imu;
pub mod input;
pub mod lidar;
pub mod lie;
pub mod object_removal;
pub mod pipeline;
pub mod polygon;
pub mod tracking;

pub use input::{
    Detection, Extrinsics, Frame, ImuSample, InputError, LidarPoint, LidarScan, ObjectClass,
};
pub use pipeline::{
    Estimator, EstimatorConfig, EstimatorError, Footprint, FrameEstimate, Mode, ParseVariantError,
    Variant,
};
