//! R11G11B10 on the GPU equals grid-core's packing bit for bit. Runs on any adapter
//! (lavapipe in CI); fails without one unless LIGHTGRID_ALLOW_NO_GPU=1.

use lightgrid_core::glam::Vec3;
use lightgrid_core::pack::{pack_r11g11b10, uf10_to_f32, uf11_to_f32};
use lightgrid_sweep_gpu::{GpuContext, GpuPacker};

fn context() -> Option<GpuContext> {
    GpuContext::new_for_tests()
}

#[test]
fn gpu_packing_is_bit_exact() {
    let Some(ctx) = context() else { return };
    let packer = GpuPacker::new(&ctx);
    // Every finite 11-bit and 10-bit code value, their midpoints (ties), and specials.
    let mut values = Vec::new();
    for code in 0..(31u32 << 6) {
        let v = uf11_to_f32(code);
        let next = uf11_to_f32(code + 1);
        values.push(Vec3::new(v, v, uf10_to_f32(code >> 1)));
        if next.is_finite() {
            values.push(Vec3::splat((v + next) * 0.5));
        }
    }
    for special in [
        0.0,
        -0.0,
        -1.0,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1e-40,
        65024.0,
        65025.0,
        1e30,
        f32::MAX,
    ] {
        values.push(Vec3::splat(special));
    }
    let mut s = 12345u32;
    for _ in 0..20_000 {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        values.push(Vec3::new(
            f32::from_bits(s >> 1),
            (s % 1000) as f32 * 0.37,
            (s >> 8) as f32 * 1e-9,
        ));
    }
    let words = packer.pack(&ctx, &values, 1.0).unwrap();
    assert_eq!(words.len(), values.len());
    for (v, w) in values.iter().zip(&words) {
        assert_ne!(*w, u32::MAX, "unwritten output for {v}");
        assert_eq!(*w, pack_r11g11b10(*v), "value {v:?}");
    }
    // The exposure is applied before packing.
    let words = packer
        .pack(&ctx, &[Vec3::splat(1e6)], 2f32.powi(-4))
        .unwrap();
    assert_eq!(words[0], pack_r11g11b10(Vec3::splat(1e6 * 2f32.powi(-4))));
}
