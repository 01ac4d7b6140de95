//! Scratch: half-space albedo error against cell optical depth.
use lightgrid_core::SweepOptions;
fn main() {
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 4000;
    o.tolerance = 1e-5;
    o.acceleration = lightgrid_core::Acceleration::Diffusion;
    for tau in [0.69f32, 1.0, 1.5, 2.0, 3.0] {
        let pass = (-tau).exp();
        let mut line = format!("tau {tau:4}:");
        for w in [0.1f32, 0.5, 0.9, 0.99] {
            let c = sweep_cpu::exact::half_space_with(w, pass, 40.0, &o);
            line += &format!(" {:+.1}%", 100.0 * (c.swept / c.exact - 1.0));
        }
        println!("{line}");
    }
}
