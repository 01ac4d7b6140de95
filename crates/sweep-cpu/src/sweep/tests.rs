//! Unit tests of the sweep's parts.

use super::*;
use lightgrid_core::{GridDesc, Material};

/// One value put into a point's light by the resolve tests (none, invalid ones, and
/// the valid extremes -0 and the largest `f32`, whose sums overflow).
const BAD_VALUES: [Option<f32>; 6] = [
    None,
    Some(f32::NAN),
    Some(-1e-3),
    Some(f32::INFINITY),
    Some(-0.0),
    Some(f32::MAX),
];

/// A xorshift generator of test values from `seed` (not 0).
fn xorshift(mut seed: u64) -> impl FnMut() -> u64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    }
}

/// Every stencil tap lies within [`RING`] columns of its point (the slot planes'
/// rings hold all a tap reads beyond a row's ends), and [`ring_slots`] names
/// exactly the slots of taps beside the column, in both passes. Every stencil holds
/// its point's own cell once ([`Ctx::phase3_row`] sets its mean light there, without
/// zeroing it first).
#[test]
fn channels_reach_no_farther_than_the_ring() {
    for up in [false, true] {
        let mut beside = Vec::new();
        for chn in channels(up) {
            let own = chn.stencil.iter().filter(|t| (t.0, t.1) == (0, 0)).count();
            assert_eq!(own, 1, "bin {}", chn.bin);
            for (k, &(dx, _, _)) in chn.stencil.iter().enumerate() {
                assert!(
                    dx.unsigned_abs() as usize <= RING,
                    "tap {dx} beyond the ring"
                );
                if dx != 0 {
                    beside.push(chn.first_slot + k);
                }
            }
        }
        assert_eq!(beside, ring_slots(), "up {up}");
    }
    assert!(!ring_slots().is_empty());
}

/// [`fill_rings`]: on periodic sides each ring column holds the row's wrapped
/// column (rows shorter than the ring included), on open sides 0; the row itself
/// and the planes of slots that read no ring are left as they were.
#[test]
fn rings_hold_the_wrapped_columns_or_zeros() {
    let mut next = xorshift(0x5eed);
    for nx in [1usize, 2, 3, 5, 16] {
        let w = ring_pitch(nx);
        for periodic in [true, false] {
            let row: Vec<f32> = (0..SLOTS * 3 * w)
                .map(|_| (next() % 1000) as f32 + 1.0)
                .collect();
            let mut filled = row.clone();
            fill_rings(&mut filled, nx, periodic);
            for slot in 0..SLOTS {
                let reads = ring_slots().contains(&slot);
                for col in 0..3 {
                    let at = (slot * 3 + col) * w;
                    let (before, after) = (&row[at..][..w], &filled[at..][..w]);
                    assert_eq!(before[RING..RING + nx], after[RING..RING + nx]);
                    for i in (0..RING).chain(nx + RING..w) {
                        let want = if !reads {
                            before[i]
                        } else if periodic {
                            let x = (i as i64 - RING as i64).rem_euclid(nx as i64);
                            before[RING + x as usize]
                        } else {
                            0.0
                        };
                        assert_eq!(
                            after[i], want,
                            "nx {nx} periodic {periodic} slot {slot} col {i}"
                        );
                    }
                }
            }
        }
    }
}

/// The range the huge-page advice covers is the whole 2 MB pages inside a buffer,
/// all of them, and nothing outside it (checked against counting the pages one by
/// one), for buffers at any alignment and of any size.
#[test]
fn huge_page_range_is_every_whole_page_inside() {
    const HUGE: usize = 2 << 20;
    for start in [0, 1, 4096, HUGE - 16, HUGE, 3 * HUGE + 12_288] {
        for bytes in [0, 1, HUGE - 1, HUGE, HUGE + 1, 2 * HUGE, 5 * HUGE + 777] {
            let pages: Vec<usize> = (0..=(start + bytes) / HUGE)
                .map(|p| p * HUGE)
                .filter(|&p| p >= start && p + HUGE <= start + bytes)
                .collect();
            let want = (!pages.is_empty()).then(|| pages[0]..pages[pages.len() - 1] + HUGE);
            assert_eq!(huge_pages_inside(start, bytes), want, "{start} + {bytes}");
        }
    }
}

