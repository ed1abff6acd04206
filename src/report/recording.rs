//! The Rerun recording of a run, written as the run goes and made to be reviewed: it carries
//! its own blueprint (see `blueprint.rs`), named series in display units with fixed colours,
//! an event log and a summary document.
//!
//! Entity paths (stable; tests and users rely on them), under an optional variant prefix
//! (`a/`, `b/` in an A/B recording):
//! - `world/machine/<link>`: link pose per recorded tick; `…/<link>/visual_<i>` its visuals
//!   (boxes, cylinders, capsules, spheres, meshes), the URDF's in order less meshes not found
//! - `world/machine/<workpiece link>/paths/programmed` (static) and `…/paths/actual/<chunk>`:
//!   the tool path on the workpiece, in its frame, growing with time; `…/paths/tool`: the tool
//! - `magnified/programmed`, `magnified/actual`: the path with the contour error magnified
//!   (nearest programmed point + k·deviation, coloured by the error), program frame
//! - `axes/<axis>/position/{commanded,physics,analytic,physics_drive,analytic_drive}` (mm, deg)
//! - `axes/<axis>/following_error/{physics,analytic}` (µm or deg), `…/max` (marker)
//! - `axes/<axis>/physics_minus_analytic` (µm or deg)
//! - `axes/<axis>/torque/{physics,analytic}` (N·m), `axes/<axis>/voltage/{…}` (V)
//! - `path/contour_error/{physics,analytic}` (µm), `path/speed/{commanded,physics,analytic}`
//!   (mm/s)
//! - `events` (text log), `summary` (text document)
//! - where the run cuts: `world/machine/<workpiece link>/stock` (the stock as cut, a mesh
//!   every few seconds of program time, in the stock's frame), `part/machined` (the finished
//!   part's surface points coloured by their error against the nominal part),
//!   `part/magnified` (the same points moved along their normal by k × the error),
//!   `cutting/force/{x,y,z}/{physics,analytic}` (N, the tool on the part, stock frame),
//!   `cutting/power/{physics,analytic}` (W), `cutting/engaged_flutes/{physics,analytic}`

use super::path::PathSample;
use super::thin::Thinned;
use super::{AxisLabel, ReportError};
use crate::machine::{Machine, Shape, Visual};
use crate::sim::{LaneKind, TickRecord};
use nalgebra::{Isometry3, Point3};
use rerun::{RecordingStream, TimeColumn};
use std::path::{Path, PathBuf};

/// Recorded rows buffered before they are sent: bounds the writer's memory.
const CHUNK_ROWS: usize = 8192;
/// Recorded ticks per piece of the actual tool path at most: the path grows with the time
/// cursor in steps this long, or shorter ones on a short run (see [`PATH_PIECES`]).
const PATH_PIECE_ROWS: usize = 1024;
/// Pieces of the actual tool path over the program's duration at least, so that a short run's
/// path grows with the time cursor too.
const PATH_PIECES: f64 = 100.0;
/// Points kept for the magnified path (evenly thinned over the run).
const MAGNIFIED_POINTS: usize = 20_000;
/// Colours: commanded grey-blue, physics orange, analytic green, drive side purple.
pub const COMMANDED: [u8; 3] = [90, 140, 230];
pub const PHYSICS: [u8; 3] = [255, 120, 40];
pub const ANALYTIC: [u8; 3] = [40, 180, 90];
pub const DRIVE: [u8; 3] = [170, 90, 220];
pub const DIFFERENCE: [u8; 3] = [220, 40, 120];
/// The analytic model's drive side.
const ANALYTIC_DRIVE: [u8; 3] = [120, 200, 220];
/// Machine visuals are see-through, so no path hides inside the machine's own geometry.
const MACHINE_ALPHA: f32 = 0.3;

/// What a recording shows besides the ticks: plain data the caller prepares.
pub struct RecordingSetup<'a> {
    /// The recording's name (the scenario's).
    pub name: &'a str,
    /// The machine, for its links, visuals and workpiece frame.
    pub machine: &'a Machine,
    /// How each machine axis is named and shown, in the machine's axis order.
    pub labels: &'a [AxisLabel],
    /// Whether the drives are DC motors: then the armature voltage is recorded too.
    pub dc_motor: bool,
    /// Record every k-th tick.
    pub decimation: usize,
    /// Lanes of the run ("physics", and "analytic" where it runs).
    pub lanes: &'a [LaneKind],
    /// The programmed tool path on the workpiece, in the workpiece link's frame (m).
    pub programmed_path: Vec<[f64; 3]>,
    /// In an A/B recording: the variant's name (legends start with it) and its colour.
    pub variant: Option<(String, [u8; 3])>,
    /// Where the run cuts: the stock's frame in the workpiece link's frame.
    pub stock_frame: Option<Isometry3<f64>>,
    /// The program's duration (s): the stock is drawn some 40 times over it.
    pub duration: f64,
}

/// Snapshots of the stock as cut over a run (each a mesh: a few MB in the file).
const STOCK_SNAPSHOTS: f64 = 40.0;
/// Most triangles a snapshot of the stock is drawn with.
const STOCK_TRIANGLES: usize = 200_000;
/// Most surface points the finished part is drawn with.
const PART_POINTS: usize = 500_000;

/// Columns of one lane's recorded rows, sent every [`CHUNK_ROWS`] rows.
#[derive(Default)]
struct Columns {
    time: Vec<f64>,
    /// The lane's series ([`RrdWriter::series`], in its order) and their values, one per row.
    series: Vec<(String, Quantity, Vec<f64>)>,
    /// Link poses per row (physics lane only).
    poses: Vec<Vec<Isometry3<f64>>>,
    /// Tool point on the workpiece per row (physics lane only).
    tool: Vec<[f32; 3]>,
    /// Tool points of these rows already drawn as pieces of the actual path.
    drawn: usize,
}

