//! The machine-axis path as the planner's windows read it: a whole path at hand, or one made
//! segment by segment from its source and kept only from the first segment a window still
//! needs, so that planning a long program holds a look-ahead of it, not all of it.

use std::sync::Arc;

use super::path::{AxisPath, Blend, Geometry, PathError, PathSegment};
use super::profile::Limits;

/// Makes a path's segments in order.
pub(super) trait SegmentSource<'a>: Send + std::fmt::Debug {
    /// The next segment, `None` after the last.
    fn next_segment(&mut self) -> Option<PathSegment>;
    /// The same source from its first segment again.
    fn restart(&self) -> Box<dyn SegmentSource<'a> + 'a>;
}

/// A path as windows read it, front to back.
#[derive(Debug)]
pub(super) enum PathReader<'a> {
    /// A whole path, borrowed.
    Whole(&'a AxisPath),
    /// A whole path, shared.
    Shared(Arc<AxisPath>),
    /// A path made by a source as it is read.
    Streamed(StreamedPath<'a>),
}

/// The segments of a path read so far that a window may still need.
#[derive(Debug)]
pub(super) struct StreamedPath<'a> {
    source: Box<dyn SegmentSource<'a> + 'a>,
    /// The path's axes and lever arms, its segments `base..` made so far, and (as its start)
    /// the point before segment `base`.
    kept: AxisPath,
    base: usize,
    /// The first segment still needed (those before it are made but not kept).
    keep_from: usize,
    /// The source has no more segments.
    done: bool,
    /// The path's own start, for reading it again.
    start: Vec<f64>,
}

impl<'a> PathReader<'a> {
    /// A path made by `source`, starting at `header.start` (whose segments are ignored) on
    /// `header.axes`; the header is checked here, each segment as it is made.
    pub fn streamed(
        header: AxisPath,
        source: Box<dyn SegmentSource<'a> + 'a>,
    ) -> Result<Self, PathError> {
        validate_header(&header)?;
        Ok(PathReader::Streamed(StreamedPath {
            source,
            start: header.start.clone(),
            kept: AxisPath {
                segments: Vec::new(),
                ..header
            },
            base: 0,
            keep_from: 0,
            done: false,
        }))
    }

    /// The same path from its start again.
    pub fn restart(&self) -> Self {
        match self {
            PathReader::Whole(path) => PathReader::Whole(path),
            PathReader::Shared(path) => PathReader::Shared(Arc::clone(path)),
            PathReader::Streamed(s) => PathReader::Streamed(StreamedPath {
                source: s.source.restart(),
                kept: AxisPath {
                    axes: s.kept.axes.clone(),
                    start: s.start.clone(),
                    segments: Vec::new(),
                    tool_lever_arms: s.kept.tool_lever_arms.clone(),
                },
                base: 0,
                keep_from: 0,
                done: false,
                start: s.start.clone(),
            }),
        }
    }

    /// Checks the whole path, segment by segment (a streamed one made once for it, not kept),
    /// so that the first bad segment is found before any is planned.
    pub fn validate(&self) -> Result<(), PathError> {
        match self {
            PathReader::Whole(_) | PathReader::Shared(_) => validate(self.at_hand()),
            PathReader::Streamed(s) => {
                let mut source = s.source.restart();
                let n = s.kept.axes.len();
                let mut k = 0;
                while let Some(segment) = source.next_segment() {
                    validate_segment(n, k, &segment)?;
                    k += 1;
                }
                Ok(())
            }
        }
    }

    /// Makes segments up to `end` (exclusive) where the path has them; returns how far it
    /// reaches (`end`, or the path's length if shorter).
    pub fn reach(&mut self, end: usize) -> Result<usize, PathError> {
        match self {
            PathReader::Whole(_) | PathReader::Shared(_) => {
                Ok(end.min(self.at_hand().segments.len()))
            }
            PathReader::Streamed(s) => {
                while !s.done && s.base + s.kept.segments.len() < end {
                    match s.source.next_segment() {
                        Some(segment) => {
                            let k = s.base + s.kept.segments.len();
                            validate_segment(s.kept.axes.len(), k, &segment)?;
                            if k < s.keep_from {
                                // Not needed: only where it ends, the next one's start.
                                s.kept.start = segment.geometry.end().to_vec();
                                s.base = k + 1;
                            } else {
                                s.kept.segments.push(segment);
                            }
                        }
                        None => s.done = true,
                    }
                }
                Ok(end.min(s.base + s.kept.segments.len()))
            }
        }
    }

