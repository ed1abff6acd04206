//! The plotter's coordinate systems and modal state.
//!
//! Three frames: *user units* (after `SC`), *plotter units* in the current `RO` rotation
//! (P1, P2, the pen position and label sizes live here), and the *page* (plotter units of the
//! unrotated plotter, which is the table's XY frame, 40 units per millimetre by default).

use super::super::options::HpglOptions;
use super::label::LabelStyle;

/// SC scaling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Scaling {
    /// User `min..max` maps onto P1..P2 (type 0, the HP-GL/1 form).
    Anisotropic { min: [f64; 2], max: [f64; 2] },
    /// Equal units on both axes, the spare room shared out by `left`/`bottom` percent.
    Isotropic {
        min: [f64; 2],
        max: [f64; 2],
        left: f64,
        bottom: f64,
    },
    /// `SC xmin,xfactor,ymin,yfactor,2`: plotter units per user unit, user `min` at P1.
    PointFactor { min: [f64; 2], factor: [f64; 2] },
}

/// How the chord parameter of CI, AA, AR, AT, RT and wedges is read (`CT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ChordMode {
    /// Degrees per chord.
    Angle,
    /// Largest distance (current units) between chord and arc.
    Deviation,
}

/// Fill type (`FT`) and pen thickness (`PT`), which spaces solid fills.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FillStyle {
    /// 1, 2 solid (bidirectional, unidirectional), 3 hatch, 4 cross-hatch, 10 shading.
    pub(super) kind: u32,
    /// Hatch spacing in plotter units; `None` = 1 % of the P1–P2 diagonal.
    pub(super) spacing: Option<f64>,
    pub(super) angle_deg: f64,
    /// Shading level in percent (type 10).
    pub(super) level: f64,
    /// Pen thickness (mm) for solid fills.
    pub(super) pen_mm: f64,
}

impl Default for FillStyle {
    fn default() -> Self {
        FillStyle {
            kind: 1,
            spacing: None,
            angle_deg: 0.0,
            level: 100.0,
            pen_mm: 0.3,
        }
    }
}

/// The plotter's state while reading.
#[derive(Debug, Clone)]
pub(super) struct Plotter {
    pub(super) absolute: bool,
    pub(super) pen_down: bool,
    /// Current pen position in plotter units (current rotation).
    pub(super) position: [f64; 2],
    pub(super) scaling: Option<Scaling>,
    pub(super) p1: [f64; 2],
    pub(super) p2: [f64; 2],
    /// Drawing speed, m/s.
    pub(super) speed: f64,
    /// `RO`: 0, 90, 180 or 270 degrees.
    pub(super) rotation: u32,
    /// Page size set by `PS` (plotter units, unrotated); `None` = the options' default page.
    pub(super) page: Option<[f64; 2]>,
    pub(super) chord_mode: ChordMode,
    pub(super) fill: FillStyle,
    /// The fill anchor corner (AC), plotter units: hatch lines are laid from it.
    pub(super) fill_anchor: [f64; 2],
    pub(super) label: LabelStyle,
    /// `TL`: tick lengths (positive, negative) in percent of P2 − P1.
    pub(super) tick: [f64; 2],
    /// `IW`: drawing window in plotter units (low corner, high corner).
    pub(super) window: Option<([f64; 2], [f64; 2])>,
    /// `SM`: the symbol drawn at each point, if any.
    pub(super) symbol: Option<u8>,
    /// `WU1`: pen widths in percent of the P1–P2 diagonal rather than millimetres.
    pub(super) width_relative: bool,
}

impl Plotter {
    pub(super) fn new(options: &HpglOptions) -> Self {
        Plotter {
            absolute: true,
            pen_down: false,
            position: [0.0, 0.0],
            scaling: None,
            p1: options.default_p1,
            p2: options.default_p2,
            speed: options.default_speed,
            rotation: 0,
            page: None,
            chord_mode: ChordMode::Angle,
            fill: FillStyle::default(),
            fill_anchor: [0.0, 0.0],
            label: LabelStyle::default(),
            tick: [0.5, 0.5],
            window: None,
            symbol: None,
            width_relative: false,
        }
    }

    /// The page size in the current rotation (plotter units).
    pub(super) fn page_extent(&self, options: &HpglOptions) -> [f64; 2] {
        let page = self.page.unwrap_or(options.default_page);
        if self.rotation % 180 == 90 {
            [page[1], page[0]]
        } else {
            page
        }
    }

