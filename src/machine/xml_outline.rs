//! A first pass over a URDF file with a streaming XML reader: it bounds the work (nesting
//! depth, element count) before any recursive parser sees the text, and it checks the
//! structure URDF needs (names, joint parents and children, numeric attributes) so that every
//! error names the line and column of the element at fault. `urdf-rs` then reads the
//! validated text; its own messages carry no position.

use crate::diagnostics::{FileError, LineColumn};
use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;
use std::collections::BTreeMap;
use std::path::Path;

/// Deepest element nesting accepted. A URDF is about five levels deep (robot › link › visual ›
/// geometry › box); the recursive parser behind `urdf-rs` overflows its stack somewhere past
/// forty thousand.
pub const MAX_XML_DEPTH: usize = 64;

/// Most elements accepted in one file: a machine has tens of links; a million elements is a
/// generated file gone wrong, and bounds the memory of the tree `urdf-rs` builds.
pub const MAX_XML_ELEMENTS: usize = 1_000_000;

/// Where the named elements of a URDF are, for error messages of later checks.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UrdfOutline {
    pub links: BTreeMap<String, LineColumn>,
    pub joints: BTreeMap<String, LineColumn>,
    /// The joints whose `<limit>` gives `lower` or `upper` (urdf-rs reads missing ones as 0).
    pub bounded: std::collections::BTreeSet<String>,
    /// Byte ranges the URDF reader is not to see, as urdfdom does not: comments (urdfdom
    /// reads `--` in them), repeated elements after the first, an unknown shape's visual or
    /// collision, a material with neither name nor colour, a texture naming no file.
    pub ignored: Vec<std::ops::Range<usize>>,
    /// What was ignored or is not URDF, located: one warning per kind of element or attribute.
    pub warnings: Vec<FileError>,
}

/// The children an element may have once (urdfdom reads the first and ignores the others).
const SINGLE_CHILDREN: &[(&str, &[&str])] = &[
    (
        "joint",
        &[
            "origin",
            "parent",
            "child",
            "axis",
            "limit",
            "dynamics",
            "mimic",
            "safety_controller",
            "calibration",
        ],
    ),
    ("link", &["inertial"]),
    ("inertial", &["origin", "mass", "inertia"]),
    ("visual", &["origin", "geometry", "material"]),
    ("collision", &["origin", "geometry"]),
    ("material", &["color", "texture"]),
];

/// The elements of URDF, by parent, with the common extensions (Gazebo's, ros2_control's,
/// URDF's `<sensor>`, Bullet's `<contact>`, PR2's `<self_collision_checking>`), whose
/// contents are not checked.
const KNOWN_CHILDREN: &[(&str, &[&str])] = &[
    (
        "robot",
        &[
            "link",
            "joint",
            "material",
            "gazebo",
            "transmission",
            "ros2_control",
            "sensor",
        ],
    ),
    (
        "link",
        &[
            "inertial",
            "visual",
            "collision",
            "gazebo",
            "contact",
            "self_collision_checking",
        ],
    ),
    ("geometry", SHAPES),
];

/// The shapes a `<geometry>` may hold (urdf-rs reads capsules too).
const SHAPES: &[&str] = &["box", "cylinder", "sphere", "mesh", "capsule"];

