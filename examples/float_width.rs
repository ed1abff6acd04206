//! Why cncsim uses Rapier's f64 build: the position error that the engine's own integration
//! (q ← q + v·dt, semi-implicit Euler on joint coordinates) accumulates in each float width
//! over the bundled circle (r = 30 mm at 5 mm/s about (100, 100) mm, 37.7 s at dt = 0.25 ms).
//! The exact velocity is fed in, so every difference from the exact circle is rounding.
//!
//! Run: `cargo run --example float_width`

fn main() {
    let (r, v, cx, cy, dt) = (0.030f64, 0.005f64, 0.100f64, 0.100f64, 2.5e-4f64);
    let omega = v / r;
    let steps = (std::f64::consts::TAU / omega / dt).round() as usize;
    let (mut x32, mut y32) = ((cx + r) as f32, cy as f32);
    let (mut x64, mut y64) = (cx + r, cy);
    let (mut worst32, mut worst64) = (0.0f64, 0.0f64);
    for k in 0..steps {
        // Mean velocity over the step, exactly: the positions would be exact in real numbers.
        let (a0, a1) = (omega * k as f64 * dt, omega * (k + 1) as f64 * dt);
        let (dx, dy) = (r * (a1.cos() - a0.cos()), r * (a1.sin() - a0.sin()));
        x32 += (dx / dt) as f32 * dt as f32;
        y32 += (dy / dt) as f32 * dt as f32;
        x64 += dx / dt * dt;
        y64 += dy / dt * dt;
        let (ex, ey) = (cx + r * a1.cos(), cy + r * a1.sin());
        worst32 = worst32.max(((x32 as f64 - ex).powi(2) + (y32 as f64 - ey).powi(2)).sqrt());
        worst64 = worst64.max(((x64 - ex).powi(2) + (y64 - ey).powi(2)).sqrt());
    }
    println!(
        "circle r = 30 mm at 5 mm/s, {steps} steps of {} ms:",
        dt * 1e3
    );
    println!(
        "  f32 coordinates: worst position error {:.3} µm",
        worst32 * 1e6
    );
    println!(
        "  f64 coordinates: worst position error {:.3e} µm",
        worst64 * 1e6
    );
    println!(
        "  one f32 ulp at 130 mm: {:.4} µm",
        (0.13f32.next_up() - 0.13f32) as f64 * 1e6
    );
}
