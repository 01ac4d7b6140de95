// The light sampling buffer on the GPU: lightgrid_render::sampling::sample_points for one
// grid, or for a hierarchy's grids as layers in three steps (params.mode): every layer,
// finest first, claims the points it owns that no later layer claimed (claims[i] = its
// index + 1: the last layer in hierarchy order owning a point, lightgrid_terrain_lod::Owner,
// Hierarchy::grid_at); every layer then adds its share of the points whose owner is it
// or a neighbour of its depth whose read falls across their seam (lightgrid_core::seam);
// a last pass turns the summed direction moment into the dominant direction.

@group(0) @binding(0) var<uniform> params: SampleParams;
// 26 RGB bins a point (78 floats), grid order.
@group(0) @binding(1) var<storage, read> bins: array<f32>;
// With the sun kept apart (params.sun.w = 1): its scattered bins on the same points, and
// its transmittance (one float a point); unread otherwise.
@group(0) @binding(2) var<storage, read> scattered: array<f32>;
@group(0) @binding(3) var<storage, read> transmittance: array<f32>;
// Two vec4 a point: (position, has_normal), (normal, 0).
@group(0) @binding(4) var<storage, read> points: array<vec4<f32>>;
// lightgrid_render::sampling::IrradianceTable::weights.
@group(0) @binding(5) var<storage, read> table: array<f32>;
// Two vec4 a point: (light, sun transmittance), (dominant, written ? 1 : 0); while the
// layers add their shares, (dominant's direction moment, its weight) in the second.
@group(0) @binding(6) var<storage, read_write> out: array<vec4<f32>>;
// With params.horizon > 0 (lightgrid_render::GpuHorizon): the downward halves of the
// horizontal bins, 8 RGB a point (24 floats), and with params.horizon = 2 after them
// those of the sun's scattered light; unread otherwise. `table` then holds, after the
// 26 bins' kernel, the horizon term (IrradianceTable::horizon, 8 floats a node).
@group(0) @binding(7) var<storage, read> halves: array<f32>;
// The layer owning each point (its index in hierarchy order + 1; 0: none).
@group(0) @binding(8) var<storage, read_write> claims: array<u32>;
// With params.sub_dims.w = 1: the listed points the dispatch visits (unread otherwise).
@group(0) @binding(9) var<storage, read> indices: array<u32>;

// lightgrid_render::sampling::octahedral_encode
fn octahedral_encode(n_in: vec3<f32>) -> vec2<f32> {
    let n = n_in / (abs(n_in.x) + abs(n_in.y) + abs(n_in.z));
    var p = vec2<f32>(n.x, n.z);
    if (n.y < 0.0) {
        let s = select(vec2<f32>(-1.0), vec2<f32>(1.0), vec2<f32>(n.x, n.z) >= vec2<f32>(0.0));
        p = (vec2<f32>(1.0) - vec2<f32>(abs(n.z), abs(n.x))) * s;
    }
    return p * 0.5 + vec2<f32>(0.5);
}

struct SamplePoint {
    p: vec3<f32>,
    has_normal: bool,
}

// Point i: of the lattice (x fastest, then z, then y, as GridDesc::position), or listed.
fn sample_point(i: u32) -> SamplePoint {
    var s: SamplePoint;
    s.has_normal = false;
    if (params.lattice_dims.w == 1u) {
        let ld = params.lattice_dims.xyz;
        let c = vec3<u32>(i % ld.x, i / (ld.x * ld.z), (i / ld.x) % ld.z);
        s.p = params.lattice_origin_h.xyz + params.lattice_origin_h.w * vec3<f32>(c);
    } else {
        let head = points[2u * i];
        s.has_normal = head.w > 0.5;
        s.p = head.xyz;
    }
    return s;
}

// params.near's entry for the layer at offset `o` (in nodes) from this one.
fn near_at(o: vec2<i32>) -> vec4<f32> {
    return params.near[u32((o.y + 1) * 3 + (o.x + 1))];
}

// lightgrid_core::seam::seam_shares along one axis: the neighbour's offset and weight.
fn seam_axis(g: f32, last: f32) -> vec2<f32> {
    if (g < 0.0) {
        return vec2<f32>(-1.0, min(-g, 1.0));
    }
    if (g > last) {
        return vec2<f32>(1.0, min(g - last, 1.0));
    }
    return vec2<f32>(0.0, 0.0);
}

