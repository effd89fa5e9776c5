//! The LiDAR-IMU extrinsic of a bag: from an `--extrinsic` file, or composed
//! along the static transform tree of `/tf_static`.

use super::msgs::{Quaternion, TransformStamped, Vector3};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use std::collections::BTreeMap;
use std::path::Path;

/// The static transforms of a bag: each child frame's parent and
/// `T_parent_child`.
#[derive(Debug, Clone, Default)]
pub struct StaticTree {
    parents: BTreeMap<String, (String, Isometry3<f64>)>,
}

impl StaticTree {
    /// Adds `transforms` (a later transform of the same child replaces an
    /// earlier one, as tf2 does).
    pub fn add(&mut self, transforms: &[TransformStamped]) {
        for t in transforms {
            self.parents.insert(
                t.child_frame_id.clone(),
                (
                    t.header.frame_id.clone(),
                    isometry(&t.transform.translation, &t.transform.rotation),
                ),
            );
        }
    }

    /// The frames of the tree (children and parents), sorted.
    pub fn frames(&self) -> Vec<String> {
        let mut frames: Vec<String> = self
            .parents
            .iter()
            .flat_map(|(child, (parent, _))| [child.clone(), parent.clone()])
            .collect();
        frames.sort();
        frames.dedup();
        frames
    }

    /// `frame`'s root and `T_root_frame`. A cycle ends the walk where it
    /// closes (such a tree is not tf2's either).
    fn to_root(&self, frame: &str) -> (String, Option<Isometry3<f64>>) {
        let mut current = frame.to_string();
        let mut t_root_frame: Option<Isometry3<f64>> = None;
        for _ in 0..=self.parents.len() {
            let Some((parent, t_parent_current)) = self.parents.get(&current) else {
                break;
            };
            t_root_frame = Some(match t_root_frame {
                None => *t_parent_current,
                Some(t) => t_parent_current * t,
            });
            current = parent.clone();
        }
        (current, t_root_frame)
    }

    /// `T_target_source`, mapping `source` points into `target`, when both
    /// frames hang in one tree (the identity when they are the same frame).
    pub fn lookup(&self, target: &str, source: &str) -> Option<Isometry3<f64>> {
        if target == source {
            return Some(Isometry3::identity());
        }
        let (target_root, t_root_target) = self.to_root(target);
        let (source_root, t_root_source) = self.to_root(source);
        if target_root != source_root {
            return None;
        }
        Some(match (t_root_target, t_root_source) {
            (None, Some(t)) => t,
            (Some(t), None) => t.inverse(),
            (Some(a), Some(b)) => a.inverse() * b,
            (None, None) => Isometry3::identity(),
        })
    }
}

/// The isometry of a ROS translation and (normalised) quaternion.
pub fn isometry(translation: &Vector3, rotation: &Quaternion) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(translation.x, translation.y, translation.z),
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            rotation.w, rotation.x, rotation.y, rotation.z,
        )),
    )
}

/// Reads an extrinsic file: TOML with `t_lidar_imu = [x, y, z, qx, qy, qz, qw]`
/// (m; the unit quaternion of the rotation; maps IMU-frame points into the
/// LiDAR frame), the key and form of a limot dataset's `meta.toml`.
///
/// # Errors
/// An unreadable file, invalid TOML, or a key that is missing, not seven
/// finite numbers or not a unit quaternion (to 1e-6); the text names the key.
pub fn read_extrinsic_file(path: &Path) -> Result<Isometry3<f64>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let table: toml::Table = text.parse().map_err(|e: toml::de::Error| e.to_string())?;
    let key = "t_lidar_imu";
    let values = table
        .get(key)
        .and_then(|v| v.as_array())
        .ok_or_else(|| format!("no `{key} = [x, y, z, qx, qy, qz, qw]`"))?;
    let numbers: Vec<f64> = values
        .iter()
        .filter_map(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
        .filter(|v| v.is_finite())
        .collect();
    let Ok(a) = <[f64; 7]>::try_from(numbers) else {
        return Err(format!(
            "`{key}` must be seven finite numbers [x, y, z, qx, qy, qz, qw]"
        ));
    };
    let norm = (a[3] * a[3] + a[4] * a[4] + a[5] * a[5] + a[6] * a[6]).sqrt();
    if (norm - 1.0).abs() > 1e-6 {
        return Err(format!("`{key}`: the quaternion's norm is {norm}, not 1"));
    }
    Ok(limot_sim::record::pose_from_array(&a))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::rosbag::msgs::{Header, Transform};

    fn edge(parent: &str, child: &str, x: f64, yaw_rad: f64) -> TransformStamped {
        let q = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad);
        TransformStamped {
            header: Header {
                frame_id: parent.into(),
                ..Header::default()
            },
            child_frame_id: child.into(),
            transform: Transform {
                translation: Vector3 { x, y: 0.0, z: 0.0 },
                rotation: Quaternion {
                    x: q.i,
                    y: q.j,
                    z: q.k,
                    w: q.w,
                },
            },
        }
    }

    #[test]
    fn lookup_composes_through_a_common_parent() {
        let mut tree = StaticTree::default();
        tree.add(&[
            edge("base_link", "velodyne", 1.0, 0.0),
            edge("base_link", "imu_link", -0.5, std::f64::consts::FRAC_PI_2),
            edge("map", "odom", 0.0, 0.0),
        ]);
        let t_lidar_imu = tree.lookup("velodyne", "imu_link").unwrap();
        // the IMU origin sits 1.5 m behind the LiDAR
        let p = t_lidar_imu * nalgebra::Point3::origin();
        assert!((p.coords - nalgebra::Vector3::new(-1.5, 0.0, 0.0)).norm() < 1e-12);
        let back = tree.lookup("imu_link", "velodyne").unwrap();
        assert!((back * t_lidar_imu).translation.vector.norm() < 1e-12);
        assert!(tree.lookup("velodyne", "odom").is_none());
        assert_eq!(tree.lookup("x", "x"), Some(Isometry3::identity()));
        assert!(tree.frames().contains(&"imu_link".to_string()));
    }

    #[test]
    fn extrinsic_files_are_checked() {
        let dir = limot_test_support::ScratchDir::new("extrinsic");
        let good = dir.join("good.toml");
        std::fs::write(&good, "t_lidar_imu = [0.1, 0, -0.2, 0, 0, 0, 1]\n").unwrap();
        let t = read_extrinsic_file(&good).unwrap();
        assert_eq!(t.translation.vector.x, 0.1);
        let bad = dir.join("bad.toml");
        std::fs::write(&bad, "t_lidar_imu = [0, 0, 0, 0, 0, 0, 2]\n").unwrap();
        assert!(read_extrinsic_file(&bad).unwrap_err().contains("norm"));
        std::fs::write(&bad, "t_imu_lidar = [0, 0, 0, 0, 0, 0, 1]\n").unwrap();
        assert!(
            read_extrinsic_file(&bad)
                .unwrap_err()
                .contains("no `t_lidar_imu")
        );
    }
}
