//! A program planned for running. The plan is made once, to check it and count its samples;
//! each run then reads its setpoints as a fresh stream computed as it is read, so no sample is
//! kept and a run's memory does not grow with the program's duration.

use super::from_program::{plan_program_stream, PlanSettings};
use super::setpoints::{LookAhead, SetpointSample, SetpointStream, Setpoints};
use super::stream::collect;
use super::PlanError;
use crate::kinematics::AxisMap;
use crate::program::Program;
use std::sync::Arc;

/// A program with the settings it was planned with, what planning it showed (its number of
/// samples and first point), and the means to stream its setpoints again. Cloning shares the
/// program.
#[derive(Debug, Clone)]
pub struct PlannedProgram {
    program: Arc<Program>,
    axes: AxisMap,
    settings: PlanSettings,
    samples: usize,
    first: Option<Vec<f64>>,
    look_ahead: LookAhead,
}

impl PlannedProgram {
    /// Plans `program` on the machine axes `axes` (an error if it cannot be planned).
    pub fn new(
        program: Program,
        axes: AxisMap,
        settings: PlanSettings,
    ) -> Result<PlannedProgram, PlanError> {
        let (samples, first, look_ahead) = {
            let mut stream = plan_program_stream(&program, &axes, &settings)?;
            let mut sample = SetpointSample::zeros(stream.axes());
            let first = stream.next_sample(&mut sample).then_some(sample.position);
            (stream.len(), first, stream.look_ahead())
        };
        Ok(PlannedProgram {
            program: Arc::new(program),
            axes,
            settings,
            samples,
            first,
            look_ahead,
        })
    }

    /// How the program's coordinates map onto the machine's axes.
    pub fn axis_map(&self) -> &AxisMap {
        &self.axes
    }

    /// The program as planned.
    pub fn program(&self) -> &Program {
        &self.program
    }

    /// The settings it was planned with.
    pub fn settings(&self) -> &PlanSettings {
        &self.settings
    }

    /// Number of setpoint samples (ticks of the program).
    pub fn len(&self) -> usize {
        self.samples
    }

    /// Whether there are no setpoint samples.
    pub fn is_empty(&self) -> bool {
        self.samples == 0
    }

    /// What the jerk-limited planner's look-ahead did with chains longer than it.
    pub fn look_ahead(&self) -> LookAhead {
        self.look_ahead
    }

    /// The first setpoint's position, if there is one.
    pub fn first_position(&self) -> Option<&[f64]> {
        self.first.as_deref()
    }

    /// The setpoints from the first sample, computed as they are read.
    pub fn stream(&self) -> Box<dyn SetpointStream + Send + '_> {
        plan_program_stream(&self.program, &self.axes, &self.settings)
            .expect("planning is deterministic: a program planned once plans again")
    }

    /// Every sample in memory (for short studies: memory grows with the program's duration).
    pub fn collect(&self) -> Setpoints {
        collect(self.stream().as_mut())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::{FirstSamples, Planner};
    use crate::program::{Feed, FeedRule, Motion, Move, Position};

    fn line_program() -> Program {
        let at = |x: f64| Position {
            linear: [x, 0.0, 0.0],
            rotary: Default::default(),
        };
        Program {
            start: at(0.0),
            moves: vec![Move {
                motion: Motion::Linear,
                end: at(0.01),
                tool_axis: None,
                feed: Feed::PathSpeed(0.005),
                feed_rule: FeedRule::LinuxCnc,
                blend: crate::program::Blend::ExactStop,
                tool_down: None,
                spindle: crate::program::Spindle::Off,
                span: Default::default(),
            }],
            ..Default::default()
        }
    }

    #[test]
    fn every_stream_of_a_plan_is_the_same_and_matches_its_count() {
        let program = line_program();
        let axes = AxisMap::from_sources(vec![(true, 0), (true, 1), (true, 2)]);
        let settings = PlanSettings {
            planner: Planner::ConstantVelocity,
            period: 1e-3,
            rapid_speed: 0.02,
            blend: Default::default(),
            axis_names: vec!["x".into(), "y".into(), "z".into()],
            naive_cam_tolerance: None,
            tool_lever_arms: Vec::new(),
        };
        let plan = PlannedProgram::new(program, axes, settings).unwrap();
        let (a, b) = (plan.collect(), plan.collect());
        assert_eq!(a, b);
        // 10 mm at 5 mm/s: 2 s, 2001 samples from the start.
        assert_eq!(plan.len(), 2001);
        assert_eq!(a.len(), plan.len());
        assert_eq!(plan.first_position(), Some(a.position(0)));
        let mut first = FirstSamples::new(plan.stream(), 5);
        assert_eq!(first.len(), 5);
        let mut sample = SetpointSample::zeros(3);
        let mut read = 0;
        while first.next_sample(&mut sample) {
            read += 1;
        }
        assert_eq!(read, 5);
    }
}