/// Pending light per level: a level never written reads as zero and holds no
/// records; writing one point allocates its level only; a cleared level reads as
/// zero again and stays allocated.
#[test]
fn pending_levels_allocate_the_levels_written() {
    let mut p = PendingLevels::new(6, 4);
    assert_eq!(p.len(), 24);
    assert!(p.levels.iter().all(Vec::is_empty));
    assert!((0..24).all(|i| p[i].s == Vec3::ZERO && p[i].m == [Vec3::ZERO; 3]));
    let v = Pending {
        s: Vec3::new(1.0, 2.0, 3.0),
        m: [Vec3::X, Vec3::Y, Vec3::Z],
    };
    p[14] = v;
    let sizes: Vec<usize> = p.levels.iter().map(Vec::len).collect();
    assert_eq!(sizes, [0, 0, 6, 0]);
    for i in 0..24 {
        let want = if i == 14 { v.s } else { Vec3::ZERO };
        assert_eq!(p[i].s, want, "point {i}");
    }
    assert_eq!(p.level_mut(2)[2].m, v.m);
    p.clear_level(2);
    p.clear_level(3);
    assert_eq!(
        p.levels.iter().map(Vec::len).collect::<Vec<_>>(),
        [0, 0, 6, 0]
    );
    assert!((0..24).all(|i| p[i].s == Vec3::ZERO && p[i].m == [Vec3::ZERO; 3]));
}

/// A sweep keeps pending light only for levels that hold material: four passes over
/// the 16³ canopy (ground and leaves in 4 of 16 levels) allocate those levels'
/// records and no others, and the same sweep into the reused buffers gives the same
/// light.
#[test]
fn pending_light_held_only_where_material_is() {
    // Ground in levels 0-1, leaves in 8-9, periodic sides, a uniform sky.
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(16)).expect("grid");
    let leaf = Material {
        reflectance: Vec3::new(0.1, 0.4, 0.1),
        pass: 0.6,
    };
    let cells = (0..desc.point_count())
        .map(|i| match desc.coords(i).expect("index").y {
            0 | 1 => Material::opaque(Vec3::splat(0.3)),
            8 | 9 => leaf,
            _ => Material::EMPTY,
        })
        .collect();
    let m = MaterialGrid::new(desc, cells).expect("material");
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(BinLight::uniform(Vec3::ONE).split_vertical().0)
    };
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 4;
    o.tolerance = 0.0;
    let mut spare = Spare::default();
    let first = run_reusing(&m, &b, None, &o, true, &mut spare).expect("sweep");
    let w = spare.work.as_ref().expect("work kept");
    let level_len = m.desc().level_len();
    let with_material: Vec<bool> = m
        .data()
        .chunks(level_len)
        .map(|l| l.iter().any(|c| !c.is_empty()))
        .collect();
    assert!(with_material.iter().any(|&b| b) && !with_material.iter().all(|&b| b));
    for p in [&w.pend_down, &w.pend_up] {
        let held: Vec<bool> = p.levels.iter().map(|l| !l.is_empty()).collect();
        assert_eq!(held, with_material);
    }
    let again = run_reusing(&m, &b, None, &o, true, &mut spare).expect("sweep");
    let bits = |s: &Sweep| -> Vec<u32> {
        let g = s.output.bins.as_ref().expect("bins");
        bytemuck::cast_slice::<BinLight, u32>(g.data()).to_vec()
    };
    assert!(bits(&first) == bits(&again));
}

