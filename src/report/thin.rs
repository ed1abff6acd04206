//! Keeping a bounded, evenly spread subset of an unbounded sequence: every `stride`-th item,
//! the stride doubling (and every other kept item dropped) whenever the buffer fills. A run of
//! any length leaves at most `capacity` items, still covering it from start to end.

/// An evenly spread subset of the items pushed, at most `capacity` of them (see the module
/// documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Thinned<T> {
    items: Vec<T>,
    capacity: usize,
    stride: usize,
    seen: usize,
}

impl<T> Thinned<T> {
    /// Keeps at most `capacity` (≥ 2) items.
    pub fn new(capacity: usize) -> Thinned<T> {
        Thinned {
            items: Vec::new(),
            capacity: capacity.max(2),
            stride: 1,
            seen: 0,
        }
    }

    /// Offers the next item of the sequence: kept if it falls on the stride, which doubles
    /// (dropping every other kept item) when the buffer is full.
    pub fn push(&mut self, item: T) {
        if self.seen.is_multiple_of(self.stride) {
            if self.items.len() == self.capacity {
                let mut k = 0;
                self.items.retain(|_| {
                    k += 1;
                    k % 2 == 1
                });
                self.stride *= 2;
                if !self.seen.is_multiple_of(self.stride) {
                    self.seen += 1;
                    return;
                }
            }
            self.items.push(item);
        }
        self.seen += 1;
    }

    /// The items kept, in the order they were pushed.
    pub fn items(&self) -> &[T] {
        &self.items
    }

    /// The items kept, in the order they were pushed.
    pub fn into_items(self) -> Vec<T> {
        self.items
    }

    /// Items seen per item kept.
    pub fn stride(&self) -> usize {
        self.stride
    }
}

/// A polyline thinned to a bounded number of points that still ends where it ends: the last
/// point is kept whether or not the thinning would have kept it.
#[derive(Debug, Clone, PartialEq)]
pub struct ThinnedPath {
    points: Thinned<[f64; 3]>,
    last: Option<[f64; 3]>,
}

impl ThinnedPath {
    /// Keeps at most `capacity` points, plus the last.
    pub fn new(capacity: usize) -> ThinnedPath {
        ThinnedPath {
            points: Thinned::new(capacity),
            last: None,
        }
    }

    /// Appends the next point of the polyline.
    pub fn push(&mut self, point: [f64; 3]) {
        self.points.push(point);
        self.last = Some(point);
    }

    /// The points kept, in order, ending with the last point pushed.
    pub fn into_points(self) -> Vec<[f64; 3]> {
        let mut points = self.points.into_items();
        points.extend(self.last.filter(|l| points.last() != Some(l)));
        points
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stays_bounded_and_evenly_spread() {
        let mut t = Thinned::new(100);
        for k in 0..1_000_000u32 {
            t.push(k);
        }
        assert!(t.items().len() <= 100);
        assert!(t.items().len() >= 50);
        let step = t.stride() as u32;
        for (i, &k) in t.items().iter().enumerate() {
            assert_eq!(k, i as u32 * step);
        }
    }

    #[test]
    fn a_thinned_path_ends_at_its_last_point() {
        let mut path = ThinnedPath::new(10);
        for k in 0..1001 {
            path.push([k as f64, 0.0, 0.0]);
        }
        let points = path.into_points();
        assert!(points.len() <= 11);
        assert_eq!(points.first(), Some(&[0.0, 0.0, 0.0]));
        assert_eq!(points.last(), Some(&[1000.0, 0.0, 0.0]));
    }

    #[test]
    fn short_sequences_are_kept_whole() {
        let mut t = Thinned::new(10);
        for k in 0..7 {
            t.push(k);
        }
        assert_eq!(t.items(), &[0, 1, 2, 3, 4, 5, 6]);
    }
}
