//! scratch
use rayon::prelude::*;
use std::time::Instant;
fn main() {
    let n = 64 * 64 * 64 * 78;
    let mut v = vec![1.0f32; n];
    let best = |f: &mut dyn FnMut()| {
        let mut b = f64::INFINITY;
        for _ in 0..20 {
            let t = Instant::now();
            f();
            b = b.min(t.elapsed().as_secs_f64());
        }
        b * 1e3
    };
    let chunk = 64 * 78;
    let w = best(&mut || v.par_chunks_mut(chunk).for_each(|c| c.fill(0.5)));
    let rmw = best(&mut || {
        v.par_chunks_mut(chunk)
            .for_each(|c| c.iter_mut().for_each(|x| *x += 1.0))
    });
    let mut s = 0.0;
    let r = best(&mut || {
        s += v
            .par_chunks(chunk)
            .map(|c| c.iter().sum::<f32>())
            .sum::<f32>()
    });
    println!("82 MB: write {w:.2} ms, read-modify-write {rmw:.2} ms, read {r:.2} ms ({s})");
}
