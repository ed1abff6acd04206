//! Part programs: the representation every front end produces, the geometry of its moves,
//! and the reference paths of the source documents that a scenario can name directly.

mod geometry;
mod reference;
mod types;

pub use geometry::{arc_segment, PathGeometry, Segment};
pub use reference::{circle, polyline, CircleSpec, PolylineSpec};
pub use types::*;
