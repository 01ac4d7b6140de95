//! The sun split against the sun in the bins (issue 14), both against the Monte Carlo
//! reference with a collimated sun along its exact direction: per-point relative RMSE of
//! average light and of irradiance on the six axes (luminance, as `scenes::compare`),
//! sun light only (no sky), suns at several elevations and at azimuth 20 degrees (between
//! bins), on the canopy and dense-block scenes (`lightgrid_measure::sun_measure`).
//!
//! Then the shadow of a dense block on the ground: the direction from the block to the
//! centroid of the missing ground irradiance, against the exact one (away from the sun).
//! `cargo xtask sun` measures the same on the bench forest and under a single tree.
//!
//! `cargo run --release -p lightgrid-measure --example sun_split -- [n] [paths]` (16, 2 000 000)

use lightgrid_core::SweepOptions;
use lightgrid_core::glam::Vec3;
use lightgrid_measure::scenes::Scene;
use lightgrid_measure::sun_measure::{
    angle_error, exact_shadow_azimuth, ground_light, shadow_azimuth, sun_errors,
};
use lightgrid_sky::Sun;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: u32 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(16);
    let paths: u64 = args
        .get(2)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(2_000_000);
    let mut o = SweepOptions::multi_bounce();
    o.tolerance = 1e-5;
    o.max_passes = 64;
    println!("{n}^3 cells, {paths} reference paths; relative RMSE of average light / irradiance");
    println!("scene        elev   bins avg  bins irr   split avg  split irr   ref noise");
    for scene in [Scene::Canopy, Scene::DenseBlock] {
        let (m, b) = scene.build(n);
        for elev in [10.0f32, 25.0, 40.0, 60.0, 80.0] {
            let e = sun_errors(
                &m,
                &b.sides,
                elev.to_radians(),
                20f32.to_radians(),
                paths,
                &o,
            )?;
            println!(
                "{:12} {elev:4.0}   {:8.4}  {:8.4}   {:9.4}  {:9.4}   {:9.4}",
                scene.name(),
                e.bins.0,
                e.bins.1,
                e.split.0,
                e.split.1,
                e.noise
            );
        }
    }
    shadows(&o)
}

fn shadows(o: &SweepOptions) -> Result<(), Box<dyn std::error::Error>> {
    use lightgrid_core::glam::UVec3;
    use lightgrid_core::{GridDesc, Material, MaterialGrid};
    let n = 32u32;
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(n, 10, n))?;
    let c = n / 2;
    let scene = |block: bool| {
        let cells = (0..d.point_count())
            .map(|i| {
                let p = d.coords(i).expect("in range");
                if p.y == 0 {
                    Material::opaque(Vec3::splat(0.3))
                } else if block
                    && (c - 1..c + 1).contains(&p.x)
                    && (c - 1..c + 1).contains(&p.z)
                    && p.y < 7
                {
                    Material {
                        reflectance: Vec3::splat(0.3),
                        pass: 0.05,
                    }
                } else {
                    Material::EMPTY
                }
            })
            .collect();
        MaterialGrid::new(d, cells)
    };
    let (with, without) = (scene(true)?, scene(false)?);
    println!(
        "\nshadow of a 2 x 6 x 2 dense block on a 32 x 32 ground: azimuth of the shadow's centroid"
    );
    println!("sun elev  azim   exact   bins (error)   split (error)");
    for (elev, azim) in [
        (40.0f32, 30.0f32),
        (30.0, 20.0),
        (55.0, 67.0),
        (25.0, 112.0),
    ] {
        let sun = Sun::at(elev.to_radians(), azim.to_radians(), Vec3::ONE);
        let (b1, s1) = ground_light(&with, &sun, 1, o)?;
        let (b0, s0) = ground_light(&without, &sun, 1, o)?;
        let centre = Vec3::new(c as f32 - 0.5, 0.0, c as f32 - 0.5);
        let exact = exact_shadow_azimuth(sun.direction);
        let (ab, asp) = (
            shadow_azimuth(&b1, &b0, n, n, centre),
            shadow_azimuth(&s1, &s0, n, n, centre),
        );
        println!(
            "         {elev:4.0}  {azim:4.0}  {exact:6.1}  {ab:6.1} ({:4.1})   {asp:6.1} ({:4.1})",
            angle_error(ab, exact),
            angle_error(asp, exact)
        );
    }
    Ok(())
}
