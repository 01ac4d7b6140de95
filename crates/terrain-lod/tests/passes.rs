//! The hierarchy's default sweep options stop passing light on where little is left to
//! send: a dark canopy after its downward and upward passes, within 1 % of the
//! converged light; brighter ones run more passes, a bright one to the pass limit.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, Material, MaterialGrid, SideBoundary, SweepOptions, Sweeper,
};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::HierarchyParams;

/// A periodic 8 × 12 × 8 grid: opaque ground of `ground` albedo at the bottom level, a
/// canopy of leaves (`leaf` albedo, pass-through 0.6 a cell) in levels 3-7 of every
/// other column, air above.
fn canopy(leaf: f32, ground: f32) -> MaterialGrid {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(8, 12, 8)).expect("a valid grid");
    let cells = (0..desc.point_count())
        .map(|i| {
            let c = desc.coords(i).expect("in range");
            if c.y == 0 {
                Material::opaque(Vec3::splat(ground))
            } else if (3..8).contains(&c.y) && (c.x + c.z).is_multiple_of(2) {
                Material {
                    reflectance: Vec3::splat(leaf),
                    pass: 0.6,
                }
            } else {
                Material::EMPTY
            }
        })
        .collect();
    MaterialGrid::new(desc, cells).expect("valid cells")
}

/// Passes run and the summed light of every bin and point, for `options`.
fn sweep(m: &MaterialGrid, options: &SweepOptions) -> (u32, f64) {
    let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(sky)
    };
    let out = CpuSweeper::new().sweep(m, &b, options).expect("the sweep");
    let sum = out
        .bins
        .expect("bins")
        .data()
        .iter()
        .map(|l| l.total().x as f64)
        .sum();
    (out.stats.passes, sum)
}

#[test]
fn default_passes_stop_where_little_light_is_left() {
    let o = HierarchyParams::default().sweep;
    let mut converged = o;
    converged.max_passes = 64;
    converged.tolerance = 1e-6;
    let mut last = 0;
    for (leaf, ground) in [
        (0.05, 0.2),
        (0.15, 0.25),
        (0.3, 0.25),
        (0.5, 0.5),
        (0.9, 0.9),
    ] {
        let m = canopy(leaf, ground);
        let (passes, light) = sweep(&m, &o);
        let (_, full) = sweep(&m, &converged);
        assert!(
            passes >= last,
            "leaves {leaf}: {passes} passes, fewer than a darker canopy's {last}"
        );
        last = passes;
        assert!(
            light <= full,
            "leaves {leaf}: {light} above converged {full}"
        );
        if passes < o.max_passes {
            // Stopped by the tolerance: what was left waiting is under 1 % of the light.
            assert!(
                light >= 0.99 * full,
                "leaves {leaf}: {passes} passes give {light}, converged {full}"
            );
        }
        if leaf <= 0.15 {
            assert_eq!(passes, 2, "leaves {leaf}: a downward and an upward pass");
        }
    }
    assert_eq!(last, o.max_passes, "a bright canopy runs to the pass limit");
}
