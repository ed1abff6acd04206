//! Mesh files (STL binary and ASCII, OBJ, COLLADA) read into plain triangle data, the URDF
//! `scale` applied, bounded in size. STL and OBJ are read by `mesh-loader`, COLLADA by
//! `collada.rs` (which says how its units and axes are taken).

use super::collada::read_collada;
use super::visual::TriangleMesh;
use quick_xml::events::Event;
use quick_xml::Reader;
use std::path::Path;

/// Largest mesh file read (bytes): above any machine part's mesh, a bound on memory and time.
pub const MAX_MESH_FILE_BYTES: u64 = 200 << 20;
/// Most triangles one mesh may have: a detailed machine part has some 10⁵; millions slow the
/// viewer down without showing more.
pub const MAX_MESH_TRIANGLES: usize = 4_000_000;
/// Deepest COLLADA element nesting read (real files are some ten deep; nested nodes are read
/// by recursion).
const MAX_COLLADA_DEPTH: usize = 256;

/// Triangles of one part of a file, before the URDF scale.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Part {
    pub vertices: Vec<[f32; 3]>,
    /// One per vertex, or none.
    pub normals: Vec<[f32; 3]>,
    pub faces: Vec<[u32; 3]>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Stl,
    Obj,
    Collada,
}

/// Reads the mesh at `path` (the format from its extension), scaled by `scale` (the URDF's,
/// applied in the mesh's frame). The error says what is wrong with the file.
pub fn read_mesh(path: &Path, scale: [f64; 3]) -> Result<TriangleMesh, String> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let format = match extension.as_str() {
        "stl" => Format::Stl,
        "obj" => Format::Obj,
        "dae" => Format::Collada,
        other => {
            return Err(format!(
                "the format '.{other}' is not read (expected .stl, .obj or .dae)"
            ))
        }
    };
    let size = std::fs::metadata(path)
        .map_err(|e| format!("cannot read it: {e}"))?
        .len();
    if size > MAX_MESH_FILE_BYTES {
        return Err(format!(
            "it has {size} bytes, more than the {} MiB a mesh file may have",
            MAX_MESH_FILE_BYTES >> 20
        ));
    }
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read it: {e}"))?;
    decode(&bytes, path, format, scale)
}

fn decode(
    bytes: &[u8],
    path: &Path,
    format: Format,
    scale: [f64; 3],
) -> Result<TriangleMesh, String> {
    let parts = match format {
        Format::Collada => {
            check_collada_depth(bytes)?;
            read_collada(bytes).map_err(|e| format!("not a usable COLLADA file: {e}"))?
        }
        Format::Stl | Format::Obj => {
            if format == Format::Stl {
                check_binary_stl_size(bytes)?;
            }
            // A binary STL whose 80-byte header starts with "solid" (many exporters write
            // one) reads as ASCII to a reader that looks at that word; its size tells: 84
            // bytes and 50 per triangle. The header is free text, so it is blanked.
            let unheaded;
            let bytes = if format == Format::Stl && is_binary_stl_headed_solid(bytes) {
                let mut copy = bytes.to_vec();
                copy[..5].copy_from_slice(b"     ");
                unheaded = copy;
                &unheaded[..]
            } else {
                bytes
            };
            let loader = mesh_loader::Loader::default();
            // The STL and OBJ readers return errors for bad files; a panic all the same would
            // be a bad file too, not a reason to stop loading the machine.
            let scene = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                if format == Format::Stl {
                    loader.load_stl_from_slice(bytes, path)
                } else {
                    // OBJ materials (.mtl) are not read: the URDF gives the colour.
                    loader.load_obj_from_slice_with_reader(bytes, path, |_| {
                        Err(std::io::Error::other("materials are not read"))
                    })
                }
            }))
            .map_err(|_| format!("the {} reader gave up on it", name(format)))?
            .map_err(|e| {
                format!(
                    "not a valid {} file: {}",
                    name(format),
                    one_line(&e.to_string())
                )
            })?;
            scene
                .meshes
                .into_iter()
                .map(|m| Part {
                    vertices: m.vertices,
                    normals: m.normals,
                    faces: m.faces,
                })
                .collect()
        }
    };
    triangle_mesh(parts, path, scale)
}

/// A binary STL (its size is 84 bytes plus 50 per the triangles its header counts) whose
/// header begins with the word that opens an ASCII one.
fn is_binary_stl_headed_solid(bytes: &[u8]) -> bool {
    bytes.len() >= 84 && bytes.starts_with(b"solid") && {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        84 + 50 * count == bytes.len() as u64
    }
}

