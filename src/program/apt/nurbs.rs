//! NX's spline output: `NURBS/` then `KNOT/` and `CNTRL/` records, a clamped B-spline that
//! starts at the tool's position.
//!
//! NX writes each distinct knot after 0 once (the last one the end of the curve) and the
//! control points after the first, which is the tool's position: with n knots written and
//! m control points written the degree is m − n + 1 (3 for NX's cubic output). The full knot
//! vector is degree + 1 zeros, the knots written but the last, and degree + 1 copies of the
//! last. A fourth number in a `CNTRL` record is the point's weight (rational curves).
//! The curve is followed by chords that stay within a stated distance of it, as arcs about
//! tilted axes are.

use nalgebra::Vector3;

/// A B-spline read from the records, in metres, in the frame the moves are in.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Spline {
    pub(super) degree: usize,
    /// The full (clamped) knot vector.
    pub(super) knots: Vec<f64>,
    pub(super) points: Vec<Vector3<f64>>,
    pub(super) weights: Vec<f64>,
}

impl Spline {
    /// The spline from the tool's position `start`, the knots written and the control
    /// points written (with their weights), or what is wrong with them.
    pub(super) fn new(
        start: Vector3<f64>,
        written_knots: &[f64],
        written_points: &[(Vector3<f64>, f64)],
    ) -> Result<Spline, String> {
        let (k, m) = (written_knots.len(), written_points.len());
        if k == 0 || m + 1 < k {
            return Err(format!(
                "expected at least as many CNTRL points as KNOT values less one in a NURBS, found {k} knots and {m} control points"
            ));
        }
        let degree = m + 1 - k;
        if !(1..=9).contains(&degree) {
            return Err(format!(
                "expected a NURBS of degree 1 to 9 (CNTRL points − KNOT values + 1), found degree {degree} ({k} knots, {m} control points)"
            ));
        }
        let last = written_knots[k - 1];
        let ordered = written_knots.windows(2).all(|w| w[0] <= w[1]);
        if !ordered || written_knots[0] < 0.0 || last <= 0.0 || !last.is_finite() {
            return Err(
                "expected non-decreasing KNOT values from above 0 to a positive last value".into(),
            );
        }
        let mut knots = vec![0.0; degree + 1];
        knots.extend_from_slice(&written_knots[..k - 1]);
        knots.extend(std::iter::repeat_n(last, degree + 1));
        let mut points = vec![start];
        let mut weights = vec![1.0];
        for (point, weight) in written_points {
            if weight.is_nan() || *weight <= 0.0 {
                return Err(format!("expected a positive CNTRL weight, found {weight}"));
            }
            points.push(*point);
            weights.push(*weight);
        }
        Ok(Spline {
            degree,
            knots,
            points,
            weights,
        })
    }

    /// The point at parameter `t` (de Boor's algorithm on homogeneous points).
    pub(super) fn at(&self, t: f64) -> Vector3<f64> {
        let p = self.degree;
        let n = self.points.len();
        // The span: knots[span] <= t < knots[span + 1], the last span for the end.
        let mut span = p;
        while span + 1 < n && self.knots[span + 1] <= t {
            span += 1;
        }
        let mut d: Vec<(Vector3<f64>, f64)> = (0..=p)
            .map(|j| {
                let i = span + j - p;
                (self.points[i] * self.weights[i], self.weights[i])
            })
            .collect();
        for r in 1..=p {
            for j in (r..=p).rev() {
                let i = span + j - p;
                let denominator = self.knots[i + p + 1 - r] - self.knots[i];
                let alpha = if denominator > 0.0 {
                    (t - self.knots[i]) / denominator
                } else {
                    0.0
                };
                d[j] = (
                    d[j - 1].0 * (1.0 - alpha) + d[j].0 * alpha,
                    d[j - 1].1 * (1.0 - alpha) + d[j].1 * alpha,
                );
            }
        }
        d[p].0 / d[p].1
    }

    /// Points along the curve after its start, the last one its end, such that no point
    /// of the curve is further than `tolerance` from the chords (checked at nine points of
    /// every chord's parameter interval); at most `max_points`.
    pub(super) fn chords(
        &self,
        tolerance: f64,
        max_points: usize,
    ) -> Result<Vec<Vector3<f64>>, String> {
        let mut out = Vec::new();
        let p = self.degree;
        let end = self.knots[self.knots.len() - 1];
        // Each knot span is a polynomial piece: flatten them one by one.
        let mut breaks: Vec<f64> = self.knots[p..self.knots.len() - p].to_vec();
        breaks.dedup();
        let mut from_t = 0.0;
        let mut from = self.at(0.0);
        for &to_t in breaks.iter().skip(1) {
            self.flatten(
                (from_t, from),
                (to_t, self.at(to_t.min(end))),
                tolerance,
                0,
                &mut out,
                max_points,
            )?;
            from_t = to_t;
            from = *out.last().unwrap_or(&from);
        }
        if let Some(last) = out.last_mut() {
            // Exactly the last control point (clamped end), not its evaluation.
            *last = self.points[self.points.len() - 1];
        }
        Ok(out)
    }

