//! The GPU sampling buffer equals the CPU one, and the rasteriser's shading gives known
//! answers (lightgrid_render::shading is the specification). Runs on any adapter (lavapipe in CI);
//! fails without one unless LIGHTGRID_ALLOW_NO_GPU=1.

use std::f32::consts::PI;
use std::sync::{Arc, Mutex, OnceLock};

use lightgrid_core::glam::{Mat4, UVec3, Vec2, Vec3, Vec4};
use lightgrid_core::{BinLight, Grid, GridDesc, HorizonGrid, HorizonLight, LightGrid, NUM_DIRS};
use lightgrid_gpu::GpuContext;
use lightgrid_render::shading::{linear_to_srgb8, tonemap_aces};
use lightgrid_render::{
    Camera, GpuLightGrid, GpuLightSampler, GpuPoints, GpuSampleLayer, GroundLight, LayerOwner,
    LightVolume, Lighting, LightingMode, MeshInstance, MeshMaterial, Renderer, SamplePoints,
    TextureRgba8, Vertex, View, Water, sample_points,
};

fn context() -> Option<Arc<GpuContext>> {
    GpuContext::shared_for_tests()
}

/// A grid whose bins vary with position and direction (every value distinct, > 0).
fn test_grid() -> LightGrid {
    let desc = GridDesc::new(Vec3::new(-1.0, 0.5, 2.0), 0.75, UVec3::new(5, 4, 3)).unwrap();
    let data = (0..desc.point_count())
        .map(|i| {
            BinLight(std::array::from_fn(|d| {
                let x = (i * 31 + d * 17) % 23;
                Vec3::new(0.1 + x as f32, 0.5 + (d % 5) as f32, 0.2 + (i % 7) as f32) * 0.1
            }))
        })
        .collect();
    Grid::from_trusted(desc, data)
}

#[test]
fn gpu_sampler_equals_cpu_sampler() {
    let Some(ctx) = context() else { return };
    let sampler = GpuLightSampler::new(ctx);
    let grid = test_grid();
    // Points inside, on the edges and outside (clamped), with odd normals.
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for i in 0..500 {
        let t = i as f32;
        positions.push(Vec3::new(
            -1.5 + (t * 0.37) % 4.5,
            0.2 + (t * 0.53) % 3.0,
            1.8 + (t * 0.29) % 2.0,
        ));
        normals.push(Vec3::new(
            (t * 1.3).sin(),
            (t * 0.7).cos(),
            (t * 2.1).sin() + 0.01,
        ));
    }
    for with_normals in [false, true] {
        let pts = SamplePoints {
            positions: &positions,
            normals: with_normals.then_some(&normals[..]),
        };
        let cpu = sample_points(&grid, pts).unwrap();
        let gpu = sampler.sample(&grid, pts).unwrap();
        assert_eq!(cpu.len(), gpu.len());
        for (i, (c, g)) in cpu.iter().zip(&gpu).enumerate() {
            assert!(
                c.light.min_element() > 0.0,
                "point {i}: light must be non-zero here"
            );
            let tol = 1e-5 * c.light.abs().max_element() + 1e-6;
            assert!(
                (c.light - g.light).abs().max_element() <= tol,
                "normals {with_normals} point {i}: cpu {} gpu {}",
                c.light,
                g.light
            );
            assert!(
                (c.dominant - g.dominant).abs().max_element() <= 1e-5,
                "point {i}: cpu {} gpu {}",
                c.dominant,
                g.dominant
            );
        }
    }
    // Empty batches and bad input.
    let none = SamplePoints {
        positions: &[],
        normals: None,
    };
    assert!(sampler.sample(&grid, none).unwrap().is_empty());
    let bad = [Vec3::ZERO];
    let err = sampler
        .sample(
            &grid,
            SamplePoints {
                positions: &positions[..1],
                normals: Some(&bad),
            },
        )
        .unwrap_err();
    assert!(err.to_string().contains("normals"), "{err}");
    assert_eq!(NUM_DIRS, 26);
}

const SIZE: u32 = 32;

/// One renderer for the binary (pipelines compile once), behind a lock.
fn renderer() -> Option<&'static Mutex<Renderer>> {
    static R: OnceLock<Option<Mutex<Renderer>>> = OnceLock::new();
    R.get_or_init(|| context().map(|c| Mutex::new(Renderer::new(c, SIZE, SIZE).unwrap())))
        .as_ref()
}

/// A horizontal square at height `y`, 20 m wide, normal up, every vertex lit by `light`.
fn quad(y: f32, light: Vec3) -> (Vec<Vertex>, Vec<u32>) {
    let v = |x: f32, z: f32, u: f32, w: f32| Vertex {
        position: [x, y, z],
        normal: [0.0, 1.0, 0.0],
        uv: [u, w],
        light: light.extend(1.0).to_array(),
    };
    (
        vec![
            v(-10.0, -10.0, 0.0, 0.0),
            v(10.0, -10.0, 1.0, 0.0),
            v(10.0, 10.0, 1.0, 1.0),
            v(-10.0, 10.0, 0.0, 1.0),
        ],
        // Counter-clockwise seen from above.
        vec![0, 2, 1, 0, 3, 2],
    )
}

fn view(mode: LightingMode, meshes: Vec<lightgrid_render::MeshId>) -> View {
    View {
        camera: Camera::look_at(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO),
        mode,
        sun_direction: Vec3::NEG_Y,
        sun_colour: Vec3::new(2.0, 1.5, 1.0),
        sky_ambient: Vec3::new(0.1, 0.2, 0.3),
        direct_sun: Vec3::ZERO,
        exposure: 0.7,
        water: None,
        ground_blend: 0.0,
        background: Vec3::new(9.0, 9.0, 9.0),
        meshes,
    }
}

fn add_quad(
    r: &mut Renderer,
    y: f32,
    light: Vec3,
    material: MeshMaterial,
) -> lightgrid_render::MeshId {
    let (v, i) = quad(y, light);
    let id = r.add_mesh(&v, &i, &material).unwrap();
    r.set_instances(id, &[MeshInstance::new(Mat4::IDENTITY, Vec4::ONE)])
        .unwrap();
    id
}

/// A white quad at height `y` lit per pixel by `lighting` (no vertex light).
fn lit_quad(r: &mut Renderer, y: f32, lighting: Lighting) -> lightgrid_render::MeshId {
    add_quad(
        r,
        y,
        Vec3::ZERO,
        MeshMaterial {
            lighting,
            ..Default::default()
        },
    )
}

/// A quad at height `y` lit by `lighting` through a 4 × 4 texture of `texels`, alpha
/// masked at 0.5.
fn masked_quad(
    r: &mut Renderer,
    y: f32,
    texels: Vec<[u8; 4]>,
    lighting: Lighting,
) -> lightgrid_render::MeshId {
    add_quad(
        r,
        y,
        Vec3::ZERO,
        MeshMaterial {
            texture: Some(TextureRgba8 {
                width: 4,
                height: 4,
                texels,
            }),
            alpha_cutoff: Some(0.5),
            lighting,
            ..Default::default()
        },
    )
}

/// The relative precision of `r`'s HDR image: 1e-5 in `f32`, one step (2^-10) in half
/// floats (the fallback where `f32` is not renderable).
fn hdr_tolerance(r: &Renderer) -> f32 {
    if r.hdr_format() == lightgrid_render::HDR_FORMAT {
        1e-5
    } else {
        2f32.powi(-10)
    }
}

fn assert_all_pixels(r: &Renderer, img: &lightgrid_render::Image, expected: Vec3, what: &str) {
    let tol = hdr_tolerance(r);
    for (i, p) in img.hdr.iter().enumerate() {
        let got = Vec3::new(p[0], p[1], p[2]);
        assert!(
            (got - expected).abs().max_element() <= tol * expected.max_element().max(1.0),
            "{what}: pixel {i} = {got}, expected {expected}"
        );
    }
}

