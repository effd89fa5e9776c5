//! Object factors of the joint graph (paper, "Joint Factor Graph
//! Optimization"): the object observation factor `r_obs`, the ternary object
//! motion factor `r_moti` and the constant-velocity smooth motion factor
//! `r_smoo`.
//!
//! Frame of the residuals: like [`BetweenFactor`](super::BetweenFactor) (the
//! paper's `r_odo`), every residual here is the *right* (body-frame) error
//! `Log(Z⁻¹·Ẑ)` between a measured or stored transform `Z` and its prediction
//! `Ẑ`. The paper writes the products as `Ẑ·Z⁻¹`, which vanishes at the same
//! values but expresses the error in the LiDAR frame, where a yaw error of the
//! detector at range `d` shows up as a translation error of `yaw·d`. In the
//! object frame the translation and rotation errors of a detection stay
//! decoupled, so a diagonal `(σ_t, σ_t, σ_t, σ_r, σ_r, σ_r)` noise model is
//! meaningful: translation sigmas are along the object's own axes.

use super::factor::{Factor, JacobiansMut};
use super::key::Key;
use super::noise::NoiseModel;
use super::values::Values;
use crate::lie;
use nalgebra::Isometry3;

fn is_object_pose(key: &Key) -> bool {
    matches!(key, Key::ObjectPose { .. } | Key::StaticObjectPose { .. })
}

// ---------------------------------------------------------------------------
// r_obs
// ---------------------------------------------------------------------------

/// Object observation factor between the ego pose `t_world_imu` and an
/// object's world pose:
/// `r_obs = Log(Z⁻¹ · (T_world_lidar⁻¹ · T_world_object))` with
/// `T_world_lidar = T_world_imu · t_imu_lidar` and `Z` the detected
/// `t_lidar_object`. The residual `(ρ, φ)` is expressed in the **object
/// frame** (see the module docs), so the 6-dim noise is translation along the
/// object's axes, then rotation.
#[derive(Debug, Clone)]
pub struct ObjectObservationFactor {
    keys: [Key; 2],
    t_imu_lidar: Isometry3<f64>,
    measured_t_lidar_object: Isometry3<f64>,
    /// `Z⁻¹·t_imu_lidar⁻¹`, cached: the residual is `Log(this·T_world_imu⁻¹·T_world_object)`.
    t_object_meas_imu: Isometry3<f64>,
    noise: NoiseModel,
}

impl ObjectObservationFactor {
    /// `ego` is an [`Key::EgoPose`], `object` an [`Key::ObjectPose`] or a
    /// [`Key::StaticObjectPose`]; `noise` must be 6-dimensional.
    pub fn new(
        ego: Key,
        object: Key,
        t_imu_lidar: Isometry3<f64>,
        t_lidar_object_measured: Isometry3<f64>,
        noise: NoiseModel,
    ) -> ObjectObservationFactor {
        debug_assert!(
            matches!(ego, Key::EgoPose(_)),
            "ego key {ego} is not an ego pose"
        );
        debug_assert!(
            is_object_pose(&object),
            "object key {object} is not an object pose"
        );
        debug_assert_eq!(noise.dim(), 6, "observation noise must be 6-dim");
        ObjectObservationFactor {
            keys: [ego, object],
            t_imu_lidar,
            measured_t_lidar_object: t_lidar_object_measured,
            t_object_meas_imu: t_lidar_object_measured.inverse() * t_imu_lidar.inverse(),
            noise,
        }
    }

    /// The detected `t_lidar_object`.
    pub fn measured(&self) -> &Isometry3<f64> {
        &self.measured_t_lidar_object
    }

    /// The LiDAR extrinsic `t_imu_lidar` this factor was built with.
    pub fn t_imu_lidar(&self) -> &Isometry3<f64> {
        &self.t_imu_lidar
    }

    fn error(&self, values: &Values) -> Isometry3<f64> {
        let t_world_imu = values.pose(&self.keys[0]);
        let t_world_object = values.pose(&self.keys[1]);
        self.t_object_meas_imu * lie::between(t_world_imu, t_world_object)
    }
}

impl Factor for ObjectObservationFactor {
    fn keys(&self) -> &[Key] {
        &self.keys
    }

