//! The horizon halves (`Outputs::horizon`): the light the downward passes' horizontal
//! channels bring, kept apart beside the bins. Asking for them changes no bin, average,
//! balance term or pass count (the same adds, in the same order: bit for bit), and
//! into recycled memory they are what they are in fresh memory; each half lies between 0 and its bin; and in
//! empty space under a sky every half is the sky's own (known answer), under a sky
//! whose upper hemisphere is dark every half is 0.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    Acceleration, BinLight, Boundary, GridDesc, Material, MaterialGrid, MediumEmission,
    SideBoundary, SweepOptions, Sweeper, TopBoundary, dirs,
};
use proptest::prelude::*;

mod common;
use common::light;

fn grid() -> impl Strategy<Value = MaterialGrid> {
    (1u32..=9, 1u32..=8, 1u32..=9).prop_flat_map(|(nx, ny, nz)| {
        prop::collection::vec(common::cell(0.4), (nx * ny * nz) as usize).prop_map(move |cells| {
            let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(nx, ny, nz)).unwrap();
            MaterialGrid::new(d, cells).unwrap()
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn the_halves_change_no_bin_and_lie_within_their_bins(
        m in grid(),
        sides in 0u8..3,
        passes in 1u32..7,
        profile in any::<bool>(),
        accelerate in any::<bool>(),
        skip in any::<bool>(),
    ) {
        let d = *m.desc();
        let b = Boundary {
            top: TopBoundary::Uniform(Box::new(light(1).split_vertical().0)),
            bottom: light(2).split_vertical().1,
            sides: common::sides(&d, sides),
        };
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = passes;
        o.tolerance = 0.0;
        o.skip_empty_levels = skip;
        o.medium = if profile { MediumEmission::Profile } else { MediumEmission::Source };
        o.acceleration = if accelerate { Acceleration::Diffusion } else { Acceleration::Off };
        let plain = lightgrid_sweep_cpu::run(&m, &b, &o).unwrap();
        o.outputs = o.outputs.with_horizon();
        let split = lightgrid_sweep_cpu::run(&m, &b, &o).unwrap();
        common::balances_agree(&plain.balance, &split.balance, 0.0)?;
        prop_assert_eq!(plain.output.stats, split.output.stats);
        let (plain, split) = (plain.output, split.output);
        prop_assert!(plain.horizon.is_none());
        prop_assert_eq!(plain.bins.as_ref().unwrap().data(), split.bins.as_ref().unwrap().data());
        prop_assert_eq!(plain.average.as_ref().unwrap().data(), split.average.as_ref().unwrap().data());
        // Into recycled memory (a sweep of other light before it): the same.
        let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
        let other = Boundary { top: TopBoundary::Uniform(Box::new(light(5))), ..b.clone() };
        let first = sweeper.sweep(&m, &other, &o).unwrap();
        sweeper.recycle(first);
        let again = sweeper.sweep(&m, &b, &o).unwrap();
        prop_assert_eq!(again.bins.as_ref().unwrap().data(), split.bins.as_ref().unwrap().data());
        prop_assert_eq!(again.horizon.as_ref().unwrap().data(), split.horizon.as_ref().unwrap().data());
        let (g, h) = (split.bins.unwrap(), split.horizon.unwrap());
        for (i, (l, down)) in g.data().iter().zip(h.data()).enumerate() {
            for (k, v) in down.0.iter().enumerate() {
                let bin = l.0[dirs::FIRST_HORIZONTAL + k];
                let slack = 1e-5 * bin.max_element();
                prop_assert!(
                    v.cmpge(Vec3::ZERO).all() && v.cmple(bin + slack).all(),
                    "point {} half {}: {} of {}", i, k, v, bin
                );
            }
        }
    }
}

/// Empty space, periodic sides: every point holds the sky, and the downward half of
/// each horizontal bin is the part of it the top boundary brings (the sky's downward
/// half). Under light only from below, 0.
#[test]
fn in_empty_space_the_halves_are_the_skys() {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 5, 3)).unwrap();
    let m = MaterialGrid::filled(d, Material::EMPTY).unwrap();
    let sky = light(3);
    let (top, bottom) = sky.split_vertical();
    let mut o = SweepOptions::multi_bounce();
    o.outputs = o.outputs.with_horizon();
    for (top, bottom, want) in [
        (top, bottom, top),
        (top, BinLight::ZERO, top),
        (BinLight::ZERO, bottom, BinLight::ZERO),
    ] {
        let b = Boundary {
            top: TopBoundary::Uniform(Box::new(top)),
            bottom,
            sides: SideBoundary::Periodic,
        };
        let out = lightgrid_sweep_cpu::run(&m, &b, &o).unwrap().output;
        for down in out.horizon.unwrap().data() {
            for (k, v) in down.0.iter().enumerate() {
                let w = want.0[dirs::FIRST_HORIZONTAL + k];
                assert!(
                    (*v - w).abs().max_element() <= 1e-5 * w.max_element().max(1e-6),
                    "half {k}: {v}, the sky's {w}"
                );
            }
        }
    }
}

/// Halves without bins are refused, naming the field.
#[test]
fn halves_without_bins_are_refused() {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(2)).unwrap();
    let m = MaterialGrid::filled(d, Material::EMPTY).unwrap();
    let mut o = SweepOptions::multi_bounce();
    o.outputs = lightgrid_core::Outputs::AVERAGE_DOMINANT;
    o.outputs.horizon = true;
    let e = lightgrid_sweep_cpu::run(&m, &Boundary::open_sky(light(0)), &o).unwrap_err();
    assert!(e.to_string().contains("outputs.horizon"), "{e}");
}

