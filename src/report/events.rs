//! What happened during a run worth a line in the recording's event log: the program start,
//! move boundaries and exact stops, backlash crossings (the drive side reaching the other end
//! of the gap), stick-slip stalls. The run-level ones (largest errors, breaches, the stop) are
//! added when the run ends. Each kind is capped, so a long program's log stays readable and
//! bounded; the cap is said in the log.

use crate::sim::TickRecord;

/// Most events of one kind kept in the log.
pub const MAX_EVENTS_PER_KIND: usize = 200;

/// An entry for the log.
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    /// When it happened: the tick's program time (s).
    pub time: f64,
    /// Rerun's text-log level: "INFO", "WARN", "ERROR", "DEBUG".
    pub level: &'static str,
    /// The log line.
    pub text: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Move,
    Stop,
    Backlash,
    Stall,
}

const KINDS: usize = 4;

/// Finds events in the primary lane's ticks.
#[derive(Debug, Clone)]
pub struct EventDetector {
    axis_names: Vec<String>,
    /// Backlash per axis (joint units; 0 = none).
    backlash: Vec<f64>,
    /// Source line and byte offset of each program move.
    move_sources: Vec<(u32, u32)>,
    /// Which end of the gap each axis's drive was last at (+1, −1; 0 not yet).
    side: Vec<f64>,
    segment: Option<u32>,
    moving: bool,
    counts: [usize; KINDS],
}

impl EventDetector {
    /// A detector for axes `axis_names` with their backlash (joint units; 0: none, no
    /// crossings looked for) and the source line and byte offset of each program move.
    pub fn new(
        axis_names: &[String],
        backlash: &[f64],
        move_sources: Vec<(u32, u32)>,
    ) -> EventDetector {
        EventDetector {
            axis_names: axis_names.to_vec(),
            backlash: backlash.to_vec(),
            move_sources,
            side: vec![0.0; axis_names.len()],
            segment: None,
            moving: false,
            counts: [0; KINDS],
        }
    }

    fn push(
        &mut self,
        out: &mut Vec<Event>,
        kind: Kind,
        time: f64,
        level: &'static str,
        text: String,
    ) {
        let count = &mut self.counts[kind as usize];
        *count += 1;
        if *count < MAX_EVENTS_PER_KIND {
            out.push(Event { time, level, text });
        } else if *count == MAX_EVENTS_PER_KIND {
            out.push(Event {
                time,
                level: "DEBUG",
                text: format!(
                    "{:?} events: the first {MAX_EVENTS_PER_KIND} are logged, later ones are not",
                    kind
                ),
            });
        }
    }

    /// The events of a primary-lane tick; `stalled` has a bit per axis that stalled on it.
    pub fn observe(&mut self, r: &TickRecord<'_>, stalled: u64, out: &mut Vec<Event>) {
        let sp = r.setpoint;
        if self.segment != Some(sp.segment) {
            let source = |segment: u32| self.move_sources.get(segment as usize).copied();
            let (line, _) = source(sp.segment).unwrap_or((0, 0));
            // The pieces of one programmed move (a tool-tip move held on its path) are one
            // move to the reader.
            let same_move = self
                .segment
                .is_some_and(|s| source(s).is_some() && source(s) == source(sp.segment));
            let text = if self.segment.is_none() {
                format!("program start: move {} (line {line})", sp.segment)
            } else {
                format!("move {} (line {line})", sp.segment)
            };
            if !same_move {
                self.push(out, Kind::Move, r.time, "DEBUG", text);
            }
            self.segment = Some(sp.segment);
        }
        let moving = sp.velocity.iter().any(|v| *v != 0.0);
        if self.moving && !moving {
            let text = format!("exact stop at the end of move {}", sp.segment);
            self.push(out, Kind::Stop, r.time, "INFO", text);
        }
        self.moving = moving;
        for i in 0..self.axis_names.len() {
            let b = self.backlash[i];
            if b > 0.0 {
                // The gap is at an end when within 5 % of b/2 of it.
                let gap = r.sensors.drive_position[i] - r.sensors.position[i];
                let side = if gap > 0.45 * b {
                    1.0
                } else if gap < -0.45 * b {
                    -1.0
                } else {
                    self.side[i]
                };
                if side != self.side[i] && self.side[i] != 0.0 {
                    let text = format!(
                        "{}: backlash crossed, the drive now pushes {}",
                        self.axis_names[i],
                        if side > 0.0 { "forward" } else { "backward" }
                    );
                    self.push(out, Kind::Backlash, r.time, "INFO", text);
                }
                self.side[i] = side;
            }
            if i < 64 && stalled & (1 << i) != 0 {
                let text = format!(
                    "{}: stalled (stick-slip) while commanded to move",
                    self.axis_names[i]
                );
                self.push(out, Kind::Stall, r.time, "WARN", text);
            }
        }
    }
}
