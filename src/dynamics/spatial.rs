//! Spatial (6-D) vector algebra, after Featherstone, *Rigid Body Dynamics Algorithms* (2008),
//! chapter 2.
//!
//! Plücker coordinates with the angular part first, all expressed in some body frame B with
//! origin O:
//! - a motion vector (velocity, acceleration, joint axis) is `[ω; v_O]`, where `v_O` is the
//!   velocity of the body point that currently coincides with O;
//! - a force vector is `[n_O; f]`, the moment about O and the resultant force.
//!
//! The types are small `Copy` values on the stack: nothing here allocates, so the recursive
//! algorithms built on them can run in a hard real-time loop.

use nalgebra::{Isometry3, Matrix3, Rotation3, Unit, Vector3};
use std::ops::{Add, AddAssign, Mul, Sub};

/// Cross-product matrix: `skew(a) * b == a × b`.
pub fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// A spatial motion vector `[ω; v_O]` (velocity, acceleration or a joint's motion subspace).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// `ω`: the angular part (rad/s for a velocity, rad/s² for an acceleration).
    pub angular: Vector3<f64>,
    /// `v_O`: the linear part at the frame origin (m/s for a velocity, m/s² for an
    /// acceleration).
    pub linear: Vector3<f64>,
}

/// A spatial force vector `[n_O; f]` (moment about the frame origin, force).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Force {
    /// `n_O`: the moment about the frame origin (N·m).
    pub angular: Vector3<f64>,
    /// `f`: the resultant force (N).
    pub linear: Vector3<f64>,
}

impl Motion {
    /// The zero motion vector.
    pub const ZERO: Motion = Motion {
        angular: Vector3::new(0.0, 0.0, 0.0),
        linear: Vector3::new(0.0, 0.0, 0.0),
    };

    /// `[angular; linear]`.
    pub fn new(angular: Vector3<f64>, linear: Vector3<f64>) -> Self {
        Motion { angular, linear }
    }

    /// `self ×ₘ m`: the rate of change of `m` when it is carried along by a body moving with
    /// velocity `self` (RBDA eq. 2.31). Gives the velocity-product accelerations.
    pub fn cross_motion(&self, m: &Motion) -> Motion {
        Motion {
            angular: self.angular.cross(&m.angular),
            linear: self.angular.cross(&m.linear) + self.linear.cross(&m.angular),
        }
    }

    /// `self ×* f`, the dual cross product (RBDA eq. 2.32). With `f = I v` it gives the
    /// gyroscopic / Coriolis forces `v ×* I v`.
    pub fn cross_force(&self, f: &Force) -> Force {
        Force {
            angular: self.angular.cross(&f.angular) + self.linear.cross(&f.linear),
            linear: self.angular.cross(&f.linear),
        }
    }

    /// The scalar product `m · f` (power of `f` on `m`). With `m = S` it projects a spatial
    /// force onto a joint axis: `τ = Sᵀ f`.
    pub fn dot(&self, f: &Force) -> f64 {
        self.angular.dot(&f.angular) + self.linear.dot(&f.linear)
    }
}

impl Force {
    /// The zero force vector.
    pub const ZERO: Force = Force {
        angular: Vector3::new(0.0, 0.0, 0.0),
        linear: Vector3::new(0.0, 0.0, 0.0),
    };

    /// `[angular; linear]`.
    pub fn new(angular: Vector3<f64>, linear: Vector3<f64>) -> Self {
        Force { angular, linear }
    }
}

macro_rules! vector_ops {
    ($t:ident) => {
        impl Add for $t {
            type Output = $t;
            fn add(self, o: $t) -> $t {
                $t {
                    angular: self.angular + o.angular,
                    linear: self.linear + o.linear,
                }
            }
        }
        impl Sub for $t {
            type Output = $t;
            fn sub(self, o: $t) -> $t {
                $t {
                    angular: self.angular - o.angular,
                    linear: self.linear - o.linear,
                }
            }
        }
        impl AddAssign for $t {
            fn add_assign(&mut self, o: $t) {
                self.angular += o.angular;
                self.linear += o.linear;
            }
        }
        impl Mul<f64> for $t {
            type Output = $t;
            fn mul(self, s: f64) -> $t {
                $t {
                    angular: self.angular * s,
                    linear: self.linear * s,
                }
            }
        }
    };
}
vector_ops!(Motion);
vector_ops!(Force);

