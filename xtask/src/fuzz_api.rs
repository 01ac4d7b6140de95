//! Fuzz targets beyond the file readers (issue 47): the export path (a grid file read,
//! packed into Bevy volumes, encoded as DDS, KTX2 and sidecar JSON, with the validity
//! fill), the bake path (a material grid file swept, the direct sun removed, exported)
//! and the library's entry points called with values read from the input's bytes
//! (any `f32`, NaN and infinities included, and any `u32`). Every call must return a
//! typed error or a finite result: a NaN or an infinity in a result is a defect, raised
//! as a panic that [`crate::fuzz`] counts.

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{BinLight, GridDesc, GridFile, LightGrid, Material, MaterialGrid, NUM_DIRS};
use lightgrid_export::{BevyVolume, Content, SidecarSun, TexelFormat};

/// Grid files of light to export, and one of material (read as its validity).
pub fn export_seeds() -> Vec<Vec<u8>> {
    let d = GridDesc::new(Vec3::new(1.0, -2.0, 0.5), 0.5, UVec3::new(3, 2, 2)).expect("valid");
    let mut data = vec![BinLight::uniform(Vec3::new(0.3, 0.5, 0.9)); d.point_count()];
    data[3].0[4] = Vec3::new(40.0, 30.0, 20.0);
    let l = LightGrid::new(d, data).expect("valid");
    let m = MaterialGrid::filled(
        d,
        Material {
            reflectance: Vec3::splat(0.3),
            pass: 0.2,
        },
    )
    .expect("valid");
    vec![
        GridFile::Light(l.clone()).to_bytes(),
        GridFile::PackedLight(l.pack()).to_bytes(),
        GridFile::Material(m).to_bytes(),
    ]
}

/// Reads a grid file and exports what it holds: light as both texel formats with the
/// validity fill (every other point invalid), DDS, KTX2 and a sidecar whose unit scale
/// comes from the input's last byte. Accepted when the whole export succeeded.
pub fn run_export(b: &[u8]) -> bool {
    let grid = match GridFile::from_bytes(b) {
        Ok(GridFile::Light(l)) => l,
        Ok(GridFile::PackedLight(p)) => p.unpack(),
        Ok(GridFile::Material(m)) => {
            let valid = lightgrid_core::validity::valid_points(&m);
            assert_eq!(valid.len(), m.desc().point_count());
            return true;
        }
        Ok(_) | Err(_) => return false,
    };
    let desc = *grid.desc();
    // 1e-32 to 1e32 from the last byte: every seed's product with its intensity stays
    // a positive finite f32; mutated grids reach the refusals.
    let scale = b
        .last()
        .map_or(1.0, |&x| 10f32.powf((x as f32 - 128.0) / 4.0));
    let valid: Vec<bool> = (0..desc.point_count()).map(|i| i % 2 == 0).collect();
    let mut ok = true;
    for format in [TexelFormat::Rgb9e5, TexelFormat::Rg11b10] {
        let v = match BevyVolume::from_field_valid(&grid, &desc, format, &valid) {
            Ok(v) => v,
            Err(_) => return false,
        };
        assert!(
            v.intensity().is_finite() && v.intensity() >= 0.0,
            "intensity"
        );
        ok &= v.to_dds().is_ok();
        assert!(!v.to_ktx2().is_empty());
        match v.sidecar("fuzz", Content::Indirect, scale) {
            Ok(info) => {
                assert!(
                    info.intensity.is_finite() && info.intensity > 0.0,
                    "sidecar intensity"
                );
            }
            Err(_) => ok = false,
        }
    }
    ok
}

/// Material grid files to bake.
pub fn bake_seeds() -> Vec<Vec<u8>> {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 3, 4)).expect("valid");
    let mut cells = vec![Material::EMPTY; d.point_count()];
    for c in &mut cells[..d.level_len()] {
        *c = Material::opaque(Vec3::splat(0.3));
    }
    cells[20] = Material {
        reflectance: Vec3::new(0.2, 0.6, 0.1),
        pass: 0.4,
    };
    vec![GridFile::Material(MaterialGrid::new(d, cells).expect("valid")).to_bytes()]
}

