//! COLLADA (`.dae`) meshes: the triangles of the geometries the scene instances, placed by the
//! scene's node transforms and scaled to metres by `<asset><unit meter="…">`.
//!
//! As RViz, Gazebo and DART show URDF meshes: `<unit>` and the node transforms apply;
//! `<up_axis>` is ignored (RViz drops the root rotation assimp makes for it, and the meshes of
//! ROS packages are drawn for that: a `Z_UP` and a `Y_UP` export of a part look the same in
//! RViz). MuJoCo and Drake read no COLLADA. Read here rather than by `mesh-loader`, whose
//! COLLADA reader composes nested node transforms in the reverse order, leaves their
//! translations out of the unit scaling, and panics on some malformed files.
//!
//! Read: `<triangles>`, `<polylist>` and `<polygons>` (fanned into triangles), positions and
//! normals; `<matrix>`, `<translate>`, `<rotate>`, `<scale>`; `<instance_geometry>`,
//! `<instance_node>`. Not read: lines, strips, textures, materials (the URDF gives the
//! colour), skinning. The caller has bounded the nesting depth and the file size.

use super::mesh::{Part, MAX_MESH_TRIANGLES};
use nalgebra::{Matrix3, Matrix4, Point3, Unit, Vector3};
use roxmltree::{Document, Node};
use std::collections::HashMap;

/// Deepest chain of `<instance_node>` references followed (a cycle would be endless).
const MAX_INSTANCE_DEPTH: usize = 64;
/// Most nodes visited: nodes that instance others twice over, level after level, multiply.
const MAX_NODE_VISITS: usize = 100_000;
/// Largest input offset of a primitive (real files use 0 to 3; it sets the index stride).
const MAX_INPUT_OFFSET: usize = 64;

/// The triangles of a COLLADA document, in metres, in the file's root frame.
pub(super) fn read_collada(bytes: &[u8]) -> Result<Vec<Part>, String> {
    let text = std::str::from_utf8(bytes).map_err(|e| format!("not UTF-8 text: {e}"))?;
    let doc = Document::parse(text).map_err(|e| format!("not well-formed XML: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "COLLADA" {
        return Err(format!(
            "the root element is <{}>: expected <COLLADA>",
            root.tag_name().name()
        ));
    }
    let ids: HashMap<&str, Node> = root
        .descendants()
        .filter_map(|n| n.attribute("id").map(|id| (id, n)))
        .collect();
    let unit = match child(root, "asset")
        .and_then(|a| child(a, "unit"))
        .and_then(|u| u.attribute("meter"))
    {
        None => 1.0,
        Some(m) => match m.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => v,
            _ => return Err(format!("<unit meter=\"{m}\">: expected a positive number")),
        },
    };
    let mut reader = Reader {
        doc: &doc,
        ids,
        parts: Vec::new(),
        triangles: 0,
        visits: 0,
    };
    let scale = Matrix4::new_scaling(unit);
    // The scene the file names, else its first visual scene, else every geometry as it is.
    let scene = child(root, "scene")
        .and_then(|s| child(s, "instance_visual_scene"))
        .and_then(|i| i.attribute("url"))
        .map(|url| reader.target(url, "visual_scene"))
        .transpose()?
        .or_else(|| {
            root.descendants()
                .find(|n| n.tag_name().name() == "visual_scene")
        });
    match scene {
        Some(scene) => {
            for node in children(scene, "node") {
                reader.node(node, &scale, 0)?;
            }
        }
        None => {
            let geometries: Vec<Node> = root
                .descendants()
                .filter(|n| n.tag_name().name() == "geometry")
                .collect();
            for g in geometries {
                reader.geometry(g, &scale)?;
            }
        }
    }
    Ok(reader.parts)
}

struct Reader<'a, 'input> {
    doc: &'a Document<'input>,
    ids: HashMap<&'a str, Node<'a, 'input>>,
    parts: Vec<Part>,
    triangles: usize,
    visits: usize,
}

fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    n.children().find(|c| c.tag_name().name() == name)
}

fn children<'a, 'i>(n: Node<'a, 'i>, name: &'static str) -> impl Iterator<Item = Node<'a, 'i>> {
    n.children().filter(move |c| c.tag_name().name() == name)
}

fn numbers<T: std::str::FromStr>(n: Node, what: &str) -> Result<Vec<T>, String> {
    n.text()
        .unwrap_or("")
        .split_whitespace()
        .map(|t| {
            t.parse::<T>()
                .map_err(|_| format!("<{what}> holds \"{}\": expected numbers", clip(t)))
        })
        .collect()
}

