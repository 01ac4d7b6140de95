//! The rasteriser's shading gives known answers (lightgrid_render::shading is the
//! specification); device sampling is in `gpu_sampling.rs`. Runs on any adapter
//! (lavapipe in CI); fails without one unless LIGHTGRID_ALLOW_NO_GPU=1.

mod common;

use std::f32::consts::PI;

use lightgrid_core::glam::{Mat4, UVec3, Vec2, Vec3, Vec4};
use lightgrid_core::{BinLight, GridDesc};
use lightgrid_render::shading::{linear_to_srgb8, tonemap_aces};
use lightgrid_render::{
    Camera, GroundLight, LightVolume, Lighting, LightingMode, MeshInstance, MeshMaterial, Renderer,
    TextureRgba8, Vertex, Water,
};

use common::*;

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

/// Views recorded one after the other and sent in one submission
/// (`Renderer::record`, `record_pair`, `send`, `finish`) each keep their own camera,
/// culled instances, exposure and lighting mode: every image equals the view rendered
/// alone, bit for bit.
#[test]
fn views_recorded_together_are_each_as_rendered_alone() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let (mut v, i) = quad(0.0, Vec3::new(3.0, 2.0, 1.0));
    for p in &mut v {
        p.position = [p.position[0] / 20.0, 0.0, p.position[2] / 20.0];
    }
    let material = MeshMaterial {
        lighting: Lighting::Vertex,
        ..Default::default()
    };
    let at =
        |x: f32, z: f32| MeshInstance::new(Mat4::from_translation(Vec3::new(x, 0.0, z)), Vec4::ONE);
    let id = r.add_mesh(&v, &i, &material).unwrap();
    // Seen all from above; a few beside the second camera's view.
    r.set_instances(
        id,
        &[at(0.0, 0.0), at(2.0, 1.0), at(-2.5, -1.0), at(9.0, 0.0)],
    )
    .unwrap();
    let above = view(LightingMode::Grid, vec![id]);
    let mut aside = view(LightingMode::Grid, vec![id]);
    aside.camera = Camera::look_at(Vec3::new(1.0, 3.0, 0.5), Vec3::new(2.0, 0.0, 1.0));
    aside.exposure = 2.0;
    let mut plain = aside.clone();
    plain.mode = LightingMode::NoGrid;
    let alone = [
        r.render(&above).unwrap(),
        r.render(&aside).unwrap(),
        r.render(&plain).unwrap(),
    ];
    let pair = r.render_pair(&aside).unwrap();
    let mut pending = r.record(&above).unwrap();
    pending.append(r.record(&aside).unwrap());
    pending.append(r.record_pair(&aside).unwrap());
    pending.append(r.record(&plain).unwrap());
    assert_eq!(pending.len(), 5);
    r.send(&mut pending);
    let together = r.finish(pending).unwrap();
    assert_eq!(together.len(), 5);
    assert!(alone[0] != alone[1], "the views differ");
    let want = [&alone[0], &alone[1], &pair[0], &pair[1], &alone[2]];
    for (k, (got, want)) in together.iter().zip(want).enumerate() {
        assert!(
            got == want,
            "image {k} differs from the view rendered alone"
        );
    }
    assert!(
        pair[0] == alone[1] && pair[1] == alone[2],
        "a pair is its two views"
    );
}

/// Readback buffers are kept for the next images (`Renderer::finish`): a view read back
/// through the buffers another view's image left is the view's own image, bit for bit.
#[test]
fn kept_readback_buffers_give_each_image_its_own_pixels() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let (v, i) = quad(0.0, Vec3::new(3.0, 2.0, 1.0));
    let material = MeshMaterial {
        lighting: Lighting::Vertex,
        ..Default::default()
    };
    let id = r.add_mesh(&v, &i, &material).unwrap();
    r.set_instances(id, &[MeshInstance::new(Mat4::IDENTITY, Vec4::ONE)])
        .unwrap();
    let lit = view(LightingMode::Grid, vec![id]);
    let mut dark = lit.clone();
    dark.exposure = 0.25;
    let first = r.render(&lit).unwrap();
    let other = r.render(&dark).unwrap();
    let again = r.render(&lit).unwrap();
    assert!(first != other, "the views differ");
    assert!(again == first, "the same view read back again");
    let mut pending = r.record(&dark).unwrap();
    pending.append(r.record(&lit).unwrap());
    let both = r.finish(pending).unwrap();
    assert!(both[0] == other && both[1] == first);
}

