//! No input may make a reader panic or hang: property tests with arbitrary bytes and with
//! structured garbage built from each language's vocabulary.
//!
//! The normal run tries `PROPTEST_CASES` inputs per generator (default 5000, about a second).
//! The ignored `*_million` tests try `FUZZ_CASES` (default 500 000) per generator, i.e. one
//! million per language:
//!     cargo test --release --test fuzz -- --ignored --test-threads=1

use cncsim::program::{
    parse_apt, parse_gcode, parse_hpgl, Program, ProgramErrors, ReadOptions, ToolSpec,
};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};

fn cases(variable: &str, default: u32) -> u32 {
    std::env::var(variable)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn config(cases: u32) -> Config {
    Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    }
}

/// What every result must satisfy: finite positions, or well-formed errors.
fn check(result: Result<Program, ProgramErrors>, source: &str) {
    match result {
        Ok(program) => {
            for mv in &program.moves {
                assert!(
                    mv.end
                        .linear
                        .iter()
                        .chain(&mv.end.rotary)
                        .all(|c| c.is_finite()),
                    "{mv:?}"
                );
                assert!(mv.span.line >= 1 && mv.span.column >= 1, "{mv:?}");
            }
        }
        Err(errors) => {
            assert!(!errors.errors.is_empty());
            for error in &errors.errors {
                let message = error.to_string();
                assert!(message.starts_with(source), "{message}");
                if let Some(span) = error.span {
                    assert!(span.line >= 1 && span.column >= 1, "{message}");
                }
            }
        }
    }
}

fn run_gcode(bytes: &[u8]) {
    // Loops may run long or forever: bound each case well below the defaults.
    let mut options = ReadOptions::default();
    options.gcode.max_blocks = 200_000;
    options.gcode.max_moves = 50_000;
    options.gcode.tools = vec![ToolSpec {
        number: 1,
        diameter: 0.006,
        ..ToolSpec::default()
    }];
    check(parse_gcode(bytes, "f.ngc", &options), "f.ngc");
}

fn run_hpgl(bytes: &[u8]) {
    let mut options = ReadOptions::default();
    check(parse_hpgl(bytes, "f.plt", &options), "f.plt");
    options.hpgl.optimise_pen_up = true;
    options.hpgl.lenient = true;
    options.hpgl.strict = true;
    options.hpgl.hatch_fills = false;
    check(parse_hpgl(bytes, "f.plt", &options), "f.plt");
}

fn run_apt(bytes: &[u8]) {
    let mut options = ReadOptions::default();
    check(parse_apt(bytes, "f.apt", &options), "f.apt");
    options.apt.strict = true;
    check(parse_apt(bytes, "f.apt", &options), "f.apt");
}

/// A number as programs write them, or a broken one.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        (-500i64..500).prop_map(|n| n.to_string()),
        any::<f64>().prop_map(|x| format!("{x}")),
        (-1e4f64..1e4).prop_map(|x| format!("{x:.4}")),
        Just("-".to_string()),
        Just(".".to_string()),
        Just("1e5".to_string()),
        Just("99999999999".to_string()),
    ]
}

/// Structured garbage: a sequence of vocabulary tokens and numbers.
fn sentence(vocabulary: &'static [&'static str]) -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(
        prop_oneof![
            3 => prop::sample::select(vocabulary).prop_map(str::to_string),
            2 => number(),
            1 => any::<u8>().prop_map(|b| (b as char).to_string()),
        ],
        0..60,
    )
    .prop_map(|parts| parts.concat().into_bytes())
}

