//! `KEY=VALUE` overrides of a scenario file (`cncsim ab S.toml --a controller=pid …`).
//!
//! An override edits the TOML document before the typed parsing, so every check of the
//! scenario format applies to overridden values exactly as to written ones. The edit keeps
//! every other line of the file as written; error positions on those lines are mapped back to
//! the file, and an error on an edited line names the override instead.

use super::Scenario;
use crate::diagnostics::{read_text, FileError, LineColumn};
use std::fmt;
use std::path::Path;
use toml_edit::{DocumentMut, InlineTable, Item, Table, Value};

/// One `KEY=VALUE` override: a dotted key into the scenario and a TOML value.
#[derive(Debug, Clone)]
pub struct Override {
    /// As the user wrote it, for messages and variant names.
    pub text: String,
    key: Vec<String>,
    value: Value,
}

impl fmt::Display for Override {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.text)
    }
}

impl Override {
    /// Parses `KEY=VALUE`. KEY is a dotted path of bare TOML keys; `controller` alone is short
    /// for `controller.type`. VALUE is a TOML value (`30`, `1.2`, `true`, `[1, 2]`,
    /// `{ kp = 1.0 }`, `"text"`); anything that is not one is taken as a bare string, so
    /// `controller=pid` needs no quotes.
    pub fn parse(text: &str) -> Result<Override, String> {
        let Some((key, value)) = text.split_once('=') else {
            return Err(format!(
                "{text}: expected KEY=VALUE (e.g. controller=pid, timing.physics_step_ms=0.125)"
            ));
        };
        let key = key.trim();
        let mut path: Vec<String> = key.split('.').map(|s| s.trim().to_string()).collect();
        let bare = |s: &String| {
            !s.is_empty()
                && s.chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        };
        if !path.iter().all(bare) {
            return Err(format!(
                "{text}: expected a dotted key of letters, digits, '_' and '-' before '=', found '{key}'"
            ));
        }
        if path == ["controller"] {
            path.push("type".into());
        }
        let value = value.trim();
        let mut value = value
            .parse::<Value>()
            .unwrap_or_else(|_| Value::from(value));
        value.decor_mut().clear();
        Ok(Override {
            text: text.to_string(),
            key: path,
            value,
        })
    }

    fn dotted(&self, n: usize) -> String {
        self.key[..n].join(".")
    }

    /// Sets the value in `doc`, creating missing tables (as dotted keys, so no new section
    /// appears). Refuses to turn a table into a value or to descend into a value.
    fn apply(&self, doc: &mut DocumentMut) -> Result<(), String> {
        let (last, parents) = self.key.split_last().expect("at least one segment");
        let mut item = doc.as_item_mut();
        for (depth, segment) in parents.iter().enumerate() {
            let inline = item.is_inline_table();
            if !item.is_table_like() {
                return Err(not_a_table(&self.dotted(depth), item));
            }
            let table = item.as_table_like_mut().expect("checked above");
            if !table.contains_key(segment) {
                let child = if inline {
                    Item::Value(Value::InlineTable(InlineTable::new()))
                } else {
                    let mut t = Table::new();
                    t.set_dotted(true);
                    Item::Table(t)
                };
                table.insert(segment, child);
            }
            item = table.get_mut(segment).expect("inserted above");
        }
        let depth = parents.len();
        if !item.is_table_like() {
            return Err(not_a_table(&self.dotted(depth), item));
        }
        let table = item.as_table_like_mut().expect("checked above");
        let mut value = self.value.clone();
        match table.get_mut(last) {
            Some(existing) if existing.is_table_like() && !value.is_inline_table() => Err(format!(
                "`{}` is a table; set one of its keys ({}.KEY=VALUE)",
                self.dotted(depth + 1),
                self.dotted(depth + 1)
            )),
            Some(Item::Value(old)) => {
                // Keep the spacing and any trailing comment of the line.
                *value.decor_mut() = old.decor().clone();
                *old = value;
                Ok(())
            }
            _ => {
                table.insert(last, Item::Value(value));
                Ok(())
            }
        }
    }
}