impl Columns {
    fn clear(&mut self) {
        self.time.clear();
        self.poses.clear();
        self.tool.clear();
        self.drawn = 0;
        for (_, _, v) in &mut self.series {
            v.clear();
        }
    }
}

/// What a recorded series shows, per recorded tick (axis index where it is an axis's).
#[derive(Debug, Clone, Copy)]
enum Quantity {
    Commanded(usize),
    Position(usize),
    /// The drive side's position, on an axis whose drive side can part from the carriage.
    DriveSide(usize),
    FollowingError(usize),
    /// The physics lane's position minus this lane's at the same tick.
    PhysicsMinusAnalytic(usize),
    Torque(usize),
    Voltage(usize),
    /// The cut's force on the part along a stock axis (N).
    CutForce(usize),
    SpindlePower,
    EngagedFlutes,
    ContourError,
    CommandedSpeed,
    PathSpeed,
}

/// One recorded series: where it is logged, its legend and colour, and what it shows. The
/// table of a lane's series ([`RrdWriter::series`]) lays out the recording (names and colours,
/// logged once) and fills its rows, so the two cannot disagree.
struct Series {
    /// Entity path below the writer's prefix.
    entity: String,
    /// Legend, without the A/B variant's name.
    legend: String,
    colour: [u8; 3],
    quantity: Quantity,
}

/// The program axes as Rerun view directions of the workpiece link's frame (X right, Y
/// forward, Z up), when each lies along one of its axes and they are right-handed (Rerun draws
/// only right-handed spaces); otherwise none, and the view keeps the frame's own axes.
fn program_view_coordinates(machine: &Machine) -> Option<rerun::ViewCoordinates> {
    use rerun::datatypes::ViewDir;
    let (frame, _) = crate::kinematics::ProgramFrame::new(machine).ok()?;
    let home: Vec<f64> = machine.axes.iter().map(|a| a.drive.home).collect();
    let poses = crate::kinematics::link_poses(machine, &home);
    let to_workpiece = (poses[machine.workpiece_link].rotation.inverse()
        * poses[frame.carrier].rotation)
        .to_rotation_matrix();
    let program = to_workpiece.matrix() * frame.directions;
    if program.determinant() < 0.0 {
        return None;
    }
    let directions = [
        [ViewDir::Right, ViewDir::Left],
        [ViewDir::Forward, ViewDir::Back],
        [ViewDir::Up, ViewDir::Down],
    ];
    // For each axis of the workpiece frame: the program axis along it, and its sense.
    let mut view = [ViewDir::Up; 3];
    for (i, dir) in view.iter_mut().enumerate() {
        let row = program.row(i);
        let (j, value) = (0..3)
            .map(|j| (j, row[j]))
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))?;
        if (value.abs() - 1.0).abs() > 1e-6 {
            return None;
        }
        *dir = directions[j][usize::from(value < 0.0)];
    }
    Some(rerun::ViewCoordinates::new(
        rerun::components::ViewCoordinates::new(view[0], view[1], view[2]),
    ))
}

/// One magnified-path sample: nearest programmed point, actual tool point (program frame, m),
/// contour error (m).
type Deviation = ([f64; 3], [f64; 3], f64);

/// Writes a run into a recording stream (its own file, or a shared A/B stream under a prefix).
pub struct RrdWriter {
    rec: RecordingStream,
    path: PathBuf,
    prefix: String,
    machine: Machine,
    labels: Vec<AxisLabel>,
    lanes: Vec<LaneKind>,
    decimation: usize,
    dc_motor: bool,
    variant: Option<(String, [u8; 3])>,
    /// Axes whose drive side can part from the carriage (backlash).
    slack: Vec<bool>,
    columns: Vec<Columns>,
    /// Lane 0's positions at the current tick, for the physics − analytic series.
    primary: Vec<f64>,
    primary_tick: Option<usize>,
    path_pieces: usize,
    /// Last tool point drawn, so consecutive path pieces join.
    last_tool: Option<[f32; 3]>,
    magnified: Thinned<Deviation>,
    /// Where the run cuts: the stock's frame on the workpiece link; when the stock was last
    /// drawn, and every how long it is (s).
    stock_frame: Option<Isometry3<f64>>,
    stock_drawn: Option<f64>,
    stock_every: f64,
    /// Program time between pieces of the actual tool path, and when the last was drawn.
    path_every: f64,
    path_drawn_at: f64,
    /// The first error; the loop does not stop for it, `finish` reports it.
    error: Option<String>,
}

fn rgb(c: [u8; 3]) -> rerun::Color {
    rerun::Color::from_rgb(c[0], c[1], c[2])
}

impl RrdWriter {
    /// A recording of its own in `path`, with the run's blueprint.
    pub fn create(path: &Path, setup: &RecordingSetup<'_>) -> Result<RrdWriter, ReportError> {
        let rec = rerun::RecordingStreamBuilder::new("cncsim")
            .recording_name(setup.name)
            .save(path)
            .map_err(|e| recording_error(path, &e))?;
        super::blueprint::run_blueprint(setup)
            .send(&rec, rerun::blueprint::BlueprintActivation::default())
            .map_err(|e| recording_error(path, &e))?;
        Self::on_stream(rec, path, "", setup)
    }

