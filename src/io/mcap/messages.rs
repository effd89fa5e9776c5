//! limot values as Foxglove well-known messages: poses, transforms, the
//! point cloud, boxes as scene entities and paths. Pure conversions, no I/O.

use foxglove::schemas::packed_element_field::NumericType;
use foxglove::schemas::scene_entity_deletion::Type as DeletionType;
use foxglove::schemas::{
    ArrowPrimitive, Color, CubePrimitive, FrameTransform, KeyValuePair, PackedElementField,
    PointCloud, Pose, PosesInFrame, Quaternion, SceneEntity, SceneEntityDeletion, SceneUpdate,
    TextPrimitive, Timestamp, Vector3,
};
use limot_estimator::geometry::OrientedBox;
use limot_estimator::tracking::{Lifecycle, Motion, TrackOutput};
use nalgebra::{Isometry3, UnitQuaternion};

/// Bytes per point of `point_cloud`: `x`, `y`, `z` as f32 (LiDAR frame, m)
/// and the `removed` flag as u8.
pub const POINT_STRIDE_BYTES: usize = 13;

/// Value of the `removed` field for a feature point the variant's filter
/// dropped as an object point; every other point has 0.
pub const REMOVED: u8 = 1;

/// Shortest velocity arrow drawn, m/s: slower tracks get none.
const MIN_ARROW_SPEED_MPS: f64 = 0.2;

/// A time of the data, in nanoseconds since the clock's zero, as a Foxglove
/// timestamp.
pub fn timestamp(t_ns: u64) -> Timestamp {
    // `t_ns` comes from `time_ns`, which keeps the seconds within u32
    Timestamp::new((t_ns / 1_000_000_000) as u32, (t_ns % 1_000_000_000) as u32)
}

/// `t_s` (seconds of the data's clock) in nanoseconds, or `None` when it is
/// not finite, negative, or past what a Foxglove timestamp holds (u32
/// seconds, year 2106).
pub fn time_ns(t_s: f64) -> Option<u64> {
    (t_s.is_finite() && t_s >= 0.0 && t_s < u32::MAX as f64).then(|| (t_s * 1e9).round() as u64)
}

