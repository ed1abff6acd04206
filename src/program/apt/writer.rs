//! Which CAM system wrote a CL file, and the conventions that follow from it.
//!
//! APT left some things to the writer, and the systems differ: NX turns `CIRCLE` arcs
//! clockwise about the record's axis vector, where APT itself, Pro/ENGINEER and Creo, CATIA
//! and the others turn them counter-clockwise (right-hand rule). Reading a file with the
//! wrong convention turns a quarter-circle corner into a three-quarter loop, so the reader
//! identifies the writer from what its header and records say, tells which it assumed and
//! why, and lets the user name it instead.

use std::path::Path;

use super::circle::CircleSense;

/// A CAM system whose CL data cncsim knows the conventions of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClWriter {
    /// Siemens NX (Unigraphics) CLSF.
    Nx,
    /// PTC Pro/ENGINEER and Creo (`.ncl` files).
    Creo,
    /// Dassault CATIA V5 APT output.
    Catia,
    /// SolidWorks CAM (built on CAMWorks).
    SolidWorksCam,
    /// CAMWorks.
    CamWorks,
    /// Mastercam.
    Mastercam,
    /// Autodesk Fusion, Inventor CAM and HSMWorks (their APT post).
    Fusion,
    /// CAMplete TruePath (its APT post, also used for MANUSnc).
    Camplete,
    /// None recognised: APT as its standard defines it.
    Apt,
}

/// Every writer, for listing the names a user may give.
pub const WRITERS: &[ClWriter] = &[
    ClWriter::Nx,
    ClWriter::Creo,
    ClWriter::Catia,
    ClWriter::SolidWorksCam,
    ClWriter::CamWorks,
    ClWriter::Mastercam,
    ClWriter::Fusion,
    ClWriter::Camplete,
    ClWriter::Apt,
];

impl ClWriter {
    /// The name a scenario (`cl_writer`) or `inspect --cl-writer` gives.
    pub fn name(self) -> &'static str {
        match self {
            ClWriter::Nx => "nx",
            ClWriter::Creo => "creo",
            ClWriter::Catia => "catia",
            ClWriter::SolidWorksCam => "solidworks",
            ClWriter::CamWorks => "camworks",
            ClWriter::Mastercam => "mastercam",
            ClWriter::Fusion => "fusion",
            ClWriter::Camplete => "camplete",
            ClWriter::Apt => "apt",
        }
    }

    /// The system's name as its maker writes it.
    pub fn title(self) -> &'static str {
        match self {
            ClWriter::Nx => "Siemens NX",
            ClWriter::Creo => "PTC Creo / Pro/ENGINEER",
            ClWriter::Catia => "CATIA",
            ClWriter::SolidWorksCam => "SolidWorks CAM",
            ClWriter::CamWorks => "CAMWorks",
            ClWriter::Mastercam => "Mastercam",
            ClWriter::Fusion => "Autodesk Fusion / Inventor CAM / HSMWorks",
            ClWriter::Camplete => "CAMplete",
            ClWriter::Apt => "standard APT (no writer recognised)",
        }
    }

    /// A writer by the name a user gives (also `ug`, `proe`, `pro-engineer`, `sw`,
    /// `inventor`, `hsm`), case-insensitive.
    pub fn from_name(name: &str) -> Option<ClWriter> {
        let name = name.trim().to_ascii_lowercase();
        let writer = match name.as_str() {
            "nx" | "ug" | "unigraphics" | "siemens-nx" => ClWriter::Nx,
            "creo" | "proe" | "pro/e" | "pro-e" | "pro-engineer" | "pro/engineer" => ClWriter::Creo,
            "catia" => ClWriter::Catia,
            "solidworks" | "solidworks-cam" | "sw" => ClWriter::SolidWorksCam,
            "camworks" => ClWriter::CamWorks,
            "mastercam" => ClWriter::Mastercam,
            "fusion" | "fusion360" | "inventor" | "hsm" | "hsmworks" | "autodesk" => {
                ClWriter::Fusion
            }
            "camplete" | "truepath" => ClWriter::Camplete,
            "apt" | "standard" => ClWriter::Apt,
            _ => return None,
        };
        Some(writer)
    }

    /// The names [`ClWriter::from_name`] takes, for messages.
    pub fn names() -> String {
        WRITERS
            .iter()
            .map(|w| w.name())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Which way its `CIRCLE` arcs turn about the record's axis vector: NX and CAMplete
    /// (whose posts write the axis of a clockwise arc as is) clockwise, the rest as APT
    /// defines it.
    pub fn circle_sense(self) -> CircleSense {
        match self {
            ClWriter::Nx | ClWriter::Camplete => CircleSense::ClockwiseAboutAxis,
            _ => CircleSense::CounterClockwiseAboutAxis,
        }
    }
}

