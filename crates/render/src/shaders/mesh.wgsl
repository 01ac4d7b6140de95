// Terrain, instanced meshes and debug views, lit by the light grids.
// Lighting kinds (per mesh): VERTEX reads the light the sampling buffer wrote into each
// vertex (irradiance from the 26 bins: stationary diffuse surfaces, the terrain);
// SURFACE and FOLIAGE read average light and dominant direction per pixel from the light
// volume (moving objects, vegetation; FOLIAGE ignores the normal, as the seed lights
// leaves), blended toward the ground's light near the ground; EMISSIVE shows the tint
// as light (grid points as balls); FLAT is a fixed key light (material cubes).

@group(0) @binding(0) var<uniform> frame: FrameUniforms;
// Light volume: two vec4 per point (grid order), (average light, sun transmittance) and
// (dominant direction, written flag): the layout the sampling kernel (sample.wgsl)
// writes, so a volume sampled on the GPU is drawn from where it was written. The sun
// transmittance is that of a sun the grids keep apart (frame.direct_sun; 0 otherwise).
@group(0) @binding(1) var<storage, read> volume: array<vec4<f32>>;
// Ground: (irradiance rgb, height) per heightmap node, x fastest.
@group(0) @binding(2) var<storage, read> ground: array<vec4<f32>>;
// Dynamic lights and their culling grid (lightgrid_render::dynamic).
@group(0) @binding(3) var<storage, read> dyn_lights: array<DynLightGpu>;
@group(0) @binding(4) var<storage, read> dyn_cells: array<vec2<u32>>;
@group(0) @binding(5) var<storage, read> dyn_indices: array<u32>;

@group(1) @binding(0) var<uniform> mesh: MeshUniforms;
@group(1) @binding(1) var base_texture: texture_2d<f32>;
@group(1) @binding(2) var base_sampler: sampler;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) light: vec4<f32>,
    @location(4) m0: vec4<f32>,
    @location(5) m1: vec4<f32>,
    @location(6) m2: vec4<f32>,
    @location(7) m3: vec4<f32>,
    @location(8) tint: vec4<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) light: vec4<f32>,
    @location(4) tint: vec4<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let model = mat4x4<f32>(v.m0, v.m1, v.m2, v.m3);
    var world = model * vec4<f32>(v.position, 1.0);
    var normal = (model * vec4<f32>(v.normal, 0.0)).xyz;
    if (mesh.shape.x != 0u) {
        // A billboard: the mesh's xy plane turned to face the eye at the instance's
        // origin, each vertex moved its z toward the eye, scaled as the model's x axis.
        let centre = v.m3.xyz;
        let to_eye = normalize(frame.eye.xyz - centre);
        var right = cross(vec3<f32>(0.0, 1.0, 0.0), to_eye);
        if (dot(right, right) < 1e-12) {
            right = vec3<f32>(1.0, 0.0, 0.0); // looking straight up or down
        }
        right = normalize(right);
        let up = cross(to_eye, right);
        let s = length(v.m0.xyz);
        world = vec4<f32>(centre + (right * v.position.x + up * v.position.y + to_eye * v.position.z) * s, 1.0);
        normal = to_eye;
    }
    var out: VertexOut;
    out.clip = frame.view_proj * world;
    out.world = world.xyz;
    out.normal = normal;
    out.uv = v.uv;
    out.light = v.light;
    out.tint = v.tint;
    return out;
}

struct AverageDominant {
    average: vec3<f32>,
    dominant: vec3<f32>,
    sun: f32,
}

// Trilinear lookup in the light volume (clamped at its edges).
fn sample_volume(p: vec3<f32>) -> AverageDominant {
    let dims = frame.volume_dims.xyz;
    let t = trilinear(dims, (p - frame.volume_origin_h.xyz) / frame.volume_origin_h.w);
    var r: AverageDominant;
    r.average = vec3<f32>(0.0);
    r.dominant = vec3<f32>(0.0);
    r.sun = 0.0;
    for (var c = 0u; c < 8u; c++) {
        let w = corner_weight(t, c);
        let i = grid_index(dims, corner(t, c));
        r.average += volume[2u * i].xyz * w;
        r.sun += volume[2u * i].w * w;
        r.dominant += volume[2u * i + 1u].xyz * w;
    }
    return r;
}