fn not_a_table(key: &str, item: &Item) -> String {
    let what = match item {
        Item::Value(v) => v.type_name(),
        Item::ArrayOfTables(_) => "array of tables",
        _ => "not a table",
    };
    format!("`{key}` is a {what}, not a table of keys")
}

/// `text` (a TOML document) with `overrides` applied, every other line as written.
pub fn edit_toml(text: &str, overrides: &[Override]) -> Result<String, String> {
    let mut doc: DocumentMut = text
        .parse()
        .map_err(|e: toml_edit::TomlError| e.to_string())?;
    for o in overrides {
        o.apply(&mut doc).map_err(|m| format!("{o}: {m}"))?;
    }
    Ok(doc.to_string())
}

impl Scenario {
    /// Loads a scenario with `overrides` applied; `flag` (`--a`, `--b`) names where they came
    /// from in messages. The variant's name is the scenario's name followed by the overrides.
    pub fn load_with_overrides(
        path: &Path,
        overrides: &[Override],
        flag: &str,
    ) -> Result<Scenario, FileError> {
        let text = read_text(path, "scenario")?;
        if overrides.is_empty() {
            return Self::parse(path, &text);
        }
        // A file that is not TOML at all: the plain parser reports where.
        let mut doc: DocumentMut = match text.parse() {
            Ok(doc) => doc,
            Err(_) => return Self::parse(path, &text),
        };
        for o in overrides {
            o.apply(&mut doc)
                .map_err(|m| FileError::new(path, None, format!("{flag} {o}: {m}")))?;
        }
        let edited = doc.to_string();
        let lines = line_map(&text, &edited);
        let all: Vec<&str> = overrides.iter().map(|o| o.text.as_str()).collect();
        match Self::parse(path, &edited) {
            Ok(mut s) => {
                s.map_positions(&|at| {
                    lines
                        .get(at.line - 1)
                        .copied()
                        .flatten()
                        .map(|line| LineColumn {
                            line: line + 1,
                            column: at.column,
                        })
                });
                s.name = format!("{} {}", s.name, all.join(" "));
                Ok(s)
            }
            Err(mut e) => {
                let with = format!("(with {flag} {})", all.join(" "));
                match e.at.map(|at| (at, lines.get(at.line - 1).copied())) {
                    // On an edited line: the override is to blame.
                    Some((at, Some(None))) => {
                        let line = edited.lines().nth(at.line - 1).unwrap_or("");
                        let culprit = overrides
                            .iter()
                            .rev()
                            .find(|o| line.contains(o.key.last().expect("non-empty").as_str()))
                            .map_or(all.join(" "), |o| o.text.clone());
                        e.at = None;
                        e.message = format!(
                            "{flag} {culprit}: {}",
                            e.message.replace("unknown field", "unknown key")
                        );
                    }
                    Some((at, Some(Some(line)))) => {
                        e.at = Some(LineColumn {
                            line: line + 1,
                            column: at.column,
                        });
                        e.message = format!("{} {with}", e.message);
                    }
                    // No place, or past the last line (the end of the file): keep it.
                    _ => e.message = format!("{} {with}", e.message),
                }
                Err(e)
            }
        }
    }
}

/// For each line of `edited`, the index of the same line in `original`, or `None` for a line
/// the edit changed or added: a longest-common-subsequence match of whole lines (scenario files
/// are short, so the quadratic table is nothing).
fn line_map(original: &str, edited: &str) -> Vec<Option<usize>> {
    let a: Vec<&str> = original.lines().collect();
    let b: Vec<&str> = edited.lines().collect();
    let (n, m) = (a.len(), b.len());
    // lcs[i][j]: length of the LCS of a[i..] and b[j..].
    let mut lcs = vec![vec![0u32; m + 1]; n + 1];
    for i in (0..n).rev() {
        for j in (0..m).rev() {
            lcs[i][j] = if a[i] == b[j] {
                lcs[i + 1][j + 1] + 1
            } else {
                lcs[i + 1][j].max(lcs[i][j + 1])
            };
        }
    }
    let mut map = vec![None; m];
    let (mut i, mut j) = (0, 0);
    while i < n && j < m {
        if a[i] == b[j] {
            map[j] = Some(i);
            i += 1;
            j += 1;
        } else if lcs[i + 1][j] >= lcs[i][j + 1] {
            i += 1;
        } else {
            j += 1;
        }
    }
    map
}

