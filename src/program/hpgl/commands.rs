//! What each HPGL command does to the plotter and the drawing.

use super::encoded::{self, Encoded};
use super::fill::{Edge, Piece, Polygon, Rule, SubPath};
use super::label::{self, Direction, LabelStyle, Size};
use super::plotter::{ChordMode, FillStyle, Plotter, Scaling};
use super::scan::{Parameter, ETX};
use super::{Problem, Reader};
use crate::program::types::Span;

/// Commands that do not move the pen, passed over with one warning per kind: what each is.
const NOT_DRAWING: &[(&str, &str)] = &[
    ("CO", "comment"),
    ("PC", "pen colour"),
    ("NP", "number of pens"),
    ("CR", "colour range"),
    ("TR", "transparency"),
    ("MC", "merge control"),
    ("PP", "pixel placement"),
    ("QL", "quality level"),
    ("LA", "line attributes"),
    ("UL", "user line type"),
    ("SV", "screened vectors"),
    ("RF", "raster fill definition"),
    ("AC", "fill anchor corner"),
    ("BP", "begin plot"),
    ("EC", "enable cutter"),
    ("FS", "force select"),
    ("AS", "acceleration select"),
    ("VA", "adaptive velocity"),
    ("VN", "normal velocity"),
    ("NR", "not ready"),
    ("IM", "input mask"),
    ("IV", "invoke character slot"),
    ("GC", "group count"),
    ("DC", "digitize clear"),
    ("DP", "digitize point"),
    ("KY", "define key"),
    ("MG", "message"),
    ("WD", "write to display"),
    ("CV", "curved line generator"),
    ("SG", "select pen group"),
    ("ST", "sort"),
    ("FN", "font"),
    ("FI", "select primary font"),
    ("FR", "advance frame"),
    ("SB", "scalable or bitmap fonts"),
    ("SD", "standard font definition"),
    ("AD", "alternate font definition"),
    ("TD", "transparent data"),
    ("LM", "label mode"),
    ("DL", "download character"),
    ("PG", "advance page"),
    ("AF", "advance full page"),
    ("AH", "advance half page"),
    ("OA", "output actual position"),
    ("OC", "output commanded position"),
    ("OD", "output digitized point"),
    ("OE", "output error"),
    ("OF", "output factors"),
    ("OH", "output hard-clip limits"),
    ("OI", "output identification"),
    ("OL", "output label length"),
    ("OO", "output options"),
    ("OP", "output P1 and P2"),
    ("OS", "output status"),
    ("OT", "output carousel type"),
    ("OW", "output window"),
];

/// The commands `execute` carries out (the rest are described, or unknown).
const CARRIED_OUT: &[&str] = &[
    "LB", "BL", "DT", "SM", "PE", "IN", "DF", "SC", "IP", "IR", "RO", "PS", "WU", "PW", "IW", "SP",
    "VS", "LT", "PU", "PD", "PA", "PR", "CT", "CI", "AA", "AR", "AT", "RT", "BZ", "BR", "PM", "EP",
    "FP", "EA", "ER", "RA", "RR", "EW", "WG", "FT", "PT", "TL", "XT", "YT", "SI", "SR", "DI", "DR",
    "SL", "ES", "LO", "CP", "PB", "SS", "SA", "CS", "CA", "DV", "UC",
];

/// Commands that draw in some plotter's dialect but are not drawn here: refused by name.
const DRAWS: &[(&str, &str)] = &[
    ("UC", "user-defined characters"),
    ("RP", "replot (the plot drawn again)"),
];

fn description(name: &str) -> Option<&'static str> {
    NOT_DRAWING
        .iter()
        .find(|(mnemonic, _)| *mnemonic == name)
        .map(|(_, text)| *text)
}

/// Commands whose parameters may be quoted strings.
fn takes_strings(name: &str) -> bool {
    matches!(name, "BP" | "CO" | "MG" | "DL" | "SD" | "AD")
}

fn count_error(name: &str, allowed: &str, found: usize) -> Problem {
    Problem::new(format!(
        "expected {allowed} parameters after {name}, not {found}"
    ))
}

fn fmt_number(value: f64) -> String {
    format!("{value}")
}

