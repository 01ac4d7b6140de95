// The largest channel of `count` RGB values: atomicMax on the bits of non-negative floats
// (their bit patterns order like their values).

struct Params {
    count: u32,
    exposure: f32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> input: array<f32>;
@group(0) @binding(2) var<storage, read_write> result: array<atomic<u32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.count) {
        return;
    }
    let c = max(max(input[3u * i], input[3u * i + 1u]), input[3u * i + 2u]);
    if (c > 0.0) {
        atomicMax(&result[0], bitcast<u32>(c));
    }
}