    fn residual_dim(&self) -> usize {
        6
    }

    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        let t_world_imu = values.pose(&self.keys[0]);
        let t_world_object = values.pose(&self.keys[1]);
        // E = Z⁻¹·C⁻¹·X⁻¹·O. A right perturbation of O enters on the right:
        // J_r⁻¹(r). One of X gives C⁻¹·Exp(-ξ)·X⁻¹ ..., i.e.
        // E·Exp(-Ad(O⁻¹·X)·ξ): the extrinsic C drops out of this Jacobian.
        let error = self.t_object_meas_imu * lie::between(t_world_imu, t_world_object);
        let (r, jr_inv) = lie::se3_log_with_jacobian(&error);
        let d_object = jr_inv;
        let d_ego = -jr_inv * lie::se3_adjoint(&lie::between(t_world_object, t_world_imu));
        residual.copy_from_slice(r.as_slice());
        jacobians.set(0, &d_ego);
        jacobians.set(1, &d_object);
    }

    fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        residual.copy_from_slice(lie::se3_log(&self.error(values)).as_slice());
    }
}

// ---------------------------------------------------------------------------
// r_moti
// ---------------------------------------------------------------------------

/// Ternary object motion factor tying two consecutive object poses to the
/// motion node between them: `r_moti = Log(M⁻¹ · (T_{k-1}⁻¹ · T_k))`, zero when
/// `M = T_{k-1}⁻¹·T_k` (the pose change in the object frame at `k-1`, paper
/// eq. `moti`). Residual in the object frame at `k` (see the module docs).
/// Keys in Jacobian order: `pose_prev`, `pose_next`, `motion`.
#[derive(Debug, Clone)]
pub struct ObjectMotionFactor {
    keys: [Key; 3],
    noise: NoiseModel,
}

impl ObjectMotionFactor {
    /// `pose_prev = ObjectPose{id, k-1}`, `pose_next = ObjectPose{id, k}`,
    /// `motion = ObjectMotion{id, k-1}` (named by the frame it starts from);
    /// `noise` must be 6-dimensional.
    pub fn new(
        pose_prev: Key,
        pose_next: Key,
        motion: Key,
        noise: NoiseModel,
    ) -> ObjectMotionFactor {
        debug_assert!(
            is_object_pose(&pose_prev),
            "{pose_prev} is not an object pose"
        );
        debug_assert!(
            is_object_pose(&pose_next),
            "{pose_next} is not an object pose"
        );
        debug_assert!(
            matches!(motion, Key::ObjectMotion { .. }),
            "{motion} is not an object motion"
        );
        debug_assert_eq!(noise.dim(), 6, "motion noise must be 6-dim");
        ObjectMotionFactor {
            keys: [pose_prev, pose_next, motion],
            noise,
        }
    }

    fn error(&self, values: &Values) -> Isometry3<f64> {
        let t_prev = values.pose(&self.keys[0]);
        let t_next = values.pose(&self.keys[1]);
        let motion = values.pose(&self.keys[2]);
        motion.inverse() * lie::between(t_prev, t_next)
    }
}

impl Factor for ObjectMotionFactor {
    fn keys(&self) -> &[Key] {
        &self.keys
    }

    fn residual_dim(&self) -> usize {
        6
    }

    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        let t_prev = values.pose(&self.keys[0]);
        let t_next = values.pose(&self.keys[1]);
        // E = M⁻¹·P⁻¹·N. Right perturbations: of N → E·Exp(ξ); of P →
        // E·Exp(-Ad(N⁻¹·P)·ξ); of M → Exp(-ξ)·E = E·Exp(-Ad(E⁻¹)·ξ).
        let error = self.error(values);
        let (r, jr_inv) = lie::se3_log_with_jacobian(&error);
        let d_next = jr_inv;
        let d_prev = -jr_inv * lie::se3_adjoint(&lie::between(t_next, t_prev));
        let d_motion = -jr_inv * lie::se3_adjoint(&error.inverse());
        residual.copy_from_slice(r.as_slice());
        jacobians.set(0, &d_prev);
        jacobians.set(1, &d_next);
        jacobians.set(2, &d_motion);
    }

    fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        residual.copy_from_slice(lie::se3_log(&self.error(values)).as_slice());
    }
}

// ---------------------------------------------------------------------------
// r_smoo
// ---------------------------------------------------------------------------

/// Constant-velocity prior between consecutive motion nodes of one object:
/// `r_smoo = Log(M_{k-2,k-1}⁻¹ · M_{k-1,k})` (assumes equal frame intervals).
/// Residual in the object frame at `k-1`. Keys: `motion_prev`, `motion_next`.
#[derive(Debug, Clone)]
pub struct SmoothMotionFactor {
    keys: [Key; 2],
    noise: NoiseModel,
}

