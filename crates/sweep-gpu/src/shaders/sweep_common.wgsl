// Shared by both sweep phases. `struct LevelParams` and the sizes are generated in wgsl.rs.

fn column(x: i32, z: i32) -> i32 {
    let nx = i32(P.nx);
    let nz = i32(P.nz);
    if (P.periodic == 1u) {
        let wx = wrap_index(x, nx);
        let wz = wrap_index(z, nz);
        return wx + nx * wz;
    }
    if (x < 0 || x >= nx || z < 0 || z >= nz) {
        return -1;
    }
    return x + nx * z;
}

// Light `v` of bin `bin` at point `gi`; a downward pass's horizontal light also into the
// horizon halves after the bins (lightgrid_core::HorizonLight), when asked for.
fn g_add(gi: u32, bin: u32, v: vec3<f32>) {
    let i = (gi * NUM_DIRS + bin) * 3u;
    g[i] += v.x;
    g[i + 1u] += v.y;
    g[i + 2u] += v.z;
    if (P.horizon == 1u && P.up == 0u && bin >= FIRST_HORIZONTAL
        && bin < FIRST_HORIZONTAL + HORIZONTAL_BINS) {
        let k = P.horizon_base + (gi * HORIZONTAL_BINS + bin - FIRST_HORIZONTAL) * 3u;
        g[k] += v.x;
        g[k + 1u] += v.y;
        g[k + 2u] += v.z;
    }
}

// Transmittance p^e of a path fraction through a cell of pass-through p.
fn trans(pass_through: f32, e: f32) -> f32 {
    if (pass_through >= 1.0) {
        return 1.0;
    }
    if (pass_through <= 0.0) {
        return 0.0;
    }
    return exp(e * log(pass_through));
}

// Mean over a segment of optical depth x (transmittance tr = e^-x) of the transmittance
// from its start, (1 - tr) / x: a point's light is the mean of its path's light over its
// own cell's segment (lightgrid_sweep_cpu::sweep::seg_mean, from the depth: right where tr
// underflows).
fn seg_mean(tr: f32, x: f32) -> f32 {
    if (!(x > 0.0)) {
        return 1.0;
    }
    if (x < 0.02) {
        return 1.0 - x * (0.5 - x * (1.0 / 6.0 - x / 24.0));
    }
    return (1.0 - tr) / x;
}

// Optical depth of a path fraction e through a cell of pass-through p (infinite for an
// opaque cell).
fn depth(pass_through: f32, e: f32) -> f32 {
    if (pass_through >= 1.0) {
        return 0.0;
    }
    if (pass_through <= 0.0) {
        return 1e30;
    }
    return -e * log(pass_through);
}