/// Instances the camera cannot see are left out of the draw (`lightgrid_render::cull`)
/// without changing the image: one in view, one across the view's edge, three outside
/// (beside, behind, above the eye looking down) give the image of the first two alone,
/// bit for bit, and the one across the edge shows.
#[test]
fn culled_instances_leave_the_image_as_it_was() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let (mut v, i) = quad(0.0, Vec3::splat(3.0));
    for p in &mut v {
        p.position = [p.position[0] / 20.0, 0.0, p.position[2] / 20.0];
    }
    let material = MeshMaterial {
        lighting: Lighting::Vertex,
        ..Default::default()
    };
    let at = |x: f32, y: f32, z: f32| {
        MeshInstance::new(Mat4::from_translation(Vec3::new(x, y, z)), Vec4::ONE)
    };
    // The camera 5 m above the origin looking down sees 5 tan 30° = 2.89 m each way.
    let seen = [at(0.0, 0.0, 0.0), at(3.2, 0.0, 0.0)];
    let unseen = [at(10.0, 0.0, 0.0), at(0.0, 0.0, -20.0), at(0.0, 10.0, 0.0)];
    let id = r.add_mesh(&v, &i, &material).unwrap();
    r.set_instances(id, &[seen.as_slice(), unseen.as_slice()].concat())
        .unwrap();
    let all = r.render(&view(LightingMode::Grid, vec![id])).unwrap();
    r.set_instances(id, &seen).unwrap();
    let alone = r.render(&view(LightingMode::Grid, vec![id])).unwrap();
    assert!(all.hdr == alone.hdr && all.srgb == alone.srgb);
    r.set_instances(id, &seen[..1]).unwrap();
    let first = r.render(&view(LightingMode::Grid, vec![id])).unwrap();
    assert!(first.hdr != alone.hdr, "the instance across the edge shows");
    r.set_instances(id, &unseen).unwrap();
    let none = r.render(&view(LightingMode::Grid, vec![id])).unwrap();
    assert_all_pixels(
        &r,
        &none,
        Vec3::splat(9.0),
        "nothing in view: the background",
    );
}

#[test]
fn vertex_light_and_tone_mapping_give_known_answers() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let albedo = Vec4::new(0.5, 0.25, 1.0, 1.0);
    let e = Vec3::new(2.0, 4.0, 0.5) * PI;
    let id = add_quad(
        &mut r,
        0.0,
        e,
        MeshMaterial {
            base_colour: albedo,
            lighting: Lighting::Vertex,
            ..Default::default()
        },
    );
    let img = r.render(&view(LightingMode::Grid, vec![id])).unwrap();
    // Lambert: albedo × E / π.
    assert_all_pixels(&r, &img, albedo.truncate() * e / PI, "vertex light");
    // The sRGB image is the CPU tone map of the HDR one, within one code.
    for (h, s) in img.hdr.iter().zip(&img.srgb) {
        let t = tonemap_aces(Vec3::new(h[0], h[1], h[2]) * 0.7);
        for c in 0..3 {
            let want = linear_to_srgb8(t[c]) as i32;
            assert!((s[c] as i32 - want).abs() <= 1, "{s:?} vs {t}");
        }
    }
    // Without the grid: the unshadowed sun plus π × sky ambient.
    let img = r.render(&view(LightingMode::NoGrid, vec![id])).unwrap();
    let v = view(LightingMode::NoGrid, vec![]);
    let e = v.sun_colour + PI * v.sky_ambient;
    assert_all_pixels(&r, &img, albedo.truncate() * e / PI, "no grid");
    // Nothing drawn: the background.
    let img = r.render(&view(LightingMode::Grid, vec![])).unwrap();
    assert_all_pixels(&r, &img, Vec3::splat(9.0), "background");
}

/// Where the adapter cannot render to `Rgba32Float` (OpenGL ES, llvmpipe through GL) the
/// HDR image is drawn in half floats: every pixel is still the known answer, within one
/// half-float step (2^-10 relative: drivers may truncate, llvmpipe through GL does), and the sRGB image is the same within one code. A format
/// the adapter cannot render to, or any other format, is refused by name.
#[test]
fn half_float_hdr_target_gives_the_same_image() {
    use lightgrid_render::{HDR_FALLBACK_FORMAT, HDR_FORMAT};
    let Some(ctx) = context() else { return };
    let albedo = Vec3::new(0.5, 0.3, 0.9);
    let e = Vec3::new(2.0, 4.0, 0.5) * PI;
    let background = Vec3::new(0.3, 700.0, 1.0e-3);
    let draw = |format| {
        let mut r = Renderer::with_hdr_format(ctx.clone(), SIZE, SIZE, format)?;
        let id = add_quad(
            &mut r,
            0.0,
            e,
            MeshMaterial {
                base_colour: albedo.extend(1.0),
                lighting: Lighting::Vertex,
                ..Default::default()
            },
        );
        let mut v = view(LightingMode::Grid, vec![id]);
        v.camera = Camera::look_at(Vec3::new(0.0, 5.0, 12.0), Vec3::ZERO);
        v.background = background;
        Ok::<_, lightgrid_render::RenderError>((r.render(&v)?, hdr_tolerance(&r)))
    };
    let mut images = Vec::new();
    for format in [HDR_FORMAT, HDR_FALLBACK_FORMAT] {
        let renderable = lightgrid_render::renderable(ctx.adapter(), format);
        let (img, tol) = match draw(format) {
            Ok(drawn) => drawn,
            Err(err) => {
                assert!(!renderable, "{format:?} is renderable here: {err}");
                assert!(err.to_string().contains("hdr_format"), "{err}");
                continue;
            }
        };
        let (mut lit, mut sky) = (0, 0);
        for (i, p) in img.hdr.iter().enumerate() {
            let got = Vec3::new(p[0], p[1], p[2]);
            let near = |want: Vec3| ((got - want).abs() - want * tol).max_element() <= 0.0;
            if near(albedo * e / PI) {
                lit += 1;
            } else if near(background) {
                sky += 1;
            } else {
                panic!("{format:?}: pixel {i} = {got} is neither the quad nor the background");
            }
        }
        assert!(
            lit > 0 && sky > 0,
            "{format:?}: {lit} quad, {sky} background pixels"
        );
        images.push(img);
    }
    assert!(!images.is_empty(), "neither HDR format is renderable");
    if let [full, half] = &images[..] {
        for (f, h) in full.srgb.iter().zip(&half.srgb) {
            for c in 0..4 {
                assert!((f[c] as i32 - h[c] as i32).abs() <= 1, "{f:?} vs {h:?}");
            }
        }
    }
    let err = Renderer::with_hdr_format(ctx, SIZE, SIZE, wgpu::TextureFormat::Rgba8Unorm)
        .err()
        .expect("an 8-bit HDR target is refused");
    assert!(err.to_string().contains("hdr_format"), "{err}");
}

fn uniform_volume(average: Vec3, dominant: Vec3) -> LightVolume {
    let desc = GridDesc::new(Vec3::new(-20.0, -5.0, -20.0), 5.0, UVec3::new(9, 4, 9)).unwrap();
    let n = desc.point_count();
    LightVolume {
        desc,
        average: vec![average.extend(0.0).to_array(); n],
        dominant: vec![dominant.extend(0.0).to_array(); n],
    }
}

#[test]
fn volume_light_ground_blend_and_water_give_known_answers() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let avg = Vec3::new(0.4, 0.8, 1.2);
    // Light arriving from straight above, half directional.
    let dom = Vec3::NEG_Y * 0.5;
    r.set_light_volume(&uniform_volume(avg, dom)).unwrap();
    let surface = lit_quad(&mut r, 1.0, Lighting::Surface);
    let foliage = add_quad(
        &mut r,
        1.0,
        Vec3::ZERO,
        MeshMaterial {
            lighting: Lighting::Foliage,
            ..Default::default()
        },
    );
    // Surface: the average + dominant model, E = π avg (1 - s) + 4π avg s cos.
    let img = r.render(&view(LightingMode::Grid, vec![surface])).unwrap();
    let e = lightgrid_render::shading::irradiance_average_dominant(avg, dom, Vec3::Y);
    assert!((e - avg * (PI * 0.5 + 2.0 * PI)).abs().max_element() < 1e-5);
    assert_all_pixels(&r, &img, e / PI, "surface");
    // Foliage: π × average, whatever the normal.
    let img = r.render(&view(LightingMode::Grid, vec![foliage])).unwrap();
    assert_all_pixels(&r, &img, avg, "foliage");
    // Ground blend: the quad is 0.5 m above a ground at 0.5 m lit with E_g; with a blend
    // height of 1 m the share of the object's own light is smoothstep(0.5) = 0.5.
    let eg = Vec3::new(3.0, 0.0, 1.0);
    r.set_ground(&GroundLight {
        origin: Vec2::splat(-30.0),
        spacing: 10.0,
        width: 7,
        depth: 7,
        nodes: vec![eg.extend(0.5).to_array(); 49],
    })
    .unwrap();
    let mut v = view(LightingMode::Grid, vec![foliage]);
    v.ground_blend = 1.0;
    let img = r.render(&v).unwrap();
    assert_all_pixels(&r, &img, (eg * 0.5 + PI * avg * 0.5) / PI, "ground blend");
    // Under 2 m of water with attenuation 0.3 per metre.
    v.ground_blend = 0.0;
    v.water = Some(Water {
        level: 3.0,
        attenuation: 0.3,
    });
    let img = r.render(&v).unwrap();
    assert_all_pixels(&r, &img, avg * (-0.6f32).exp(), "underwater");
}