/// A Plücker coordinate transform `B_X_A` from frame A to frame B, stored as the rotation
/// `E` (A coordinates → B coordinates) and the position `r` of B's origin in A coordinates
/// (RBDA §2.8). Storing `(E, r)` instead of a 6×6 matrix makes each application two 3×3
/// products and a cross product.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// `E`: rotates A coordinates into B coordinates.
    pub rotation: Matrix3<f64>,
    /// `r`: the position of B's origin in A coordinates (m).
    pub translation: Vector3<f64>,
}

impl Transform {
    /// The transform between coincident frames (E = 1, r = 0).
    pub fn identity() -> Self {
        Transform {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// The transform into frame B from frame A, given B's pose in A (as URDF gives a joint
    /// origin: the child frame in the parent frame).
    pub fn from_pose(b_in_a: &Isometry3<f64>) -> Self {
        Transform {
            rotation: b_in_a
                .rotation
                .to_rotation_matrix()
                .into_inner()
                .transpose(),
            translation: b_in_a.translation.vector,
        }
    }

    /// The frame after a rotation by `angle` about the unit `axis` (revolute joint motion).
    pub fn rotation_about(axis: &Vector3<f64>, angle: f64) -> Self {
        // E rotates parent coordinates into the rotated frame: the inverse rotation.
        let rotation = Rotation3::from_axis_angle(&Unit::new_unchecked(*axis), -angle);
        Transform {
            rotation: rotation.into_inner(),
            translation: Vector3::zeros(),
        }
    }

    /// The frame after a translation by `distance` along the unit `axis` (prismatic joint).
    pub fn translation_along(axis: &Vector3<f64>, distance: f64) -> Self {
        Transform {
            rotation: Matrix3::identity(),
            translation: axis * distance,
        }
    }

    /// `X m`: a motion vector in A coordinates to B coordinates.
    pub fn transform_motion(&self, m: &Motion) -> Motion {
        Motion {
            angular: self.rotation * m.angular,
            linear: self.rotation * (m.linear - self.translation.cross(&m.angular)),
        }
    }

    /// `X⁻¹ m`: a motion vector in B coordinates to A coordinates.
    pub fn inverse_transform_motion(&self, m: &Motion) -> Motion {
        let angular = self.rotation.tr_mul(&m.angular);
        Motion {
            angular,
            linear: self.rotation.tr_mul(&m.linear) + self.translation.cross(&angular),
        }
    }

    /// `X* f`: a force vector in A coordinates to B coordinates.
    pub fn transform_force(&self, f: &Force) -> Force {
        Force {
            angular: self.rotation * (f.angular - self.translation.cross(&f.linear)),
            linear: self.rotation * f.linear,
        }
    }

    /// `Xᵀ f = (X*)⁻¹ f`: a force vector in B coordinates to A coordinates. This is how a
    /// child body's force is passed to its parent in the backward passes.
    pub fn inverse_transform_force(&self, f: &Force) -> Force {
        let linear = self.rotation.tr_mul(&f.linear);
        Force {
            angular: self.rotation.tr_mul(&f.angular) + self.translation.cross(&linear),
            linear,
        }
    }

    /// `Xᵀ I X`: a spatial inertia given in B coordinates, expressed in A coordinates
    /// (RBDA eq. 2.66, done on the inertia's parameters rather than 6×6 matrices).
    pub fn inverse_transform_inertia(&self, inertia: &SpatialInertia) -> SpatialInertia {
        let e = &self.rotation;
        let r = &self.translation;
        let m = inertia.mass;
        // Rotate into A's axes (still about B's origin) ...
        let h_rot = e.tr_mul(&inertia.first_moment);
        let i_rot = e.transpose() * inertia.rotational * e;
        // ... then move the reference point from B's origin (at r) to A's origin:
        // Ī_A = Ī - r× (Eᵀh)× - h_A× r×, with h_A = Eᵀh + m r (parallel-axis theorem).
        let h = h_rot + r * m;
        SpatialInertia {
            mass: m,
            first_moment: h,
            rotational: i_rot - skew(r) * skew(&h_rot) - skew(&h) * skew(r),
        }
    }
}

/// `X_BC * X_AB = X_AC`: apply the right-hand transform first.
impl Mul for Transform {
    type Output = Transform;
    fn mul(self, first: Transform) -> Transform {
        Transform {
            rotation: self.rotation * first.rotation,
            translation: first.translation + first.rotation.tr_mul(&self.translation),
        }
    }
}

/// A rigid body's spatial inertia in some frame, by its ten inertial parameters: mass `m`,
/// first moment `h = m c` (c: centre of mass) and rotational inertia `Ī` about the frame
/// origin. As a 6×6 matrix it is `[[Ī, h×], [h×ᵀ, m 1]]` (RBDA eq. 2.63).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpatialInertia {
    /// `m` (kg).
    pub mass: f64,
    /// `h = m c`, c the centre of mass in this frame (kg·m).
    pub first_moment: Vector3<f64>,
    /// `Ī`: the rotational inertia about the frame origin (kg·m²).
    pub rotational: Matrix3<f64>,
}

impl SpatialInertia {
    /// No body at all: zero mass, first moment and rotational inertia.
    pub const ZERO: SpatialInertia = SpatialInertia {
        mass: 0.0,
        first_moment: Vector3::new(0.0, 0.0, 0.0),
        rotational: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    };