    /// Forgets the segments before `first`, but the one just before it (where `first` starts,
    /// and the path's last segment once all are read).
    pub fn release(&mut self, first: usize) {
        if let PathReader::Streamed(s) = self {
            s.keep_from = s.keep_from.max(first.saturating_sub(1));
            let k = first
                .saturating_sub(1)
                .saturating_sub(s.base)
                .min(s.kept.segments.len());
            if k > 0 {
                s.kept.start = s.kept.segments[k - 1].geometry.end().to_vec();
                s.kept.segments.drain(..k);
                s.base += k;
            }
        }
    }

    /// The segments at hand as a path whose segment `k` is the path's `k + base`, with the
    /// point before them as its start; and `base`.
    pub fn view(&self) -> (&AxisPath, usize) {
        match self {
            PathReader::Streamed(s) => (&s.kept, s.base),
            PathReader::Whole(_) | PathReader::Shared(_) => (self.at_hand(), 0),
        }
    }

    /// The segments at hand as a path: all of a whole one, those kept of a streamed one.
    fn at_hand(&self) -> &AxisPath {
        match self {
            PathReader::Whole(path) => path,
            PathReader::Shared(path) => path,
            PathReader::Streamed(s) => &s.kept,
        }
    }
}

/// Checks a whole path: its header and every segment.
pub(super) fn validate(path: &AxisPath) -> Result<(), PathError> {
    validate_header(path)?;
    let n = path.axes.len();
    for (k, segment) in path.segments.iter().enumerate() {
        validate_segment(n, k, segment)?;
    }
    Ok(())
}

/// Checks the axis limits, the start and the lever arms of a path.
fn validate_header(path: &AxisPath) -> Result<(), PathError> {
    let n = path.axes.len();
    for (axis, spec) in path.axes.iter().enumerate() {
        let l = spec.limits;
        if !Limits::new(l.velocity, l.acceleration, l.jerk).is_valid() {
            return Err(PathError::InvalidLimits { axis });
        }
    }
    check_len(n, None, path.start.len())?;
    finite(None, "start position", &path.start)?;
    if !path.tool_lever_arms.is_empty() {
        check_len(n, None, path.tool_lever_arms.len())?;
        if !path
            .tool_lever_arms
            .iter()
            .all(|x| x.is_finite() && *x >= 0.0)
        {
            return Err(PathError::InvalidValue {
                segment: None,
                what: "tool lever arm",
            });
        }
    }
    Ok(())
}

/// Checks segment `k` of a path on `n` axes.
fn validate_segment(n: usize, k: usize, segment: &PathSegment) -> Result<(), PathError> {
    let s = Some(k);
    check_len(n, s, segment.geometry.end().len())?;
    check_len(n, s, segment.feed_metric.len())?;
    finite(s, "end position", segment.geometry.end())?;
    finite(s, "feed metric", &segment.feed_metric)?;
    if let Geometry::Arc { center, .. } = &segment.geometry {
        finite(s, "arc centre", center)?;
    }
    if matches!(segment.feed, Some(f) if !(f.is_finite() && f > 0.0)) {
        return Err(PathError::InvalidValue {
            segment: s,
            what: "feed",
        });
    }
    let negative = |t: f64| t.is_nan() || t < 0.0;
    if matches!(segment.blend, Blend::Continuous { tolerance: Some(t) } if negative(t)) {
        return Err(PathError::InvalidValue {
            segment: s,
            what: "tolerance",
        });
    }
    Ok(())
}

fn check_len(n: usize, segment: Option<usize>, found: usize) -> Result<(), PathError> {
    if found == n {
        Ok(())
    } else {
        Err(PathError::AxisCountMismatch {
            segment,
            expected: n,
            found,
        })
    }
}

fn finite(segment: Option<usize>, what: &'static str, values: &[f64]) -> Result<(), PathError> {
    if values.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(PathError::InvalidValue { segment, what })
    }
}
