//! The fast path (`lightgrid_sweep_cpu::run`: index reads away from the sides, quiet points
//! without material within two cells skip the transmit step) against the scalar oracle
//! (`lightgrid_sweep_cpu::sweep::run_scalar`, the crate docs step by step): equal **bit for bit**
//! (light, average, dominant direction; the energy balance to `f64` rounding, as its
//! tallies sum in another order) over random sparse and dense
//! grids, every side mode (open, periodic, given halo, with or without its horizon
//! halves), uniform and per-point tops,
//! bottom light, cell sources, smoothing on and off, any number of passes and both
//! output kinds. The fast path changes no arithmetic, only which work it skips, so any
//! difference at all is a defect.

use lightgrid_core::glam::Vec3;
use lightgrid_core::{
    BinLight, Boundary, CellSource, GridDesc, Material, MaterialGrid, Outputs, SweepOptions,
    TopBoundary,
};
use proptest::prelude::*;

mod common;
use common::light;

/// Grids up to 14 × 6 × 14, or with rows of 16 and 32 points (the hierarchy's node
/// widths: one block a row), whose cells are empty with probability `1 - density`.
fn grid(density: f64) -> impl Strategy<Value = MaterialGrid> {
    let nx = prop_oneof![4 => 1u32..=14, 1 => Just(16u32), 1 => Just(32u32)];
    (nx, 1u32..=6, 1u32..=14).prop_flat_map(move |(nx, ny, nz)| {
        let n = (nx * ny * nz) as usize;
        let cell = common::cell(density);
        prop::collection::vec(cell, n).prop_map(move |cells| {
            let d = GridDesc::new(
                Vec3::ZERO,
                1.0,
                lightgrid_core::glam::UVec3::new(nx, ny, nz),
            )
            .unwrap();
            MaterialGrid::new(d, cells).unwrap()
        })
    })
}

#[derive(Debug, Clone, Copy)]
struct Case {
    sides: u8,
    per_point_top: bool,
    bottom: bool,
    source: bool,
    smoothing: f32,
    passes: u32,
    bins: bool,
    /// `MediumEmission::Profile` (a quadratic source in height) instead of the flat rule.
    profile: bool,
    /// `SweepOptions::halo_paths` (the halo's partial paths traced, with given sides).
    halo_paths: bool,
}

fn case() -> impl Strategy<Value = Case> {
    (
        0u8..4,
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        prop_oneof![Just(0.0f32), 0.0f32..0.9],
        1u32..6,
        any::<bool>(),
        (any::<bool>(), any::<bool>()),
    )
        .prop_map(
            |(
                sides,
                per_point_top,
                bottom,
                source,
                smoothing,
                passes,
                bins,
                (profile, halo_paths),
            )| Case {
                sides,
                per_point_top,
                bottom,
                source,
                smoothing,
                passes,
                bins,
                profile,
                halo_paths,
            },
        )
}

fn check(m: &MaterialGrid, c: Case) -> Result<(), TestCaseError> {
    let d = *m.desc();
    let top = if c.per_point_top {
        TopBoundary::PerPoint(
            (0..d.level_len())
                .map(|i| light(i).split_vertical().0)
                .collect(),
        )
    } else {
        TopBoundary::Uniform(Box::new(light(1).split_vertical().0))
    };
    let b = Boundary {
        top,
        bottom: if c.bottom {
            light(2).split_vertical().1
        } else {
            BinLight::ZERO
        },
        sides: common::sides(&d, c.sides),
    };
    let source = c.source.then(|| {
        let removed = (0..d.point_count())
            .map(|i| {
                if m.data()[i].is_empty() {
                    Vec3::ZERO
                } else {
                    Vec3::new(0.3, 0.2, 0.1) * (i % 5) as f32
                }
            })
            .collect();
        CellSource::new(d, removed, Vec3::new(0.3, -0.8, 0.2)).unwrap()
    });
    let mut o = SweepOptions::multi_bounce();
    o.smoothing = c.smoothing;
    o.max_passes = c.passes;
    o.tolerance = 0.0;
    o.halo_paths = c.halo_paths;
    if !c.bins {
        o.outputs = Outputs::AVERAGE_DOMINANT;
    }
    o.medium = if c.profile {
        lightgrid_core::MediumEmission::Profile
    } else {
        lightgrid_core::MediumEmission::Source
    };
    let fast = lightgrid_sweep_cpu::run_with_source(m, &b, source.as_ref(), &o).unwrap();
    let oracle = lightgrid_sweep_cpu::sweep::run_scalar(m, &b, source.as_ref(), &o).unwrap();
    prop_assert!(fast.output.bins == oracle.output.bins, "bins differ");
    prop_assert!(
        fast.output.average == oracle.output.average,
        "average differs"
    );
    prop_assert!(
        fast.output.dominant == oracle.output.dominant,
        "dominant differs"
    );
    prop_assert_eq!(fast.output.stats, oracle.output.stats);
    // The flux tallies sum in another order (rows of channel planes): equal to `f64`
    // rounding of the input, term by term.
    common::balances_agree(&fast.balance, &oracle.balance, 1e-12)?;
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Mostly empty grids: quiet points everywhere, material here and there.
    #[test]
    fn sparse_grids_equal_the_oracle_bit_for_bit(m in grid(0.08), c in case()) {
        check(&m, c)?;
    }

    /// Dense grids: the transmit step everywhere, sides and corners.
    #[test]
    fn dense_grids_equal_the_oracle_bit_for_bit(m in grid(0.6), c in case()) {
        check(&m, c)?;
    }
}