#[cfg(test)]
mod tests {
    use super::*;

    fn edit(text: &str, overrides: &[&str]) -> Result<String, String> {
        let mut doc: DocumentMut = text.parse().unwrap();
        for o in overrides {
            Override::parse(o)?.apply(&mut doc)?;
        }
        Ok(doc.to_string())
    }

    #[test]
    fn values_are_replaced_in_place_and_new_keys_join_their_table() {
        let text = "name = \"s\"\n[controller]\ntype = \"pid\"  # why\naxes.x = { kp = 1.0 }\n[timing]\nservo_period_ms = 1.0\n";
        let edited = edit(
            text,
            &[
                "controller=inverse-dynamics",
                "controller.natural_frequency_hz=30",
                "controller.axes.x.kp=2.5",
                "timing.physics_step_ms=0.125",
                "analytic.enabled=true",
            ],
        )
        .unwrap();
        let parsed: toml::Table = toml::from_str(&edited).unwrap();
        assert_eq!(
            parsed["controller"]["type"].as_str(),
            Some("inverse-dynamics")
        );
        assert_eq!(
            parsed["controller"]["natural_frequency_hz"].as_integer(),
            Some(30)
        );
        assert_eq!(
            parsed["controller"]["axes"]["x"]["kp"].as_float(),
            Some(2.5)
        );
        assert_eq!(parsed["timing"]["physics_step_ms"].as_float(), Some(0.125));
        assert_eq!(parsed["analytic"]["enabled"].as_bool(), Some(true));
        assert!(
            edited.contains("type = \"inverse-dynamics\"  # why\n"),
            "{edited}"
        );
        // Untouched lines keep their place relative to each other.
        let map = line_map(text, &edited);
        let kept: Vec<usize> = map.iter().flatten().copied().collect();
        assert!(kept.windows(2).all(|w| w[0] < w[1]));
        assert!(kept.contains(&0) && kept.contains(&5), "{map:?}\n{edited}");
    }

    #[test]
    fn malformed_overrides_say_what_was_expected() {
        assert!(Override::parse("controller")
            .unwrap_err()
            .contains("expected KEY=VALUE"));
        assert!(Override::parse("a..b=1")
            .unwrap_err()
            .contains("dotted key"));
        let text = "[timing]\nservo_period_ms = 1.0\n[controller]\naxes.x = { kp = 1.0 }\n";
        assert!(edit(text, &["timing=3"])
            .unwrap_err()
            .contains("`timing` is a table"));
        assert!(edit(text, &["timing.servo_period_ms.x=3"])
            .unwrap_err()
            .contains("`timing.servo_period_ms` is a float, not a table"));
    }

    #[test]
    fn bare_words_are_strings_and_toml_values_keep_their_type() {
        let v = |s: &str| Override::parse(s).unwrap().value;
        assert_eq!(v("controller=pid").as_str(), Some("pid"));
        assert_eq!(v("k=30").as_integer(), Some(30));
        assert_eq!(v("k=1e-3").as_float(), Some(1e-3));
        assert_eq!(v("k=\"30\"").as_str(), Some("30"));
        assert_eq!(v("k=false").as_bool(), Some(false));
        assert_eq!(
            Override::parse("controller=pid").unwrap().key,
            ["controller", "type"]
        );
    }
}

#[cfg(test)]
mod file_tests {
    use super::*;

