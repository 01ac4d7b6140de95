//! The sweep's results do not depend on the vector instructions its row kernels run on:
//! they are compiled for the baseline (SSE2, four floats a vector) and for x86-64-v3
//! (AVX2 and FMA, eight), chosen at run time (`lightgrid_sweep_cpu::isa`), and both
//! paths must give, bit for bit, the same outputs. They do because Rust never fuses a
//! multiply and an add, nor reorders float sums, by itself: wider vectors run the same
//! operations in the same order.
//!
//! The table below holds the hashes ([`ContentHash`] of the bins, average light and
//! dominant direction) for the five test scenes at 12³, one and four passes, both medium
//! rules; each test checks one path against it. A sweep whose semantics change on
//! purpose changes them: the test fails and prints the new table, to paste here (the fog's
//! medium is thinner than the profile rule's least depth, so its two rules agree; the
//! canopies' and the dense block's are thicker). Only
//! on x86-64 Linux, where the table was made (the sweep calls the C library's `expf`;
//! another libm may round differently).
#![cfg(all(target_arch = "x86_64", target_os = "linux"))]

use lightgrid_core::hash::ContentHash;
use lightgrid_core::{MediumEmission, Outputs, SweepOptions, Sweeper};
use lightgrid_measure::scenes::Scene;

/// (scene, passes, medium rule, hash), the same on every path.
const BASELINE: &[(&str, u32, &str, u64)] = &[
    ("empty", 1, "profile", 0xeb694ebdb12aeee1),
    ("empty", 1, "source", 0xeb694ebdb12aeee1),
    ("empty", 4, "profile", 0xeb694ebdb12aeee1),
    ("empty", 4, "source", 0xeb694ebdb12aeee1),
    ("uniform fog", 1, "profile", 0xc35bf7c595bcbe01),
    ("uniform fog", 1, "source", 0xc35bf7c595bcbe01),
    ("uniform fog", 4, "profile", 0x68c7b981d101e9e1),
    ("uniform fog", 4, "source", 0x68c7b981d101e9e1),
    ("dense block", 1, "profile", 0x6dee1426540b7e85),
    ("dense block", 1, "source", 0x7c09ee941c5e64c5),
    ("dense block", 4, "profile", 0xe88b37bb5480647d),
    ("dense block", 4, "source", 0xbd28b5a5c2fd71cf),
    ("canopy", 1, "profile", 0x711fced58077e101),
    ("canopy", 1, "source", 0xfb65524714fcade1),
    ("canopy", 4, "profile", 0xba0cb3411e3822a1),
    ("canopy", 4, "source", 0x6e7901ec4de89061),
    ("canopy, 1-level ground", 1, "profile", 0x53ab3616eff05381),
    ("canopy, 1-level ground", 1, "source", 0xe75965c5d77f03c1),
    ("canopy, 1-level ground", 4, "profile", 0x98610ba74a0068c1),
    ("canopy, 1-level ground", 4, "source", 0x7c17f7bc03809101),
];

fn hashes() -> Vec<(&'static str, u32, &'static str, u64)> {
    let mut out = Vec::new();
    for scene in Scene::ALL {
        let (m, b) = scene.build(12);
        for passes in [1, 4] {
            for (rule, medium) in [
                ("profile", MediumEmission::Profile),
                ("source", MediumEmission::Source),
            ] {
                let mut o = SweepOptions::multi_bounce();
                o.outputs = Outputs::ALL;
                o.max_passes = passes;
                o.tolerance = 0.0;
                o.medium = medium;
                let s = lightgrid_sweep_cpu::CpuSweeper::new()
                    .sweep(&m, &b, &o)
                    .unwrap();
                let mut h = ContentHash::new(b"build-flags-v1");
                for b in s.bins.as_ref().unwrap().data() {
                    h.bins(b);
                }
                for a in s.average.as_ref().unwrap().data() {
                    h.vec3(a.0);
                }
                for d in s.dominant.as_ref().unwrap().data() {
                    h.vec3(d.0);
                }
                out.push((scene.name(), passes, rule, h.finish()));
            }
        }
    }
    out
}

/// Fails with this path's table if it differs from [`BASELINE`].
fn check(path: &str) {
    let got = hashes();
    if got != BASELINE {
        let table: String = got
            .iter()
            .map(|(s, p, r, h)| format!("    ({s:?}, {p}, {r:?}, 0x{h:016x}),\n"))
            .collect();
        panic!(
            "the sweep's outputs on the {path} path differ from the table (a vector path \
             changed a result, or the semantics changed: see this file's docs). This \
             path's table:\n{table}"
        );
    }
}

/// One test for both paths: the choice is process-wide, and tests run in parallel.
#[test]
fn every_vector_path_gives_the_same_outputs_bit_for_bit() {
    use lightgrid_sweep_cpu::isa::{VectorIsa, force_baseline, vector_isa};
    let widest = vector_isa();
    eprintln!("this CPU's widest path: {widest:?}");
    check(&format!("{widest:?}"));
    force_baseline(true);
    assert_eq!(vector_isa(), VectorIsa::Baseline);
    check("baseline");
    force_baseline(false);
    // On a CPU without AVX2 both checks ran the baseline: say so rather than pass in
    // silence as if both paths had been compared.
    if widest == VectorIsa::Baseline && std::env::var("LIGHTGRID_SIMD").is_err() {
        eprintln!("note: this CPU has no x86-64-v3; only the baseline path was checked");
    }
}
