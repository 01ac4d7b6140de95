// Sun transmittance by exact DDA march, one thread per point: lightgrid_sweep_cpu::sun::
// SunTransmittance::march (lightgrid_core::dda::{exit, cross}) step for step, periodic
// sides wrapping, with a constant transmittance where the ray leaves the grid.

@group(0) @binding(0) var<uniform> params: SunParams;
// Pass-through per cell, grid order.
@group(0) @binding(1) var<storage, read> cell_pass: array<f32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

const BIG: f32 = 3.0e38;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    let periodic = params.dims.w == 1u;
    let i = gid.x;
    if (i >= d.x * d.y * d.z) {
        return;
    }
    let dir = params.dir_outside.xyz;
    let outside = params.dir_outside.w;
    let di = vec3<i32>(d);
    var cell = vec3<i32>(vec3<u32>(i % d.x, i / (d.x * d.z), (i / d.x) % d.z));
    var pos = vec3<f32>(cell);
    var log_t = 0.0;
    let max_steps = params.steps.x;
    for (var n = 0u; n < max_steps; n++) {
        let p = cell_pass[u32(cell.x) + d.x * (u32(cell.z) + d.z * u32(cell.y))];
        // dda::exit
        var s = BIG;
        var axis = 0u;
        for (var k = 0u; k < 3u; k++) {
            var t = BIG;
            if (dir[k] > 0.0) {
                t = (f32(cell[k]) + 0.5 - pos[k]) / dir[k];
            } else if (dir[k] < 0.0) {
                t = (f32(cell[k]) - 0.5 - pos[k]) / dir[k];
            }
            t = max(t, 0.0);
            if (t < s) {
                s = t;
                axis = k;
            }
        }
        if (s > 0.0) {
            if (p <= 0.0) {
                out[i] = 0.0;
                return;
            }
            log_t += s * log(p);
            if (log_t < -60.0) {
                out[i] = 0.0;
                return;
            }
        }
        pos += dir * s;
        // dda::cross
        var step = -1;
        if (dir[axis] > 0.0) {
            step = 1;
        }
        pos[axis] = f32(cell[axis]) + 0.5 * f32(step);
        cell[axis] += step;
        if (cell[axis] >= 0 && cell[axis] < di[axis]) {
            continue;
        }
        if (axis == 1u || !periodic) {
            out[i] = exp(log_t) * outside;
            return;
        }
        // Wrap to the opposite side.
        cell[axis] = wrap_index(cell[axis], di[axis]);
        pos[axis] -= f32(step) * f32(di[axis]);
    }
    out[i] = exp(log_t) * outside;
}
