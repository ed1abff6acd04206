//! `cncsim machine check URDF` and `cncsim machine init URDF`: a user's own machine, from a
//! URDF exported from CAD or taken from a ROS package, to a machine cncsim runs.
//!
//! `check` shows how cncsim reads the machine: which joint each program letter drives, where
//! that letter moves the tool relative to the part, the travels, the masses and what is
//! missing. `init` writes a drive file to fill in, its letters guessed from the kinematics.

use crate::diagnostics::FileError;
use crate::kinematics::{self, ProgramFrame};
use crate::machine::{
    load_urdf, DrivesFile, JointKind, KinematicTree, Machine, Tool, Undriven, AXIS_LETTERS,
};
use nalgebra::Vector3;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One program axis as the machine has it.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisRow {
    /// The program letter (lowercase, e.g. `x`, `a`).
    pub letter: String,
    /// The URDF joint the letter drives.
    pub joint: String,
    /// Whether the joint is revolute (units rad, else m).
    pub rotary: bool,
    /// Whether the joint moves the tool (else the workpiece).
    pub moves_tool: bool,
    /// The letter's positive direction (linear) or axis (rotary) in the program frame's
    /// carrier link, sign applied.
    pub direction: [f64; 3],
    /// The drive file's `sign`: +1, or −1 where the letter runs against the joint.
    pub sign: i8,
    /// Joint units (m or rad).
    pub home: f64,
    /// Travel limits of the joint (m or rad); `None`: endless.
    pub travel: Option<[f64; 2]>,
    /// The URDF joint's own `<dynamics damping>` (N·s/m or N·m·s/rad), applied at the joint
    /// besides the drive's.
    pub joint_damping: f64,
    /// The URDF joint's own `<dynamics friction>` (N or N·m), applied at the joint.
    pub joint_friction: f64,
    /// Why the letter fits the axis in ISO 841, or what it should be instead.
    pub letter_reason: String,
}

/// Where the tool point is, as `check` shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolPointRow {
    /// The tool link.
    pub link: String,
    /// Offset in the tool link's frame (m).
    pub offset: [f64; 3],
    /// With every axis at its home, in the carrier link's frame (m).
    pub at_home: [f64; 3],
    /// `guessed = true` in `[tool]`: `machine init`'s guess, unchecked.
    pub guessed: bool,
}

/// What `cncsim machine check` found.
#[derive(Debug, Clone)]
pub struct MachineReport {
    /// The URDF read.
    pub urdf: PathBuf,
    /// The drive file read with it.
    pub drives: PathBuf,
    /// The machine's name.
    pub name: String,
    /// The carrier link of the program frame, the tool and workpiece links.
    pub carrier: String,
    /// The tool link.
    pub tool: String,
    /// The workpiece link.
    pub workpiece: String,
    /// The program axes, in the order X, Y, Z, A, B, C.
    pub axes: Vec<AxisRow>,
    /// Joints no axis drives: (name, what happens to it).
    pub undriven: Vec<(String, String)>,
    /// Total mass each axis moves is not simple to give on a tree; the links' masses instead.
    pub links: Vec<(String, f64)>,
    /// Links whose mass was computed from their geometry.
    pub masses_from_geometry: Vec<String>,
    /// The meshes drawn in the recording: link, file and size.
    pub meshes: Vec<String>,
    /// Whether X, Y, Z form a right-handed frame (ISO 841); else parts come out mirrored.
    pub right_handed: bool,
    /// Whether +Z points up (from the part towards the tool, ISO 841): `None` where Z is
    /// horizontal (a horizontal spindle) or the machine has no Z.
    pub z_up: Option<bool>,
    /// The tool point: its link, offset (m), where it is at home in the program frame's
    /// carrier (m), and whether the link is `machine init`'s unchecked guess.
    pub tool_point: ToolPointRow,
    /// What loads but may not be meant: the machine's and the program frame's warnings.
    pub warnings: Vec<FileError>,
}

