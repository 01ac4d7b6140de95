//! The exported files read exactly as Bevy reads them: its DDS and KTX2 loaders
//! (`bevy_image::dds::dds_buffer_to_image`, `bevy_image::ktx2::ktx2_buffer_to_image`,
//! ported below for the two formats we write, with the same `ddsfile` and `ktx2` crates),
//! then its shader's lookup (`irradiance_volume_light` in
//! `bevy_pbr/src/light_probe/irradiance_volume.wgsl`, ported line by line with a
//! clamp-to-edge trilinear sampler). Bevy itself does not build on this machine in
//! reasonable time, so this is the check that the face order, the transform and the
//! intensity are the ones Bevy's code uses.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{BinLight, GridDesc, LightField, LightGrid, dirs};
use lightgrid_export::{BevyVolume, Content, Sidecar, TexelFormat, Transform, write_volumes};

/// What Bevy's loaders hand to wgpu for our files.
struct Image {
    format: TexelFormat,
    size: UVec3,
    is_3d: bool,
    data: Vec<u8>,
}

/// `dds_buffer_to_image`: `Dds::read`, the DXGI format mapping, `depth > 1` is a 3D
/// texture, mip levels 0 are bumped to 1, the data is used as is.
fn bevy_load_dds(bytes: &[u8]) -> Image {
    let dds = ddsfile::Dds::read(&mut std::io::Cursor::new(bytes)).expect("Failed to parse DDS");
    assert!(
        dds.get_d3d_format().is_none(),
        "a D3D format takes the other branch"
    );
    let format = match dds.get_dxgi_format().expect("a DXGI format") {
        ddsfile::DxgiFormat::R9G9B9E5_SharedExp => TexelFormat::Rgb9e5,
        ddsfile::DxgiFormat::R11G11B10_Float => TexelFormat::Rg11b10,
        f => panic!("unexpected {f:?}"),
    };
    assert!(!dds.header.caps2.contains(ddsfile::Caps2::CUBEMAP));
    assert_eq!(dds.get_num_array_layers(), 1);
    assert_eq!(dds.get_num_mipmap_levels().max(1), 1);
    Image {
        format,
        size: UVec3::new(dds.get_width(), dds.get_height(), dds.get_depth()),
        is_3d: dds.get_depth() > 1,
        data: dds.data,
    }
}

/// `ktx2_buffer_to_image`: `Reader::new`, `header.format` mapped (ours always has one),
/// no supercompression, levels concatenated, `depth > 1` is a 3D texture.
fn bevy_load_ktx2(bytes: &[u8]) -> Image {
    let ktx = ktx2::Reader::new(bytes).expect("Failed to parse ktx2 file");
    let h = ktx.header();
    assert!(h.supercompression_scheme.is_none());
    assert_eq!(
        (h.layer_count.max(1), h.face_count.max(1), h.level_count),
        (1, 1, 1)
    );
    let format = match h.format.expect("a vkFormat") {
        ktx2::Format::E5B9G9R9_UFLOAT_PACK32 => TexelFormat::Rgb9e5,
        ktx2::Format::B10G11R11_UFLOAT_PACK32 => TexelFormat::Rg11b10,
        f => panic!("unexpected {f:?}"),
    };
    let data: Vec<u8> = ktx.levels().flat_map(|l| l.data.to_vec()).collect();
    // The data format descriptor parses and describes one 4-byte RGB plane.
    let block = ktx.dfd_blocks().next().expect("a DFD block");
    assert_eq!(block.header, ktx2::DfdHeader::BASIC);
    let basic = ktx2::DfdBlockBasic::parse(block.data).expect("a basic DFD");
    assert_eq!(basic.header.color_model, Some(ktx2::ColorModel::RGBSDA));
    assert_eq!(basic.header.bytes_planes[0], 4);
    let channels: Vec<u8> = basic.sample_information().map(|s| s.channel_type).collect();
    assert!(channels.contains(&0) && channels.contains(&1) && channels.contains(&2));
    let writer = ktx
        .key_value_data()
        .find(|(k, _)| *k == "KTXwriter")
        .expect("a KTXwriter key");
    assert!(
        std::str::from_utf8(writer.1)
            .unwrap()
            .starts_with("lightgrid-export")
    );
    let depth = h.pixel_depth.max(1);
    Image {
        format,
        size: UVec3::new(h.pixel_width, h.pixel_height, depth),
        is_3d: depth > 1,
        data,
    }
}