/// The sun kept apart from the bins (issue 14): the volume's `w` is its transmittance
/// `T`, and surfaces add `E T max(0, n·s)` with the exact direction plus its specular
/// (shininess 0: the lobe is the constant 1/π, so every pixel has one known answer);
/// foliage adds `E T / 4`. Behind the surface, with `T = 0` or with no sun apart
/// (`direct_sun` zero), nothing is added.
#[test]
fn direct_sun_from_the_volume_gives_known_answers() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let avg = Vec3::new(0.2, 0.3, 0.1);
    let t = 0.6;
    let mut vol = uniform_volume(avg, Vec3::ZERO);
    for a in &mut vol.average {
        a[3] = t;
    }
    r.set_light_volume(&vol).unwrap();
    let (k, albedo) = (0.7, Vec4::new(0.5, 0.8, 1.0, 1.0));
    let surface = add_quad(
        &mut r,
        1.0,
        Vec3::ZERO,
        MeshMaterial {
            base_colour: albedo,
            specular: k,
            shininess: 0.0,
            ..Default::default()
        },
    );
    let foliage = lit_quad(&mut r, 1.0, Lighting::Foliage);
    let e = Vec3::new(2.0, 1.5, 1.0);
    let to_sun = Vec3::new(0.3, 1.0, 0.2).normalize();
    let mut v = view(LightingMode::Grid, vec![surface]);
    v.direct_sun = e;
    v.sun_direction = -to_sun;
    let img = r.render(&v).unwrap();
    let diffuse = albedo.truncate() * (PI * avg + e * (t * to_sun.y)) / PI;
    assert_all_pixels(
        &r,
        &img,
        diffuse + k * e * t / PI,
        "surface with the direct sun",
    );
    // The CPU specification at one normal and view (the WGSL's twin).
    let (d, sp) =
        lightgrid_render::shading::direct_sun(e, t, to_sun, Vec3::Y, Vec3::new(0.1, 1.0, 0.0), 0.0);
    assert!((d - e * t * to_sun.y).abs().max_element() < 1e-6);
    assert!((sp - e * t / PI).abs().max_element() < 1e-6);
    // Foliage: pi x average plus E T / 4.
    v.meshes = vec![foliage];
    let img = r.render(&v).unwrap();
    assert_all_pixels(
        &r,
        &img,
        avg + e * t / (4.0 * PI),
        "foliage with the direct sun",
    );
    // The sun below the surface's horizon, no transmittance, no sun apart: the bins only.
    v.meshes = vec![surface];
    v.sun_direction = Vec3::new(0.3, 1.0, 0.2).normalize();
    let img = r.render(&v).unwrap();
    assert_all_pixels(&r, &img, albedo.truncate() * avg, "sun behind the surface");
    v.sun_direction = -to_sun;
    v.direct_sun = Vec3::ZERO;
    let img = r.render(&v).unwrap();
    assert_all_pixels(&r, &img, albedo.truncate() * avg, "no sun apart");
    for a in &mut vol.average {
        a[3] = 0.0;
    }
    r.set_light_volume(&vol).unwrap();
    v.direct_sun = e;
    let img = r.render(&v).unwrap();
    assert_all_pixels(&r, &img, albedo.truncate() * avg, "full shadow");
}

#[test]
fn alpha_mask_and_emissive_tint() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    // Left half of the texture transparent.
    let texels = (0..16)
        .map(|i| {
            if i % 4 < 2 {
                [255, 0, 0, 0]
            } else {
                [255, 255, 255, 255]
            }
        })
        .collect();
    let masked = masked_quad(&mut r, 0.0, texels, Lighting::Emissive);
    let img = r.render(&view(LightingMode::Grid, vec![masked])).unwrap();
    // Every pixel is either background (alpha under the cutoff) or the texture's
    // colour (red 1 everywhere; green filtered between 0 and 1), and both occur.
    let bg = img.hdr.iter().filter(|p| p[0] == 9.0).count();
    let drawn = img.hdr.iter().filter(|p| (p[0] - 1.0).abs() < 1e-6).count();
    let total = (SIZE * SIZE) as usize;
    assert_eq!(bg + drawn, total);
    assert!(
        bg > total / 10 && drawn > total / 10,
        "bg {bg} drawn {drawn}"
    );
    // Emissive tint is the HDR colour.
    let mut r2 = r;
    let glow = add_quad(
        &mut r2,
        0.0,
        Vec3::ZERO,
        MeshMaterial {
            lighting: Lighting::Emissive,
            ..Default::default()
        },
    );
    r2.set_instances(
        glow,
        &[MeshInstance::new(
            Mat4::IDENTITY,
            Vec4::new(5.0, 0.5, 0.05, 1.0),
        )],
    )
    .unwrap();
    let img = r2.render(&view(LightingMode::Grid, vec![glow])).unwrap();
    assert_all_pixels(&r2, &img, Vec3::new(5.0, 0.5, 0.05), "emissive");
    // Bad input is a typed error naming the field.
    let mut bad = view(LightingMode::Grid, vec![glow]);
    bad.exposure = f32::NAN;
    assert!(
        r2.render(&bad)
            .unwrap_err()
            .to_string()
            .contains("exposure")
    );
    let (v, _) = quad(0.0, Vec3::ZERO);
    let err = r2
        .add_mesh(&v, &[0, 1, 9], &MeshMaterial::default())
        .unwrap_err();
    assert!(err.to_string().contains("indices"), "{err}");
}

/// `render_pair` draws the geometry once into two targets: its images are those of
/// `render` lit by the grids and without them, bit for bit (HDR and sRGB), whatever the
/// view's mode says. The scene mixes every lighting kind the demo draws (vertex light,
/// a volume that varies point to point with the sun kept apart, foliage, an alpha mask,
/// instances at several heights) seen at a slant, so the two images differ everywhere
/// the geometry is.
#[test]
fn a_pair_of_images_equals_the_two_renders() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let mut vol = uniform_volume(Vec3::ZERO, Vec3::ZERO);
    for (i, (a, d)) in vol.average.iter_mut().zip(&mut vol.dominant).enumerate() {
        let f = (i % 7) as f32 / 7.0;
        *a = [0.2 + f, 0.5 - 0.3 * f, 0.3, 0.2 + 0.7 * f];
        *d = [0.1 * f, -0.4, 0.05, 0.0];
    }
    r.set_light_volume(&vol).unwrap();
    let texels = (0..16)
        .map(|i| {
            if i % 3 == 0 {
                [255, 0, 0, 0]
            } else {
                [200, 255, 90, 255]
            }
        })
        .collect();
    let meshes = [
        add_quad(
            &mut r,
            -1.0,
            Vec3::new(1.0, 2.0, 0.5),
            MeshMaterial {
                lighting: Lighting::Vertex,
                ..Default::default()
            },
        ),
        lit_quad(&mut r, 0.0, Lighting::Surface),
        masked_quad(&mut r, 0.5, texels, Lighting::Foliage),
    ];
    let shrink = |x: f32, y: f32, s: f32| {
        MeshInstance::new(
            Mat4::from_scale_rotation_translation(
                Vec3::splat(s),
                lightgrid_core::glam::Quat::from_rotation_x(0.4 * x),
                Vec3::new(x, y, -x),
            ),
            Vec4::new(0.9, 1.0, 0.8, 1.0),
        )
    };
    r.set_instances(meshes[1], &[shrink(-2.0, 0.0, 0.1), shrink(1.5, 0.3, 0.08)])
        .unwrap();
    let mut v = view(LightingMode::Grid, meshes.to_vec());
    v.camera = Camera::look_at(Vec3::new(3.0, 4.0, 5.0), Vec3::ZERO);
    v.sun_direction = Vec3::new(0.3, -0.8, 0.2).normalize();
    v.direct_sun = Vec3::new(2.0, 1.8, 1.5);
    let grid = r.render(&v).unwrap();
    let mut plain = v.clone();
    plain.mode = LightingMode::NoGrid;
    let no_grid = r.render(&plain).unwrap();
    assert!(
        grid.hdr != no_grid.hdr,
        "the two modes differ in this scene"
    );
    for mode in [LightingMode::Grid, LightingMode::NoGrid] {
        let mut w = v.clone();
        w.mode = mode;
        let [a, b] = r.render_pair(&w).unwrap();
        assert!(
            a.hdr == grid.hdr && a.srgb == grid.srgb,
            "{mode:?}: lit by the grids"
        );
        assert!(
            b.hdr == no_grid.hdr && b.srgb == no_grid.srgb,
            "{mode:?}: without them"
        );
    }
    // A single render after a pair is the single render again.
    assert!(r.render(&plain).unwrap().hdr == no_grid.hdr);
}