/// Loads the URDF and its drive file and reports the mapping; a machine that cannot be run
/// (no drive file, a massless link, axes not at right angles) is the error.
pub fn check_machine(urdf: &Path) -> Result<MachineReport, FileError> {
    let machine = Machine::load(urdf)?;
    let (frame, frame_warnings) = ProgramFrame::new(&machine)?;
    let mut warnings = machine.warnings.clone();
    warnings.extend(frame_warnings);
    let tool_chain = kinematics::chain_joints(&machine, machine.tool_link);
    let home: Vec<f64> = machine.axes.iter().map(|a| a.drive.home).collect();
    let poses = kinematics::link_poses(&machine, &home);
    let carrier_rotation = poses[frame.carrier].rotation;
    let mut axes: Vec<AxisRow> = machine
        .axes
        .iter()
        .map(|a| {
            let joint = &machine.joints[a.joint];
            let rotary = joint.kind == JointKind::Revolute;
            let moves_tool = tool_chain.contains(&a.joint);
            let linear = ["x", "y", "z"].iter().position(|l| *l == a.name);
            let direction: Vector3<f64> = match linear {
                Some(c) => frame.directions.column(c).into_owned(),
                None => {
                    let world = (poses[joint.parent] * joint.origin).rotation * joint.axis;
                    carrier_rotation.inverse() * world * f64::from(a.drive.sign)
                }
            };
            AxisRow {
                letter_reason: letter_reason(&a.name, &frame.program_vector(&direction), rotary),
                letter: a.name.clone(),
                joint: joint.name.clone(),
                rotary,
                moves_tool,
                // Round-off of the turned frames reads as 0, not -0.0000.
                direction: direction
                    .map(|v| if v.abs() < 1e-12 { 0.0 } else { v })
                    .into(),
                sign: a.drive.sign,
                home: a.drive.home,
                travel: joint.limits,
                joint_damping: joint.damping,
                joint_friction: joint.friction,
            }
        })
        .collect();
    axes.sort_by_key(|a| AXIS_LETTERS.iter().position(|l| *l == a.letter));
    let undriven = machine
        .undriven
        .iter()
        .map(|(name, what)| {
            let text = match what {
                Undriven::Locked { position, named } => format!(
                    "locked at {position} ({})",
                    if *named {
                        "[joints] in the drive file"
                    } else {
                        "by default"
                    }
                ),
                Undriven::Passive => "passive (moves freely)".to_string(),
                Undriven::HeldByMimic { leader, position } => {
                    format!("held at {position} by its <mimic> of '{leader}'")
                }
                Undriven::RidesOn { leader } => {
                    format!("follows '{leader}' (<mimic>), riding on its link")
                }
                Undriven::Coupled {
                    leader,
                    multiplier,
                    offset,
                } => format!(
                    "coupled to '{leader}' (<mimic>): q = {multiplier} × q({leader}) + {offset}"
                ),
            };
            (name.clone(), text)
        })
        .collect();
    // The meshes drawn: (link, file, triangles); those not found or not read are warnings.
    let meshes = machine
        .links
        .iter()
        .flat_map(|l| l.visuals.iter().map(move |v| (l, v)))
        .filter_map(|(l, v)| match &v.shape {
            crate::machine::Shape::Mesh(m) => Some(format!(
                "{}: {} ({} triangles)",
                l.name,
                m.source.display(),
                m.triangles.len()
            )),
            _ => None,
        })
        .collect();
    Ok(MachineReport {
        urdf: urdf.to_path_buf(),
        drives: DrivesFile::path_for(urdf),
        name: machine.name.clone(),
        carrier: machine.links[frame.carrier].name.clone(),
        tool: machine.links[machine.tool_link].name.clone(),
        workpiece: machine.links[machine.workpiece_link].name.clone(),
        axes,
        undriven,
        links: machine
            .links
            .iter()
            .map(|l| (l.name.clone(), l.mass))
            .collect(),
        masses_from_geometry: machine.masses_from_geometry.clone(),
        meshes,
        right_handed: frame.directions.determinant() > 0.0,
        z_up: z_up(&machine, &frame, &poses),
        tool_point: ToolPointRow {
            link: machine.tool.link.clone(),
            offset: machine.tool.offset_m,
            at_home: (frame.origin.coords).into(),
            guessed: machine.tool.guessed,
        },
        warnings,
    })
}

/// Whether program +Z points up (the URDF's +z, REP 103) at home, so from the part towards
/// the tool; `None` where it is within 60° of horizontal or the machine has no Z axis.
fn z_up(
    machine: &Machine,
    frame: &ProgramFrame,
    poses: &[nalgebra::Isometry3<f64>],
) -> Option<bool> {
    machine.axis_index("z")?;
    let up = (poses[frame.carrier].rotation * frame.directions.column(2))
        .normalize()
        .z;
    (up.abs() >= 0.5).then_some(up > 0.0)
}