/// The writer a file was read as, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identification {
    /// The CAM system.
    pub writer: ClWriter,
    /// What decided it: the record or comment (with its line) or the user's setting.
    pub reason: String,
}

impl Identification {
    /// The line `inspect` shows.
    pub fn describe(&self) -> String {
        let sense = match self.writer.circle_sense() {
            CircleSense::ClockwiseAboutAxis => "clockwise",
            CircleSense::CounterClockwiseAboutAxis => "counter-clockwise",
        };
        format!(
            "CL data written by {} ({}): CIRCLE arcs turn {sense} about their axis vector unless their entry or exit move is tangent to the other way",
            self.writer.title(),
            self.reason
        )
    }
}

/// Marks in a file's comments and records, each naming its writer. Matched, case-insensitive,
/// against each line of the file's first records; the first line that matches any decides.
const MARKS: &[(&str, ClWriter, MarkKind)] = &[
    ("PRO/CLFILE", ClWriter::Creo, MarkKind::Anywhere),
    ("$$->", ClWriter::Creo, MarkKind::LineStart),
    ("TOOL PATH/", ClWriter::Nx, MarkKind::LineStart),
    ("TLDATA/", ClWriter::Nx, MarkKind::LineStart),
    ("MSYS/", ClWriter::Nx, MarkKind::LineStart),
    ("$$ CENTERLINE DATA", ClWriter::Nx, MarkKind::LineStart),
    ("UNIGRAPHICS", ClWriter::Nx, MarkKind::Comment),
    ("CATIA", ClWriter::Catia, MarkKind::Comment),
    ("CAMPLETE", ClWriter::Camplete, MarkKind::Comment),
    ("CSI_TOOL_PATH", ClWriter::Camplete, MarkKind::LineStart),
    (
        "CSI_PATH_TOLERANCE",
        ClWriter::Camplete,
        MarkKind::LineStart,
    ),
    ("CAMWORKS", ClWriter::CamWorks, MarkKind::Comment),
    ("SOLIDWORKS", ClWriter::SolidWorksCam, MarkKind::Comment),
    ("CSI_SET_", ClWriter::SolidWorksCam, MarkKind::LineStart),
    ("MASTERCAM", ClWriter::Mastercam, MarkKind::Comment),
    ("$$MACHINE GROUP", ClWriter::Mastercam, MarkKind::LineStart),
    ("HSMWORKS", ClWriter::Fusion, MarkKind::Comment),
    ("FUSION", ClWriter::Fusion, MarkKind::Comment),
    ("INVENTOR CAM", ClWriter::Fusion, MarkKind::Comment),
    ("AUTODESK", ClWriter::Fusion, MarkKind::Comment),
];

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MarkKind {
    /// The line starts with it (blanks before it and around '/' aside).
    LineStart,
    /// In a comment (`$$`) or a text record (PARTNO, PPRINT, REMARK, …).
    Comment,
    /// Anywhere on the line.
    Anywhere,
}

/// How many lines at the top of a file are searched for marks.
const HEADER_LINES: usize = 400;