fn dynamic_lights() -> lightgrid_render::DynamicLights {
    let lights = lightgrid_render::dynamic::scatter(
        600,
        12345,
        Vec3::new(-15.0, 0.0, -15.0),
        Vec3::new(15.0, 4.0, 15.0),
    );
    lightgrid_render::DynamicLights::build(lights, 2.0).unwrap()
}

#[test]
fn gpu_dynamic_lights_equal_cpu_brute_force() {
    let Some(ctx) = context() else { return };
    let lights = dynamic_lights();
    let shader = lightgrid_render::GpuDynamicShader::new(ctx);
    let points: Vec<(Vec3, Vec3, Vec3)> = (0..4000)
        .map(|i| {
            let t = i as f32;
            (
                Vec3::new(
                    (t * 0.37) % 34.0 - 17.0,
                    (t * 0.11) % 5.0 - 0.5,
                    (t * 0.73) % 34.0 - 17.0,
                ),
                Vec3::new((t * 1.3).sin(), 1.0, (t * 0.7).cos()).normalize(),
                Vec3::new((t * 0.3).cos(), 0.8, (t * 2.1).sin()).normalize(),
            )
        })
        .collect();
    let gpu = shader.shade(&lights, &points, 24.0).unwrap();
    let mut lit = 0;
    for ((p, n, v), g) in points.iter().zip(&gpu) {
        let c = lights.shade_brute_force(*p, *n, *v, 24.0);
        let tol_d = 1e-4 * c.diffuse.max_element() + 1e-6;
        let tol_s = 1e-3 * c.specular.max_element() + 1e-6;
        assert!(
            (c.diffuse - g.diffuse).abs().max_element() <= tol_d,
            "{p}: cpu {} gpu {}",
            c.diffuse,
            g.diffuse
        );
        assert!(
            (c.specular - g.specular).abs().max_element() <= tol_s,
            "{p}: cpu {} gpu {}",
            c.specular,
            g.specular
        );
        lit += (c.diffuse != Vec3::ZERO) as u32;
    }
    assert!(
        lit > 500,
        "only {lit} points lit: the test would prove little"
    );
}

#[test]
fn dynamic_point_light_in_the_mesh_shader_gives_the_cpu_answer() {
    use lightgrid_render::{DynamicLight, DynamicLights, LightKind};
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let lights = DynamicLights::build(
        vec![DynamicLight {
            kind: LightKind::Point {
                position: Vec3::new(0.3, 1.5, -0.2),
            },
            colour: Vec3::new(3.0, 2.0, 1.0),
            range: 8.0,
        }],
        1.0,
    )
    .unwrap();
    r.set_dynamic_lights(&lights).unwrap();
    let id = add_quad(
        &mut r,
        0.0,
        Vec3::ZERO,
        MeshMaterial {
            lighting: Lighting::Vertex,
            ..Default::default()
        },
    );
    let v = view(LightingMode::Grid, vec![id]);
    let img = r.render(&v).unwrap();
    // Each pixel's world point on the quad (y = 0), by unprojecting its centre.
    let inv = v.camera.view_proj(1.0).inverse();
    let mut checked = 0;
    for y in 0..SIZE {
        for x in 0..SIZE {
            let ndc = lightgrid_core::glam::Vec2::new(
                (x as f32 + 0.5) / SIZE as f32 * 2.0 - 1.0,
                1.0 - (y as f32 + 0.5) / SIZE as f32 * 2.0,
            );
            let a = inv.project_point3(ndc.extend(0.0));
            let b = inv.project_point3(ndc.extend(1.0));
            let t = a.y / (a.y - b.y);
            let p = a + (b - a) * t;
            let to_eye = (v.camera.position - p).normalize();
            let e = lights.shade(p, Vec3::Y, to_eye, 32.0).diffuse;
            let got = img.hdr[(y * SIZE + x) as usize];
            let got = Vec3::new(got[0], got[1], got[2]);
            // Vertex light is zero: the pixel is albedo 1 × E / π (no specular: the
            // mesh's specular strength is 0).
            assert!(
                (got - e / PI).abs().max_element() <= 2e-3 * (e / PI).max_element() + 1e-5,
                "pixel ({x}, {y}) at {p}: {got} vs {}",
                e / PI
            );
            checked += 1;
        }
    }
    assert_eq!(checked, SIZE * SIZE);
    // No lights again for the other tests of this binary.
    r.set_dynamic_lights(&DynamicLights::build(Vec::new(), 1.0).unwrap())
        .unwrap();
}

#[test]
fn bin_grid_uploads_only_the_changed_box() {
    let Some(ctx) = context() else { return };
    let grid = test_grid();
    let gpu = lightgrid_render::GpuLightGrid::new(ctx, &grid).unwrap();
    assert_eq!(gpu.read().unwrap(), grid);
    // Change a box on the CPU, upload only that box.
    let mut changed = grid.clone();
    let (lo, hi) = (
        lightgrid_core::glam::UVec3::new(1, 1, 0),
        lightgrid_core::glam::UVec3::new(3, 2, 1),
    );
    let d = *changed.desc();
    for y in lo.y..=hi.y {
        for z in lo.z..=hi.z {
            for x in lo.x..=hi.x {
                let i = d.index_unchecked(lightgrid_core::glam::UVec3::new(x, y, z));
                changed.data_mut()[i] = BinLight::uniform(Vec3::splat(7.0 + i as f32));
            }
        }
    }
    let bytes = gpu.upload_region(&changed, lo, hi).unwrap();
    assert_eq!(bytes, 3 * 2 * 2 * 26 * 12, "only the box's points");
    assert_eq!(gpu.read().unwrap(), changed);
    assert!(gpu.upload_region(&changed, hi, lo).is_err());
}

#[test]
fn toggling_a_local_light_uploads_only_its_box() {
    use lightgrid_light_volumes::{
        CompressedVolume, Light, LightKind, LightSet, TraceParams, trace_light,
    };
    use lightgrid_material_voxelizer::model::{Model, SurfaceMaterial, Triangle};
    let Some(ctx) = context() else { return };
    let p = |x: f32, z: f32| Vec3::new(x, 0.0, z);
    let tri = |a, b, c| Triangle {
        positions: [a, b, c],
        uvs: [Vec2::ZERO; 3],
        material: 0,
        part: 0,
    };
    let model = Model {
        triangles: vec![
            tri(p(-4.0, -4.0), p(4.0, -4.0), p(4.0, 4.0)),
            tri(p(-4.0, -4.0), p(4.0, 4.0), p(-4.0, 4.0)),
        ],
        materials: vec![SurfaceMaterial::default()],
        textures: Vec::new(),
    };
    let scene = lightgrid_material_voxelizer::voxelize::RayScene::new(
        &model,
        obvhs::BvhBuildParams::fast_build(),
    );
    let desc = GridDesc::new(Vec3::new(-4.0, -0.25, -4.0), 0.5, UVec3::new(17, 8, 17)).unwrap();
    let mut set = LightSet::new(desc).unwrap();
    let mut ids = Vec::new();
    for pos in [Vec3::new(-2.5, 1.0, -2.5), Vec3::new(2.5, 1.0, 2.5)] {
        let l = Light {
            kind: LightKind::Spot {
                position: pos,
                direction: Vec3::NEG_Y,
                inner: 0.2,
                outer: 0.5,
            },
            colour: Vec3::ONE,
            intensity: 3.0,
        };
        let params = TraceParams {
            rays: 20_000,
            ..TraceParams::preview()
        };
        let (v, _) = trace_light(&scene, &desc, &l, &params, &|_, _| {}).unwrap();
        ids.push(
            set.add(&CompressedVolume::compress(&v, 0), l.colour, l.intensity)
                .unwrap(),
        );
    }
    set.take_dirty();
    let gpu = lightgrid_render::GpuLightGrid::new(ctx, set.grid()).unwrap();
    set.set_on(ids[0], false).unwrap();
    let r = set.take_dirty().unwrap();
    let bytes = gpu.upload_region(set.grid(), r.lo, r.hi).unwrap();
    assert_eq!(bytes, r.point_count() as u64 * 26 * 12);
    assert!(
        r.point_count() < desc.point_count(),
        "the box is not the whole grid"
    );
    assert_eq!(&gpu.read().unwrap(), set.grid());
}