/// A flat quad 1 m across at the origin lit by its vertices' light (3 everywhere), to
/// place as instances.
fn small_quad(r: &mut Renderer) -> lightgrid_render::MeshId {
    let (mut v, i) = quad(0.0, Vec3::splat(3.0));
    for p in &mut v {
        p.position = [p.position[0] / 20.0, 0.0, p.position[2] / 20.0];
    }
    let material = MeshMaterial {
        lighting: Lighting::Vertex,
        ..Default::default()
    };
    r.add_mesh(&v, &i, &material).unwrap()
}

/// Instances the camera cannot see are left out of the draw (`lightgrid_render::cull`)
/// without changing the image: one in view, one across the view's edge, three outside
/// (beside, behind, above the eye looking down) give the image of the first two alone,
/// bit for bit, and the one across the edge shows.
#[test]
fn culled_instances_leave_the_image_as_it_was() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let at = |x: f32, y: f32, z: f32| {
        MeshInstance::new(Mat4::from_translation(Vec3::new(x, y, z)), Vec4::ONE)
    };
    // The camera 5 m above the origin looking down sees 5 tan 30° = 2.89 m each way.
    let seen = [at(0.0, 0.0, 0.0), at(3.2, 0.0, 0.0)];
    let unseen = [at(10.0, 0.0, 0.0), at(0.0, 0.0, -20.0), at(0.0, 10.0, 0.0)];
    let id = small_quad(&mut r);
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

/// A mesh's draw range (`Renderer::set_draw_range`) keeps the instances whose origin
/// lies within it from the eye: near and far instances drawn with the range `0..d`
/// give the image of the near ones alone, with `d..∞` that of the far ones alone, bit
/// for bit; each shows (the images differ from the background's). Bad ranges are
/// refused, naming the bound.
#[test]
fn a_draw_range_keeps_the_instances_at_its_distances() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let at =
        |x: f32, y: f32| MeshInstance::new(Mat4::from_translation(Vec3::new(x, y, 0.0)), Vec4::ONE);
    // The eye 5 m above the origin looking down: one quad 5 m away, one 4 m lower (9 m).
    let (near, far) = ([at(-1.0, 0.0)], [at(1.0, -4.0)]);
    let id = small_quad(&mut r);
    let render = |r: &mut Renderer, list: &[MeshInstance], range: std::ops::Range<f32>| {
        r.set_instances(id, list).unwrap();
        r.set_draw_range(id, range).unwrap();
        r.render(&view(LightingMode::Grid, vec![id])).unwrap()
    };
    let both = [near, far].concat();
    let within = render(&mut r, &both, 0.0..7.0);
    let near_alone = render(&mut r, &near, 0.0..f32::INFINITY);
    assert!(within.hdr == near_alone.hdr && within.srgb == near_alone.srgb);
    let beyond = render(&mut r, &both, 7.0..f32::INFINITY);
    let far_alone = render(&mut r, &far, 0.0..f32::INFINITY);
    assert!(beyond.hdr == far_alone.hdr && beyond.srgb == far_alone.srgb);
    let background = render(&mut r, &both, 20.0..30.0);
    assert!(near_alone.hdr != background.hdr && far_alone.hdr != background.hdr);
    for (range, what) in [
        (-1.0..2.0, "range.start"),
        (f32::NAN..2.0, "range.start"),
        (f32::INFINITY..f32::INFINITY, "range.start"),
        (3.0..3.0, "range.end"),
        (3.0..f32::NAN, "range.end"),
    ] {
        let e = r.set_draw_range(id, range).unwrap_err().to_string();
        assert!(e.contains(what), "{e}");
    }
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
    let foliage = lit_quad(&mut r, 1.0, Lighting::Foliage);
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