/// The writer of `text` (read from `path`): by the marks of its header, else by the `.ncl`
/// extension (Creo's own), else standard APT.
pub fn identify(text: &[u8], path: &Path) -> Identification {
    let head = &text[..text.len().min(1 << 16)];
    let head = String::from_utf8_lossy(head);
    for (index, line) in head.lines().take(HEADER_LINES).enumerate() {
        let upper = line.trim().to_ascii_uppercase();
        // `GOTO / x` and `GOTO/x` alike.
        let squeezed: String = {
            let mut out = String::with_capacity(upper.len());
            let mut chars = upper.chars().peekable();
            while let Some(c) = chars.next() {
                if c == ' ' && (out.ends_with('/') || chars.peek() == Some(&'/')) {
                    continue;
                }
                out.push(c);
            }
            out
        };
        let comment = squeezed.starts_with("$$")
            || ["PARTNO", "PPRINT", "REMARK", "INSERT", "CLPRNT", "TPRINT"]
                .iter()
                .any(|word| squeezed.starts_with(word));
        for &(mark, writer, kind) in MARKS {
            let found = match kind {
                MarkKind::LineStart => squeezed.starts_with(mark),
                MarkKind::Comment => comment && squeezed.contains(mark),
                MarkKind::Anywhere => squeezed.contains(mark),
            };
            if found {
                let shown: String = line.trim().chars().take(60).collect();
                return Identification {
                    writer,
                    reason: format!("line {}: `{shown}`", index + 1),
                };
            }
        }
    }
    if is_ncl(path) {
        return Identification {
            writer: ClWriter::Creo,
            reason: "the file name's .ncl, Creo's CL extension".into(),
        };
    }
    Identification {
        writer: ClWriter::Apt,
        reason: "no writer's mark in its header".into(),
    }
}

/// Whether `path` is named as Creo names CL files: `.ncl`, or `.ncl.N` (its numbered
/// versions).
pub fn is_ncl(path: &Path) -> bool {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return false;
    };
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".ncl") {
        return true;
    }
    match lower.rsplit_once('.') {
        Some((stem, version)) => {
            !version.is_empty()
                && version.bytes().all(|b| b.is_ascii_digit())
                && stem.ends_with(".ncl")
        }
        None => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn writer_of(text: &str, name: &str) -> ClWriter {
        identify(text.as_bytes(), Path::new(name)).writer
    }

    #[test]
    fn headers_name_their_writers() {
        assert_eq!(
            writer_of(
                "$$*          Pro/CLfile  Version 8.0 - 8.0.3.0\nPARTNO / X\n",
                "a.txt"
            ),
            ClWriter::Creo
        );
        assert_eq!(
            writer_of("TOOL PATH/OP,TOOL,MILL\nTLDATA/MILL,10,0,50,0,0\n", "a.cls"),
            ClWriter::Nx
        );
        assert_eq!(
            writer_of(
                "PARTNO/PART\n$$ Mastercam APT output\nGOTO/1,2,3\n",
                "a.apt"
            ),
            ClWriter::Mastercam
        );
        assert_eq!(
            writer_of("PARTNO / TEST\nUNITS / MM\nGOTO / 50, 50, 10\n", "a.apt"),
            ClWriter::Apt
        );
        // A writer's name in a GOTO-free line that is not a comment does not count.
        assert_eq!(writer_of("GOTO/1,2,3\nCATIA/1\n", "a.apt"), ClWriter::Apt);
    }

    #[test]
    fn creo_names_its_files_ncl_with_versions() {
        for name in ["part.ncl", "part.NCL", "bohren_1.ncl.8", "x.ncl.12"] {
            assert!(is_ncl(Path::new(name)), "{name}");
            assert_eq!(writer_of("GOTO/1,2,3\n", name), ClWriter::Creo);
        }
        for name in ["part.nc", "part.ncl.", "part.ncl.x1", "ncl"] {
            assert!(!is_ncl(Path::new(name)), "{name}");
        }
    }

    #[test]
    fn names_round_trip() {
        for &writer in WRITERS {
            assert_eq!(ClWriter::from_name(writer.name()), Some(writer));
        }
        assert_eq!(ClWriter::from_name("Pro/ENGINEER"), Some(ClWriter::Creo));
        assert_eq!(ClWriter::from_name("gibbs"), None);
    }

    #[test]
    fn only_nx_and_camplete_turn_clockwise_about_the_axis() {
        for &writer in WRITERS {
            let clockwise = writer.circle_sense() == CircleSense::ClockwiseAboutAxis;
            let expected = matches!(writer, ClWriter::Nx | ClWriter::Camplete);
            assert_eq!(clockwise, expected, "{writer:?}");
        }
    }
}
