//! The G and M codes LinuxCNC knows: their modal groups, and whether cncsim runs them (with
//! the reason shown when it does not).

/// Modal groups of G codes (LinuxCNC numbering; used as indices).
pub(super) mod group {
    pub const NON_MODAL: usize = 0;
    pub const MOTION: usize = 1;
    pub const PLANE: usize = 2;
    pub const DISTANCE: usize = 3;
    pub const ARC_DISTANCE: usize = 4;
    pub const FEED_MODE: usize = 5;
    pub const UNITS: usize = 6;
    pub const CUTTER_COMP: usize = 7;
    pub const TOOL_LENGTH: usize = 8;
    pub const RETURN_MODE: usize = 10;
    pub const COORD_SYSTEM: usize = 12;
    pub const PATH_CONTROL: usize = 13;
    pub const SPINDLE_MODE: usize = 14;
    pub const LATHE: usize = 15;
    pub const COUNT: usize = 16;

    pub fn name(group: usize) -> &'static str {
        match group {
            NON_MODAL => "non-modal codes",
            MOTION => "motion",
            PLANE => "plane selection",
            DISTANCE => "distance mode",
            ARC_DISTANCE => "arc centre distance mode",
            FEED_MODE => "feed rate mode",
            UNITS => "units",
            CUTTER_COMP => "cutter compensation",
            TOOL_LENGTH => "tool length offset",
            RETURN_MODE => "canned cycle return mode",
            COORD_SYSTEM => "coordinate system",
            PATH_CONTROL => "path control mode",
            SPINDLE_MODE => "spindle speed mode",
            LATHE => "lathe diameter mode",
            _ => "modal group",
        }
    }
}

/// Modal groups of M codes.
pub(super) mod mgroup {
    pub const STOP: usize = 0;
    pub const TOOL_CHANGE: usize = 1;
    pub const SPINDLE: usize = 2;
    pub const COOLANT: usize = 3;
    pub const OVERRIDE: usize = 4;
    pub const COUNT: usize = 5;

    pub fn name(group: usize) -> &'static str {
        match group {
            STOP => "stopping",
            TOOL_CHANGE => "tool change",
            SPINDLE => "spindle",
            COOLANT => "coolant",
            _ => "override switches",
        }
    }
}

/// Whether cncsim executes a code LinuxCNC knows.
pub(super) enum Support {
    Yes,
    /// Known to LinuxCNC, refused here, with the reason shown to the user.
    No(&'static str),
}

/// G code (in tenths: G64 = 640, G90.1 = 901) → modal group and support.
pub(super) fn g_code_info(tenths: u32) -> Option<(usize, Support)> {
    use Support::{No, Yes};
    let info = match tenths {
        0 | 10 | 20 | 30 | 800 => (group::MOTION, Yes),
        880 => (
            group::MOTION,
            No("G88 stops for the operator to retract the spindle by hand, which a simulation cannot do"),
        ),
        730 | 740 | 810..=890 if tenths.is_multiple_of(10) => (group::MOTION, Yes),
        50..=53 => (
            group::MOTION,
            No("spline and NURBS motion (G5.x) is not supported; post the path as lines and arcs"),
        ),
        330 | 331 | 760 => (
            group::MOTION,
            No("spindle-synchronised motion (G33, G33.1, G76) is not supported"),
        ),
        382..=385 => (group::MOTION, No("probing moves (G38.x) are not supported")),
        700 | 710..=712 | 720..=722 => (
            group::MOTION,
            No("lathe roughing cycles (G70-G72) are not supported"),
        ),
        40 | 100 | 280 | 281 | 300 | 301 | 520 | 530 | 920..=923 => (group::NON_MODAL, Yes),
        170 | 180 | 190 => (group::PLANE, Yes),
        171 | 181 | 191 => (group::PLANE, No("UVW planes are not supported")),
        900 | 910 => (group::DISTANCE, Yes),
        901 | 911 => (group::ARC_DISTANCE, Yes),
        930 | 940 => (group::FEED_MODE, Yes),
        950 => (
            group::FEED_MODE,
            No("feed per revolution (G95) is not supported"),
        ),
        200 | 210 => (group::UNITS, Yes),
        400 | 410 | 411 | 420 | 421 => (group::CUTTER_COMP, Yes),
        430 | 431 | 432 | 490 => (group::TOOL_LENGTH, Yes),
        980 | 990 => (group::RETURN_MODE, Yes),
        540 | 550 | 560 | 570 | 580 | 590..=593 => (group::COORD_SYSTEM, Yes),
        610 | 611 | 640 => (group::PATH_CONTROL, Yes),
        960 => (
            group::SPINDLE_MODE,
            No("constant surface speed (G96) is not supported"),
        ),
        970 => (group::SPINDLE_MODE, Yes),
        70 => (
            group::LATHE,
            No("lathe diameter mode (G7) is not supported: cncsim's machines are mills"),
        ),
        80 => (group::LATHE, Yes),
        _ => return None,
    };
    Some(info)
}

/// M code → modal group and support.
pub(super) fn m_code_info(code: u32) -> Option<(usize, Support)> {
    use Support::{No, Yes};
    let info = match code {
        0 | 1 | 2 | 30 | 60 => (mgroup::STOP, Yes),
        6 | 61 => (mgroup::TOOL_CHANGE, Yes),
        3..=5 => (mgroup::SPINDLE, Yes),
        19 => (
            mgroup::SPINDLE,
            No("spindle orientation (M19) is not supported"),
        ),
        7..=9 => (mgroup::COOLANT, Yes),
        48..=53 => (mgroup::OVERRIDE, Yes),
        62..=68 => (
            mgroup::OVERRIDE,
            No("digital and analog inputs and outputs (M62-M68) are not supported"),
        ),
        70..=73 => (
            mgroup::OVERRIDE,
            No("saving and restoring modal state (M70-M73) is not supported"),
        ),
        98 | 99 => (
            mgroup::STOP,
            No("Fanuc-style subprograms (M98/M99) are not supported; use o<name> sub / call"),
        ),
        100..=199 => (
            mgroup::OVERRIDE,
            No("user-defined M codes (M100-M199) are not supported"),
        ),
        _ => return None,
    };
    Some(info)
}