/// The bake path of `lightgrid bake` on a material grid file: two passes under a
/// uniform sky and a sun whose elevation comes from the input's last byte, the direct
/// sun removed ([`lightgrid_export::indirect_light`]), the validity fill, both texel
/// formats, DDS, KTX2 and the sidecar. Grids over 4096 points are rejected (time).
pub fn run_bake(b: &[u8]) -> bool {
    let m = match GridFile::from_bytes(b) {
        Ok(GridFile::Material(m)) if m.desc().point_count() <= 4096 => m,
        _ => return false,
    };
    let elevation = b
        .last()
        .map_or(30.0, |&x| x as f32 * 0.4 - 10.0)
        .to_radians();
    let Ok(sky) = lightgrid_sky::uniform_sky(Vec3::splat(0.5)) else {
        return false;
    };
    let sun = lightgrid_sky::Sun::at(elevation, 1.0, Vec3::splat(3.0))
        .bins()
        .unwrap_or(BinLight::ZERO);
    let both = lightgrid_core::Boundary {
        top: lightgrid_core::TopBoundary::Uniform(Box::new(sky.top + sun)),
        bottom: sky.bottom,
        sides: lightgrid_core::SideBoundary::Open,
    };
    let sun_alone = lightgrid_core::Boundary::open_sky(sun);
    let mut o = lightgrid_core::SweepOptions::multi_bounce();
    o.max_passes = 2;
    let Ok(light) = lightgrid_export::indirect_light(
        &mut lightgrid_sweep_cpu::CpuSweeper::new(),
        &m,
        &both,
        Some(&sun_alone),
        &o,
    ) else {
        return false;
    };
    assert!(light.data().iter().all(|l| l.is_valid()), "baked light");
    let valid = lightgrid_core::validity::valid_points(&m);
    for format in [TexelFormat::Rgb9e5, TexelFormat::Rg11b10] {
        let Ok(v) = BevyVolume::from_field_valid(&light, m.desc(), format, &valid) else {
            return false;
        };
        if v.to_dds().is_err() || v.to_ktx2().is_empty() {
            return false;
        }
        if let Ok(info) = v.sidecar("bake", Content::Indirect, 1.0) {
            assert!(
                info.intensity.is_finite() && info.intensity > 0.0,
                "sidecar"
            );
        }
    }
    true
}

/// The input's bytes as a stream of `f32` and `u32` values (wrapping round).
struct Values<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Values<'_> {
    fn u32(&mut self) -> u32 {
        if self.bytes.is_empty() {
            return 0;
        }
        let mut w = [0u8; 4];
        for x in &mut w {
            *x = self.bytes[self.at % self.bytes.len()];
            self.at += 1;
        }
        u32::from_le_bytes(w)
    }
    fn f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }
    fn v3(&mut self) -> Vec3 {
        Vec3::new(self.f32(), self.f32(), self.f32())
    }
    /// A size that allocates little: mostly 0 to 5, sometimes `u32::MAX` (refused
    /// before anything is allocated).
    fn size(&mut self) -> u32 {
        let v = self.u32();
        if v & 0xFF == 0xFF { u32::MAX } else { v % 6 }
    }
}

/// Seeds for [`run_api`]: a grid descriptor (origin, spacing, three sizes) then
/// ordinary values (the mutations write zeros, all ones, `u32::MAX` and other extremes
/// over them).
pub fn api_seeds() -> Vec<Vec<u8>> {
    let seed = |origin: [f32; 3], h: f32, dims: [u32; 3], rest: &[f32]| {
        let mut b: Vec<u8> = origin.iter().flat_map(|x| x.to_le_bytes()).collect();
        b.extend(h.to_le_bytes());
        b.extend(dims.iter().flat_map(|x| x.to_le_bytes()));
        b.extend(rest.iter().flat_map(|x| x.to_le_bytes()));
        b
    };
    vec![
        seed(
            [0.5, 1.0, 2.0],
            0.25,
            [2, 3, 4],
            &[3.0, 0.9, 1.5, 0.1, 4.0, 0.7, 2.5, 0.3],
        ),
        seed(
            [-4.0, 0.0, 9.0],
            2.0,
            [1, 5, 1],
            &[0.2, 0.75, 0.6, 0.4, 1.0, 5.0, 0.8],
        ),
    ]
}

