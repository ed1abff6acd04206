//! The layouts recordings open with, designed for review: nothing to arrange by hand.
//!
//! A run: on the left the machine moving in 3D, the tool path on the workpiece alone (so the
//! machine's own geometry never hides it) and the path with its error magnified; below them
//! the summary and the event log. On the right, tabs: an overview (contour error, path speed,
//! every axis's following error with physics and analytic model overlaid) and one tab per
//! axis (position commanded / physics / analytic / drive side, following error, physics −
//! analytic on its own scale, torque, voltage). Every time-series view shares the time cursor.
//!
//! An A/B recording: the variants' tool paths in one 3D view, and one plot each for contour
//! error, every axis's following error and torque, with both variants overlaid.

use super::recording::RecordingSetup;
use super::AxisLabel;
use rerun::blueprint::{
    Blueprint, ContainerLike, Grid, Horizontal, Spatial3DView, Tabs, TextDocumentView, TextLogView,
    TimeSeriesView, Vertical,
};

fn series(name: String, contents: Vec<String>) -> ContainerLike {
    TimeSeriesView::new(name).with_contents(contents).into()
}

/// The view name of an axis's error plots, with the unit.
fn error_unit(l: &AxisLabel) -> &'static str {
    super::recording::error_unit(l)
}

/// The layout of a run's recording: the machine and tool paths on the left, the summary and
/// event log below them, the overview and per-axis plots in tabs on the right.
pub fn run_blueprint(setup: &RecordingSetup<'_>) -> Blueprint {
    let analytic = setup.lanes.len() > 1;
    let workpiece = &setup.machine.links[setup.machine.workpiece_link].name;
    let left = Vertical::new([
        Spatial3DView::new(format!("{}: machine", setup.name))
            .with_contents(["world/**"])
            .into(),
        Horizontal::new([
            Spatial3DView::new("tool path on the workpiece")
                .with_origin(format!("world/machine/{workpiece}"))
                .with_contents(if setup.stock_frame.is_some() {
                    vec!["$origin/paths/**", "$origin/stock/**"]
                } else {
                    vec!["$origin/paths/**"]
                })
                .into(),
            Spatial3DView::new("path error, magnified")
                .with_origin("magnified")
                .with_contents(["$origin/**"])
                .into(),
        ])
        .into(),
        Tabs::new([
            TextDocumentView::new("summary")
                .with_contents(["summary"])
                .into(),
            TextLogView::new("events").with_contents(["events"]).into(),
        ])
        .into(),
    ])
    .with_row_shares([3.0, 2.0, 2.0]);

    let mut overview = vec![
        series(
            "contour error (µm)".into(),
            vec!["path/contour_error/**".into()],
        ),
        series("path speed (mm/s)".into(), vec!["path/speed/**".into()]),
    ];
    for l in setup.labels {
        overview.push(series(
            format!("{} following error ({})", l.name, error_unit(l)),
            vec![format!("axes/{}/following_error/**", l.name)],
        ));
    }
    let mut tabs = vec![Grid::new(overview).with_name("overview").into()];
    for l in setup.labels {
        let a = &l.name;
        let mut plots = vec![
            series(
                format!("{a} position ({})", l.unit()),
                vec![format!("axes/{a}/position/**")],
            ),
            series(
                format!("{a} following error ({})", error_unit(l)),
                vec![format!("axes/{a}/following_error/**")],
            ),
        ];
        if analytic {
            plots.push(series(
                format!("{a} physics − analytic ({})", error_unit(l)),
                vec![format!("axes/{a}/physics_minus_analytic")],
            ));
        }
        plots.push(series(
            format!("{a} torque (N·m)"),
            vec![format!("axes/{a}/torque/**")],
        ));
        if setup.dc_motor {
            plots.push(series(
                format!("{a} voltage (V)"),
                vec![format!("axes/{a}/voltage/**")],
            ));
        }
        tabs.push(Vertical::new(plots).with_name(format!("axis {a}")).into());
    }
    if setup.stock_frame.is_some() {
        tabs.insert(1, cutting_tab());
    }
    let root =
        Horizontal::new([left.into(), Tabs::new(tabs).into()]).with_column_shares([2.0, 3.0]);
    Blueprint::new(root)
        .with_auto_views(false)
        .with_auto_layout(false)
}

/// The tab of a run that cuts: the part as cut and its error magnified, the force of the tool
/// on the part, the spindle's power and the flutes engaged.
fn cutting_tab() -> ContainerLike {
    let part = Horizontal::new([
        Spatial3DView::new("part as cut: error against the nominal part")
            .with_contents(["part/machined"])
            .into(),
        Spatial3DView::new("part error, magnified")
            .with_contents(["part/magnified"])
            .into(),
    ]);
    let plots = Vertical::new([
        series(
            "cutting force on the part (N)".into(),
            vec!["cutting/force/**".into()],
        ),
        series("spindle power (W)".into(), vec!["cutting/power/**".into()]),
        series(
            "flutes engaged".into(),
            vec!["cutting/engaged_flutes/**".into()],
        ),
    ]);
    Vertical::new([part.into(), plots.into()])
        .with_row_shares([3.0, 4.0])
        .with_name("cutting")
        .into()
}

/// The A/B layout: `variants` are (entity prefix without the slash, display name); where
/// they cut, each variant's part as cut beside the other's, and their cutting forces.
pub fn ab_blueprint(
    labels: &[AxisLabel],
    workpiece_link: &str,
    variants: &[(&str, &str)],
    cutting: bool,
) -> Blueprint {
    let paths = variants
        .iter()
        .map(|(p, _)| format!("{p}/world/machine/{workpiece_link}/paths/**"))
        .collect::<Vec<_>>();
    let over = |path: &str| -> Vec<String> {
        variants
            .iter()
            .map(|(p, _)| format!("{p}/{path}"))
            .collect()
    };
    let mut plots = vec![series(
        "contour error (µm)".into(),
        over("path/contour_error/physics"),
    )];
    for l in labels {
        let a = &l.name;
        plots.push(series(
            format!("{a} following error ({})", error_unit(l)),
            over(&format!("axes/{a}/following_error/physics")),
        ));
    }
    for l in labels {
        let a = &l.name;
        plots.push(series(
            format!("{a} torque (N·m)"),
            over(&format!("axes/{a}/torque/physics")),
        ));
    }
    if cutting {
        plots.push(series(
            "cutting force on the part (N)".into(),
            over("cutting/force/**"),
        ));
    }
    let names: Vec<String> = variants.iter().map(|(p, n)| format!("{p}: {n}")).collect();
    let mut left = vec![
        Spatial3DView::new(format!("tool paths: {}", names.join(" vs ")))
            .with_contents(paths)
            .into(),
    ];
    if cutting {
        left.push(
            Horizontal::new(variants.iter().map(|(p, n)| {
                Spatial3DView::new(format!("{p}: {n}, part as cut"))
                    .with_contents([format!("{p}/part/machined")])
                    .into()
            }))
            .into(),
        );
    }
    left.push(
        TextDocumentView::new("A/B summary")
            .with_contents(["ab_summary"])
            .into(),
    );
    let left = Vertical::new(left);
    let root =
        Horizontal::new([left.into(), Grid::new(plots).into()]).with_column_shares([2.0, 3.0]);
    Blueprint::new(root)
        .with_auto_views(false)
        .with_auto_layout(false)
}