/// A medium of `passes` (by column) on `ny` levels over an opaque ground, 6 × 5 columns.
fn profile_grid(ny: u32, passes: &[f32]) -> MaterialGrid {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(6, ny, 5)).expect("grid");
    let cells = (0..desc.point_count())
        .map(|i| {
            let q = desc.coords(i).expect("index");
            match q.y {
                0 => Material::opaque(Vec3::splat(0.3)),
                1..=5 => Material {
                    reflectance: Vec3::new(0.2, 0.5, 0.2),
                    pass: passes[q.x as usize % passes.len()],
                },
                _ => Material::EMPTY,
            }
        })
        .collect();
    MaterialGrid::new(desc, cells).expect("material")
}

/// Sweeps with `spare` (2 passes, open sky; its media thick enough for the profile
/// rule's quadratic source, `medium::PROFILE_MIN_DEPTH`): the bins' bits and the profiles its
/// sweeper has computed so far.
fn profile_sweep(m: &MaterialGrid, spare: &mut Spare) -> (Vec<u32>, u64) {
    let b = Boundary::open_sky(BinLight::uniform(Vec3::ONE).split_vertical().0);
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 2;
    let s = run_reusing(m, &b, None, &o, true, spare).expect("sweep");
    let bits = bytemuck::cast_slice::<BinLight, u32>(s.output.bins.as_ref().expect("bins").data())
        .to_vec();
    (
        bits,
        spare.work.as_ref().expect("work kept").prof.computed(),
    )
}

/// A sweeper's memory whose cell profiles have a store of their own holding `cap`
/// (counts that other tests' sweeps in this process do not change).
fn own_profiles(cap: usize) -> Spare {
    let mut w = Work::new(1, 1, 1);
    w.prof = crate::profile::Profiles::own(cap);
    Spare {
        work: Some(w),
        ..Spare::default()
    }
}

/// The cell profiles a sweeper integrated outlive a change of grid size (a
/// hierarchy's nodes differ in height): after a medium of three depths on 8 levels,
/// one of those depths on 12 levels (new work buffers) integrates no profile (fresh
/// profiles would count its two, down and up, from 0), and a new depth its own two.
#[test]
fn cell_profiles_outlive_a_change_of_grid_size() {
    let mut spare = own_profiles(crate::profile::Profiles::KEEP);
    let mut sweep = |m: MaterialGrid| profile_sweep(&m, &mut spare).1;
    assert_eq!(
        sweep(profile_grid(8, &[0.1, 0.2, 0.3])),
        6,
        "three depths, down and up"
    );
    assert_eq!(
        sweep(profile_grid(12, &[0.2])),
        6,
        "a depth integrated before"
    );
    assert_eq!(sweep(profile_grid(12, &[0.2, 0.15])), 8, "one new depth");
}

/// Sweepers that share a store (a hierarchy's forks) compute each profile once
/// between them, and read the same values bit for bit as a sweeper computing its own;
/// a store with no room left computes a level's other values for the level alone,
/// the same bit for bit, and once a sweep found fewer values kept than it computed so
/// (another scene's depths fill the store), the store is retired and the next sweep
/// keeps its own.
#[test]
fn sweepers_share_cell_profiles_and_a_full_store_gives_way() {
    let depths = [0.11, 0.22, 0.33];
    let m = profile_grid(8, &depths);
    let (alone, n) = profile_sweep(&m, &mut own_profiles(crate::profile::Profiles::KEEP));
    assert_eq!(n, 6);
    // Two sweepers on one store.
    let first = own_profiles(crate::profile::Profiles::KEEP);
    let mut second = Spare {
        work: first.work.clone(),
        ..Spare::default()
    };
    let mut first = first;
    assert_eq!(profile_sweep(&m, &mut first), (alone.clone(), 6));
    assert_eq!(
        profile_sweep(&m, &mut second),
        (alone.clone(), 0),
        "the first's"
    );
    // A store of four: the downward pass enters its three depths and the upward one
    // its first; the upward pass's other two are computed at each of the five levels
    // of medium (3 + 1 + 2 × 5), and again every sweep (the kept ones are read more
    // than the others are computed: the store stays).
    let mut small = own_profiles(4);
    let (bits, n) = profile_sweep(&m, &mut small);
    assert!(bits == alone);
    assert_eq!(n, 14);
    let (bits, again) = profile_sweep(&m, &mut small);
    assert!(bits == alone);
    assert_eq!(again - n, 10);
    // Another scene's three depths: none kept, all six computed at every level; the
    // store gives way, and the next sweep keeps four of them again.
    let other = profile_grid(8, &[0.12, 0.24, 0.36]);
    let (_, other_first) = profile_sweep(&other, &mut small);
    let (_, other_second) = profile_sweep(&other, &mut small);
    assert_eq!(other_first - again, 30);
    assert_eq!(other_second - other_first, 14);
}

