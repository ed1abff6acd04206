//! Every link a joint moves must carry mass: the physics cannot accelerate a massless body.
//! All such links are reported at once, located in the URDF; with `inertia_from_geometry` in
//! the drive file, the masses and inertias the URDF leaves out are computed from the links'
//! geometry at a uniform density (as MuJoCo's `inertiafromgeom` does), with parry's mass
//! properties of each solid.

use super::{JointKind, KinematicTree, Link, SolidShape, MIN_BODY_MASS_KG};
use crate::convert::{from_vec, to_pose, to_vec};
use crate::diagnostics::FileError;
use nalgebra::{Matrix3, Point3};
use parry3d_f64::mass_properties::MassProperties;
use std::path::Path;

/// Completes the masses of `tree` (with `density`, kg/m³, when given) and returns the links
/// whose mass was computed; refuses, listing them all, moving rigid groups left without mass.
pub(super) fn complete(
    tree: &mut KinematicTree,
    density: Option<f64>,
    drives_path: &Path,
) -> Result<Vec<String>, FileError> {
    let group = rigid_groups(tree);
    let root_group = group[tree.root];
    let mut computed = Vec::new();
    if let Some(density) = density {
        for (i, link) in tree.links.iter_mut().enumerate() {
            if group[i] == root_group || link.mass >= MIN_BODY_MASS_KG {
                continue;
            }
            if let Some(properties) = from_geometry(link, density) {
                link.mass = properties.mass();
                link.center_of_mass = Point3::from(from_vec(&properties.local_com));
                link.inertia = from_matrix(&properties.reconstruct_inertia_matrix());
                computed.push(link.name.clone());
            }
        }
    }
    // A moving rigid group without mass, named by its links.
    let mut massless: Vec<usize> = Vec::new();
    for (i, _) in tree.links.iter().enumerate() {
        if group[i] == i && i != tree.root && group_mass(tree, &group, i) < MIN_BODY_MASS_KG {
            massless.push(i);
        }
    }
    let Some(&first) = massless.first() else {
        return Ok(computed);
    };
    let describe = |i: usize| {
        let l: &Link = &tree.links[i];
        let line = l
            .place
            .map_or(String::new(), |p| format!(" (line {})", p.line));
        let meshes = l
            .solids
            .iter()
            .any(|s| matches!(s.shape, SolidShape::Mesh { .. }));
        let why = if density.is_none() {
            ""
        } else if l.solids.is_empty() {
            ": it has no geometry"
        } else if meshes {
            ": its geometry is a mesh, whose volume cncsim does not compute"
        } else {
            ""
        };
        format!("'{}'{line}{why}", l.name)
    };
    let names: Vec<String> = massless.iter().map(|&i| describe(i)).collect();
    let remedy = match density {
        None => format!(
            "Give each an <inertial> with a positive mass, or add `inertia_from_geometry = {{ density_kg_m3 = 2700.0 }}` to {} to compute them from their geometry",
            drives_path.display()
        ),
        Some(_) => "Give each an <inertial> with a positive mass, or a box, cylinder or sphere collision geometry".into(),
    };
    Err(FileError::new(
        &tree.path,
        tree.links[first].place,
        format!(
            "{} moving link{} {} no mass (less than {MIN_BODY_MASS_KG:?} kg with the links fixed to {}), and the physics cannot move a massless body: {}. {remedy}",
            massless.len(),
            if massless.len() == 1 { "" } else { "s" },
            if massless.len() == 1 { "has" } else { "have" },
            if massless.len() == 1 { "it" } else { "them" },
            names.join(", ")
        ),
    ))
}

/// Per link, the link whose rigid group carries it: links on fixed joints move with their
/// parent (joints are ordered parents first).
fn rigid_groups(tree: &KinematicTree) -> Vec<usize> {
    let mut group: Vec<usize> = (0..tree.links.len()).collect();
    for joint in tree.joints.iter().filter(|j| j.kind == JointKind::Fixed) {
        group[joint.child] = group[joint.parent];
    }
    group
}

fn group_mass(tree: &KinematicTree, group: &[usize], carrier: usize) -> f64 {
    tree.links
        .iter()
        .enumerate()
        .filter(|(i, _)| group[*i] == carrier)
        .map(|(_, l)| l.mass)
        .sum()
}