fn clip(s: &str) -> String {
    s.chars().take(24).collect()
}

impl<'a, 'input> Reader<'a, 'input> {
    fn place(&self, n: Node) -> String {
        let p = self.doc.text_pos_at(n.range().start);
        format!("line {}, column {}", p.row, p.col)
    }

    /// The element a `#id` URL names, which must be a `<kind>`.
    fn target(&self, url: &str, kind: &str) -> Result<Node<'a, 'input>, String> {
        let id = url.strip_prefix('#').ok_or_else(|| {
            format!("the reference \"{url}\" is not to this file (expected \"#id\")")
        })?;
        match self.ids.get(id) {
            Some(n) if n.tag_name().name() == kind => Ok(*n),
            Some(n) => Err(format!(
                "\"{url}\" names a <{}> ({}): expected a <{kind}>",
                n.tag_name().name(),
                self.place(*n)
            )),
            None => Err(format!("\"{url}\" names no element of the file")),
        }
    }

    fn node(
        &mut self,
        node: Node<'a, 'input>,
        parent: &Matrix4<f64>,
        depth: usize,
    ) -> Result<(), String> {
        self.visits += 1;
        if self.visits > MAX_NODE_VISITS {
            return Err(format!(
                "the scene visits more than {MAX_NODE_VISITS} nodes (instanced over and over?)"
            ));
        }
        if depth > MAX_INSTANCE_DEPTH {
            return Err(format!(
                "nodes instanced more than {MAX_INSTANCE_DEPTH} deep ({}): a cycle?",
                self.place(node)
            ));
        }
        let mut m = *parent;
        for t in node.children().filter(|c| c.is_element()) {
            let name = t.tag_name().name();
            let local = match name {
                "matrix" | "translate" | "rotate" | "scale" => self.transform(t)?,
                _ => continue,
            };
            // Each transform acts in the frame the ones before it leave.
            m *= local;
        }
        for c in node.children().filter(|c| c.is_element()) {
            match c.tag_name().name() {
                "instance_geometry" => {
                    let url = c.attribute("url").unwrap_or("");
                    let g = self.target(url, "geometry")?;
                    self.geometry(g, &m)?;
                }
                "instance_node" => {
                    let url = c.attribute("url").unwrap_or("");
                    let n = self.target(url, "node")?;
                    self.node(n, &m, depth + 1)?;
                }
                "node" => self.node(c, &m, depth)?,
                _ => {}
            }
        }
        Ok(())
    }

    fn transform(&self, t: Node) -> Result<Matrix4<f64>, String> {
        let name = t.tag_name().name();
        let v: Vec<f64> = numbers(t, name)?;
        let expected = match name {
            "matrix" => 16,
            "rotate" => 4,
            _ => 3,
        };
        if v.len() != expected || !v.iter().all(|x| x.is_finite()) {
            return Err(format!(
                "<{name}> ({}) holds {} numbers: expected {expected} finite ones",
                self.place(t),
                v.len()
            ));
        }
        Ok(match name {
            // Row-major, column vectors (translation in the last column).
            "matrix" => Matrix4::from_row_slice(&v),
            "translate" => Matrix4::new_translation(&Vector3::new(v[0], v[1], v[2])),
            "rotate" => match Unit::try_new(Vector3::new(v[0], v[1], v[2]), 1e-12) {
                Some(axis) => Matrix4::from_axis_angle(&axis, v[3].to_radians()),
                None => Matrix4::identity(),
            },
            _ => Matrix4::new_nonuniform_scaling(&Vector3::new(v[0], v[1], v[2])),
        })
    }

