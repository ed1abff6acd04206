//! `CIRCLE` records: the arc from the tool's position to the following GOTO about the
//! record's centre, axis and radius (helical when the GOTO moves along the axis).
//!
//! NX writes `CIRCLE/x,y,z,i,j,k,r,t,f,d,e[,TIMES,n]`: centre, axis vector, radius, total
//! tolerance (INTOL + OUTTOL), tolerance ratio, tool diameter and corner radius; the tool
//! moves *clockwise* about the axis vector, where APT and the other writers move it
//! counter-clockwise (see `writer`). Arcs about X, Y or Z become [`Motion::Arc`] in the YZ,
//! ZX or XY plane; arcs about any other axis are followed by chords that stay within a
//! stated distance of the arc.

use nalgebra::{Unit, Vector3};

use crate::program::types::{Motion, Plane};

/// Which way the tool goes round the axis vector of a CIRCLE record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CircleSense {
    /// NX CLSF: clockwise about (i, j, k), i.e. counter-clockwise about −(i, j, k).
    ClockwiseAboutAxis,
    /// Counter-clockwise about (i, j, k) (right-hand rule).
    CounterClockwiseAboutAxis,
}

/// How far (degrees) a move entering or leaving an arc may turn from the arc's tangent and
/// still say which way the arc turns: CAM systems lead into and out of arcs tangentially.
/// Wider would mislead: a zig-zag pass that reverses into a short arc along a pocket's wall
/// meets it 20° to 40° off the other way's tangent, and a radial lead or a plunge says
/// nothing.
pub(super) const TANGENT_ANGLE: f64 = 15.0;

/// A CIRCLE record in metres, in the frame the moves are in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Circle {
    pub(super) centre: Vector3<f64>,
    pub(super) axis: Unit<Vector3<f64>>,
    pub(super) radius: f64,
    /// How far the start and end may lie off the circle (m).
    pub(super) tolerance: f64,
    /// Extra full turns (`TIMES,n`: n − 1).
    pub(super) turns: u32,
    /// The way round the record itself gives (a direction word, or APT's for a CIRCLE
    /// without radius); `None`: the reader's setting.
    pub(super) sense: Option<CircleSense>,
}

/// How the arc is to be moved along.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum ArcPath {
    /// An arc in a coordinate plane, for [`Motion::Arc`].
    Plane(Motion),
    /// Points along the arc (the last one the end point), for linear moves.
    Chords(Vec<Vector3<f64>>),
}

impl Circle {
    /// Distance (m) of `point` from the circle's cylinder surface.
    fn off_circle(&self, point: &Vector3<f64>) -> f64 {
        let from_centre = point - self.centre;
        let radial = from_centre - self.axis.into_inner() * from_centre.dot(&self.axis);
        (radial.norm() - self.radius).abs()
    }

    /// The unit direction of travel at `point` on the circle going round the `sense` way
    /// (`None` on the axis).
    pub(super) fn tangent(&self, point: &Vector3<f64>, sense: CircleSense) -> Option<Vector3<f64>> {
        let axis = self.axis.into_inner();
        let radial = point - self.centre;
        let radial = radial - axis * radial.dot(&axis);
        if radial.norm() <= 1e-12 {
            return None;
        }
        // Counter-clockwise about +axis (right-hand rule): axis × radial.
        let counter_clockwise = axis.cross(&radial).normalize();
        Some(match sense {
            CircleSense::CounterClockwiseAboutAxis => counter_clockwise,
            CircleSense::ClockwiseAboutAxis => -counter_clockwise,
        })
    }

    /// The way round the circle a move through `point` along `direction` runs, when it runs
    /// along the circle: its part across the axis within [`TANGENT_ANGLE`] of the tangent
    /// one way. `None` for a move across the circle or along its axis, which tells nothing.
    pub(super) fn tangent_sense(
        &self,
        point: &Vector3<f64>,
        direction: &Vector3<f64>,
    ) -> Option<CircleSense> {
        let axis = self.axis.into_inner();
        let across = direction - axis * direction.dot(&axis);
        // Mostly along the axis (a plunge onto a helix): no reading.
        if across.norm() <= 0.25 * direction.norm() || across.norm() <= 1e-12 {
            return None;
        }
        let ahead = self.tangent(point, CircleSense::CounterClockwiseAboutAxis)?;
        let cosine = across.normalize().dot(&ahead);
        let limit = TANGENT_ANGLE.to_radians().cos();
        if cosine >= limit {
            Some(CircleSense::CounterClockwiseAboutAxis)
        } else if cosine <= -limit {
            Some(CircleSense::ClockwiseAboutAxis)
        } else {
            None
        }
    }