fn name(format: Format) -> &'static str {
    match format {
        Format::Stl => "STL",
        Format::Obj => "OBJ",
        Format::Collada => "COLLADA",
    }
}

/// A binary STL's size gives its triangle count; an ASCII one ("solid …") cannot hold more
/// than the bound in the largest file read.
fn check_binary_stl_size(bytes: &[u8]) -> Result<(), String> {
    let ascii = bytes.trim_ascii_start().starts_with(b"solid");
    check_stl_triangles(ascii, bytes.len())
}

fn check_stl_triangles(ascii: bool, len: usize) -> Result<(), String> {
    // 80-byte header, a count, 50 bytes a triangle.
    let triangles = len.saturating_sub(84) / 50;
    if !ascii && triangles > MAX_MESH_TRIANGLES {
        return Err(format!(
            "it holds {triangles} triangles, more than the {MAX_MESH_TRIANGLES} a mesh may have"
        ));
    }
    Ok(())
}

/// Bounds a COLLADA file's nesting before the reader (whose node walk recurses) sees it.
fn check_collada_depth(bytes: &[u8]) -> Result<(), String> {
    let mut reader = Reader::from_reader(bytes);
    let mut buf = Vec::new();
    let mut depth = 0usize;
    loop {
        let at = reader.buffer_position();
        match reader.read_event_into(&mut buf) {
            Ok(Event::Start(_)) => {
                depth += 1;
                if depth > MAX_COLLADA_DEPTH {
                    return Err(format!(
                        "elements nested more than {MAX_COLLADA_DEPTH} deep (at byte {at})"
                    ));
                }
            }
            Ok(Event::End(_)) => depth = depth.saturating_sub(1),
            Ok(Event::Eof) => return Ok(()),
            Ok(_) => {}
            Err(e) => {
                return Err(format!(
                    "not well-formed XML at byte {}: {e}",
                    reader.error_position()
                ))
            }
        }
        buf.clear();
    }
}