impl Image {
    fn texel(&self, t: UVec3) -> Vec3 {
        let i = 4 * (t.x + self.size.x * (t.y + self.size.y * t.z)) as usize;
        let w = u32::from_le_bytes(self.data[i..i + 4].try_into().unwrap());
        self.format.unpack(w)
    }

    /// `textureSampleLevel` with a linear, clamp-to-edge sampler at normalised `uvw`.
    fn sample(&self, uvw: Vec3) -> Vec3 {
        let size = self.size.as_vec3();
        let f = uvw * size - 0.5;
        let base = f.floor();
        let w = f - base;
        let clamp = |v: f32, n: u32| (v.max(0.0) as u32).min(n - 1);
        let mut acc = Vec3::ZERO;
        for corner in 0..8u32 {
            let o = UVec3::new(corner & 1, (corner >> 1) & 1, corner >> 2);
            let t = UVec3::new(
                clamp(base.x + o.x as f32, self.size.x),
                clamp(base.y + o.y as f32, self.size.y),
                clamp(base.z + o.z as f32, self.size.z),
            );
            let wt = Vec3::select(o.cmpeq(UVec3::ONE), w, Vec3::ONE - w);
            acc += self.texel(t) * wt.x * wt.y * wt.z;
        }
        acc
    }

    /// `irradiance_volume_light(world_position, N)` after `query_light_probe` found this
    /// volume: `light_from_world` is the inverse of the probe's transform, and the result
    /// is multiplied by the probe's intensity.
    fn bevy_light(&self, t: &Transform, intensity: f32, world: Vec3, n: Vec3) -> Vec3 {
        let atlas_resolution = self.size.as_vec3();
        let resolution = (self.size / UVec3::new(1, 2, 3)).as_vec3();
        let unit_pos = (world - Vec3::from(t.translation)) / Vec3::from(t.scale);
        let stp = ((unit_pos + 0.5) * resolution).clamp(Vec3::splat(0.5), resolution - 0.5);
        let uvw = stp / atlas_resolution;
        let neg_offset = Vec3::select(n.cmplt(Vec3::ZERO), Vec3::splat(0.5), Vec3::ZERO);
        let uvw_x = uvw + Vec3::new(0.0, neg_offset.x, 0.0);
        let uvw_y = uvw + Vec3::new(0.0, neg_offset.y, 1.0 / 3.0);
        let uvw_z = uvw + Vec3::new(0.0, neg_offset.z, 2.0 / 3.0);
        let rgb_x = self.sample(uvw_x);
        let rgb_y = self.sample(uvw_y);
        let rgb_z = self.sample(uvw_z);
        let nn = n * n;
        (rgb_x * nn.x + rgb_y * nn.y + rgb_z * nn.z) * intensity
    }
}

/// Sky-like light that differs in every direction: brighter from above and from +X, a
/// colour that changes with the direction, varying from point to point.
fn test_grid() -> LightGrid {
    let desc = GridDesc::new(Vec3::new(-3.0, 1.0, 2.0), 0.75, UVec3::new(5, 4, 3)).unwrap();
    let data = (0..desc.point_count())
        .map(|i| {
            let p = desc.coords(i).unwrap().as_vec3();
            BinLight(std::array::from_fn(|d| {
                let v = dirs::dir_unit(d);
                // Light travelling along v arrives from -v.
                let from = -v;
                let base = 1.0 + 3.0 * from.y.max(0.0) + 1.5 * from.x.max(0.0) + 0.2 * p.x;
                Vec3::new(base, base * (0.8 + 0.1 * from.z), base * (0.5 + 0.05 * p.y))
                    * dirs::solid_angles()[d]
                    * 500.0
            }))
        })
        .collect();
    LightGrid::new(desc, data).unwrap()
}

fn rel(a: Vec3, b: Vec3) -> f32 {
    ((a - b).abs() / b.max_element().max(1e-30)).max_element()
}

