//! The pen: raising, lowering and moving it (lines, arcs, chords of ellipses), recording moves
//! into the polygon buffer in polygon mode, and drawing outlines and fills.
//!
//! Positions handed in are plotter units of the current rotation; the drawing receives
//! metres on the table.

use std::f64::consts::TAU;

use super::drawing::{Element, Segment, Step, Stroke};
use super::fill::{self, Edge, Piece, Polygon, Rule, SubPath};
use super::plotter::ChordMode;
use super::{Problem, Reader};
use crate::program::types::Span;

/// At most this many chords for one arc of an anisotropically scaled circle.
const MAX_CHORDS: f64 = 1_000_000.0;

impl Reader<'_> {
    /// Plotter units (current rotation) to metres on the table.
    pub(super) fn metres(&self, point: [f64; 2]) -> [f64; 2] {
        let page = self.plotter.to_page(point, self.options);
        let per_metre = self.options.units_per_mm * 1000.0;
        [page[0] / per_metre, page[1] / per_metre]
    }

    pub(super) fn pen_up(&mut self, span: Span) {
        if let Some(mut stroke) = self.stroke.take() {
            stroke.up_span = span;
            self.drawing.push(Element::Stroke(stroke));
        }
        self.plotter.pen_down = false;
    }

    pub(super) fn pen_down(&mut self, span: Span) {
        // A dot outside the input window is clipped away, one on a page not plotted too.
        let outside = self.window_clips() && !self.inside_window(self.plotter.position);
        if self.stroke.is_none() && !self.polygon_mode && !outside && self.page_plotted() {
            self.stroke = Some(Stroke {
                start: self.metres(self.plotter.position),
                steps: Vec::new(),
                down_span: span,
                up_span: span,
                open_at_end: false,
            });
        }
        self.plotter.pen_down = true;
    }

    /// Whether drawing is clipped at the input window (IW; refused instead with `strict`).
    fn window_clips(&self) -> bool {
        self.plotter.window.is_some() && !self.options.strict
    }

    fn inside_window(&self, point: [f64; 2]) -> bool {
        let Some((low, high)) = self.plotter.window else {
            return true;
        };
        let slack = 1e-6;
        (0..2).all(|axis| point[axis] >= low[axis] - slack && point[axis] <= high[axis] + slack)
    }

    /// A pen-down piece from the pen to `to` that leaves the input window, drawn as HP-GL
    /// defines IW: only what lies inside the window is drawn; the pen stays down, lifting
    /// where the piece leaves the window and lowering where it comes back. An arc that
    /// crosses the window's edge is drawn as chords within `fill::FLATNESS`.
    fn clipped(&mut self, to: [f64; 2], piece: Piece, span: Span) -> Result<(), Problem> {
        let from = self.plotter.position;
        let at = span.byte_offset as usize;
        self.skip(
            "IW clip",
            at,
            at,
            "drawing outside the input window (IW) is not drawn",
            "was clipped at the window as HP-GL defines (arcs crossing its edge as chords within 0.01 mm)",
        );
        let points = match piece {
            Piece::Line => vec![to],
            Piece::Arc {
                centre,
                clockwise,
                turns,
            } => fill::arc_points(from, to, centre, clockwise, turns),
        };
        let (low, high) = self.plotter.window.expect("a window");
        let mut a = from;
        for b in points {
            match clip_segment(a, b, low, high) {
                None => self.lift_for_window(span),
                Some((t0, t1)) => {
                    let lerp = |t: f64| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
                    let (p0, p1) = (lerp(t0), lerp(t1));
                    if t0 > 0.0 || self.stroke.is_none() {
                        self.lift_for_window(span);
                        self.stroke = Some(Stroke {
                            start: self.metres(p0),
                            steps: Vec::new(),
                            down_span: span,
                            up_span: span,
                            open_at_end: false,
                        });
                    }
                    let step = Step {
                        segment: Segment::Line,
                        to: self.metres(p1),
                        speed: self.plotter.speed,
                        span,
                    };
                    if let Some(stroke) = &mut self.stroke {
                        stroke.steps.push(step);
                    }
                    if t1 < 1.0 {
                        self.lift_for_window(span);
                    }
                }
            }
            a = b;
        }
        self.plotter.position = to;
        Ok(())
    }

    /// Ends the stroke where the drawing leaves the window; the pen stays down.
    fn lift_for_window(&mut self, span: Span) {
        if let Some(mut stroke) = self.stroke.take() {
            stroke.up_span = span;
            self.drawing.push(Element::Stroke(stroke));
        }
    }

    /// Whether a pen-down piece from the pen to `to` may be drawn: not on a later page with
    /// `strict`, not outside the input window (with `strict`, which does not clip).
    fn drawable(&self, to: [f64; 2], piece: Piece) -> Result<(), Problem> {
        if let (true, Some((span, command))) = (self.options.strict, &self.pages.first_advance) {
            return Err(Problem::new(format!(
                "expected one page; this draws after the page advance ({command}) at line {} column {}",
                span.line, span.column
            ))
            .hint("plot each page to its own file, or choose one (page = N in [program], inspect --page N)"));
        }
        if let Some((low, high)) = self.plotter.window {
            let from = self.plotter.position;
            let (mut min, mut max) = (
                [from[0].min(to[0]), from[1].min(to[1])],
                [from[0].max(to[0]), from[1].max(to[1])],
            );
            if let Piece::Arc {
                centre,
                clockwise,
                turns,
            } = piece
            {
                let radius = (from[0] - centre[0]).hypot(from[1] - centre[1]);
                let start = (from[1] - centre[1]).atan2(from[0] - centre[0]);
                let angle = fill::sweep(from, to, centre, clockwise, turns);
                // The arc reaches the extreme of each axis it sweeps past.
                for quarter in 0..4 {
                    let direction = f64::from(quarter) * TAU / 4.0;
                    let offset = if clockwise {
                        start - direction
                    } else {
                        direction - start
                    };
                    if offset.rem_euclid(TAU) <= angle {
                        let point = [
                            centre[0] + radius * direction.cos(),
                            centre[1] + radius * direction.sin(),
                        ];
                        for axis in 0..2 {
                            min[axis] = min[axis].min(point[axis]);
                            max[axis] = max[axis].max(point[axis]);
                        }
                    }
                }
            }
            let slack = 1e-6;
            if min[0] < low[0] - slack
                || min[1] < low[1] - slack
                || max[0] > high[0] + slack
                || max[1] > high[1] + slack
            {
                return Err(Problem::new(format!(
                    "expected drawing inside the input window (IW {},{},{},{} plotter units); clipping at the window is not supported",
                    low[0], low[1], high[0], high[1]
                ))
                .hint("re-plot without an input window, or keep the drawing inside it"));
            }
        }
        Ok(())
    }

    /// Moves the pen (drawing if it is down, recording if in polygon mode) to `to`.
    pub(super) fn move_to(
        &mut self,
        to: [f64; 2],
        piece: Piece,
        span: Span,
    ) -> Result<(), Problem> {
        if self.plotter.pen_down && !self.polygon_mode {
            self.pages.mark_drawn();
        }
        if self.polygon_mode {
            self.record(to, piece);
        } else if !self.page_plotted() {
            // A page not plotted: the pen moves, nothing is drawn or travelled (hp2xx -P).
            self.lift_for_window(span);
        } else if self.plotter.pen_down {
            if self.window_clips() {
                let inside = self.drawable(to, piece).is_ok();
                if !inside || self.stroke.is_none() && !self.inside_window(self.plotter.position) {
                    return self.clipped(to, piece, span);
                }
            }
            self.drawable(to, piece)?;
            let segment = match piece {
                Piece::Line => Segment::Line,
                Piece::Arc {
                    centre,
                    clockwise,
                    turns,
                } => Segment::Arc {
                    centre: self.metres(centre),
                    clockwise,
                    turns,
                },
            };
            let step = Step {
                segment,
                to: self.metres(to),
                speed: self.plotter.speed,
                span,
            };
            if self.stroke.is_none() {
                self.pen_down(span);
            }
            if let Some(stroke) = &mut self.stroke {
                stroke.steps.push(step);
            }
            self.check_on_page(to, span);
        } else {
            let to = self.metres(to);
            self.drawing.push(Element::Travel { to, span });
        }
        self.plotter.position = to;
        Ok(())
    }

    /// A pen-down move ending beyond the page the file set (PS): drawn as written, with one
    /// warning counting them (a plotter clips at its limits, which cncsim does not model).
    fn check_on_page(&mut self, to: [f64; 2], span: Span) {
        let Some(page) = self.plotter.page else {
            return;
        };
        let point = self.plotter.to_page(to, self.options);
        // Half a plotter unit: rounding in the file's coordinates.
        let slack = 0.5;
        if (0..2).all(|axis| point[axis] >= -slack && point[axis] <= page[axis] + slack) {
            return;
        }
        let per_mm = self.options.units_per_mm;
        self.warn_counted("off the page", span, || {
            format!(
                "the pen draws off the page the file set (PS: {:.1} × {:.1} mm), first to ({:.2}, {:.2}) mm on it: drawn as written, where a plotter clips at its limits",
                page[0] / per_mm,
                page[1] / per_mm,
                point[0] / per_mm,
                point[1] / per_mm
            )
        });
    }

    /// Polygon mode: a pen-down move adds an edge; a pen-up move closes the sub-polygon and
    /// starts the next one where it ends (HP-GL/2), or moves the start of a sub-polygon that
    /// has no edge yet.
    fn record(&mut self, to: [f64; 2], piece: Piece) {
        let drawn = self.plotter.pen_down;
        let position = self.plotter.position;
        let paths = &mut self.polygon.paths;
        if paths.is_empty() {
            paths.push(SubPath {
                start: position,
                edges: Vec::new(),
                open: false,
            });
        }
        let path = paths.last_mut().expect("a sub-polygon");
        if drawn {
            path.edges.push(Edge { piece, to });
        } else if path.edges.is_empty() {
            path.start = to;
        } else {
            paths.push(SubPath {
                start: to,
                edges: Vec::new(),
                open: false,
            });
        }
    }

    /// Polygon mode: closes the current sub-polygon (PM1, PM2), with the pen up an open one;
    /// the next move starts another.
    pub(super) fn close_subpolygon(&mut self) {
        let position = self.plotter.position;
        let pen_up = !self.plotter.pen_down;
        if let Some(path) = self.polygon.paths.last_mut() {
            if !path.edges.is_empty() {
                path.open = pen_up;
                self.polygon.paths.push(SubPath {
                    start: position,
                    edges: Vec::new(),
                    open: false,
                });
            }
        }
    }

    /// An arc (or full circles) in *user units* from the pen about `centre` (user units)
    /// through `sweep_deg`, as HP plotters draw arcs: a circle in user units stays a circle
    /// on the table only when X and Y user units are equal; otherwise it is an ellipse,
    /// drawn as chords at the chord tolerance `chord` (CT).
    pub(super) fn user_arc(
        &mut self,
        centre: [f64; 2],
        sweep_deg: f64,
        chord: Option<f64>,
        span: Span,
    ) -> Result<(), Problem> {
        let start = self.plotter.to_user(self.plotter.position);
        let radius = (start[0] - centre[0]).hypot(start[1] - centre[1]);
        let start_angle = (start[1] - centre[1]).atan2(start[0] - centre[0]);
        let end_angle = start_angle + sweep_deg.to_radians();
        let end_user = [
            centre[0] + radius * end_angle.cos(),
            centre[1] + radius * end_angle.sin(),
        ];
        let (similar, mirrored) = self.plotter.user_map_shape();
        if similar {
            // Sweeps of 360° or more: the last partial (or full) turn plus extra turns.
            let full_turns = (sweep_deg.abs() / 360.0 - 1e-12).ceil().max(1.0) - 1.0;
            let turns = full_turns.min(f64::from(u32::MAX)) as u32;
            let piece = Piece::Arc {
                centre: self.plotter.to_plotter(centre),
                clockwise: (sweep_deg < 0.0) != mirrored,
                turns,
            };
            let to = if sweep_deg.abs() >= 360.0 && (sweep_deg.abs() % 360.0) < 1e-9 {
                // Whole turns end exactly where they started.
                self.plotter.position
            } else {
                self.plotter.to_plotter(end_user)
            };
            return self.move_to(to, piece, span);
        }
        let step = self.chord_angle(chord, radius);
        let count = (sweep_deg.abs().to_radians() / step).ceil().max(1.0);
        if count > MAX_CHORDS {
            return Err(Problem::new(format!(
                "expected an arc of at most {MAX_CHORDS} chords; this ellipse (anisotropic SC) would take {count}"
            )));
        }
        let count = count as u32;
        for index in 1..=count {
            let angle = start_angle + sweep_deg.to_radians() * f64::from(index) / f64::from(count);
            let point = [
                centre[0] + radius * angle.cos(),
                centre[1] + radius * angle.sin(),
            ];
            let to = self.plotter.to_plotter(point);
            self.move_to(to, Piece::Line, span)?;
        }
        Ok(())
    }

    /// The angle (rad) per chord that the chord parameter asks for (CT decides whether it is
    /// an angle or a deviation); HP's default 5°, clamped to 0.5°–180° as plotters do.
    fn chord_angle(&self, chord: Option<f64>, radius: f64) -> f64 {
        let degrees = match (chord, self.plotter.chord_mode) {
            (None, _) => 5.0,
            (Some(angle), ChordMode::Angle) => angle.abs(),
            (Some(deviation), ChordMode::Deviation) => {
                let deviation = deviation.abs();
                if deviation >= radius {
                    180.0
                } else {
                    (2.0 * (1.0 - deviation / radius).acos()).to_degrees()
                }
            }
        };
        degrees.clamp(0.5, 180.0).to_radians()
    }

    /// Moves the pen up to `to`, then lowers it again if `was_down`.
    pub(super) fn return_pen(
        &mut self,
        to: [f64; 2],
        was_down: bool,
        span: Span,
    ) -> Result<(), Problem> {
        self.pen_up(span);
        self.move_to(to, Piece::Line, span)?;
        if was_down {
            self.pen_down(span);
        }
        Ok(())
    }

    /// Draws a polyline (plotter units) with the pen down, leaving the pen up at its end.
    pub(super) fn polyline(&mut self, points: &[[f64; 2]], span: Span) -> Result<(), Problem> {
        let Some((first, rest)) = points.split_first() else {
            return Ok(());
        };
        self.pen_up(span);
        self.move_to(*first, Piece::Line, span)?;
        self.pen_down(span);
        for point in rest {
            self.move_to(*point, Piece::Line, span)?;
        }
        self.pen_up(span);
        Ok(())
    }

    /// Draws the edges of a polygon, closing each sub-polygon (an open one only when
    /// `close_open`: a fill's boundary); the pen ends up.
    pub(super) fn outline(
        &mut self,
        polygon: &Polygon,
        close_open: bool,
        span: Span,
    ) -> Result<(), Problem> {
        for path in &polygon.paths {
            if path.edges.is_empty() {
                continue;
            }
            self.pen_up(span);
            self.move_to(path.start, Piece::Line, span)?;
            self.pen_down(span);
            for edge in &path.edges {
                self.move_to(edge.to, edge.piece, span)?;
            }
            if path.end() != path.start && (close_open || !path.open) {
                self.pen_down(span);
                self.move_to(path.start, Piece::Line, span)?;
            }
            self.pen_up(span);
        }
        Ok(())
    }

    /// A filled polygon as a pen draws it: the outline, then (unless fills are drawn as
    /// outlines only) the hatch lines the fill type asks for. The pen ends up where it was.
    pub(super) fn fill(
        &mut self,
        polygon: &Polygon,
        rule: Rule,
        span: Span,
    ) -> Result<(), Problem> {
        let position = self.plotter.position;
        let was_down = self.plotter.pen_down;
        self.outline(polygon, true, span)?;
        if self.options.hatch_fills {
            let style = self.plotter.fill;
            let pen = style.pen_mm * self.options.units_per_mm;
            let diagonal = (self.plotter.p2[0] - self.plotter.p1[0])
                .hypot(self.plotter.p2[1] - self.plotter.p1[1]);
            let hatch_spacing = style.spacing.unwrap_or(0.01 * diagonal);
            let passes: Vec<(f64, f64)> = match style.kind {
                1 | 2 => vec![(style.angle_deg, pen)],
                3 => vec![(style.angle_deg, hatch_spacing)],
                4 => vec![
                    (style.angle_deg, hatch_spacing),
                    (style.angle_deg + 90.0, hatch_spacing),
                ],
                // Shading: lines dense enough to cover the asked share of the area.
                _ if style.level > 0.0 => {
                    vec![(style.angle_deg, pen * 100.0 / style.level.min(100.0))]
                }
                _ => Vec::new(),
            };
            for (angle, spacing) in passes {
                if spacing.is_nan() || spacing <= 0.0 {
                    return Err(Problem::new(format!(
                        "expected a positive fill line spacing, not {spacing} plotter units"
                    )));
                }
                let anchor = self.plotter.fill_anchor;
                let lines = fill::hatch(polygon, (angle, spacing, anchor), rule, style.kind != 2, self.fill_budget)
                    .map_err(|lines| {
                        Problem::new(format!(
                            "expected at most {} fill lines in a plot; this fill needs {lines:.0} more",
                            self.options.max_fill_lines
                        ))
                        .hint("draw fills as outlines (--no-hatch), or widen the fill spacing (FT, PT, PW)")
                    })?;
                self.fill_budget -= lines.len().min(self.fill_budget);
                for [from, to] in lines {
                    self.polyline(&[from, to], span)?;
                }
            }
        }
        self.return_pen(position, was_down, span)
    }
}

/// The part of the segment `a`–`b` inside the rectangle `low`–`high` as parameters
/// `t0 < t1` along it (Liang–Barsky), or `None` when none of it is inside.
fn clip_segment(a: [f64; 2], b: [f64; 2], low: [f64; 2], high: [f64; 2]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    let d = [b[0] - a[0], b[1] - a[1]];
    for axis in 0..2 {
        for (p, q) in [
            (-d[axis], a[axis] - low[axis]),
            (d[axis], high[axis] - a[axis]),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
    }
    (t0 < t1).then_some((t0, t1))
}