/// Calls the library's entry points with values from `b`. Accepted when the grid
/// descriptor it starts from was.
pub fn run_api(b: &[u8]) -> bool {
    lightgrid_core::limits::set_memory_limit(crate::fuzz::FUZZ_MEMORY_LIMIT);
    let mut r = Values { bytes: b, at: 0 };
    let desc = (r.v3(), r.f32(), UVec3::new(r.size(), r.size(), r.size()));
    // Projections of any bins.
    let bins = BinLight(std::array::from_fn(|_| r.v3()));
    let n = r.v3();
    assert!(
        bins.total().is_finite() && bins.irradiance(n).is_finite(),
        "projection"
    );
    assert!(bins.sh2().0.iter().all(|c| c.is_finite()), "sh2");
    assert!(
        bins.ambient_cube().0.iter().all(|c| c.is_finite()),
        "ambient cube"
    );
    assert!(bins.dominant().is_finite(), "dominant");
    for d in 0..NUM_DIRS {
        assert!(bins.horizon_share(d).is_finite(), "horizon share");
    }
    // Suns and skies.
    let (elevation, azimuth, light) = (r.f32(), r.f32(), r.v3());
    if let Ok(s) = lightgrid_sky::Sun::at(elevation, azimuth, light).bins() {
        assert!(s.is_valid(), "sun bins");
    }
    if let Ok(s) = lightgrid_sky::uniform_sky(light) {
        assert!(s.top.is_valid(), "uniform sky");
    }
    let _ = lightgrid_core::light::check_sun(r.v3(), r.v3());
    let _ = SidecarSun::new(r.v3(), r.v3(), r.f32());
    // Heightmaps.
    let (w, d) = (r.size(), r.size());
    let heights: Vec<f32> = (0..(w as u64 * d as u64).min(64))
        .map(|_| r.f32())
        .collect();
    if let Ok(hm) =
        lightgrid_core::Heightmap::new(Vec2::new(r.f32(), r.f32()), r.f32(), w, d, heights)
    {
        assert!(hm.height_at(r.f32(), r.f32()).is_finite(), "height");
    }
    // Voxelization parameters.
    let mut p = lightgrid_material_voxelizer::voxelize::VoxelizeParams::preview(r.f32());
    p.directions = r.u32();
    p.chords_per_direction = r.u32();
    let _ = p.validate();
    // Grids, compression and light sets.
    let Ok(desc) = GridDesc::new(desc.0, desc.1, desc.2) else {
        return false;
    };
    if let Ok(mut g) = LightGrid::filled(desc, BinLight::uniform(r.v3().abs())) {
        if let Some(first) = g.data_mut().first_mut() {
            first.0[0] = r.v3();
        }
        let c = lightgrid_light_volumes::CompressedVolume::compress(&g, 1);
        assert!(c.scale.is_finite(), "compressed scale");
        if let Ok(mut set) = lightgrid_light_volumes::LightSet::new(
            GridDesc::new(Vec3::ZERO, desc.h(), UVec3::splat(4)).unwrap_or(desc),
        ) && set.add(&c, r.v3(), r.f32()).is_ok()
        {
            assert!(set.grid().data().iter().all(|b| b.is_valid()), "light set");
        }
    }
    // The exact problems, kept short.
    let (w, pass, depth) = (r.f32(), r.f32(), r.f32());
    if depth.abs() < 8.0
        && let Ok(c) = lightgrid_measure::exact::half_space(w, pass, depth, r.u32() % 8)
    {
        assert!(c.swept.is_finite(), "half-space");
    }
    let _ = lightgrid_measure::exact::furnace_material(r.u32(), 1).map(|m| m.desc().point_count());
    true
}
