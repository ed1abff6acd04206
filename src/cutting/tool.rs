//! The cutter: its shape, flutes and helix, and where it stands on the part.
//!
//! Everything in SI units (m, rad). The tool's local frame has its origin at the tip (the
//! lowest point of the tool on its axis) and its axis pointing from the tip toward the spindle.

use nalgebra::{Point3, Unit, Vector3};

/// The end of the cutter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ToolShape {
    /// A flat end mill: a cylinder with a flat bottom.
    Flat,
    /// A ball end mill: a cylinder on a hemisphere of the tool's radius.
    Ball,
    /// A bull-nose (toroidal) end mill: a flat bottom of radius R − r rounded by corners of
    /// radius r.
    Bull {
        /// Corner radius r (m), 0 < r < R.
        corner_radius: f64,
    },
}

/// A milling cutter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tool {
    /// Diameter D = 2R (m).
    pub diameter: f64,
    /// Number of flutes (teeth) N ≥ 1, evenly spaced (pitch 2π/N).
    pub flutes: u32,
    /// Helix angle β (rad), 0 ≤ β < π/2; 0 is a straight-flute tool.
    pub helix: f64,
    /// Length of the fluted part from the tip (m): no cutting above it (the shank above it
    /// still removes material, as a cylinder of the tool's diameter, and is reported).
    pub flute_length: f64,
    /// The end's shape.
    pub shape: ToolShape,
}

impl Tool {
    /// Radius R (m).
    pub fn radius(&self) -> f64 {
        0.5 * self.diameter
    }

    /// Corner radius of the end: 0 for flat, R for ball, r for bull nose (m).
    pub fn corner_radius(&self) -> f64 {
        match self.shape {
            ToolShape::Flat => 0.0,
            ToolShape::Ball => self.radius(),
            ToolShape::Bull { corner_radius } => corner_radius,
        }
    }

    /// Radius of the tool's envelope (its solid of revolution) at height `z` above the tip
    /// (m); 0 below the tip.
    pub fn envelope_radius(&self, z: f64) -> f64 {
        let big = self.radius();
        let r = self.corner_radius();
        if z < 0.0 {
            return 0.0;
        }
        if z >= r {
            return big;
        }
        // On the corner's arc: centre at height r, at radius R − r.
        let dz = r - z;
        (big - r) + (r * r - dz * dz).max(0.0).sqrt()
    }

    /// Whether the tool cuts at its centre (ball: yes; flat and bull nose: an end mill's
    /// centre is where its flutes meet, and a plunge is drilling, which this model does not
    /// cover).
    pub fn cuts_at_centre(&self) -> bool {
        matches!(self.shape, ToolShape::Ball)
    }
}

/// Where the tool stands on the part: its tip and its axis in the part's (stock's) frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// The tool tip (m).
    pub tip: Point3<f64>,
    /// Unit vector from the tip toward the spindle.
    pub axis: Unit<Vector3<f64>>,
}