    /// A `<geometry>`'s triangles, placed by `m`.
    fn geometry(&mut self, g: Node<'a, 'input>, m: &Matrix4<f64>) -> Result<(), String> {
        let Some(mesh) = child(g, "mesh") else {
            return Ok(()); // splines, convex meshes: nothing to draw as triangles
        };
        // Normals transform by the inverse transpose of the linear part.
        let linear: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
        let normal_map = linear.try_inverse().map(|i| i.transpose());
        for prim in mesh.children().filter(|c| c.is_element()) {
            let kind = prim.tag_name().name();
            if !matches!(kind, "triangles" | "polylist" | "polygons") {
                continue;
            }
            let part = self.primitive(prim)?;
            self.triangles += part.faces.len();
            if self.triangles > MAX_MESH_TRIANGLES {
                return Err(format!(
                    "it holds more than the {MAX_MESH_TRIANGLES} triangles a mesh may have (its geometries as the scene instances them)"
                ));
            }
            let vertices = part
                .vertices
                .iter()
                .map(|p| {
                    let q = m.transform_point(&Point3::from(p.map(f64::from)));
                    [q.x as f32, q.y as f32, q.z as f32]
                })
                .collect();
            let normals = match normal_map {
                Some(nm) => part
                    .normals
                    .iter()
                    .map(|n| {
                        let v = (nm * Vector3::from(n.map(f64::from))).normalize();
                        [v.x as f32, v.y as f32, v.z as f32]
                    })
                    .collect(),
                None => Vec::new(),
            };
            self.parts.push(Part {
                vertices,
                normals,
                faces: part.faces,
            });
        }
        Ok(())
    }

    /// One primitive's triangles, unindexed (three corners each), in the geometry's frame.
    fn primitive(&self, prim: Node<'a, 'input>) -> Result<Part, String> {
        let kind = prim.tag_name().name();
        let at = self.place(prim);
        let mut positions: Option<(usize, Vec<[f32; 3]>)> = None;
        let mut normals: Option<(usize, Vec<[f32; 3]>)> = None;
        let mut stride = 0usize;
        for input in children(prim, "input") {
            let offset = input.attribute("offset").unwrap_or("0");
            let offset = match offset.trim().parse::<usize>() {
                Ok(o) if o <= MAX_INPUT_OFFSET => o,
                _ => {
                    return Err(format!(
                        "an <input> of the <{kind}> at {at} has offset=\"{}\": expected 0 to {MAX_INPUT_OFFSET}",
                        clip(offset)
                    ))
                }
            };
            stride = stride.max(offset + 1);
            let source = input.attribute("source").unwrap_or("");
            match input.attribute("semantic") {
                Some("VERTEX") => {
                    let vertices = self.target(source, "vertices")?;
                    for vi in children(vertices, "input") {
                        let src = vi.attribute("source").unwrap_or("");
                        match vi.attribute("semantic") {
                            Some("POSITION") => positions = Some((offset, self.source(src)?)),
                            Some("NORMAL") => normals = Some((offset, self.source(src)?)),
                            _ => {}
                        }
                    }
                }
                Some("NORMAL") => normals = Some((offset, self.source(source)?)),
                _ => {}
            }
        }
        let Some((position_offset, points)) = positions else {
            return Err(format!("the <{kind}> at {at} has no vertex positions"));
        };
        // Corners per polygon.
        let p: Vec<u32> = children(prim, "p")
            .map(|n| numbers::<u32>(n, "p"))
            .collect::<Result<Vec<_>, _>>()?
            .concat();
        let counts: Vec<usize> = match kind {
            "triangles" => vec![3; p.len() / stride.max(1) / 3],
            "polylist" => match child(prim, "vcount") {
                Some(v) => numbers::<usize>(v, "vcount")?,
                None => Vec::new(),
            },
            // One <p> per polygon.
            _ => children(prim, "p")
                .map(|n| n.text().unwrap_or("").split_whitespace().count() / stride.max(1))
                .collect(),
        };
        let corners = counts
            .iter()
            .try_fold(0usize, |a, &b| a.checked_add(b))
            .unwrap_or(usize::MAX);
        if corners.checked_mul(stride) != Some(p.len()) {
            return Err(format!(
                "the <{kind}> at {at} has {} indices: expected {} ({} corners × {stride} inputs)",
                p.len(),
                corners.saturating_mul(stride),
                corners
            ));
        }
        let mut part = Part::default();
        let corner = |i: usize, offset: usize, values: &[[f32; 3]], what: &str| {
            let k = p[i * stride + offset] as usize;
            values.get(k).copied().ok_or_else(|| {
                format!(
                    "the <{kind}> at {at} refers to {what} {k} of {}",
                    values.len()
                )
            })
        };
        let mut first = 0usize;
        for &n in &counts {
            // A polygon of n corners is fanned from its first corner into n − 2 triangles.
            for j in 1..n.saturating_sub(1) {
                if part.vertices.len() / 3 >= MAX_MESH_TRIANGLES {
                    return Err(format!(
                        "it holds more than the {MAX_MESH_TRIANGLES} triangles a mesh may have"
                    ));
                }
                let base = part.vertices.len() as u32;
                for c in [first, first + j, first + j + 1] {
                    part.vertices
                        .push(corner(c, position_offset, &points, "position")?);
                    if let Some((offset, values)) = &normals {
                        part.normals.push(corner(c, *offset, values, "normal")?);
                    }
                }
                part.faces.push([base, base + 1, base + 2]);
            }
            first += n;
        }
        Ok(part)
    }