// This layer's weight in the read at `q` of a point at height `y` owned by the layer at
// offset `o` from it (lightgrid_core::seam: each node of the lookup's corners by its
// share of them); where one of those nodes is missing or does not reach `y`, the
// owner's read stands alone (weight 1 for it, 0 for the others).
fn seam_weight(q: vec3<f32>, y: f32, o: vec2<i32>) -> f32 {
    // The owner's points: this grid's, moved by `o` nodes.
    let h = params.origin_h.w;
    let owner_xz = params.origin_h.xz + vec2<f32>(o) * params.own.z;
    let g = (q.xz - owner_xz) / h;
    let last = vec2<f32>(params.dims.xz) - vec2<f32>(1.0);
    let ax = seam_axis(g.x, last.x);
    let az = seam_axis(g.y, last.y);
    let off = vec2<i32>(i32(ax.x), i32(az.x));
    var mine = 0.0;
    for (var k = 0u; k < 4u; k++) {
        let e = vec2<i32>(i32(k & 1u) * off.x, i32(k >> 1u) * off.y);
        let w = select(1.0 - ax.y, ax.y, (k & 1u) != 0u) * select(1.0 - az.y, az.y, (k >> 1u) != 0u);
        if (w <= 0.0) {
            continue;
        }
        // The node at `e` from the owner is at `o + e` from this layer.
        let at = o + e;
        if (any(abs(at) > vec2<i32>(1))) {
            return select(0.0, 1.0, all(o == vec2<i32>(0)));
        }
        let nb = near_at(at);
        if (nb.z < 0.5 || y < nb.x || y > nb.y) {
            return select(0.0, 1.0, all(o == vec2<i32>(0)));
        }
        if (all(at == vec2<i32>(0))) {
            mine = w;
        }
    }
    return mine;
}

