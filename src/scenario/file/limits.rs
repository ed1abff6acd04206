//! Ranges of a scenario's numbers, in the units of their keys (inclusive). Outside them a value
//! is refused with its place in the file; a run's length is bounded besides by
//! [`crate::sim::MAX_SERVO_TICKS`] and [`crate::sim::MAX_PHYSICS_STEPS`].

/// Servo period (ms): from 100 kHz drives to the slowest seed document (20 ms) with margin.
pub const SERVO_PERIOD_MS: (f64, f64) = (0.01, 100.0);
/// Physics step (ms); it must also divide the servo period.
pub const PHYSICS_STEP_MS: (f64, f64) = (0.001, 100.0);
/// Most physics steps per servo period.
pub const MAX_SUBSTEPS: usize = 10_000;
/// Settle time before the program (s).
pub const SETTLE_S: (f64, f64) = (0.0, 3600.0);
/// Path speeds: built-in path feed, rapid speed (mm/s). No machine tool moves 20 m/s.
pub const SPEED_MM_S: (f64, f64) = (1e-3, 2e4);
/// Above this a feed loads with a warning (mm/s).
pub const SUSPECT_SPEED_MM_S: f64 = 5e3;
/// Trapezoid path acceleration (mm/s²).
pub const ACCELERATION_MM_S2: (f64, f64) = (1e-3, 1e7);
/// Jerk-limited planner limits per axis, mm or deg per s, s², s³.
pub const LIMIT_VELOCITY: (f64, f64) = (1e-3, 1e5);
/// Jerk-limited planner acceleration limit per axis (mm/s², or deg/s² on a rotary axis).
pub const LIMIT_ACCELERATION: (f64, f64) = (1e-3, 1e8);
/// Jerk-limited planner jerk limit per axis (mm/s³, or deg/s³ on a rotary axis).
pub const LIMIT_JERK: (f64, f64) = (1e-3, 1e11);
/// Corner tolerance (mm).
pub const TOLERANCE_MM: (f64, f64) = (1e-6, 100.0);
/// Coordinates and radii of built-in paths and pen heights (|value| ≤, mm): 100 m.
pub const COORDINATE_MM: f64 = 1e5;
/// Following-error fault limits.
pub const FOLLOWING_ERROR_LIMIT_MM: (f64, f64) = (1e-6, 1e3);
/// Following-error fault limit of rotary axes (deg).
pub const FOLLOWING_ERROR_LIMIT_DEG: (f64, f64) = (1e-6, 360.0);
/// PID gains (≥ 0) and output limits.
pub const MAX_GAIN: f64 = 1e12;
/// Inverse dynamics: closed-loop natural frequency (Hz), damping ratio, model mass scale,
/// task-space least-squares damping.
pub const NATURAL_FREQUENCY_HZ: (f64, f64) = (1e-3, 1e4);
/// Inverse dynamics: closed-loop damping ratio (dimensionless).
pub const DAMPING_RATIO: (f64, f64) = (1e-3, 100.0);
/// Inverse dynamics: scale on the controller model's link masses and inertias.
pub const MODEL_MASS_SCALE: (f64, f64) = (1e-3, 100.0);
/// Task-space controller: least-squares damping λ of the Jacobian's inverse.
pub const TASK_DAMPING: (f64, f64) = (1e-9, 10.0);
/// Recording decimation (record every k-th tick).
pub const MAX_DECIMATION: i64 = 1_000_000;
/// PID error limits and deadband (m or rad).
pub const MAX_ERROR: f64 = 1.0;
/// Cascade feed-forward shares (1 = the whole setpoint velocity or inertia torque).
pub const MAX_FEED_FORWARD_SHARE: f64 = 2.0;
/// Cut-off of the cascade's velocity estimate (Hz).
pub const VELOCITY_FILTER_HZ: (f64, f64) = (0.0, 1e6);
/// Compensated backlash.
pub const MAX_BACKLASH_MM: f64 = 100.0;
/// Compensated backlash of rotary axes (deg).
pub const MAX_BACKLASH_DEG: f64 = 90.0;
/// Spindle speed (rev/min): from a hand-turned spindle to the fastest HSC spindles.
pub const SPINDLE_RPM: (f64, f64) = (1.0, 200_000.0);
/// Stock resolution (mm): the dexel spacing.
pub const STOCK_RESOLUTION_MM: (f64, f64) = (1e-3, 10.0);
/// Tool diameters, flute lengths and corner radii (mm).
pub const TOOL_DIAMETER_MM: (f64, f64) = (0.01, 500.0);
/// Most flutes of a cutter.
pub const MAX_FLUTES: i64 = 64;
/// Helix angle (deg).
pub const HELIX_DEG: (f64, f64) = (0.0, 75.0);
