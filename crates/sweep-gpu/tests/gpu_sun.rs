//! The GPU sun march equals sweep-cpu's `SunTransmittance::march` (the specification,
//! with its own known-answer tests) on random media, sun directions and outside values.
//! Runs on any adapter (lavapipe in CI); fails without one unless LIGHTGRID_ALLOW_NO_GPU=1.

use std::sync::Arc;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{Grid, GridDesc, Material, MaterialGrid};
use lightgrid_sweep_cpu::SunTransmittance;
use lightgrid_sweep_gpu::{GpuContext, GpuSunTransmittance};
use proptest::prelude::*;

fn march() -> Option<&'static GpuSunTransmittance> {
    static S: std::sync::OnceLock<Option<GpuSunTransmittance>> = std::sync::OnceLock::new();
    S.get_or_init(|| GpuContext::new_for_tests().map(|c| GpuSunTransmittance::new(Arc::new(c))))
        .as_ref()
}

fn grid(dims: UVec3, seed: u64) -> MaterialGrid {
    let desc = GridDesc::new(Vec3::new(2.0, -1.0, 0.5), 0.75, dims).unwrap();
    let mut r = fastrand::Rng::with_seed(seed);
    let data = (0..desc.point_count())
        .map(|_| Material {
            reflectance: Vec3::splat(0.5),
            pass: match r.u32(0..5) {
                0 => 0.0,
                1 | 2 => 1.0,
                _ => r.f32(),
            },
        })
        .collect();
    Grid::new(desc, data).unwrap()
}

/// |gpu - cpu| <= 1e-4 of the larger plus 1e-6: the GPU's `log` and `exp` differ from
/// the CPU's in the last bits, and a long path sums many of them.
fn close(cpu: &SunTransmittance, gpu: &SunTransmittance) -> Result<(), String> {
    for (i, (a, b)) in cpu.values().iter().zip(gpu.values()).enumerate() {
        if (a - b).abs() > 1e-4 * a.max(*b) + 1e-6 {
            return Err(format!("point {i}: cpu {a} gpu {b}"));
        }
    }
    Ok(())
}

#[test]
fn canopy_at_several_suns_matches_the_cpu() {
    let Some(gpu) = march() else { return };
    let (m, _) = lightgrid_measure::scenes::Scene::Canopy.build(24);
    for to_sun in [
        Vec3::Y,
        Vec3::new(0.766, 0.643, 0.0),
        Vec3::new(0.5, 0.3, -0.81),
        Vec3::new(-0.9, 0.17, 0.4),
        Vec3::new(0.2, -0.1, 0.0),
    ] {
        for periodic in [false, true] {
            let cpu = SunTransmittance::march(&m, to_sun, periodic, &|_| 1.0).unwrap();
            let g = gpu.march(&m, to_sun, periodic, 1.0).unwrap();
            close(&cpu, &g).unwrap_or_else(|e| panic!("{to_sun} periodic {periodic}: {e}"));
        }
        let cpu = SunTransmittance::march(&m, to_sun, false, &|_| 1.0).unwrap();
        // Shadows exist (not all 1) unless the sun is below the horizon (all 0).
        let lit = cpu.values().iter().filter(|&&v| v > 0.99).count();
        if to_sun.y > 0.0 {
            assert!(lit > 0 && lit < cpu.values().len(), "{to_sun}: {lit}");
        } else {
            assert_eq!(lit, 0);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn random_media_match_the_cpu(
        dims in (1u32..12, 1u32..10, 1u32..12),
        seed in any::<u64>(),
        sun in (-1.0f32..1.0, 0.02f32..1.0, -1.0f32..1.0),
        outside in 0.0f32..=1.0,
        periodic in any::<bool>(),
    ) {
        let Some(gpu) = march() else { return Ok(()) };
        let m = grid(UVec3::new(dims.0, dims.1, dims.2), seed);
        let to_sun = Vec3::new(sun.0, sun.1, sun.2);
        let cpu = SunTransmittance::march(&m, to_sun, periodic, &move |_| outside).unwrap();
        let g = gpu.march(&m, to_sun, periodic, outside).unwrap();
        prop_assert!(close(&cpu, &g).is_ok(), "{}", close(&cpu, &g).unwrap_err());
    }
}