/// Why a letter fits an axis in ISO 841 (A, B, C turn about X, Y, Z; U, V, W and D, E are
/// the secondary motions), or what it should be: `direction` in program axes.
fn letter_reason(letter: &str, direction: &Vector3<f64>, rotary: bool) -> String {
    let nearest = (0..3)
        .max_by(|&a, &b| direction[a].abs().total_cmp(&direction[b].abs()))
        .unwrap_or(0);
    let about = ["X", "Y", "Z"][nearest];
    let (primary, secondary): (&[&str], &[&str]) = if rotary {
        (&["a", "b", "c"], &["d", "e"])
    } else {
        (&["x", "y", "z"], &["u", "v", "w"])
    };
    let upper = letter.to_uppercase();
    match (primary.iter().position(|l| *l == letter), secondary.iter().position(|l| *l == letter)) {
        (Some(_), _) if !rotary => format!("moves the tool along {upper} relative to the part (ISO 841)"),
        (Some(i), _) if i == nearest => format!("turns about {about}: {upper} (ISO 841: A, B, C turn about X, Y, Z)"),
        (Some(_), _) => format!(
            "turns about {about}, but {upper} turns about {} in ISO 841: name it {} (or D, E where {} is taken)",
            ["X", "Y", "Z"][primary.iter().position(|l| *l == letter).unwrap_or(0)],
            primary[nearest].to_uppercase(),
            primary[nearest].to_uppercase()
        ),
        (None, Some(_)) if rotary => format!("a second rotation (about {about}): {upper}, ISO 841's secondary rotary motion; programs hold it at home"),
        (None, Some(i)) if i == nearest => format!("a second motion along {about}: {upper}, ISO 841's secondary linear motion; programs hold it at home"),
        (None, Some(_)) => format!(
            "moves along {about}, but {upper} is parallel to {} in ISO 841: name it {}",
            ["X", "Y", "Z"][secondary.iter().position(|l| *l == letter).unwrap_or(0)],
            secondary[nearest].to_uppercase()
        ),
        (None, None) => format!(
            "{upper} names a {} motion in ISO 841, but its joint {}",
            if rotary { "linear" } else { "rotary" },
            if rotary { "turns" } else { "slides" }
        ),
    }
}