/// Mass properties of a link's solids at `density` (in the link frame), if it has any solid
/// with a volume cncsim can compute (a mesh has none here).
fn from_geometry(link: &Link, density: f64) -> Option<MassProperties> {
    let mut total: Option<MassProperties> = None;
    for solid in &link.solids {
        let own = match &solid.shape {
            SolidShape::Box { half_extents } => {
                MassProperties::from_cuboid(density, to_vec(half_extents))
            }
            // parry's cylinder stands along y, URDF's along z: turned about x.
            SolidShape::Cylinder { radius, length } => {
                let z_up = nalgebra::Isometry3::rotation(
                    nalgebra::Vector3::x() * std::f64::consts::FRAC_PI_2,
                );
                MassProperties::from_cylinder(density, length / 2.0, *radius)
                    .transform_by(&to_pose(&z_up))
            }
            SolidShape::Sphere { radius } => MassProperties::from_ball(density, *radius),
            SolidShape::Mesh { .. } => continue,
        };
        let placed = own.transform_by(&to_pose(&solid.pose));
        *total.get_or_insert(MassProperties::default()) += placed;
    }
    total.filter(|p| p.mass() > 0.0)
}

fn from_matrix(m: &parry3d_f64::math::Matrix) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| m.col(c)[r])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::{Solid, SolidShape};
    use nalgebra::{Isometry3, Vector3};

    fn link(solids: Vec<Solid>) -> Link {
        Link {
            name: "l".into(),
            mass: 0.0,
            center_of_mass: Point3::origin(),
            inertia: Matrix3::zeros(),
            visuals: Vec::new(),
            solids,
            place: None,
        }
    }

    /// A box and a z cylinder against their closed forms, the cylinder's offset by the
    /// parallel-axis theorem.
    #[test]
    fn primitives_match_their_closed_forms() {
        let rho = 2700.0;
        let b = link(vec![Solid {
            pose: Isometry3::identity(),
            shape: SolidShape::Box {
                half_extents: Vector3::new(0.1, 0.2, 0.3),
            },
        }]);
        let p = from_geometry(&b, rho).unwrap();
        let m = rho * 0.2 * 0.4 * 0.6;
        assert!((p.mass() - m).abs() < 1e-9 * m);
        let i = from_matrix(&p.reconstruct_inertia_matrix());
        let expected = [
            m * (0.4f64.powi(2) + 0.6f64.powi(2)) / 12.0,
            m * (0.2f64.powi(2) + 0.6f64.powi(2)) / 12.0,
            m * (0.2f64.powi(2) + 0.4f64.powi(2)) / 12.0,
        ];
        for k in 0..3 {
            assert!((i[(k, k)] - expected[k]).abs() < 1e-9 * expected[k], "{i}");
        }

        let (r, h, dx) = (0.05, 0.4, 0.3);
        let c = link(vec![Solid {
            pose: Isometry3::translation(dx, 0.0, 0.0),
            shape: SolidShape::Cylinder {
                radius: r,
                length: h,
            },
        }]);
        let p = from_geometry(&c, rho).unwrap();
        let m = rho * std::f64::consts::PI * r * r * h;
        assert!((p.mass() - m).abs() < 1e-9 * m);
        assert!((p.local_com.x - dx).abs() < 1e-12);
        let i = from_matrix(&p.reconstruct_inertia_matrix());
        let axial = m * r * r / 2.0;
        let transverse = m * (3.0 * r * r + h * h) / 12.0;
        assert!(
            (i[(2, 2)] - axial).abs() < 1e-9 * axial,
            "about z (the axis): {i}"
        );
        assert!((i[(0, 0)] - transverse).abs() < 1e-9 * transverse, "{i}");
        assert!((i[(1, 1)] - transverse).abs() < 1e-9 * transverse, "{i}");
    }

    #[test]
    fn a_mesh_alone_gives_no_mass() {
        let l = link(vec![Solid {
            pose: Isometry3::identity(),
            shape: SolidShape::Mesh {
                filename: "a.stl".into(),
            },
        }]);
        assert!(from_geometry(&l, 1000.0).is_none());
    }
}
