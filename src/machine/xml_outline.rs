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
    /// For `<joint>`: whether `<parent>` and `<child>` were seen.
    parent: bool,
    child: bool,
    /// `name` attribute, where there is one.
    label: Option<String>,
}

/// Checks `text` (the contents of `path`) and returns where its links and joints are.
pub fn outline(path: &Path, text: &str) -> Result<UrdfOutline, FileError> {
    let mut reader = Reader::from_str(text);
    let at = |offset: u64| LineColumn::of_offset(text, offset as usize);
    let mut stack: Vec<Open> = Vec::new();
    let mut out = UrdfOutline::default();
    let mut elements = 0usize;
    let mut seen_root = false;
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
                if open.name == "joint" && stack.len() == 1 {
                    let j = open.label.unwrap_or_default();
                    for (seen, what) in [(open.parent, "parent"), (open.child, "child")] {
                        if !seen {
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
            if seen_root {
                return Err(fail(format!(
                    "a second top-level element <{name}>: a URDF has one <robot>"
                )));
            }
            seen_root = true;
            if name != "robot" {
                return Err(fail(format!(
                    "expected the root element <robot>, found <{name}>"
                )));
            }
        }
        check_numbers(&name, &attributes).map_err(&fail)?;
        let parent = stack.last().map(|o| o.name.as_str());
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
                let joint = stack.last_mut().expect("parent is the joint");
                let j = joint.label.clone().unwrap_or_default();
                if attributes.get("link").is_none_or(|l| l.is_empty()) {
                    return Err(fail(format!("joint '{j}': <{name}> has no link attribute")));
                }
                let seen = if name == "parent" {
                    &mut joint.parent
                } else {
                    &mut joint.child
                };
                if *seen {
                    return Err(fail(format!("joint '{j}' has a second <{name}>")));
                }
                *seen = true;
            }
            _ => {}
        }
        if !empty {
            stack.push(Open {
                name,
                at: here,
                parent: false,
                child: false,
                label,
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
