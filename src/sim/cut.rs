//! The cutting process as a plant runs it: the lane's own [`Cut`] (stock, force model,
//! removal), placed on the part, stepped every physics step with the tool's pose and velocity
//! on the part, and summed over each servo period for the observers.

use super::CutRecord;
use crate::cutting::{cut::pose, Cut};
use crate::model::CuttingLoad;
use nalgebra::{Isometry3, Point3, Vector3};

/// A plant's cut, placed on the part.
pub struct PlantCut {
    cut: Cut,
    /// The stock's frame in the frame of the link carrying the part, and its inverse.
    stock_in_part: Isometry3<f64>,
    part_to_stock: Isometry3<f64>,
    /// Spindle speed over the present period (rad/s, > 0 as M3).
    spindle: f64,
    fault: Option<String>,
    /// Sums over the present period.
    period: PeriodSums,
}

#[derive(Default)]
struct PeriodSums {
    steps: u32,
    force: Vector3<f64>,
    peak: f64,
    power: f64,
    torque: f64,
    flutes: u32,
}

impl PlantCut {
    /// `cut`, its stock laid out in the stock frame `stock_in_part` of the part's link.
    pub fn new(cut: Cut, stock_in_part: Isometry3<f64>) -> PlantCut {
        PlantCut {
            cut,
            stock_in_part,
            part_to_stock: stock_in_part.inverse(),
            spindle: 0.0,
            fault: None,
            period: PeriodSums::default(),
        }
    }

    /// The spindle speed over the coming period (rad/s).
    pub fn set_spindle(&mut self, speed: f64) {
        self.spindle = speed;
    }

    /// One physics step of length `dt`: the tool at `point` with its axis `axis`, moving at
    /// `velocity` relative to the part (all in the part link's frame). Returns the load on the
    /// machine over the step.
    pub fn step(
        &mut self,
        point: &Point3<f64>,
        axis: &Vector3<f64>,
        velocity: &Vector3<f64>,
        dt: f64,
    ) -> CuttingLoad {
        let to_stock = self.part_to_stock;
        let tool = pose(to_stock * point, to_stock * axis);
        let v = to_stock * velocity;
        let f = self.cut.step(&tool, &v, self.spindle, dt);
        if f.spindle_stopped_while_engaged && self.fault.is_none() {
            self.fault = Some(format!(
                "the tool engaged the stock with the spindle stopped (tool tip at [{:.3}, {:.3}, {:.3}] mm on the stock)",
                tool.tip.x * 1e3,
                tool.tip.y * 1e3,
                tool.tip.z * 1e3
            ));
        }
        let p = &mut self.period;
        p.steps += 1;
        p.force -= f.mean_on_tool;
        p.peak = p.peak.max(f.peak_force);
        p.power += f.mean_power;
        p.torque += f.mean_torque;
        p.flutes = p.flutes.max(f.engaged_flutes);
        // The part turns with the cutting edges: the tangential forces' moment about the
        // tool axis, in the sense the spindle turns (M3 turns about −axis).
        let sense = -self.spindle.signum();
        CuttingLoad {
            on_tool: self.stock_in_part * f.mean_on_tool,
            at: *point,
            torque_on_part: axis * (sense * f.mean_torque),
        }
    }

    /// Hands the period's sums to `out` and starts the next period.
    pub fn end_period(&mut self, out: &mut CutRecord) {
        let p = std::mem::take(&mut self.period);
        let n = f64::from(p.steps.max(1));
        *out = CutRecord {
            force: (p.force / n).into(),
            peak_force: p.peak,
            spindle_power: p.power / n,
            spindle_torque: p.torque / n,
            engaged_flutes: p.flutes,
        };
    }

    /// The stock as cut so far.
    pub fn stock(&self) -> &crate::cutting::Stock {
        self.cut.stock()
    }

    /// Why the cut cannot go on, if it cannot.
    pub fn fault(&self) -> Option<String> {
        self.fault
            .clone()
            .or_else(|| self.cut.fault().map(str::to_string))
    }

    /// The cut, its last sweep removed.
    pub fn into_cut(mut self) -> Cut {
        self.cut.finish();
        self.cut
    }
}
