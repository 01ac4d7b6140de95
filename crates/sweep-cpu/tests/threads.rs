//! A sweep on pools of one, two and four threads, alone and side by side with other
//! sweeps and parallel work (as the hierarchy runs its nodes): the same light bit for
//! bit, and every run ends (a helper kept awake for the levels' loops never waits on
//! a sweep it sits on: `sweep/helper.rs`).

use std::sync::mpsc;
use std::time::Duration;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, HaloLayout, HorizonLight, Material, MaterialGrid, SideBoundary,
    SweepOptions, Sweeper, TopBoundary,
};
use lightgrid_sweep_cpu::CpuSweeper;
use rayon::prelude::*;

/// Bin light whose bins and colours all differ (`seed` shifts them).
fn light(seed: usize) -> BinLight {
    BinLight(std::array::from_fn(|d| {
        Vec3::new(0.1, 0.2, 0.3) * (1 + (d * 7 + seed * 3) % 11) as f32
    }))
}

/// A 16-point node of foliage over an opaque ground, its sides a given halo with the
/// downward halves (`seed` varies the foliage).
fn node(seed: u64) -> (MaterialGrid, Boundary) {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(16, 12, 16)).unwrap();
    let mut rng = fastrand::Rng::with_seed(seed);
    let cells = (0..d.point_count())
        .map(|i| {
            let y = d.coords(i).unwrap().y;
            match y {
                0 => Material::opaque(Vec3::splat(0.2)),
                1..8 if rng.u32(0..10) < 6 => Material {
                    reflectance: Vec3::new(0.1, 0.3, 0.1),
                    pass: 0.3 + 0.6 * rng.f32(),
                },
                _ => Material::EMPTY,
            }
        })
        .collect();
    let halo = HaloLayout::new(d.dims()).len();
    let boundary = Boundary {
        top: TopBoundary::Uniform(Box::new(light(1))),
        bottom: BinLight::ZERO,
        sides: SideBoundary::GivenHalves {
            light: (0..halo).map(|i| light(i).scaled(0.5)).collect(),
            down: (0..halo)
                .map(|i| {
                    HorizonLight(std::array::from_fn(|k| {
                        Vec3::splat(0.03 * ((i + 3 * k) % 13) as f32)
                    }))
                })
                .collect(),
            cells: None,
        },
    };
    (MaterialGrid::new(d, cells).unwrap(), boundary)
}

fn options() -> SweepOptions {
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 2;
    o.outputs.horizon = true;
    o
}

/// The bins of `sweeps` nodes swept side by side on forks (each on its own thread
/// where the pool has them), beside a parallel loop of other work.
fn side_by_side(sweeps: u64) -> Vec<Vec<BinLight>> {
    let main = CpuSweeper::new();
    let (light, other) = rayon::join(
        || {
            (0..sweeps)
                .into_par_iter()
                .map(|s| {
                    let mut fork = main.fork().expect("the CPU sweeper forks");
                    let (m, b) = node(s);
                    let out = fork.sweep(&m, &b, &options()).unwrap();
                    out.bins.unwrap().data().to_vec()
                })
                .collect::<Vec<_>>()
        },
        || {
            (0..20_000usize)
                .into_par_iter()
                .with_max_len(64)
                .map(|i| (i as u64).wrapping_mul(2_654_435_761) % 97)
                .sum::<u64>()
        },
    );
    assert!(other > 0);
    light
}

#[test]
fn a_sweep_is_the_same_on_any_pool_and_side_by_side() {
    let (m, b) = node(7);
    let alone = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let out = CpuSweeper::new().sweep(&m, &b, &options()).unwrap();
            (out.bins.unwrap().data().to_vec(), out.horizon.unwrap())
        })
    };
    let one = alone(1);
    for threads in [2, 4] {
        let (bins, halves) = alone(threads);
        assert!(
            bins == one.0,
            "{threads} threads: other light than one thread's"
        );
        assert!(halves == one.1, "{threads} threads: other halves");
    }
    // Many rounds of sweeps side by side on two threads, with a watchdog: a run that
    // waits on itself would hang here.
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let rounds: Vec<_> = (0..12).map(|_| pool.install(|| side_by_side(5))).collect();
        tx.send(rounds).ok();
    });
    let rounds = rx
        .recv_timeout(Duration::from_secs(300))
        .expect("sweeps side by side ended within 5 minutes");
    let serial = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| side_by_side(5));
    for (r, round) in rounds.iter().enumerate() {
        assert!(*round == serial, "round {r}: other light than one thread's");
    }
    assert!(
        serial[0] != one.0,
        "node 0 and node 7 swept alike: the seed varies nothing"
    );
}
