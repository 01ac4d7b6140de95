//! What the tests that compare two ways of running one sweep share: random cells, a
//! light of many values, the side boundaries by number, and the energy balance term
//! by term.

use lightgrid_core::glam::{DVec3, Vec3};
use lightgrid_core::{BinLight, GridDesc, HaloLayout, Material, SideBoundary};
use lightgrid_sweep_cpu::EnergyBalance;
use proptest::prelude::*;

/// A cell that holds material with probability `density` (reflectance `(a, a/2, 1 - a)`,
/// opaque often), else empty.
pub(crate) fn cell(density: f64) -> impl Strategy<Value = Material> {
    (
        prop::bool::weighted(density),
        0.0f32..1.0,
        prop_oneof![Just(0.0f32), 0.0f32..1.0],
    )
        .prop_map(|(full, a, p)| {
            if full {
                Material {
                    reflectance: Vec3::new(a, 0.5 * a, 1.0 - a),
                    pass: p,
                }
            } else {
                Material::EMPTY
            }
        })
}

/// Bin light whose bins and colours all differ (`seed` shifts them).
pub(crate) fn light(seed: usize) -> BinLight {
    BinLight(std::array::from_fn(|d| {
        Vec3::new(0.1, 0.2, 0.3) * (1 + (d * 7 + seed * 3) % 11) as f32
    }))
}

/// Side boundary `kind`: 0 open, 1 periodic, else a given halo of `light`s at half.
pub(crate) fn sides(d: &GridDesc, kind: u8) -> SideBoundary {
    match kind {
        0 => SideBoundary::Open,
        1 => SideBoundary::Periodic,
        2 => SideBoundary::Given(
            (0..HaloLayout::new(d.dims()).len())
                .map(|i| light(i).scaled(0.5))
                .collect(),
        ),
        // As a hierarchy hands its nodes' sides over: with the downward halves of the
        // horizontal bins (some over their bins, which a sweep clamps).
        _ => SideBoundary::GivenHalves {
            light: (0..HaloLayout::new(d.dims()).len())
                .map(|i| light(i).scaled(0.5))
                .collect(),
            down: (0..HaloLayout::new(d.dims()).len())
                .map(|i| {
                    lightgrid_core::HorizonLight(std::array::from_fn(|k| {
                        Vec3::splat(0.05 * ((i + 3 * k) % 13) as f32)
                    }))
                })
                .collect(),
            cells: None,
        },
    }
}

/// Every term of two energy balances equal to within `tolerance` of `b`'s input.
pub(crate) fn balances_agree(
    a: &EnergyBalance,
    b: &EnergyBalance,
    tolerance: f64,
) -> Result<(), TestCaseError> {
    let scale = b.input().max_element().max(1e-30);
    let terms: [(&str, DVec3, DVec3); 9] = [
        ("top_in", a.top_in, b.top_in),
        ("bottom_in", a.bottom_in, b.bottom_in),
        ("side_in", a.side_in, b.side_in),
        ("top_out", a.top_out, b.top_out),
        ("bottom_out", a.bottom_out, b.bottom_out),
        ("side_out", a.side_out, b.side_out),
        ("absorbed", a.absorbed, b.absorbed),
        ("pending", a.pending, b.pending),
        ("source_in", a.source_in, b.source_in),
    ];
    for (name, u, v) in terms {
        let d = (u - v).abs().max_element() / scale;
        prop_assert!(
            d <= tolerance,
            "{}: {} vs {} (relative {:e})",
            name,
            u,
            v,
            d
        );
    }
    Ok(())
}