    /// A variant's part of a shared recording, its entities under `prefix` (e.g. `a/`).
    pub fn on_stream(
        rec: RecordingStream,
        path: &Path,
        prefix: &str,
        setup: &RecordingSetup<'_>,
    ) -> Result<RrdWriter, ReportError> {
        let mut w = RrdWriter {
            rec,
            path: path.to_path_buf(),
            prefix: prefix.to_string(),
            machine: setup.machine.clone(),
            labels: setup.labels.to_vec(),
            lanes: setup.lanes.to_vec(),
            decimation: setup.decimation.max(1),
            dc_motor: setup.dc_motor,
            variant: setup.variant.clone(),
            slack: setup
                .machine
                .axes
                .iter()
                .map(|a| a.drive.backlash > 0.0)
                .collect(),
            columns: Vec::new(),
            primary: vec![0.0; setup.labels.len()],
            primary_tick: None,
            path_pieces: 0,
            last_tool: None,
            magnified: Thinned::new(MAGNIFIED_POINTS),
            stock_frame: setup.stock_frame,
            stock_drawn: None,
            stock_every: setup.duration / STOCK_SNAPSHOTS,
            path_every: setup.duration / PATH_PIECES,
            path_drawn_at: 0.0,
            error: None,
        };
        w.columns = (0..w.lanes.len())
            .map(|lane| w.lane_columns(lane))
            .collect();
        let header = w.log_static_content(setup);
        w.keep(header);
        Ok(w)
    }

    fn entity(&self, path: &str) -> String {
        format!("{}{path}", self.prefix)
    }

    /// The path of the workpiece link's entity, under which the paths are drawn.
    fn workpiece_entity(&self) -> String {
        let link = &self.machine.links[self.machine.workpiece_link].name;
        self.entity(&format!("world/machine/{link}"))
    }

    /// The series lane `lane` records, in the order its rows fill them.
    fn series(&self, lane: usize) -> Vec<Series> {
        let kind = &self.lanes[lane];
        let colour = self.colour(kind);
        let mut table = Vec::new();
        let mut add = |entity: String, legend: String, colour: [u8; 3], quantity: Quantity| {
            table.push(Series {
                entity,
                legend,
                colour,
                quantity,
            })
        };
        for (i, l) in self.labels.iter().enumerate() {
            let (a, u, e) = (&l.name, l.unit(), error_unit(l));
            if lane == 0 {
                add(
                    format!("axes/{a}/position/commanded"),
                    format!("{a} commanded ({u})"),
                    COMMANDED,
                    Quantity::Commanded(i),
                );
            }
            add(
                format!("axes/{a}/position/{kind}"),
                format!("{a} {kind} ({u})"),
                colour,
                Quantity::Position(i),
            );
            if self.slack[i] {
                let drive = if *kind == LaneKind::Physics {
                    DRIVE
                } else {
                    ANALYTIC_DRIVE
                };
                add(
                    format!("axes/{a}/position/{kind}_drive"),
                    format!("{a} {kind} drive side ({u})"),
                    drive,
                    Quantity::DriveSide(i),
                );
            }
            add(
                format!("axes/{a}/following_error/{kind}"),
                format!("{a} following error, {kind} ({e})"),
                colour,
                Quantity::FollowingError(i),
            );
            if lane > 0 {
                add(
                    format!("axes/{a}/physics_minus_analytic"),
                    format!("{a} physics − analytic ({e})"),
                    DIFFERENCE,
                    Quantity::PhysicsMinusAnalytic(i),
                );
            }
            add(
                format!("axes/{a}/torque/{kind}"),
                format!("{a} torque, {kind} (N·m)"),
                colour,
                Quantity::Torque(i),
            );
            if self.dc_motor {
                add(
                    format!("axes/{a}/voltage/{kind}"),
                    format!("{a} voltage, {kind} (V)"),
                    colour,
                    Quantity::Voltage(i),
                );
            }
        }
        if self.stock_frame.is_some() {
            // The three components apart: red, green, blue as the axes are drawn; the analytic
            // lane's paler, an A/B variant's its own colour.
            let components: [[u8; 3]; 3] = match (kind, &self.variant) {
                (LaneKind::Analytic, _) => [[240, 150, 150], [150, 220, 150], [150, 170, 240]],
                (_, Some(_)) => [colour; 3],
                _ => [[220, 40, 40], [40, 170, 60], [50, 90, 230]],
            };
            for (k, a) in ["x", "y", "z"].iter().enumerate() {
                add(
                    format!("cutting/force/{a}/{kind}"),
                    format!("F{a}, {kind} (N)"),
                    components[k],
                    Quantity::CutForce(k),
                );
            }
            add(
                format!("cutting/power/{kind}"),
                format!("spindle power, {kind} (W)"),
                colour,
                Quantity::SpindlePower,
            );
            add(
                format!("cutting/engaged_flutes/{kind}"),
                format!("flutes engaged, {kind}"),
                colour,
                Quantity::EngagedFlutes,
            );
        }
        add(
            format!("path/contour_error/{kind}"),
            format!("contour error, {kind} (µm)"),
            colour,
            Quantity::ContourError,
        );
        if lane == 0 {
            add(
                "path/speed/commanded".into(),
                "commanded (mm/s)".into(),
                COMMANDED,
                Quantity::CommandedSpeed,
            );
        }
        add(
            format!("path/speed/{kind}"),
            format!("{kind} (mm/s)"),
            colour,
            Quantity::PathSpeed,
        );
        table
    }