/// The pose `t_frame_child` (child origin and axes in `frame`) as a Foxglove pose.
pub fn pose(t_frame_child: &Isometry3<f64>) -> Pose {
    let t = t_frame_child.translation.vector;
    let q = t_frame_child.rotation.quaternion();
    Pose {
        position: Some(Vector3 {
            x: t.x,
            y: t.y,
            z: t.z,
        }),
        orientation: Some(Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

/// The pose of an upright box's centre: x along its heading, z up.
pub fn box_pose(b: &OrientedBox) -> Pose {
    pose(&Isometry3::from_parts(
        b.center.into(),
        UnitQuaternion::from_axis_angle(&nalgebra::Vector3::z_axis(), b.yaw_rad),
    ))
}

/// The transform that places `child` in `parent` at `t_ns`: `t_parent_child`
/// maps child-frame points into the parent frame.
pub fn transform(
    t_ns: u64,
    parent: &str,
    child: &str,
    t_parent_child: &Isometry3<f64>,
) -> FrameTransform {
    let p = pose(t_parent_child);
    FrameTransform {
        timestamp: Some(timestamp(t_ns)),
        parent_frame_id: parent.to_string(),
        child_frame_id: child.to_string(),
        translation: p.position,
        rotation: p.orientation,
    }
}

/// One sweep's points (`points`, in `frame_id`, m) as a point cloud of
/// [`POINT_STRIDE_BYTES`] per point, little-endian: `x`, `y`, `z` (f32) and
/// `removed` (u8, [`REMOVED`] for the indices in `removed_indices`, 0
/// otherwise; indices past the points are ignored).
///
/// With `max_points`, a sweep of more points is thinned to every k-th point
/// in storage order (the smallest k that keeps at most `max_points`), and
/// every removed point is kept besides: what the filter dropped is what the
/// recording is looked at for.
pub fn point_cloud(
    t_ns: u64,
    frame_id: &str,
    points: &[nalgebra::Vector3<f64>],
    removed_indices: &[u32],
    max_points: Option<usize>,
) -> PointCloud {
    let mut removed = vec![false; points.len()];
    for &i in removed_indices {
        if let Some(flag) = removed.get_mut(i as usize) {
            *flag = true;
        }
    }
    let stride = max_points.map_or(1, |max| points.len().div_ceil(max.max(1)).max(1));
    let mut data =
        Vec::with_capacity((points.len() / stride + removed_indices.len()) * POINT_STRIDE_BYTES);
    for (i, (p, &is_removed)) in points.iter().zip(&removed).enumerate() {
        if is_removed || i % stride == 0 {
            data.extend_from_slice(&(p.x as f32).to_le_bytes());
            data.extend_from_slice(&(p.y as f32).to_le_bytes());
            data.extend_from_slice(&(p.z as f32).to_le_bytes());
            data.push(if is_removed { REMOVED } else { 0 });
        }
    }
    let field = |name: &str, offset: u32, kind: NumericType| PackedElementField {
        name: name.to_string(),
        offset,
        r#type: kind as i32,
    };
    PointCloud {
        timestamp: Some(timestamp(t_ns)),
        frame_id: frame_id.to_string(),
        pose: Some(pose(&Isometry3::identity())),
        point_stride: POINT_STRIDE_BYTES as u32,
        fields: vec![
            field("x", 0, NumericType::Float32),
            field("y", 4, NumericType::Float32),
            field("z", 8, NumericType::Float32),
            field("removed", 12, NumericType::Uint8),
        ],
        data: data.into(),
    }
}

/// A path: `poses_frame` (`t_frame_lidar` of successive instants) in `frame_id`.
pub fn poses_path(t_ns: u64, frame_id: &str, poses_frame: &[Isometry3<f64>]) -> PosesInFrame {
    PosesInFrame {
        timestamp: Some(timestamp(t_ns)),
        frame_id: frame_id.to_string(),
        poses: poses_frame.iter().map(pose).collect(),
    }
}

/// A scene update that replaces everything its topic showed before with `entities`.
pub fn replace_scene(t_ns: u64, entities: Vec<SceneEntity>) -> SceneUpdate {
    SceneUpdate {
        deletions: vec![SceneEntityDeletion {
            timestamp: Some(timestamp(t_ns)),
            r#type: DeletionType::All as i32,
            id: String::new(),
        }],
        entities,
    }
}

/// How a box entity looks and what it says.
pub struct BoxStyle {
    /// Entity id, unique on its topic within one update.
    pub id: String,
    /// Fill colour (RGBA, 0..1).
    pub color: Color,
    /// Label drawn above the box.
    pub label: String,
    /// Key/value pairs Foxglove shows for the entity.
    pub metadata: Vec<(&'static str, String)>,
}

/// An RGBA colour.
pub fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

/// An upright box in `frame_id` as a scene entity: the cube, its label
/// above it and, with `velocity_frame_mps` (same frame) at least
/// [`MIN_ARROW_SPEED_MPS`], an arrow from the box centre along the velocity
/// as long as one second of motion.
pub fn box_entity(
    t_ns: u64,
    frame_id: &str,
    b: &OrientedBox,
    velocity_frame_mps: Option<nalgebra::Vector3<f64>>,
    style: BoxStyle,
) -> SceneEntity {
    let size = Vector3 {
        x: b.size_lwh.x,
        y: b.size_lwh.y,
        z: b.size_lwh.z,
    };
    let above = b.center + nalgebra::Vector3::new(0.0, 0.0, 0.5 * b.size_lwh.z + 0.4);
    let text = TextPrimitive {
        pose: Some(pose(&Isometry3::translation(above.x, above.y, above.z))),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: Some(rgba(1.0, 1.0, 1.0, 1.0)),
        text: style.label,
    };
    let arrows = velocity_frame_mps
        .filter(|v| v.norm() >= MIN_ARROW_SPEED_MPS)
        .map(|v| {
            let direction = UnitQuaternion::rotation_between(&nalgebra::Vector3::x(), &v)
                // exactly backwards along x: turn about z
                .unwrap_or_else(|| {
                    UnitQuaternion::from_axis_angle(
                        &nalgebra::Vector3::z_axis(),
                        std::f64::consts::PI,
                    )
                });
            let length_m = v.norm();
            let head_m = length_m.min(0.5);
            ArrowPrimitive {
                pose: Some(pose(&Isometry3::from_parts(b.center.into(), direction))),
                shaft_length: length_m - head_m,
                shaft_diameter: 0.1,
                head_length: head_m,
                head_diameter: 0.3,
                color: Some(rgba(1.0, 1.0, 0.2, 1.0)),
            }
        })
        .into_iter()
        .collect();
    SceneEntity {
        timestamp: Some(timestamp(t_ns)),
        frame_id: frame_id.to_string(),
        id: style.id,
        lifetime: None,
        frame_locked: false,
        metadata: style
            .metadata
            .into_iter()
            .map(|(key, value)| KeyValuePair {
                key: key.to_string(),
                value,
            })
            .collect(),
        arrows,
        cubes: vec![CubePrimitive {
            pose: Some(box_pose(b)),
            size: Some(size),
            color: Some(style.color),
        }],
        texts: vec![text],
        ..SceneEntity::default()
    }
}

/// `static` or `dynamic`.
pub fn motion_name(motion: Motion) -> &'static str {
    match motion {
        Motion::Static => "static",
        Motion::Dynamic => "dynamic",
    }
}

/// A track (world frame) as a box entity: orange when dynamic, blue when
/// static, fainter while tentative; labelled `id class motion speed`.
pub fn track_entity(t_ns: u64, frame_id: &str, track: &TrackOutput) -> SceneEntity {
    let alpha = match track.lifecycle {
        Lifecycle::Confirmed => 0.5,
        Lifecycle::Tentative => 0.2,
    };
    let color = match track.motion {
        Motion::Dynamic => rgba(1.0, 0.5, 0.0, alpha),
        Motion::Static => rgba(0.2, 0.5, 1.0, alpha),
    };
    let b = OrientedBox::new(track.center_world, track.size_lwh, track.yaw_rad);
    let motion = motion_name(track.motion);
    box_entity(
        t_ns,
        frame_id,
        &b,
        Some(track.velocity_world_mps),
        BoxStyle {
            id: format!("track {}", track.id),
            color,
            label: format!(
                "{} {} {motion} {:.1} m/s",
                track.id, track.class, track.speed_mps
            ),
            metadata: vec![
                ("id", track.id.to_string()),
                ("class", track.class.to_string()),
                ("motion", motion.to_string()),
                ("lifecycle", format!("{:?}", track.lifecycle).to_lowercase()),
                ("speed_mps", format!("{:.3}", track.speed_mps)),
                ("predicted", track.predicted.to_string()),
            ],
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3 as V3;

    #[test]
    fn times_become_nanoseconds_and_bad_times_none() {
        assert_eq!(time_ns(0.0), Some(0));
        assert_eq!(time_ns(12.3456789011), Some(12_345_678_901));
        assert_eq!(time_ns(-0.1), None);
        assert_eq!(time_ns(f64::NAN), None);
        assert_eq!(time_ns(5.0e9), None);
        let t = timestamp(12_345_678_901);
        assert_eq!((t.sec(), t.nsec()), (12, 345_678_901));
    }

    #[test]
    fn cloud_packs_points_and_flags_the_removed_ones() {
        let points = [
            V3::new(1.0, -2.0, 0.5),
            V3::new(3.0, 4.0, -1.0),
            V3::zeros(),
        ];
        let cloud = point_cloud(7, "lidar", &points, &[1, 99], None);
        assert_eq!(cloud.point_stride as usize, POINT_STRIDE_BYTES);
        assert_eq!(cloud.data.len(), 3 * POINT_STRIDE_BYTES);
        let f32_at =
            |offset: usize| f32::from_le_bytes(cloud.data[offset..offset + 4].try_into().unwrap());
        let point = |i: usize| {
            let o = i * POINT_STRIDE_BYTES;
            (f32_at(o), f32_at(o + 4), f32_at(o + 8), cloud.data[o + 12])
        };
        assert_eq!(point(0), (1.0, -2.0, 0.5, 0));
        assert_eq!(point(1), (3.0, 4.0, -1.0, REMOVED));
        assert_eq!(point(2), (0.0, 0.0, 0.0, 0));
        let names: Vec<_> = cloud.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["x", "y", "z", "removed"]);
        assert_eq!(cloud.fields[3].r#type, NumericType::Uint8 as i32);
    }

    #[test]
    fn a_thinned_cloud_keeps_every_kth_point_and_every_removed_one() {
        let points: Vec<_> = (0..10).map(|i| V3::new(i as f64, 0.0, 0.0)).collect();
        // 10 points, at most 4: every 3rd (0, 3, 6, 9), and removed 4 and 7
        let cloud = point_cloud(0, "lidar", &points, &[4, 7, 99], Some(4));
        let kept: Vec<(f32, u8)> = cloud
            .data
            .chunks_exact(POINT_STRIDE_BYTES)
            .map(|c| (f32::from_le_bytes(c[0..4].try_into().unwrap()), c[12]))
            .collect();
        assert_eq!(
            kept,
            [
                (0.0, 0),
                (3.0, 0),
                (4.0, REMOVED),
                (6.0, 0),
                (7.0, REMOVED),
                (9.0, 0)
            ]
        );
        // a cap above the size, or none, keeps all
        for max in [Some(10), Some(1000), None] {
            let all = point_cloud(0, "lidar", &points, &[], max);
            assert_eq!(all.data.len(), 10 * POINT_STRIDE_BYTES);
        }
        // a cap of one keeps the first point (and the removed ones)
        let one = point_cloud(0, "lidar", &points, &[5], Some(1));
        assert_eq!(one.data.len(), 2 * POINT_STRIDE_BYTES);
    }

    #[test]
    fn box_pose_turns_about_z_by_the_yaw() {
        let b = OrientedBox::new(V3::new(1.0, 2.0, 3.0), V3::new(4.0, 2.0, 1.5), 0.7);
        let p = box_pose(&b);
        let q = p.orientation.unwrap();
        let (half_angle, axis_z) = ((0.7f64 / 2.0).cos(), (0.7f64 / 2.0).sin());
        assert!((q.w - half_angle).abs() < 1e-12 && (q.z - axis_z).abs() < 1e-12);
        assert!(q.x.abs() < 1e-12 && q.y.abs() < 1e-12);
        assert_eq!(p.position.unwrap().x, 1.0);
    }

    #[test]
    fn arrow_follows_the_velocity_and_slow_boxes_have_none() {
        let b = OrientedBox::new(V3::zeros(), V3::new(4.0, 2.0, 1.5), 0.0);
        let style = || BoxStyle {
            id: "a".into(),
            color: rgba(1.0, 0.0, 0.0, 1.0),
            label: "a".into(),
            metadata: vec![],
        };
        let moving = box_entity(0, "world", &b, Some(V3::new(0.0, -3.0, 0.0)), style());
        assert_eq!(moving.arrows.len(), 1);
        let arrow = &moving.arrows[0];
        assert!((arrow.shaft_length + arrow.head_length - 3.0).abs() < 1e-12);
        let q = arrow.pose.as_ref().unwrap().orientation.unwrap();
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
        assert!((q * V3::x() - V3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
        let backwards = box_entity(0, "world", &b, Some(V3::new(-2.0, 0.0, 0.0)), style());
        let q = backwards.arrows[0]
            .pose
            .as_ref()
            .unwrap()
            .orientation
            .unwrap();
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
        assert!((q * V3::x() - V3::new(-1.0, 0.0, 0.0)).norm() < 1e-12);
        let parked = box_entity(0, "world", &b, Some(V3::new(0.1, 0.0, 0.0)), style());
        assert!(parked.arrows.is_empty());
        assert_eq!(parked.cubes.len(), 1);
    }
}