impl MachineReport {
    /// The report as text, in program units (mm, deg, kg).
    pub fn text(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "machine '{}': {} with {}",
            self.name,
            self.urdf.display(),
            self.drives.display()
        );
        let _ = writeln!(
            out,
            "tool on link '{}', workpiece on link '{}'; program frame fixed in link '{}'{}",
            self.tool,
            self.workpiece,
            self.carrier,
            if self.carrier == self.workpiece {
                String::new()
            } else {
                " (the link the rotary axes carrying the workpiece stand on)".into()
            }
        );
        let _ = writeln!(
            out,
            "\n{:<5} {:<20} {:<8} {:<6} {:<28} {:>4} {:>10} {:>24}",
            "axis",
            "joint",
            "kind",
            "moves",
            format!("direction in '{}'", self.carrier),
            "sign",
            "home",
            "travel"
        );
        for a in &self.axes {
            let scale = if a.rotary {
                180.0 / std::f64::consts::PI
            } else {
                1e3
            };
            let unit = if a.rotary { "deg" } else { "mm" };
            let d = a.direction;
            let travel = a.travel.map_or_else(
                || "endless".to_string(),
                |[lo, hi]| format!("{:.3} … {:.3} {unit}", lo * scale, hi * scale),
            );
            let _ = writeln!(
                out,
                "{:<5} {:<20} {:<8} {:<6} [{:>7.4}, {:>7.4}, {:>7.4}]    {:>4} {:>10} {:>24}",
                a.letter.to_uppercase(),
                a.joint,
                if a.rotary { "rotary" } else { "linear" },
                if a.moves_tool { "tool" } else { "part" },
                d[0],
                d[1],
                d[2],
                format!("{:+}", a.sign),
                format!("{:.3} {unit}", a.home * scale),
                travel
            );
        }
        // The URDF's own joint damping and friction act besides the drives': said, not hidden.
        for a in self
            .axes
            .iter()
            .filter(|a| a.joint_damping > 0.0 || a.joint_friction > 0.0)
        {
            let (damping, friction) = if a.rotary {
                ("N·m·s/rad", "N·m")
            } else {
                ("N·s/m", "N")
            };
            let _ = writeln!(
                out,
                "{} also has the URDF's <dynamics> at joint '{}': damping {} {damping}, Coulomb friction {} {friction}",
                a.letter.to_uppercase(),
                a.joint,
                a.joint_damping,
                a.joint_friction
            );
        }
        self.frame_lines(&mut out);
        if !self.undriven.is_empty() {
            let _ = writeln!(out, "\njoints no axis drives:");
            for (name, what) in &self.undriven {
                let _ = writeln!(out, "  {name}: {what}");
            }
        }
        let total: f64 = self.links.iter().map(|(_, m)| m).sum();
        let _ = writeln!(
            out,
            "\nlinks: {} with {:.3} kg in all",
            self.links.len(),
            total
        );
        for (name, mass) in &self.links {
            let computed = if self.masses_from_geometry.contains(name) {
                " (from geometry)"
            } else {
                ""
            };
            let _ = writeln!(out, "  {name}: {mass:.4} kg{computed}");
        }
        if !self.meshes.is_empty() {
            let _ = writeln!(out, "\nmeshes drawn: {}", self.meshes.len());
            for m in &self.meshes {
                let _ = writeln!(out, "  {m}");
            }
        }
        for w in &self.warnings {
            let _ = writeln!(out, "\nwarning: {w}");
        }
        out
    }

    /// The letters' ISO 841 reasons, the frame's hand and the tool point.
    fn frame_lines(&self, out: &mut String) {
        let _ = writeln!(out, "\nletters (ISO 841):");
        for a in &self.axes {
            let _ = writeln!(out, "  {}: {}", a.letter.to_uppercase(), a.letter_reason);
        }
        let hand = if self.right_handed {
            "right-handed"
        } else {
            "LEFT-handed: parts come out mirrored (see the warning)"
        };
        let _ = match self.z_up {
            Some(true) if self.right_handed => writeln!(
                out,
                "X, Y, Z are right-handed with +Z up, from the part towards the tool (ISO 841)"
            ),
            Some(false) => writeln!(
                out,
                "X, Y, Z are {hand}, and +Z points DOWN, from the tool into the part: ISO 841's +Z points from the part towards the tool. Flip `sign = -1` in [axes.z] and, to stay right-handed, in one of [axes.x], [axes.y]"
            ),
            None if self.right_handed => writeln!(
                out,
                "X, Y, Z are right-handed (ISO 841); +Z is not vertical (a horizontal spindle?): check that it points from the part towards the tool"
            ),
            _ => writeln!(out, "X, Y, Z are {hand}"),
        };
        let p = &self.tool_point;
        // Round-off reads as 0, not -0.000.
        let mm = |v: f64| if (v * 1e3).abs() < 5e-4 { 0.0 } else { v * 1e3 };
        let _ = writeln!(
            out,
            "tool point: link '{}' + [{:.3}, {:.3}, {:.3}] mm, at [{:.3}, {:.3}, {:.3}] mm in '{}' with every axis at home{}",
            p.link,
            mm(p.offset[0]),
            mm(p.offset[1]),
            mm(p.offset[2]),
            mm(p.at_home[0]),
            mm(p.at_home[1]),
            mm(p.at_home[2]),
            self.carrier,
            if p.guessed {
                " — machine init's GUESS (guessed = true in [tool]): check the link and offset, then delete that line"
            } else {
                ""
            }
        );
    }

    /// The report as JSON (`--json`), lengths in joint units (m or rad).
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "machine": self.name,
            "urdf": self.urdf,
            "drives": self.drives,
            "tool_link": self.tool,
            "workpiece_link": self.workpiece,
            "frame_link": self.carrier,
            "right_handed": self.right_handed,
            "z_up": self.z_up,
            "tool_point": {
                "link": self.tool_point.link,
                "offset_m": self.tool_point.offset,
                "at_home_m": self.tool_point.at_home,
                "guessed": self.tool_point.guessed,
            },
            "axes": self.axes.iter().map(|a| serde_json::json!({
                "letter": a.letter,
                "joint": a.joint,
                "rotary": a.rotary,
                "moves": if a.moves_tool { "tool" } else { "workpiece" },
                "direction": a.direction,
                "sign": a.sign,
                "home": a.home,
                "travel": a.travel,
                "joint_damping": a.joint_damping,
                "joint_friction": a.joint_friction,
                "letter_reason": a.letter_reason,
            })).collect::<Vec<_>>(),
            "undriven_joints": self.undriven.iter().map(|(n, w)| serde_json::json!({"joint": n, "mode": w})).collect::<Vec<_>>(),
            "links": self.links.iter().map(|(n, m)| serde_json::json!({"link": n, "mass_kg": m, "from_geometry": self.masses_from_geometry.contains(n)})).collect::<Vec<_>>(),
            "meshes": self.meshes,
            "warnings": self.warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>(),
        })
    }
}

/// Link names that say "the tool is here", and "the part is here", most telling first.
const TOOL_WORDS: [&str; 12] = [
    "tool", "tcp", "tip", "nozzle", "spindle", "laser", "torch", "pen", "extruder", "hotend",
    "effector", "head",
];
const WORKPIECE_WORDS: [&str; 7] = ["workpiece", "work", "part", "bed", "table", "plate", "vise"];

