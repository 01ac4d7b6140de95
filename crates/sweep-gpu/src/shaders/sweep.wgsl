// The sweep of sweep-cpu (its crate docs are the specification), one level per dispatch
// pair: `phase1` (gather, transmit, record removals) then `phase2` (collect, absorb,
// emit, re-absorb). Channel tables are read through the generated accessors
// (`ch_mu(c)`, ...) from `tables` (`crate::wgsl::table_floats`).


@group(0) @binding(0) var<storage, read> P: LevelParams;
@group(0) @binding(1) var<storage, read> cells: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> prev: array<f32>;
@group(0) @binding(3) var<storage, read_write> cur: array<f32>;
@group(0) @binding(4) var<storage, read_write> scratch: array<f32>;
@group(0) @binding(5) var<storage, read_write> g: array<f32>;
@group(0) @binding(6) var<storage, read> virt: array<f32>;
@group(0) @binding(7) var<storage, read> halo: array<f32>;
@group(0) @binding(8) var<storage, read_write> aux: array<f32>;
@group(0) @binding(9) var<storage, read> tables: array<f32, TABLE_FLOATS>;

fn load3(i: u32) -> vec3<f32> {
    return vec3<f32>(prev[i], prev[i + 1u], prev[i + 2u]);
}

fn virt_at(x: i32, z: i32, c: u32) -> vec3<f32> {
    let w = u32(i32(P.nx) + 2 * HALO_WIDTH);
    let i = ((u32(z + HALO_WIDTH) * w + u32(x + HALO_WIDTH)) * CH + c) * 3u;
    return vec3<f32>(virt[i], virt[i + 1u], virt[i + 2u]);
}

// Index of outside point (x, level, z) in the halo (lightgrid_core::HaloLayout).
fn halo_index(x: i32, level: u32, z: i32) -> u32 {
    let w = HALO_WIDTH;
    let nx = i32(P.nx);
    let nz = i32(P.nz);
    let width = u32(nx + 2 * w);
    let per_level = width * u32(nz + 2 * w) - u32(nx * nz);
    let row = u32(z + w);
    let col = u32(x + w);
    var before = 0u;
    if (z < 0) {
        before = row * width + col;
    } else if (z < nz) {
        var c = col;
        if (x >= 0) {
            c = col - u32(nx);
        }
        before = u32(w) * width + u32(z) * 2u * u32(w) + c;
    } else {
        before = u32(w) * width + u32(nz) * 2u * u32(w) + u32(z - nz) * width + col;
    }
    return level * per_level + before;
}

fn outside(x: i32, z: i32, c: u32) -> vec3<f32> {
    if (P.given == 1u) {
        let level = u32(clamp(P.src_level, 0, i32(P.ny) - 1));
        let i = (halo_index(x, level, z) * CH + c) * 3u;
        return vec3<f32>(halo[i], halo[i + 1u], halo[i + 2u]);
    }
    return virt_at(x, z, c);
}

fn ch_bin(c: u32) -> u32 {
    if (P.up == 1u) {
        return ch_bin_up(c);
    }
    return ch_bin_down(c);
}

fn ch_unit(c: u32) -> vec3<f32> {
    return dir_unit(ch_bin(c));
}

@compute @workgroup_size(64)
fn phase1(@builtin(global_invocation_id) id: vec3<u32>) {
    let li = id.x;
    if (li >= P.level_len) {
        return;
    }
    let x = i32(li % P.nx);
    let z = i32(li / P.nx);
    let gi = li + P.level_len * P.j;
    var flux_in = vec3<f32>(0.0);
    for (var c = 0u; c < CH; c++) {
        // Step 1: gather from the source point and its smoothing taps.
        let st = ch_step(c);
        let qx = x - st.x;
        let qz = z - st.y;
        let s = P.smoothing;
        var ins = vec3<f32>(0.0);
        var outs = vec3<f32>(0.0);
        for (var t = 0u; t < 5u; t++) {
            var tx = qx;
            var tz = qz;
            var w = 0.25 * s;
            switch t {
                case 0u: { w = 1.0 - s; }
                case 1u: { tx = qx + 1; }
                case 2u: { tx = qx - 1; }
                case 3u: { tz = qz + 1; }
                default: { tz = qz - 1; }
            }
            if (w == 0.0) {
                continue;
            }
            let col = column(tx, tz);
            if (col >= 0) {
                ins += load3((u32(col) * CH + c) * 3u) * w;
            } else if (P.from_virtual == 1u) {
                // Beyond the sides too, given or not (sweep-cpu's `fill_ghost`).
                outs += virt_at(tx, tz, c) * w;
            } else {
                outs += outside(tx, tz, c) * w;
            }
        }
        if (P.from_virtual == 1u) {
            flux_in += ins * ch_mu(c);
        }
        flux_in += outs * ch_mu(c);
        let light = ins + outs;
        // Step 2: transmit along the path, recording what each cell removes.
        var t = 1.0;
        var t_mid = 1.0;
        var after = 1.0;
        var past = false;
        let first = ch_first_slot(c);
        for (var k = 0u; k < ch_nstencil(c); k++) {
            let sd = stencil_d(first + k);
            var tr = 1.0;
            var half = 1.0;
            let col = column(x + sd.x, z + sd.y);
            if (col >= 0) {
                let p = cells[u32(col) + P.level_len * P.j].w;
                tr = trans(p, stencil_e(first + k));
                half = seg_mean(tr, depth(p, stencil_e(first + k)));
            }
            let r = light * (t * (1.0 - tr));
            let ri = li * SCRATCH + (first + k) * 3u;
            scratch[ri] = r.x;
            scratch[ri + 1u] = r.y;
            scratch[ri + 2u] = r.z;
            if (past) {
                after *= tr;
            }
            if (sd.x == 0 && sd.y == 0) {
                t_mid = t * half;
                past = true;
            }
            t *= tr;
        }
        scratch[li * SCRATCH + T_AFTER_OFFSET + c] = after;
        let o = light * t;
        let oi = (li * CH + c) * 3u;
        cur[oi] = o.x;
        cur[oi + 1u] = o.y;
        cur[oi + 2u] = o.z;
        g_add(gi, ch_bin(c), light * t_mid);
    }
    // Input flux of this column (for the stopping test).
    aux[li * 3u] += flux_in.x;
    aux[li * 3u + 1u] += flux_in.y;
    aux[li * 3u + 2u] += flux_in.z;
}

// ---- phase 2: bindings reuse slots: prev = pending of this direction, virt/halo unused,
// aux = pending flux per cell. See phase2_main in sweep_phase2.wgsl.
