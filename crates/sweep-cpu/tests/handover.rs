//! The hand-over through given sides: a crop of a sweep, handed that sweep's own light
//! at its halo, reproduces it. Exact where the paths that start beyond the crop's sides
//! cross only empty cells before they reach its points (a clear band around its sides):
//! what is left elsewhere is the halo's cells, which the crop does not hold (measured
//! by `cargo run --release -p lightgrid-measure --example handover`). With the halo's
//! paths traced (`SweepOptions::halo_paths`) the band may end at the crop's sides: the
//! paths from the halo's points nearest them go on through the crop's edge cells as in
//! the full sweep. With the halo's cells given, its light is carried through them
//! (`lightgrid_core::halo_carry`).

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
/// cells outside the crop's sides to `inside` cells inside (3: the farthest a path
/// reaches into the grid from a halo point's own cell). `None`: a hedge instead, denser
/// fog (pass-through 0.3) from `HALO_WIDTH` to 3 cells outside the sides, clear from
/// there to the sides: the crop's own points' paths cross only empty cells beyond its
/// sides, and the halo's points farther out are means of the hedge's cells.
fn scene(inside: Option<u32>) -> MaterialGrid {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(N, NY, N)).unwrap();
    let w = HALO_WIDTH as u32;
    let (from, to) = match inside {
        Some(i) => (X0 - w, X0 + i),
        None => (X0 - w, X0 - 2),
    };
    let band =
        |v: u32| (from..to).contains(&v) || (2 * X0 + W - to..2 * X0 + W - from).contains(&v);
    let near = |v: u32| (X0 - 2..X0).contains(&v) || (X0 + W..X0 + W + 2).contains(&v);
    let within = |v: u32| (X0 - w..X0 + W + w).contains(&v);
    let fog = |pass| Material {
        reflectance: Vec3::new(0.6, 0.5, 0.4),
        pass,
    };
    let cells = (0..desc.point_count())
        .map(|i| {
            let p = desc.coords(i).unwrap();
            let ring = (band(p.x) && within(p.z)) || (band(p.z) && within(p.x));
            let clear = (near(p.x) && within(p.z)) || (near(p.z) && within(p.x));
            match inside {
                Some(_) if ring => Material::EMPTY,
                None if clear && !(band(p.x) || band(p.z)) => Material::EMPTY,
                None if ring => fog(0.3),
                _ => fog(0.7),
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

/// The largest difference, over every bin of every point of the crop, between the crop
/// handed the full sweep's light at its halo (and, with `cells`, the halo's cells) and
/// the full sweep, over the full sweep's brightest bin; `inside`: the clear band's
/// cells inside the crop ([`scene`]). Checks that the crop's flux balance closes.
fn crop_error(inside: Option<u32>, passes: u32, halo_paths: bool, cells: bool) -> f32 {
    let m = scene(inside);
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
    {
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = passes;
        o.tolerance = 0.0;
        o.outputs.bins = true;
        o.outputs.horizon = true;
        o.halo_paths = halo_paths;

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
        let mut halo_cells = vec![Material::EMPTY; layout.len()];
        let w = HALO_WIDTH;
        for j in 0..NY {
            for z in -w..W as i32 + w {
                for x in -w..W as i32 + w {
                    if let Some(k) = layout.index(x, j, z) {
                        let q = UVec3::new((X0 as i32 + x) as u32, j, (X0 as i32 + z) as u32);
                        light[k] = *fb.get(q).unwrap();
                        down[k] = *fh.get(q).unwrap();
                        halo_cells[k] = *m.get(q).unwrap();
                    }
                }
            }
        }
        let b = Boundary {
            top: TopBoundary::Uniform(Box::new(sky())),
            bottom: BinLight::ZERO,
            sides: SideBoundary::GivenHalves {
                light,
                down,
                cells: cells.then_some(halo_cells),
            },
        };
        let crop = lightgrid_sweep_cpu::run(&crop_m, &b, &o).unwrap();
        let balance = crop.balance.relative_error();
        // The flux balance closes (2.5e-8 with the paths traced, 2.3e-8 without).
        assert!(
            balance <= 1e-6,
            "{passes} passes, halo paths {halo_paths}: the flux balance is {balance:e} off"
        );
        let crop = crop.output;
        let cb = crop.bins.unwrap();
        let largest = fb.data().iter().fold(0.0f32, |a, l| {
            l.0.iter().fold(a, |a, v| a.max(v.max_element()))
        });
        let mut worst = 0.0f32;
        for i in 0..cdesc.point_count() {
            let p = cdesc.coords(i).unwrap();
            let q = UVec3::new(X0 + p.x, p.y, X0 + p.z);
            let (got, want) = (cb.get(p).unwrap(), fb.get(q).unwrap());
            for bin in 0..lightgrid_core::NUM_DIRS {
                worst = worst.max((got.0[bin] - want.0[bin]).abs().max_element());
            }
        }
        worst / largest
    }
}

#[test]
fn a_crop_given_the_sweeps_own_light_at_its_halo_reproduces_it() {
    // One pass (downward) and two (and back up): boundary light enters in both.
    for passes in [1, 2] {
        for halo_paths in [false, true] {
            let e = crop_error(Some(3), passes, halo_paths, false);
            assert!(e <= 1e-5, "{passes} passes, halo paths {halo_paths}: {e}");
        }
    }
}

/// With the clear band outside the crop alone, the paths of the halo's points nearest
/// its sides cross its edge cells of fog, entering the crop and leaving it: traced, a
/// downward pass reproduces the full sweep to rounding; untraced, it is 7 % of the
/// brightest bin off. With a second pass they are within 2e-4: what the edge cells stop
/// of their level-mates' emission into those paths waits for the next pass, and the
/// crop's cells then miss it.
#[test]
fn the_halos_paths_through_the_crops_edge_cells_are_traced() {
    let traced = crop_error(Some(0), 1, true, false);
    assert!(traced <= 1e-5, "one pass, traced: {traced}");
    let untraced = crop_error(Some(0), 1, false, false);
    assert!(untraced > 0.05, "one pass, untraced: {untraced}");
    let (traced, untraced) = (
        crop_error(Some(0), 2, true, false),
        crop_error(Some(0), 2, false, false),
    );
    assert!(traced <= 5e-4, "two passes, traced: {traced}");
    assert!(untraced > 0.05, "two passes, untraced: {untraced}");
}

/// A hedge of dense fog three to five cells beyond the crop's sides, clear from there to
/// the sides ([`scene`]): the halo's points in the hedge hold its cells' means, and a
/// path leaves such a cell darker than its mean. Taken as empty space (the halo's cells
/// not given), the crop is 3.5-3.8 % of the brightest bin off. Given
/// (`SideBoundary::GivenHalves`'s `cells`), the halo's light is carried through them
/// (`lightgrid_core::halo_carry`): 2.4-2.8 % off, and 0.7-1.0 % with the halo's paths
/// traced through the crop's edge cells too (what is left: a cell's source taken as its
/// albedo's share of its mean light, where the sweep's rule puts it by height).
#[test]
fn the_halos_cells_given_carry_its_light_through_them() {
    for passes in [1, 2] {
        let without = crop_error(None, passes, true, false);
        let with = crop_error(None, passes, true, true);
        let untraced = crop_error(None, passes, false, true);
        assert!(without > 0.03, "{passes} passes, no cells: {without}");
        assert!(with <= 0.015, "{passes} passes, cells given: {with}");
        assert!(
            untraced < 0.8 * without,
            "{passes} passes, cells given, paths untraced: {untraced} against {without}"
        );
    }
}