/// A drive file for `urdf`, every key commented with its unit and default; the values that
/// must come from the user's datasheets are marked ASSUMED (typical of a small servo axis),
/// so the file loads and a first run works before they are filled in.
pub fn drive_file_template(urdf: &Path) -> Result<String, FileError> {
    let tree = load_urdf(urdf)?;
    let guess = Guess::of(&tree);
    if guess.axes.is_empty() {
        return Err(FileError::new(
            urdf,
            None,
            format!(
                "no joint moves the tool (guessed: link '{}') relative to the part (guessed: link '{}'): the URDF has {} moving joints, none between them; a machine needs at least one axis",
                tree.links[guess.tool].name,
                tree.links[guess.workpiece].name,
                tree.joints.iter().filter(|j| j.kind != JointKind::Fixed).count()
            ),
        ));
    }
    // The text the tree was read from (a xacro file's expansion).
    let urdf_text = tree.text.clone();
    // Masses from geometry only where the URDF leaves a moving body without any.
    let mut density = false;
    let mut text = render(&tree, urdf, &guess, &[], density);
    if Machine::parse(urdf, &urdf_text, &text).is_err() {
        density = true;
        text = render(&tree, urdf, &guess, &[], density);
    }
    // Check the guess the way a run will read it: +Z up, from the part towards the tool, and
    // X, Y, Z right-handed (ISO 841).
    let machine = Machine::parse(urdf, &urdf_text, &text)?;
    let (frame, _) = ProgramFrame::new(&machine)?;
    let home: Vec<f64> = machine.axes.iter().map(|a| a.drive.home).collect();
    let poses = kinematics::link_poses(&machine, &home);
    let mut directions = frame.directions;
    let mut flips: Vec<(&str, &str)> = Vec::new();
    let z_set = z_up(&machine, &frame, &poses);
    if z_set == Some(false) {
        flips.push(("z", "+Z pointed down, into the part: reversed so it points from the part towards the tool (ISO 841)"));
        directions.set_column(2, &-directions.column(2));
    }
    if directions.determinant() < 0.0 {
        // Flip the axis that points most against its namesake of the frame's link; Z only
        // where gravity did not fix its sign.
        let candidates = ["x", "y", "z"]
            .iter()
            .enumerate()
            .filter(|&(c, l)| machine.axis_index(l).is_some() && (c < 2 || z_set.is_none()))
            .map(|(c, _)| c);
        if let Some(flip) =
            candidates.min_by(|&a, &b| directions[(a, a)].total_cmp(&directions[(b, b)]))
        {
            flips.push((
                ["x", "y", "z"][flip],
                "the axes were left-handed: this one is reversed so parts are not mirrored",
            ));
        }
    }
    if !flips.is_empty() {
        text = render(&tree, urdf, &guess, &flips, density);
    }
    Ok(text)
}

/// The guessed roles of a tree's joints and links.
struct Guess {
    tool: usize,
    workpiece: usize,
    /// (joint, letter, why that letter) for the joints that move the tool or the part.
    axes: Vec<Lettered>,
    /// Moving joints on neither chain (grippers, doors, tool changers).
    others: Vec<usize>,
}

