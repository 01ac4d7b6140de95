//! The sweep's results do not depend on the CPU features a build targets: this
//! workspace builds for x86-64-v3 (`.cargo/config.toml`: AVX2 and FMA, eight floats a
//! vector), and the outputs must equal, bit for bit, those of a baseline x86-64 build
//! (SSE2, four). They do because Rust never fuses a multiply and an add, nor reorders
//! float sums, by itself: wider vectors run the same operations in the same order.
//!
//! The table below holds the hashes ([`ContentHash`] of the bins, average light and
//! dominant direction) that a baseline build gives for the five test scenes at 12³, one
//! and four passes, both medium rules. A sweep whose semantics change on purpose
//! changes them: run `RUSTFLAGS= cargo test -p sweep-cpu --test build_flags` (an empty
//! `RUSTFLAGS` replaces the config's flags: the baseline build), which fails and prints
//! the new table, and paste it here. Only on x86-64 Linux, where the table was made
//! (the sweep calls the C library's `expf`; another libm may round differently).
#![cfg(all(target_arch = "x86_64", target_os = "linux"))]

use lightgrid_core::hash::ContentHash;
use lightgrid_core::{MediumEmission, Outputs, SweepOptions, Sweeper};
use sweep_cpu::scenes::Scene;

/// (scene, passes, medium rule, hash) from a baseline build.
const BASELINE: &[(&str, u32, &str, u64)] = &[
    ("empty", 1, "profile", 0xeb694ebdb12aeee1),
    ("empty", 1, "source", 0xeb694ebdb12aeee1),
    ("empty", 4, "profile", 0xeb694ebdb12aeee1),
    ("empty", 4, "source", 0xeb694ebdb12aeee1),
    ("uniform fog", 1, "profile", 0x0ec2870f03adade1),
    ("uniform fog", 1, "source", 0xc35bf7c595bcbe01),
    ("uniform fog", 4, "profile", 0x22ea516f27cbdf21),
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
                let s = sweep_cpu::CpuSweeper::new().sweep(&m, &b, &o).unwrap();
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

#[test]
fn outputs_equal_a_baseline_builds_bit_for_bit() {
    let got = hashes();
    if got != BASELINE {
        let table: String = got
            .iter()
            .map(|(s, p, r, h)| format!("    ({s:?}, {p}, {r:?}, 0x{h:016x}),\n"))
            .collect();
        panic!(
            "the sweep's outputs differ from the baseline build's (a build flag changed a \
             result, or the semantics changed: see this file's docs). This build's table:\n\
             {table}"
        );
    }
}
