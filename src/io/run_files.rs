//! The files `limot run` writes: the trajectory (TUM, KITTI poses + times),
//! the per-frame estimates, stage timings and tracks.

use crate::io::kitti::poses::{StampedPose, write_kitti_poses, write_tum};
use limot_estimator::pipeline::FrameEstimate;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

/// A file or directory of a run's outputs could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {source}")]
pub struct WriteError {
    /// The file or directory.
    pub path: PathBuf,
    /// The I/O error.
    #[source]
    pub source: std::io::Error,
}

/// Writes the files of a run of the estimator into `out_dir` (created if
/// missing): `poses_tum.txt` (LiDAR poses, for evo / `limot eval ego`),
/// `poses_kitti.txt` + `times.txt`, `estimates.csv` (velocity, biases,
/// match diagnostics), `timings.csv` (ms per stage) and `tracks.csv` (each
/// frame's tracks in the world and in that frame's LiDAR frame).
///
/// # Errors
/// A directory or file that cannot be written ([`WriteError`] names it).
///
/// # Panics
/// When `estimates` is empty (the stage names of `timings.csv` come from
/// the first estimate).
pub fn write_run_files(out_dir: &Path, estimates: &[FrameEstimate]) -> Result<(), WriteError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| WriteError { path, source }
    };
    fs::create_dir_all(out_dir).map_err(io(out_dir))?;
    let poses: Vec<StampedPose> = estimates
        .iter()
        .map(|e| StampedPose {
            t_s: e.t_s,
            pose: e.t_world_lidar,
        })
        .collect();
    let write = |name: &str, text: String| {
        let path = out_dir.join(name);
        fs::write(&path, text).map_err(io(&path))
    };
    write("poses_tum.txt", write_tum(&poses))?;
    write(
        "poses_kitti.txt",
        write_kitti_poses(&poses.iter().map(|p| p.pose).collect::<Vec<_>>()),
    )?;
    let mut times = String::new();
    for p in &poses {
        let _ = writeln!(times, "{}", p.t_s);
    }
    write("times.txt", times)?;

    let mut csv = String::from(
        "frame,t_s,x,y,z,qx,qy,qz,qw,vx,vy,vz,bax,bay,baz,bgx,bgy,bgz,removed_features,edge_features,planar_features,edge_matches,planar_matches,iterations,converged,degenerate_directions,rms_residual_m\n",
    );
    for e in estimates {
        let t = e.t_world_lidar.translation.vector;
        let q = e.t_world_lidar.rotation.quaternion();
        let v = e.velocity_world_mps;
        let (ba, bg) = (e.bias.accel_mps2, e.bias.gyro_radps);
        let _ = write!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            e.frame_index,
            e.t_s,
            t.x,
            t.y,
            t.z,
            q.i,
            q.j,
            q.k,
            q.w,
            v.x,
            v.y,
            v.z,
            ba.x,
            ba.y,
            ba.z,
            bg.x,
            bg.y,
            bg.z,
            e.removed_feature_indices.len()
        );
        match &e.scan_match {
            Some(m) => {
                let _ = writeln!(
                    csv,
                    ",{},{},{},{},{},{},{},{}",
                    m.edge_features,
                    m.planar_features,
                    m.edge_matches,
                    m.planar_matches,
                    m.iterations,
                    m.converged,
                    m.degenerate_directions,
                    m.rms_residual_m
                );
            }
            None => {
                let _ = writeln!(csv, ",,,,,,,,");
            }
        }
    }
    write("estimates.csv", csv)?;

    let mut timings = String::from("frame");
    let names = estimates[0].timings.stages().map(|(n, _)| n);
    for name in names {
        let _ = write!(timings, ",{name}_ms");
    }
    timings.push_str(",total_ms\n");
    for e in estimates {
        let _ = write!(timings, "{}", e.frame_index);
        for (_, d) in e.timings.stages() {
            let _ = write!(timings, ",{:.3}", d.as_secs_f64() * 1e3);
        }
        let _ = writeln!(timings, ",{:.3}", e.timings.total().as_secs_f64() * 1e3);
    }
    write("timings.csv", timings)?;

    // Tracks per frame: the box in the world frame and in the frame's LiDAR
    // frame (our format; KITTI tracking results need a camera calibration,
    // see `write_kitti_tracks`).
    let mut tracks = String::from(
        "frame,t_s,id,class,x,y,z,yaw_rad,l,w,h,vx,vy,vz,lifecycle,motion,predicted,\
         x_lidar,y_lidar,z_lidar,yaw_lidar_rad\n",
    );
    for e in estimates {
        for t in &e.tracks {
            let c = t.center_world;
            let v = t.velocity_world_mps;
            let lidar = crate::experiments::world_box_to_lidar(
                &t.center_world,
                &t.size_lwh,
                t.yaw_rad,
                &e.t_world_lidar,
            );
            let _ = writeln!(
                tracks,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:?},{:?},{},{},{},{},{}",
                e.frame_index,
                e.t_s,
                t.id,
                t.class,
                c.x,
                c.y,
                c.z,
                t.yaw_rad,
                t.size_lwh.x,
                t.size_lwh.y,
                t.size_lwh.z,
                v.x,
                v.y,
                v.z,
                t.lifecycle,
                t.motion,
                t.predicted,
                lidar.center.x,
                lidar.center.y,
                lidar.center.z,
                lidar.yaw_rad
            );
        }
    }
    write("tracks.csv", tracks)?;
    Ok(())
}