/// The attributes of URDF's elements.
const KNOWN_ATTRIBUTES: &[(&str, &[&str])] = &[
    ("robot", &["name", "version"]),
    ("link", &["name", "type"]),
    ("joint", &["name", "type"]),
    ("origin", &["xyz", "rpy"]),
    ("parent", &["link"]),
    ("child", &["link"]),
    ("axis", &["xyz"]),
    ("limit", &["lower", "upper", "effort", "velocity"]),
    ("dynamics", &["damping", "friction"]),
    ("mimic", &["joint", "multiplier", "offset"]),
    (
        "safety_controller",
        &[
            "soft_lower_limit",
            "soft_upper_limit",
            "k_position",
            "k_velocity",
        ],
    ),
    ("calibration", &["rising", "falling", "reference_position"]),
    ("mass", &["value"]),
    ("inertia", &["ixx", "ixy", "ixz", "iyy", "iyz", "izz"]),
    ("visual", &["name"]),
    ("collision", &["name"]),
    ("box", &["size"]),
    ("cylinder", &["radius", "length"]),
    ("sphere", &["radius"]),
    ("capsule", &["radius", "length"]),
    ("mesh", &["filename", "scale"]),
    ("material", &["name"]),
    ("color", &["rgba"]),
    ("texture", &["filename"]),
];

fn listed<'a>(table: &[(&str, &'a [&'a str])], key: &str) -> Option<&'a [&'a str]> {
    table.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)
}

/// Warnings given once per kind (the first place, and how many more there were).
#[derive(Default)]
struct OncePerKind {
    seen: BTreeMap<String, (LineColumn, String, usize)>,
}

impl OncePerKind {
    fn note(&mut self, kind: String, at: LineColumn, message: String) {
        self.seen
            .entry(kind)
            .and_modify(|(_, _, more)| *more += 1)
            .or_insert((at, message, 0));
    }

    fn into_warnings(self, path: &Path) -> Vec<FileError> {
        let mut found: Vec<_> = self.seen.into_values().collect();
        found.sort_by_key(|(at, _, _)| (at.line, at.column));
        found
            .into_iter()
            .map(|(at, message, more)| {
                let more = match more {
                    0 => String::new(),
                    n => format!(" ({n} more like it)"),
                };
                FileError::new(path, Some(at), format!("{message}{more}"))
            })
            .collect()
    }
}

/// Attributes whose value is a list of numbers, with the count URDF gives them.
const NUMERIC_ATTRIBUTES: &[(&str, &str, usize)] = &[
    ("origin", "xyz", 3),
    ("origin", "rpy", 3),
    ("axis", "xyz", 3),
    ("mass", "value", 1),
    ("inertia", "ixx", 1),
    ("inertia", "ixy", 1),
    ("inertia", "ixz", 1),
    ("inertia", "iyy", 1),
    ("inertia", "iyz", 1),
    ("inertia", "izz", 1),
    ("limit", "lower", 1),
    ("limit", "upper", 1),
    ("limit", "effort", 1),
    ("limit", "velocity", 1),
    ("dynamics", "damping", 1),
    ("dynamics", "friction", 1),
    ("box", "size", 3),
    ("cylinder", "radius", 1),
    ("cylinder", "length", 1),
    ("sphere", "radius", 1),
    ("mesh", "scale", 3),
    ("color", "rgba", 4),
];

const JOINT_TYPES: &[&str] = &[
    "fixed",
    "prismatic",
    "revolute",
    "continuous",
    "floating",
    "planar",
    "spherical",
];

/// One open element on the reader's stack.
struct Open {
    name: String,
    at: LineColumn,
    /// Byte offset of its `<`.
    start: usize,
    /// `name` attribute, where there is one.
    label: Option<String>,
    /// The names of the children seen so far.
    children: Vec<String>,
    /// Whether the reader is not to see it (and so nothing inside it).
    ignored: bool,
    /// Inside an extension (`<gazebo>`, …): its contents are not URDF's.
    extension: bool,
}

impl Open {
    /// An element that opened at byte `start` (place `at`).
    fn new(name: String, at: LineColumn, start: u64) -> Open {
        Open {
            name,
            at,
            start: start as usize,
            label: None,
            children: Vec::new(),
            ignored: false,
            extension: false,
        }
    }
}

/// Leaves `element` out of what the URDF reader sees: an empty one (ending at `end`) at once,
/// an open one, with all it holds, when it closes.
fn leave_out(element: Open, empty: bool, end: u64, stack: &mut Vec<Open>, out: &mut UrdfOutline) {
    if empty {
        out.ignored.push(element.start..end as usize);
    } else {
        stack.push(Open {
            ignored: true,
            ..element
        });
    }
}