/// A grid on `desc` whose bins vary with position, direction and `seed` (all > 0).
fn varied_grid(desc: GridDesc, seed: usize) -> LightGrid {
    let data = (0..desc.point_count())
        .map(|i| {
            BinLight(std::array::from_fn(|d| {
                let x = (i * 31 + d * 17 + seed * 7) % 23;
                Vec3::new(
                    0.1 + x as f32,
                    0.5 + ((d + seed) % 5) as f32,
                    0.2 + (i % 7) as f32,
                ) * 0.1
            }))
        })
        .collect();
    Grid::from_trusted(desc, data)
}

/// The layer rule, on the CPU: the last layer owning `p` (lightgrid_terrain_lod::Owner::owns).
fn owning<'a>(layers: &[(&'a LightGrid, Option<LayerOwner>)], p: Vec3) -> Option<&'a LightGrid> {
    layers.iter().rev().find_map(|(g, o)| {
        let owns = o.is_none_or(|o| {
            ((Vec2::new(p.x, p.z) - o.origin) / o.size)
                .floor()
                .as_ivec2()
                == o.index
                && g.desc().contains(p)
        });
        owns.then_some(*g)
    })
}

/// Layered sampling on the device (a coarse grid under two owned finer ones, as the
/// hierarchy draws) equals the CPU: per point, the last owning layer's
/// `sample_points`; for listed points with and without normals and for a generated
/// lattice. Points no layer owns keep the zero the output starts with.
#[test]
fn layered_device_sampling_equals_the_cpu_rule() {
    let Some(ctx) = context() else { return };
    let sampler = GpuLightSampler::new(ctx.clone());
    let world = varied_grid(
        GridDesc::new(Vec3::new(-8.0, 0.0, -8.0), 2.0, UVec3::new(9, 4, 9)).unwrap(),
        0,
    );
    let a = varied_grid(
        GridDesc::new(Vec3::new(-4.0, 0.0, -4.0), 1.0, UVec3::new(5, 5, 5)).unwrap(),
        1,
    );
    let b = varied_grid(
        GridDesc::new(Vec3::new(0.0, 0.0, 0.0), 0.5, UVec3::new(9, 9, 9)).unwrap(),
        2,
    );
    let owner = |x, z| {
        Some(LayerOwner {
            origin: Vec2::splat(-8.0),
            size: 4.0,
            index: lightgrid_core::glam::IVec2::new(x, z),
        })
    };
    let cpu_layers = [(&world, None), (&a, owner(1, 1)), (&b, owner(2, 2))];
    let dev: Vec<GpuLightGrid> = cpu_layers
        .iter()
        .map(|(g, _)| GpuLightGrid::new(ctx.clone(), g).unwrap())
        .collect();
    let layers: Vec<GpuSampleLayer> = dev
        .iter()
        .zip(&cpu_layers)
        .map(|(g, (_, o))| GpuSampleLayer {
            grid: g,
            owner: *o,
            sun: None,
            horizon: None,
        })
        .collect();
    let (positions, normals) = point_cloud(3);
    let compare = |cpu: &[lightgrid_render::SampledLight],
                   gpu: &[lightgrid_render::SampledLight],
                   what: &str| {
        assert_eq!(cpu.len(), gpu.len());
        for (i, (c, g)) in cpu.iter().zip(gpu).enumerate() {
            let tol = 1e-5 * c.light.abs().max_element() + 1e-6;
            assert!(
                (c.light - g.light).abs().max_element() <= tol
                    && (c.dominant - g.dominant).abs().max_element() <= 1e-5,
                "{what} point {i}: cpu {c:?} gpu {g:?}"
            );
        }
    };
    let cpu_sample = |pts: &[Vec3], ns: Option<&[Vec3]>| -> Vec<lightgrid_render::SampledLight> {
        pts.iter()
            .enumerate()
            .map(|(i, p)| {
                let g = owning(&cpu_layers, *p).unwrap();
                let n = ns.map(|n| &n[i..i + 1]);
                sample_points(
                    g,
                    SamplePoints {
                        positions: &pts[i..i + 1],
                        normals: n,
                    },
                )
                .unwrap()[0]
            })
            .collect()
    };
    let mut fine = [0usize; 3];
    for p in &positions {
        let g = owning(&cpu_layers, *p).unwrap();
        fine[[&world, &a, &b]
            .iter()
            .position(|x| std::ptr::eq(*x, g))
            .unwrap()] += 1;
    }
    assert!(fine.iter().all(|&n| n > 100), "{fine:?}");
    for with_normals in [false, true] {
        let ns = with_normals.then_some(&normals[..]);
        let pts = SamplePoints {
            positions: &positions,
            normals: ns,
        };
        let gpu = sampler
            .sample_layers(&layers, GpuPoints::List(pts))
            .unwrap()
            .read()
            .unwrap();
        compare(
            &cpu_sample(&positions, ns),
            &gpu,
            &format!("normals {with_normals}"),
        );
    }
    // A lattice generated on the device, including points on the owners' edges.
    let lattice = GridDesc::new(Vec3::new(-8.0, -0.5, -8.0), 0.5, UVec3::new(33, 12, 33)).unwrap();
    let lpos: Vec<Vec3> = (0..lattice.point_count())
        .map(|i| lattice.position(lattice.coords(i).unwrap()))
        .collect();
    let gpu = sampler
        .sample_layers(&layers, GpuPoints::Lattice(lattice))
        .unwrap();
    assert_eq!(gpu.count(), lattice.point_count());
    compare(&cpu_sample(&lpos, None), &gpu.read().unwrap(), "lattice");
    // Without the world layer, points outside both nodes are untouched: zero.
    let only_nodes = sampler
        .sample_layers(
            &layers[1..],
            GpuPoints::List(SamplePoints {
                positions: &positions,
                normals: None,
            }),
        )
        .unwrap()
        .read()
        .unwrap();
    for (p, s) in positions.iter().zip(&only_nodes) {
        let owned = owning(&cpu_layers[1..], *p).is_some();
        assert_eq!(owned, s.light != Vec3::ZERO, "{p}: {s:?}");
    }
    // A grid of another device is refused, naming the layer.
    let other = Arc::new(GpuContext::new().unwrap());
    let foreign = GpuLightGrid::new(other, &world).unwrap();
    let e = sampler
        .sample_layers(
            &[GpuSampleLayer {
                grid: &foreign,
                owner: None,
                sun: None,
                horizon: None,
            }],
            GpuPoints::Lattice(lattice),
        )
        .err()
        .unwrap();
    assert!(e.to_string().contains("layers[0]"), "{e}");
}

