// Phase 2 of a level: each cell collects what it removed, absorbs, emits into this
// pass's channels and re-absorbs what its own material stops (sweep-cpu steps 3-7);
// under the source rule a medium sets its source instead, and phase 3 (below) adds what
// the sources emit along every path (lightgrid_sweep_cpu::medium).

const LOCAL_ROUNDS: u32 = LOCAL_ROUNDS_GEN;

@group(0) @binding(0) var<storage, read> P: LevelParams;
@group(0) @binding(1) var<storage, read> cells: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> exposed: array<u32>;
@group(0) @binding(3) var<storage, read_write> cur: array<f32>;
@group(0) @binding(4) var<storage, read> scratch: array<f32>;
@group(0) @binding(5) var<storage, read_write> g: array<f32>;
@group(0) @binding(6) var<storage, read_write> pend_same: array<f32>;
@group(0) @binding(7) var<storage, read_write> pend_other: array<f32>;
@group(0) @binding(8) var<storage, read_write> pend_flux: array<f32>;
@group(0) @binding(9) var<uniform> SURFACE_W4: array<vec4<f32>, SURFACE_ROWS_GEN>;
// The source rules' source per cell of the level: J_0 (RGB), then (the profile rule,
// medium 3) J_1 and J_2; 0: none.
@group(0) @binding(10) var<storage, read_write> srcj: array<f32>;
// The profile rule's tables (lightgrid_sweep_cpu::profile::table_floats), then the
// sweep's (`crate::wgsl::table_floats`, read through the generated accessors).
@group(0) @binding(11) var<storage, read> tables: array<f32, TABLE_FLOATS>;

// --- The quadratic source in height (lightgrid_sweep_cpu::profile, P.medium == 3) ---

struct ProfNode {
    i: u32,
    f: f32,
}

// Whether a cell of pass-through p takes the quadratic source (sweep-cpu's
// medium::profiled): the profile rule, and optical depth at least its least; thinner
// media emit the flat source under that rule too.
fn profiled(p: f32) -> bool {
    return P.medium == 3u && p > 0.0 && p <= PROFILE_MAX_PASS;
}

// The table node of a cell of ln(pass) lnp (CellProfile::new's interpolation).
fn prof_node(lnp: f32) -> ProfNode {
    let tau = max(-lnp, 0.0);
    let u = sqrt(min(tau, PROF_TAU_MAX) / PROF_TAU_MAX) * f32(PROF_N - 1u);
    let i = min(u32(u), PROF_N - 2u);
    return ProfNode(i, clamp(u - f32(i), 0.0, 1.0));
}

// Value q (0..6: C_1/C_0, C_2/C_0, E_1, E_2, M_1, M_2) of slot `slot` of pass `pass`.
fn prof_val(n: ProfNode, ps: u32, slot: u32, q: u32) -> f32 {
    let o = (ps * SLOTS + slot) * 6u + q;
    let a = tables[n.i * PROF_NODE + o];
    let b = tables[(n.i + 1u) * PROF_NODE + o];
    return a + (b - a) * n.f;
}

// A cell's full-sphere sums for the pass `up`: O, G of this pass and of the other, K.
struct ProfSums {
    o: f32,
    g_this: vec3<f32>,
    g_other: vec3<f32>,
    k: array<vec3<f32>, 3>,
}

fn prof_sums(pass_through: f32, up: u32) -> ProfSums {
    let lnp = log(pass_through);
    let n = prof_node(lnp);
    let tau = max(-lnp, 0.0);
    var o = 0.0;
    var g_this = vec3<f32>(0.0);
    var g_other = vec3<f32>(0.0);
    var kn0 = vec2<f32>(0.0);
    for (var ps = 0u; ps < 2u; ps++) {
        for (var sl = 0u; sl < SLOTS; sl++) {
            let geo = prof_geo(ps * SLOTS + sl);
            let seg_t = geo.y * tau;
            let c0 = 1.0 - exp(geo.y * lnp);
            let c = vec2<f32>(prof_val(n, ps, sl, 0u), prof_val(n, ps, sl, 1u));
            let g = geo.x * vec3<f32>(c0, prof_val(n, ps, sl, 2u), prof_val(n, ps, sl, 3u));
            if (ps == up) {
                g_this += g;
            } else {
                g_other += g;
            }
            o += geo.x * seg_t;
            kn0 += geo.x * (seg_t * geo.zw - c * c0);
        }
    }
    let gt = g_this + g_other;
    let kb = n.i * PROF_NODE + 2u * SLOTS * 6u;
    var kk: array<f32, 4>;
    for (var q = 0u; q < 4u; q++) {
        kk[q] = tables[kb + q] + (tables[kb + PROF_NODE + q] - tables[kb + q]) * n.f;
    }
    var k: array<vec3<f32>, 3>;
    k[0] = vec3<f32>(o, 0.0, 0.0) - gt;
    k[1] = vec3<f32>(kn0.x, kk[0], kk[1]);
    k[2] = vec3<f32>(kn0.y, kk[2], kk[3]);
    return ProfSums(o, g_this, g_other, k);
}