impl SmoothMotionFactor {
    /// `motion_prev = ObjectMotion{id, k-2}`, `motion_next = ObjectMotion{id, k-1}`;
    /// `noise` must be 6-dimensional.
    pub fn new(motion_prev: Key, motion_next: Key, noise: NoiseModel) -> SmoothMotionFactor {
        debug_assert!(
            matches!(motion_prev, Key::ObjectMotion { .. }),
            "{motion_prev} is not an object motion"
        );
        debug_assert!(
            matches!(motion_next, Key::ObjectMotion { .. }),
            "{motion_next} is not an object motion"
        );
        debug_assert_eq!(noise.dim(), 6, "smoothness noise must be 6-dim");
        SmoothMotionFactor {
            keys: [motion_prev, motion_next],
            noise,
        }
    }
}

impl Factor for SmoothMotionFactor {
    fn keys(&self) -> &[Key] {
        &self.keys
    }

    fn residual_dim(&self) -> usize {
        6
    }

    fn linearize_into(
        &self,
        values: &Values,
        residual: &mut [f64],
        jacobians: &mut JacobiansMut<'_>,
    ) {
        let (r, d_prev, d_next) =
            lie::between_with_jacobians(values.pose(&self.keys[0]), values.pose(&self.keys[1]));
        residual.copy_from_slice(r.as_slice());
        jacobians.set(0, &d_prev);
        jacobians.set(1, &d_next);
    }

    fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    fn residual_into(&self, values: &Values, residual: &mut [f64]) {
        let between = lie::between(values.pose(&self.keys[0]), values.pose(&self.keys[1]));
        residual.copy_from_slice(lie::se3_log(&between).as_slice());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::{Variable, check_factor_jacobians};
    use nalgebra::{DVector, Translation3, UnitQuaternion, Vector3, Vector6};

    const EGO: Key = Key::EgoPose(4);
    const OBJ_PREV: Key = Key::ObjectPose { id: 7, frame: 3 };
    const OBJ_NEXT: Key = Key::ObjectPose { id: 7, frame: 4 };
    const MOT_PREV: Key = Key::ObjectMotion { id: 7, frame: 2 };
    const MOT_NEXT: Key = Key::ObjectMotion { id: 7, frame: 3 };

    fn noise() -> NoiseModel {
        NoiseModel::diagonal_sigmas(&[0.15, 0.15, 0.15, 0.03, 0.03, 0.03])
    }

    fn pose(x: f64, y: f64, z: f64, roll: f64, pitch: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        )
    }

    fn twist(rho: [f64; 3], phi: [f64; 3]) -> Vector6<f64> {
        lie::xi_from_parts(&Vector3::from(rho), &Vector3::from(phi))
    }

    fn assert_close(actual: &DVector<f64>, expected: &Vector6<f64>, tol: f64) {
        let diff = (actual - DVector::from_column_slice(expected.as_slice())).amax();
        assert!(
            diff < tol,
            "residual {actual} != {expected} (diff {diff:e})"
        );
    }

    /// Ego (IMU) at some world pose, LiDAR mounted above and yawed, a car
    /// 30 m ahead-left: the detection is the true relative pose.
    fn observation_scene() -> (Values, Isometry3<f64>, Isometry3<f64>) {
        let t_world_imu = pose(12.0, -4.0, 0.3, 0.02, -0.01, 0.7);
        let t_imu_lidar = pose(0.8, 0.0, 1.7, 0.0, 0.0, 0.05);
        let t_world_object = t_world_imu * pose(28.0, 9.0, -0.6, 0.0, 0.0, 1.2);
        let t_lidar_object = (t_world_imu * t_imu_lidar).inverse() * t_world_object;
        let mut values = Values::new();
        values.insert(EGO, Variable::Pose(t_world_imu));
        values.insert(OBJ_NEXT, Variable::Pose(t_world_object));
        (values, t_imu_lidar, t_lidar_object)
    }

    #[test]
    fn observation_residual_vanishes_at_truth_and_is_in_the_object_frame() {
        let (mut values, t_imu_lidar, t_lidar_object) = observation_scene();
        let factor =
            ObjectObservationFactor::new(EGO, OBJ_NEXT, t_imu_lidar, t_lidar_object, noise());
        assert_eq!(factor.measured(), &t_lidar_object);
        assert!(factor.residual(&values).amax() < 1e-12);
        assert!(check_factor_jacobians(&factor, &values, 1e-6) < 1e-6);

        // A detection yawed by ψ about the box centre (a pure heading error,
        // 30 m away): only the rotation part moves, by -ψ about the object z.
        let psi = 0.04;
        let yawed = t_lidar_object * pose(0.0, 0.0, 0.0, 0.0, 0.0, psi);
        let heading_error =
            ObjectObservationFactor::new(EGO, OBJ_NEXT, t_imu_lidar, yawed, noise());
        assert_close(
            &heading_error.residual(&values),
            &twist([0.0; 3], [0.0, 0.0, -psi]),
            1e-12,
        );

        // The estimated object 0.2 m further along its own x axis: +0.2 in ρ_x.
        let t_world_object = *values.pose(&OBJ_NEXT);
        values.insert(
            OBJ_NEXT,
            Variable::Pose(t_world_object * pose(0.2, 0.0, 0.0, 0.0, 0.0, 0.0)),
        );
        assert_close(
            &factor.residual(&values),
            &twist([0.2, 0.0, 0.0], [0.0; 3]),
            1e-12,
        );
    }

