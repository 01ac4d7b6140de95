// R11G11B10 packing, bit for bit as lightgrid_core::pack (round to nearest even, negative and
// NaN to 0, overflow and +inf saturated to the largest finite value, denormals).

fn encode_ufloat(x: f32, mant: u32) -> u32 {
    let max_code = (30u << mant) | ((1u << mant) - 1u);
    // Also false for NaN.
    if (!(x > 0.0)) {
        return 0u;
    }
    let bits = bitcast<u32>(x);
    let exp_bits = (bits >> 23u) & 0xffu;
    if (exp_bits == 0xffu) {
        return max_code;
    }
    if (exp_bits == 0u) {
        return 0u;
    }
    let sig = (bits & 0x7fffffu) | 0x800000u;
    let e = i32(exp_bits) - 127 + 15;
    var shift = 23 - i32(mant);
    if (e < 1) {
        shift = shift + 1 - e;
    }
    if (shift > 25) {
        return 0u;
    }
    let s = u32(shift);
    let kept = sig >> s;
    let rem = sig & ((1u << s) - 1u);
    let half = 1u << (s - 1u);
    var code = kept;
    if (e >= 1) {
        code = (u32(e) << mant) | (kept & ((1u << mant) - 1u));
    }
    if (rem > half || (rem == half && (code & 1u) == 1u)) {
        code = code + 1u;
    }
    return min(code, max_code);
}

fn pack_r11g11b10(c: vec3<f32>) -> u32 {
    return encode_ufloat(c.x, 6u) | (encode_ufloat(c.y, 6u) << 11u) | (encode_ufloat(c.z, 5u) << 22u);
}