impl Reader<'_> {
    pub(super) fn command(&mut self) {
        let start = self.scan.at;
        let mnemonic = match self.scan.mnemonic() {
            Ok(mnemonic) => mnemonic,
            Err(_) if self.trailing_junk(start) => return,
            Err(error) => {
                self.scan_error(error);
                self.scan.skip_to_terminator();
                return;
            }
        };
        let name = String::from_utf8_lossy(&mnemonic).into_owned();
        let span = self.span(start);
        let result = match name.as_str() {
            "LB" | "BL" => {
                let terminator = self.plotter.label.terminator;
                let (text_start, text_end, _) = self.scan.label_text(terminator);
                let text = self.scan.text[text_start..text_end].to_vec();
                if name == "BL" {
                    self.label_buffer = text;
                    Ok(())
                } else {
                    self.label(&text, Some(text_start), start, span)
                }
            }
            "DT" => match self.scan.terminator_definition() {
                Ok(terminator) => {
                    self.plotter.label.terminator = terminator.unwrap_or(ETX);
                    Ok(())
                }
                Err(error) => {
                    self.scan_error(error);
                    self.scan.skip_to_terminator();
                    return;
                }
            },
            "SM" => {
                self.plotter.symbol = self.scan.symbol();
                Ok(())
            }
            "PE" => {
                let (data_start, data_end) = self.scan.encoded();
                let undone = if self.options.strict {
                    None
                } else {
                    encoded::undo_utf8(self.scan.text, data_start, data_end)
                };
                let result = match &undone {
                    None => {
                        encoded::decode(self.scan.text, data_start, data_end, !self.options.strict)
                    }
                    Some((bytes, offsets)) => {
                        self.skip(
                            "PE UTF-8",
                            start,
                            data_end,
                            "PE data re-encoded as UTF-8 after the driver wrote them (bytes no PE data hold) are not what the driver wrote",
                            "were decoded from UTF-8 back to the driver's bytes (exact), then read",
                        );
                        // Offsets back into the file, for spans and messages.
                        let back = |at: usize| offsets.get(at).copied().unwrap_or(data_end);
                        encoded::decode(bytes, 0, bytes.len(), true)
                            .map(|(decoded, dropped)| {
                                let decoded = decoded
                                    .into_iter()
                                    .map(|element| match element {
                                        Encoded::Pen { number, at } => Encoded::Pen {
                                            number,
                                            at: back(at),
                                        },
                                        Encoded::Point {
                                            xy,
                                            absolute,
                                            pen_up,
                                            at,
                                        } => Encoded::Point {
                                            xy,
                                            absolute,
                                            pen_up,
                                            at: back(at),
                                        },
                                    })
                                    .collect();
                                (decoded, dropped.map(back))
                            })
                            .map_err(|mut error| {
                                error.start = back(error.start);
                                error.end = back(error.end).max(error.start + 1);
                                error
                            })
                    }
                };
                match result {
                    Ok((decoded, dropped)) => {
                        if let Some(dropped) = dropped {
                            self.skip(
                                "PE tail",
                                dropped,
                                data_end,
                                "PE data that end in an unfinished number (no terminating digit before ';') are not a pen move",
                                "the unfinished number was dropped, as plotters and ezdxf drop it",
                            );
                        }
                        self.encoded_polyline(&decoded)
                    }
                    Err(error) => {
                        self.scan_error(error);
                        return;
                    }
                }
            }
            // The unquoted form some drivers write (`CO text;`).
            "CO" if !self.options.strict && self.scan.unquoted_comment() => {
                self.skip(
                    "CO",
                    start,
                    self.scan.at,
                    "CO (comment) is not a pen move",
                    "was skipped",
                );
                Ok(())
            }
            _ => {
                let parameters = match self.scan.parameters(&name, takes_strings(&name)) {
                    Ok(parameters) => parameters,
                    // A command a plotter does not know is passed over, parameters and all.
                    Err(_) if self.unknown_skipped(&name, start) => {
                        self.scan.skip_to_terminator();
                        return;
                    }
                    Err(error) => {
                        self.scan_error(error);
                        self.scan.skip_to_terminator();
                        return;
                    }
                };
                self.execute(&name, &parameters, start, span)
            }
        };
        if let Err(problem) = result {
            let end = self.scan.at.max(start + 2);
            // Quote the command and its parameters, not the terminator.
            let end = if self.scan.text.get(end - 1) == Some(&b';') {
                end - 1
            } else {
                end
            };
            self.error(start, end, problem.problem, problem.hint.as_deref());
        }
    }

    fn execute(
        &mut self,
        name: &str,
        parameters: &[Parameter],
        start: usize,
        span: Span,
    ) -> Result<(), Problem> {
        let values: Vec<f64> = parameters.iter().map(|p| p.value).collect();
        let count = |allowed: &str| Err(count_error(name, allowed, values.len()));
        match name {
            "IN" => {
                self.pen_up(span);
                let page = self.plotter.to_page(self.plotter.position, self.options);
                let kept_page = self.plotter.page;
                self.plotter = Plotter::new(self.options);
                self.plotter.page = kept_page;
                if let Some(size) = kept_page {
                    self.plotter.p1 = [0.0, 0.0];
                    self.plotter.p2 = size;
                }
                self.plotter.position = self.plotter.page_to_plotter(page, self.options);
                self.carriage = self.plotter.position;
                self.polygon_mode = false;
            }
            "DF" => {
                let defaults = Plotter::new(self.options);
                let plotter = &mut self.plotter;
                plotter.absolute = true;
                plotter.scaling = None;
                plotter.chord_mode = defaults.chord_mode;
                plotter.fill = defaults.fill;
                plotter.fill_anchor = defaults.fill_anchor;
                plotter.label = defaults.label;
                plotter.tick = defaults.tick;
                plotter.window = None;
                plotter.symbol = None;
                self.polygon_mode = false;
            }
            "SC" => self.scale(name, &values)?,
            "IP" => match values.as_slice() {
                [] => self.default_p1_p2(),
                &[x1, y1] => {
                    // P2 keeps its distance from P1.
                    let shift = [x1 - self.plotter.p1[0], y1 - self.plotter.p1[1]];
                    self.plotter.p1 = [x1, y1];
                    self.plotter.p2 =
                        [self.plotter.p2[0] + shift[0], self.plotter.p2[1] + shift[1]];
                }
                &[x1, y1, x2, y2] => {
                    self.plotter.p1 = [x1, y1];
                    self.plotter.p2 = [x2, y2];
                }
                _ => return count("0, 2 or 4"),
            },
            "IR" => {
                let extent = self.plotter.page_extent(self.options);
                let at = |x: f64, y: f64| [extent[0] * x / 100.0, extent[1] * y / 100.0];
                match values.as_slice() {
                    [] => self.default_p1_p2(),
                    &[x1, y1] => {
                        let p1 = at(x1, y1);
                        let shift = [p1[0] - self.plotter.p1[0], p1[1] - self.plotter.p1[1]];
                        self.plotter.p1 = p1;
                        self.plotter.p2 =
                            [self.plotter.p2[0] + shift[0], self.plotter.p2[1] + shift[1]];
                    }
                    &[x1, y1, x2, y2] => {
                        self.plotter.p1 = at(x1, y1);
                        self.plotter.p2 = at(x2, y2);
                    }
                    _ => return count("0, 2 or 4"),
                }
            }
            "RO" => {
                let rotation = match values.as_slice() {
                    [] => 0.0,
                    &[angle] => angle,
                    _ => return count("0 or 1"),
                };
                if ![0.0, 90.0, 180.0, 270.0].contains(&rotation) {
                    return Err(Problem::new(format!(
                        "expected a rotation of 0, 90, 180 or 270 degrees after RO, not {}",
                        fmt_number(rotation)
                    )));
                }
                // The pen and P1/P2 keep their places on the page.
                let options = self.options;
                let page_of = |plotter: &Plotter, point| plotter.to_page(point, options);
                let (position, p1, p2) = (
                    page_of(&self.plotter, self.plotter.position),
                    page_of(&self.plotter, self.plotter.p1),
                    page_of(&self.plotter, self.plotter.p2),
                );
                self.plotter.rotation = rotation as u32;
                let back = |point| self.plotter.page_to_plotter(point, options);
                let (position, p1, p2) = (back(position), back(p1), back(p2));
                self.plotter.position = position;
                self.plotter.p1 = [p1[0].min(p2[0]), p1[1].min(p2[1])];
                self.plotter.p2 = [p1[0].max(p2[0]), p1[1].max(p2[1])];
                self.carriage = position;
            }
            // HP-GL/1 pen plotters (HP 7475A, 7550A) read `PS n` as the paper loaded (4:
            // A/A4, 0: B/A3), which vpype writes for them; as an HP-GL/2 plot size it would be
            // a page a tenth of a millimetre long. The page and P1/P2 stay as they were.
            "PS" if matches!(*values.as_slice(), [n] if n.fract() == 0.0 && (0.0..=4.0).contains(&n)) =>
            {
                self.skip(
                    "PS paper",
                    start,
                    self.scan.at,
                    &format!("PS{} selects the paper of an HP-GL/1 plotter (HP 7475A: 4 = A/A4, 0 = B/A3), not a plot size", fmt_number(values[0])),
                    "the page and P1/P2 were left as they were",
                );
            }
            "PS" => {
                let default = self.options.default_page;
                let page = match values.as_slice() {
                    [] => default,
                    &[length] => [length, default[1]],
                    &[length, width] => [length, width],
                    _ => return count("0, 1 or 2"),
                };
                if page[0] <= 0.0 || page[1] <= 0.0 {
                    return Err(Problem::new(format!(
                        "expected a positive plot size after PS, not {},{}",
                        fmt_number(page[0]),
                        fmt_number(page[1])
                    )));
                }
                self.plotter.page = Some(page);
                self.plotter.p1 = [0.0, 0.0];
                self.plotter.p2 = self.plotter.page_extent(self.options);
            }
            "WU" => {
                match values.as_slice() {
                    [] | [0.0] => self.plotter.width_relative = false,
                    [1.0] => self.plotter.width_relative = true,
                    _ => return Err(Problem::new(
                        "expected WU0 (pen widths in mm) or WU1 (percent of the P1-P2 diagonal)",
                    )),
                }
            }
            "PW" => {
                let width = match *values.as_slice() {
                    [] => FillStyle::default().pen_mm,
                    [width] | [width, _] => width,
                    _ => return count("0, 1 or 2"),
                };
                let mm = if self.plotter.width_relative {
                    let diagonal = (self.plotter.p2[0] - self.plotter.p1[0])
                        .hypot(self.plotter.p2[1] - self.plotter.p1[1]);
                    width / 100.0 * diagonal / self.options.units_per_mm
                } else {
                    width
                };
                // The pen's width spaces the lines of solid fills; a width of 0 (the
                // thinnest line the device draws) leaves the spacing as it was.
                if mm > 0.0 {
                    self.plotter.fill.pen_mm = mm;
                }
            }
            "IW" => match values.as_slice() {
                [] => self.plotter.window = None,
                &[x1, y1, x2, y2] => {
                    let low = self.plotter.to_plotter([x1, y1]);
                    let high = self.plotter.to_plotter([x2, y2]);
                    self.plotter.window = Some((
                        [low[0].min(high[0]), low[1].min(high[1])],
                        [low[0].max(high[0]), low[1].max(high[1])],
                    ));
                }
                _ => return count("0 or 4"),
            },
            "SP" => {
                if values.len() > 1 {
                    return count("0 or 1");
                }
                self.select_pen(span);
            }
            "VS" => match values.as_slice() {
                [] => self.plotter.speed = self.options.default_speed,
                &[speed] | &[speed, _] => {
                    if speed <= 0.0 {
                        return Err(Problem::new(format!(
                            "expected a positive pen speed (cm/s) after VS, not {speed}"
                        )));
                    }
                    self.plotter.speed = speed / 100.0;
                }
                _ => return count("0, 1 or 2"),
            },
            "LT" => match values.as_slice() {
                [] => {}
                [pattern, ..] if values.len() <= 3 => {
                    let what = format!("LT (line type) {} is a dashed line", fmt_number(*pattern));
                    let kind = format!("LT{pattern}");
                    self.skip(&kind, start, self.scan.at, &what, "is drawn solid");
                }
                _ => return count("0 to 3"),
            },
            "PU" | "PD" | "PA" | "PR" => self.plot(name, parameters, start, span)?,
            "CT" => {
                self.plotter.chord_mode = match values.as_slice() {
                    [] | [0.0] => ChordMode::Angle,
                    [1.0] => ChordMode::Deviation,
                    _ => {
                        return Err(Problem::new(
                            "expected CT, CT0 (chord angle) or CT1 (chord deviation)",
                        ))
                    }
                };
            }
            "CI" => {
                let (radius, chord) = match *values.as_slice() {
                    [radius] => (radius, None),
                    [radius, chord] => (radius, Some(chord)),
                    _ => return count("1 or 2"),
                };
                self.circle(radius, chord, span)?;
            }
            "AA" | "AR" => {
                let (x, y, sweep, chord) = match *values.as_slice() {
                    [x, y, sweep] => (x, y, sweep, None),
                    [x, y, sweep, chord] => (x, y, sweep, Some(chord)),
                    _ => return count("3 or 4"),
                };
                let here = self.plotter.to_user(self.plotter.position);
                let centre = if name == "AA" {
                    [x, y]
                } else {
                    [here[0] + x, here[1] + y]
                };
                if sweep == 0.0 || (centre[0] - here[0]).hypot(centre[1] - here[1]) == 0.0 {
                    let message = format!("{name} with zero radius or zero sweep draws nothing");
                    self.warn(span, message);
                    return Ok(());
                }
                self.user_arc(centre, sweep, chord, span)?;
            }
            "AT" | "RT" => {
                let (through, end, chord) = match *values.as_slice() {
                    [xi, yi, xe, ye] => ([xi, yi], [xe, ye], None),
                    [xi, yi, xe, ye, chord] => ([xi, yi], [xe, ye], Some(chord)),
                    _ => return count("4 or 5"),
                };
                let here = self.plotter.to_user(self.plotter.position);
                let (through, end) = if name == "AT" {
                    (through, end)
                } else {
                    (
                        [here[0] + through[0], here[1] + through[1]],
                        [here[0] + end[0], here[1] + end[1]],
                    )
                };
                self.three_point_arc(here, through, end, chord, span)?;
            }
            "BZ" | "BR" => {
                if values.is_empty() || !values.len().is_multiple_of(6) {
                    return count("a multiple of 6 (control points and end point)");
                }
                for curve in values.chunks_exact(6) {
                    let here = self.plotter.to_user(self.plotter.position);
                    let mut points = [
                        [curve[0], curve[1]],
                        [curve[2], curve[3]],
                        [curve[4], curve[5]],
                    ];
                    if name == "BR" {
                        for point in &mut points {
                            *point = [here[0] + point[0], here[1] + point[1]];
                        }
                    }
                    self.bezier(points, span)?;
                }
            }
            "PM" => match values.as_slice() {
                [] | [0.0] => {
                    // The stroke drawn so far ends; the pen stays up or down as it is
                    // (HP-GL/2): KiCad enters polygon mode with the pen down, so its edges
                    // are pen-down moves.
                    let down = self.plotter.pen_down;
                    self.pen_up(span);
                    self.plotter.pen_down = down;
                    self.polygon_mode = true;
                    self.polygon = Polygon {
                        paths: vec![SubPath {
                            start: self.plotter.position,
                            edges: Vec::new(),
                            open: false,
                        }],
                    };
                }
                [1.0] | [2.0] => {
                    if !self.polygon_mode {
                        return Err(Problem::new(format!(
                            "expected PM0 (polygon mode) before PM{}",
                            fmt_number(values[0])
                        )));
                    }
                    self.close_subpolygon();
                    if values[0] == 2.0 {
                        self.polygon_mode = false;
                    }
                }
                _ => return Err(Problem::new("expected PM0, PM1 or PM2")),
            },
            "EP" | "FP" => {
                if self.polygon_mode {
                    return Err(Problem::new(format!(
                        "expected PM2 (end of polygon mode) before {name}"
                    )));
                }
                let rule = match (name, values.as_slice()) {
                    ("EP", []) => None,
                    ("FP", [] | [0.0]) => Some(Rule::EvenOdd),
                    ("FP", [1.0]) => Some(Rule::NonZero),
                    _ => {
                        return Err(Problem::new(format!(
                            "expected {name} with {}",
                            if name == "EP" {
                                "no parameters"
                            } else {
                                "fill method 0 (even-odd) or 1 (non-zero winding)"
                            }
                        )))
                    }
                };
                let polygon = self.polygon.clone();
                let position = self.plotter.position;
                let was_down = self.plotter.pen_down;
                match rule {
                    None => {
                        self.outline(&polygon, false, span)?;
                        self.return_pen(position, was_down, span)?;
                    }
                    Some(rule) => self.fill(&polygon, rule, span)?,
                }
            }
            "EA" | "ER" | "RA" | "RR" => {
                // One corner; more pairs (`RA0,0,4000,4000`) are not HP-GL, but hp2xx draws
                // a rectangle for each from the same pen position, and so does cncsim (with a
                // warning; refused with --strict).
                let pairs = values.len() / 2;
                if !values.len().is_multiple_of(2)
                    || pairs == 0
                    || (pairs > 1 && self.options.strict)
                {
                    return count("2");
                }
                if pairs > 1 {
                    self.skip(
                        &format!("{name} pairs"),
                        start,
                        self.scan.at,
                        &format!("{name} takes one corner (2 parameters), not {}", values.len()),
                        "each pair was drawn as a rectangle from the same pen position, as hp2xx reads them",
                    );
                }
                for corner in values.chunks_exact(2) {
                    let here = self.plotter.to_user(self.plotter.position);
                    let corner = if name.ends_with('A') {
                        [corner[0], corner[1]]
                    } else {
                        [here[0] + corner[0], here[1] + corner[1]]
                    };
                    let corners = [[corner[0], here[1]], corner, [here[0], corner[1]], here];
                    let polygon = self.user_polygon(&corners);
                    self.shape(name.starts_with('E'), polygon, span)?;
                }
            }
            "EW" | "WG" => {
                let (radius, start_deg, sweep, chord) = match *values.as_slice() {
                    [r, a, s] => (r, a, s, None),
                    [r, a, s, c] => (r, a, s, Some(c)),
                    _ => return count("3 or 4"),
                };
                self.wedge(name == "EW", radius, start_deg, sweep, chord, span)?;
            }
            "AC" => {
                self.plotter.fill_anchor = match *values.as_slice() {
                    [] => [0.0, 0.0],
                    [x, y] => self.plotter.to_plotter([x, y]),
                    _ => return count("0 or 2"),
                };
            }
            "FT" => {
                let defaults = FillStyle::default();
                let pen_mm = self.plotter.fill.pen_mm;
                let (factor, _) = self.plotter.user_map();
                let style = match *values.as_slice() {
                    [] => defaults,
                    [kind, ref rest @ ..] if rest.len() <= 2 => {
                        let kind_ok = [1.0, 2.0, 3.0, 4.0, 10.0].contains(&kind);
                        let raster = [11.0, 21.0, 22.0].contains(&kind);
                        if raster && !self.options.strict {
                            // A raster pattern cannot be drawn with a pen: filled solid,
                            // as ezdxf reads these types.
                            self.skip(
                                &format!("FT {kind}"),
                                start,
                                self.scan.at,
                                &format!(
                                    "FT {} (a raster fill pattern) cannot be drawn with a pen",
                                    fmt_number(kind)
                                ),
                                "its fills are drawn solid instead",
                            );
                            self.plotter.fill = FillStyle { pen_mm, ..defaults };
                            return Ok(());
                        }
                        if !kind_ok {
                            return Err(Problem::new(format!(
                                "expected fill type 1, 2 (solid), 3, 4 (hatch) or 10 (shading) after FT, not {}", fmt_number(kind)
                            ))
                            .hint("raster fill patterns (FT 11, 21, 22) cannot be drawn with a pen"));
                        }
                        let mut style = FillStyle {
                            kind: kind as u32,
                            ..defaults
                        };
                        if kind == 10.0 {
                            if let Some(&level) = rest.first() {
                                style.level = level;
                            }
                        } else if let Some(&spacing) = rest.first() {
                            if spacing != 0.0 {
                                // Spacing in current units, measured along X.
                                style.spacing = Some((spacing * factor[0]).abs());
                            }
                        }
                        if let Some(&angle) = rest.get(1) {
                            style.angle_deg = angle;
                        }
                        style
                    }
                    _ => return count("0 to 3"),
                };
                self.plotter.fill = FillStyle { pen_mm, ..style };
            }
            "PT" => match values.as_slice() {
                [] => self.plotter.fill.pen_mm = FillStyle::default().pen_mm,
                &[mm] if mm > 0.0 && mm <= 5.0 => self.plotter.fill.pen_mm = mm,
                // Out of range (PT0 is common): a plotter ignores the command.
                &[mm] if !self.options.strict => {
                    let what = format!(
                        "PT {} (pen thickness) is out of the range 0.1 to 5 mm",
                        fmt_number(mm)
                    );
                    self.skip(
                        "PT range",
                        start,
                        self.scan.at,
                        &what,
                        "was ignored, as plotters ignore it",
                    );
                }
                &[mm] => {
                    return Err(Problem::new(format!(
                        "expected a pen thickness of more than 0 and at most 5 mm after PT, not {}",
                        fmt_number(mm)
                    )))
                }
                _ => return count("0 or 1"),
            },
            "TL" => {
                self.plotter.tick = match values.as_slice() {
                    [] => Plotter::new(self.options).tick,
                    &[positive] => [positive, 0.0],
                    &[positive, negative] => [positive, negative],
                    _ => return count("0, 1 or 2"),
                };
            }
            "XT" | "YT" => {
                if !values.is_empty() {
                    return count("0");
                }
                self.tick(name == "XT", span)?;
            }
            "SI" | "SR" => {
                let size = match (name, values.as_slice()) {
                    ("SI", []) => Size::Absolute {
                        width_cm: 0.187,
                        height_cm: 0.269,
                    },
                    ("SR", []) => LabelStyle::default().size,
                    (_, &[width, height]) => {
                        if width == 0.0 || height == 0.0 {
                            return Err(Problem::new(format!(
                                "expected a non-zero character width and height after {name}"
                            )));
                        }
                        if name == "SI" {
                            Size::Absolute {
                                width_cm: width,
                                height_cm: height,
                            }
                        } else {
                            Size::Relative { width, height }
                        }
                    }
                    _ => return count("0 or 2"),
                };
                self.plotter.label.size = size;
            }
            "DI" | "DR" => {
                let direction = match values.as_slice() {
                    [] => LabelStyle::default().direction,
                    &[run, rise] => {
                        if run == 0.0 && rise == 0.0 {
                            return Err(Problem::new(format!(
                                "expected a direction other than 0,0 after {name}"
                            )));
                        }
                        if name == "DI" {
                            Direction::Absolute { run, rise }
                        } else {
                            Direction::Relative { run, rise }
                        }
                    }
                    _ => return count("0 or 2"),
                };
                self.plotter.label.direction = direction;
                self.carriage = self.plotter.position;
            }
            "SL" => match values.as_slice() {
                [] => self.plotter.label.slant = 0.0,
                &[slant] => self.plotter.label.slant = slant,
                _ => return count("0 or 1"),
            },
            "ES" => {
                self.plotter.label.extra = match values.as_slice() {
                    [] => [0.0, 0.0],
                    &[spaces] => [spaces, 0.0],
                    &[spaces, lines] => [spaces, lines],
                    _ => return count("0, 1 or 2"),
                };
            }
            "LO" => match values.as_slice() {
                [] => self.plotter.label.origin = 1,
                &[origin]
                    if origin.fract() == 0.0
                        && ((1.0..=9.0).contains(&origin) || (11.0..=19.0).contains(&origin)) =>
                {
                    self.plotter.label.origin = origin as u32;
                }
                _ => {
                    return Err(Problem::new(
                        "expected a label origin of 1 to 9 or 11 to 19 after LO",
                    ))
                }
            },
            "CP" => {
                let geometry = self.label_geometry();
                let target = match values.as_slice() {
                    [] => {
                        let to = [
                            self.carriage[0] + geometry.line_feed[0],
                            self.carriage[1] + geometry.line_feed[1],
                        ];
                        self.carriage = to;
                        to
                    }
                    &[spaces, lines] => {
                        let p = self.plotter.position;
                        [
                            p[0] + spaces * geometry.advance[0] - lines * geometry.line_feed[0],
                            p[1] + spaces * geometry.advance[1] - lines * geometry.line_feed[1],
                        ]
                    }
                    _ => return count("0 or 2"),
                };
                self.return_pen(target, self.plotter.pen_down, span)?;
            }
            "PB" => {
                if !values.is_empty() {
                    return count("0");
                }
                let text = std::mem::take(&mut self.label_buffer);
                let result = self.label(&text, None, start, span);
                self.label_buffer = text;
                result?;
            }
            "SS" | "SA" => {
                if !values.is_empty() {
                    return count("0");
                }
            }
            "CS" | "CA" => match values.as_slice() {
                [] | [0.0] => {}
                &[set] => {
                    let what = format!("{name} selects character set {}", fmt_number(set));
                    let kind = format!("{name}{set}");
                    self.skip(
                        &kind,
                        start,
                        self.scan.at,
                        &what,
                        "labels are drawn with the ASCII stroke font",
                    );
                }
                _ => return count("0 or 1"),
            },
            "DV" => {
                // Clamped integers, as HP-GL/2 defines them.
                let (path, line) = match *values.as_slice() {
                    [] => (0.0, 0.0),
                    [path] => (path, 0.0),
                    [path, line] => (path, line),
                    _ => return count("0 to 2"),
                };
                self.plotter.label.path = path.trunc().clamp(0.0, 3.0) as u8;
                self.plotter.label.reverse_line_feed = line.trunc().clamp(0.0, 1.0) == 1.0;
            }
            "UC" => return Err(Problem::new(
                "expected a command cncsim draws; user-defined characters (UC) are not supported",
            )
            .hint("plot text as vectors")),
            _ => {
                if let Some(what) = description(name) {
                    let what = format!("{name} ({what}) is not a pen move");
                    if matches!(name, "PG" | "FR" | "AF" | "AH") {
                        // Counted as pages: a warning at the end of the file says what
                        // became of them when drawing goes on after one.
                        self.pen_up(span);
                        self.pages.advance(span, name);
                        if self.options.strict {
                            self.skip(name, start, self.scan.at, &what, "was skipped");
                        }
                    } else {
                        self.skip(name, start, self.scan.at, &what, "was skipped");
                    }
                } else if self.unknown_skipped(name, start) {
                } else {
                    return Err(Problem::new(format!(
                        "expected an HPGL command; {name} is not one cncsim knows"
                    ))
                    .hint("HP-GL/1 and HP-GL/2 commands are read; check the file is a plot file"));
                }
            }
        }
        Ok(())
    }

    /// A mnemonic cncsim does not know: passed over as a plotter passes over it (it raises
    /// error 1), with one warning per mnemonic, unless it is known to draw. Not with
    /// `strict`.
    fn unknown_skipped(&mut self, name: &str, start: usize) -> bool {
        if self.options.strict
            || CARRIED_OUT.contains(&name)
            || DRAWS.iter().any(|(n, _)| *n == name)
            || description(name).is_some()
        {
            return false;
        }
        let end = self.scan.at.max(start + 2);
        self.skip(
            &format!("unknown {name}"),
            start,
            end,
            &format!(
                "{name} is not an HP-GL command cncsim knows; a plotter passes over it (error 1)"
            ),
            "so was it",
        );
        true
    }

    fn default_p1_p2(&mut self) {
        let defaults = Plotter::new(self.options);
        if self.plotter.page.is_some() {
            self.plotter.p1 = [0.0, 0.0];
            self.plotter.p2 = self.plotter.page_extent(self.options);
        } else {
            self.plotter.p1 = defaults.p1;
            self.plotter.p2 = defaults.p2;
        }
    }

    fn scale(&mut self, name: &str, values: &[f64]) -> Result<(), Problem> {
        let degenerate = |a: f64, b: f64| a == b;
        self.plotter.scaling = match *values {
            [] => None,
            [x0, x1, y0, y1] | [x0, x1, y0, y1, 0.0] => {
                if degenerate(x0, x1) || degenerate(y0, y1) {
                    return Err(Problem::new(format!("expected SC limits with xmin ≠ xmax and ymin ≠ ymax, not {x0},{x1},{y0},{y1}")));
                }
                Some(Scaling::Anisotropic {
                    min: [x0, y0],
                    max: [x1, y1],
                })
            }
            [x0, x1, y0, y1, 1.0, ref rest @ ..] if rest.len() <= 2 => {
                if degenerate(x0, x1) || degenerate(y0, y1) {
                    return Err(Problem::new(format!("expected SC limits with xmin ≠ xmax and ymin ≠ ymax, not {x0},{x1},{y0},{y1}")));
                }
                let left = rest.first().copied().unwrap_or(50.0).clamp(0.0, 100.0);
                let bottom = rest.get(1).copied().unwrap_or(50.0).clamp(0.0, 100.0);
                Some(Scaling::Isotropic {
                    min: [x0, y0],
                    max: [x1, y1],
                    left,
                    bottom,
                })
            }
            [x0, fx, y0, fy, 2.0] => {
                if fx == 0.0 || fy == 0.0 {
                    return Err(Problem::new(
                        "expected non-zero point factors in SC xmin,xfactor,ymin,yfactor,2",
                    ));
                }
                Some(Scaling::PointFactor {
                    min: [x0, y0],
                    factor: [fx, fy],
                })
            }
            _ => {
                return Err(count_error(
                    name,
                    "0, 4, 5 (type 0, 2), 5 to 7 (type 1)",
                    values.len(),
                ))
            }
        };
        Ok(())
    }

    fn select_pen(&mut self, span: Span) {
        // Selecting (or putting away) a pen lifts it; strokes are not reordered across a
        // pen change.
        self.pen_up(span);
        if !self.polygon_mode {
            self.drawing.push(super::drawing::Element::Barrier);
        }
    }

    /// PU, PD, PA, PR with their coordinate pairs.
    fn plot(
        &mut self,
        name: &str,
        parameters: &[Parameter],
        start: usize,
        span: Span,
    ) -> Result<(), Problem> {
        match name {
            "PU" => self.pen_up(span),
            "PD" => {
                self.pen_down_records.0 += 1;
                self.pen_down_records.1.get_or_insert(span);
                self.pen_down(span);
            }
            "PA" => self.plotter.absolute = true,
            _ => self.plotter.absolute = false,
        }
        let mut coordinates = parameters;
        if coordinates.len() % 2 == 1 {
            let dangling = coordinates[coordinates.len() - 1];
            if self.options.lenient {
                let message = format!(
                    "{name} has {} coordinate{}: the dangling coordinate {} is dropped",
                    coordinates.len(),
                    if coordinates.len() == 1 { "" } else { "s" },
                    fmt_number(dangling.value)
                );
                self.warn(span, message);
                coordinates = &coordinates[..coordinates.len() - 1];
            } else {
                self.error(
                    start,
                    dangling.end,
                    format!(
                        "expected x,y pairs after {name}: an even number of coordinates, not {} (byte offset {})",
                        coordinates.len(),
                        span.byte_offset
                    ),
                    Some("the file may be damaged; the lenient option drops the dangling coordinate"),
                );
                return Ok(());
            }
        }
        for pair in coordinates.chunks_exact(2) {
            let target = self.plotter.target([pair[0].value, pair[1].value]);
            let pair_span = self.span(pair[0].start);
            self.move_to(target, Piece::Line, pair_span)?;
            self.carriage = target;
            self.symbol_at(target, pair_span)?;
        }
        Ok(())
    }

    /// PE: the decoded polyline, relative to the pen unless flagged absolute.
    fn encoded_polyline(&mut self, decoded: &[Encoded]) -> Result<(), Problem> {
        for element in decoded {
            match *element {
                Encoded::Pen { at, .. } => {
                    let span = self.span(at);
                    self.select_pen(span);
                }
                Encoded::Point {
                    xy,
                    absolute,
                    pen_up,
                    at,
                } => {
                    let span = self.span(at);
                    if pen_up {
                        self.pen_up(span);
                    } else {
                        self.pen_down(span);
                    }
                    let target = if absolute {
                        self.plotter.to_plotter(xy)
                    } else {
                        let delta = self.plotter.scale_delta(xy);
                        let p = self.plotter.position;
                        [p[0] + delta[0], p[1] + delta[1]]
                    };
                    self.move_to(target, Piece::Line, span)?;
                    self.carriage = target;
                }
            }
        }
        Ok(())
    }

    /// CI: a full circle about the pen (radius in user units; a negative radius starts at
    /// 180°). The pen goes up to the circumference, down round the circle, and back up to
    /// the centre; then the pen state is restored. In polygon mode the circle is a closed
    /// sub-polygon of its own.
    fn circle(&mut self, radius: f64, chord: Option<f64>, span: Span) -> Result<(), Problem> {
        if radius == 0.0 {
            self.warn(span, "CI with radius 0 draws nothing".to_string());
            return Ok(());
        }
        let centre_plotter = self.plotter.position;
        let centre = self.plotter.to_user(centre_plotter);
        let on_circle = self.plotter.to_plotter([centre[0] + radius, centre[1]]);
        let was_down = self.plotter.pen_down;
        if self.polygon_mode {
            self.close_subpolygon();
        }
        self.pen_up(span);
        self.move_to(on_circle, Piece::Line, span)?;
        self.pen_down(span);
        self.user_arc(centre, 360.0, chord, span)?;
        if self.polygon_mode {
            self.close_subpolygon();
        }
        self.return_pen(centre_plotter, was_down, span)
    }

    /// AT / RT: the arc from the pen through `through` to `end` (user units); a straight
    /// line when the three points are collinear.
    fn three_point_arc(
        &mut self,
        start: [f64; 2],
        through: [f64; 2],
        end: [f64; 2],
        chord: Option<f64>,
        span: Span,
    ) -> Result<(), Problem> {
        let (ax, ay) = (through[0] - start[0], through[1] - start[1]);
        let (bx, by) = (end[0] - start[0], end[1] - start[1]);
        let determinant = 2.0 * (ax * by - ay * bx);
        let scale = (ax.hypot(ay) * bx.hypot(by)).max(f64::MIN_POSITIVE);
        if determinant.abs() <= 1e-12 * scale {
            let target = self.plotter.to_plotter(end);
            return self.move_to(target, Piece::Line, span);
        }
        let (a2, b2) = (ax * ax + ay * ay, bx * bx + by * by);
        let centre = [
            start[0] + (by * a2 - ay * b2) / determinant,
            start[1] + (ax * b2 - bx * a2) / determinant,
        ];
        let angle = |p: [f64; 2]| (p[1] - centre[1]).atan2(p[0] - centre[0]);
        let (a0, ai, ae) = (angle(start), angle(through), angle(end));
        let tau = std::f64::consts::TAU;
        let counter_clockwise = (ai - a0).rem_euclid(tau) <= (ae - a0).rem_euclid(tau);
        let sweep = if counter_clockwise {
            (ae - a0).rem_euclid(tau)
        } else {
            -(a0 - ae).rem_euclid(tau)
        };
        let sweep_deg = if sweep == 0.0 {
            360.0
        } else {
            sweep.to_degrees()
        };
        self.user_arc(centre, sweep_deg, chord, span)?;
        // Land exactly on the programmed end point.
        if self.plotter.user_map_shape().0 {
            let target = self.plotter.to_plotter(end);
            self.plotter.position = target;
        }
        Ok(())
    }

    /// A cubic Bézier from the pen (control points and end in user units), flattened into
    /// lines no farther than a quarter plotter unit from the curve, as plotters flatten it.
    fn bezier(&mut self, points: [[f64; 2]; 3], span: Span) -> Result<(), Problem> {
        let p0 = self.plotter.position;
        let [p1, p2, p3] = points.map(|p| self.plotter.to_plotter(p));
        // Distance bound of de Casteljau flattening: n segments are within
        // (3/4)·max|second difference|/n² of the curve.
        let second = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
            (a[0] - 2.0 * b[0] + c[0]).hypot(a[1] - 2.0 * b[1] + c[1])
        };
        let bend = second(p0, p1, p2).max(second(p1, p2, p3));
        let segments = (0.75 * 6.0 * bend / 0.25)
            .sqrt()
            .ceil()
            .clamp(1.0, 10_000.0) as u32;
        for index in 1..=segments {
            let t = f64::from(index) / f64::from(segments);
            let u = 1.0 - t;
            let weights = [u * u * u, 3.0 * u * u * t, 3.0 * u * t * t, t * t * t];
            let point = [
                weights[0] * p0[0] + weights[1] * p1[0] + weights[2] * p2[0] + weights[3] * p3[0],
                weights[0] * p0[1] + weights[1] * p1[1] + weights[2] * p2[1] + weights[3] * p3[1],
            ];
            let point = if index == segments { p3 } else { point };
            self.move_to(point, Piece::Line, span)?;
        }
        self.carriage = p3;
        Ok(())
    }

    /// A closed polygon through user-unit corners, starting and ending at the last corner.
    fn user_polygon(&self, corners: &[[f64; 2]]) -> Polygon {
        let points: Vec<[f64; 2]> = corners
            .iter()
            .map(|&c| self.plotter.to_plotter(c))
            .collect();
        let start = *points.last().expect("corners");
        Polygon {
            paths: vec![SubPath {
                start,
                edges: points
                    .iter()
                    .map(|&to| Edge {
                        piece: Piece::Line,
                        to,
                    })
                    .collect(),
                open: false,
            }],
        }
    }

    /// EA ER EW (edged) and RA RR WG (filled): drawn from the pen, which ends where it was
    /// with its state restored; the shape becomes the polygon buffer, as in HP-GL/2.
    fn shape(&mut self, edged: bool, polygon: Polygon, span: Span) -> Result<(), Problem> {
        if self.polygon_mode {
            return Err(Problem::new(
                "expected rectangles and wedges outside polygon mode (PM0 … PM2)",
            ));
        }
        if edged {
            let position = self.plotter.position;
            let was_down = self.plotter.pen_down;
            self.outline(&polygon, true, span)?;
            self.return_pen(position, was_down, span)?;
        } else {
            self.fill(&polygon, Rule::EvenOdd, span)?;
        }
        self.polygon = polygon;
        Ok(())
    }

    /// EW / WG: a wedge about the pen, radius and angles in user units.
    fn wedge(
        &mut self,
        edged: bool,
        radius: f64,
        start_deg: f64,
        sweep: f64,
        chord: Option<f64>,
        span: Span,
    ) -> Result<(), Problem> {
        if radius == 0.0 || sweep == 0.0 {
            self.warn(
                span,
                "a wedge with zero radius or sweep draws nothing".to_string(),
            );
            return Ok(());
        }
        let sweep = sweep.clamp(-360.0, 360.0);
        // The wedge is built in polygon mode, then drawn like any shape.
        let centre_plotter = self.plotter.position;
        let was_down = self.plotter.pen_down;
        let centre = self.plotter.to_user(centre_plotter);
        let angle = start_deg.to_radians();
        let on_arc = self.plotter.to_plotter([
            centre[0] + radius * angle.cos(),
            centre[1] + radius * angle.sin(),
        ]);
        let saved = std::mem::take(&mut self.polygon);
        self.polygon_mode = true;
        self.polygon = Polygon {
            paths: vec![SubPath {
                start: centre_plotter,
                edges: Vec::new(),
                open: false,
            }],
        };
        self.plotter.pen_down = true;
        // Out along the first radius, round the arc, back along the second (for a full
        // circle the two radii coincide, as HP plotters draw it).
        let built = (|| {
            self.move_to(on_arc, Piece::Line, span)?;
            self.user_arc(centre, sweep, chord, span)?;
            self.move_to(centre_plotter, Piece::Line, span)
        })();
        self.polygon_mode = false;
        self.plotter.pen_down = was_down;
        self.plotter.position = centre_plotter;
        let polygon = std::mem::replace(&mut self.polygon, saved);
        built?;
        self.shape(edged, polygon, span)
    }

    /// XT / YT: a tick through the pen, lengths TL percent of P2 − P1.
    fn tick(&mut self, vertical: bool, span: Span) -> Result<(), Problem> {
        let position = self.plotter.position;
        let axis = if vertical { 1 } else { 0 };
        let span_length = self.plotter.p2[axis] - self.plotter.p1[axis];
        let up = self.plotter.tick[0] / 100.0 * span_length;
        let down = self.plotter.tick[1] / 100.0 * span_length;
        let at = |offset: f64| {
            let mut point = position;
            point[axis] += offset;
            point
        };
        let was_down = self.plotter.pen_down;
        self.pen_down(span);
        for point in [at(up), at(-down), position] {
            self.move_to(point, Piece::Line, span)?;
        }
        if !was_down {
            self.pen_up(span);
        }
        Ok(())
    }

    fn label_geometry(&self) -> label::Geometry {
        let units_per_cm = self.options.units_per_mm * 10.0;
        self.plotter
            .label
            .geometry(self.plotter.p1, self.plotter.p2, units_per_cm)
    }

    /// LB / PB: the label's strokes from the pen; the pen ends at the next character origin
    /// with its up/down state restored.
    /// `text_start` is the text's offset in the file (`None` for the buffered label of PB,
    /// whose problems are reported at the command, `command_start`).
    fn label(
        &mut self,
        text: &[u8],
        text_start: Option<usize>,
        command_start: usize,
        span: Span,
    ) -> Result<(), Problem> {
        let geometry = self.label_geometry();
        let text = self.ascii_label(text, text_start.unwrap_or(command_start));
        let laid = match label::lay_out(
            &text,
            self.plotter.position,
            self.carriage,
            &geometry,
            self.plotter.label.origin,
        ) {
            Ok(laid) => laid,
            Err(index) => {
                // Point at the character itself where the file has it.
                let (at, end) = match text_start {
                    Some(text_start) => {
                        (text_start + index, self.scan.char_end(text_start + index))
                    }
                    None => (command_start, command_start + 2),
                };
                self.error(
                    at,
                    end,
                    "expected label characters the stroke font has (ASCII 32–126)",
                    Some("the Hershey stroke font draws ASCII only"),
                );
                return Ok(());
            }
        };
        let was_down = self.plotter.pen_down;
        for stroke in &laid.strokes {
            self.polyline(stroke, span)?;
        }
        self.carriage = laid.carriage;
        self.return_pen(laid.end, was_down, span)
    }

    /// A label's characters outside ASCII, which the stroke font cannot draw: dashes and
    /// minus signs as `-` (plotting programs write HP Roman-8's dash, 0xF6, for a minus
    /// sign), any other as a blank cell the pen moves over; text that is valid UTF-8 is read
    /// a character a cell, other bytes as Roman-8. One warning counts them; refused with
    /// `strict` (left for the layout to refuse).
    fn ascii_label(&mut self, text: &[u8], at: usize) -> Vec<u8> {
        if self.options.strict || text.is_ascii() {
            return text.to_vec();
        }
        let cells: Vec<(u8, Option<String>)> = match std::str::from_utf8(text) {
            Ok(utf8) => utf8
                .chars()
                .map(|c| match c {
                    c if c.is_ascii() => (c as u8, None),
                    '\u{2010}'..='\u{2015}' | '\u{2212}' => (b'-', Some(c.to_string())),
                    c => (b' ', Some(c.to_string())),
                })
                .collect(),
            Err(_) => text
                .iter()
                .map(|&b| match b {
                    b if b.is_ascii() => (b, None),
                    0xF6 => (b'-', Some("0xF6".into())),
                    b => (b' ', Some(format!("0x{b:02X}"))),
                })
                .collect(),
        };
        let span = self.span(at);
        for (_, shown) in &cells {
            if let Some(shown) = shown {
                self.warn_counted("label outside ASCII", span, || {
                    format!("label characters outside ASCII (the first `{shown}`) are drawn as '-' where they are dashes or minus signs (HP Roman-8's 0xF6 among them), else left blank: the stroke font has ASCII only")
                });
            }
        }
        cells.into_iter().map(|(byte, _)| byte).collect()
    }

    /// Symbol mode: the symbol character centred on a plotted point.
    fn symbol_at(&mut self, point: [f64; 2], span: Span) -> Result<(), Problem> {
        let Some(symbol) = self.plotter.symbol else {
            return Ok(());
        };
        let glyph = super::font::glyph(symbol).ok_or_else(|| {
            Problem::new(format!(
                "expected a symbol (SM) the stroke font has; 0x{symbol:02x} has none"
            ))
        })?;
        let strokes = self.label_geometry().symbol_strokes(glyph, point);
        let was_down = self.plotter.pen_down;
        for stroke in &strokes {
            self.polyline(stroke, span)?;
        }
        self.return_pen(point, was_down, span)
    }
}