/// The huge-page advice leaves a buffer's contents as they are (it only changes how
/// the kernel backs its pages), for buffers with whole 2 MB pages inside and
/// without; `fresh_buffer` gives zeros.
#[test]
fn huge_page_advice_keeps_contents() {
    for n in [0usize, 1000, 1 << 20, 3 << 20] {
        let mut v: Vec<u32> = (0..n as u32)
            .map(|i| i.wrapping_mul(2_654_435_761))
            .collect();
        let want = v.clone();
        advise_huge_pages(&mut v);
        assert!(v == want, "{n} values");
        let z: Vec<u32> = fresh_buffer(n);
        assert!(z.len() == n && z.iter().all(|&x| x == 0), "{n} zeros");
    }
}

/// `Ahead`'s shares cover the lines of the bytes after a row once each, in order,
/// for rows of any size and any number of shares (more shares than lines too).
#[test]
fn fetch_ahead_shares_cover_every_line_once() {
    for bytes in [0usize, 1, 63, 64, 65, 312, 20 * 312, 64 * 312, 1000] {
        let row = vec![0u8; bytes];
        let a = Ahead::after(&row);
        assert_eq!(a.start, row.as_ptr_range().end);
        for n in [1usize, 2, 7, CHANNELS, 200] {
            let offs: Vec<usize> = (0..n).flat_map(|i| a.share(i, n).step_by(64)).collect();
            let want: Vec<usize> = (0..bytes.div_ceil(64)).map(|l| l * 64).collect();
            assert_eq!(offs, want, "{bytes} bytes in {n} shares");
        }
    }
}

/// `BinLight`'s four-point `resolve_all` gives `BinLight::average` and `dominant`
/// bit for bit, and flags what `is_valid` rejects, for any number of points (the
/// tail after the last four too).
#[test]
fn resolve_all_equals_average_and_dominant() {
    let mut next = xorshift(0x2545_f491_4f6c_dd1d_u64);
    for n in 0..=11 {
        for bad in BAD_VALUES {
            let mut g: Vec<BinLight> = (0..n)
                .map(|_| {
                    BinLight(std::array::from_fn(|_| {
                        Vec3::from_array(std::array::from_fn(|_| {
                            let r = next();
                            // Zeros, and values over many magnitudes.
                            if r.is_multiple_of(5) {
                                0.0
                            } else {
                                (r >> 40) as f32 * 2f32.powi((r % 40) as i32 - 30)
                            }
                        }))
                    }))
                })
                .collect();
            if let (Some(v), true) = (bad, n > 0) {
                let i = (next() % n as u64) as usize;
                g[i].0[(next() % NUM_DIRS as u64) as usize].y = v;
            }
            for dominant in [false, true] {
                let mut avg = vec![AverageLight(Vec3::splat(7.0)); n];
                let mut dom = vec![DominantDir(Vec3::splat(7.0)); n];
                let ok = BinLight::resolve_all(&g, &mut avg, &mut dom, dominant);
                assert_eq!(ok, g.iter().all(|b| b.is_valid()), "n {n} bad {bad:?}");
                if !ok {
                    continue;
                }
                for (i, b) in g.iter().enumerate() {
                    assert_eq!(
                        avg[i].0.to_array().map(f32::to_bits),
                        b.average().to_array().map(f32::to_bits)
                    );
                    let want = if dominant { b.dominant() } else { Vec3::ZERO };
                    assert_eq!(
                        dom[i].0.to_array().map(f32::to_bits),
                        want.to_array().map(f32::to_bits)
                    );
                }
            }
        }
    }
}

