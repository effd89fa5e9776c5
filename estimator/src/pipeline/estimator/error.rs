//! [`EstimatorError`]: why the estimator rejected input or could not
//! process a frame.

use crate::object_removal::FilterError;
use crate::graph::{FactorError, WindowError};
use crate::imu::preintegration::PreintegrationError;
use crate::input::InputError;
use crate::lidar::deskew::DeskewError;
use crate::lidar::local_map::LocalMapError;
use crate::tracking::tracker::TrackerError;

/// Why the estimator rejected input or could not process a frame.
#[derive(Debug, thiserror::Error)]
pub enum EstimatorError {
    #[error(transparent)]
    Input(#[from] InputError),
    #[error("frame {frame_index} at t={t_s}: IMU data: {source}")]
    Imu {
        frame_index: u64,
        t_s: f64,
        #[source]
        source: PreintegrationError,
    },
    #[error("frame {frame_index} at t={t_s}: de-skew: {source}")]
    Deskew {
        frame_index: u64,
        t_s: f64,
        #[source]
        source: DeskewError,
    },
    #[error("object filter configuration: {0}")]
    FilterConfig(#[source] FilterError),
    #[error(
        "variant limot needs the IMU: its joint graph is the IMU sliding window (LiDAR-only runs take lio, allfilt or dynafilt)"
    )]
    LimotNeedsImu,
    #[error("tracker: {0}")]
    Tracker(#[source] TrackerError),
    #[error("frame {frame_index} at t={t_s}: local map: {source}")]
    Map {
        frame_index: u64,
        t_s: f64,
        #[source]
        source: LocalMapError,
    },
    #[error("frame {frame_index} at t={t_s}: cannot build a factor: {source}")]
    Factor {
        frame_index: u64,
        t_s: f64,
        #[source]
        source: FactorError,
    },
    #[error("frame {frame_index} at t={t_s}: sliding-window optimisation failed: {source}")]
    Graph {
        frame_index: u64,
        t_s: f64,
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