/// Light sampled on the device and drawn from where it lies (light volume, vertex
/// light, ground light) gives the image that uploading the CPU samples gives.
#[test]
fn drawing_device_samples_equals_drawing_uploaded_samples() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let ctx = r.context().clone();
    let sampler = GpuLightSampler::new(ctx.clone());
    let grid = varied_grid(
        GridDesc::new(Vec3::new(-12.0, -1.0, -12.0), 3.0, UVec3::new(9, 4, 9)).unwrap(),
        5,
    );
    let dev = GpuLightGrid::new(ctx, &grid).unwrap();
    let layer = [GpuSampleLayer {
        grid: &dev,
        owner: None,
        sun: None,
        horizon: None,
    }];
    let close = |a: &lightgrid_render::Image, b: &lightgrid_render::Image, what: &str| {
        let mut lit = 0;
        for (i, (p, q)) in a.hdr.iter().zip(&b.hdr).enumerate() {
            let (p, q) = (Vec3::new(p[0], p[1], p[2]), Vec3::new(q[0], q[1], q[2]));
            assert!(
                (p - q).abs().max_element() <= 1e-4 * p.max_element().max(1e-3),
                "{what}: pixel {i} uploaded {p} device {q}"
            );
            lit += (p.max_element() > 0.01) as usize;
        }
        assert!(lit > a.hdr.len() / 2, "{what}: {lit} lit pixels");
    };
    // Light volume.
    let desc = GridDesc::new(Vec3::new(-11.0, -0.5, -11.0), 1.0, UVec3::new(23, 4, 23)).unwrap();
    let surface = lit_quad(&mut r, 1.0, Lighting::Surface);
    r.set_light_volume(&LightVolume::from_field(&grid, desc).unwrap())
        .unwrap();
    let uploaded = r.render(&view(LightingMode::Grid, vec![surface])).unwrap();
    let samples = sampler
        .sample_layers(&layer, GpuPoints::Lattice(desc))
        .unwrap();
    r.set_light_volume_samples(desc, &samples).unwrap();
    let device = r.render(&view(LightingMode::Grid, vec![surface])).unwrap();
    close(&uploaded, &device, "light volume");
    // Vertex light: irradiance on the quad's normals at its vertices.
    let (v, i) = quad(0.5, Vec3::ZERO);
    let vertex = r
        .add_mesh(
            &v,
            &i,
            &MeshMaterial {
                lighting: Lighting::Vertex,
                ..Default::default()
            },
        )
        .unwrap();
    r.set_instances(vertex, &[MeshInstance::new(Mat4::IDENTITY, Vec4::ONE)])
        .unwrap();
    let positions: Vec<Vec3> = v.iter().map(|v| Vec3::from(v.position)).collect();
    let normals: Vec<Vec3> = v.iter().map(|v| Vec3::from(v.normal)).collect();
    let pts = SamplePoints {
        positions: &positions,
        normals: Some(&normals),
    };
    let cpu = sample_points(&grid, pts).unwrap();
    let lit: Vec<Vertex> = v
        .iter()
        .zip(&cpu)
        .map(|(v, s)| Vertex {
            light: s.light.extend(1.0).to_array(),
            ..*v
        })
        .collect();
    r.update_vertices(vertex, &lit).unwrap();
    let uploaded = r.render(&view(LightingMode::Grid, vec![vertex])).unwrap();
    r.update_vertices(vertex, &v).unwrap();
    let dark = r.render(&view(LightingMode::Grid, vec![vertex])).unwrap();
    assert!(
        dark.hdr.iter().all(|p| p[..3] == [0.0; 3]),
        "unlit vertices draw black"
    );
    let samples = sampler.sample_layers(&layer, GpuPoints::List(pts)).unwrap();
    r.set_vertex_light_samples(vertex, &samples).unwrap();
    let device = r.render(&view(LightingMode::Grid, vec![vertex])).unwrap();
    close(&uploaded, &device, "vertex light");
    // Ground light: 7 x 7 nodes at height 0.5 under the Surface quad, blended in.
    let nodes: Vec<Vec3> = (0..49)
        .map(|k| {
            Vec3::new(
                -30.0 + 10.0 * (k % 7) as f32,
                0.5,
                -30.0 + 10.0 * (k / 7) as f32,
            )
        })
        .collect();
    let up = vec![Vec3::Y; 49];
    let npts = SamplePoints {
        positions: &nodes,
        normals: Some(&up),
    };
    let ground = |light: &[Vec3]| GroundLight {
        origin: Vec2::splat(-30.0),
        spacing: 10.0,
        width: 7,
        depth: 7,
        nodes: light.iter().map(|e| e.extend(0.5).to_array()).collect(),
    };
    let cpu: Vec<Vec3> = sample_points(&grid, npts)
        .unwrap()
        .iter()
        .map(|s| s.light)
        .collect();
    r.set_ground(&ground(&cpu)).unwrap();
    let mut v = view(LightingMode::Grid, vec![surface]);
    v.ground_blend = 1.0;
    let uploaded = r.render(&v).unwrap();
    r.set_ground(&ground(&[Vec3::ZERO; 49])).unwrap();
    let samples = sampler
        .sample_layers(&layer, GpuPoints::List(npts))
        .unwrap();
    r.set_ground_light_samples(&samples).unwrap();
    let device = r.render(&v).unwrap();
    close(&uploaded, &device, "ground light");
    // Wrong counts are refused.
    let e = r.set_ground_light_samples(
        &sampler
            .sample_layers(&layer, GpuPoints::Lattice(desc))
            .unwrap(),
    );
    assert!(e.unwrap_err().to_string().contains("samples.count()"));
}

/// 3000 random points in a 10 x 5 x 10 m box and random (not unit) normals.
fn point_cloud(seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = fastrand::Rng::with_seed(seed);
    let positions: Vec<Vec3> = (0..3000)
        .map(|_| {
            Vec3::new(
                rng.f32() * 10.0 - 5.0,
                rng.f32() * 5.0 - 0.5,
                rng.f32() * 10.0 - 5.0,
            )
        })
        .collect();
    let normals: Vec<Vec3> = (0..3000)
        .map(|_| Vec3::new(rng.f32() - 0.5, rng.f32() - 0.3, rng.f32() - 0.5))
        .collect();
    (positions, normals)
}

/// A layer lit as the hierarchy lights it with the sun kept apart: `sky × scale +
/// scattered × E`, and the transmittance (the CPU rule of `sample_layers_lit`).
/// With horizon halves, those of the sky scaled plus the sun's (its bins split evenly
/// where it has none) times `E`, as `lightgrid_terrain_lod::Hierarchy` reads them.
struct LitLayer<'a> {
    sky: &'a LightGrid,
    scattered: &'a LightGrid,
    t: &'a Grid<f32>,
    scale: Vec3,
    sun: Vec3,
    halves: (Option<&'a HorizonGrid>, Option<&'a HorizonGrid>),
}

impl lightgrid_core::LightField for LitLayer<'_> {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, lightgrid_core::GridError> {
        Ok(self.sky.light(p, n)? * self.scale + self.scattered.light(p, n)? * self.sun)
    }
    fn horizon(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<Option<HorizonLight>, lightgrid_core::GridError> {
        let read = |h: &HorizonGrid| match n {
            Some(n) => h.sample_biased(p, n),
            None => h.sample(p),
        };
        let Some(sky) = self.halves.0 else {
            return Ok(None);
        };
        let sun = match self.halves.1 {
            Some(h) => read(h)?,
            None => HorizonLight::even(&self.scattered.light(p, n)?),
        };
        Ok(Some(read(sky)? * self.scale + sun * self.sun))
    }
    fn sun_transmittance(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<f32, lightgrid_core::GridError> {
        Ok(match n {
            Some(n) => self.t.sample_biased(p, n)?,
            None => self.t.sample(p)?,
        }
        .clamp(0.0, 1.0))
    }
}

/// Random downward halves of `bins`' horizontal bins (each a share of its bin).
fn varied_halves(bins: &LightGrid, seed: u64) -> HorizonGrid {
    let mut rng = fastrand::Rng::with_seed(seed);
    let data = bins
        .data()
        .iter()
        .map(|b| {
            HorizonLight(std::array::from_fn(|k| {
                b.0[lightgrid_core::dirs::FIRST_HORIZONTAL + k] * rng.f32()
            }))
        })
        .collect();
    Grid::from_trusted(*bins.desc(), data)
}

/// Layers lit as the hierarchy lights them, on the CPU and on the device: per grid
/// descriptor its sky bins, scattered sun and transmittance (varied, seeded by layer).
struct LitGrids {
    sky: Vec<LightGrid>,
    scat: Vec<LightGrid>,
    ts: Vec<Grid<f32>>,
    dev_sky: Vec<GpuLightGrid>,
    dev_scat: Vec<GpuLightGrid>,
    dev_t: Vec<wgpu::Buffer>,
}

impl LitGrids {
    fn new(ctx: &Arc<GpuContext>, descs: &[GridDesc]) -> Self {
        let sky: Vec<LightGrid> = descs
            .iter()
            .enumerate()
            .map(|(i, d)| varied_grid(*d, i))
            .collect();
        let scat: Vec<LightGrid> = descs
            .iter()
            .enumerate()
            .map(|(i, d)| varied_grid(*d, 10 + i))
            .collect();
        let ts: Vec<Grid<f32>> = descs
            .iter()
            .enumerate()
            .map(|(k, d)| {
                Grid::from_trusted(
                    *d,
                    (0..d.point_count())
                        .map(|i| ((i * 37 + k * 11) % 101) as f32 / 100.0)
                        .collect(),
                )
            })
            .collect();
        let up = |g: &LightGrid| GpuLightGrid::new(ctx.clone(), g).unwrap();
        Self {
            dev_sky: sky.iter().map(up).collect(),
            dev_scat: scat.iter().map(up).collect(),
            dev_t: ts
                .iter()
                .map(|t| lightgrid_render::transmittance_buffer(ctx, t.data()))
                .collect(),
            sky,
            scat,
            ts,
        }
    }

    /// Layer `i` on the device, owned by `owner`, with `horizon` halves.
    fn layer<'a>(
        &'a self,
        i: usize,
        owner: Option<LayerOwner>,
        horizon: Option<&'a lightgrid_render::GpuHorizon>,
    ) -> GpuSampleLayer<'a> {
        GpuSampleLayer {
            grid: &self.dev_sky[i],
            owner,
            sun: Some(lightgrid_render::GpuLayerSun {
                scattered: &self.dev_scat[i],
                transmittance: &self.dev_t[i],
            }),
            horizon,
        }
    }
}