/// `resolve_planes` (a row's resolve from its planes) gives what `BinLight`'s
/// `clamp` then `resolve_all` give on the bins the pass's channels fill, bit for bit,
/// with the same verdict on bad values, for rows of any length (block tails too),
/// both passes, with and without the clamp and the dominant direction.
#[test]
fn resolve_planes_equals_resolve_all() {
    let mut next = xorshift(0x9e37_79b9_7f4a_7c15_u64);
    for nx in [1, 3, 16, 63, 64, 65, 130] {
        for up in [false, true] {
            let ch = channels(up);
            for bad in BAD_VALUES {
                let mut level = LevelLight::new(nx, 1);
                let p = level.pitch();
                let row = level.row_mut(0);
                for c in 0..CHANNELS {
                    for k in 0..3 {
                        for x in 0..nx {
                            let r = next();
                            row[(c * 3 + k) * p + PAD + x] = match r % 7 {
                                0 => 0.0,
                                // Light of either sign (the profile rule's).
                                1 => -((r >> 40) as f32) * 1e-9,
                                _ => (r >> 40) as f32 * 2f32.powi((r % 40) as i32 - 30),
                            };
                        }
                    }
                }
                if let Some(v) = bad {
                    let (c, k, x) = (
                        next() as usize % CHANNELS,
                        next() as usize % 3,
                        next() as usize % nx,
                    );
                    row[(c * 3 + k) * p + PAD + x] = v;
                }
                let row = level.row(0);
                for clamp in [false, true] {
                    for dominant in [false, true] {
                        let mut g = vec![BinLight::default(); nx];
                        for (x, gp) in g.iter_mut().enumerate() {
                            gp.add_channels(ch, |c| row_get(row, p, x, c));
                            if clamp {
                                Sink::clamp(gp);
                            }
                        }
                        let mut want = (
                            vec![AverageLight(Vec3::splat(7.0)); nx],
                            vec![DominantDir(Vec3::splat(7.0)); nx],
                        );
                        let mut got = want.clone();
                        let ok_want = BinLight::resolve_all(&g, &mut want.0, &mut want.1, dominant);
                        let ok_got =
                            resolve_planes(ch, row, p, (clamp, dominant), &mut got.0, &mut got.1);
                        let case = format!(
                            "nx {nx} up {up} bad {bad:?} clamp {clamp} dominant {dominant}"
                        );
                        assert_eq!(ok_got, ok_want, "{case}");
                        // A bad value can leave the clamp (NaN -> 0): valid again.
                        assert_eq!(ok_want, g.iter().all(|b| b.is_valid()), "{case}");
                        let bits = |v: &[AverageLight]| {
                            v.iter()
                                .map(|a| a.0.to_array().map(f32::to_bits))
                                .collect::<Vec<_>>()
                        };
                        let dbits = |v: &[DominantDir]| {
                            v.iter()
                                .map(|a| a.0.to_array().map(f32::to_bits))
                                .collect::<Vec<_>>()
                        };
                        if ok_want {
                            assert_eq!(bits(&got.0), bits(&want.0), "{case}");
                            assert_eq!(dbits(&got.1), dbits(&want.1), "{case}");
                        }
                    }
                }
            }
        }
    }
}