    /// The bundled fast mill scenario with absolute paths, written to a temporary folder, with
    /// `edit` applied to its text.
    fn scenario(edit: impl Fn(&str) -> String) -> (tempfile::TempDir, std::path::PathBuf, String) {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(root.join("scenarios/mill_table2_fast.toml"))
            .unwrap()
            .replace("../models/", &format!("{}/models/", root.display()))
            .replace(
                "programs/",
                &format!("{}/scenarios/programs/", root.display()),
            );
        let text = edit(&text);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(&path, &text).unwrap();
        (dir, path, text)
    }

    fn line_of(text: &str, needle: &str) -> usize {
        LineColumn::of_first(text, needle).unwrap().line
    }

    #[test]
    fn errors_on_lines_the_overrides_left_alone_point_into_the_file() {
        let (_dir, path, text) = scenario(|t| t.replace("settle_s = 0.5", "settle_s = -0.5"));
        // A new key in [controller] and a new root table: lines are added before the error.
        let overrides: Vec<Override> = ["controller.task_damping=0.1", "analytic.enabled=false"]
            .iter()
            .map(|o| Override::parse(o).unwrap())
            .collect();
        let e = Scenario::load_with_overrides(&path, &overrides, "--b").unwrap_err();
        assert_eq!(
            e.at.map(|at| at.line),
            Some(line_of(&text, "settle_s")),
            "{e}"
        );
        assert!(
            e.message.starts_with("settle_s = -0.5 s: expected a value from 0.0 to 3600.0 s (with --b controller.task_damping=0.1 analytic.enabled=false)"),
            "{e}"
        );
    }

    #[test]
    fn positions_of_a_loaded_variant_are_the_files() {
        let (_dir, path, text) = scenario(|t| t.to_string());
        let overrides = [
            Override::parse("planner.blend=exact-stop").unwrap(),
            Override::parse("controller.damping_ratio=0.9").unwrap(),
        ];
        let s = Scenario::load_with_overrides(&path, &overrides, "--a").unwrap();
        assert_eq!(
            s.name,
            "mill_table2_fast planner.blend=exact-stop controller.damping_ratio=0.9"
        );
        assert_eq!(
            s.controller.as_ref().unwrap().pid.axes["x"]
                .at
                .map(|at| at.line),
            Some(line_of(&text, "axes.x"))
        );
        assert_eq!(
            s.expect
                .iter()
                .find(|e| e.metric == "max_contour_error_mm")
                .and_then(|e| e.at)
                .map(|at| at.line),
            Some(line_of(&text, "max_contour_error_mm = "))
        );
        let id = s.controller.as_ref().unwrap().inverse_dynamics.unwrap();
        assert_eq!(id.damping_ratio, 0.9);
    }

    #[test]
    fn settings_of_the_controller_not_chosen_are_still_checked() {
        let (_dir, path, _) = scenario(|t| t.replace("kp = 5806.0", "kp = -5806.0"));
        let e = Scenario::load_with_overrides(&path, &[], "--a").unwrap_err();
        assert!(
            e.message
                .contains("controller.axes.x: gains must be from 0 to 1000000000000.0"),
            "{e}"
        );
        let (_dir, path, _) = scenario(|t| t.to_string());
        let pid = [
            Override::parse("controller=pid").unwrap(),
            Override::parse("controller.damping_ratio=0").unwrap(),
        ];
        let e = Scenario::load_with_overrides(&path, &pid, "--a").unwrap_err();
        assert_eq!(
            e.message,
            "--a controller.damping_ratio=0: damping_ratio = 0.0: expected a value from 0.001 to 100.0"
        );
        // Chosen PID: no inverse-dynamics settings, the file's gains.
        let s = Scenario::load_with_overrides(&path, &pid[..1], "--a").unwrap();
        assert!(
            s.controller_type() == Some(super::super::ControllerType::Pid)
                && s.controller.as_ref().unwrap().pid.axes["c"].settings.kp == 196.5
        );
    }
}