/// `points` (with `normals` if given) sampled on the device from `layers` under `light`.
fn read_lit(
    sampler: &GpuLightSampler,
    layers: &[GpuSampleLayer<'_>],
    (positions, normals): (&[Vec3], Option<&[Vec3]>),
    light: &lightgrid_render::LayerLight,
) -> Vec<lightgrid_render::SampledLight> {
    sampler
        .sample_layers_lit(
            layers,
            GpuPoints::List(SamplePoints { positions, normals }),
            light,
        )
        .unwrap()
        .read()
        .unwrap()
}

/// Layered device sampling with the sky scaled and the sun kept apart equals the CPU
/// rule: per point the last owning layer's `sky × scale + scattered × E` through
/// `sample_points`, the transmittance in `w`, and for points with normals the direct sun
/// `E T max(0, n · s)` added (as vertex light holds it); with horizon halves (the
/// coarse layer the sky's alone, the fine one the sky's and the sun's), read through
/// them as the CPU sampler reads them. A layer without sun responses, or with halves
/// not on its grid, is refused by name.
#[test]
fn layered_device_sampling_with_the_sun_apart() {
    use lightgrid_render::{GpuHorizon, LayerLight};
    let Some(ctx) = context() else { return };
    let sampler = GpuLightSampler::new(ctx.clone());
    let descs = [
        GridDesc::new(Vec3::new(-8.0, 0.0, -8.0), 2.0, UVec3::new(9, 4, 9)).unwrap(),
        GridDesc::new(Vec3::new(0.0, 0.0, 0.0), 0.5, UVec3::new(9, 9, 9)).unwrap(),
    ];
    let grids = LitGrids::new(&ctx, &descs);
    let (sky, scat, ts) = (&grids.sky, &grids.scat, &grids.ts);
    let owners = [
        None,
        Some(LayerOwner {
            origin: Vec2::splat(-8.0),
            size: 4.0,
            index: lightgrid_core::glam::IVec2::new(2, 2),
        }),
    ];
    let (scale, e, to_sun) = (
        Vec3::new(0.5, 0.8, 1.2),
        Vec3::new(3.0, 2.5, 2.0),
        Vec3::new(0.3, 0.8, -0.4).normalize(),
    );
    let sky_h: Vec<HorizonGrid> = sky
        .iter()
        .enumerate()
        .map(|(i, g)| varied_halves(g, 20 + i as u64))
        .collect();
    let scat_h = varied_halves(&scat[1], 30);
    let dev_h = [
        GpuHorizon::new(ctx.clone(), &sky_h[0], None).unwrap(),
        GpuHorizon::new(ctx.clone(), &sky_h[1], Some(&scat_h)).unwrap(),
    ];
    let cpu_h = [(Some(&sky_h[0]), None), (Some(&sky_h[1]), Some(&scat_h))];
    let light = LayerLight {
        sky_scale: scale,
        sun: Some((to_sun, e)),
    };
    let (positions, normals) = point_cloud(9);
    let normals: Vec<Vec3> = normals.iter().map(|n| n.normalize()).collect();
    let cpu_layers: Vec<(&LightGrid, Option<LayerOwner>)> = sky.iter().zip(owners).collect();
    for (with_normals, with_halves) in [(false, false), (true, false), (true, true)] {
        let layers: Vec<GpuSampleLayer> = (0..2)
            .map(|i| grids.layer(i, owners[i], with_halves.then_some(&dev_h[i])))
            .collect();
        let ns = with_normals.then_some(&normals[..]);
        let gpu = read_lit(&sampler, &layers, (&positions, ns), &light);
        for (i, p) in positions.iter().enumerate() {
            let g = owning(&cpu_layers, *p).unwrap();
            let k = sky.iter().position(|s| std::ptr::eq(s, g)).unwrap();
            let field = LitLayer {
                sky: &sky[k],
                scattered: &scat[k],
                t: &ts[k],
                scale,
                sun: e,
                halves: if with_halves { cpu_h[k] } else { (None, None) },
            };
            let c = sample_points(
                &field,
                SamplePoints {
                    positions: &positions[i..i + 1],
                    normals: ns.map(|n| &n[i..i + 1]),
                },
            )
            .unwrap()[0];
            let want = match ns {
                Some(n) => c.light + e * (c.sun * n[i].dot(to_sun).max(0.0)),
                None => c.light,
            };
            let got = gpu[i];
            assert!(
                (want - got.light).abs().max_element() <= 1e-5 * want.abs().max_element() + 1e-5
                    && (c.sun - got.sun).abs() <= 1e-5,
                "normals {with_normals} halves {with_halves} point {i}: cpu {want} T {} gpu {} T {}",
                c.sun,
                got.light,
                got.sun
            );
        }
    }
    // A layer without its sun responses: refused by name.
    let bare = [GpuSampleLayer {
        grid: &grids.dev_sky[0],
        owner: None,
        sun: None,
        horizon: None,
    }];
    let e = sampler
        .sample_layers_lit(&bare, GpuPoints::Lattice(descs[0]), &light)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("layers[0].sun"), "{e}");
    // Halves on another grid, or the sun's without a sun: refused by name.
    let unlike = [GpuSampleLayer {
        grid: &grids.dev_sky[0],
        owner: None,
        sun: None,
        horizon: Some(&dev_h[1]),
    }];
    let e = sampler
        .sample_layers(&unlike, GpuPoints::Lattice(descs[0]))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("layers[0].horizon"), "{e}");
}

/// Several layers' reads blended (`lightgrid_core::seam`): bins, halves and the
/// transmittance each the weighted sum of the parts', as the hierarchy's `LightField`
/// reads across a seam.
struct Blended<'a>(Vec<(LitLayer<'a>, f32)>);