/// `BinLight`'s `clamp` (flat floats) is `Vec3::max(ZERO)` on every bin, bit for bit:
/// NaN and -0 become +0, negative values 0, the rest stay.
#[test]
fn clamp_equals_vec3_max() {
    let vals = [
        f32::NAN,
        -0.0,
        0.0,
        -1e-30,
        -5.0,
        1e-40,
        3.5,
        f32::INFINITY,
        f32::NEG_INFINITY,
    ];
    let mut b = BinLight(std::array::from_fn(|d| {
        Vec3::from_array(std::array::from_fn(|k| vals[(d * 3 + k) % vals.len()]))
    }));
    let want = b.0.map(|v| v.max(Vec3::ZERO));
    Sink::clamp(&mut b);
    for (got, want) in b.0.iter().zip(&want) {
        assert_eq!(
            got.to_array().map(f32::to_bits),
            want.to_array().map(f32::to_bits)
        );
    }
}

/// Enclosed opaque cells (no exposed face: inside a solid) absorb what reaches them
/// ([`swept_reflectance`]): a ground of five levels whose sides take a given halo's
/// light (as a node's ground beside a coarser grid's) holds no light in any enclosed
/// cell, on the fast path and in the oracle, and the energy still balances. Scattered
/// on instead, the light that a path's long step carries one cell past a side cell
/// spread through the whole ground: every one of its enclosed cells held light.
/// An opaque cell's face toward the outside is a surface through an open side (the
/// empty world), not through a periodic one (the wrapped cell) or a given one (the
/// world goes on as at the side); its top face is one under the sky, its bottom face
/// never.
#[test]
fn faces_beyond_the_sides_are_exposed_through_open_sides_alone() {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 3, 4)).expect("grid");
    // A ground of two levels, a clear level above.
    let cells = (0..desc.point_count())
        .map(|i| match desc.coords(i).expect("index").y {
            0 | 1 => Material::opaque(Vec3::splat(0.3)),
            _ => Material::EMPTY,
        })
        .collect();
    let m = MaterialGrid::new(desc, cells).expect("material");
    let up = FACE_NORMALS.iter().position(|n| n.y > 0.0).expect("up") as u8;
    let side_faces: u8 = (0..6u8)
        .filter(|&f| FACE_NORMALS[f as usize].y == 0.0)
        .map(|f| 1 << f)
        .sum();
    let halo = vec![BinLight::ZERO; lightgrid_core::HaloLayout::new(desc.dims()).len()];
    for (sides, edges_open) in [
        (SideBoundary::Open, true),
        (SideBoundary::Periodic, false),
        (SideBoundary::Given(halo), false),
    ] {
        let e = exposure(&m, &sides);
        for i in 0..desc.point_count() {
            let c = desc.coords(i).expect("index");
            let edge = c.x == 0 || c.z == 0 || c.x == 3 || c.z == 3;
            let want_sides = edges_open && edge && c.y < 2;
            assert_eq!(e[i] & side_faces != 0, want_sides, "{sides:?}, cell {c}");
            assert_eq!(e[i] & (1 << up) != 0, c.y == 1, "{sides:?}, cell {c}");
        }
    }
}

