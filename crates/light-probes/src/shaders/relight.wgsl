// Probe relighting (lightgrid_light_probes::ProbeLight::frame, the CPU specification), three
// stages selected by params.counts.x: 0 surfels, 1 bricks, 2 probes. Ambient cubes are
// six vec4 a probe (+X, -X, +Y, -Y, +Z, -Z).

@group(0) @binding(0) var<uniform> params: RelightParams;
// Surfels: (position, hits), (normal, outside), (albedo, 0); outside = 1 for an interior
// set's surfels beyond its room (lit by the exterior set's probes).
@group(0) @binding(1) var<storage, read> surfels: array<vec4<f32>>;
// Every index table, at the offsets of params.offsets: per surfel its links' range
// (from 0), links (probe, bitcast weight), brick_start (bricks + 1), brick_surfels, per
// probe its factors' range.
@group(0) @binding(2) var<storage, read> index: array<u32>;
// Factors: (w0..w3), (w4, w5, bitcast brick, 0).
@group(0) @binding(3) var<storage, read> factors: array<vec4<f32>>;
// Per probe: sky visibility [axis][bin], 6 x 26 floats.
@group(0) @binding(4) var<storage, read> probe_sky: array<f32>;
// This frame: the 26 sky bins (rgb), then the surfels' sun visibility, four a vec4.
@group(0) @binding(5) var<storage, read> frame_in: array<vec4<f32>>;
// Last frame's probes.
@group(0) @binding(6) var<storage, read> last: array<vec4<f32>>;
// Surfel radiance (one vec4 each), then brick radiance.
@group(0) @binding(7) var<storage, read_write> work: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> probes: array<vec4<f32>>;
// The exterior set's probes this frame (an interior set's outside surfels read them; an
// exterior set binds its own last frame here, unread).
@group(0) @binding(9) var<storage, read> exterior: array<vec4<f32>>;

// lightgrid_core::AmbientCube::irradiance of the cube with faces c (+X, -X, ... -Z).
fn cube_eval(c: array<vec3<f32>, 6>, n: vec3<f32>) -> vec3<f32> {
    let n2 = n * n;
    let x = select(c[1], c[0], n.x >= 0.0);
    let y = select(c[3], c[2], n.y >= 0.0);
    let z = select(c[5], c[4], n.z >= 0.0);
    return x * n2.x + y * n2.y + z * n2.z;
}

// Probe p's irradiance facing n: last frame's, or the exterior set's this frame.
fn cube_irradiance(p: u32, n: vec3<f32>, outside: bool) -> vec3<f32> {
    var c: array<vec3<f32>, 6>;
    for (var k = 0u; k < 6u; k++) {
        if (outside) {
            c[k] = exterior[6u * p + k].xyz;
        } else {
            c[k] = last[6u * p + k].xyz;
        }
    }
    return cube_eval(c, n);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    let stage = params.counts.x;
    let n_surfels = params.counts.y;
    if (stage == 0u) {
        if (i >= n_surfels) {
            return;
        }
        let n = surfels[3u * i + 1u].xyz;
        let outside = surfels[3u * i + 1u].w != 0.0;
        let albedo = surfels[3u * i + 2u].xyz;
        var e = vec3<f32>(0.0);
        for (var l = index[2u * i]; l < index[2u * i + 1u]; l++) {
            let o = params.offsets.x + 2u * l;
            e += cube_irradiance(index[o], n, outside) * bitcast<f32>(index[o + 1u]);
        }
        if (params.to_sun.w != 0.0) {
            let v = frame_in[NUM_DIRS + i / 4u][i % 4u];
            e += params.sun_irradiance.xyz * (clamp(v, 0.0, 1.0) * max(dot(n, params.to_sun.xyz), 0.0));
        }
        work[i] = vec4<f32>(albedo * e / PI, 0.0);
    } else if (stage == 1u) {
        if (i >= params.counts.z) {
            return;
        }
        var sum = vec3<f32>(0.0);
        var hits = 0u;
        let start = params.offsets.y;
        for (var m = index[start + i]; m < index[start + i + 1u]; m++) {
            let s = index[params.offsets.z + m];
            let h = u32(surfels[3u * s].w);
            sum += work[s].xyz * f32(h);
            hits += h;
        }
        work[n_surfels + i] = vec4<f32>(select(vec3<f32>(0.0), sum / f32(hits), hits > 0u), 0.0);
    } else {
        if (i >= params.counts.w) {
            return;
        }
        var e: array<vec3<f32>, 6>;
        for (var k = 0u; k < 6u; k++) {
            e[k] = vec3<f32>(0.0);
        }
        let r = params.offsets.w + 2u * i;
        for (var f = index[r]; f < index[r + 1u]; f++) {
            let a = factors[2u * f];
            let b = factors[2u * f + 1u];
            let l = work[n_surfels + bitcast<u32>(b.z)].xyz;
            e[0] += l * a.x;
            e[1] += l * a.y;
            e[2] += l * a.z;
            e[3] += l * a.w;
            e[4] += l * b.x;
            e[5] += l * b.y;
        }
        for (var k = 0u; k < 6u; k++) {
            var ek = e[k];
            for (var bin = 0u; bin < NUM_DIRS; bin++) {
                ek += frame_in[bin].xyz * probe_sky[(6u * i + k) * NUM_DIRS + bin];
            }
            probes[6u * i + k] = vec4<f32>(ek, 0.0);
        }
    }
}