    /// Empty columns for lane `lane`'s rows.
    fn lane_columns(&self, lane: usize) -> Columns {
        Columns {
            series: self
                .series(lane)
                .into_iter()
                .map(|s| (self.entity(&s.entity), s.quantity, Vec::new()))
                .collect(),
            ..Default::default()
        }
    }

    /// Names, units and colours of every series, the machine's visuals and the programmed path.
    fn log_static_content(&self, setup: &RecordingSetup<'_>) -> rerun::RecordingStreamResult<()> {
        let rec = &self.rec;
        rec.log_static(
            self.entity("world"),
            &rerun::ViewCoordinates::RIGHT_HAND_Z_UP(),
        )?;
        for (li, link) in self.machine.links.iter().enumerate() {
            let entity = self.entity(&format!("world/machine/{}", link.name));
            for (vi, v) in link.visuals.iter().enumerate() {
                let child = format!("{entity}/visual_{vi}");
                rec.log_static(child.as_str(), &transform(&v.pose))?;
                log_visual_shape(rec, &child, v)?;
            }
            if li == self.machine.root {
                rec.log_static(entity.as_str(), &rerun::Transform3D::IDENTITY)?;
            }
        }
        if let Some(frame) = &self.stock_frame {
            rec.log_static(
                format!("{}/stock", self.workpiece_entity()),
                &transform(frame),
            )?;
        }
        let paths = format!("{}/paths", self.workpiece_entity());
        if let Some(view) = program_view_coordinates(&self.machine) {
            // The "tool path on the workpiece" view looks at the part in its own link's frame:
            // its up is program +Z there, not the frame's own z (a CAD frame may be turned).
            rec.log_static(self.workpiece_entity(), &view)?;
        }
        rec.log_static(
            format!("{paths}/tool"),
            &rerun::Points3D::update_fields()
                .with_radii([rerun::Radius::new_ui_points(6.0)])
                .with_colors([rgb([230, 30, 30])]),
        )?;
        rec.log_static(
            format!("{paths}/programmed"),
            &rerun::LineStrips3D::new([f32_points(&setup.programmed_path)])
                .with_colors([rgb(COMMANDED)])
                .with_radii([rerun::Radius::new_ui_points(1.5)]),
        )?;
        let lead = self
            .variant
            .as_ref()
            .map_or(String::new(), |(name, _)| format!("{name}: "));
        for lane in 0..self.lanes.len() {
            for series in self.series(lane) {
                rec.log_static(
                    self.entity(&series.entity),
                    &rerun::SeriesLines::new()
                        .with_names([format!("{lead}{}", series.legend)])
                        .with_colors([rgb(series.colour)]),
                )?;
            }
        }
        for l in &self.labels {
            rec.log_static(
                self.entity(&format!("axes/{}/following_error/max", l.name)),
                &rerun::SeriesPoints::new()
                    .with_names([format!("{} largest error ({})", l.name, error_unit(l))])
                    .with_colors([rgb([200, 0, 0])])
                    .with_marker_sizes([6.0]),
            )?;
        }
        Ok(())
    }

    /// Adds a tick of lane `lane` with its path figures; every `decimation`-th tick is kept.
    pub fn tick(&mut self, lane: usize, r: &TickRecord<'_>, path: &PathSample) {
        // A writer records the lanes it was set up for (an A/B recording: physics only).
        if lane >= self.columns.len() {
            return;
        }
        if lane == 0 {
            self.primary.copy_from_slice(&r.sensors.position);
            self.primary_tick = Some(r.k);
            if let Some(q) = path.nearest {
                self.magnified.push((q, path.tool, path.contour_error));
            }
            if let Some(stock) = r.stock {
                if self
                    .stock_drawn
                    .is_none_or(|t| r.time - t >= self.stock_every)
                {
                    self.stock_drawn = Some(r.time);
                    let drawn = self.log_stock(r.time, stock);
                    self.keep(drawn);
                }
            }
        }
        if !r.k.is_multiple_of(self.decimation) || self.error.is_some() {
            return;
        }
        let compare = lane > 0 && self.primary_tick == Some(r.k);
        let poses =
            (lane == 0).then(|| crate::kinematics::link_poses(&self.machine, &r.sensors.position));
        let (labels, primary) = (&self.labels, &self.primary);
        let (setpoint, position) = (&r.setpoint.position, &r.sensors.position);
        let value = |quantity: Quantity| match quantity {
            Quantity::Commanded(i) => setpoint[i] * labels[i].scale(),
            Quantity::Position(i) => position[i] * labels[i].scale(),
            Quantity::DriveSide(i) => r.sensors.drive_position[i] * labels[i].scale(),
            Quantity::FollowingError(i) => (setpoint[i] - position[i]) * error_scale(&labels[i]),
            Quantity::PhysicsMinusAnalytic(i) if compare => {
                (primary[i] - position[i]) * error_scale(&labels[i])
            }
            Quantity::PhysicsMinusAnalytic(_) => f64::NAN,
            Quantity::Torque(i) => r.hold.mean_torque[i],
            Quantity::Voltage(i) => r.hold.voltage[i],
            Quantity::CutForce(k) => r.hold.cut.force[k],
            Quantity::SpindlePower => r.hold.cut.spindle_power,
            Quantity::EngagedFlutes => f64::from(r.hold.cut.engaged_flutes),
            Quantity::ContourError => path.contour_error * 1e6,
            Quantity::CommandedSpeed => path.commanded_speed * 1e3,
            Quantity::PathSpeed => path.actual_speed * 1e3,
        };
        let c = &mut self.columns[lane];
        c.time.push(r.time);
        for (_, quantity, values) in &mut c.series {
            values.push(value(*quantity));
        }
        if let Some(poses) = poses {
            // The tool point the physics simulated (what the contour error measures), not the
            // axes' kinematics: a tool that a free joint or a compliance moves is drawn there.
            let workpiece = poses[self.machine.workpiece_link];
            let on_workpiece =
                workpiece.inverse_transform_point(&Point3::from(r.sensors.tool_point));
            c.tool.push([
                on_workpiece.x as f32,
                on_workpiece.y as f32,
                on_workpiece.z as f32,
            ]);
            c.poses.push(poses);
            let due = r.time - self.path_drawn_at >= self.path_every;
            if c.tool.len() - c.drawn >= PATH_PIECE_ROWS || due {
                self.path_drawn_at = r.time;
                let drawn = self.draw_path_piece();
                self.keep(drawn);
            }
        }
        let c = &self.columns[lane];
        if c.time.len() >= CHUNK_ROWS {
            let sent = self.send(lane);
            self.keep(sent);
        }
    }