impl Guess {
    fn of(tree: &KinematicTree) -> Guess {
        let probe = provisional(tree, tree.root, tree.root);
        let chain = |link| kinematics::chain_joints(&probe, link);
        let moving = |js: &[usize]| {
            js.iter()
                .filter(|&&j| {
                    tree.joints[j].kind != JointKind::Fixed && tree.joints[j].mimic.is_none()
                })
                .count()
        };
        // Words of three letters match whole words of the name only ("tip" is not in
        // "multiple", "pen" not in "open").
        let named = |words: &[&str], l: usize| {
            let name = tree.links[l].name.to_lowercase();
            let tokens: Vec<&str> = name.split(|c: char| !c.is_ascii_alphabetic()).collect();
            words.iter().position(|w| {
                if w.len() <= 3 {
                    tokens.contains(w)
                } else {
                    name.contains(w)
                }
            })
        };
        // The tool: a link named like one, deepest first; else the leaf with the longest
        // moving chain. Leaves that tie (the fingers of a gripper) hang on one hand: the tool
        // is the deepest link all their chains share, if a joint moves that link (the legs of
        // a walking robot share only its body, which nothing moves: one leg stands for it).
        let leaves: Vec<usize> = (0..tree.links.len())
            .filter(|&l| tree.joints.iter().all(|j| j.parent != l))
            .collect();
        let deepest_leaves = || {
            let longest = leaves.iter().map(|&l| moving(&chain(l))).max()?;
            let tied: Vec<usize> = (leaves.iter().copied())
                .filter(|&l| moving(&chain(l)) == longest)
                .collect();
            let below = |leaf: usize, link: usize| {
                leaf == link || chain(leaf).iter().any(|&j| tree.joints[j].parent == link)
            };
            // Up the first one's chain to the first link every tied leaf hangs below.
            let mut hand = tied[0];
            while !tied.iter().all(|&t| below(t, hand)) {
                hand = tree.joints[probe.parent_joint(hand)?].parent;
            }
            Some(if moving(&chain(hand)) > 0 {
                hand
            } else {
                *tied.last()?
            })
        };
        let tool = (0..tree.links.len())
            .filter(|&l| named(&TOOL_WORDS, l).is_some())
            .max_by_key(|&l| {
                (
                    moving(&chain(l)),
                    usize::MAX - named(&TOOL_WORDS, l).unwrap_or(0),
                )
            })
            .or_else(deepest_leaves)
            .unwrap_or(tree.root);
        let tool_chain = chain(tool);
        let workpiece = (0..tree.links.len())
            .filter(|&l| l != tool && named(&WORKPIECE_WORDS, l).is_some())
            .filter(|&l| !tool_chain.iter().any(|&j| tree.joints[j].child == l))
            .max_by_key(|&l| {
                (
                    moving(&chain(l)),
                    usize::MAX - named(&WORKPIECE_WORDS, l).unwrap_or(0),
                )
            })
            // Else the link moved most on a branch of its own, which no joint moving the tool
            // carries (a moving table), else the base.
            .or_else(|| {
                let moving_tool_joint =
                    |j: &usize| tool_chain.contains(j) && tree.joints[*j].kind != JointKind::Fixed;
                (0..tree.links.len())
                    .filter(|&l| !chain(l).iter().any(moving_tool_joint))
                    .filter(|&l| l != tool && moving(&chain(l)) > 0)
                    .max_by_key(|&l| moving(&chain(l)))
            })
            .unwrap_or(tree.root);
        let work_chain = chain(workpiece);
        let (mut axes, others) = letters(tree, &probe, &tool_chain, &work_chain);
        axes.sort_by_key(|(_, l, _)| AXIS_LETTERS.iter().position(|a| a == l));
        Guess {
            tool,
            workpiece,
            axes,
            others,
        }
    }
}