    /// From mass, centre of mass and the inertia tensor about the centre of mass, all in the
    /// frame this inertia is expressed in (what URDF gives per link).
    pub fn from_center_of_mass(
        mass: f64,
        center_of_mass: &Vector3<f64>,
        inertia_about_com: &Matrix3<f64>,
    ) -> Self {
        let cx = skew(center_of_mass);
        SpatialInertia {
            mass,
            first_moment: center_of_mass * mass,
            // Parallel-axis theorem: Ī_O = I_C + m (cᵀc 1 - c cᵀ) = I_C - m c× c×.
            rotational: inertia_about_com - cx * cx * mass,
        }
    }

    /// `I v`: the momentum of a body moving with velocity `v` (or the force that gives it
    /// acceleration `v`).
    pub fn mul_motion(&self, v: &Motion) -> Force {
        Force {
            angular: self.rotational * v.angular + self.first_moment.cross(&v.linear),
            linear: v.linear * self.mass - self.first_moment.cross(&v.angular),
        }
    }
}

impl AddAssign for SpatialInertia {
    /// Two bodies rigidly joined: inertias in the same frame add.
    fn add_assign(&mut self, o: SpatialInertia) {
        self.mass += o.mass;
        self.first_moment += o.first_moment;
        self.rotational += o.rotational;
    }
}

#[cfg(test)]
mod tests {
    //! Each operation against its textbook 6×6 matrix form, so that the parameter-level
    //! shortcuts above cannot drift from the definitions.
    use super::*;
    use nalgebra::{Matrix6, Translation3, UnitQuaternion, Vector6};