    /// A `<source>`'s 3-vectors, read through its accessor (stride, offset, count).
    fn source(&self, url: &str) -> Result<Vec<[f32; 3]>, String> {
        let source = self.target(url, "source")?;
        let at = self.place(source);
        let array = child(source, "float_array")
            .ok_or_else(|| format!("the <source> at {at} has no <float_array>"))?;
        let values: Vec<f32> = numbers(array, "float_array")?;
        let accessor = child(source, "technique_common").and_then(|t| child(t, "accessor"));
        let attr = |name: &str, default: usize| -> Result<usize, String> {
            match accessor.and_then(|a| a.attribute(name)) {
                None => Ok(default),
                Some(v) => v
                    .trim()
                    .parse()
                    .map_err(|_| format!("the accessor at {at}: {name}=\"{v}\" is not a count")),
            }
        };
        let stride = attr("stride", 3)?.max(1);
        let offset = attr("offset", 0)?;
        let count = attr("count", values.len().saturating_sub(offset) / stride)?;
        if stride < 3 {
            return Err(format!(
                "the accessor at {at} has stride {stride}: expected 3 or more values per vector"
            ));
        }
        let needed = count
            .checked_mul(stride)
            .and_then(|n| n.checked_add(offset));
        if needed.is_none_or(|n| n > values.len()) {
            return Err(format!(
                "the accessor at {at} reads {count} vectors of {stride} from offset {offset}: the array has {} values",
                values.len()
            ));
        }
        Ok((0..count)
            .map(|i| {
                let k = offset + i * stride;
                [values[k], values[k + 1], values[k + 2]]
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygons_are_fanned_and_transforms_compose_parent_first() {
        // A unit square as one polylist quad, under a node rotated 90° about z and then moved
        // 10 mm along x; the child node moves 20 mm along x in the rotated frame (so along y).
        let text = r##"<COLLADA version="1.4.1">
  <asset><unit meter="0.001"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries><geometry id="g"><mesh>
    <source id="pos"><float_array id="pa" count="12">0 0 0 1 0 0 1 1 0 0 1 0</float_array>
      <technique_common><accessor source="#pa" count="4" stride="3"/></technique_common></source>
    <source id="nor"><float_array id="na" count="3">0 0 1</float_array>
      <technique_common><accessor source="#na" count="1" stride="3"/></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#pos"/></vertices>
    <polylist count="1"><input semantic="VERTEX" source="#v" offset="0"/>
      <input semantic="NORMAL" source="#nor" offset="1"/>
      <vcount>4</vcount><p>0 0 1 0 2 0 3 0</p></polylist>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s">
    <node><translate>10 0 0</translate><rotate>0 0 1 90</rotate>
      <node><translate>20 0 0</translate><instance_geometry url="#g"/></node>
    </node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>"##;
        let parts = read_collada(text.as_bytes()).unwrap();
        assert_eq!(parts.len(), 1);
        assert_eq!(parts[0].faces.len(), 2);
        assert_eq!(parts[0].vertices.len(), 6);
        // Corner (1, 0) of the square: rotated to (0, 1), moved by the child's (0, 20) and the
        // parent's (10, 0): (10, 21) mm.
        let v = parts[0].vertices[1];
        assert!(
            (v[0] - 0.010).abs() < 1e-7 && (v[1] - 0.021).abs() < 1e-7,
            "{v:?}"
        );
        assert_eq!(parts[0].normals.len(), 6);
        let n = parts[0].normals[0];
        assert!((n[2] - 1.0).abs() < 1e-6, "{n:?}");

        // An index past the positions, a reference to nothing: errors that say so.
        let bad = text.replace("<p>0 0 1 0 2 0 3 0</p>", "<p>0 0 1 0 2 0 9 0</p>");
        let e = read_collada(bad.as_bytes()).unwrap_err();
        assert!(e.contains("refers to position 9 of 4"), "{e}");
        let bad = text.replace("url=\"#g\"", "url=\"#nothing\"");
        let e = read_collada(bad.as_bytes()).unwrap_err();
        assert!(e.contains("\"#nothing\" names no element"), "{e}");
    }
}