    /// An entry of the event log at program time `time`.
    pub fn event(&mut self, time: f64, level: &str, text: &str) {
        self.rec.set_duration_secs("sim_time", time);
        let logged = self.rec.log(
            self.entity("events"),
            &rerun::TextLog::new(text).with_level(level),
        );
        self.rec.disable_timeline("sim_time");
        self.keep(logged);
    }

    /// A marker on axis `axis`'s following-error plot at its largest error.
    pub fn mark_largest_error(&mut self, axis: usize, time: f64, error: f64) {
        let l = &self.labels[axis];
        self.rec.set_duration_secs("sim_time", time);
        let logged = self.rec.log(
            self.entity(&format!("axes/{}/following_error/max", l.name)),
            &rerun::Scalars::new([error * error_scale(l)]),
        );
        self.rec.disable_timeline("sim_time");
        self.keep(logged);
    }

    fn keep(&mut self, result: rerun::RecordingStreamResult<()>) {
        if let (Err(e), None) = (result, &self.error) {
            self.error = Some(e.to_string());
        }
    }

    /// Sends lane `lane`'s buffered rows.
    fn send(&mut self, lane: usize) -> rerun::RecordingStreamResult<()> {
        let c = &self.columns[lane];
        if c.time.is_empty() {
            return Ok(());
        }
        let times = || TimeColumn::new_duration_secs("sim_time", c.time.iter().copied());
        for (entity, _, values) in &c.series {
            self.rec.send_columns(
                entity.as_str(),
                [times()],
                rerun::Scalars::new(values.iter().copied()).columns_of_unit_batches()?,
            )?;
        }
        if lane == 0 {
            for (li, link) in self.machine.links.iter().enumerate() {
                if li == self.machine.root {
                    continue;
                }
                let t = rerun::Transform3D::new()
                    .with_many_translation(c.poses.iter().map(|p| f32x3(&p[li].translation.vector)))
                    .with_many_quaternion(c.poses.iter().map(|p| quaternion(&p[li])));
                self.rec.send_columns(
                    self.entity(&format!("world/machine/{}", link.name))
                        .as_str(),
                    [times()],
                    t.columns_of_unit_batches()?,
                )?;
            }
            let paths = format!("{}/paths", self.workpiece_entity());
            self.rec.send_columns(
                format!("{paths}/tool").as_str(),
                [times()],
                rerun::Points3D::new(c.tool.iter().copied()).columns_of_unit_batches()?,
            )?;
            self.draw_path_piece()?;
        }
        self.columns[lane].clear();
        Ok(())
    }

    /// Draws the physics lane's tool points not drawn yet as the next piece of the actual
    /// path, from the last point drawn: the path grows with the time cursor (each piece is an
    /// entity of its own, shown from its last point's time on).
    fn draw_path_piece(&mut self) -> rerun::RecordingStreamResult<()> {
        let c = &mut self.columns[0];
        let (Some(&end), Some(&time)) = (c.tool.last(), c.time.last()) else {
            return Ok(());
        };
        if c.drawn == c.tool.len() {
            return Ok(());
        }
        let strip: Vec<[f32; 3]> = self
            .last_tool
            .into_iter()
            .chain(c.tool[c.drawn..].iter().copied())
            .collect();
        c.drawn = c.tool.len();
        let paths = format!("{}/paths", self.workpiece_entity());
        self.rec.set_duration_secs("sim_time", time);
        self.rec.log(
            format!("{paths}/actual/{:05}", self.path_pieces),
            &rerun::LineStrips3D::new([strip])
                .with_colors([rgb(self.colour(&LaneKind::Physics))])
                .with_radii([rerun::Radius::new_ui_points(1.5)]),
        )?;
        self.rec.disable_timeline("sim_time");
        self.last_tool = Some(end);
        self.path_pieces += 1;
        Ok(())
    }

    /// The stock as cut at program time `time`, in its frame on the workpiece.
    fn log_stock(
        &mut self,
        time: f64,
        stock: &crate::cutting::Stock,
    ) -> rerun::RecordingStreamResult<()> {
        let triangles = stock.surface_coarse(STOCK_TRIANGLES);
        self.rec.set_duration_secs("sim_time", time);
        let logged = self.rec.log(
            format!("{}/stock", self.workpiece_entity()),
            &stock_mesh(&triangles, [170, 175, 185]),
        );
        self.rec.disable_timeline("sim_time");
        logged
    }

