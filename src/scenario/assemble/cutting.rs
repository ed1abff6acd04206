//! The scenario's cut on its machine: the tool with its diameter resolved, the stock's frame
//! on the part, the spindle speed of every program move, and the memory the stocks will take,
//! checked before anything is allocated.

use super::RunError;
use crate::cutting::{cut::Cut, CuttingSpec, ForceModel, Stock, Tool};
use crate::diagnostics::FileError;
use crate::kinematics::{PartPlacement, ProgramFrame};
use crate::machine::Machine;
use crate::program::{Program, Spindle};
use crate::scenario::Scenario;
use crate::sim::cut::PlantCut;
use crate::sim::Spindles;
use nalgebra::Point3;
use std::f64::consts::PI;

/// Copies of the stock a run holds at once: the physics lane's, the analytic lane's and the
/// nominal part's.
const STOCK_COPIES: u64 = 3;

/// What every lane of a run needs to make its own cut.
#[derive(Debug, Clone)]
pub struct CutSetup {
    /// The scenario's `[cutting]`.
    pub spec: CuttingSpec,
    /// The tool, its diameter resolved.
    pub tool: Tool,
    /// The stock's frame on the part, the tool's axis on the tool.
    pub placement: PartPlacement,
    /// The stock as the run starts (each lane cuts a copy).
    pub stock: Stock,
}

impl CutSetup {
    /// A fresh cut of the starting stock.
    pub fn cut(&self) -> Cut {
        let model = ForceModel::new(self.tool, self.spec.coefficients)
            .expect("checked when the setup was made");
        Cut::new(self.stock.clone(), model, self.tool)
    }

    /// A fresh cut placed on the part, for a plant.
    pub fn plant_cut(&self) -> PlantCut {
        PlantCut::new(self.cut(), self.placement.stock_in_part)
    }
}

/// The cut of scenario `s` (`None` without `[cutting]`), the program starting at joint
/// coordinates `start`.
pub(super) fn cut_setup(
    s: &Scenario,
    machine: &Machine,
    frame: &ProgramFrame,
    program: &Program,
    start: &[f64],
) -> Result<Option<CutSetup>, RunError> {
    let Some(spec) = &s.cutting else {
        return Ok(None);
    };
    let error = |message: String| RunError::from(FileError::new(&s.path, None, message));
    let diameter = match spec.tool.diameter {
        Some(d) => d,
        None => program
            .tools
            .iter()
            .map(|t| t.diameter)
            .find(|&d| d > 0.0)
            .ok_or_else(|| {
                error("[cutting.tool]: the program describes no tool with a diameter (a CL file's TLDATA, or a G-code tool table's tool loaded with M6): give diameter_mm".into())
            })?,
    };
    let size = spec.stock.max - spec.stock.min;
    if spec.stock.stl.is_none() && diameter > size.max() {
        return Err(error(format!(
            "[cutting.tool]: the program's tool is {:?} mm wide, wider than every side of the stock",
            diameter * 1e3
        )));
    }
    let tool = spec.tool.with_diameter(diameter);
    ForceModel::new(tool, spec.coefficients).map_err(|e| error(format!("[cutting]: {e}")))?;
    if frame.directions.determinant() < 0.0 {
        return Err(error("[cutting]: the machine's program axes are left-handed (see `cncsim machine check`); a stock cannot be laid out in them".into()));
    }
    let limit = memory_limit();
    let stock = match &spec.stock.stl {
        Some(path) => {
            let triangles = read_stl(path)?;
            let (lo, hi) = bounds(&triangles);
            check_memory(
                s,
                Stock::estimate_bytes(lo, hi, spec.stock.resolution),
                limit,
            )?;
            Stock::from_triangles(&triangles, spec.stock.resolution, limit / STOCK_COPIES)
                .map_err(|e| RunError::from(FileError::new(path, None, e.to_string())))?
        }
        None => {
            let st = &spec.stock;
            check_memory(
                s,
                Stock::estimate_bytes(st.min, st.max, st.resolution),
                limit,
            )?;
            Stock::from_box(st.min, st.max, st.resolution, limit / STOCK_COPIES)
                .map_err(|e| error(format!("[cutting.stock]: {e}")))?
        }
    };
    let placement = PartPlacement::new(machine, frame, s.program.work_offset, start);
    Ok(Some(CutSetup {
        spec: spec.clone(),
        tool,
        placement,
        stock,
    }))
}

