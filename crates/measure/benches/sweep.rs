//! Points per second of the sweep: the 64³ canopy with 26-bin and average-only
//! outputs, one downward pass and four passes (and the bins with the horizon halves,
//! four passes), and a small tall grid (16 × 64 × 16),
//! each for the fast path into recycled memory (`CpuSweeper::sweep` after
//! `CpuSweeper::recycle`: what a per-frame rebuild runs), the fast path into fresh memory
//! (`lightgrid_sweep_cpu::run`) and, in the same run, the scalar oracle it equals bit for bit
//! (`lightgrid_sweep_cpu::sweep::run_scalar`); and the uniform fog at 16³ and 48³, media in every
//! level, where phases 2 and 3 take the time, under the default medium rule and the
//! flat source. The error of each setting against
//! the Monte Carlo reference is in the crate docs (`canonical` example for timings with
//! errors side by side); `cargo run --release -p lightgrid-measure --example throughput` is the
//! quick version of this.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lightgrid_core::glam::UVec3;
use lightgrid_core::{GridDesc, MaterialGrid, Outputs, SweepOptions, Sweeper};
use lightgrid_measure::scenes::Scene;

fn bench(c: &mut Criterion) {
    let (m, b) = Scene::Canopy.build(64);
    let d = *m.desc();
    let small_desc = GridDesc::new(d.origin(), d.h(), UVec3::new(16, 64, 16)).expect("valid");
    let small = MaterialGrid::new(
        small_desc,
        (0..small_desc.point_count())
            .map(|i| {
                *m.get(small_desc.coords(i).expect("in range"))
                    .expect("inside")
            })
            .collect(),
    )
    .expect("valid");
    for (group, m, outputs_list) in [
        (
            "sweep 64³ canopy",
            &m,
            vec![
                ("26 bins", Outputs::ALL),
                ("average only", Outputs::AVERAGE_DOMINANT),
            ],
        ),
        (
            "sweep 16×64×16 canopy",
            &small,
            vec![("26 bins", Outputs::ALL)],
        ),
    ] {
        let mut g = c.benchmark_group(group);
        g.throughput(Throughput::Elements(m.desc().point_count() as u64));
        g.sample_size(10);
        for (name, outputs) in outputs_list {
            for (passes_name, passes) in [("1 pass", 1), ("4 passes", 4)] {
                let mut o = SweepOptions::multi_bounce();
                o.outputs = outputs;
                o.max_passes = passes;
                o.tolerance = 0.0;
                let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
                g.bench_function(format!("{name}, {passes_name}, recycled"), |bch| {
                    bch.iter(|| {
                        let out = sweeper.sweep(m, &b, &o).expect("sweep");
                        sweeper.recycle(out);
                    })
                });
                g.bench_function(format!("{name}, {passes_name}"), |bch| {
                    bch.iter(|| lightgrid_sweep_cpu::run(m, &b, &o).expect("sweep"))
                });
                g.bench_function(format!("{name}, {passes_name}, scalar oracle"), |bch| {
                    bch.iter(|| {
                        lightgrid_sweep_cpu::sweep::run_scalar(m, &b, None, &o).expect("sweep")
                    })
                });
            }
        }
        g.finish();
    }
    // The horizon halves beside the bins (`Outputs::horizon`: a third more memory),
    // against "26 bins, 4 passes" above.
    let mut g = c.benchmark_group("sweep 64³ canopy");
    g.throughput(Throughput::Elements(m.desc().point_count() as u64));
    g.sample_size(10);
    let mut o = SweepOptions::multi_bounce();
    o.outputs = Outputs::ALL.with_horizon();
    o.max_passes = 4;
    o.tolerance = 0.0;
    let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
    g.bench_function("26 bins and horizon halves, 4 passes, recycled", |bch| {
        bch.iter(|| {
            let out = sweeper.sweep(&m, &b, &o).expect("sweep");
            sweeper.recycle(out);
        })
    });
    g.finish();
}

/// Media in every level (the uniform fog, 16³ and 48³, 4 passes): where phases 2 and
/// 3 dominate, as in the bench forest's foliage (`cargo run --release -p xtask --example
/// forest_profile` times the forest itself).
fn bench_media(c: &mut Criterion) {
    let mut g = c.benchmark_group("sweep uniform fog, 4 passes");
    g.sample_size(10);
    for n in [16u32, 48] {
        let (m, b) = Scene::UniformFog.build(n);
        g.throughput(Throughput::Elements(m.desc().point_count() as u64));
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = 4;
        o.tolerance = 0.0;
        let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
        g.bench_function(format!("{n}³, recycled"), |bch| {
            bch.iter(|| {
                let out = sweeper.sweep(&m, &b, &o).expect("sweep");
                sweeper.recycle(out);
            })
        });
        // The flat source (the option), against the default quadratic source in height.
        let mut flat = o;
        flat.medium = lightgrid_core::MediumEmission::Source;
        g.bench_function(format!("{n}³, recycled, flat source"), |bch| {
            bch.iter(|| {
                let out = sweeper.sweep(&m, &b, &flat).expect("sweep");
                sweeper.recycle(out);
            })
        });
        g.bench_function(format!("{n}³, scalar oracle"), |bch| {
            bch.iter(|| lightgrid_sweep_cpu::sweep::run_scalar(&m, &b, None, &o).expect("sweep"))
        });
    }
    g.finish();
}

criterion_group!(benches, bench, bench_media);
criterion_main!(benches);