// The point of invocation `g`: on a lattice, the points of the dispatch's box of it
// (x fastest, then z, then y); of listed points, the one its index list names, or the
// point `g` where it visits them all.
fn point_index(g: u32) -> u32 {
    if (params.lattice_dims.w == 1u) {
        let sd = params.sub_dims.xyz;
        let c = params.sub_lo.xyz + vec3<u32>(g % sd.x, g / (sd.x * sd.z), (g / sd.x) % sd.z);
        let ld = params.lattice_dims.xyz;
        return (c.y * ld.z + c.z) * ld.x + c.x;
    }
    if (params.sub_dims.w == 1u) {
        return indices[g];
    }
    return g;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.count) {
        return;
    }
    let i = point_index(gid.x);
    if (params.mode == 2u) {
        // The dominant direction from its summed moment (as sample_points: clamped to
        // unit length), the transmittance within [0, 1], the written flag.
        if (claims[i] == 0u) {
            return;
        }
        let m = out[2u * i + 1u];
        var dom = vec3<f32>(0.0);
        if (m.w > 0.0) {
            dom = m.xyz / m.w;
            let len = length(dom);
            if (len > 1.0) {
                dom = dom / len;
            }
        }
        out[2u * i + 1u] = vec4<f32>(dom, 1.0);
        let a = out[2u * i];
        out[2u * i] = vec4<f32>(a.xyz, clamp(a.w, 0.0, 1.0));
        return;
    }
    let sp = sample_point(i);
    var p = sp.p;
    let has_normal = sp.has_normal;
    if (params.mode == 0u) {
        // Claim: the first layer (finest first) owning the point. Owned layers own
        // lightgrid_terrain_lod::Owner::owns: the point's quadtree cell is the layer's
        // node, and its height lies within the layer grid's levels.
        if (claims[i] != 0u) {
            return;
        }
        if (params.own.w > 0.5) {
            let cell = vec2<i32>(floor((p.xz - params.own.xy) / params.own.z));
            let lo = params.origin_h.y;
            let hi = lo + params.origin_h.w * f32(params.dims.y - 1u);
            if (any(cell != params.own_index.xy) || p.y < lo || p.y > hi) {
                return;
            }
        }
        claims[i] = params.layer;
        return;
    }
    // Add this layer's share: the owner's offset from this layer, if it is this layer
    // or a neighbour of its depth.
    let owner = claims[i];
    if (owner == 0u) {
        return;
    }
    var o = vec2<i32>(0);
    if (owner != params.layer) {
        var found = false;
        for (var k = 0u; k < 9u; k++) {
            if (k != 4u && params.near[k].z == f32(owner)) {
                o = vec2<i32>(i32(k % 3u) - 1, i32(k / 3u) - 1);
                found = true;
            }
        }
        if (!found) {
            return;
        }
    }
    let y = p.y;
    var n = vec3<f32>(0.0, 1.0, 0.0);
    if (has_normal) {
        n = normalize(points[2u * i + 1u].xyz);
        p = p + n * (0.5 * params.origin_h.w);
    }
    var share = 1.0;
    if (params.own.w > 0.5) {
        share = seam_weight(p, y, o);
    } else if (owner != params.layer) {
        return;
    }
    if (share <= 0.0) {
        return;
    }
    let dims = params.dims.xyz;
    let t = trilinear(dims, (p - params.origin_h.xyz) / params.origin_h.w);
    var acc: array<vec3<f32>, 26>;
    for (var d = 0u; d < NUM_DIRS; d++) {
        acc[d] = vec3<f32>(0.0);
    }
    var acc_h: array<vec3<f32>, HORIZONTAL_BINS>;
    for (var k = 0u; k < HORIZONTAL_BINS; k++) {
        acc_h[k] = vec3<f32>(0.0);
    }
    let sun_halves = dims.x * dims.y * dims.z * 24u;
    let has_sun = params.sun.w > 0.5;
    var t_sun = 0.0;
    for (var c = 0u; c < 8u; c++) {
        let w = corner_weight(t, c);
        if (w != 0.0) {
            let point = grid_index(dims, corner(t, c));
            let base = point * 78u;
            for (var d = 0u; d < NUM_DIRS; d++) {
                let o = base + 3u * d;
                var v = vec3<f32>(bins[o], bins[o + 1u], bins[o + 2u]) * params.sky_scale.xyz;
                if (has_sun) {
                    v += vec3<f32>(scattered[o], scattered[o + 1u], scattered[o + 2u]) * params.sun.xyz;
                }
                acc[d] += v * w;
            }
            if (has_sun) {
                t_sun += transmittance[point] * w;
            }
            if (params.horizon > 0u) {
                // LightField::horizon of the hierarchy: the sky's halves scaled, plus the
                // sun's (or its bins split evenly) times its irradiance.
                for (var k = 0u; k < HORIZONTAL_BINS; k++) {
                    let o = point * 24u + 3u * k;
                    var h = vec3<f32>(halves[o], halves[o + 1u], halves[o + 2u]) * params.sky_scale.xyz;
                    if (has_sun) {
                        if (params.horizon == 2u) {
                            let s = sun_halves + o;
                            h += vec3<f32>(halves[s], halves[s + 1u], halves[s + 2u]) * params.sun.xyz;
                        } else {
                            let s = point * 78u + 3u * (FIRST_HORIZONTAL + k);
                            h += vec3<f32>(scattered[s], scattered[s + 1u], scattered[s + 2u]) * (0.5 * params.sun.xyz);
                        }
                    }
                    acc_h[k] += h * w;
                }
            }
        }
    }
    t_sun = clamp(t_sun, 0.0, 1.0);
    var light = vec3<f32>(0.0);
    if (has_normal) {
        let size = params.dims.w;
        let g = octahedral_encode(n) * f32(size - 1u);
        let b = min(vec2<u32>(floor(g)), vec2<u32>(size - 2u));
        let f = clamp(g - vec2<f32>(b), vec2<f32>(0.0), vec2<f32>(1.0));
        for (var k = 0u; k < 4u; k++) {
            let dx = k & 1u;
            let dy = k >> 1u;
            let wx = select(1.0 - f.x, f.x, dx == 1u);
            let wy = select(1.0 - f.y, f.y, dy == 1u);
            let w = wx * wy;
            let node = ((b.y + dy) * size + b.x + dx) * NUM_DIRS;
            for (var d = 0u; d < NUM_DIRS; d++) {
                light += acc[d] * (table[node + d] * w);
            }
            if (params.horizon > 0u) {
                // IrradianceTable::irradiance_split: the even read plus
                // (down - bin / 2) (W_down - W_up) per horizontal bin.
                let hnode = size * size * NUM_DIRS + ((b.y + dy) * size + b.x + dx) * HORIZONTAL_BINS;
                for (var k = 0u; k < HORIZONTAL_BINS; k++) {
                    let excess = acc_h[k] - 0.5 * acc[FIRST_HORIZONTAL + k];
                    light += excess * (table[hnode + k] * w);
                }
            }
        }
    } else {
        for (var d = 0u; d < NUM_DIRS; d++) {
            light += acc[d];
        }
        light = light / (4.0 * PI);
    }
    if (has_normal && has_sun) {
        // The direct sun, as vertex light holds it (shading::direct_sun).
        light += params.sun.xyz * (t_sun * max(dot(n, params.to_sun.xyz), 0.0));
    }
    // The direction moment and its weight, summed over the shares (the last pass
    // divides).
    var dom = vec3<f32>(0.0);
    var sum = 0.0;
    // Indexed as a variable, copied once: naga writes a runtime index into a `const`
    // array as a copy of the whole array at every read.
    var units = DIR_UNIT;
    for (var d = 0u; d < NUM_DIRS; d++) {
        let l = luminance(acc[d]);
        dom += units[d] * l;
        sum += l;
    }
    out[2u * i] += vec4<f32>(light, t_sun) * share;
    out[2u * i + 1u] += vec4<f32>(dom, sum) * share;
}