    /// User → plotter units: plotter = offset + factor × user (per axis).
    pub(super) fn user_map(&self) -> ([f64; 2], [f64; 2]) {
        let span = [self.p2[0] - self.p1[0], self.p2[1] - self.p1[1]];
        match self.scaling {
            None => ([1.0, 1.0], [0.0, 0.0]),
            Some(Scaling::Anisotropic { min, max }) => {
                let factor = [span[0] / (max[0] - min[0]), span[1] / (max[1] - min[1])];
                (
                    factor,
                    [
                        self.p1[0] - min[0] * factor[0],
                        self.p1[1] - min[1] * factor[1],
                    ],
                )
            }
            Some(Scaling::Isotropic {
                min,
                max,
                left,
                bottom,
            }) => {
                let raw = [span[0] / (max[0] - min[0]), span[1] / (max[1] - min[1])];
                let size = raw[0].abs().min(raw[1].abs());
                let factor = [size.copysign(raw[0]), size.copysign(raw[1])];
                // The room the picture does not use, shared out as asked.
                let spare = [
                    span[0] - (max[0] - min[0]) * factor[0],
                    span[1] - (max[1] - min[1]) * factor[1],
                ];
                (
                    factor,
                    [
                        self.p1[0] + spare[0] * left / 100.0 - min[0] * factor[0],
                        self.p1[1] + spare[1] * bottom / 100.0 - min[1] * factor[1],
                    ],
                )
            }
            Some(Scaling::PointFactor { min, factor }) => (
                factor,
                [
                    self.p1[0] - min[0] * factor[0],
                    self.p1[1] - min[1] * factor[1],
                ],
            ),
        }
    }

    pub(super) fn to_plotter(&self, user: [f64; 2]) -> [f64; 2] {
        let (factor, offset) = self.user_map();
        [
            offset[0] + user[0] * factor[0],
            offset[1] + user[1] * factor[1],
        ]
    }

    pub(super) fn to_user(&self, plotter: [f64; 2]) -> [f64; 2] {
        let (factor, offset) = self.user_map();
        [
            (plotter[0] - offset[0]) / factor[0],
            (plotter[1] - offset[1]) / factor[1],
        ]
    }

    /// A user-unit displacement in plotter units.
    pub(super) fn scale_delta(&self, delta: [f64; 2]) -> [f64; 2] {
        let (factor, _) = self.user_map();
        [delta[0] * factor[0], delta[1] * factor[1]]
    }

    /// Target of a coordinate pair under the current PA/PR mode, in plotter units.
    pub(super) fn target(&self, pair: [f64; 2]) -> [f64; 2] {
        if self.absolute {
            self.to_plotter(pair)
        } else {
            let delta = self.scale_delta(pair);
            [self.position[0] + delta[0], self.position[1] + delta[1]]
        }
    }

    /// Plotter units (current rotation) → page (unrotated plotter units). RO turns the
    /// coordinate system counter-clockwise and moves its origin to keep the page in the
    /// first quadrant (RO 90: origin at the page's lower-right corner).
    pub(super) fn to_page(&self, point: [f64; 2], options: &HpglOptions) -> [f64; 2] {
        let page = self.page.unwrap_or(options.default_page);
        let [x, y] = point;
        match self.rotation {
            90 => [page[0] - y, x],
            180 => [page[0] - x, page[1] - y],
            270 => [y, page[1] - x],
            _ => [x, y],
        }
    }

    /// The inverse of [`Plotter::to_page`].
    pub(super) fn page_to_plotter(&self, point: [f64; 2], options: &HpglOptions) -> [f64; 2] {
        let page = self.page.unwrap_or(options.default_page);
        let [x, y] = point;
        match self.rotation {
            90 => [y, page[0] - x],
            180 => [page[0] - x, page[1] - y],
            270 => [page[1] - y, x],
            _ => [x, y],
        }
    }

    /// Whether user units map onto plotter units with equal scale on both axes (arcs stay
    /// circles), and whether the map mirrors (arcs change direction).
    pub(super) fn user_map_shape(&self) -> (bool, bool) {
        let (factor, _) = self.user_map();
        let similar = (factor[0].abs() - factor[1].abs()).abs()
            <= 1e-12 * factor[0].abs().max(factor[1].abs());
        (similar, factor[0] * factor[1] < 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_keeps_the_page_in_the_first_quadrant_and_round_trips() {
        let options = HpglOptions::default();
        let mut plotter = Plotter::new(&options);
        plotter.page = Some([1000.0, 600.0]);
        for rotation in [0, 90, 180, 270] {
            plotter.rotation = rotation;
            let extent = plotter.page_extent(&options);
            for corner in [[0.0, 0.0], [extent[0], extent[1]], [extent[0], 0.0]] {
                let page = plotter.to_page(corner, &options);
                assert!(page[0] >= 0.0 && page[0] <= 1000.0 && page[1] >= 0.0 && page[1] <= 600.0);
                assert_eq!(plotter.page_to_plotter(page, &options), corner);
            }
        }
        // RO 90: the rotated x axis points up the page.
        plotter.rotation = 90;
        assert_eq!(plotter.to_page([10.0, 0.0], &options), [1000.0, 10.0]);
    }

    #[test]
    fn isotropic_scaling_centres_the_picture() {
        let options = HpglOptions::default();
        let mut plotter = Plotter::new(&options);
        plotter.p1 = [0.0, 0.0];
        plotter.p2 = [2000.0, 1000.0];
        plotter.scaling = Some(Scaling::Isotropic {
            min: [0.0, 0.0],
            max: [10.0, 10.0],
            left: 50.0,
            bottom: 50.0,
        });
        assert_eq!(plotter.to_plotter([0.0, 0.0]), [500.0, 0.0]);
        assert_eq!(plotter.to_plotter([10.0, 10.0]), [1500.0, 1000.0]);
    }
}
