//! The GPU sweeper on grids the size of the hierarchy's nodes, where a sweep's fixed
//! costs (buffers, bind groups, dispatches, the wait and the readback) outweigh its
//! arithmetic: the median of 20 sweeps after 3 warm-ups, split into upload, compute and
//! readback, beside the CPU sweeper on the same grid.
//!
//! `cargo run --release -p lightgrid-sweep-gpu --example node_sweep`

use std::time::{Duration, Instant};

use lightgrid_core::SweepOptions;
use lightgrid_measure::scenes::Scene;
use lightgrid_sweep_gpu::GpuSweeper;

fn median(mut v: Vec<Duration>) -> f64 {
    v.sort();
    v[v.len() / 2].as_secs_f64() * 1e3
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let gpu = GpuSweeper::new()?;
    let info = &gpu.context().info;
    println!(
        "GPU: {} ({:?}, {:?})",
        info.name, info.device_type, info.backend
    );
    for n in [8u32, 16, 32] {
        let (m, b) = Scene::Canopy.build(n);
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = 4;
        o.tolerance = 0.0;
        for _ in 0..3 {
            gpu.run_timed(&m, &b, &o)?;
        }
        let (mut up, mut comp, mut read, mut total, mut cpu) =
            (vec![], vec![], vec![], vec![], vec![]);
        for _ in 0..20 {
            let t0 = Instant::now();
            let (_, t) = gpu.run_timed(&m, &b, &o)?;
            total.push(t0.elapsed());
            up.push(t.upload);
            comp.push(t.compute);
            read.push(t.readback);
            let t0 = Instant::now();
            lightgrid_sweep_cpu::run(&m, &b, &o)?;
            cpu.push(t0.elapsed());
        }
        let points = m.desc().point_count() as f64;
        let (total, cpu) = (median(total), median(cpu));
        println!(
            "{n}³ canopy, 4 passes: gpu {total:.2} ms (upload {:.2}, compute {:.2}, readback {:.2}; {:.2} M points/s), cpu {cpu:.2} ms ({:.2} M points/s)",
            median(up),
            median(comp),
            median(read),
            points / total / 1e3,
            points / cpu / 1e3,
        );
    }
    Ok(())
}