// Bilinear lookup of the ground's (irradiance, height) at world (x, z).
fn sample_ground(xz: vec2<f32>) -> vec4<f32> {
    let dims = frame.ground_dims.xy;
    let g = clamp((xz - frame.ground_origin.xy) / frame.ground_origin.z, vec2<f32>(0.0), vec2<f32>(dims - vec2<u32>(1u)));
    let base = min(vec2<u32>(floor(g)), max(dims, vec2<u32>(2u)) - vec2<u32>(2u));
    let hi = min(base + vec2<u32>(1u), dims - vec2<u32>(1u));
    let f = clamp(g - vec2<f32>(base), vec2<f32>(0.0), vec2<f32>(1.0));
    let a = ground[base.y * dims.x + base.x];
    let b = ground[base.y * dims.x + hi.x];
    let c = ground[hi.y * dims.x + base.x];
    let d = ground[hi.y * dims.x + hi.x];
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    return shade(in, front, frame.mode.x == MODE_NO_GRID);
}

// Both lighting modes from one draw (`Renderer::render_pair`): the scene's geometry
// is rasterised once for the two images.
struct PairOut {
    @location(0) grid: vec4<f32>,
    @location(1) no_grid: vec4<f32>,
}

@fragment
fn fs_pair(in: VertexOut, @builtin(front_facing) front: bool) -> PairOut {
    var out: PairOut;
    out.grid = shade(in, front, false);
    out.no_grid = shade(in, front, true);
    return out;
}

// A fragment's colour, lit by the grids or (`no_grid`) by the unshadowed sun and a
// constant sky.
fn shade(in: VertexOut, front: bool, no_grid: bool) -> vec4<f32> {
    var albedo = mesh.base_colour * in.tint;
    if (mesh.flags.x != 0u) {
        albedo = albedo * textureSample(base_texture, base_sampler, in.uv);
    }
    if (mesh.flags.y != 0u && albedo.a < mesh.params.x) {
        discard;
    }
    var n = normalize(in.normal);
    if (mesh.flags.w != 0u && !front) {
        n = -n;
    }
    let kind = mesh.flags.z;
    if (kind == LIGHTING_EMISSIVE) {
        return vec4<f32>(albedo.rgb, 1.0);
    }
    if (kind == LIGHTING_FLAT) {
        let key = normalize(vec3<f32>(0.4, 1.0, 0.3));
        return vec4<f32>(albedo.rgb * (0.35 + 0.65 * max(dot(n, key), 0.0)), 1.0);
    }
    var e = vec3<f32>(0.0);
    var spec = vec3<f32>(0.0);
    if (no_grid) {
        // Without the grid: unshadowed sun plus a constant sky.
        e = frame.sun_colour.rgb * max(dot(n, -frame.sun_direction.xyz), 0.0) + PI * frame.sky_ambient.rgb;
    } else if (kind == LIGHTING_VERTEX) {
        e = in.light.rgb;
    } else {
        let bias = select(n * frame.volume_params.x, vec3<f32>(0.0), kind == LIGHTING_FOLIAGE);
        let s = sample_volume(in.world + bias);
        var e_obj = PI * s.average;
        let to_sun = -frame.sun_direction.xyz;
        if (kind == LIGHTING_SURFACE) {
            let to_eye = normalize(frame.eye.xyz - in.world);
            e_obj = irradiance_average_dominant(s.average, s.dominant, n);
            spec = mesh.params.y * specular_dominant(s.average, s.dominant, n, to_eye, mesh.params.z);
            // The sun kept apart, along its exact direction.
            let d = direct_sun(frame.direct_sun.rgb, s.sun, to_sun, n, to_eye, mesh.params.z);
            e_obj += d.irradiance;
            spec += mesh.params.y * d.specular;
        } else {
            // Foliage: pi x the beam's average light, E T / 4.
            e_obj += frame.direct_sun.rgb * (max(s.sun, 0.0) * 0.25);
        }
        var t = 1.0;
        var e_ground = e_obj;
        if (frame.ground_dims.z != 0u) {
            let g = sample_ground(in.world.xz);
            t = ground_blend_weight(in.world.y - g.w, frame.volume_params.y);
            e_ground = g.rgb;
        }
        e = mix(e_ground, e_obj, t);
    }
    // Dynamic lights add to either mode.
    let to_eye = normalize(frame.eye.xyz - in.world);
    let dl = dynamic_shade(in.world, n, to_eye, mesh.params.z, frame.dyn_origin_cell, frame.dyn_dims);
    e += dl.diffuse;
    spec += mesh.params.y * dl.specular;
    let water = underwater_attenuation(in.world.y, frame.water.x, frame.water.y);
    let colour = (albedo.rgb * e / PI + spec) * water;
    return vec4<f32>(colour, 1.0);
}
