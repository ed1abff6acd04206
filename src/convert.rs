//! nalgebra ⇄ the math types of parry and Rapier 0.36 (glam), kept in one place: the machine
//! description computes mass properties with parry, the physics model talks to Rapier.

use nalgebra::{Isometry3, Matrix3, Quaternion, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::math::{Matrix, Pose, Rotation, Vector};

pub fn to_vec(v: &Vector3<f64>) -> Vector {
    Vector::new(v.x, v.y, v.z)
}

pub fn from_vec(v: &Vector) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

pub fn to_mat(m: &Matrix3<f64>) -> Matrix {
    Matrix::from_cols(
        Vector::new(m[(0, 0)], m[(1, 0)], m[(2, 0)]),
        Vector::new(m[(0, 1)], m[(1, 1)], m[(2, 1)]),
        Vector::new(m[(0, 2)], m[(1, 2)], m[(2, 2)]),
    )
}

pub fn to_pose(p: &Isometry3<f64>) -> Pose {
    let q = p.rotation.quaternion();
    Pose::from_parts(
        to_vec(&p.translation.vector),
        Rotation::from_xyzw(q.i, q.j, q.k, q.w),
    )
}

pub fn from_pose(p: &Pose) -> Isometry3<f64> {
    let r = p.rotation;
    Isometry3::from_parts(
        Translation3::from(from_vec(&p.translation)),
        UnitQuaternion::new_normalize(Quaternion::new(r.w, r.x, r.y, r.z)),
    )
}