/// Checks `text` (the contents of `path`) and returns where its links and joints are.
pub fn outline(path: &Path, text: &str) -> Result<UrdfOutline, FileError> {
    let mut reader = Reader::from_str(text);
    let at = |offset: u64| LineColumn::of_offset(text, offset as usize);
    let mut stack: Vec<Open> = Vec::new();
    let mut out = UrdfOutline::default();
    let mut elements = 0usize;
    let mut seen_root = false;
    let mut notes = OncePerKind::default();
    loop {
        let start_offset = reader.buffer_position();
        let event = reader.read_event().map_err(|e| {
            FileError::new(
                path,
                Some(at(reader.error_position())),
                format!("not well-formed XML: {e}"),
            )
        })?;
        let (e, empty) = match event {
            Event::Start(e) => (e, false),
            Event::Empty(e) => (e, true),
            Event::End(_) => {
                let Some(open) = stack.pop() else {
                    return Err(FileError::new(
                        path,
                        Some(at(start_offset)),
                        "a closing tag without an opening one",
                    ));
                };
                let inside_ignored = stack.iter().any(|o| o.ignored);
                let has = |child: &str| open.children.iter().any(|c| c == child);
                if !open.ignored && !open.extension && !inside_ignored {
                    match open.name.as_str() {
                        "visual" | "collision" if !has("geometry") => {
                            // urdfdom drops it (with an error in its log); it shows nothing.
                            notes.note(
                                format!("no geometry {}", open.name),
                                open.at,
                                format!("<{}> without <geometry>: ignored", open.name),
                            );
                            out.ignored
                                .push(open.start..reader.buffer_position() as usize);
                        }
                        "inertial" if !(has("mass") && has("inertia")) => {
                            return Err(FileError::new(
                                path,
                                Some(open.at),
                                "<inertial> without both <mass value=\"…\"/> and <inertia ixx=\"…\" …/>: give both, or leave the <inertial> out",
                            ));
                        }
                        _ => {}
                    }
                }
                if open.ignored {
                    out.ignored
                        .push(open.start..reader.buffer_position() as usize);
                }
                if open.name == "joint" && stack.len() == 1 && !inside_ignored && !open.ignored {
                    let j = open.label.unwrap_or_default();
                    for what in ["parent", "child"] {
                        if !open.children.iter().any(|c| c == what) {
                            return Err(FileError::new(
                                path,
                                Some(open.at),
                                format!("joint '{j}' has no <{what} link=\"…\"/>"),
                            ));
                        }
                    }
                }
                continue;
            }
            Event::Comment(c) => {
                // urdfdom reads any comment (`--` inside too); the URDF reader never sees them.
                if c.windows(2).any(|w| w == b"--") || c.ends_with(b"-") {
                    notes.note(
                        "comment --".into(),
                        at(start_offset),
                        "a comment holds `--`, which XML does not allow in one: read as a comment, as urdfdom (ROS, RViz, Gazebo) does".into(),
                    );
                }
                out.ignored
                    .push(start_offset as usize..reader.buffer_position() as usize);
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        // Whitespace before a tag is a text event of its own, so the tag starts here.
        let here = at(start_offset);
        elements += 1;
        if elements > MAX_XML_ELEMENTS {
            return Err(FileError::new(
                path,
                Some(here),
                format!("more than {MAX_XML_ELEMENTS} elements: not a machine description"),
            ));
        }
        if stack.len() >= MAX_XML_DEPTH {
            return Err(FileError::new(
                        path,
                        Some(here),
                        format!(
                            "elements nested more than {MAX_XML_DEPTH} deep (a URDF needs about 5): expected a flat list of <link> and <joint> under <robot>"
                        ),
                    ));
        }
        let name = String::from_utf8_lossy(e.name().as_ref()).into_owned();
        let attributes = attributes(path, &e, here)?;
        let fail = |m: String| FileError::new(path, Some(here), m);
        if stack.is_empty() {
            if seen_root && name == "robot" {
                return Err(fail(
                    "a second <robot>: a URDF describes one robot".to_string(),
                ));
            }
            if name != "robot" {
                // urdfdom looks for the <robot> and passes over anything beside it.
                notes.note(
                    format!("top-level {name}"),
                    here,
                    format!("<{name}> beside the <robot> element: ignored, as urdfdom does"),
                );
                let end = reader.buffer_position();
                leave_out(
                    Open::new(name, here, start_offset),
                    empty,
                    end,
                    &mut stack,
                    &mut out,
                );
                continue;
            }
            seen_root = true;
        }
        let parent = stack.last().map(|o| o.name.clone());
        let extension = stack.last().is_some_and(|o| {
            o.extension
                || [
                    "gazebo",
                    "transmission",
                    "ros2_control",
                    "sensor",
                    "contact",
                    "self_collision_checking",
                ]
                .contains(&o.name.as_str())
        });
        let inside_ignored = stack.iter().any(|o| o.ignored);
        let mut ignored = false;
        if let (Some(p), false, false) = (&parent, extension, inside_ignored) {
            let siblings = &stack.last().expect("a parent is open").children;
            let repeated = siblings.contains(&name)
                && listed(SINGLE_CHILDREN, p).is_some_and(|c| c.contains(&name.as_str()));
            if repeated || p == "geometry" && !siblings.is_empty() {
                ignored = true;
                notes.note(
                    format!("second {p}/{name}"),
                    here,
                    format!("a second <{name}> in <{p}>: the first is read and this one ignored, as urdfdom (ROS, RViz, Gazebo) does"),
                );
            } else if p == "geometry" && !SHAPES.contains(&name.as_str()) {
                // urdfdom drops a visual or collision whose shape it does not know.
                if let Some(holder) = stack
                    .iter_mut()
                    .rev()
                    .nth(1)
                    .filter(|h| h.name == "visual" || h.name == "collision")
                {
                    holder.ignored = true;
                }
                notes.note(
                    format!("shape {name}"),
                    here,
                    format!("<geometry> holds <{name}>, which is not a URDF shape (box, cylinder, sphere, mesh): its <visual> or <collision> is ignored, as urdfdom does"),
                );
            } else if listed(KNOWN_CHILDREN, p).is_some_and(|known| !known.contains(&name.as_str()))
            {
                notes.note(
                    format!("element {p}/{name}"),
                    here,
                    format!("<{name}> in <{p}> is not a URDF element: ignored"),
                );
            }
            let open = stack.last_mut().expect("a parent is open");
            open.children.push(name.clone());
        }
        // A material with neither a name nor a colour (an exporter's empty `<material/>`)
        // says nothing; urdfdom ignores it.
        if name == "material" && empty && attributes.get("name").is_none_or(|n| n.is_empty()) {
            ignored = true;
        }
        // So does a `<texture/>` naming no file (exporters write one in every material, and
        // urdf-rs refuses it); textures are not drawn.
        if name == "texture" && attributes.is_empty() {
            ignored = true;
        }
        if empty && !inside_ignored && !extension {
            match name.as_str() {
                "visual" | "collision" => {
                    ignored = true;
                    notes.note(
                        format!("no geometry {name}"),
                        here,
                        format!("<{name}> without <geometry>: ignored"),
                    );
                }
                "inertial" => {
                    return Err(fail("<inertial> without both <mass value=\"…\"/> and <inertia ixx=\"…\" …/>: give both, or leave the <inertial> out".into()));
                }
                _ => {}
            }
        }
        if ignored || inside_ignored || extension {
            let element = Open {
                extension,
                ..Open::new(name, here, start_offset)
            };
            if ignored {
                let end = reader.buffer_position();
                leave_out(element, empty, end, &mut stack, &mut out);
            } else if !empty {
                stack.push(element);
            }
            continue;
        }
        if let Some(known) = listed(KNOWN_ATTRIBUTES, &name) {
            for key in attributes.keys() {
                if !known.contains(&key.as_str()) && !key.contains(':') {
                    notes.note(
                        format!("attribute {name}/{key}"),
                        here,
                        format!("<{name} {key}=…>: not a URDF attribute: ignored"),
                    );
                }
            }
        }
        if name == "color" {
            if let Err(why) = check_numbers(&name, &attributes) {
                // A colour only paints: urdfdom reads past a bad one, and so does cncsim.
                notes.note(
                    "color rgba".into(),
                    here,
                    format!("{why}: the colour is ignored"),
                );
                let end = reader.buffer_position();
                leave_out(
                    Open::new(name, here, start_offset),
                    empty,
                    end,
                    &mut stack,
                    &mut out,
                );
                continue;
            }
        }
        check_numbers(&name, &attributes).map_err(&fail)?;
        if name == "inertia" {
            let missing: Vec<&str> = ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"]
                .into_iter()
                .filter(|k| !attributes.contains_key(*k))
                .collect();
            if !missing.is_empty() {
                return Err(fail(format!(
                    "<inertia> without {}: expected all six of ixx, ixy, ixz, iyy, iyz, izz (kg·m²)",
                    missing.join(", ")
                )));
            }
        }
        let parent = parent.as_deref();
        let in_robot = stack.len() == 1;
        let label = attributes.get("name").cloned();
        match (name.as_str(), parent) {
            ("link", _) if in_robot => {
                let n = label
                    .clone()
                    .ok_or_else(|| fail("<link> has no name attribute".into()))?;
                if out.links.insert(n.clone(), here).is_some() {
                    return Err(fail(format!("link name '{n}' is used twice")));
                }
            }
            ("joint", _) if in_robot => {
                let n = label
                    .clone()
                    .ok_or_else(|| fail("<joint> has no name attribute".into()))?;
                let kind = attributes.get("type").ok_or_else(|| {
                    fail(format!(
                        "joint '{n}' has no type attribute (expected one of {})",
                        JOINT_TYPES.join(", ")
                    ))
                })?;
                if !JOINT_TYPES.contains(&kind.as_str()) {
                    return Err(fail(format!(
                        "joint '{n}': type=\"{kind}\": expected one of {}",
                        JOINT_TYPES.join(", ")
                    )));
                }
                if out.joints.insert(n.clone(), here).is_some() {
                    return Err(fail(format!("joint name '{n}' is used twice")));
                }
            }
            ("limit", Some("joint"))
                if attributes.contains_key("lower") || attributes.contains_key("upper") =>
            {
                let joint = stack.last().expect("parent is the joint");
                out.bounded.insert(joint.label.clone().unwrap_or_default());
            }
            ("parent" | "child", Some("joint")) => {
                let joint = stack.last().expect("parent is the joint");
                let j = joint.label.clone().unwrap_or_default();
                if attributes.get("link").is_none_or(|l| l.is_empty()) {
                    return Err(fail(format!("joint '{j}': <{name}> has no link attribute")));
                }
            }
            _ => {}
        }
        if !empty {
            stack.push(Open {
                label,
                ..Open::new(name, here, start_offset)
            });
        } else if name == "joint" && in_robot {
            return Err(fail(format!(
                "joint '{}' has no <parent> and <child>",
                label.unwrap_or_default()
            )));
        }
    }
    if let Some(open) = stack.last() {
        return Err(FileError::new(
            path,
            Some(at(text.len() as u64)),
            format!(
                "the file ends inside <{}> (opened at line {}, column {}): truncated?",
                open.name, open.at.line, open.at.column
            ),
        ));
    }
    if !seen_root {
        return Err(FileError::new(
            path,
            None,
            "no <robot> element: the file is empty or not a URDF",
        ));
    }
    out.warnings = notes.into_warnings(path);
    Ok(out)
}

fn attributes(
    path: &Path,
    e: &BytesStart<'_>,
    here: LineColumn,
) -> Result<BTreeMap<String, String>, FileError> {
    let mut out = BTreeMap::new();
    for a in e.attributes() {
        let a = a.map_err(|err| {
            FileError::new(path, Some(here), format!("malformed attribute: {err}"))
        })?;
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a
            .unescape_value()
            .map_err(|err| FileError::new(path, Some(here), format!("attribute {key}: {err}")))?
            .into_owned();
        out.insert(key, value);
    }
    Ok(out)
}

fn check_numbers(element: &str, attributes: &BTreeMap<String, String>) -> Result<(), String> {
    for &(e, key, count) in NUMERIC_ATTRIBUTES {
        if e != element {
            continue;
        }
        let Some(value) = attributes.get(key) else {
            continue;
        };
        let numbers: Vec<&str> = value.split_whitespace().collect();
        let parsed: Vec<Option<f64>> = numbers.iter().map(|t| t.parse::<f64>().ok()).collect();
        if numbers.len() != count || parsed.iter().any(|p| p.is_none_or(|v| !v.is_finite())) {
            let expected = if count == 1 {
                "a finite number".to_string()
            } else {
                format!("{count} finite numbers separated by spaces")
            };
            return Err(format!(
                "<{element} {key}=\"{}\">: expected {expected}",
                clip(value)
            ));
        }
    }
    Ok(())
}

/// At most 40 characters of a value, for a message.
fn clip(value: &str) -> String {
    if value.chars().count() <= 40 {
        value.to_string()
    } else {
        value.chars().take(40).collect::<String>() + "…"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(text: &str) -> Result<UrdfOutline, String> {
        outline(Path::new("m.urdf"), text).map_err(|e| e.to_string())
    }

    #[test]
    fn deep_nesting_is_refused_before_any_recursion() {
        let depth = 200_000;
        let text = format!(
            "<robot name=\"r\">{}{}</robot>",
            "<a>".repeat(depth),
            "</a>".repeat(depth)
        );
        let e = check(&text).unwrap_err();
        assert!(e.starts_with("m.urdf:1:"), "{e}");
        assert!(e.contains("nested more than 64 deep"), "{e}");
    }

    #[test]
    fn structural_errors_name_the_element_and_its_place() {
        let e = check("<robot name=\"r\">\n  <link name=\"a\"/>\n  <joint name=\"j\" type=\"fixed\">\n    <child link=\"a\"/>\n  </joint>\n</robot>").unwrap_err();
        assert_eq!(e, "m.urdf:3:3: joint 'j' has no <parent link=\"…\"/>");
        let e = check("<robot name=\"r\">\n<link name=\"a\">\n<inertial><mass value=\"heavy\"/></inertial></link></robot>").unwrap_err();
        assert_eq!(
            e,
            "m.urdf:3:11: <mass value=\"heavy\">: expected a finite number"
        );
        let e =
            check("<robot name=\"r\">\n<joint name=\"j\" type=\"hinge\"/></robot>").unwrap_err();
        assert!(
            e.starts_with("m.urdf:2:1: joint 'j': type=\"hinge\": expected one of fixed"),
            "{e}"
        );
    }

    #[test]
    fn truncation_says_where_and_what_is_open() {
        let e = check("<robot name=\"r\">\n  <link name=\"a\">\n    <inertial>").unwrap_err();
        assert_eq!(
            e,
            "m.urdf:3:15: the file ends inside <inertial> (opened at line 3, column 5): truncated?"
        );
        let e = check("").unwrap_err();
        assert!(e.contains("no <robot> element"), "{e}");
    }
}