/// The spindle speed of every program move (rad/s, > 0 for M3), and the moves' lines: as the
/// program says, or the scenario's `spindle_rpm` turning as M3 where the program never starts
/// the spindle.
pub(super) fn spindles(s: &Scenario, program: &Program) -> Spindles {
    let rad_s = |rpm: f64| rpm * 2.0 * PI / 60.0;
    let programmed = starts_spindle(program);
    let fallback = s.cutting.as_ref().and_then(|c| c.spindle_rpm);
    let speed = program
        .moves
        .iter()
        .map(|m| match (m.spindle, programmed, fallback) {
            (Spindle::Clockwise { rpm }, _, _) => rad_s(rpm),
            (Spindle::CounterClockwise { rpm }, _, _) => -rad_s(rpm),
            (Spindle::Off, false, Some(rpm)) => rad_s(rpm),
            (Spindle::Off, _, _) => 0.0,
        })
        .collect();
    Spindles {
        speed,
        line: program.moves.iter().map(|m| m.span.line as usize).collect(),
    }
}

/// Whether the program turns no spindle and the scenario gives no speed either: a cut needs
/// one. Returns the message.
pub(super) fn missing_spindle(s: &Scenario, program: &Program) -> Option<String> {
    let cutting = s.cutting.as_ref()?;
    (!starts_spindle(program) && cutting.spindle_rpm.is_none()).then(|| {
        "[cutting]: the program never starts the spindle (S with M3/M4, or SPINDL): give [cutting] spindle_rpm".to_string()
    })
}

/// Whether the program turns the spindle anywhere.
fn starts_spindle(program: &Program) -> bool {
    program
        .moves
        .iter()
        .any(|m| !matches!(m.spindle, Spindle::Off))
}

fn check_memory(s: &Scenario, estimate: u64, limit: u64) -> Result<(), RunError> {
    let need = estimate.saturating_mul(STOCK_COPIES);
    if need > limit {
        return Err(FileError::new(
            &s.path,
            None,
            format!(
                "[cutting.stock]: the stock at this resolution takes about {:.0} MB ({} copies of {:.0} MB: the physics', the analytic lane's and the nominal part's), more than the {:.0} MB this machine has free: raise resolution_mm or shrink the stock",
                need as f64 / 1e6,
                STOCK_COPIES,
                estimate as f64 / 1e6,
                limit as f64 / 1e6
            ),
        )
        .into());
    }
    Ok(())
}

/// The memory a run may give its stocks: what the system reports free (Linux), else 4 GB.
fn memory_limit() -> u64 {
    let fallback = 4_000_000_000;
    let Ok(text) = std::fs::read_to_string("/proc/meminfo") else {
        return fallback;
    };
    text.lines()
        .find_map(|l| {
            let rest = l.strip_prefix("MemAvailable:")?;
            let kb: u64 = rest.trim().trim_end_matches("kB").trim().parse().ok()?;
            Some(kb * 1024)
        })
        .unwrap_or(fallback)
}

/// The triangles of the stock's starting shape (an STL, OBJ or COLLADA mesh in mm, read as
/// metres by the reader machines' meshes go through).
fn read_stl(path: &std::path::Path) -> Result<Vec<[Point3<f64>; 3]>, RunError> {
    let mesh = crate::machine::read_mesh(path, [1e-3; 3]).map_err(|m| {
        RunError::from(FileError::new(
            path,
            None,
            format!("the stock's shape: {m}"),
        ))
    })?;
    let vertex = |i: u32| {
        let p = mesh.vertices[i as usize];
        Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
    };
    let triangles: Vec<_> = mesh.triangles.iter().map(|t| t.map(vertex)).collect();
    if triangles.is_empty() {
        return Err(FileError::new(path, None, "the stock's shape has no triangles").into());
    }
    Ok(triangles)
}

fn bounds(triangles: &[[Point3<f64>; 3]]) -> (Point3<f64>, Point3<f64>) {
    let mut lo = Point3::from([f64::INFINITY; 3]);
    let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
    for p in triangles.iter().flatten() {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (lo, hi)
}