#[test]
fn enclosed_opaque_cells_hold_no_light() {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(10, 9, 10)).expect("grid");
    let cells = (0..desc.point_count())
        .map(|i| {
            let c = desc.coords(i).expect("index");
            if c.y < 5 {
                Material::opaque(Vec3::splat(0.6))
            } else if c.y == 6 && (c.x + c.z).is_multiple_of(3) {
                Material {
                    reflectance: Vec3::new(0.2, 0.5, 0.2),
                    pass: 0.5,
                }
            } else {
                Material::EMPTY
            }
        })
        .collect();
    let m = MaterialGrid::new(desc, cells).expect("material");
    let sky = BinLight::uniform(Vec3::new(0.6, 0.7, 1.0));
    let halo = (0..lightgrid_core::HaloLayout::new(desc.dims()).len())
        .map(|i| sky * (0.5 + 0.1 * (i % 5) as f32))
        .collect();
    let b = Boundary {
        sides: SideBoundary::Given(halo),
        ..Boundary::open_sky(sky.split_vertical().0)
    };
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 4;
    o.tolerance = 0.0;
    let exposed = exposure(&m, &b.sides);
    let enclosed: Vec<usize> = (0..desc.point_count())
        .filter(|&i| m.data()[i].pass <= 0.0 && exposed[i] == 0)
        .collect();
    // The ground below its top level: all 10 x 10 columns of levels 0-3 (level 0's
    // bottom face is never exposed, and through the given sides the ground goes on).
    assert_eq!(enclosed.len(), 10 * 10 * 4);
    for fast in [true, false] {
        let s = run_impl(&m, &b, None, &o, fast).expect("sweep");
        let g = s.output.bins.as_ref().expect("bins");
        for &i in &enclosed {
            let c = desc.coords(i).expect("index");
            assert_eq!(g.data()[i], BinLight::ZERO, "fast {fast}: cell {c}");
        }
        // (To the f32 rounding of the light the balance sums, as the other tests.)
        let err = s.balance.relative_error();
        assert!(err < 1e-6, "fast {fast}: balance off by {err:e}");
        // The surface still reflects: the top ground level's points hold light.
        let top = desc.level_range(4);
        assert!(
            g.data()[top]
                .iter()
                .all(|l| l.average().max_element() > 0.0)
        );
    }
    // A sweeper's recycled memory gives the same light.
    let mut spare = Spare::default();
    let first = run_reusing(&m, &b, None, &o, true, &mut spare).expect("sweep");
    let again = run_reusing(&m, &b, None, &o, true, &mut spare).expect("sweep");
    assert!(first.output.bins == again.output.bins);
}

/// A sweep into memory another height of grid left (a hierarchy's nodes differ in
/// height: the work buffers and outputs are made as long as each grid needs, in the
/// memory they had) gives the light of a sweep into fresh memory, bit for bit: tall,
/// short, tall again and short again, with horizon halves and the accelerated passes'
/// pending light, the sides periodic and open.
#[test]
fn memory_of_another_height_gives_fresh_light() {
    let grid = |ny: u32| {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(7, ny, 6)).expect("grid");
        let cells = (0..desc.point_count())
            .map(|i| {
                let q = desc.coords(i).expect("index");
                match q.y {
                    0 => Material::opaque(Vec3::splat(0.3)),
                    y if y + 3 >= ny.min(9) && y < ny.min(9) && !(q.x + q.z).is_multiple_of(3) => {
                        Material {
                            reflectance: Vec3::new(0.2, 0.5, 0.2),
                            pass: 0.4 + 0.1 * (q.x % 3) as f32,
                        }
                    }
                    _ => Material::EMPTY,
                }
            })
            .collect();
        MaterialGrid::new(desc, cells).expect("material")
    };
    let bits = |s: &Sweep| -> Vec<u32> {
        let o = &s.output;
        let mut v =
            bytemuck::cast_slice::<BinLight, u32>(o.bins.as_ref().expect("bins").data()).to_vec();
        v.extend(bytemuck::cast_slice::<lightgrid_core::HorizonLight, u32>(
            o.horizon.as_ref().expect("halves").data(),
        ));
        v
    };
    for sides in [SideBoundary::Periodic, SideBoundary::Open] {
        let b = Boundary {
            sides,
            ..Boundary::open_sky(BinLight::uniform(Vec3::ONE).split_vertical().0)
        };
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = 6;
        o.tolerance = 0.0;
        o.outputs.horizon = true;
        let mut spare = Spare::default();
        for ny in [14, 9, 14, 5, 9] {
            let m = grid(ny);
            let reused = run_reusing(&m, &b, None, &o, true, &mut spare).expect("sweep");
            let fresh = run_reusing(&m, &b, None, &o, true, &mut Spare::default()).expect("sweep");
            assert!(bits(&reused) == bits(&fresh), "{ny} levels after others");
        }
    }
}