    /// The finished part: its surface as cut, and its surface points coloured by their error
    /// against the nominal part (blue: overcut, grey: on size, red: material left), once as
    /// they are and once moved along their normal by a round magnification of the error.
    /// Returns a sentence for the summary.
    pub fn log_part(
        &mut self,
        time: f64,
        stock: &crate::cutting::Stock,
        comparison: &crate::cutting::SurfaceComparison,
    ) -> String {
        let logged = self.log_stock(time, stock);
        self.keep(logged);
        // At most PART_POINTS points drawn (every k-th): the viewer's budget, not the figures'.
        let stride = comparison.points.len().div_ceil(PART_POINTS).max(1);
        let points: Vec<&crate::cutting::SurfacePoint> =
            comparison.points.iter().step_by(stride).collect();
        let worst = comparison.max_error;
        let (lo, hi) = stock.bounds();
        let k = magnification((hi - lo).norm(), worst);
        let colour = |e: f64| signed_heat(if worst > 0.0 { e / worst } else { 0.0 });
        let frame = self.stock_frame.unwrap_or_else(Isometry3::identity);
        let place = |p: &Point3<f64>| {
            let q = frame * p;
            [q.x as f32, q.y as f32, q.z as f32]
        };
        let radius = rerun::Radius::new_scene_units((0.6 * stock.resolution()) as f32);
        // The finished part is a result of the whole run: shown from its end on.
        self.rec.set_duration_secs("sim_time", time);
        let at = self.rec.log(
            self.entity("part/machined"),
            &rerun::Points3D::new(points.iter().map(|p| place(&p.position)))
                .with_colors(points.iter().map(|p| colour(p.error)))
                .with_radii([radius]),
        );
        self.keep(at);
        let at = self.rec.log(
            self.entity("part/magnified"),
            &rerun::Points3D::new(
                points
                    .iter()
                    .map(|p| place(&(p.position - p.normal * (k * p.error)))),
            )
            .with_colors(points.iter().map(|p| colour(p.error)))
            .with_radii([radius]),
        );
        self.rec.disable_timeline("sim_time");
        self.keep(at);
        format!(
            "*The part as cut*: its surface points coloured by their normal distance from the nominal part's surface, blue where the tool cut too deep, red where it left material (±{:.3} µm at full colour); the magnified view moves each point {k} × that distance along its normal.",
            worst * 1e6
        )
    }

    /// Sends what is buffered, the magnified path and the summary, and closes the stream.
    pub fn finish(mut self, summary_markdown: &str) -> Result<PathBuf, ReportError> {
        for lane in 0..self.columns.len() {
            let sent = self.send(lane);
            self.keep(sent);
        }
        let magnified = self.log_magnified();
        let note = match &magnified {
            Ok(Some(note)) => format!("\n\n{note}"),
            _ => String::new(),
        };
        self.keep(magnified.map(|_| ()));
        let summary = self.rec.log_static(
            self.entity("summary"),
            &rerun::TextDocument::new(format!("{summary_markdown}{note}"))
                .with_media_type(rerun::MediaType::markdown()),
        );
        self.keep(summary);
        if let (Err(e), None) = (self.rec.flush_blocking(), &self.error) {
            self.error = Some(e.to_string());
        }
        match self.error {
            None => Ok(self.path),
            Some(message) => Err(ReportError::Recording {
                path: self.path,
                message,
            }),
        }
    }

    /// The path with its deviation from the program magnified k times (k a round number that
    /// makes the largest deviation a tenth of the path's extent), coloured by the error.
    /// Returns a sentence saying how the view is magnified.
    fn log_magnified(&self) -> rerun::RecordingStreamResult<Option<String>> {
        let samples = self.magnified.items();
        if samples.len() < 2 {
            return Ok(None);
        }
        let extent = samples.iter().fold(
            (
                Point3::from([f64::INFINITY; 3]),
                Point3::from([f64::NEG_INFINITY; 3]),
            ),
            |(lo, hi), (q, _, _)| (lo.inf(&Point3::from(*q)), hi.sup(&Point3::from(*q))),
        );
        let size = (extent.1 - extent.0).norm();
        let worst = samples
            .iter()
            .map(|s| s.2)
            .filter(|e| e.is_finite())
            .fold(0.0, f64::max);
        let k = magnification(size, worst);
        let programmed: Vec<[f64; 3]> = samples.iter().map(|s| s.0).collect();
        let actual: Vec<[f64; 3]> = samples
            .iter()
            .map(|(q, p, _)| std::array::from_fn(|i| q[i] + k * (p[i] - q[i])))
            .collect();
        self.rec.log_static(
            self.entity("magnified/programmed"),
            &rerun::LineStrips3D::new([f32_points(&programmed)])
                .with_colors([rgb(COMMANDED)])
                .with_radii([rerun::Radius::new_ui_points(1.0)]),
        )?;
        // Short strips, each coloured by its largest error on a blue → red scale.
        let pieces: Vec<(Vec<[f32; 3]>, rerun::Color)> = (0..actual.len() - 1)
            .step_by(8)
            .map(|start| {
                let end = (start + 9).min(actual.len());
                let e = samples[start..end].iter().map(|s| s.2).fold(0.0, f64::max);
                (
                    f32_points(&actual[start..end]),
                    heat(if worst > 0.0 { e / worst } else { 0.0 }),
                )
            })
            .collect();
        self.rec.log_static(
            self.entity("magnified/actual"),
            &rerun::LineStrips3D::new(pieces.iter().map(|p| p.0.clone()))
                .with_colors(pieces.iter().map(|p| p.1))
                .with_radii([rerun::Radius::new_ui_points(2.0)])
                .with_labels([format!("deviation ×{k} (largest {:.3} µm)", worst * 1e6)])
                .with_show_labels(false),
        )?;
        Ok(Some(format!(
            "*Path error, magnified*: the tool drawn at its nearest programmed point + {k} × its deviation from it; colour blue (no error) → red (the largest contour error, {:.3} µm).",
            worst * 1e6
        )))
    }
}

