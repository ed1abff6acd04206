//! The metrics as a terminal table.

use super::Metrics;

/// The run's metrics as a plain-text table: per-axis following error, torque and voltage, then
/// contour and path-speed error, physics against the analytic model, and the run's timing.
pub fn metrics_table(m: &Metrics) -> String {
    let mut s = String::new();
    let status = match &m.stopped {
        None => "completed".to_string(),
        Some(why) => format!("STOPPED: {why}"),
    };
    s.push_str(&format!("scenario {} — {status}\n", m.scenario));
    s.push_str(&format!(
        "  {:<6} {:>14} {:>14} {:>12} {:>12} {:>10}\n",
        "axis", "max |e|", "rms e", "peak T N·m", "rms T N·m", "peak V"
    ));
    for (name, a) in &m.axes {
        let (max, rms, unit) = match (a.max_following_error_mm, a.rms_following_error_mm) {
            (Some(max), Some(rms)) => (max * 1e3, rms * 1e3, "µm"),
            _ => (
                a.max_following_error_deg.unwrap_or(f64::NAN) * 1e3,
                a.rms_following_error_deg.unwrap_or(f64::NAN) * 1e3,
                "mdeg",
            ),
        };
        let volts = a
            .peak_voltage_v
            .map_or("—".to_string(), |v| format!("{v:.3}"));
        s.push_str(&format!(
            "  {:<6} {:>11.3} {unit:<4} {:>11.3} {unit:<4} {:>12.5} {:>12.5} {:>10}\n",
            name, max, rms, a.peak_torque_nm, a.rms_torque_nm, volts
        ));
    }
    s.push_str(&format!(
        "  contour error: max {:.3} µm, rms {:.3} µm;  path-speed error: max {:.4} mm/s (after a catch-up from rest of {:.0} ms)\n",
        m.max_contour_error_mm * 1e3,
        m.rms_contour_error_mm * 1e3,
        m.max_path_speed_error_mm_s,
        m.path_speed_catch_up_s * 1e3
    ));
    let comparison: Vec<String> = m
        .axes
        .iter()
        .filter_map(|(name, a)| {
            match (a.max_physics_vs_analytic_mm, a.max_physics_vs_analytic_deg) {
                (Some(mm), _) => Some(format!("{name} {:.4} µm", mm * 1e3)),
                (_, Some(deg)) => Some(format!("{name} {deg:.6} deg")),
                _ => None,
            }
        })
        .collect();
    if !comparison.is_empty() {
        s.push_str(&format!(
            "  physics vs analytic model, max |difference|: {}\n",
            comparison.join(", ")
        ));
    }
    if let Some(c) = &m.cutting {
        s.push_str(&format!(
            "  cutting: max force {:.1} N, max spindle power {:.1} W, max spindle torque {:.3} N·m, engaged {:.3} s\n",
            c.max_force_n, c.max_spindle_power_w, c.max_spindle_torque_nm, c.engaged_time_s
        ));
    }
    if let Some(p) = &m.part {
        s.push_str(&format!(
            "  part as cut vs nominal: surface error max {:.3} µm, rms {:.3} µm (undercut {:.3} µm, overcut {:.3} µm); removed {:.1} mm³ (nominal {:.1} mm³)\n",
            p.max_surface_error_mm * 1e3,
            p.rms_surface_error_mm * 1e3,
            p.max_undercut_mm * 1e3,
            p.max_overcut_mm * 1e3,
            p.removed_volume_mm3,
            p.nominal_removed_volume_mm3
        ));
    }
    s.push_str(&format!(
        "  simulated {:.3} s in {:.3} s wall ({:.1}× real time), {} servo ticks, {} physics steps\n",
        m.sim_time_s, m.wall_time_s, m.real_time_factor, m.servo_ticks, m.physics_steps
    ));
    s
}
