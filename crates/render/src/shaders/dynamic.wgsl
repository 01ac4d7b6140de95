// Dynamic lights through the grid bag: lightgrid_render::dynamic (the specification) in WGSL.
// The including shader declares dyn_lights, dyn_cells and dyn_indices.

struct DynShade {
    diffuse: vec3<f32>,
    specular: vec3<f32>,
}

fn dyn_source(l: DynLightGpu, p: vec3<f32>) -> vec3<f32> {
    if (l.colour_kind.w == 2.0) {
        let a = l.position_range.xyz;
        let ab = l.end_cos_inner.xyz - a;
        let t = clamp(dot(p - a, ab) / max(dot(ab, ab), 1e-12), 0.0, 1.0);
        return a + ab * t;
    }
    return l.position_range.xyz;
}

// lightgrid_render::dynamic::shade_one
fn dyn_shade_one(l: DynLightGpu, p: vec3<f32>, n: vec3<f32>, v: vec3<f32>, shininess: f32) -> DynShade {
    var out: DynShade;
    out.diffuse = vec3<f32>(0.0);
    out.specular = vec3<f32>(0.0);
    let to = dyn_source(l, p) - p;
    let d2 = dot(to, to);
    let d = sqrt(d2);
    let range = l.position_range.w;
    if (d >= range) {
        return out;
    }
    var dir_l = n;
    if (d > 0.0) {
        dir_l = to / d;
    }
    let ndl = dot(n, dir_l);
    if (ndl <= 0.0) {
        return out;
    }
    let x = d / range;
    let window = max(1.0 - x * x * x * x, 0.0);
    var f = window * window / (d2 + DYN_FALLOFF_EPSILON);
    if (l.colour_kind.w == 1.0) {
        let c = dot(-dir_l, l.dir_cos_outer.xyz);
        let t = clamp((c - l.dir_cos_outer.w) / (l.end_cos_inner.w - l.dir_cos_outer.w), 0.0, 1.0);
        f = f * (t * t * (3.0 - 2.0 * t));
    }
    let e = l.colour_kind.xyz * (f * ndl);
    let hl = l_plus_v(dir_l, v);
    let spec = pow(max(dot(n, hl), 0.0), shininess) * (shininess + 8.0) / (8.0 * PI);
    out.diffuse = e;
    out.specular = e * spec;
    return out;
}

fn l_plus_v(l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let s = l + v;
    let len = length(s);
    if (len > 0.0) {
        return s / len;
    }
    return vec3<f32>(0.0);
}

// lightgrid_render::dynamic::DynamicLights::shade: the lights listed in p's cell.
fn dynamic_shade(p: vec3<f32>, n: vec3<f32>, v: vec3<f32>, shininess: f32, origin_cell: vec4<f32>, dims: vec4<u32>) -> DynShade {
    var out: DynShade;
    out.diffuse = vec3<f32>(0.0);
    out.specular = vec3<f32>(0.0);
    if (dims.w == 0u) {
        return out;
    }
    let g = (p - origin_cell.xyz) / origin_cell.w;
    if (any(g < vec3<f32>(0.0))) {
        return out;
    }
    let c = vec3<u32>(floor(g));
    if (any(c >= dims.xyz)) {
        return out;
    }
    let cell = dyn_cells[c.x + dims.x * (c.z + dims.z * c.y)];
    for (var k = 0u; k < cell.y; k++) {
        let s = dyn_shade_one(dyn_lights[dyn_indices[cell.x + k]], p, n, v, shininess);
        out.diffuse += s.diffuse;
        out.specular += s.specular;
    }
    return out;
}
