// Dynamic lights for a batch of points (tests and sampling buffers).

@group(0) @binding(0) var<uniform> dyn_params: DynParams;
@group(0) @binding(1) var<storage, read> dyn_lights: array<DynLightGpu>;
@group(0) @binding(2) var<storage, read> dyn_cells: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read> dyn_indices: array<u32>;
// Three vec4 a point: (position, shininess), (normal, 0), (to eye, 0).
@group(0) @binding(4) var<storage, read> points: array<vec4<f32>>;
// Two vec4 a point: (diffuse, 0), (specular, 0).
@group(0) @binding(5) var<storage, read_write> out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= dyn_params.count.x) {
        return;
    }
    let a = points[3u * i];
    let s = dynamic_shade(a.xyz, points[3u * i + 1u].xyz, points[3u * i + 2u].xyz, a.w, dyn_params.origin_cell, dyn_params.dims);
    out[2u * i] = vec4<f32>(s.diffuse, 0.0);
    out[2u * i + 1u] = vec4<f32>(s.specular, 0.0);
}
