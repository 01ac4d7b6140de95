//! Chandrasekhar's half-space albedo under a **uniform sky** (isotropic incident
//! radiance, `lightgrid_measure::exact::half_space_albedo_diffuse`): the light enters through
//! the top boundary's bins, not as a cell source, so this checks the medium rules on
//! the sweep's own channel light. Periodic sides, cells of optical depth `τ`, total
//! depth 40. `cargo run --release -p lightgrid-measure --example hs_diffuse -- [profile|source]`
//! (the default rule, profile, when left out)
use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, Material, MaterialGrid, MediumEmission, SideBoundary,
    SweepOptions,
};
fn main() {
    let rule = match std::env::args().nth(1).as_deref() {
        Some("source") => MediumEmission::Source,
        _ => MediumEmission::Profile,
    };
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 2000;
    o.tolerance = 1e-6;
    o.medium = rule;
    o.acceleration = lightgrid_core::Acceleration::Diffusion;
    let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    for tau in [0.05f32, 0.69, 1.5, 3.0] {
        let mut line = format!("tau {tau:4}:");
        for w in [0.1f32, 0.5, 0.9, 0.99] {
            let levels = ((40.0 / tau).ceil() as u32).max(2);
            let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, levels, 4)).unwrap();
            let m = MaterialGrid::filled(
                d,
                Material {
                    reflectance: Vec3::splat(w),
                    pass: (-tau).exp(),
                },
            )
            .unwrap();
            let b = Boundary {
                sides: SideBoundary::Periodic,
                ..Boundary::open_sky(sky)
            };
            let s = lightgrid_sweep_cpu::run(&m, &b, &o).unwrap();
            let albedo = s.balance.top_out.x / s.balance.top_in.x;
            let exact = lightgrid_measure::exact::half_space_albedo_diffuse(w as f64);
            line += &format!(" {:+.2}%", 100.0 * (albedo / exact - 1.0));
        }
        println!("{line}");
    }
}
