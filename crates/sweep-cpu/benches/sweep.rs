//! Points per second of the sweep on a 64³ grid: 26-bin and average-only outputs, one
//! downward pass and repeated down/up passes. The error of each setting against the
//! Monte Carlo reference is in the crate docs (`canonical` example for timings with
//! errors side by side).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lightgrid_core::{Outputs, SweepOptions};
use sweep_cpu::scenes::Scene;

fn bench(c: &mut Criterion) {
    let (m, b) = Scene::Canopy.build(64);
    let mut g = c.benchmark_group("sweep 64³ canopy");
    g.throughput(Throughput::Elements(m.desc().point_count() as u64));
    g.sample_size(10);
    for (name, outputs) in [
        ("26 bins", Outputs::ALL),
        ("average only", Outputs::AVERAGE_DOMINANT),
    ] {
        for (passes_name, passes) in [("1 pass", 1), ("4 passes", 4)] {
            let mut o = SweepOptions::multi_bounce();
            o.outputs = outputs;
            o.max_passes = passes;
            o.tolerance = 0.0;
            g.bench_function(format!("{name}, {passes_name}"), |bch| {
                bch.iter(|| sweep_cpu::run(&m, &b, &o).expect("sweep"))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
