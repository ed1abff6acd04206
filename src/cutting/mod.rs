//! The cutting process, a block inside the servo loop beside the plant: every physics step it
//! takes the tool's pose and velocity on the part, finds where the flutes meet the stock,
//! returns the force on the tool and the part, and removes what the tool swept. Plain geometry
//! and mechanics in SI units: it knows nothing of Rapier, and serves the physics and the
//! analytic lane alike.
//!
//! - [`tool`]: the cutter's shape and where it stands on the part;
//! - [`material`]: cutting-force coefficients and the table of published ones;
//! - [`force`]: the linear edge-force mechanistic model (Altintas), per flute and axial slice;
//! - [`process`]: a cut over time (the spindle turning, forces averaged over each step);
//! - [`stock`]: the workpiece as tri-dexels and the removal of what the tool sweeps;
//! - [`surface`]: the stock's surface (marching cubes on the dexel lattice), STL;
//! - [`compare`]: the part as cut against the nominal part, point by point;
//! - [`cut`]: one lane's cut over a run (stock, force model and removal together).

pub mod compare;
pub mod cut;
pub mod force;
pub mod material;
pub mod process;
pub mod stock;
pub mod surface;
pub mod tool;

pub use compare::{compare, SurfaceComparison, SurfacePoint};
pub use cut::{Cut, CutTotals};
pub use force::{EdgeForces, ForceModel, Material};
pub use material::{material, Coefficients, MaterialEntry, MATERIALS};
pub use process::{CutProcess, StepForces};
pub use stock::{Stock, StockError};
pub use surface::{
    mesh_volume, write_binary_stl, write_binary_stl_triangles, IndexedMesh, SurfaceTriangles,
};
pub use tool::{Pose, Tool, ToolShape};

use nalgebra::Point3;
use std::path::PathBuf;

/// The stock a scenario starts from (program frame at the program's start, m).
#[derive(Debug, Clone, PartialEq)]
pub struct StockSpec {
    /// Lowest corner of the box (m); with only an STL, its bounds are used.
    pub min: Point3<f64>,
    /// Highest corner of the box (m).
    pub max: Point3<f64>,
    /// Dexel spacing (m).
    pub resolution: f64,
    /// A closed STL mesh (mm, program frame) as the starting shape instead of the box.
    pub stl: Option<PathBuf>,
}

/// The tool as a scenario gives it; the diameter may come from the program's tool.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolSpec {
    /// Diameter (m); `None`: the diameter of the tool the program names.
    pub diameter: Option<f64>,
    /// Number of flutes.
    pub flutes: u32,
    /// Helix angle (rad).
    pub helix: f64,
    /// Fluted length (m).
    pub flute_length: f64,
    /// The end's shape.
    pub shape: ToolShape,
}

impl ToolSpec {
    /// The tool with its diameter.
    pub fn with_diameter(&self, diameter: f64) -> Tool {
        Tool {
            diameter,
            flutes: self.flutes,
            helix: self.helix,
            flute_length: self.flute_length,
            shape: self.shape,
        }
    }
}

/// What a scenario's `[cutting]` says: plain data, SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct CuttingSpec {
    /// The stock.
    pub stock: StockSpec,
    /// The tool.
    pub tool: ToolSpec,
    /// The material's cutting-force coefficients.
    pub coefficients: Coefficients,
    /// The material's name in the table, where it came from there.
    pub material_name: Option<String>,
    /// Spindle speed when the program gives none (rev/min).
    pub spindle_rpm: Option<f64>,
}
