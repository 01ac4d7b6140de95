//! The hand-over through given sides: a crop of a sweep, handed that sweep's own light
//! at its halo, reproduces it. Exact where the paths that start beyond the crop's sides
//! cross only empty cells before they reach its points (a clear band around its sides):
//! what is left elsewhere is the halo's cells, which the crop does not hold (measured
//! by `cargo run --release -p lightgrid-measure --example handover`).

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, HALO_WIDTH, HaloLayout, HorizonLight, Material, MaterialGrid,
    SideBoundary, SweepOptions, Sweeper, TopBoundary,
};
use lightgrid_sweep_cpu::CpuSweeper;

/// The full grid's size across, its levels, and the crop's corner and size across.
const N: u32 = 40;
const NY: u32 = 10;
const X0: u32 = 12;
const W: u32 = 16;

/// Fog (pass-through 0.7, albedo 0.6) everywhere but a clear band from `HALO_WIDTH`
/// cells outside the crop's sides to 3 inside: the farthest a path reaches into the
/// grid from a halo point's own cell.
fn scene() -> MaterialGrid {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(N, NY, N)).unwrap();
    let w = HALO_WIDTH as u32;
    let band = |v: u32| (X0 - w..X0 + 3).contains(&v) || (X0 + W - 3..X0 + W + w).contains(&v);
    let within = |v: u32| (X0 - w..X0 + W + w).contains(&v);
    let cells = (0..desc.point_count())
        .map(|i| {
            let p = desc.coords(i).unwrap();
            if (band(p.x) && within(p.z)) || (band(p.z) && within(p.x)) {
                Material::EMPTY
            } else {
                Material {
                    reflectance: Vec3::new(0.6, 0.5, 0.4),
                    pass: 0.7,
                }
            }
        })
        .collect();
    MaterialGrid::new(desc, cells).unwrap()
}

/// A sky whose bins all differ (the downward ones and the horizontal bins' downward
/// halves).
fn sky() -> BinLight {
    let b = BinLight(std::array::from_fn(|d| {
        Vec3::new(0.3, 0.4, 0.5) * (1 + (d * 5) % 7) as f32
    }));
    b.split_vertical().0
}

#[test]
fn a_crop_given_the_sweeps_own_light_at_its_halo_reproduces_it() {
    let m = scene();
    let cdesc = GridDesc::new(
        Vec3::new(X0 as f32, 0.0, X0 as f32),
        1.0,
        UVec3::new(W, NY, W),
    )
    .unwrap();
    let crop_m = MaterialGrid::new(
        cdesc,
        (0..cdesc.point_count())
            .map(|i| {
                let p = cdesc.coords(i).unwrap();
                *m.get(UVec3::new(X0 + p.x, p.y, X0 + p.z)).unwrap()
            })
            .collect(),
    )
    .unwrap();
    // One pass (downward) and two (and back up): boundary light enters in both.
    for passes in [1, 2] {
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = passes;
        o.tolerance = 0.0;
        o.outputs.bins = true;
        o.outputs.horizon = true;
        let full = CpuSweeper::new()
            .sweep(
                &m,
                &Boundary {
                    sides: SideBoundary::Periodic,
                    ..Boundary::open_sky(sky())
                },
                &o,
            )
            .unwrap();
        let (fb, fh) = (full.bins.unwrap(), full.horizon.unwrap());
        let layout = HaloLayout::new(cdesc.dims());
        let mut light = vec![BinLight::ZERO; layout.len()];
        let mut down = vec![HorizonLight::default(); layout.len()];
        let w = HALO_WIDTH;
        for j in 0..NY {
            for z in -w..W as i32 + w {
                for x in -w..W as i32 + w {
                    if let Some(k) = layout.index(x, j, z) {
                        let q = UVec3::new((X0 as i32 + x) as u32, j, (X0 as i32 + z) as u32);
                        light[k] = *fb.get(q).unwrap();
                        down[k] = *fh.get(q).unwrap();
                    }
                }
            }
        }
        let b = Boundary {
            top: TopBoundary::Uniform(Box::new(sky())),
            bottom: BinLight::ZERO,
            sides: SideBoundary::GivenHalves { light, down },
        };
        let crop = CpuSweeper::new().sweep(&crop_m, &b, &o).unwrap();
        let cb = crop.bins.unwrap();
        let largest = fb.data().iter().fold(0.0f32, |a, l| {
            l.0.iter().fold(a, |a, v| a.max(v.max_element()))
        });
        for i in 0..cdesc.point_count() {
            let p = cdesc.coords(i).unwrap();
            let q = UVec3::new(X0 + p.x, p.y, X0 + p.z);
            let (got, want) = (cb.get(p).unwrap(), fb.get(q).unwrap());
            for bin in 0..lightgrid_core::NUM_DIRS {
                let d = (got.0[bin] - want.0[bin]).abs().max_element();
                assert!(
                    d <= 1e-5 * largest,
                    "{passes} passes, point {p}, bin {bin}: {} against {}",
                    got.0[bin],
                    want.0[bin]
                );
            }
        }
    }
}