/// A round magnification (1, 2 or 5 × 10ⁿ) that draws the largest deviation at about a tenth
/// of the path's size; 1 when there is nothing to magnify.
pub fn magnification(path_size: f64, largest_deviation: f64) -> f64 {
    if !(largest_deviation > 0.0 && path_size > 0.0) {
        return 1.0;
    }
    let wanted = (0.1 * path_size / largest_deviation).max(1.0);
    let decade = 10f64.powf(wanted.log10().floor());
    let mantissa = wanted / decade;
    let round = if mantissa >= 5.0 {
        5.0
    } else if mantissa >= 2.0 {
        2.0
    } else {
        1.0
    };
    round * decade
}

/// A mesh of a triangle soup in `colour`, in metres.
fn stock_mesh(triangles: &[[Point3<f64>; 3]], colour: [u8; 3]) -> rerun::Mesh3D {
    let vertices: Vec<[f32; 3]> = triangles
        .iter()
        .flatten()
        .map(|p| [p.x as f32, p.y as f32, p.z as f32])
        .collect();
    // Each triangle's own normal at its three corners: flat shading, so a groove or a wall
    // reads as one (without normals the viewer draws the whole mesh in one flat colour).
    let normals: Vec<[f32; 3]> = triangles
        .iter()
        .flat_map(|t| {
            let n = (t[1] - t[0])
                .cross(&(t[2] - t[0]))
                .try_normalize(0.0)
                .unwrap_or_else(nalgebra::Vector3::z);
            [[n.x as f32, n.y as f32, n.z as f32]; 3]
        })
        .collect();
    let indices: Vec<rerun::TriangleIndices> = (0..triangles.len() as u32)
        .map(|t| rerun::TriangleIndices::from([3 * t, 3 * t + 1, 3 * t + 2]))
        .collect();
    rerun::Mesh3D::new(vertices)
        .with_vertex_normals(normals)
        .with_triangle_indices(indices)
        .with_albedo_factor(rerun::Rgba32::from_rgb(colour[0], colour[1], colour[2]))
}

/// Blue (−1) through grey (0) to red (+1).
fn signed_heat(x: f64) -> rerun::Color {
    let x = x.clamp(-1.0, 1.0);
    let grey = 200.0;
    let (r, g, b) = if x < 0.0 {
        let t = -x;
        (
            grey * (1.0 - t),
            grey * (1.0 - t) + 60.0 * t,
            grey + (255.0 - grey) * t,
        )
    } else {
        (
            grey + (255.0 - grey) * x,
            grey * (1.0 - x),
            grey * (1.0 - x),
        )
    };
    rerun::Color::from_rgb(r as u8, g as u8, b as u8)
}

/// Blue (0) through yellow to red (1).
fn heat(x: f64) -> rerun::Color {
    let x = x.clamp(0.0, 1.0);
    let (r, g, b) = if x < 0.5 {
        (2.0 * x, 2.0 * x, 1.0 - 2.0 * x)
    } else {
        (1.0, 2.0 - 2.0 * x, 0.0)
    };
    rerun::Color::from_rgb((r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8)
}

impl RrdWriter {
    /// A lane's colour: physics orange and analytic green, or the variant's own colour.
    fn colour(&self, lane: &LaneKind) -> [u8; 3] {
        match (lane, &self.variant) {
            (LaneKind::Analytic, _) => ANALYTIC,
            (_, Some((_, colour))) => *colour,
            _ => PHYSICS,
        }
    }
}

/// Errors in µm on linear axes, degrees on rotary ones (as the CLI prints them).
fn error_scale(l: &AxisLabel) -> f64 {
    if l.rotary {
        l.scale()
    } else {
        1e6
    }
}

pub(super) fn error_unit(l: &AxisLabel) -> &'static str {
    if l.rotary {
        "deg"
    } else {
        "µm"
    }
}

fn recording_error(path: &Path, e: &dyn std::fmt::Display) -> ReportError {
    ReportError::Recording {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

fn f32_points(points: &[[f64; 3]]) -> Vec<[f32; 3]> {
    points
        .iter()
        .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32])
        .collect()
}

fn quaternion(p: &Isometry3<f64>) -> rerun::Quaternion {
    let q = p.rotation.quaternion();
    rerun::Quaternion::from_xyzw([q.i as f32, q.j as f32, q.k as f32, q.w as f32])
}

