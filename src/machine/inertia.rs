//! Every link a joint moves must carry mass: the physics cannot accelerate a massless body.
//! All such links are reported at once, located in the URDF; with `inertia_from_geometry` in
//! the drive file, the masses and inertias the URDF leaves out are computed from the links'
//! geometry at a uniform density (as MuJoCo's `inertiafromgeom` does), with parry's mass
//! properties of each solid: boxes, cylinders, spheres, and closed meshes by their volume.

use super::mesh::read_mesh;
use super::mesh_path::{package_search_roots, MeshFiles};
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
    // Why a link's geometry gave no mass, for the error below.
    let mut no_mass_why: Vec<Option<String>> = vec![None; tree.links.len()];
    if let Some(density) = density {
        let mut files = MeshFiles::new(&tree.path, package_search_roots(&[]));
        let mut hulls = Vec::new();
        for (i, link) in tree.links.iter_mut().enumerate() {
            if group[i] == root_group || link.mass >= MIN_BODY_MASS_KG {
                continue;
            }
            let mut open_meshes = Vec::new();
            let found = from_geometry(link, density, &mut files, &mut open_meshes);
            for mesh in open_meshes {
                hulls.push(FileError::new(
                    &tree.path,
                    link.place,
                    format!(
                        "link '{}': mesh {} is not closed (an edge not shared by exactly two triangles), so it encloses no volume: its mass is that of its convex hull",
                        link.name,
                        mesh.display()
                    ),
                ));
            }
            match found {
                Ok(properties) => {
                    link.mass = properties.mass();
                    link.center_of_mass = Point3::from(from_vec(&properties.local_com));
                    link.inertia = from_matrix(&properties.reconstruct_inertia_matrix());
                    computed.push(link.name.clone());
                }
                Err(why) => no_mass_why[i] = Some(why),
            }
        }
        tree.warnings.extend(hulls);
    }
    // A moving rigid group with no mass in it or beyond it, named by its links. (A massless
    // frame between two joints with mass beyond is fine in reduced coordinates; whether the
    // chain as a whole is singular is the dynamics model's check.)
    let beyond = mass_beyond(tree);
    let mut massless: Vec<usize> = Vec::new();
    for (i, _) in tree.links.iter().enumerate() {
        if group[i] == i && i != tree.root && beyond[i] < MIN_BODY_MASS_KG {
            massless.push(i);
        }
    }
    // Asked for masses from geometry, a link that got none (a mesh not found) is said even
    // where the mass beyond it lets it stay massless.
    for (i, why) in no_mass_why.iter().enumerate() {
        if let Some(why) = why.as_ref().filter(|_| !massless.contains(&i)) {
            let link = &tree.links[i];
            tree.warnings.push(FileError::new(
                &tree.path,
                link.place,
                format!(
                    "link '{}': inertia_from_geometry gives it no mass ({why}): it stays massless, the links beyond it carrying the mass",
                    link.name
                ),
            ));
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
        let why = no_mass_why[i]
            .as_ref()
            .map_or(String::new(), |w| format!(": {w}"));
        format!("'{}'{line}{why}", l.name)
    };
    let names: Vec<String> = massless.iter().map(|&i| describe(i)).collect();
    let remedy = match density {
        None => format!(
            "Give each an <inertial> with a positive mass, or add `inertia_from_geometry = {{ density_kg_m3 = 2700.0 }}` to {} to compute them from their geometry",
            drives_path.display()
        ),
        Some(_) => "Give each an <inertial> with a positive mass, or collision geometry with a volume".into(),
    };
    Err(FileError::new(
        &tree.path,
        tree.links[first].place,
        format!(
            "{} moving link{} {} no mass (less than {MIN_BODY_MASS_KG:?} kg with every link {}), and the physics cannot move a massless body: {}. {remedy}",
            massless.len(),
            if massless.len() == 1 { "" } else { "s" },
            if massless.len() == 1 { "has" } else { "have" },
            if massless.len() == 1 { "it carries" } else { "they carry" },
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

/// Per link, its mass and that of every link beyond it (joints are ordered parents first).
fn mass_beyond(tree: &KinematicTree) -> Vec<f64> {
    let mut beyond: Vec<f64> = tree.links.iter().map(|l| l.mass).collect();
    for joint in tree.joints.iter().rev() {
        beyond[joint.parent] += beyond[joint.child];
    }
    beyond
}

/// Mass properties of a link's solids at `density` (in the link frame), or why there are none.
/// Open meshes are weighed by their convex hull, and pushed to `open_meshes`.
fn from_geometry(
    link: &Link,
    density: f64,
    files: &mut MeshFiles,
    open_meshes: &mut Vec<std::path::PathBuf>,
) -> Result<MassProperties, String> {
    if link.solids.is_empty() {
        return Err("it has no geometry".into());
    }
    let mut total = MassProperties::default();
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
            SolidShape::Mesh { filename, scale } => {
                mesh_mass(filename, *scale, density, files, open_meshes)?
            }
        };
        total += own.transform_by(&to_pose(&solid.pose));
    }
    Ok(total)
}

/// A closed mesh's mass properties by its enclosed volume (parry: divergence theorem over its
/// triangles, so it must be closed and face outwards); an open one's by its convex hull (as
/// MuJoCo weighs meshes), its path pushed to `open_meshes` for a warning.
fn mesh_mass(
    filename: &str,
    scale: [f64; 3],
    density: f64,
    files: &mut MeshFiles,
    open_meshes: &mut Vec<std::path::PathBuf>,
) -> Result<MassProperties, String> {
    let path = files.resolve(filename)?;
    let mesh = read_mesh(&path, scale).map_err(|e| format!("mesh {}: {e}", path.display()))?;
    let vertices: Vec<parry3d_f64::math::Vector> = mesh
        .vertices
        .iter()
        .map(|v| parry3d_f64::math::Vector::new(v[0].into(), v[1].into(), v[2].into()))
        .collect();
    let properties = if is_closed(&mesh.vertices, &mesh.triangles) {
        MassProperties::from_trimesh(density, &vertices, &mesh.triangles)
    } else {
        let (hull, faces) =
            parry3d_f64::transformation::try_convex_hull(&vertices).map_err(|e| {
                format!(
                "mesh {} is not closed, and its points span no volume for a convex hull ({e:?})",
                path.display()
            )
            })?;
        open_meshes.push(path.clone());
        MassProperties::from_convex_polyhedron(density, &hull, &faces)
    };
    let mass = properties.mass();
    if mass.is_finite() && mass > 0.0 {
        Ok(properties)
    } else {
        Err(format!(
            "mesh {} encloses no volume (it must be closed, its faces outwards)",
            path.display()
        ))
    }
}

/// Whether every edge of the mesh is shared by exactly two triangles, vertices at the same
/// place counted as one (STL repeats them per triangle).
fn is_closed(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> bool {
    use std::collections::HashMap;
    let mut id: HashMap<[u32; 3], u32> = HashMap::new();
    let ids: Vec<u32> = vertices
        .iter()
        .map(|v| {
            let next = id.len() as u32;
            *id.entry(v.map(f32::to_bits)).or_insert(next)
        })
        .collect();
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (ids[t[k] as usize], ids[t[(k + 1) % 3] as usize]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    !triangles.is_empty() && edges.values().all(|&n| n == 2)
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
        let mut files = MeshFiles::new(std::path::Path::new("m.urdf"), Vec::new());
        let p = from_geometry(&b, rho, &mut files, &mut Vec::new()).unwrap();
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
        let p = from_geometry(&c, rho, &mut files, &mut Vec::new()).unwrap();
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

    /// A unit-less cube as an OBJ, scaled to 0.2 × 0.4 × 0.6 m: the box's closed form.
    #[test]
    fn a_closed_mesh_weighs_as_its_volume_and_an_open_one_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let corners = (0..8)
            .map(|i| {
                let c = |bit| if i & bit == 0 { -0.5 } else { 0.5 };
                format!("v {} {} {}\n", c(1), c(2), c(4))
            })
            .collect::<String>();
        // Outward faces, counter-clockwise seen from outside (OBJ indices from 1).
        let faces = [
            [1, 3, 4, 2],
            [5, 6, 8, 7],
            [1, 2, 6, 5],
            [3, 7, 8, 4],
            [1, 5, 7, 3],
            [2, 4, 8, 6],
        ];
        let mut closed = corners.clone();
        for f in faces {
            closed += &format!(
                "f {} {} {}\nf {} {} {}\n",
                f[0], f[1], f[2], f[0], f[2], f[3]
            );
        }
        std::fs::write(dir.path().join("cube.obj"), &closed).unwrap();
        let open = closed.lines().take(8 + 10).collect::<Vec<_>>().join("\n") + "\n";
        std::fs::write(dir.path().join("open.obj"), open).unwrap();
        let urdf = dir.path().join("m.urdf");
        let mut files = MeshFiles::new(&urdf, Vec::new());
        let mesh = |name: &str| {
            link(vec![Solid {
                pose: Isometry3::translation(0.0, 0.0, 0.1),
                shape: SolidShape::Mesh {
                    filename: name.into(),
                    scale: [0.2, 0.4, 0.6],
                },
            }])
        };
        let rho = 7850.0;
        let mut open_meshes = Vec::new();
        let p = from_geometry(&mesh("cube.obj"), rho, &mut files, &mut open_meshes).unwrap();
        assert!(open_meshes.is_empty());
        let m = rho * 0.2 * 0.4 * 0.6;
        assert!((p.mass() - m).abs() < 1e-6 * m, "{} kg", p.mass());
        assert!((p.local_com.z - 0.1).abs() < 1e-6);
        let i = from_matrix(&p.reconstruct_inertia_matrix());
        let ixx = m * (0.4f64.powi(2) + 0.6f64.powi(2)) / 12.0;
        assert!((i[(0, 0)] - ixx).abs() < 1e-5 * ixx, "{i}");
        // Two faces missing: weighed by its convex hull (the whole box), and named.
        let p = from_geometry(&mesh("open.obj"), rho, &mut files, &mut open_meshes).unwrap();
        assert!((p.mass() - m).abs() < 1e-6 * m, "{} kg", p.mass());
        assert!(open_meshes.len() == 1 && open_meshes[0].ends_with("open.obj"));
        let e = from_geometry(&link(Vec::new()), rho, &mut files, &mut open_meshes).unwrap_err();
        assert_eq!(e, "it has no geometry");
    }
}