impl lightgrid_core::LightField for Blended<'_> {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, lightgrid_core::GridError> {
        let mut acc = BinLight::ZERO;
        for (l, w) in &self.0 {
            acc += l.light(p, n)? * *w;
        }
        Ok(acc)
    }
    fn horizon(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<Option<HorizonLight>, lightgrid_core::GridError> {
        let mut acc = HorizonLight::default();
        for (l, w) in &self.0 {
            let Some(h) = l.horizon(p, n)? else {
                return Ok(None);
            };
            acc = acc + h * *w;
        }
        Ok(Some(acc))
    }
    fn sun_transmittance(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<f32, lightgrid_core::GridError> {
        let mut t = 0.0;
        for (l, w) in &self.0 {
            t += l.sun_transmittance(p, n)? * *w;
        }
        Ok(t.clamp(0.0, 1.0))
    }
}

/// Layered device sampling across the seams between owned layers that tile (one
/// quadtree, one cell size and points across, each the next one's neighbour) equals
/// the CPU rule: where a point's read (half a cell along its normal) falls between the
/// owning layer's outermost points and a neighbour's, the reads of the layers holding
/// the lookup's corners weighted by their shares (`lightgrid_core::seam::seam_shares`),
/// with the sun kept apart and horizon halves; the owner's read alone where one of
/// them is missing, does not reach the point's height, or does not tile (another cell
/// size beside the block). Across the block's inner seams the light is continuous.
#[test]
fn layered_device_sampling_reads_across_seams() {
    use lightgrid_core::glam::IVec2;
    use lightgrid_core::seam::seam_shares;
    use lightgrid_render::{GpuHorizon, LayerLight};
    let Some(ctx) = context() else { return };
    let sampler = GpuLightSampler::new(ctx.clone());
    let owner = |x, z| LayerOwner {
        origin: Vec2::splat(-8.0),
        size: 4.0,
        index: IVec2::new(x, z),
    };
    // The world grid; a 2 x 2 block of tiles over -4..4 (0.5 m, 8 points across; one
    // lower than the others); beside it a layer of another cell size (no seam).
    let tile = |x: i32, z: i32, levels: u32| {
        let o = Vec3::new(
            -8.0 + 4.0 * x as f32 + 0.25,
            0.0,
            -8.0 + 4.0 * z as f32 + 0.25,
        );
        GridDesc::new(o, 0.5, UVec3::new(8, levels, 8)).unwrap()
    };
    let mut descs =
        vec![GridDesc::new(Vec3::new(-8.0, 0.0, -8.0), 2.0, UVec3::new(9, 4, 9)).unwrap()];
    let mut owners = vec![None];
    for (x, z, levels) in [(1, 1, 9), (2, 1, 9), (1, 2, 9), (2, 2, 7)] {
        descs.push(tile(x, z, levels));
        owners.push(Some(owner(x, z)));
    }
    descs.push(GridDesc::new(Vec3::new(-7.5, 0.0, -3.5), 1.0, UVec3::new(4, 5, 4)).unwrap());
    owners.push(Some(owner(0, 1)));
    let n = descs.len();
    let grids = LitGrids::new(&ctx, &descs);
    let (sky, scat, ts) = (&grids.sky, &grids.scat, &grids.ts);
    let sky_h: Vec<HorizonGrid> = (0..n)
        .map(|i| varied_halves(&sky[i], 40 + i as u64))
        .collect();
    let scat_h: Vec<HorizonGrid> = (0..n)
        .map(|i| varied_halves(&scat[i], 50 + i as u64))
        .collect();
    let dev_h: Vec<GpuHorizon> = (0..n)
        .map(|i| GpuHorizon::new(ctx.clone(), &sky_h[i], Some(&scat_h[i])).unwrap())
        .collect();
    let (scale, e, to_sun) = (
        Vec3::new(0.5, 0.8, 1.2),
        Vec3::new(3.0, 2.5, 2.0),
        Vec3::new(0.3, 0.8, -0.4).normalize(),
    );
    let light = LayerLight {
        sky_scale: scale,
        sun: Some((to_sun, e)),
    };
    let lit = |k: usize| LitLayer {
        sky: &sky[k],
        scattered: &scat[k],
        t: &ts[k],
        scale,
        sun: e,
        halves: (Some(&sky_h[k]), Some(&scat_h[k])),
    };
    let layers: Vec<GpuSampleLayer> = (0..n)
        .map(|i| grids.layer(i, owners[i], Some(&dev_h[i])))
        .collect();
    // Points over the block and beside it, many in the strips along its seams.
    let mut rng = fastrand::Rng::with_seed(17);
    let positions: Vec<Vec3> = (0..4000)
        .map(|k| {
            let (mut x, mut z) = (rng.f32() * 11.0 - 6.0, rng.f32() * 11.0 - 6.0);
            if k % 2 == 0 {
                x = 0.8 * rng.f32() - 0.4;
            }
            if k % 3 == 0 {
                z = 0.8 * rng.f32() - 0.4;
            }
            Vec3::new(x, rng.f32() * 4.4 - 0.2, z)
        })
        .collect();
    let normals: Vec<Vec3> = (0..4000)
        .map(|_| Vec3::new(rng.f32() - 0.5, rng.f32() - 0.3, rng.f32() - 0.5).normalize())
        .collect();
    // The owner (lightgrid_terrain_lod::Owner::owns: the quadtree cell, and the height
    // within the grid's levels; the strips beside a tile's outermost points are its).
    let owner_of = |p: Vec3| -> usize {
        (0..n)
            .rev()
            .find(|&k| {
                owners[k].is_none_or(|o| {
                    ((Vec2::new(p.x, p.z) - o.origin) / o.size)
                        .floor()
                        .as_ivec2()
                        == o.index
                        && p.y >= descs[k].origin().y
                        && p.y <= descs[k].point_bounds().1.y
                })
            })
            .unwrap()
    };
    // The CPU rule: the owner, and across a seam the layers of the block that tile.
    let parts = |p: Vec3, nrm: Option<Vec3>| -> Vec<(usize, f32)> {
        let a = owner_of(p);
        let Some(oa) = owners[a] else {
            return vec![(a, 1.0)];
        };
        let d = descs[a];
        let q = nrm.map_or(p, |nv| p + nv * (0.5 * d.h()));
        let (w, count) = seam_shares(&d, q);
        let mut out = Vec::new();
        for &(off, wt) in &w[..count] {
            let found = (0..n).rev().find(|&j| {
                owners[j].is_some_and(|o| o.index == oa.index + off)
                    && descs[j].h() == d.h()
                    && descs[j].dims().x == d.dims().x
            });
            match found {
                Some(j) if p.y <= descs[j].point_bounds().1.y && p.y >= descs[j].origin().y => {
                    out.push((j, wt))
                }
                _ => return vec![(a, 1.0)],
            }
        }
        out
    };
    let mut across = 0;
    for with_normals in [false, true] {
        let ns = with_normals.then_some(&normals[..]);
        let gpu = read_lit(&sampler, &layers, (&positions, ns), &light);
        for (i, p) in positions.iter().enumerate() {
            let nrm = ns.map(|v| v[i]);
            let ps = parts(*p, nrm);
            across += (ps.len() > 1) as usize;
            let field = Blended(ps.iter().map(|&(k, w)| (lit(k), w)).collect());
            let c = sample_points(
                &field,
                SamplePoints {
                    positions: &positions[i..i + 1],
                    normals: ns.map(|v| &v[i..i + 1]),
                },
            )
            .unwrap()[0];
            let want = match nrm {
                Some(nv) => c.light + e * (c.sun * nv.dot(to_sun).max(0.0)),
                None => c.light,
            };
            let got = gpu[i];
            assert!(
                (want - got.light).abs().max_element() <= 1e-5 * want.abs().max_element() + 1e-5
                    && (c.sun - got.sun).abs() <= 1e-5
                    && (c.dominant - got.dominant).abs().max_element() <= 1e-4,
                "normals {with_normals} point {i} at {p} from {ps:?}: cpu {want} T {} dominant {} gpu {} T {} dominant {}",
                c.sun,
                c.dominant,
                got.light,
                got.sun,
                got.dominant
            );
        }
    }
    assert!(across > 1000, "{across} reads across a seam");
    // Continuous across the block's inner seams (x = 0, z = 0), away from the lower
    // tile's top: a step of a thousandth of a metre changes the light by little, where
    // the owners' reads alone jump.
    let eps = 1e-3;
    let pairs: Vec<Vec3> = (0..200)
        .flat_map(|k| {
            let t = -3.5 + 7.0 * k as f32 / 200.0;
            let y = 0.3 + 2.5 * (k % 7) as f32 / 7.0;
            [
                Vec3::new(-eps, y, t),
                Vec3::new(eps, y, t),
                Vec3::new(t, y, -eps),
                Vec3::new(t, y, eps),
            ]
        })
        .collect();
    let gpu = read_lit(&sampler, &layers, (&pairs, None), &light);
    let (mut worst, mut jump) = (0.0f32, 0.0f32);
    for (k, s) in gpu.chunks(2).enumerate() {
        worst = worst.max((s[0].light - s[1].light).abs().max_element());
        let (a, b) = (
            &sky[owner_of(pairs[2 * k])],
            &sky[owner_of(pairs[2 * k + 1])],
        );
        let alone = |g: &LightGrid, p: Vec3| g.sample(p).unwrap().total().max_element();
        jump = jump.max((alone(a, pairs[2 * k]) - alone(b, pairs[2 * k + 1])).abs());
    }
    assert!(
        worst < 0.01 * jump,
        "largest step {worst}, the owners' reads alone {jump}"
    );
}