/// The quiet shortcut is taken: on a grid of one material cell in a wide empty level the
/// fast path still equals the oracle, and the scene's light is not trivial.
#[test]
fn one_cell_in_empty_space() {
    let d = GridDesc::new(Vec3::ZERO, 1.0, lightgrid_core::glam::UVec3::new(16, 4, 16)).unwrap();
    let mut cells = vec![Material::EMPTY; d.point_count()];
    cells[d.index(lightgrid_core::glam::UVec3::new(8, 2, 8)).unwrap()] = Material {
        reflectance: Vec3::splat(0.8),
        pass: 0.2,
    };
    let m = MaterialGrid::new(d, cells).unwrap();
    for profile in [false, true] {
        let c = Case {
            sides: 0,
            per_point_top: false,
            bottom: false,
            source: false,
            smoothing: 0.25,
            passes: 4,
            bins: true,
            profile,
            halo_paths: false,
        };
        check(&m, c).unwrap();
    }
}

/// Levels of more than 4096 cells (the profile rule's emission planes filled on every
/// core, rows of more than one block): a 72 × 3 × 72 grid of mixed media and surfaces,
/// each side mode, both source rules, equal to the oracle bit for bit.
#[test]
fn wide_levels() {
    let m = mixed(72, 3, 72, 13);
    for (sides, profile) in [(0, true), (1, true), (2, true), (1, false)] {
        let c = Case {
            sides,
            per_point_top: false,
            bottom: true,
            source: false,
            smoothing: 0.25,
            passes: 2,
            bins: true,
            profile,
            halo_paths: false,
        };
        check(&m, c).unwrap();
    }
}

/// Rows whose blocks have the widths the row loops are compiled for as constants
/// (`with_width`: 16, 32 and 64 points) and others: rows of 16, 32, 80 (64 + 16), 96
/// (64 + 32) and 21 points, of mixed media and surfaces, open and periodic sides, both
/// source rules, equal to the oracle bit for bit.
#[test]
fn block_widths() {
    for nx in [16, 32, 80, 96, 21] {
        let m = mixed(nx, 3, 5, 7);
        for (sides, profile) in [(0, true), (1, true), (1, false)] {
            let c = Case {
                sides,
                per_point_top: true,
                bottom: true,
                source: false,
                smoothing: 0.25,
                passes: 3,
                bins: true,
                profile,
                halo_paths: false,
            };
            check(&m, c).unwrap_or_else(|e| panic!("rows of {nx}: {e}"));
        }
    }
}

/// A sink too large to stay in cache between passes (`FETCH_AHEAD_BYTES`: each row's
/// gather hints the next row's bins into cache): a 72 × 11 × 72 grid of mixed media and
/// surfaces, equal to the oracle bit for bit.
#[test]
fn sinks_fetched_ahead() {
    let m = mixed(72, 11, 72, 29);
    let n = m.desc().point_count();
    assert!(n * size_of::<BinLight>() >= lightgrid_sweep_cpu::sweep::FETCH_AHEAD_BYTES);
    let c = Case {
        sides: 0,
        per_point_top: false,
        bottom: true,
        source: false,
        smoothing: 0.25,
        passes: 3,
        bins: true,
        profile: true,
        halo_paths: false,
    };
    check(&m, c).unwrap();
}

/// An `nx × ny × nz` grid of mixed cells: of every `period` cells (in a scrambled
/// order) one opaque and five media of five depths, the rest empty.
fn mixed(nx: u32, ny: u32, nz: u32, period: usize) -> MaterialGrid {
    let d = GridDesc::new(
        Vec3::ZERO,
        1.0,
        lightgrid_core::glam::UVec3::new(nx, ny, nz),
    )
    .unwrap();
    let cells = (0..d.point_count())
        .map(|i| match (i * 7919) % period {
            0 => Material::opaque(Vec3::splat(0.4)),
            1..=5 => Material {
                reflectance: Vec3::new(0.2, 0.6, 0.9),
                pass: 0.05 + 0.15 * ((i % 5) as f32),
            },
            _ => Material::EMPTY,
        })
        .collect();
    MaterialGrid::new(d, cells).unwrap()
}
