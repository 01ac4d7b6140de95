//! Half-space albedo error against cell optical depth, for a medium rule
//! (`cargo run --release -p lightgrid-measure --example hs_depths -- [profile|source|escape]`;
//! the default rule, profile, when left out),
//! with the balance and passes of each case.
use lightgrid_core::{MediumEmission, SweepOptions};
fn main() {
    let rule = match std::env::args().nth(1).as_deref() {
        Some("source") => MediumEmission::Source,
        Some("escape") => MediumEmission::Escape,
        _ => MediumEmission::Profile,
    };
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 4000;
    o.tolerance = 1e-5;
    o.medium = rule;
    o.acceleration = lightgrid_core::Acceleration::Diffusion;
    let ws: Vec<f32> = std::env::var("WS")
        .ok()
        .map(|v| v.split(',').filter_map(|x| x.parse().ok()).collect())
        .unwrap_or(vec![0.1, 0.5, 0.9, 0.99]);
    for tau in [0.05f32, 0.69, 1.0, 1.5, 2.0, 3.0] {
        let pass = (-tau).exp();
        let mut line = format!("tau {tau:4}:");
        for &w in &ws {
            let c = lightgrid_measure::exact::half_space_with(w, pass, 40.0, &o).unwrap();
            line += &format!(
                " {:+.2}% (balance {:.0e}, {} passes)",
                100.0 * (c.swept / c.exact - 1.0),
                c.balance,
                c.passes
            );
        }
        println!("{line}");
    }
}
