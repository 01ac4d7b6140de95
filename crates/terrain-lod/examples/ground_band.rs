//! What the composed ground reflects against a Lambertian plane's exact answers, with
//! each [`GroundBand`]: flat ground of colour 0.2 (the terrain's height at several
//! places within a cell), periodic sides, one sweep at cells of 0.5–8 m. Printed: the
//! irradiance on a surface facing down 16 m above the ground over the exact `a π` under
//! a uniform sky of radiance 1, and over the exact `a E sin(elevation)` under a sun
//! alone of unit irradiance (the direct beam kept apart), for suns at 60°, 40° and 15°,
//! swept as the hierarchy's frames sweep (no gather), and the 15° sun again with its
//! first scatterings gathered (`Gather::LOW_SUN`, as `SweepOptions::multi_bounce` and a
//! bake gather a sun at or below 30°).
//!
//! `cargo run --release -p lightgrid-terrain-lod --example ground_band`

use std::f32::consts::PI;

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, LightField, MaterialSource, SideBoundary, SplitLightGrid,
    SunBoundary, Sweeper,
};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundBand, GroundColour, Heightmap, Terrain,
};
use lightgrid_sweep_cpu::CpuSweeper;

const ALBEDO: f32 = 0.2;
const ABOVE: f32 = 16.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "ground colour {ALBEDO}; facing down {ABOVE} m above the ground, over the exact answer"
    );
    println!(
        "band       | cell m | terrain at | sky   | sun 60° | sun 40° | sun 15° | 15°, gathered"
    );
    for band in [GroundBand::Colour, GroundBand::Reflecting] {
        for h in [0.5f32, 1.0, 2.0, 4.0, 8.0] {
            for ground in [10.0f32, 10.3, 10.55, 10.8] {
                let r = reflected(band, h, ground)?;
                println!(
                    "{:10} | {h:6} | {ground:10} | {:.3} | {:.3}   | {:.3}   | {:.3}   | {:.3}",
                    format!("{band:?}"),
                    r[0],
                    r[1],
                    r[2],
                    r[3],
                    r[4]
                );
            }
        }
    }
    Ok(())
}

/// Sky, then suns at 60°, 40° and 15° swept, then the 15° sun gathered: the ground's
/// reflected light over the exact.
fn reflected(
    band: GroundBand,
    h: f32,
    ground: f32,
) -> Result<[f32; 5], Box<dyn std::error::Error>> {
    let hm = Heightmap::from_fn(Vec2::splat(-64.0), 4.0, 64, 64, |_, _| ground)?;
    let terrain = Terrain {
        heightmap: hm,
        colour: GroundColour::Uniform(Vec3::splat(ALBEDO)),
    };
    let params = ComposeParams {
        band_albedo: band,
        ..ComposeParams::default()
    };
    let composer = AreaComposer::new(Vec::new(), &[], Some(terrain), params)?;
    let side = (8.0 / h).max(4.0) as u32;
    let levels = (40.0 / h) as u32;
    let desc = GridDesc::new(Vec3::splat(0.5 * h), h, UVec3::new(side, levels, side))?;
    let m = composer.material(&desc)?;
    let mut o = lightgrid_core::SweepOptions::multi_bounce();
    o.max_passes = 64;
    o.tolerance = 1e-6;
    o.outputs.horizon = true;
    // As the hierarchy's frames sweep (`HierarchyParams::default`): nothing gathered.
    o.gather = lightgrid_core::Gather::OFF;
    let periodic = |top: BinLight| Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(top)
    };
    let p = Vec3::new(0.5 * side as f32 * h, ground + ABOVE, 0.5 * side as f32 * h);
    let sky = CpuSweeper::new().sweep(
        &m,
        &periodic(BinLight::uniform(Vec3::ONE).split_vertical().0),
        &o,
    )?;
    let sky = SplitLightGrid::new(sky.bins.ok_or("bins")?, sky.horizon.ok_or("halves")?)?;
    let mut out = [sky.irradiance(p, Vec3::NEG_Y)?.x / (ALBEDO * PI); 5];
    let mut gathered = o;
    gathered.gather = lightgrid_core::Gather::LOW_SUN;
    for (slot, (elevation, o)) in
        out[1..]
            .iter_mut()
            .zip([(60f32, &o), (40.0, &o), (15.0, &o), (15.0, &gathered)])
    {
        let e = elevation.to_radians();
        let to_sun = Vec3::new(0.6 * e.cos(), e.sin(), 0.8 * e.cos());
        let sun = CpuSweeper::new().sweep_sun(
            &m,
            &SunBoundary {
                to_sun,
                scattered: periodic(BinLight::ZERO),
                outside: &|_| 1.0,
            },
            o,
        )?;
        *slot = sun.irradiance(p, Vec3::NEG_Y)?.x / (ALBEDO * e.sin());
    }
    Ok(out)
}

/// Run by `cargo test` (`test = true` in the crate's manifest).
#[cfg(test)]
mod tests {
    use super::*;

    /// Measured bounds, held: with `Reflecting` the reflected sky reads 0.89–1.00 of the
    /// exact answer, the sun 0.86–1.00 at 40° and 1.0–1.18 at 15°, wherever the surface
    /// falls in cells of 0.5, 1 and 4 m, swept as the hierarchy's frames sweep, and the
    /// sky never further from it than with `Colour` (0.25–1.00 there: the defect
    /// `GroundBand` documents). (Gathered, the 15° sun reads 1.09–1.22: ARCHITECTURE's
    /// known defects.)
    #[test]
    fn a_reflecting_band_reads_near_the_lambertian_ground() {
        let mut worst_colour: f32 = 1.0;
        for h in [0.5f32, 1.0, 4.0] {
            for ground in [10.0f32, 10.3, 10.55, 10.8] {
                let c = reflected(GroundBand::Colour, h, ground).unwrap();
                let r = reflected(GroundBand::Reflecting, h, ground).unwrap();
                let at = format!("{h} m cells, terrain at {ground}: {c:?} -> {r:?}");
                assert!((0.88..=1.005).contains(&r[0]), "sky, {at}");
                assert!((0.84..=1.005).contains(&r[2]), "sun 40°, {at}");
                assert!((0.99..=1.2).contains(&r[3]), "sun 15°, {at}");
                assert!((r[0] - 1.0).abs() <= (c[0] - 1.0).abs() + 1e-3, "{at}");
                worst_colour = worst_colour.min(c[0]);
            }
        }
        // (Not a test that cannot fail: the set-up does reach partly covered cells.)
        assert!(worst_colour < 0.5, "{worst_colour}");
    }
}
