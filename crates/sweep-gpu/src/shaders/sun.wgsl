// Sun transmittance by exact DDA march, one thread per point: sweep_cpu::sun::
// SunTransmittance::march (and lightgrid_core::dda::{exit, cross, walk_segment}) step
// for step, with a constant transmittance where the ray leaves the grid's box.

@group(0) @binding(0) var<uniform> params: SunParams;
// Pass-through per cell, grid order.
@group(0) @binding(1) var<storage, read> cell_pass: array<f32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

const BIG: f32 = 3.0e38;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    let i = gid.x;
    if (i >= d.x * d.y * d.z) {
        return;
    }
    let c = vec3<u32>(i % d.x, i / (d.x * d.z), (i / d.x) % d.z);
    let dir = params.dir_outside.xyz;
    let a = vec3<f32>(c);
    let dims = vec3<f32>(d);
    // exit_distance: to the box [-0.5, dims - 0.5].
    var len = BIG;
    for (var k = 0u; k < 3u; k++) {
        if (dir[k] > 0.0) {
            len = min(len, max((dims[k] - 0.5 - a[k]) / dir[k], 0.0));
        } else if (dir[k] < 0.0) {
            len = min(len, max((-0.5 - a[k]) / dir[k], 0.0));
        }
    }
    // walk_segment from a (inside the box) over len.
    var pos = a;
    var cell = vec3<i32>(c);
    var left = len;
    var log_t = 0.0;
    var blocked = false;
    let di = vec3<i32>(d);
    loop {
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
        let idx = u32(cell.x) + d.x * (u32(cell.z) + d.z * u32(cell.y));
        let p = cell_pass[idx];
        let l = min(s, left);
        if (l > 0.0) {
            if (p <= 0.0) {
                blocked = true;
                break;
            }
            log_t += l * log(p);
        }
        if (s >= left) {
            break;
        }
        left -= s;
        pos += dir * s;
        // dda::cross
        var step = -1;
        if (dir[axis] > 0.0) {
            step = 1;
        }
        pos[axis] = f32(cell[axis]) + 0.5 * f32(step);
        cell[axis] += step;
        if (any(cell < vec3<i32>(0)) || any(cell >= di)) {
            break;
        }
    }
    if (blocked) {
        out[i] = 0.0;
    } else {
        out[i] = exp(log_t) * params.dir_outside.w;
    }
}