/// A joint with its ISO 841 letter and why that letter.
type Lettered = (usize, &'static str, String);

/// ISO 841 letters for the moving joints between the tool and the part, and the moving joints
/// on neither chain or left without a letter.
fn letters(
    tree: &KinematicTree,
    probe: &Machine,
    tool_chain: &[usize],
    work_chain: &[usize],
) -> (Vec<Lettered>, Vec<usize>) {
    let poses = kinematics::link_poses(probe, &[]);
    let mut axes: Vec<(usize, &'static str, String)> = Vec::new();
    let mut others = Vec::new();
    for (j, joint) in tree.joints.iter().enumerate() {
        if joint.kind == JointKind::Fixed || joint.mimic.is_some() {
            continue;
        }
        let on_tool = tool_chain.contains(&j);
        let on_part = work_chain.contains(&j);
        if on_tool == on_part {
            others.push(j);
            continue;
        }
        let world = (poses[joint.parent] * joint.origin).rotation * joint.axis;
        let direction = if on_tool { world } else { -world };
        let rotary = joint.kind == JointKind::Revolute;
        // ISO 841: the letter of the axis it moves along (turns about) most; a second one
        // parallel to a letter already taken is a secondary motion (U V W, D E).
        let (letters, secondary): ([&'static str; 3], &[&'static str]) = if rotary {
            (["a", "b", "c"], &["d", "e"])
        } else {
            (["x", "y", "z"], &["u", "v", "w"])
        };
        let nearest = (0..3)
            .max_by(|&a, &b| direction[a].abs().total_cmp(&direction[b].abs()))
            .unwrap_or(0);
        let (verb, along) = if rotary {
            ("turns about", ["X", "Y", "Z"][nearest])
        } else {
            ("moves the tool along", ["X", "Y", "Z"][nearest])
        };
        let taken = |l: &str| axes.iter().any(|(_, t, _)| *t == l);
        let holder = |l: &str| {
            axes.iter()
                .find(|(_, t, _)| *t == l)
                .map_or(String::new(), |(j, _, _)| tree.joints[*j].name.clone())
        };
        let primary = letters[nearest];
        let free_secondary = if rotary {
            secondary.iter().copied().find(|l| !taken(l))
        } else {
            Some(secondary[nearest]).filter(|l| !taken(l))
        };
        if !taken(primary) {
            let reason = format!(
                "{verb} {along} in the base's frame: {} (ISO 841)",
                primary.to_uppercase()
            );
            axes.push((j, primary, reason));
        } else if let Some(letter) = free_secondary {
            let reason = format!(
                    "{verb} {along} in the base's frame like {} (joint '{}'): {}, ISO 841's secondary {} motion; programs hold it at home",
                    primary.to_uppercase(),
                    holder(primary),
                    letter.to_uppercase(),
                    if rotary { "rotary" } else { "linear" }
                );
            axes.push((j, letter, reason));
        } else {
            others.push(j);
        }
    }
    (axes, others)
}

/// The tree as a machine without axes, for its kinematics.
fn provisional(tree: &KinematicTree, tool: usize, workpiece: usize) -> Machine {
    Machine {
        name: tree.name.clone(),
        urdf_path: tree.path.clone(),
        links: tree.links.clone(),
        joints: tree.joints.clone(),
        root: tree.root,
        axes: Vec::new(),
        undriven: Vec::new(),
        masses_from_geometry: Vec::new(),
        tool: Tool {
            link: tree.links[tool].name.clone(),
            offset_m: [0.0; 3],
            guessed: true,
        },
        tool_link: tool,
        workpiece_link: workpiece,
        warnings: Vec::new(),
    }
}

fn render(
    tree: &KinematicTree,
    urdf: &Path,
    guess: &Guess,
    flips: &[(&str, &str)],
    density: bool,
) -> String {
    let mut t = String::new();
    let file = urdf
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let _ = writeln!(
        t,
        "# Drive data for {file}: what URDF has no element for. SI units throughout (m, rad, kg, s,\n\
         # N·m, V, A). Written by `cncsim machine init`; every key is documented in docs/machines.md.\n\
         # Values marked ASSUMED are typical of a small servo axis, not your machine's: replace them\n\
         # with your datasheets' before trusting a figure. `cncsim machine check {}` shows how cncsim\n\
         # reads the machine (letters, directions, travels, masses).\n",
        urdf.display()
    );
    let _ = writeln!(
        t,
        "# The URDF's <robot name> (or its file name).\nmachine = {:?}\n",
        tree.name
    );
    let _ = writeln!(
        t,
        "# Masses and inertias of links the URDF leaves massless, from their collision (else visual)\n\
         # geometry at this density (kg/m³; aluminium 2700, steel 7850). Without it every moving link\n\
         # needs an <inertial> with a positive mass.\n{}inertia_from_geometry = {{ density_kg_m3 = 2700.0 }}\n",
        if density { "" } else { "# " }
    );
    let _ = writeln!(
        t,
        "# The tool point: a point fixed in one link (guessed: '{}'), offset_m in that link's frame.\n\
         # `cncsim machine check` shows where it is; delete `guessed` once it is right.\n\
         [tool]\nlink = {:?}\noffset_m = [0.0, 0.0, 0.0]\nguessed = true\n",
        tree.links[guess.tool].name, tree.links[guess.tool].name
    );
    let _ = writeln!(
        t,
        "# The link that carries the part (guessed: '{}'). Program X, Y, Z are where each axis moves\n\
         # the tool relative to it (ISO 841); without this table, the base link.\n\
         [workpiece]\nlink = {:?}\nguessed = true\n",
        tree.links[guess.workpiece].name, tree.links[guess.workpiece].name
    );
    for (j, letter, reason) in &guess.axes {
        let (j, letter) = (*j, *letter);
        let joint = &tree.joints[j];
        let rotary = joint.kind == JointKind::Revolute;
        let _ = writeln!(
            t,
            "# {}: URDF joint '{}', which {reason}.",
            letter.to_uppercase(),
            joint.name
        );
        let _ = writeln!(t, "[axes.{letter}]\njoint = {:?}", joint.name);
        if rotary {
            let _ = writeln!(t, "# Gearbox (motor radians per joint radian).\ntransmission = {{ kind = \"gear\", ratio = 50.0 }}   # ASSUMED");
        } else {
            let _ = writeln!(
                t,
                "# kind = \"screw\" (lead_m, optional gear_ratio) or \"belt\" (gear_ratio, pulley_radius_m).\n\
                 transmission = {{ kind = \"screw\", lead_m = 0.010 }}   # ASSUMED: 10 mm ball screw"
            );
        }
        let backlash_unit = if rotary { "rad" } else { "m" };
        let _ = writeln!(
            t,
            "rotor_inertia_kg_m2 = 1.3e-4            # ASSUMED: motor rotor (kg·m²)\n\
             transmission_inertia_kg_m2 = 1.0e-4     # ASSUMED: screw, gears or pulley on the motor side (kg·m²); default 0\n\
             viscous_damping_nm_s_per_rad = 1.0e-4   # ASSUMED: motor-side viscous damping (N·m·s/rad)\n\
             motor = {{ torque_constant_nm_per_a = 0.6, back_emf_v_s_per_rad = 0.6, resistance_ohm = 1.5, inductance_h = 4.0e-3 }}   # ASSUMED\n\
             amplifier_gain = 10.0                   # ASSUMED: volts at the armature per volt of controller output\n\
             supply_voltage_v = 300.0                # ASSUMED: the amplifier's supply (V)\n\
             peak_torque_nm = 7.0                    # ASSUMED: torque limit of the ideal-torque actuator (N·m)\n\
             # amplifier_mode = \"voltage\"          # or \"current\" (torque mode); default voltage\n\
             # backlash = 0.0                        # lost motion at the joint ({backlash_unit}); default none\n\
             # feedback = \"motor\"                  # or \"carriage\" (a linear scale); default motor\n\
             # encoder_counts_per_rev = 10000        # default: ideal feedback"
        );
        if !rotary {
            let _ = writeln!(
                t,
                "# guide = {{ friction_coefficient = 0.01 }}   # guide contact with Coulomb friction; default frictionless"
            );
        }
        let sign = match flips.iter().find(|(l, _)| *l == letter) {
            Some((_, why)) => format!("sign = -1                               # {why}"),
            None => "# sign = 1                              # -1 reverses the letter's direction; default 1".to_string(),
        };
        let unit = if rotary { "rad" } else { "m" };
        let home = match joint.limits {
            Some([lo, hi]) if !(lo..=hi).contains(&0.0) => format!(
                "home = {:?}                             # joint coordinate at machine zero ({unit}): 0 is outside this joint's travel, so its nearer limit",
                0.0f64.clamp(lo, hi)
            ),
            _ => format!(
                "# home = 0.0                             # joint coordinate at machine zero ({unit}); default 0"
            ),
        };
        let _ = writeln!(t, "{sign}\n{home}\n");
    }
    for &j in &guess.others {
        let joint = &tree.joints[j];
        let _ = writeln!(
            t,
            "# '{}' moves neither the tool nor the part as an axis would: held where it is.\n\
             # mode = \"passive\" lets it move freely with its URDF damping and friction.\n\
             [joints.{}]\nmode = \"locked\"\n# position = 0.0\n",
            joint.name,
            toml_key(&joint.name)
        );
    }
    t
}

/// A TOML key: bare where the name allows it, else quoted.
fn toml_key(name: &str) -> String {
    if !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        name.to_string()
    } else {
        format!("{name:?}")
    }
}

impl crate::command::Report for MachineReport {
    fn text(&self) -> String {
        MachineReport::text(self)
    }

    fn json(&self) -> Option<serde_json::Value> {
        Some(MachineReport::json(self))
    }
}

/// `cncsim machine init`: a drive file drafted for a URDF, to be written to `out` (`-`: the
/// terminal).
#[derive(Debug, Clone)]
pub struct DriveFileDraft {
    /// The URDF the draft is for.
    pub urdf: PathBuf,
    /// The drafted drive file (TOML).
    pub text: String,
    /// Where it is written; `-`: the terminal.
    pub out: PathBuf,
}

impl DriveFileDraft {
    fn to_terminal(&self) -> bool {
        self.out == Path::new("-")
    }
}

impl crate::command::Report for DriveFileDraft {
    fn write(&self) -> Result<Vec<PathBuf>, crate::command::WriteError> {
        if self.to_terminal() {
            return Ok(Vec::new());
        }
        Ok(vec![crate::command::write_file(
            self.out.clone(),
            &self.text,
        )?])
    }

    fn text(&self) -> String {
        if self.to_terminal() {
            self.text.clone()
        } else {
            let sidecar = DrivesFile::path_for(&self.urdf);
            let place = if self.out == sidecar {
                String::new()
            } else {
                // cncsim reads a machine's drive file beside its URDF, by name.
                format!(", put it at {} (where cncsim reads it)", sidecar.display())
            };
            format!(
                "fill in the values marked ASSUMED in {}{place}, then `cncsim machine check {}`\n",
                self.out.display(),
                self.urdf.display()
            )
        }
    }
}
