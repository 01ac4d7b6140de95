//! The memory side of the sweep's roofline (the crate docs, "Roofline"): how long this
//! machine takes, on every core, to write, to read-modify-write and to read a 64³
//! grid's 26-bin output (82 MB of `f32`), the traffic a pass has with the output.
//! `cargo run --release -p lightgrid-measure --example memory_floor`
use rayon::prelude::*;
use std::time::Instant;

fn main() {
    let n = 64 * 64 * 64 * 78;
    let row = 64 * 78;
    let mut v = vec![1.0f32; n];
    let best = |f: &mut dyn FnMut()| {
        (0..20)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e3
            })
            .fold(f64::INFINITY, f64::min)
    };
    let write = best(&mut || v.par_chunks_mut(row).for_each(|c| c.fill(0.5)));
    let rmw = best(&mut || {
        v.par_chunks_mut(row)
            .for_each(|c| c.iter_mut().for_each(|x| *x += 1.0))
    });
    // Eight lanes, so that the adds vectorise and the read is what is timed.
    let mut total = 0.0;
    let read = best(&mut || {
        total += v
            .par_chunks(row)
            .map(|c| {
                let mut l = [0f32; 8];
                for ch in c.chunks_exact(8) {
                    for i in 0..8 {
                        l[i] += ch[i];
                    }
                }
                l.iter().sum::<f32>()
            })
            .sum::<f32>();
    });
    let mb = (n * 4) as f64 / 1e6;
    println!(
        "{mb:.0} MB on {} threads, fastest of 20: write {write:.2} ms, read-modify-write \
         {rmw:.2} ms, read {read:.2} ms (checksum {total:e})",
        rayon::current_num_threads()
    );
}
