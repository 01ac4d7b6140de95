//! Sun transmittance along the exact sun direction: the exact march against the sheared
//! level-by-level form, at several sun elevations and azimuths between the bins, on the
//! canopy and dense-block scenes (64³): time of each, and the sheared form's error
//! (mean and largest absolute difference, and over the points the march puts in
//! half-shadow, 0.05 < T < 0.95).
//!
//! `cargo run --release -p lightgrid-measure --example sun`

use std::time::Instant;

use lightgrid_core::glam::Vec3;
use lightgrid_measure::scenes::Scene;
use lightgrid_sweep_cpu::SunTransmittance;

fn main() -> Result<(), lightgrid_core::GridError> {
    let open = |_: Vec3| 1.0f32;
    println!(
        "scene        elev  azim   march ms  sheared ms   mean |diff|  max |diff|  penumbra mean"
    );
    for scene in [Scene::Canopy, Scene::DenseBlock] {
        let (m, _) = scene.build(64);
        for (elev, azim) in [
            (80.0f32, 30.0f32),
            (60.0, 20.0),
            (40.0, 30.0),
            (25.0, 10.0),
            (10.0, 30.0),
        ] {
            let (e, a) = (elev.to_radians(), azim.to_radians());
            let to_sun = Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin());
            let t = Instant::now();
            let exact = SunTransmittance::march(&m, to_sun, false, &open)?;
            let t_march = t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            let sheared = SunTransmittance::sheared(&m, to_sun, &open)?;
            let t_sheared = t.elapsed().as_secs_f64() * 1e3;
            let (mut sum, mut max, mut pen, mut n_pen) = (0.0f64, 0.0f32, 0.0f64, 0usize);
            for (x, y) in exact.values().iter().zip(sheared.values()) {
                let d = (x - y).abs();
                sum += d as f64;
                max = max.max(d);
                if *x > 0.05 && *x < 0.95 {
                    pen += d as f64;
                    n_pen += 1;
                }
            }
            let n = exact.values().len() as f64;
            println!(
                "{:12} {elev:4.0}  {azim:4.0}  {t_march:9.1}  {t_sheared:10.1}  {:12.4}  {max:10.3}  {:13.4}",
                format!("{scene:?}"),
                sum / n,
                pen / n_pen.max(1) as f64
            );
        }
    }
    Ok(())
}