    /// The arc from `start` to `end`, or what is wrong with them.
    pub(super) fn path(
        &self,
        start: &Vector3<f64>,
        end: &Vector3<f64>,
        sense: CircleSense,
        chord_tolerance: f64,
        max_chords: usize,
    ) -> Result<ArcPath, String> {
        for (what, point) in [
            ("start (the tool's position)", start),
            ("end (the GOTO)", end),
        ] {
            let off = self.off_circle(point);
            if off.is_nan() || off > self.tolerance {
                return Err(format!(
                    "expected the arc's {what} on the CIRCLE (radius {:.4} mm), but it is {:.4} mm off it; expected at most {:.4} mm",
                    self.radius * 1e3,
                    off * 1e3,
                    self.tolerance * 1e3
                ));
            }
        }
        let axis = self.axis.into_inner();
        // Motion about +axis (right-hand rule) is counter-clockwise.
        let counter_clockwise_about_axis = sense == CircleSense::CounterClockwiseAboutAxis;
        let aligned = (0..3).find(|&index| (axis[index].abs() - 1.0).abs() <= 1e-9);
        if let Some(index) = aligned {
            let plane = match index {
                0 => Plane::YZ,
                1 => Plane::ZX,
                _ => Plane::XY,
            };
            // The plane's counter-clockwise sense is about the +X, +Y or +Z axis.
            let positive = axis[index] > 0.0;
            let clockwise = positive != counter_clockwise_about_axis;
            let mut centre = [self.centre.x, self.centre.y, self.centre.z];
            // The centre's coordinate along the normal is the arc's start value.
            centre[index] = start[index];
            return Ok(ArcPath::Plane(Motion::Arc {
                center: centre,
                plane,
                clockwise,
                turns: self.turns,
            }));
        }
        // Any other axis: chords of the arc (and of the helix along it).
        let u = {
            let radial = start - self.centre;
            let radial = radial - axis * radial.dot(&axis);
            if radial.norm() == 0.0 {
                return Err("expected the arc's start away from the CIRCLE's axis".into());
            }
            radial.normalize()
        };
        let v = axis.cross(&u);
        let end_radial = end - self.centre;
        let angle_to_end = end_radial.dot(&v).atan2(end_radial.dot(&u));
        let tau = std::f64::consts::TAU;
        let mut sweep = if counter_clockwise_about_axis {
            angle_to_end.rem_euclid(tau)
        } else {
            (-angle_to_end).rem_euclid(tau)
        };
        if sweep < 1e-12 {
            sweep = tau;
        }
        sweep += tau * f64::from(self.turns);
        let signed = if counter_clockwise_about_axis {
            sweep
        } else {
            -sweep
        };
        let step = if self.radius > chord_tolerance {
            2.0 * (1.0 - chord_tolerance / self.radius).acos()
        } else {
            tau
        };
        let count = (sweep / step).ceil().max(1.0);
        if count > max_chords as f64 {
            return Err(format!(
                "expected an arc of at most {max_chords} chords at {:.4} mm; this one needs {count}",
                chord_tolerance * 1e3
            ));
        }
        let count = count as u32;
        let height_start = (start - self.centre).dot(&axis);
        let height_end = (end - self.centre).dot(&axis);
        let points = (1..=count)
            .map(|index| {
                if index == count {
                    return *end;
                }
                let fraction = f64::from(index) / f64::from(count);
                let angle = signed * fraction;
                let height = height_start + (height_end - height_start) * fraction;
                self.centre + (u * angle.cos() + v * angle.sin()) * self.radius + axis * height
            })
            .collect();
        Ok(ArcPath::Chords(points))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(axis: Vector3<f64>) -> Circle {
        Circle {
            centre: Vector3::new(0.0, 0.0, 0.0),
            axis: Unit::new_normalize(axis),
            radius: 0.01,
            tolerance: 1e-6,
            turns: 0,
            sense: None,
        }
    }

    #[test]
    fn the_nx_example_turns_counter_clockwise_seen_from_plus_z() {
        // NX's documentation example: axis (0,0,-1), clockwise about it.
        let arc = circle(Vector3::new(0.0, 0.0, -1.0));
        let path = arc
            .path(
                &Vector3::new(0.01, 0.0, 0.0),
                &Vector3::new(0.0, 0.01, 0.0),
                CircleSense::ClockwiseAboutAxis,
                1e-6,
                1000,
            )
            .unwrap();
        assert_eq!(
            path,
            ArcPath::Plane(Motion::Arc {
                center: [0.0, 0.0, 0.0],
                plane: Plane::XY,
                clockwise: false,
                turns: 0
            })
        );
    }

    #[test]
    fn points_off_the_circle_are_refused() {
        let arc = circle(Vector3::new(0.0, 0.0, 1.0));
        let error = arc
            .path(
                &Vector3::new(0.01, 0.0, 0.0),
                &Vector3::new(0.0, 0.0102, 0.0),
                CircleSense::ClockwiseAboutAxis,
                1e-6,
                1000,
            )
            .unwrap_err();
        assert!(
            error.contains("end (the GOTO)") && error.contains("0.2000 mm off"),
            "{error}"
        );
    }

    #[test]
    fn tilted_arcs_become_chords_on_the_arc() {
        let axis = Vector3::new(0.0, 1.0, 1.0);
        let arc = circle(axis);
        let unit = axis.normalize();
        let start = Vector3::new(0.01, 0.0, 0.0);
        let end = unit.cross(&start); // 90° counter-clockwise about the axis
        let ArcPath::Chords(points) = arc
            .path(
                &start,
                &end,
                CircleSense::CounterClockwiseAboutAxis,
                1e-6,
                100_000,
            )
            .unwrap()
        else {
            panic!("expected chords");
        };
        assert_eq!(*points.last().unwrap(), end);
        // Every chord point on the circle, every chord within the tolerance of the arc.
        let mut previous = start;
        for point in &points {
            assert!((point.norm() - 0.01).abs() < 1e-12);
            let midpoint = (previous + point) / 2.0;
            assert!(0.01 - midpoint.norm() <= 1e-6 + 1e-15);
            previous = *point;
        }
        // The quarter turn: the first chord heads towards the end, not away from it.
        assert!(points[0].dot(&end) > 0.0);
    }

    #[test]
    fn moves_along_the_circle_tell_its_sense_and_moves_across_it_do_not() {
        let arc = circle(Vector3::new(0.0, 0.0, -1.0));
        let start = Vector3::new(0.01, 0.0, 0.0);
        // Seen from +Z the tool at +X heading +Y goes counter-clockwise: clockwise about -Z.
        let sense = |direction: Vector3<f64>| arc.tangent_sense(&start, &direction);
        assert_eq!(
            sense(Vector3::new(0.0, 1.0, 0.0)),
            Some(CircleSense::ClockwiseAboutAxis)
        );
        assert_eq!(
            sense(Vector3::new(0.1, -1.0, 0.0)),
            Some(CircleSense::CounterClockwiseAboutAxis)
        );
        // Radial, 20° off (a zig-zag reversing into the arc), or down the axis: nothing.
        assert_eq!(sense(Vector3::new(1.0, 0.0, 0.0)), None);
        assert_eq!(sense(Vector3::new(0.364, 1.0, 0.0)), None);
        assert_eq!(sense(Vector3::new(0.0, 0.1, -1.0)), None);
        // 10° off: tangent.
        assert_eq!(
            sense(Vector3::new(0.176, 1.0, 0.0)),
            Some(CircleSense::ClockwiseAboutAxis)
        );
        // A helical lead (mostly across the axis) still tells.
        assert_eq!(
            sense(Vector3::new(0.0, 1.0, -0.2)),
            Some(CircleSense::ClockwiseAboutAxis)
        );
    }
}