/// Each light volume set is the one drawn: `Renderer::set_light_volume` keeps its
/// buffers for the next volume of the same size and writes them again, and a volume of
/// another size takes new ones.
#[test]
fn each_light_volume_set_is_the_one_drawn() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let foliage = lit_quad(&mut r, 1.0, Lighting::Foliage);
    let v = view(LightingMode::Grid, vec![foliage]);
    let wider = |avg: Vec3| {
        let desc = GridDesc::new(Vec3::new(-25.0, -5.0, -25.0), 5.0, UVec3::new(11, 4, 11));
        let desc = desc.unwrap();
        let n = desc.point_count();
        LightVolume {
            desc,
            average: vec![avg.extend(0.0).to_array(); n],
            dominant: vec![[0.0; 4]; n],
        }
    };
    let (a, b, c) = (
        Vec3::new(0.4, 0.8, 1.2),
        Vec3::new(1.0, 0.5, 0.25),
        Vec3::new(0.3, 0.3, 0.9),
    );
    let volumes = [
        (uniform_volume(a, Vec3::ZERO), a),
        (uniform_volume(b, Vec3::ZERO), b),
        (wider(c), c),
        (uniform_volume(a, Vec3::ZERO), a),
    ];
    for (k, (vol, avg)) in volumes.iter().enumerate() {
        r.set_light_volume(vol).unwrap();
        let img = r.render(&v).unwrap();
        assert_all_pixels(&r, &img, *avg, &format!("volume {k}"));
    }
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

/// A billboard (`MeshMaterial::billboard`) faces every eye: a square of side 4 in its
/// mesh's xy plane (its instance turned about x, which is ignored) covers the same
/// pixels' count from above, the side, below and askew, all of them its emissive tint,
/// as many as its area seen face on (within the rasterised edges' pixels); the same
/// mesh drawn as given is edge-on from the side and shows nothing; and its vertices'
/// z moves it toward the eye (z 3 at scale 2, half the way from 12 m: twice as wide).
#[test]
fn a_billboard_faces_every_eye() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let corner = |x: f32, y: f32| Vertex {
        position: [x, y, 7.0],
        normal: [0.0, 0.0, 1.0],
        uv: [0.0; 2],
        light: [0.0; 4],
    };
    let v = [
        corner(-1.0, -1.0),
        corner(1.0, -1.0),
        corner(1.0, 1.0),
        corner(-1.0, 1.0),
    ];
    let tint = Vec3::new(2.0, 1.0, 0.5);
    let mut add = |billboard: bool, z: f32| {
        let mut v = v;
        for c in &mut v {
            c.position[2] = z;
        }
        let id = r
            .add_mesh(
                &v,
                &[0, 1, 2, 0, 2, 3],
                &MeshMaterial {
                    lighting: Lighting::Emissive,
                    billboard,
                    ..Default::default()
                },
            )
            .unwrap();
        let turned = if billboard { 1.0 } else { 0.0 };
        let model = Mat4::from_scale_rotation_translation(
            Vec3::splat(2.0),
            lightgrid_core::glam::Quat::from_rotation_x(turned),
            Vec3::ZERO,
        );
        r.set_instances(id, &[MeshInstance::new(model, tint.extend(1.0))])
            .unwrap();
        id
    };
    let board = add(true, 0.0);
    let nearer = add(true, 3.0);
    let flat = add(false, 0.0);
    let distance = 12.0f32;
    // The square's side across the image at that distance, in pixels (60° field).
    let side = 4.0 / (2.0 * distance * 30f32.to_radians().tan()) * SIZE as f32;
    let mut counts = Vec::new();
    for dir in [
        Vec3::Y,
        Vec3::X,
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(-0.3, -1.0, 0.2),
        Vec3::new(-1.0, 0.2, -1.0),
    ] {
        for (mesh, side) in [(board, side), (nearer, 2.0 * side)] {
            let mut v = view(LightingMode::Grid, vec![mesh]);
            v.camera = Camera::look_at(dir.normalize() * distance, Vec3::ZERO);
            let img = r.render(&v).unwrap();
            let drawn = img.hdr.iter().filter(|p| p[0] != 9.0).count();
            for p in img.hdr.iter().filter(|p| p[0] != 9.0) {
                let got = Vec3::new(p[0], p[1], p[2]);
                assert!((got - tint).abs().max_element() < 1e-3, "{dir}: {got}");
            }
            // Within the pixels of its edges (a side's worth) of its area.
            assert!(
                (drawn as f32 - side * side).abs() <= 2.0 * side,
                "{dir}: {drawn} pixels, area {}",
                side * side
            );
            counts.push(drawn);
        }
    }
    // From the side the plain square lies edge-on.
    let mut v = view(LightingMode::Grid, vec![flat]);
    v.camera = Camera::look_at(Vec3::X * distance, Vec3::ZERO);
    let img = r.render(&v).unwrap();
    let drawn = img.hdr.iter().filter(|p| p[0] != 9.0).count();
    assert!(
        drawn <= SIZE as usize,
        "edge-on: {drawn} pixels; billboards {counts:?}"
    );
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
    let id = lit_quad(&mut r, 0.0, Lighting::Vertex);
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