    #[test]
    fn observation_residual_of_an_ego_offset_is_seen_from_the_object() {
        // Object yawed +90° relative to the ego: an ego step of d forward (IMU
        // x) makes the object appear d closer, i.e. d along its own +y.
        let t_world_imu = pose(5.0, 1.0, 0.0, 0.0, 0.0, -0.3);
        let t_imu_lidar = pose(1.0, 0.2, 1.5, 0.0, 0.0, 0.0);
        let t_world_object =
            t_world_imu * pose(20.0, -3.0, 0.0, 0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let t_lidar_object = (t_world_imu * t_imu_lidar).inverse() * t_world_object;
        let d = 0.3;
        let mut values = Values::new();
        values.insert(
            EGO,
            Variable::Pose(t_world_imu * pose(d, 0.0, 0.0, 0.0, 0.0, 0.0)),
        );
        values.insert(
            Key::StaticObjectPose { id: 2 },
            Variable::Pose(t_world_object),
        );
        let factor = ObjectObservationFactor::new(
            EGO,
            Key::StaticObjectPose { id: 2 },
            t_imu_lidar,
            t_lidar_object,
            noise(),
        );
        assert_close(
            &factor.residual(&values),
            &twist([0.0, d, 0.0], [0.0; 3]),
            1e-12,
        );
        assert!(check_factor_jacobians(&factor, &values, 1e-6) < 1e-6);
    }

    #[test]
    fn motion_residual_vanishes_at_consistent_values_and_measures_offsets() {
        let t_prev = pose(30.0, -2.0, 0.1, 0.0, 0.01, 0.4);
        let motion = pose(1.4, 0.05, 0.0, 0.0, 0.0, 0.02);
        let mut values = Values::new();
        values.insert(OBJ_PREV, Variable::Pose(t_prev));
        values.insert(OBJ_NEXT, Variable::Pose(t_prev * motion));
        values.insert(MOT_PREV, Variable::Pose(motion));
        let factor = ObjectMotionFactor::new(OBJ_PREV, OBJ_NEXT, MOT_PREV, noise());
        assert_eq!(factor.keys(), &[OBJ_PREV, OBJ_NEXT, MOT_PREV]);
        assert!(factor.residual(&values).amax() < 1e-12);
        assert!(check_factor_jacobians(&factor, &values, 1e-6) < 1e-6);

        // The motion node claims 0.1 m more forward travel than the poses:
        // the poses fall short, -0.1 along x.
        values.insert(
            MOT_PREV,
            Variable::Pose(motion * pose(0.1, 0.0, 0.0, 0.0, 0.0, 0.0)),
        );
        assert_close(
            &factor.residual(&values),
            &twist([-0.1, 0.0, 0.0], [0.0; 3]),
            1e-12,
        );
        // The next pose turned 0.05 rad more (about its own z) than that.
        values.insert(MOT_PREV, Variable::Pose(motion));
        values.insert(
            OBJ_NEXT,
            Variable::Pose(t_prev * motion * pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.05)),
        );
        assert_close(
            &factor.residual(&values),
            &twist([0.0; 3], [0.0, 0.0, 0.05]),
            1e-12,
        );
        assert!(check_factor_jacobians(&factor, &values, 1e-6) < 1e-6);
    }

    #[test]
    fn smooth_motion_residual_is_the_change_of_motion() {
        let motion = pose(1.4, 0.05, 0.0, 0.0, 0.0, 0.02);
        let mut values = Values::new();
        values.insert(MOT_PREV, Variable::Pose(motion));
        values.insert(MOT_NEXT, Variable::Pose(motion));
        let factor = SmoothMotionFactor::new(MOT_PREV, MOT_NEXT, noise());
        assert!(factor.residual(&values).amax() < 1e-12);
        // Accelerating: 0.12 m more travel in the next interval.
        values.insert(
            MOT_NEXT,
            Variable::Pose(motion * pose(0.12, 0.0, 0.0, 0.0, 0.0, 0.0)),
        );
        assert_close(
            &factor.residual(&values),
            &twist([0.12, 0.0, 0.0], [0.0; 3]),
            1e-12,
        );
        assert!(check_factor_jacobians(&factor, &values, 1e-6) < 1e-6);
    }
}
