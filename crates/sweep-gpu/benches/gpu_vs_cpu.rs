//! Points per second of the GPU sweep beside the CPU sweep on the same grid, and where the
//! GPU's time goes (upload, compute, readback). On the CI machine the "GPU" is lavapipe,
//! Mesa's software Vulkan on the same two CPU cores.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lightgrid_core::SweepOptions;
use lightgrid_measure::scenes::Scene;
use lightgrid_sweep_gpu::GpuSweeper;

fn bench(c: &mut Criterion) {
    let gpu = match GpuSweeper::new() {
        Ok(g) => g,
        Err(e) => {
            eprintln!("!!! GPU BENCH NOT RUN: {e} !!!");
            return;
        }
    };
    let info = &gpu.context().info;
    eprintln!(
        "GPU: {} ({:?}, {:?})",
        info.name, info.device_type, info.backend
    );
    for n in [32u32, 64] {
        let (m, b) = Scene::Canopy.build(n);
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = 4;
        o.tolerance = 0.0;
        let (_, t) = gpu.run_timed(&m, &b, &o).expect("gpu sweep");
        eprintln!(
            "{n}³, 4 passes: upload {:.1} ms, compute {:.1} ms, readback {:.1} ms",
            t.upload.as_secs_f64() * 1e3,
            t.compute.as_secs_f64() * 1e3,
            t.readback.as_secs_f64() * 1e3
        );
        let mut g = c.benchmark_group(format!("sweep {n}³ canopy, 4 passes"));
        g.sample_size(10);
        g.throughput(Throughput::Elements(m.desc().point_count() as u64));
        g.bench_function("cpu", |bch| {
            bch.iter(|| lightgrid_sweep_cpu::run(&m, &b, &o).expect("cpu sweep"))
        });
        g.bench_function("gpu (upload + compute + readback)", |bch| {
            bch.iter(|| gpu.run(&m, &b, &o).expect("gpu sweep"))
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
