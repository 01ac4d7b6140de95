// Packs `count` RGB values (scaled by `exposure`) into R11G11B10 words.

struct Params {
    count: u32,
    exposure: f32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> input: array<f32>;
@group(0) @binding(2) var<storage, read_write> output: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.count) {
        return;
    }
    let c = vec3<f32>(input[3u * i], input[3u * i + 1u], input[3u * i + 2u]) * params.exposure;
    output[i] = pack_r11g11b10(c);
}
