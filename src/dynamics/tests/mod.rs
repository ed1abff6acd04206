//! Tests of the dynamics module.
//!
//! - `fixture.rs`: the reference A-C table values from an established library;
//! - `closed_form.rs`: one-joint machines with textbook answers, model validation errors;
//! - `properties.rs`: random trees (fixed, prismatic and revolute joints, branches) checked
//!   against identities that do not share code with the algorithms — energies computed from
//!   link poses, the Lagrangian form of `C q̇`, CRBA against RNEA, forward against inverse;
//! - `machines.rs`: the shipped models under `models/`, with drive armature;
//! - `report.rs`: the `cncsim dynamics` data, its JSON and its input errors;
//! - `timing.rs`: an ignored timing loop (run it in release).

mod closed_form;
mod fixture;
mod machines;
mod properties;
mod report;
mod support;
mod timing;