    fn flatten(
        &self,
        (t0, p0): (f64, Vector3<f64>),
        (t1, p1): (f64, Vector3<f64>),
        tolerance: f64,
        depth: u32,
        out: &mut Vec<Vector3<f64>>,
        max_points: usize,
    ) -> Result<(), String> {
        let deviation = (1..10)
            .map(|k| {
                let t = t0 + (t1 - t0) * f64::from(k) / 10.0;
                distance_to_segment(&self.at(t), &p0, &p1)
            })
            .fold(0.0, f64::max);
        // Two pieces at least per span at the top level: a chord's two ends can lie on the
        // curve with the nine samples close to it only by accident of symmetry.
        if (deviation > tolerance || depth == 0) && depth < 40 {
            let tm = 0.5 * (t0 + t1);
            let pm = self.at(tm);
            self.flatten((t0, p0), (tm, pm), tolerance, depth + 1, out, max_points)?;
            return self.flatten((tm, pm), (t1, p1), tolerance, depth + 1, out, max_points);
        }
        if out.len() >= max_points {
            return Err(format!(
                "expected a NURBS of at most {max_points} chords at {:.4} mm",
                tolerance * 1e3
            ));
        }
        out.push(p1);
        Ok(())
    }
}

fn distance_to_segment(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let ab = b - a;
    let length_squared = ab.norm_squared();
    if length_squared == 0.0 {
        return (p - a).norm();
    }
    let t = ((p - a).dot(&ab) / length_squared).clamp(0.0, 1.0);
    (p - (a + ab * t)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_degree_one_spline_is_its_control_polygon() {
        // One knot written, one control point more: degree 1 through (1,0,0) to (1,1,0).
        let spline = Spline::new(
            Vector3::zeros(),
            &[0.5, 1.0],
            &[
                (Vector3::new(1.0, 0.0, 0.0), 1.0),
                (Vector3::new(1.0, 1.0, 0.0), 1.0),
            ],
        )
        .unwrap();
        assert_eq!(spline.degree, 1);
        assert!((spline.at(0.25) - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-12);
        assert!((spline.at(0.75) - Vector3::new(1.0, 0.5, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn a_cubic_bezier_matches_bernstein() {
        // No interior knots: a cubic Bézier curve.
        let c = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 2.0, 0.0),
            Vector3::new(3.0, 2.0, 1.0),
            Vector3::new(4.0, 0.0, 0.0),
        ];
        let spline = Spline::new(c[0], &[1.0], &[(c[1], 1.0), (c[2], 1.0), (c[3], 1.0)]).unwrap();
        assert_eq!(spline.degree, 3);
        for t in [0.0, 0.2, 0.5, 0.9, 1.0] {
            let s = 1.0 - t;
            let bernstein = c[0] * s * s * s
                + c[1] * 3.0 * s * s * t
                + c[2] * 3.0 * s * t * t
                + c[3] * t * t * t;
            assert!((spline.at(t) - bernstein).norm() < 1e-12, "t = {t}");
        }
        let chords = spline.chords(1e-4, 100_000).unwrap();
        assert_eq!(*chords.last().unwrap(), c[3]);
        for k in 0..=1000 {
            let point = spline.at(f64::from(k) / 1000.0);
            let mut previous = c[0];
            let nearest = chords
                .iter()
                .map(|q| {
                    let d = distance_to_segment(&point, &previous, q);
                    previous = *q;
                    d
                })
                .fold(f64::INFINITY, f64::min);
            assert!(nearest <= 1e-4 + 1e-12, "{nearest}");
        }
    }

    #[test]
    fn inconsistent_counts_and_knots_are_refused() {
        let p = (Vector3::new(1.0, 0.0, 0.0), 1.0);
        assert!(Spline::new(Vector3::zeros(), &[0.2, 0.5, 1.0], &[p]).is_err());
        assert!(Spline::new(Vector3::zeros(), &[0.5, 0.2, 1.0], &[p, p, p]).is_err());
        assert!(Spline::new(Vector3::zeros(), &[1.0], &[(p.0, 0.0)]).is_err());
    }
}
