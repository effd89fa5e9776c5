//! [`EstimatorError`]: why the estimator rejected input or could not
//! process a frame.

use crate::graph::{FactorError, WindowError};
use crate::imu::PreintegrationError;
use crate::input::InputError;
use crate::lidar::DeskewError;
use crate::lidar::LocalMapError;
use crate::object_removal::FilterError;
use crate::tracking::TrackerError;

/// Why the estimator rejected input or could not process a frame.
#[derive(Debug, thiserror::Error)]
pub enum EstimatorError {
    /// An IMU sample, scan or detection was rejected.
    #[error(transparent)]
    Input(#[from] InputError),
    /// The IMU data does not cover the interval between two frames.
    #[error("frame {frame_index} at t={t_s}: IMU data: {source}")]
    Imu {
        /// Index of the frame.
        frame_index: u64,
        /// Its scan start time, s.
        t_s: f64,
        /// What the preintegration found.
        #[source]
        source: PreintegrationError,
    },
    /// The sweep's motion could not be built.
    #[error("frame {frame_index} at t={t_s}: de-skew: {source}")]
    Deskew {
        /// Index of the frame.
        frame_index: u64,
        /// Its scan start time, s.
        t_s: f64,
        /// What the de-skew found.
        #[source]
        source: DeskewError,
    },
    /// The object-removal settings are invalid.
    #[error("object filter configuration: {0}")]
    FilterConfig(#[source] FilterError),
    /// `limot` was asked for without the IMU.
    #[error(
        "variant limot needs the IMU: its joint graph is the IMU sliding window (LiDAR-only runs take lio, allfilt or dynafilt)"
    )]
    LimotNeedsImu,
    /// The tracker's settings are invalid or its update failed.
    #[error("tracker: {0}")]
    Tracker(#[source] TrackerError),
    /// The local map rejected a keyframe.
    #[error("frame {frame_index} at t={t_s}: local map: {source}")]
    Map {
        /// Index of the frame.
        frame_index: u64,
        /// Its scan start time, s.
        t_s: f64,
        /// What the map found.
        #[source]
        source: LocalMapError,
    },
    /// A factor of the frame could not be built.
    #[error("frame {frame_index} at t={t_s}: cannot build a factor: {source}")]
    Factor {
        /// Index of the frame.
        frame_index: u64,
        /// Its scan start time, s.
        t_s: f64,
        /// Why.
        #[source]
        source: FactorError,
    },
    /// The sliding window could not be optimized or marginalized.
    #[error("frame {frame_index} at t={t_s}: sliding-window optimisation failed: {source}")]
    Graph {
        /// Index of the frame.
        frame_index: u64,
        /// Its scan start time, s.
        t_s: f64,
        /// Why.
        #[source]
        source: WindowError,
    },
}

/// Wraps a sliding-window error of frame `frame_index` (scan start `t_s`).
pub(super) fn graph_error(frame_index: u64, t_s: f64) -> impl Fn(WindowError) -> EstimatorError {
    move |source| EstimatorError::Graph {
        frame_index,
        t_s,
        source,
    }
}

/// Wraps a factor-construction error of frame `frame_index`.
pub(super) fn factor_error(frame_index: u64, t_s: f64) -> impl Fn(FactorError) -> EstimatorError {
    move |source| EstimatorError::Factor {
        frame_index,
        t_s,
        source,
    }
}

/// Wraps a de-skew error of frame `frame_index`.
pub(super) fn deskew_error(frame_index: u64, t_s: f64) -> impl Fn(DeskewError) -> EstimatorError {
    move |source| EstimatorError::Deskew {
        frame_index,
        t_s,
        source,
    }
}