fn det3(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> f32 {
    // rows a, b, c
    return a.x * (b.y * c.z - b.z * c.y) - a.y * (b.x * c.z - b.z * c.x) + a.z * (b.x * c.y - b.y * c.x);
}

// CellProfile::source for one colour: O J_n / (2n + 1) - a Σ K_nm J_m = a r_n.
fn prof_solve(s: ProfSums, a: f32, r: vec3<f32>) -> vec3<f32> {
    if (!(a > 0.0) || r.x == 0.0) {
        return vec3<f32>(0.0);
    }
    let m0 = vec3<f32>(s.o, 0.0, 0.0) - a * s.k[0];
    let m1 = vec3<f32>(0.0, s.o / 3.0, 0.0) - a * s.k[1];
    let m2 = vec3<f32>(0.0, 0.0, s.o / 5.0) - a * s.k[2];
    let e = a * r;
    let d = det3(m0, m1, m2);
    if (!(abs(d) > 0.0)) {
        return vec3<f32>(0.0);
    }
    let j = vec3<f32>(
        det3(vec3<f32>(e.x, m0.y, m0.z), vec3<f32>(e.y, m1.y, m1.z), vec3<f32>(e.z, m2.y, m2.z)),
        det3(vec3<f32>(m0.x, e.x, m0.z), vec3<f32>(m1.x, e.y, m1.z), vec3<f32>(m2.x, e.z, m2.z)),
        det3(vec3<f32>(m0.x, m0.y, e.x), vec3<f32>(m1.x, m1.y, e.y), vec3<f32>(m2.x, m2.y, e.z)),
    ) / d;
    if (any(j != j) || any(abs(j) > vec3<f32>(3.0e38))) {
        return vec3<f32>(0.0);
    }
    return j;
}

// Per colour: the source coefficients (J_0, J_1, J_2 as Pending's s, m0, m1) for
// collisions of moments (r0, r1, r2) (RGB each), albedo alb.
fn prof_source(s: ProfSums, alb: vec3<f32>, r0: vec3<f32>, r1: vec3<f32>, r2: vec3<f32>) -> Pending {
    var j0 = vec3<f32>(0.0);
    var j1 = vec3<f32>(0.0);
    var j2 = vec3<f32>(0.0);
    for (var c = 0u; c < 3u; c++) {
        let j = prof_solve(s, alb[c], vec3<f32>(r0[c], r1[c], r2[c]));
        j0[c] = j.x;
        j1[c] = j.y;
        j2[c] = j.z;
    }
    return Pending(j0, j1, j2, vec3<f32>(0.0));
}

// G·J per colour for the coefficients held in p.
fn prof_flux(g: vec3<f32>, p: Pending) -> vec3<f32> {
    return p.s * g.x + p.m0 * g.y + p.m1 * g.z;
}

fn surface_w(i: u32) -> f32 {
    return SURFACE_W4[i / 4u][i % 4u];
}

struct Pending {
    s: vec3<f32>,
    m0: vec3<f32>,
    m1: vec3<f32>,
    m2: vec3<f32>,
}

fn load_pending(buf: u32, gi: u32) -> Pending {
    let b = gi * 12u;
    var v: array<f32, 12>;
    for (var k = 0u; k < 12u; k++) {
        if (buf == 0u) {
            v[k] = pend_same[b + k];
        } else {
            v[k] = pend_other[b + k];
        }
    }
    return Pending(vec3<f32>(v[0], v[1], v[2]), vec3<f32>(v[3], v[4], v[5]), vec3<f32>(v[6], v[7], v[8]), vec3<f32>(v[9], v[10], v[11]));
}

fn store_pending(buf: u32, gi: u32, p: Pending) {
    let b = gi * 12u;
    // A `var`: a `let` array indexed at run time is copied at every read (naga).
    var v = array<f32, 12>(p.s.x, p.s.y, p.s.z, p.m0.x, p.m0.y, p.m0.z, p.m1.x, p.m1.y, p.m1.z, p.m2.x, p.m2.y, p.m2.z);
    for (var k = 0u; k < 12u; k++) {
        if (buf == 0u) {
            pend_same[b + k] = v[k];
        } else {
            pend_other[b + k] = v[k];
        }
    }
}

fn add_p(a: Pending, b: Pending) -> Pending {
    return Pending(a.s + b.s, a.m0 + b.m0, a.m1 + b.m1, a.m2 + b.m2);
}

fn ch_bin(up: u32, c: u32) -> u32 {
    if (up == 1u) {
        return ch_bin_up(c);
    }
    return ch_bin_down(c);
}

// A medium cell's emission weights (A, B) under the escape rule:
// lightgrid_sweep_cpu::sweep::medium_emission (a slab's escape forward and back); once per cell.
fn medium_weights(pass_through: f32) -> vec2<f32> {
    if (pass_through > 0.0 && pass_through < 1.0) {
        let forward = -log(pass_through) * pass_through / (1.0 - pass_through);
        let back = (1.0 + pass_through) * 0.5;
        return vec2<f32>((forward + back) * 0.5, (back - forward) * 0.5);
    }
    return vec2<f32>(1.0, 0.0);
}

// Flux sent into channel c before T_after (sweep-cpu's Emission::flux); `ab` the cell's
// medium_weights.
fn emission(p: Pending, pass_through: f32, ab: vec2<f32>, mask: u32, up: u32, c: u32) -> vec3<f32> {
    let bin = ch_bin(up, c);
    if (pass_through > 0.0) {
        let a = ab.x;
        let b = ab.y;
        let u = dir_unit(bin);
        let w = solid_angle(bin) / FOUR_PI;
        let um = p.m0 * u.x + p.m1 * u.y + p.m2 * u.z;
        return max((p.s * a - um * b) * (w * ch_share(c)), vec3<f32>(0.0));
    }
    return p.s * surface_w((mask * 2u + up) * NUM_DIRS + bin);
}

// What of flux f leaves the cell's level through T_after (sweep-cpu's Emission::leaving):
// a top or bottom face's horizontal light is free of the level's path cells.
fn leaving(p: Pending, f: vec3<f32>, t_after: f32, pass_through: f32, mask: u32, up: u32, c: u32) -> vec3<f32> {
    if (pass_through > 0.0) {
        return f * t_after;
    }
    let free = p.s * surface_w(SURFACE_FREE_OFFSET_GEN + (mask * 2u + up) * NUM_DIRS + ch_bin(up, c));
    return (f - free) * t_after + free;
}

// The channel's share before anything stops it (Emission::full).
fn full(p: Pending, pass_through: f32, mask: u32, up: u32, c: u32) -> vec3<f32> {
    let bin = ch_bin(up, c);
    if (pass_through > 0.0) {
        return p.s * (solid_angle(bin) / FOUR_PI * ch_share(c));
    }
    return p.s * surface_w((mask * 2u + up) * NUM_DIRS + bin);
}

// lightgrid_sweep_cpu::medium::split: the share of a cell's scattered light between the passes.
fn split(lnp: f32) -> f32 {
    let n = f32(SPLIT_N - 1u);
    let u = sqrt(max(-lnp / SPLIT_TAU_MAX, 0.0)) * n;
    if (!(u < n)) {
        return split_table(SPLIT_N - 1u);
    }
    let i = u32(u);
    let f = u - f32(i);
    return split_table(i) + (split_table(i + 1u) - split_table(i)) * f;
}

// lightgrid_sweep_cpu::medium::source for the three colours: the cell's source J.
fn medium_source(pass_through: f32, share: vec3<f32>, alb: vec3<f32>) -> vec3<f32> {
    let lnp = log(pass_through);
    var g = 0.0;
    for (var e = 0u; e < MAX_E; e++) {
        g += src_w(e) * (1.0 - trans(pass_through, path_e(e)));
    }
    let k = max(-lnp * SRC_O - g, 0.0);
    var j = vec3<f32>(0.0);
    for (var c = 0u; c < 3u; c++) {
        let d = g + (1.0 - alb[c]) * k;
        if (share[c] > 0.0 && d > 0.0) {
            j[c] = share[c] / d;
        }
    }
    return j;
}

fn budget(p: Pending, pass_through: f32, mask: u32, up: u32) -> vec3<f32> {
    if (all(p.s == vec3<f32>(0.0))) {
        return vec3<f32>(0.0);
    }
    if (pass_through > 0.0) {
        return p.s * 0.5;
    }
    var sum = vec3<f32>(0.0);
    for (var c = 0u; c < CH; c++) {
        sum += full(p, pass_through, mask, up, c);
    }
    return sum;
}

@compute @workgroup_size(64)
fn phase2(@builtin(global_invocation_id) id: vec3<u32>) {
    let li = id.x;
    if (li >= P.level_len) {
        return;
    }
    let gi = li + P.level_len * P.j;
    let mat = cells[gi];
    for (var q = 0u; q < 9u; q++) {
        srcj[li * 9u + q] = 0.0;
    }
    if (mat.w >= 1.0) {
        return;
    }
    let x = i32(li % P.nx);
    let z = i32(li / P.nx);
    let profile = profiled(mat.w);
    var node = ProfNode(0u, 0.0);
    if (profile) {
        node = prof_node(log(mat.w));
    }
    // Step 3: the flux this cell removed from every path crossing it (and, the profile
    // rule, its height moments).
    var s_raw = vec3<f32>(0.0);
    var m0 = vec3<f32>(0.0);
    var m1 = vec3<f32>(0.0);
    var m2 = vec3<f32>(0.0);
    var h1 = vec3<f32>(0.0);
    var h2 = vec3<f32>(0.0);
    for (var c = 0u; c < CH; c++) {
        var r = vec3<f32>(0.0);
        let first = ch_first_slot(c);
        for (var k = 0u; k < ch_nstencil(c); k++) {
            let sd = stencil_d(first + k);
            let col = column(x - sd.x, z - sd.y);
            if (col >= 0) {
                let i = u32(col) * SCRATCH + (first + k) * 3u;
                let v = vec3<f32>(scratch[i], scratch[i + 1u], scratch[i + 2u]);
                r += v;
                if (profile) {
                    let vm = v * ch_mu(c);
                    h1 += vm * prof_val(node, P.up, first + k, 0u);
                    h2 += vm * prof_val(node, P.up, first + k, 1u);
                }
            }
        }
        r = r * ch_mu(c);
        let u = dir_unit(ch_bin(P.up, c));
        s_raw += r;
        m0 += r * u.x;
        m1 += r * u.y;
        m2 += r * u.z;
    }
    // Step 4: absorb (1 - albedo), keep albedo for scattering.
    let alb = mat.xyz;
    let fresh = Pending(s_raw * alb, m0 * alb, m1 * alb, m2 * alb);
    // Steps 5 and 6: emit, re-absorb in rounds.
    if (profile) {
        // The profile rule: the collisions become an isotropic source (coefficients in
        // height); this pass emits what waits for it, the other pass's waits.
        let sums = prof_sums(mat.w, P.up);
        let dj = prof_source(sums, alb, s_raw, h1, h2);
        let emit = add_p(load_pending(0u, gi), dj);
        var v = array<vec3<f32>, 3>(emit.s, emit.m0, emit.m1);
        for (var q = 0u; q < 3u; q++) {
            srcj[li * 9u + q * 3u] = v[q].x;
            srcj[li * 9u + q * 3u + 1u] = v[q].y;
            srcj[li * 9u + q * 3u + 2u] = v[q].z;
        }
        let zero = vec3<f32>(0.0);
        store_pending(0u, gi, Pending(zero, zero, zero, zero));
        let other = add_p(load_pending(1u, gi), dj);
        store_pending(1u, gi, other);
        let pf = max(prof_flux(sums.g_other, other), zero);
        pend_flux[gi * 3u] = pf.x;
        pend_flux[gi * 3u + 1u] = pf.y;
        pend_flux[gi * 3u + 2u] = pf.z;
        return;
    }
    var own = add_p(fresh, load_pending(0u, gi));
    var other = add_p(load_pending(1u, gi), fresh);
    if ((P.medium == 2u || P.medium == 3u) && mat.w > 0.0) {
        // The source rule: this direction's share ½ (S ∓ β M_y) as the cell's source.
        let beta = split(log(mat.w));
        let sgn = select(0.5, -0.5, P.up == 1u);
        let share = max(own.s * 0.5 + own.m1 * (beta * sgn), vec3<f32>(0.0));
        let j = medium_source(mat.w, share, alb);
        srcj[li * 9u] = j.x;
        srcj[li * 9u + 1u] = j.y;
        srcj[li * 9u + 2u] = j.z;
        let zero = vec3<f32>(0.0);
        store_pending(0u, gi, Pending(zero, zero, zero, zero));
        store_pending(1u, gi, other);
        let pf = max(other.s * 0.5 + other.m1 * (beta * -sgn), zero);
        pend_flux[gi * 3u] = pf.x;
        pend_flux[gi * 3u + 1u] = pf.y;
        pend_flux[gi * 3u + 2u] = pf.z;
        return;
    }
    let mask = exposed[gi];
    let ab = medium_weights(mat.w);
    for (var round = 0u; round < LOCAL_ROUNDS; round++) {
        if (all(own.s == vec3<f32>(0.0))) {
            break;
        }
        var lost_s = vec3<f32>(0.0);
        var l0 = vec3<f32>(0.0);
        var l1 = vec3<f32>(0.0);
        var l2 = vec3<f32>(0.0);
        for (var c = 0u; c < CH; c++) {
            let f = emission(own, mat.w, ab, mask, P.up, c);
            let leaving = leaving(own, f, scratch[li * SCRATCH + T_AFTER_OFFSET + c], mat.w, mask, P.up, c);
            let lost = max(full(own, mat.w, mask, P.up, c) - leaving, vec3<f32>(0.0));
            let u = dir_unit(ch_bin(P.up, c));
            lost_s += lost;
            l0 += lost * u.x;
            l1 += lost * u.y;
            l2 += lost * u.z;
            let oi = (li * CH + c) * 3u;
            let add = leaving / ch_mu(c);
            cur[oi] += add.x;
            cur[oi + 1u] += add.y;
            cur[oi + 2u] += add.z;
            g_add(gi, ch_bin(P.up, c), f * (0.5 / ch_mu(c)));
        }
        own = Pending(lost_s * alb, l0 * alb, l1 * alb, l2 * alb);
        other = add_p(other, own);
    }
    store_pending(0u, gi, own);
    store_pending(1u, gi, other);
    let pf = budget(own, mat.w, mask, P.up) + budget(other, mat.w, mask, 1u - P.up);
    pend_flux[gi * 3u] = pf.x;
    pend_flux[gi * 3u + 1u] = pf.y;
    pend_flux[gi * 3u + 2u] = pf.z;
}

// Coefficient q (0: J_0, 1: J_1, 2: J_2) of the source of cell i of the level.
fn src_q(i: u32, q: u32) -> vec3<f32> {
    let b = i * 9u + q * 3u;
    return vec3<f32>(srcj[b], srcj[b + 1u], srcj[b + 2u]);
}

fn src_at(i: u32) -> vec3<f32> {
    return src_q(i, 0u);
}

// Segment k of channel c's path from column (x, z) offset by (dx, dz): its
// transmittance and emission (per unit ω_b σ_c); beyond open sides empty.
fn segment(x: i32, z: i32, c: u32, k: u32) -> vec4<f32> {
    let sd = stencil_d(ch_first_slot(c) + k);
    let col = column(x + sd.x, z + sd.y);
    if (col < 0) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    let q = u32(col);
    let slot = ch_first_slot(c) + k;
    let pt = cells[q + P.level_len * P.j].w;
    let tr = trans(pt, stencil_e(slot));
    var e = src_at(q) * (1.0 - tr);
    if (profiled(pt)) {
        let n = prof_node(log(pt));
        e += src_q(q, 1u) * prof_val(n, P.up, slot, 2u) + src_q(q, 2u) * prof_val(n, P.up, slot, 3u);
    }
    return vec4<f32>(e, tr);
}

// Phase 3 (the source rule, sweep-cpu's Ctx::phase3): every path gains what its
// segments' sources emit, attenuated by the segments after them, the point's light the
// emission before its centre; every cell with material collects what it stops of its
// level-mates' emission, scattered for the next passes.
@compute @workgroup_size(64)
fn phase3(@builtin(global_invocation_id) id: vec3<u32>) {
    let li = id.x;
    if (li >= P.level_len || P.medium < 2u) {
        return;
    }
    let gi = li + P.level_len * P.j;
    let x = i32(li % P.nx);
    let z = i32(li / P.nx);
    let mat = cells[gi];
    let profile = profiled(mat.w);
    var node = ProfNode(0u, 0.0);
    if (profile) {
        node = prof_node(log(mat.w));
    }
    for (var c = 0u; c < CH; c++) {
        var acc = vec3<f32>(0.0);
        var centre = vec3<f32>(0.0);
        for (var k = 0u; k < ch_nstencil(c); k++) {
            let sd = stencil_d(ch_first_slot(c) + k);
            let s = segment(x, z, c, k);
            if (sd.x == 0 && sd.y == 0) {
                let half = seg_mean(s.w, depth(mat.w, stencil_e(ch_first_slot(c) + k)));
                centre = acc * half + src_at(li) * (1.0 - half);
                if (profile) {
                    let slot = ch_first_slot(c) + k;
                    centre += src_q(li, 1u) * prof_val(node, P.up, slot, 4u) + src_q(li, 2u) * prof_val(node, P.up, slot, 5u);
                }
            }
            acc = acc * s.w + s.xyz;
        }
        let om = src_omega(c);
        let oi = (li * CH + c) * 3u;
        let add = acc * om;
        cur[oi] += add.x;
        cur[oi + 1u] += add.y;
        cur[oi + 2u] += add.z;
        g_add(gi, ch_bin(P.up, c), centre * om);
    }
    if (mat.w >= 1.0) {
        return;
    }
    var got = Pending(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    var h1 = vec3<f32>(0.0);
    var h2 = vec3<f32>(0.0);
    for (var c = 0u; c < CH; c++) {
        let om = src_omega(c) * ch_mu(c);
        let u = dir_unit(ch_bin(P.up, c));
        for (var j = 0u; j < ch_nstencil(c); j++) {
            let sj = stencil_d(ch_first_slot(c) + j);
            if (column(x - sj.x, z - sj.y) < 0) {
                continue;
            }
            var acc = vec3<f32>(0.0);
            for (var m = 0u; m < j; m++) {
                let s = segment(x - sj.x, z - sj.y, c, m);
                acc = acc * s.w + s.xyz;
            }
            let r = acc * ((1.0 - trans(mat.w, stencil_e(ch_first_slot(c) + j))) * om);
            got = add_p(got, Pending(r, r * u.x, r * u.y, r * u.z));
            if (profile) {
                h1 += r * prof_val(node, P.up, ch_first_slot(c) + j, 0u);
                h2 += r * prof_val(node, P.up, ch_first_slot(c) + j, 1u);
            }
        }
    }
    if (all(got.s == vec3<f32>(0.0))) {
        return;
    }
    let alb = mat.xyz;
    if (profile) {
        // Waits for the next passes of both directions, as an isotropic source.
        let sums = prof_sums(mat.w, P.up);
        let dj = prof_source(sums, alb, got.s, h1, h2);
        store_pending(0u, gi, add_p(load_pending(0u, gi), dj));
        store_pending(1u, gi, add_p(load_pending(1u, gi), dj));
        let pf = max(prof_flux(sums.g_this, dj) + prof_flux(sums.g_other, dj), vec3<f32>(0.0));
        pend_flux[gi * 3u] += pf.x;
        pend_flux[gi * 3u + 1u] += pf.y;
        pend_flux[gi * 3u + 2u] += pf.z;
        return;
    }
    let sc = Pending(got.s * alb, got.m0 * alb, got.m1 * alb, got.m2 * alb);
    store_pending(0u, gi, add_p(load_pending(0u, gi), sc));
    store_pending(1u, gi, add_p(load_pending(1u, gi), sc));
    pend_flux[gi * 3u] += sc.s.x;
    pend_flux[gi * 3u + 1u] += sc.s.y;
    pend_flux[gi * 3u + 2u] += sc.s.z;
}

// The profile rule's output: light a quadratic source sent below 0 clamped at 0, as
// sweep-cpu does after its last pass (one level per dispatch).
@compute @workgroup_size(64)
fn clamp_light(@builtin(global_invocation_id) id: vec3<u32>) {
    let li = id.x;
    if (li >= P.level_len) {
        return;
    }
    let b = (li + P.level_len * P.j) * NUM_DIRS * 3u;
    for (var q = 0u; q < NUM_DIRS * 3u; q++) {
        g[b + q] = max(g[b + q], 0.0);
    }
    if (P.horizon == 1u) {
        let h = P.horizon_base + (li + P.level_len * P.j) * HORIZONTAL_BINS * 3u;
        for (var q = 0u; q < HORIZONTAL_BINS * 3u; q++) {
            g[h + q] = max(g[h + q], 0.0);
        }
    }
}
