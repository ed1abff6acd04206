//! Parameter storage: the numbered parameters #1–#5601, named parameters local to a
//! subroutine call (`#<name>`) and global ones (`#<_name>`).
//!
//! The numbered parameters LinuxCNC keeps its state in are kept up to date by the interpreter
//! (5161–5169 G28 home, 5181–5189 G30 home, 5210–5219 G92, 5220 active system, 5221–5390
//! G54–G59.3 with their rotation, 5400–5413 tool in the spindle, 5420–5428 current position);
//! like LinuxCNC's, lengths there are in the machine's (user) units.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use super::expr::PARAMETER_COUNT;

/// FNV-1a: parameter names are short, and the standard hasher's defence against crafted keys
/// costs more than the lookups themselves here.
#[derive(Default)]
pub(super) struct Fnv(u64);

impl Hasher for Fnv {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        let mut hash = if self.0 == 0 {
            0xcbf2_9ce4_8422_2325
        } else {
            self.0
        };
        for &byte in bytes {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
        self.0 = hash;
    }
}

/// Named parameters by name.
pub(super) type NameMap = HashMap<String, f64, BuildHasherDefault<Fnv>>;

/// Numbered parameters and named globals; locals live in the call frames.
pub(super) struct Store {
    numbered: Vec<f64>,
    globals: NameMap,
}

impl Store {
    pub fn new() -> Self {
        Store {
            numbered: vec![0.0; PARAMETER_COUNT],
            globals: NameMap::default(),
        }
    }

    pub fn get(&self, index: usize) -> f64 {
        self.numbered[index]
    }

    pub fn set(&mut self, index: usize, value: f64) {
        self.numbered[index] = value;
    }

    /// Subroutine arguments #1–#30.
    pub fn arguments(&self) -> [f64; 30] {
        let mut saved = [0.0; 30];
        saved.copy_from_slice(&self.numbered[1..31]);
        saved
    }

    pub fn set_arguments(&mut self, values: &[f64; 30]) {
        self.numbered[1..31].copy_from_slice(values);
    }

    pub fn global(&self, name: &str) -> Option<f64> {
        self.globals.get(name).copied()
    }

    pub fn set_global(&mut self, name: &str, value: f64) {
        match self.globals.get_mut(name) {
            Some(slot) => *slot = value,
            None => {
                self.globals.insert(name.to_string(), value);
            }
        }
    }
}

/// Index of coordinate system `system` (1 = G54 … 9 = G59.3) axis `axis` (0..6 = X Y Z A B C,
/// 9 = rotation) in the numbered parameters.
pub(super) fn coordinate_system_index(system: usize, axis: usize) -> usize {
    5201 + system * 20 + axis
}

pub(super) const G28_HOME: usize = 5161;
pub(super) const G30_HOME: usize = 5181;
pub(super) const G92_APPLIED: usize = 5210;
pub(super) const G92_OFFSET: usize = 5211;
pub(super) const ACTIVE_SYSTEM: usize = 5220;
pub(super) const TOOL_NUMBER: usize = 5400;
pub(super) const TOOL_OFFSET: usize = 5401;
pub(super) const TOOL_DIAMETER: usize = 5410;
pub(super) const CURRENT_POSITION: usize = 5420;