const GCODE_WORDS: &[&str] = &[
    "G0",
    "G1",
    "G2",
    "G3",
    "G4",
    "G17",
    "G18",
    "G19",
    "G20",
    "G21",
    "G90",
    "G91",
    "G90.1",
    "G91.1",
    "G93",
    "G94",
    "G61",
    "G64",
    "G80",
    "M2",
    "M3",
    "M4",
    "M5",
    "M30",
    "X",
    "Y",
    "Z",
    "A",
    "B",
    "C",
    "I",
    "J",
    "K",
    "R",
    "P",
    "F",
    "S",
    "N",
    "(",
    ")",
    ";",
    "%",
    "/",
    " ",
    "\n",
    "\n",
    "\r\n",
    // Parameters and expressions.
    "#1",
    "#2",
    "#<a>",
    "#<_g>",
    "#[",
    "=",
    "[",
    "]",
    "+",
    "-",
    "*",
    "/",
    "**",
    "MOD",
    "EQ",
    "NE",
    "LT",
    "GT",
    "AND",
    "OR",
    "XOR",
    "SIN[",
    "ATAN[1]/[",
    "SQRT[",
    "EXISTS[#<a>]",
    "ROUND[",
    "#<_x>",
    "#5420",
    "@",
    "^",
    // O-word control flow.
    "o100 sub",
    "o100 endsub",
    "o100 call [1] [2]",
    "o100 return",
    "o<s> sub",
    "o<s> endsub",
    "o<s> call",
    "o1 while [#1 LT 3]",
    "o1 endwhile",
    "o2 if [#1]",
    "o2 elseif [1]",
    "o2 else",
    "o2 endif",
    "o3 repeat [3]",
    "o3 endrepeat",
    "o4 do",
    "o4 while [0]",
    "o1 break",
    "o1 continue",
    "o5 while [1]",
    "o5 endwhile",
    // Offsets, tools, homes, cycles, compensation.
    "G10 L2 P1",
    "G10 L20 P0",
    "G10 L1 P1",
    "G54",
    "G55",
    "G59.3",
    "G92",
    "G92.1",
    "G92.2",
    "G92.3",
    "G52",
    "G53",
    "G28",
    "G30",
    "G28.1",
    "T1",
    "M6",
    "M61 Q1",
    "G43",
    "G43.1",
    "G49",
    "H1",
    "G81",
    "G82",
    "G83",
    "G73",
    "G85",
    "G89",
    "G98",
    "G99",
    "L",
    "Q",
    "G41",
    "G42",
    "G41.1",
    "G40",
    "D1",
    "(MSG,hi)",
    "(ABORT,stop)",
];
const HPGL_WORDS: &[&str] = &[
    "IN",
    "DF",
    "SC",
    "IP",
    "IR",
    "SP",
    "PU",
    "PD",
    "PA",
    "PR",
    "VS",
    "LT",
    "CI",
    "AA",
    "AR",
    "AT",
    "RT",
    "BZ",
    "BR",
    "LB",
    "BL",
    "PB",
    "DT",
    "DI",
    "DR",
    "SI",
    "SR",
    "SL",
    "ES",
    "LO",
    "CP",
    "SM",
    "RA",
    "RR",
    "EA",
    "ER",
    "EW",
    "WG",
    "FT",
    "PT",
    "PW",
    "WU",
    "PM",
    "PM0",
    "PM1",
    "PM2",
    "EP",
    "FP",
    "RO",
    "RO90",
    "PS",
    "IW",
    "CT",
    "XT",
    "YT",
    "TL",
    "PE",
    "PE<=",
    "PE>",
    "PE:",
    "PG",
    "EC",
    "CO\"",
    "BP",
    "NP",
    "SC0,1,0,1,1",
    "SC0,2,0,2,2",
    ";",
    ";",
    ",",
    ",",
    " ",
    "\n",
    "\"",
    "\x1b.(",
    "\x1b.I81;;17:",
    "\x1b.N;19:",
    "\x1b",
    "\x1b%-1B",
    "\x1b%0A",
    "\x1b%-12345X",
    "@PJL ENTER LANGUAGE=HPGL2\r\n",
    "\x1bE",
    "\x1b*b4W",
    "\x1b&l0O",
    "\x03",
    "\r",
    "\x08",
    "\u{bf}",
    "\u{ff}",
    "?",
    "~",
];
const APT_WORDS: &[&str] = &[
    "GOTO/",
    "GODLTA/",
    "FROM/",
    "FEDRAT/",
    "RAPID",
    "UNITS/MM",
    "UNITS/INCHES",
    "FINI",
    "$$",
    "$",
    "\n",
    "\n",
    ",",
    ",",
    ",",
    "SPINDL/",
    "CLW",
    "MULTAX",
    "PARTNO",
    "IPM",
    "MMPM",
    "/",
    "CIRCLE/",
    "TIMES",
    "MSYS/",
    "TLAXIS/",
    "DELAY/",
    "REV",
    "GOHOME",
    "TOOL PATH/",
    "END-OF-PATH",
    "TLDATA/MILL",
    "PAINT/COLOR",
    "LOAD/TOOL",
    "CUTCOM/LEFT",
    "CYCLE/DRILL",
    "0,0,1",
    "0,0,-1",
    "0.7071068,0.7071068,0",
];

fn fuzz(cases: u32, strategy: impl Strategy<Value = Vec<u8>>, run: fn(&[u8])) {
    let mut runner = TestRunner::new(config(cases));
    runner
        .run(&strategy, |bytes| {
            run(&bytes);
            Ok(())
        })
        .unwrap();
}

fn raw_bytes() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(any::<u8>(), 0..200)
}

macro_rules! fuzz_tests {
    ($quick_raw:ident, $quick_structured:ident, $million:ident, $words:ident, $run:ident) => {
        #[test]
        fn $quick_raw() {
            fuzz(cases("PROPTEST_CASES", 5000), raw_bytes(), $run);
        }

        #[test]
        fn $quick_structured() {
            fuzz(cases("PROPTEST_CASES", 5000), sentence($words), $run);
        }

        #[test]
        #[ignore = "long: a million generated inputs; run in release"]
        fn $million() {
            let per_generator = cases("FUZZ_CASES", 500_000);
            let started = std::time::Instant::now();
            fuzz(per_generator, raw_bytes(), $run);
            fuzz(per_generator, sentence($words), $run);
            eprintln!(
                "{}: {} inputs in {:.1} s",
                stringify!($million),
                2 * u64::from(per_generator),
                started.elapsed().as_secs_f64()
            );
        }
    };
}

fuzz_tests!(
    gcode_raw_bytes,
    gcode_structured,
    gcode_million,
    GCODE_WORDS,
    run_gcode
);
fuzz_tests!(
    hpgl_raw_bytes,
    hpgl_structured,
    hpgl_million,
    HPGL_WORDS,
    run_hpgl
);
fuzz_tests!(
    apt_raw_bytes,
    apt_structured,
    apt_million,
    APT_WORDS,
    run_apt
);