fn normals() -> Vec<Vec3> {
    let mut v: Vec<Vec3> = lightgrid_core::light::AMBIENT_AXES.to_vec();
    for (x, y, z) in [
        (1.0, 2.0, -0.5),
        (-0.3, -1.0, 0.7),
        (0.6, -0.2, -0.9),
        (-1.0, 0.4, 0.2),
    ] {
        v.push(Vec3::new(x, y, z).normalize());
    }
    v
}

fn files(format: TexelFormat) -> (LightGrid, BevyVolume, Vec<Image>) {
    let g = test_grid();
    let v = BevyVolume::from_field(&g, g.desc(), format).unwrap();
    let images = vec![
        bevy_load_dds(&v.to_dds().unwrap()),
        bevy_load_ktx2(&v.to_ktx2()),
    ];
    (g, v, images)
}

#[test]
fn bevy_loaders_read_a_3d_texture_of_the_right_size_and_format() {
    for format in [TexelFormat::Rgb9e5, TexelFormat::Rg11b10] {
        let (g, v, images) = files(format);
        let d = g.desc().dims();
        for img in &images {
            assert!(img.is_3d);
            assert_eq!(img.format, format);
            assert_eq!(img.size, UVec3::new(d.x, 2 * d.y, 3 * d.z));
            assert_eq!(img.data.len(), 4 * v.texels().len());
            // Both containers hold the same texels.
            assert_eq!(img.data, images[0].data);
        }
    }
}

/// At every grid point, for the six axis normals, Bevy's lookup gives the sweep's
/// irradiance on that normal / pi: the face order, the transform and the intensity are
/// right. The light is brighter from above than below and from +X than -X, so swapping
/// the halves of the texture (Bevy's doc-comment order) fails this by a factor of ~2.
#[test]
fn bevy_lookup_at_grid_points_is_the_irradiance_over_pi() {
    for (format, tol) in [
        (TexelFormat::Rgb9e5, 1.0 / 256.0),
        (TexelFormat::Rg11b10, 1.0 / 32.0),
    ] {
        let (g, v, images) = files(format);
        let t = v.transform();
        for img in &images {
            for i in 0..g.desc().point_count() {
                let p = g.desc().coords(i).unwrap();
                let world = g.desc().position(p);
                let b = &g.data()[i];
                for n in lightgrid_core::light::AMBIENT_AXES {
                    let want = b.irradiance(n) / std::f32::consts::PI;
                    let got = img.bevy_light(&t, v.intensity(), world, n);
                    assert!(
                        rel(got, want) < tol,
                        "{format:?} {p} n {n}: {got} vs {want}"
                    );
                }
                // The halves differ, so the test above can tell them apart.
                let up = b.irradiance(Vec3::Y).x;
                let down = b.irradiance(Vec3::NEG_Y).x;
                assert!(up > 1.5 * down, "{up} vs {down}");
            }
        }
    }
}

/// Between grid points and for any normal, Bevy's lookup is the trilinear blend of the
/// ambient cubes at the eight surrounding points (hardware filtering inside one half of
/// the texture), evaluated with Valve's formula.
#[test]
fn bevy_lookup_between_points_is_the_blended_ambient_cube() {
    let (g, v, images) = files(TexelFormat::Rgb9e5);
    let t = v.transform();
    let desc = g.desc();
    let img = &images[1];
    for (k, n) in normals().into_iter().enumerate() {
        for q in [
            Vec3::new(0.3, 0.5, 0.25),
            Vec3::new(2.7, 1.2, 1.9),
            Vec3::new(3.99, 2.5, 0.01),
        ] {
            let world = desc.to_world(q + 0.013 * k as f32);
            let want =
                g.light(world, None).unwrap().ambient_cube().irradiance(n) / std::f32::consts::PI;
            let got = img.bevy_light(&t, v.intensity(), world, n);
            assert!(rel(got, want) < 1.0 / 200.0, "{q} n {n}: {got} vs {want}");
        }
    }
}