/// The halves are linear in the light: two responses combined under colours
/// (`combine_outputs`) hold the halves of one sweep under the mixed light, within
/// rounding.
#[test]
fn combined_responses_keep_the_halves_of_the_mixed_light() {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(5, 6, 4)).unwrap();
    let cells = (0..d.point_count())
        .map(|i| match i % 7 {
            0 => Material::opaque(Vec3::new(0.6, 0.4, 0.2)),
            3 => Material {
                reflectance: Vec3::splat(0.8),
                pass: 0.5,
            },
            _ => Material::EMPTY,
        })
        .collect();
    let m = MaterialGrid::new(d, cells).unwrap();
    let boundary = |top: BinLight| Boundary {
        top: TopBoundary::Uniform(Box::new(top)),
        bottom: BinLight::ZERO,
        sides: SideBoundary::Periodic,
    };
    let (a, b) = (light(1).split_vertical().0, light(4).split_vertical().0);
    let (sky, sun) = (Vec3::new(0.5, 1.0, 2.0), Vec3::new(3.0, 2.0, 1.0));
    let mut o = SweepOptions::multi_bounce();
    o.outputs = o.outputs.with_horizon();
    o.tolerance = 0.0;
    o.max_passes = 6;
    let run = |top: BinLight| {
        lightgrid_sweep_cpu::run(&m, &boundary(top), &o)
            .unwrap()
            .output
    };
    let combined = lightgrid_sweep_cpu::combine_outputs(&run(a), &run(b), sky, sun);
    let mixed = run(a * sky + b * sun);
    let (x, y) = (combined.horizon.unwrap(), mixed.horizon.unwrap());
    let scale = mixed.bins.unwrap().max_value();
    for (i, (p, q)) in x.data().iter().zip(y.data()).enumerate() {
        for k in 0..p.0.len() {
            let diff = (p.0[k] - q.0[k]).abs().max_element();
            assert!(
                diff <= 1e-5 * scale,
                "point {i} half {k}: {} vs {}",
                p.0[k],
                q.0[k]
            );
        }
    }
}
