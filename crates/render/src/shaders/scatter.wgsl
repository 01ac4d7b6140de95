// Copies sampled light (GpuSamples: two vec4 a point, light first) into the rgb of a
// strided array of f32 on the device: a mesh's vertices (Vertex::light) or the ground
// light (rgb, height). Only the three light floats are written.

@group(0) @binding(0) var<uniform> params: ScatterParams;
@group(0) @binding(1) var<storage, read> samples: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<f32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= params.count) {
        return;
    }
    let l = samples[2u * i].xyz;
    let o = i * params.stride + params.offset;
    dst[o] = l.x;
    dst[o + 1u] = l.y;
    dst[o + 2u] = l.z;
}