#[test]
fn the_sidecar_describes_the_files() {
    let g = test_grid();
    let v = BevyVolume::from_field(&g, g.desc(), TexelFormat::Rg11b10).unwrap();
    let dir = std::env::temp_dir().join(format!("lightgrid-export-test-{}", std::process::id()));
    // A sun 30 degrees up, towards +X, of irradiance (3, 2, 1) in the grid's units.
    let to_sun = Vec3::new(30f32.to_radians().cos(), 30f32.to_radians().sin(), 0.0);
    let e = Vec3::new(3.0, 2.0, 1.0);
    let paths = write_volumes(
        &dir,
        "volume",
        std::slice::from_ref(&v),
        Content::Indirect,
        2.0,
        Some((to_sun * 7.0, e)),
    )
    .unwrap();
    assert_eq!(paths.len(), 3);
    let text = std::fs::read_to_string(dir.join("volume.json")).unwrap();
    let side: Sidecar = serde_json::from_str(&text).unwrap();
    let info = &side.volumes[0];
    assert_eq!(info.content, Content::Indirect);
    assert_eq!(info.format, "Rg11b10Ufloat");
    assert_eq!(info.intensity, 2.0 * v.intensity());
    assert_eq!(info.resolution, g.desc().dims().to_array());
    assert_eq!(info.transform, v.transform());
    let dds = std::fs::read(dir.join(&info.dds)).unwrap();
    let ktx = std::fs::read(dir.join(&info.ktx2)).unwrap();
    assert_eq!(bevy_load_dds(&dds).data, bevy_load_ktx2(&ktx).data);
    // The sun the indirect volume leaves out: unit direction, lux = luminance of the
    // irradiance times the unit scale, colour of luminance 1 in the irradiance's ratios.
    assert_eq!(side.version, 2);
    assert!(side.units.contains("unit_scale"));
    let sun = side
        .sun
        .expect("an indirect volume's sidecar names its sun");
    assert!((Vec3::from_array(sun.direction_to_sun) - to_sun).length() < 1e-6);
    let luma = 0.2126 * 3.0 + 0.7152 * 2.0 + 0.0722 * 1.0;
    assert!(
        (sun.illuminance - 2.0 * luma).abs() < 1e-5,
        "{}",
        sun.illuminance
    );
    let c = Vec3::from_array(sun.color);
    assert!((lightgrid_core::light::luminance(c) - 1.0).abs() < 1e-6);
    assert!((c * luma - e).length() < 1e-5, "{c}");
    std::fs::remove_dir_all(&dir).unwrap();
    // A volume holding all the light leaves the sun out; so does one without a sun.
    for (content, sun) in [(Content::All, Some((to_sun, e))), (Content::Indirect, None)] {
        write_volumes(&dir, "volume", std::slice::from_ref(&v), content, 2.0, sun).unwrap();
        let text = std::fs::read_to_string(dir.join("volume.json")).unwrap();
        assert!(!text.contains("direction_to_sun"), "{text}");
        let side: Sidecar = serde_json::from_str(&text).unwrap();
        assert!(side.sun.is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }
    // A sun below the horizon lights nothing: none; a bad one or an overflowing unit
    // scale is an error naming it.
    let below = write_volumes(
        &dir,
        "volume",
        std::slice::from_ref(&v),
        Content::Indirect,
        2.0,
        Some((-to_sun, e)),
    );
    assert!(below.is_ok());
    assert!(
        !std::fs::read_to_string(dir.join("volume.json"))
            .unwrap()
            .contains("direction_to_sun")
    );
    std::fs::remove_dir_all(&dir).unwrap();
    for (sun, scale, field) in [
        ((Vec3::ZERO, e), 2.0, "sun direction"),
        (
            (to_sun, Vec3::new(1.0, f32::NAN, 0.0)),
            2.0,
            "sun irradiance",
        ),
        ((to_sun, Vec3::splat(1e30)), 1e30, "unit_scale"),
    ] {
        let err = write_volumes(
            &dir,
            "volume",
            std::slice::from_ref(&v),
            Content::Indirect,
            scale,
            Some(sun),
        )
        .unwrap_err();
        assert!(err.to_string().contains(field), "{err}");
        assert!(!dir.join("volume.json").exists());
    }
}

/// A sun of irradiance 1 at the zenith, as bins.
fn zenith_sun() -> BinLight {
    lightgrid_sky::Sun::at(std::f32::consts::FRAC_PI_2, 0.0, Vec3::ONE)
        .bins()
        .unwrap()
}

/// `top` from above, periodic sides: with ground below, an infinite ground.
fn periodic(top: BinLight) -> lightgrid_core::Boundary {
    lightgrid_core::Boundary {
        top: lightgrid_core::TopBoundary::Uniform(Box::new(top)),
        bottom: BinLight::ZERO,
        sides: lightgrid_core::SideBoundary::Periodic,
    }
}

/// Passes until 1e-7 of the input waits (at most 64).
fn converged() -> lightgrid_core::SweepOptions {
    let mut o = lightgrid_core::SweepOptions::multi_bounce();
    o.tolerance = 1e-7;
    o.max_passes = 64;
    o
}

/// An infinite Lambertian ground (one level, albedo 0.3, periodic sides) under a sun at
/// the zenith and no sky: the sun's light travels downward only, and everything that
/// travels upward or sideways is the ground's reflection. So the indirect light must be
/// exactly the full light's upward and horizontal bins, with nothing in the downward
/// ones, at every level; In an empty grid the indirect light is
/// zero.
#[test]
fn indirect_light_is_the_ground_bounce_alone() {
    let b = periodic(zenith_sun());
    let o = converged();
    let mut cpu = lightgrid_sweep_cpu::CpuSweeper::new();
    for (levels, albedo) in [(1, 0.3f32), (1, 0.9), (0, 0.3)] {
        let m = lightgrid_measure::exact::ground_material(levels, albedo).unwrap();
        let full = lightgrid_export::indirect_light(&mut cpu, &m, &b, None, &o).unwrap();
        let ind = lightgrid_export::indirect_light(&mut cpu, &m, &b, Some(&b), &o).unwrap();
        let d = m.desc();
        for j in levels..d.dims().y {
            let i = d.index(UVec3::new(3, j, 4)).unwrap();
            let (f, g) = (&full.data()[i], &ind.data()[i]);
            let scale = f.0.iter().map(|v| v.x).fold(0.0, f32::max);
            for k in 0..26 {
                let want = if dirs::dir_unit(k).y < 0.0 {
                    0.0
                } else {
                    f.0[k].x
                };
                assert!(
                    (g.0[k].x - want).abs() <= 1e-5 * scale,
                    "ground {levels} albedo {albedo} level {j} bin {k}: {} vs {want}",
                    g.0[k].x
                );
            }
            if levels > 0 {
                // The bounce is there: the ground reflected light up to every level.
                let up: f32 = (0..26)
                    .filter(|&k| dirs::dir_unit(k).y > 0.0)
                    .map(|k| g.0[k].x)
                    .sum();
                assert!(up > 0.1 * albedo, "level {j}: upward light {up}");
            }
        }
    }
}

/// The bake's light with its horizon halves (`indirect_light_split`): over an infinite
/// Lambertian ground (albedo 0.3, periodic sides) under a uniform sky of radiance 1 and
/// a zenith sun of irradiance 1 that the export leaves out, the volume's face facing up
/// holds the sky alone (irradiance / pi = 1) and the face facing down the ground's
/// reflection of both, `a (pi + 1) / pi`, within the texel format's rounding; the bins
/// alone read facing down 10 % more.
#[test]
fn the_baked_faces_read_the_horizon_halves() {
    use lightgrid_export::{BevyVolume, TexelFormat};
    let pi = std::f32::consts::PI;
    let sky = lightgrid_sky::uniform_sky(Vec3::ONE).unwrap().top;
    let sun = zenith_sun();
    let boundary = periodic;
    let o = converged();
    let mut cpu = lightgrid_sweep_cpu::CpuSweeper::new();
    let a = 0.3f32;
    let m = lightgrid_measure::exact::ground_material(1, a).unwrap();
    let (all, sun_b) = (boundary(sky + sun), boundary(sun));
    let split =
        lightgrid_export::indirect_light_split(&mut cpu, &m, &all, Some(&sun_b), &o).unwrap();
    let plain = lightgrid_export::indirect_light(&mut cpu, &m, &all, Some(&sun_b), &o).unwrap();
    assert_eq!(split.bins(), &plain);
    let valid = lightgrid_core::validity::valid_points(&m);
    let d = *m.desc();
    let v = BevyVolume::from_field_valid(&split, &d, TexelFormat::Rgb9e5, &valid).unwrap();
    let even = BevyVolume::from_field_valid(&plain, &d, TexelFormat::Rgb9e5, &valid).unwrap();
    let (up, down) = (2, 3);
    let want_down = a * (pi + 1.0) / pi;
    for j in 1..d.dims().y {
        let p = UVec3::new(3, j, 4);
        let face = |v: &BevyVolume, f: usize| v.texel(p, f).x * v.intensity();
        assert!(
            (face(&v, up) - 1.0).abs() < 1.0 / 64.0,
            "level {j}: {}",
            face(&v, up)
        );
        assert!(
            (face(&v, down) - want_down).abs() < want_down / 64.0,
            "level {j}: {} against {want_down}",
            face(&v, down)
        );
        assert!(
            face(&even, down) > 1.08 * want_down,
            "level {j}: {}",
            face(&even, down)
        );
    }
}

/// Bevy's lookup on a surface: a flat ground (two opaque levels) under a uniform sky,
/// bare and under a canopy (a layer of foliage, pass-through 0.6, four to six metres up),
/// periodic sides. Half way between the top ground point (inside) and the point above,
/// the lookup reads the light just above within 2 % once the points inside are filled
/// from their valid neighbours; left as swept it reads about half (the test's control).
#[test]
fn a_lookup_on_the_ground_reads_the_light_above_it() {
    use lightgrid_core::{Boundary, Material, MaterialGrid, SideBoundary, TopBoundary, validity};
    for canopy in [false, true] {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(6, 10, 6)).unwrap();
        let cells = (0..desc.point_count())
            .map(|i| match desc.coords(i).unwrap().y {
                0 | 1 => Material::opaque(Vec3::splat(0.3)),
                4..=6 if canopy => Material {
                    reflectance: Vec3::new(0.1, 0.3, 0.1),
                    pass: 0.6,
                },
                _ => Material::EMPTY,
            })
            .collect();
        let m = MaterialGrid::new(desc, cells).unwrap();
        let b = Boundary {
            top: TopBoundary::Uniform(Box::new(BinLight::uniform(Vec3::ONE).split_vertical().0)),
            bottom: BinLight::ZERO,
            sides: SideBoundary::Periodic,
        };
        let mut o = lightgrid_core::SweepOptions::multi_bounce();
        o.outputs.bins = true;
        let light = lightgrid_sweep_cpu::run(&m, &b, &o)
            .unwrap()
            .output
            .bins
            .unwrap();
        let valid = validity::valid_points(&m);
        let filled =
            BevyVolume::from_field_valid(&light, &desc, TexelFormat::Rgb9e5, &valid).unwrap();
        let plain = BevyVolume::from_field(&light, &desc, TexelFormat::Rgb9e5).unwrap();
        let look = |v: &BevyVolume, y: f32| {
            let img = bevy_load_dds(&v.to_dds().unwrap());
            img.bevy_light(
                &v.transform(),
                v.intensity(),
                Vec3::new(2.5, y, 3.0),
                Vec3::Y,
            )
        };
        // The ground's surface: the top face of level 1, half way to level 2.
        let (surface, above) = (look(&filled, 1.5), look(&filled, 2.0));
        assert!(
            rel(surface, above) < 0.02,
            "canopy {canopy}: {surface} on the ground, {above} above"
        );
        let bare = look(&plain, 1.5);
        assert!(
            bare.y < 0.6 * above.y,
            "canopy {canopy}: control {bare} vs {above}"
        );
        // Where all eight corners are valid, nothing changes.
        for y in [2.0, 2.5, 3.7, 8.2] {
            assert_eq!(look(&filled, y), look(&plain, y), "canopy {canopy}, y {y}");
        }
    }
}

/// A set of volumes and its sidecar appear whole or not at all: when the sidecar cannot
/// be written (a folder stands where it goes), no texture stays behind.
#[test]
fn volumes_and_sidecar_are_written_whole_or_not_at_all() {
    let g = test_grid();
    let v = BevyVolume::from_field(&g, g.desc(), TexelFormat::Rgb9e5).unwrap();
    let dir = std::env::temp_dir().join(format!("lightgrid-export-set-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("set.json")).unwrap();
    let vols = [v.clone(), v];
    let e = write_volumes(&dir, "set", &vols, Content::All, 1.0, None).unwrap_err();
    assert!(e.to_string().contains("set.json"), "{e}");
    let left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, vec!["set.json".to_string()], "{left:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
