// Shading functions shared by the render shaders. The specification is
// lightgrid_render::shading (CPU); these are the same formulas.

fn luminance(c: vec3<f32>) -> f32 {
    return dot(c, LUMA);
}

// lightgrid_render::shading::irradiance_average_dominant
fn irradiance_average_dominant(average: vec3<f32>, dominant: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let s = min(length(dominant), 1.0);
    var c = 0.0;
    if (s > 0.0) {
        c = max(-dot(n, dominant / s), 0.0);
    }
    return average * (PI * (1.0 - s) + 4.0 * PI * s * c);
}

// lightgrid_render::shading::specular_dominant
fn specular_dominant(average: vec3<f32>, dominant: vec3<f32>, n: vec3<f32>, to_eye: vec3<f32>, shininess: f32) -> vec3<f32> {
    let s = min(length(dominant), 1.0);
    if (s <= 0.0) {
        return vec3<f32>(0.0);
    }
    let l = -dominant / s;
    if (dot(n, l) <= 0.0) {
        return vec3<f32>(0.0);
    }
    let h = normalize(l + to_eye);
    let spec = pow(max(dot(n, h), 0.0), shininess) * (shininess + 8.0) / (8.0 * PI);
    return average * (4.0 * PI * s * spec);
}

// lightgrid_render::shading::direct_sun: (irradiance, specular) of the sun kept apart.
struct DirectSun {
    irradiance: vec3<f32>,
    specular: vec3<f32>,
}

fn direct_sun(sun: vec3<f32>, t: f32, to_sun: vec3<f32>, n: vec3<f32>, to_eye: vec3<f32>, shininess: f32) -> DirectSun {
    var r: DirectSun;
    r.irradiance = vec3<f32>(0.0);
    r.specular = vec3<f32>(0.0);
    let l = normalize(to_sun);
    let cos = dot(n, l);
    if (cos <= 0.0 || !(t > 0.0)) {
        return r;
    }
    let h = normalize(l + to_eye);
    let spec = pow(max(dot(n, h), 0.0), shininess) * (shininess + 8.0) / (8.0 * PI);
    r.irradiance = sun * (t * cos);
    r.specular = sun * (t * spec);
    return r;
}

// lightgrid_render::shading::ground_blend_weight
fn ground_blend_weight(height_above_ground: f32, blend_height: f32) -> f32 {
    if (!(blend_height > 0.0)) {
        return 1.0;
    }
    let x = clamp(height_above_ground / blend_height, 0.0, 1.0);
    return x * x * (3.0 - 2.0 * x);
}

// lightgrid_render::shading::underwater_attenuation
fn underwater_attenuation(y: f32, water_level: f32, k: f32) -> f32 {
    let depth = water_level - y;
    if (depth > 0.0 && k > 0.0) {
        return exp(-k * depth);
    }
    return 1.0;
}

// lightgrid_render::shading::tonemap_aces
fn tonemap_aces(x_in: vec3<f32>) -> vec3<f32> {
    let x = max(x_in, vec3<f32>(0.0));
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), vec3<f32>(0.0), vec3<f32>(1.0));
}

// lightgrid_core::trilinear_corners: base corner and fractions of a clamped lookup at grid
// coordinates g.
struct Corners {
    base: vec3<u32>,
    hi: vec3<u32>,
    f: vec3<f32>,
}

fn trilinear(dims: vec3<u32>, g_in: vec3<f32>) -> Corners {
    let maxf = vec3<f32>(dims - vec3<u32>(1u));
    let g = clamp(g_in, vec3<f32>(0.0), maxf);
    let sat = select(dims - vec3<u32>(2u), vec3<u32>(0u), dims < vec3<u32>(2u));
    let base = min(vec3<u32>(floor(g)), sat);
    var out: Corners;
    out.base = base;
    out.f = clamp(g - vec3<f32>(base), vec3<f32>(0.0), vec3<f32>(1.0));
    out.hi = min(base + vec3<u32>(1u), dims - vec3<u32>(1u));
    return out;
}

// Corner c (bit 0: x, bit 1: y, bit 2: z) of a lookup, and its weight.
fn corner(t: Corners, c: u32) -> vec3<u32> {
    return vec3<u32>(
        select(t.base.x, t.hi.x, (c & 1u) != 0u),
        select(t.base.y, t.hi.y, (c & 2u) != 0u),
        select(t.base.z, t.hi.z, (c & 4u) != 0u),
    );
}

fn corner_weight(t: Corners, c: u32) -> f32 {
    let wx = select(1.0 - t.f.x, t.f.x, (c & 1u) != 0u);
    let wy = select(1.0 - t.f.y, t.f.y, (c & 2u) != 0u);
    let wz = select(1.0 - t.f.z, t.f.z, (c & 4u) != 0u);
    return wx * wy * wz;
}

// Memory order of every grid: x fastest, then z, then y.
fn grid_index(dims: vec3<u32>, p: vec3<u32>) -> u32 {
    return (p.y * dims.z + p.z) * dims.x + p.x;
}