/// The meshes of a file as one, scaled, checked.
fn triangle_mesh(meshes: Vec<Part>, path: &Path, scale: [f64; 3]) -> Result<TriangleMesh, String> {
    let n_vertices: usize = meshes.iter().map(|m| m.vertices.len()).sum();
    let n_triangles: usize = meshes.iter().map(|m| m.faces.len()).sum();
    if n_triangles > MAX_MESH_TRIANGLES {
        return Err(format!(
            "it holds {n_triangles} triangles, more than the {MAX_MESH_TRIANGLES} a mesh may have"
        ));
    }
    if n_triangles == 0 {
        return Err("it holds no triangles".into());
    }
    if u32::try_from(n_vertices).is_err() {
        return Err(format!("it holds {n_vertices} vertices: too many to index"));
    }
    // Normals only where every vertex has one (a file may give them for some parts only).
    let with_normals = meshes.iter().all(|m| m.normals.len() == m.vertices.len());
    let mut vertices = Vec::with_capacity(n_vertices);
    let mut normals = Vec::with_capacity(if with_normals { n_vertices } else { 0 });
    let mut triangles = Vec::with_capacity(n_triangles);
    // A mirroring scale turns the faces inside out: swapping two corners turns them back.
    let mirrored = scale[0] * scale[1] * scale[2] < 0.0;
    for m in &meshes {
        let first = vertices.len() as u32;
        for (i, v) in m.vertices.iter().enumerate() {
            let p = [0, 1, 2].map(|k| (f64::from(v[k]) * scale[k]) as f32);
            if !p.iter().all(|x| x.is_finite()) {
                return Err(format!(
                    "vertex {} is {v:?}: expected finite coordinates",
                    first as usize + i
                ));
            }
            vertices.push(p);
        }
        if with_normals {
            // Normals transform by the inverse transpose of the scale.
            normals.extend(m.normals.iter().map(|n| {
                let s = [0, 1, 2].map(|k| f64::from(n[k]) / scale[k]);
                let norm = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
                s.map(|x| (x / norm) as f32)
            }));
        }
        for f in &m.faces {
            if let Some(bad) = f.iter().find(|&&k| k as usize >= m.vertices.len()) {
                return Err(format!(
                    "a triangle refers to vertex {bad} of a part with {} vertices",
                    m.vertices.len()
                ));
            }
            let [a, b, c] = f.map(|k| k + first);
            triangles.push(if mirrored { [a, c, b] } else { [a, b, c] });
        }
    }
    // Zero normals (some STL exporters write them) would shade black: let the viewer make its
    // own.
    let normals =
        (with_normals && normals.iter().flatten().all(|x| x.is_finite())).then_some(normals);
    Ok(TriangleMesh {
        source: path.to_path_buf(),
        vertices,
        triangles,
        normals,
    })
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// A unit tetrahedron (corners at the origin and on the three axes), faces outward.
    const TETRA: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    const TETRA_FACES: [[usize; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

    pub(crate) fn binary_stl() -> Vec<u8> {
        let mut out = vec![0u8; 80];
        out.extend_from_slice(&(TETRA_FACES.len() as u32).to_le_bytes());
        for f in TETRA_FACES {
            for x in [0.0f32; 3] {
                out.extend_from_slice(&x.to_le_bytes()); // normal: left for the reader
            }
            for k in f {
                for x in TETRA[k] {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
            out.extend_from_slice(&[0, 0]);
        }
        out
    }

    fn ascii_stl() -> String {
        let mut s = String::from("solid tetra\n");
        for f in TETRA_FACES {
            s += "  facet normal 0 0 0\n    outer loop\n";
            for k in f {
                let [x, y, z] = TETRA[k];
                s += &format!("      vertex {x} {y} {z}\n");
            }
            s += "    endloop\n  endfacet\n";
        }
        s + "endsolid tetra\n"
    }

    fn obj() -> String {
        let mut s = String::from("# tetrahedron\n");
        for [x, y, z] in TETRA {
            s += &format!("v {x} {y} {z}\n");
        }
        s += "vn 0 0 1\n";
        // One quad (two triangles' worth of the same face plane is fine for a count) and 1-based
        // indices with normals.
        s += "f 1//1 3//1 2//1\nf 1//1 2//1 4//1\nf 1//1 4//1 3//1\nf 2//1 3//1 4//1\n";
        s
    }

    /// A COLLADA file in millimetres holding the tetrahedron scaled by 1000 (so 1 m edges),
    /// under a node moved 2 units along x and a child node 3 units along y.
    pub(crate) fn collada() -> String {
        let positions: Vec<String> = TETRA
            .iter()
            .flatten()
            .map(|x| format!("{}", x * 1000.0))
            .collect();
        let indices: Vec<String> = TETRA_FACES
            .iter()
            .flatten()
            .map(|k| k.to_string())
            .collect();
        format!(
            r##"<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="millimeter" meter="0.001"/><up_axis>Y_UP</up_axis></asset>
  <library_geometries>
    <geometry id="tetra" name="tetra">
      <mesh>
        <source id="tetra-pos">
          <float_array id="tetra-pos-array" count="12">{}</float_array>
          <technique_common>
            <accessor source="#tetra-pos-array" count="4" stride="3">
              <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
            </accessor>
          </technique_common>
        </source>
        <vertices id="tetra-vtx"><input semantic="POSITION" source="#tetra-pos"/></vertices>
        <triangles count="4"><input semantic="VERTEX" source="#tetra-vtx" offset="0"/><p>{}</p></triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="scene">
      <node id="outer"><translate>2000 0 0</translate>
        <node id="inner"><translate>0 3000 0</translate>
          <instance_geometry url="#tetra"/>
        </node>
      </node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"##,
            positions.join(" "),
            indices.join(" ")
        )
    }

    fn read(name: &str, bytes: &[u8], scale: [f64; 3]) -> Result<TriangleMesh, String> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        read_mesh(&path, scale)
    }

    fn bounds(m: &TriangleMesh) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for v in &m.vertices {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        (lo, hi)
    }

    #[test]
    fn a_binary_stl_whose_header_says_solid_reads_as_binary() {
        let mut bytes = binary_stl();
        bytes[..12].copy_from_slice(b"solid foot  ");
        let mesh = decode(&bytes, Path::new("foot.stl"), Format::Stl, [1.0; 3]).unwrap();
        let plain = decode(&binary_stl(), Path::new("foot.stl"), Format::Stl, [1.0; 3]).unwrap();
        assert_eq!(mesh.triangles.len(), TETRA_FACES.len());
        assert_eq!(mesh.vertices, plain.vertices);
    }

    #[test]
    fn binary_and_ascii_stl_read_the_same_triangles_scaled() {
        let scale = [0.001, 0.002, 0.003];
        for (name, bytes) in [("a.stl", binary_stl()), ("b.STL", ascii_stl().into_bytes())] {
            let m = read(name, &bytes, scale).unwrap();
            assert_eq!(m.triangles.len(), 4, "{name}");
            assert_eq!(m.vertices.len(), 12, "{name}");
            assert_eq!(bounds(&m), ([0.0; 3], [0.001, 0.002, 0.003]), "{name}");
            // Zero normals in the file: none kept.
            assert!(m.normals.is_none(), "{name}");
        }
    }

    #[test]
    fn obj_reads_with_its_normals_and_a_mirroring_scale_keeps_faces_outward() {
        let m = read("t.obj", obj().as_bytes(), [1.0, 1.0, 1.0]).unwrap();
        assert_eq!(m.triangles.len(), 4);
        let normals = m.normals.as_ref().expect("the file gives normals");
        assert_eq!(normals.len(), m.vertices.len());
        let first = m.triangles[0];
        let mirrored = read("t.obj", obj().as_bytes(), [-1.0, 1.0, 1.0]).unwrap();
        assert_eq!(mirrored.triangles[0], [first[0], first[2], first[1]]);
        assert_eq!(bounds(&mirrored), ([-1.0, 0.0, 0.0], [0.0, 1.0, 1.0]));
    }

    #[test]
    fn collada_applies_its_unit_and_node_transforms_and_ignores_up_axis() {
        let m = read("t.dae", collada().as_bytes(), [1.0, 1.0, 2.0]).unwrap();
        assert_eq!(m.triangles.len(), 4);
        // 1 mm units: the 1000-unit tetrahedron is 1 m; the nodes move it by (2, 3, 0) m; Y_UP
        // turns nothing; the URDF scale doubles z.
        assert_eq!(bounds(&m), ([2.0, 3.0, 0.0], [3.0, 4.0, 2.0]));
    }

    #[test]
    fn damaged_files_of_every_format_give_a_mesh_or_an_error() {
        let files = [
            (Format::Stl, binary_stl()),
            (Format::Stl, ascii_stl().into_bytes()),
            (Format::Obj, obj().into_bytes()),
            (Format::Collada, collada().into_bytes()),
        ];
        let path = Path::new("damaged");
        for (format, good) in files {
            for cut in (0..good.len()).step_by(5) {
                let _ = decode(&good[..cut], path, format, [1.0; 3]);
            }
            for at in (0..good.len()).step_by(3) {
                for b in *b"<>\"9-.#/ xe\0" {
                    let mut bad = good.clone();
                    bad[at] = b;
                    let _ = decode(&bad, path, format, [1.0; 3]);
                }
            }
        }
    }

    #[test]
    fn bad_files_are_errors_that_say_what_is_wrong() {
        let e = read("x.ply", b"ply\n", [1.0; 3]).unwrap_err();
        assert!(e.contains("'.ply' is not read"), "{e}");
        let e = read("x.stl", b"not an stl at all", [1.0; 3]).unwrap_err();
        assert!(e.starts_with("not a valid STL file"), "{e}");
        let e = read("x.obj", b"v 0 0 0\nf 1 2 3\n", [1.0; 3]).unwrap_err();
        assert!(e.starts_with("not a valid OBJ file"), "{e}");
        let e = read("x.obj", b"# nothing\n", [1.0; 3]).unwrap_err();
        assert_eq!(e, "it holds no triangles");
        // A truncated COLLADA file, one with an index past its positions, absurd counts, deep
        // nesting: errors, no panic, no huge allocation.
        let full = collada();
        let e = read("x.dae", &full.as_bytes()[..full.len() / 2], [1.0; 3]).unwrap_err();
        assert!(!e.is_empty());
        let past = full.replace("<p>0 2 1", "<p>0 2 99");
        assert!(read("x.dae", past.as_bytes(), [1.0; 3]).is_err());
        let huge = full.replace("count=\"4\" stride", "count=\"4000000000\" stride");
        let e = read("x.dae", huge.as_bytes(), [1.0; 3]).unwrap_err();
        assert!(e.contains("reads 4000000000 vectors"), "{e}");
        let deep = format!(
            "<COLLADA version=\"1.4.1\">{}{}</COLLADA>",
            "<node>".repeat(100_000),
            "</node>".repeat(100_000)
        );
        let e = read("x.dae", deep.as_bytes(), [1.0; 3]).unwrap_err();
        assert!(e.contains("nested more than"), "{e}");
        // A binary STL claiming (by its size) more triangles than read.
        let e = check_stl_triangles(false, 84 + 50 * (MAX_MESH_TRIANGLES + 1)).unwrap_err();
        assert!(e.contains("more than the"), "{e}");
        assert!(check_stl_triangles(false, 84 + 50 * MAX_MESH_TRIANGLES).is_ok());
    }
}