    fn motion6(m: &Motion) -> Vector6<f64> {
        Vector6::new(
            m.angular.x,
            m.angular.y,
            m.angular.z,
            m.linear.x,
            m.linear.y,
            m.linear.z,
        )
    }
    fn force6(f: &Force) -> Vector6<f64> {
        motion6(&Motion::new(f.angular, f.linear))
    }
    fn blocks(a: Matrix3<f64>, b: Matrix3<f64>, c: Matrix3<f64>, d: Matrix3<f64>) -> Matrix6<f64> {
        let mut x = Matrix6::zeros();
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&a);
        x.fixed_view_mut::<3, 3>(0, 3).copy_from(&b);
        x.fixed_view_mut::<3, 3>(3, 0).copy_from(&c);
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&d);
        x
    }
    /// RBDA eq. 2.24: X = [[E, 0], [-E r×, E]].
    fn motion_matrix(x: &Transform) -> Matrix6<f64> {
        let e = x.rotation;
        blocks(e, Matrix3::zeros(), -e * skew(&x.translation), e)
    }
    fn inertia_matrix(i: &SpatialInertia) -> Matrix6<f64> {
        let hx = skew(&i.first_moment);
        blocks(
            i.rotational,
            hx,
            hx.transpose(),
            Matrix3::identity() * i.mass,
        )
    }
    fn sample_transform() -> Transform {
        Transform::from_pose(&Isometry3::from_parts(
            Translation3::new(0.3, -0.2, 0.7),
            UnitQuaternion::from_euler_angles(0.4, -1.1, 2.0),
        ))
    }
    fn sample_inertia() -> SpatialInertia {
        let i_c = Matrix3::new(0.5, 0.01, -0.02, 0.01, 0.4, 0.03, -0.02, 0.03, 0.3);
        SpatialInertia::from_center_of_mass(3.0, &Vector3::new(0.1, -0.3, 0.25), &i_c)
    }
    const M: Motion = Motion {
        angular: Vector3::new(0.3, -1.2, 0.8),
        linear: Vector3::new(-0.5, 0.9, 2.0),
    };
    const F: Force = Force {
        angular: Vector3::new(1.5, 0.2, -0.7),
        linear: Vector3::new(0.4, -2.2, 1.1),
    };

    fn assert_close6(a: Vector6<f64>, b: Vector6<f64>) {
        assert!((a - b).amax() < 1e-12, "{a} != {b}");
    }

    #[test]
    fn transforms_match_plucker_matrices() {
        let x = sample_transform();
        let xm = motion_matrix(&x);
        let xm_inv = xm.try_inverse().unwrap();
        let xf = xm_inv.transpose(); // X* = X⁻ᵀ
        assert_close6(motion6(&x.transform_motion(&M)), xm * motion6(&M));
        assert_close6(
            motion6(&x.inverse_transform_motion(&M)),
            xm_inv * motion6(&M),
        );
        assert_close6(force6(&x.transform_force(&F)), xf * force6(&F));
        assert_close6(
            force6(&x.inverse_transform_force(&F)),
            xm.transpose() * force6(&F),
        );
    }

    #[test]
    fn composition_applies_right_operand_first() {
        let a = sample_transform();
        let b = Transform::rotation_about(&Vector3::new(0.0, 0.6, 0.8), 0.9)
            * Transform::translation_along(&Vector3::x(), 0.25);
        let ab = motion_matrix(&(b * a));
        assert!((ab - motion_matrix(&b) * motion_matrix(&a)).amax() < 1e-12);
    }

    #[test]
    fn joint_transforms_match_urdf_child_poses() {
        // The child frame of a revolute joint at angle q is the parent frame rotated by q.
        let axis = Vector3::new(0.0, 0.6, 0.8);
        let pose = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Unit::new_normalize(axis), 0.9),
        );
        let expected = Transform::from_pose(&pose);
        let got = Transform::rotation_about(&axis, 0.9);
        assert!((got.rotation - expected.rotation).amax() < 1e-15);
        let pose = Isometry3::translation(0.0, 0.6 * 0.3, 0.8 * 0.3);
        let expected = Transform::from_pose(&pose);
        let got = Transform::translation_along(&axis, 0.3);
        assert!((got.translation - expected.translation).amax() < 1e-15);
    }

    #[test]
    fn inertia_products_match_matrices() {
        let i = sample_inertia();
        assert_close6(force6(&i.mul_motion(&M)), inertia_matrix(&i) * motion6(&M));
        let x = sample_transform();
        let xm = motion_matrix(&x);
        let moved = inertia_matrix(&x.inverse_transform_inertia(&i));
        assert!((moved - xm.transpose() * inertia_matrix(&i) * xm).amax() < 1e-12);
    }

    #[test]
    fn cross_products_match_matrices() {
        let v = M;
        // RBDA eq. 2.31: v×ₘ = [[ω×, 0], [v×, ω×]]; v×* = -(v×ₘ)ᵀ.
        let crm = blocks(
            skew(&v.angular),
            Matrix3::zeros(),
            skew(&v.linear),
            skew(&v.angular),
        );
        let m2 = Motion::new(Vector3::new(0.1, 0.2, -0.3), Vector3::new(1.0, -1.0, 0.5));
        assert_close6(motion6(&v.cross_motion(&m2)), crm * motion6(&m2));
        assert_close6(force6(&v.cross_force(&F)), -crm.transpose() * force6(&F));
        // Power is frame-independent: (X m)·(X* f) = m·f.
        let x = sample_transform();
        let p = x.transform_motion(&M).dot(&x.transform_force(&F));
        assert!((p - M.dot(&F)).abs() < 1e-12);
    }
}