/// One visual's shape at `entity` (its pose is the entity's transform), see-through in its URDF
/// colour.
fn log_visual_shape(
    rec: &RecordingStream,
    entity: &str,
    v: &Visual,
) -> rerun::RecordingStreamResult<()> {
    let [r, g, b, _] = v.color.unwrap_or([0.6, 0.6, 0.65, 1.0]);
    let colour = rerun::Color::from_unmultiplied_rgba(
        (r * 255.0) as u8,
        (g * 255.0) as u8,
        (b * 255.0) as u8,
        (MACHINE_ALPHA * 255.0) as u8,
    );
    match &v.shape {
        Shape::Box { half_extents } => rec.log_static(
            entity,
            &rerun::Boxes3D::from_half_sizes([[
                half_extents.x as f32,
                half_extents.y as f32,
                half_extents.z as f32,
            ]])
            .with_fill_mode(rerun::FillMode::Solid)
            .with_colors([colour]),
        ),
        // Rerun's cylinder is centred on the origin along +z, as URDF's.
        Shape::Cylinder { radius, length } => rec.log_static(
            entity,
            &rerun::Cylinders3D::from_lengths_and_radii([*length as f32], [*radius as f32])
                .with_fill_mode(rerun::FillMode::Solid)
                .with_colors([colour]),
        ),
        // Rerun's capsule runs from the origin to +z: moved to be centred, as URDF's.
        Shape::Capsule { radius, length } => rec.log_static(
            entity,
            &rerun::Capsules3D::from_lengths_and_radii([*length as f32], [*radius as f32])
                .with_translations([[0.0, 0.0, -(*length as f32) / 2.0]])
                .with_fill_mode(rerun::FillMode::Solid)
                .with_colors([colour]),
        ),
        Shape::Sphere { radius } => rec.log_static(
            entity,
            &rerun::Ellipsoids3D::from_radii([*radius as f32])
                .with_fill_mode(rerun::FillMode::Solid)
                .with_colors([colour]),
        ),
        Shape::Mesh(mesh) => {
            // A mesh's vertex colours carry no alpha: the albedo factor gives colour and
            // see-through alike.
            let mut archetype = rerun::Mesh3D::new(mesh.vertices.iter().copied())
                .with_triangle_indices(mesh.triangles.iter().copied())
                .with_albedo_factor(colour.0);
            if let Some(normals) = &mesh.normals {
                archetype = archetype.with_vertex_normals(normals.iter().copied());
            }
            rec.log_static(entity, &archetype)
        }
    }
}

fn transform(p: &Isometry3<f64>) -> rerun::Transform3D {
    rerun::Transform3D::from_translation(f32x3(&p.translation.vector))
        .with_quaternion(quaternion(p))
}

fn f32x3(v: &nalgebra::Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// A recording of a planned setpoint stream (`cncsim plan --rrd`): per machine axis position,
/// velocity and acceleration (mm or deg units) under `setpoints/<axis>/…`, sent in chunks as the
/// stream is read, and the tool path on the workpiece (`workpiece/tool_path`, m) when given.
pub fn write_setpoints_recording(
    path: &Path,
    name: &str,
    setpoints: &mut dyn crate::plan::SetpointStream,
    labels: &[AxisLabel],
    tool_on_workpiece: &[[f64; 3]],
) -> Result<(), ReportError> {
    let fail = |e: &dyn std::fmt::Display| recording_error(path, e);
    let rec = rerun::RecordingStreamBuilder::new("cncsim")
        .recording_name(name)
        .save(path)
        .map_err(|e| fail(&e))?;
    let mut log = || -> Result<(), Box<dyn std::error::Error>> {
        let n = setpoints.axes();
        let period = setpoints.period();
        // (entity, scale) per series: position, velocity, acceleration of each axis.
        let mut series = Vec::new();
        for l in labels {
            let (s, u) = (l.scale(), l.unit());
            for (what, unit) in [
                ("position", u.to_string()),
                ("velocity", format!("{u}/s")),
                ("acceleration", format!("{u}/s²")),
            ] {
                let entity = format!("setpoints/{}/{what}", l.name);
                rec.log_static(
                    entity.as_str(),
                    &rerun::SeriesLines::new().with_names([format!("{} {what} ({unit})", l.name)]),
                )?;
                series.push((entity, s));
            }
        }
        let mut sample = crate::plan::SetpointSample::zeros(n);
        let mut times = Vec::with_capacity(CHUNK_ROWS);
        let mut columns: Vec<Vec<f64>> = vec![Vec::with_capacity(CHUNK_ROWS); series.len()];
        let mut k = 0usize;
        loop {
            let more = setpoints.next_sample(&mut sample);
            if more {
                times.push(k as f64 * period);
                for i in 0..n {
                    let values = [
                        sample.position[i],
                        sample.velocity[i],
                        sample.acceleration[i],
                    ];
                    for (j, v) in values.into_iter().enumerate() {
                        columns[3 * i + j].push(v * series[3 * i + j].1);
                    }
                }
                k += 1;
            }
            if !times.is_empty() && (times.len() == CHUNK_ROWS || !more) {
                for ((entity, _), column) in series.iter().zip(&mut columns) {
                    rec.send_columns(
                        entity.as_str(),
                        [TimeColumn::new_duration_secs(
                            "sim_time",
                            times.iter().copied(),
                        )],
                        rerun::Scalars::new(column.drain(..)).columns_of_unit_batches()?,
                    )?;
                }
                times.clear();
                // Planning outruns the stream's writer thread: waiting for it after each chunk
                // keeps what is queued (and memory) to one chunk.
                rec.flush_blocking()?;
            }
            if !more {
                break;
            }
        }
        if !tool_on_workpiece.is_empty() {
            rec.log_static("workpiece", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;
            rec.log_static(
                "workpiece/tool_path",
                &rerun::LineStrips3D::new([f32_points(tool_on_workpiece)]),
            )?;
        }
        Ok(())
    };
    log().map_err(|e| fail(&e))?;
    rec.flush_blocking().map_err(|e| fail(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magnification_is_a_round_number_showing_the_error_at_a_tenth() {
        // 0.6 mm on a 60 mm circle: ×10; 0.08 µm on 85 mm: ×100 000.
        assert_eq!(magnification(0.085, 0.6e-3), 10.0);
        assert_eq!(magnification(0.085, 0.076e-6), 100_000.0);
        assert_eq!(magnification(0.085, 0.0), 1.0);
        assert_eq!(magnification(0.01, 0.01), 1.0);
    }
}
