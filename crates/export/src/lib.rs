//! Light grids into engines: **Bevy irradiance volumes**, as DDS and KTX2 3D textures
//! with a JSON sidecar.
//!
//! Bevy (0.13 and later) lights meshes inside an `IrradianceVolume` from a 3D texture of
//! ambient cubes, but ships no baker. This crate turns any light field — a swept
//! [`LightGrid`], the grid hierarchy, or the indirect part of either — into that texture.
//! Where the field keeps the sweep's horizon halves (a
//! [`lightgrid_core::SplitLightGrid`], [`indirect_light_split`]) the faces read each
//! horizontal bin in its two halves, exact across the horizon.
//!
//! ```
//! use lightgrid_export::{BevyVolume, TexelFormat};
//! use lightgrid_core::{BinLight, GridDesc, LightGrid, glam::{UVec3, Vec3}};
//!
//! // A 4 x 3 x 2 grid of points 0.5 m apart, lit by a uniform radiance of 1.
//! let desc = GridDesc::new(Vec3::ZERO, 0.5, UVec3::new(4, 3, 2)).unwrap();
//! let grid = LightGrid::filled(desc, BinLight::uniform(Vec3::ONE)).unwrap();
//! let volume = BevyVolume::from_field(&grid, &desc, TexelFormat::Rgb9e5).unwrap();
//! assert_eq!(volume.texture_size(), UVec3::new(4, 6, 6));
//! // Every face holds irradiance / pi = 1 (times the volume's intensity).
//! let texel = volume.texel(UVec3::new(1, 1, 1), 3);
//! assert!((texel * volume.intensity() - Vec3::ONE).abs().max_element() < 4e-3);
//! let dds = volume.to_dds().unwrap();
//! assert_eq!(&dds[..4], b"DDS ");
//! ```
//!
//! # Layout (what Bevy reads)
//!
//! A grid of `(Rx, Ry, Rz)` points becomes a 3D texture of `(Rx, 2 Ry, 3 Rz)` texels, one
//! 32-bit texel per point and face of the ambient cube:
//!
//! ```text
//! texel(x, y, z, face) = (x,  y + Ry * [face is negative],  z + Rz * axis(face))
//! value = irradiance on the face's axis normal / pi / intensity
//! ```
//!
//! The face placement follows Bevy's shader (`irradiance_volume.wgsl`), which reads a
//! negative normal component from the upper half of `t`; Bevy's module docs state the
//! opposite. See [`lightgrid_core::AmbientCube::bevy_texel`]; `tests/bevy.rs` runs a port of
//! the shader's lookup on the written files. Bevy multiplies the sample by the diffuse
//! colour and by [`IrradianceVolume::intensity`], hence the `/ pi` (Lambert) and the
//! intensity: texels are scaled by a power of two so the brightest is near 2^14, far from
//! both ends of the formats' range, and the sidecar's `intensity` undoes it (times the
//! caller's `unit_scale`, from the grid's light units to Bevy's cd/m²).
//!
//! Bevy's light probes are unit cubes `[-1/2, 1/2]^3` under a transform, with voxel
//! centres at `(i + 1/2) / R`. Grid point `i` sits at `origin + h i`, so the transform is
//! `translation = origin + h (dims - 1) / 2`, `scale = h dims`, no rotation; the volume's
//! box reaches half a spacing past the outer points on every side.
//!
//! # Formats
//!
//! | format | bits (R, G, B) | relative error | when |
//! |--------|----------------|----------------|------|
//! | [`TexelFormat::Rgb9e5`] (default) | 9, 9, 9 mantissa, shared 5-bit exponent | 2^-9 of the brightest channel | light with colour: sky blue beside sun yellow |
//! | [`TexelFormat::Rg11b10`] | 6, 6, 5 mantissa, own exponents | 2^-7 (R, G), 2^-6 (B) of each channel | dark channels next to bright ones |
//!
//! Both are 4 bytes a texel, 24 bytes a point (Bevy's own figure for ambient cubes).
//! DDS is written with `ddsfile` (a DX10 header, `DXGI_FORMAT_R9G9B9E5_SHAREDEXP` or
//! `R11G11B10_FLOAT`, depth = `3 Rz`), KTX2 with the `ktx2` crate's header types
//! (`E5B9G9R9_UFLOAT_PACK32` or `B10G11R11_UFLOAT_PACK32`, one level, a basic data format
//! descriptor); both are the crates Bevy's loaders use.
//!
//! [`LightGrid`]: lightgrid_core::LightGrid
//! [`IrradianceVolume::intensity`]: https://docs.rs/bevy/latest/bevy/pbr/irradiance_volume/struct.IrradianceVolume.html

use std::num::NonZeroU8;
use std::path::{Path, PathBuf};

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    AmbientCube, BinLight, Boundary, GridDesc, GridError, HorizonGrid, LightField, LightGrid,
    MaterialGrid, MaterialSource, NoScatter, SplitLightGrid, SweepError, SweepOptions, Sweeper,
    pack,
};
use serde::{Deserialize, Serialize};

/// The largest side of a 3D texture wgpu allows by default (`max_texture_dimension_3d`).
pub const MAX_TEXTURE_SIDE: u32 = 2048;

/// The brightest texel is scaled to about this value (2^14): far below the formats'
/// largest value (65024 and more), far above their smallest normal (2^-14).
const TARGET_MAX: f32 = 16384.0;

/// What went wrong while exporting.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A grid error (a bad descriptor, a light field that cannot be sampled, I/O).
    #[error(transparent)]
    Grid(#[from] GridError),
    /// The texture would not fit a GPU's 3D texture.
    #[error("{field} = {value}: a 3D texture side may be at most {MAX_TEXTURE_SIDE} texels")]
    TooLarge {
        /// Which side (`texture width`, `texture height`, `texture depth`).
        field: &'static str,
        /// Its size in texels.
        value: u64,
    },
    /// A parameter out of its range.
    #[error("invalid {field} = {value}: {reason}")]
    Invalid {
        /// The parameter.
        field: &'static str,
        /// Its value.
        value: String,
        /// What it must be.
        reason: &'static str,
    },
    /// A sweep failed.
    #[error(transparent)]
    Sweep(#[from] SweepError),
    /// The DDS writer refused the texture.
    #[error("writing DDS: {0}")]
    Dds(String),
}

/// The texel format of the exported texture (see the module docs' table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum TexelFormat {
    /// Shared-exponent RGB (`Rgb9e5Ufloat` in wgpu and Bevy).
    #[default]
    Rgb9e5,
    /// Packed small floats (`Rg11b10Ufloat` in wgpu and Bevy).
    Rg11b10,
}

impl TexelFormat {
    /// wgpu's name of the format (what Bevy's loaders produce).
    pub const fn wgpu_name(self) -> &'static str {
        match self {
            Self::Rgb9e5 => "Rgb9e5Ufloat",
            Self::Rg11b10 => "Rg11b10Ufloat",
        }
    }
    /// Packs linear RGB into one texel.
    pub fn pack(self, c: Vec3) -> u32 {
        match self {
            Self::Rgb9e5 => pack::pack_rgb9e5(c),
            Self::Rg11b10 => pack::pack_r11g11b10(c),
        }
    }
    /// Unpacks one texel.
    pub fn unpack(self, w: u32) -> Vec3 {
        match self {
            Self::Rgb9e5 => pack::unpack_rgb9e5(w),
            Self::Rg11b10 => pack::unpack_r11g11b10(w),
        }
    }
    fn dxgi(self) -> ddsfile::DxgiFormat {
        match self {
            Self::Rgb9e5 => ddsfile::DxgiFormat::R9G9B9E5_SharedExp,
            Self::Rg11b10 => ddsfile::DxgiFormat::R11G11B10_Float,
        }
    }
    fn vk(self) -> ktx2::Format {
        match self {
            Self::Rgb9e5 => ktx2::Format::E5B9G9R9_UFLOAT_PACK32,
            Self::Rg11b10 => ktx2::Format::B10G11R11_UFLOAT_PACK32,
        }
    }
}

/// An irradiance volume ready to write: packed texels, transform and intensity.
#[derive(Debug, Clone, PartialEq)]
pub struct BevyVolume {
    desc: GridDesc,
    format: TexelFormat,
    /// Texels in texture order: `x` fastest, then `t` (`2 Ry`), then `p` (`3 Rz`).
    texels: Vec<u32>,
    intensity: f32,
}

impl BevyVolume {
    /// [`BevyVolume::from_field`] with the points inside geometry given their valid
    /// neighbours' light first (`lightgrid_core::validity`: `valid` holds one flag per
    /// point of `desc`, [`lightgrid_core::validity::valid_points`] of the material
    /// there). Bevy reads the volume trilinearly: a surface half way between a point
    /// inside the ground and one above would otherwise get about half the light. Points
    /// whose lookups have all eight corners valid read what they read before.
    pub fn from_field_valid(
        field: &impl LightField,
        desc: &GridDesc,
        format: TexelFormat,
        valid: &[bool],
    ) -> Result<Self, ExportError> {
        lightgrid_core::limits::check_memory(
            "irradiance volume's light",
            lightgrid_core::limits::checked_bytes(
                "points",
                &[
                    desc.point_count() as u64,
                    std::mem::size_of::<BinLight>() as u64,
                ],
            )?,
        )?;
        let at = |i: usize| desc.position(desc.coords(i).expect("in range"));
        let data = (0..desc.point_count())
            .map(|i| field.light(at(i), None))
            .collect::<Result<Vec<_>, _>>()?;
        let mut grid = LightGrid::from_trusted(*desc, data);
        let rounds = lightgrid_core::validity::DEFAULT_ROUNDS;
        lightgrid_core::validity::fill_invalid(&mut grid, valid, rounds)?;
        // The horizon halves, where the field keeps them, filled the same way.
        let halves = (0..desc.point_count())
            .map(|i| field.horizon(at(i), None))
            .collect::<Result<Option<Vec<_>>, _>>()?;
        match halves {
            Some(h) => {
                let mut halves = lightgrid_core::HorizonGrid::from_trusted(*desc, h);
                lightgrid_core::validity::fill_invalid(&mut halves, valid, rounds)?;
                let split = lightgrid_core::SplitLightGrid::new(grid, halves)?;
                Self::from_field(&split, desc, format)
            }
            None => Self::from_field(&grid, desc, format),
        }
    }

    /// Samples `field` at every point of `desc` (no normal bias: the points are in free
    /// space or the light is what it is there) and packs the ambient cubes (each
    /// horizontal bin read in its two halves where the field keeps them,
    /// [`LightField::horizon`]: a [`lightgrid_core::SplitLightGrid`]). For a
    /// [`lightgrid_core::LightGrid`] sampled at its own descriptor this is its values exactly.
    pub fn from_field(
        field: &impl LightField,
        desc: &GridDesc,
        format: TexelFormat,
    ) -> Result<Self, ExportError> {
        let res = desc.dims();
        let size = texture_size(res);
        for (field, v) in [
            ("texture width", size.x),
            ("texture height", size.y),
            ("texture depth", size.z),
        ] {
            if v as u64 > MAX_TEXTURE_SIDE as u64 {
                return Err(ExportError::TooLarge {
                    field,
                    value: v as u64,
                });
            }
        }
        // Each side is at most 2048, so the product fits a u64; 4 bytes a texel plus
        // 4 x 3 floats a face while sampling.
        let n = size.x as u64 * size.y as u64 * size.z as u64;
        lightgrid_core::limits::check_memory("irradiance volume", n * 16)?;
        let n = n as usize;
        // Ambient cubes of every point, as irradiance / pi, in f64: faces of bins near
        // f32::MAX exceed it until the intensity scales them back.
        let mut cubes = Vec::with_capacity(desc.point_count());
        for z in 0..res.z {
            for y in 0..res.y {
                for x in 0..res.x {
                    let p = desc.position(UVec3::new(x, y, z));
                    let l = field.light(p, None)?;
                    let c = match field.horizon(p, None)? {
                        Some(h) => l.ambient_cube_split_f64(&h),
                        None => l.ambient_cube_f64(),
                    };
                    cubes.push(c.map(|f| f / std::f64::consts::PI));
                }
            }
        }
        let max = cubes
            .iter()
            .flat_map(|c| c.iter().map(|f| f.max_element()))
            .fold(0.0f64, f64::max);
        let intensity = intensity_for(max);
        let mut texels = vec![0u32; n];
        let mut i = 0;
        for z in 0..res.z {
            for y in 0..res.y {
                for x in 0..res.x {
                    for (face, v) in cubes[i].iter().enumerate() {
                        let t = AmbientCube::bevy_texel(UVec3::new(x, y, z), face, res);
                        let k = (t.x + size.x * (t.y + size.y * t.z)) as usize;
                        texels[k] = format.pack((*v / intensity as f64).as_vec3());
                    }
                    i += 1;
                }
            }
        }
        Ok(Self {
            desc: *desc,
            format,
            texels,
            intensity,
        })
    }

    /// The grid the volume was sampled on.
    pub fn desc(&self) -> &GridDesc {
        &self.desc
    }
    /// The texel format.
    pub fn format(&self) -> TexelFormat {
        self.format
    }
    /// `(Rx, 2 Ry, 3 Rz)`.
    pub fn texture_size(&self) -> UVec3 {
        texture_size(self.desc.dims())
    }
    /// The packed texels, `x` fastest, then `t`, then `p`.
    pub fn texels(&self) -> &[u32] {
        &self.texels
    }
    /// The factor that turns texel values back into irradiance / pi (a power of two).
    pub fn intensity(&self) -> f32 {
        self.intensity
    }
    /// The unpacked texel of face `face` (ambient-cube order `+X, -X, +Y, -Y, +Z, -Z`) of
    /// grid point `p` (before the intensity).
    pub fn texel(&self, p: UVec3, face: usize) -> Vec3 {
        let size = self.texture_size();
        let t = AmbientCube::bevy_texel(p, face, self.desc.dims());
        self.format
            .unpack(self.texels[(t.x + size.x * (t.y + size.y * t.z)) as usize])
    }
    /// Bevy's light-probe transform: the unit cube onto the volume's box.
    pub fn transform(&self) -> Transform {
        let d = self.desc.dims().as_vec3();
        let h = self.desc.h();
        Transform {
            translation: (self.desc.origin() + h * (d - Vec3::ONE) * 0.5).to_array(),
            rotation: [0.0, 0.0, 0.0, 1.0],
            scale: (h * d).to_array(),
        }
    }

    /// The texture as a DDS file (DX10 header, a volume texture of one mip level).
    pub fn to_dds(&self) -> Result<Vec<u8>, ExportError> {
        let size = self.texture_size();
        let mut dds = ddsfile::Dds::new_dxgi(ddsfile::NewDxgiParams {
            height: size.y,
            width: size.x,
            depth: Some(size.z),
            format: self.format.dxgi(),
            mipmap_levels: Some(1),
            array_layers: None,
            caps2: Some(ddsfile::Caps2::VOLUME),
            is_cubemap: false,
            resource_dimension: ddsfile::D3D10ResourceDimension::Texture3D,
            alpha_mode: ddsfile::AlphaMode::Unknown,
        })
        .map_err(|e| ExportError::Dds(e.to_string()))?;
        let bytes: &[u8] = bytemuck_cast(&self.texels);
        if dds.data.len() != bytes.len() {
            return Err(ExportError::Dds(format!(
                "ddsfile sized the data {} bytes, the texels are {}",
                dds.data.len(),
                bytes.len()
            )));
        }
        dds.data.copy_from_slice(bytes);
        let mut out = Vec::with_capacity(bytes.len() + 148);
        dds.write(&mut out)
            .map_err(|e| ExportError::Dds(e.to_string()))?;
        Ok(out)
    }

    /// The texture as a KTX2 file: one level, no supercompression, a basic data format
    /// descriptor for the packed format, and a `KTXwriter` key.
    pub fn to_ktx2(&self) -> Vec<u8> {
        let size = self.texture_size();
        let dfd = basic_dfd(self.format);
        let kvd = key_value(
            "KTXwriter",
            concat!("lightgrid-export ", env!("CARGO_PKG_VERSION")),
        );
        let level_index_len = ktx2::LevelIndex::LENGTH;
        let dfd_offset = ktx2::Header::LENGTH + level_index_len;
        let kvd_offset = dfd_offset + dfd.len();
        // Level data aligned to lcm(texel block size 4, 4).
        let data_offset = (kvd_offset + kvd.len()).next_multiple_of(4);
        let bytes: &[u8] = bytemuck_cast(&self.texels);
        let header = ktx2::Header {
            format: Some(self.format.vk()),
            type_size: 4,
            pixel_width: size.x,
            pixel_height: size.y,
            pixel_depth: size.z,
            layer_count: 0,
            face_count: 1,
            level_count: 1,
            supercompression_scheme: None,
            index: ktx2::Index {
                dfd_byte_offset: dfd_offset as u32,
                dfd_byte_length: dfd.len() as u32,
                kvd_byte_offset: kvd_offset as u32,
                kvd_byte_length: kvd.len() as u32,
                sgd_byte_offset: 0,
                sgd_byte_length: 0,
            },
        };
        let level = ktx2::LevelIndex {
            byte_offset: data_offset as u64,
            byte_length: bytes.len() as u64,
            uncompressed_byte_length: bytes.len() as u64,
        };
        let mut out = Vec::with_capacity(data_offset + bytes.len());
        out.extend_from_slice(&header.as_bytes());
        out.extend_from_slice(&level.as_bytes());
        out.extend_from_slice(&dfd);
        out.extend_from_slice(&kvd);
        out.resize(data_offset, 0);
        out.extend_from_slice(bytes);
        out
    }

    /// The sidecar describing this volume (file names relative to the sidecar). The
    /// written intensity, `intensity × unit_scale`, must be a positive finite `f32` (a
    /// scale of 1e-45 gave 0, 1e20 on a bright grid infinity): else an error naming
    /// `unit_scale`.
    pub fn sidecar(
        &self,
        stem: &str,
        content: Content,
        unit_scale: f32,
    ) -> Result<VolumeInfo, ExportError> {
        let product = self.intensity * unit_scale;
        if !(unit_scale.is_finite() && product.is_finite() && product > 0.0) {
            return Err(ExportError::Invalid {
                field: "unit_scale",
                value: format!("{unit_scale:?} (the volume's intensity {})", self.intensity),
                reason: "times the volume's intensity it must be a positive finite f32",
            });
        }
        let d = self.desc.dims();
        Ok(VolumeInfo {
            name: stem.to_string(),
            dds: format!("{stem}.dds"),
            ktx2: format!("{stem}.ktx2"),
            format: self.format.wgpu_name().to_string(),
            resolution: d.to_array(),
            texture_size: self.texture_size().to_array(),
            transform: self.transform(),
            intensity: self.intensity * unit_scale,
            content,
            grid_origin: self.desc.origin().to_array(),
            grid_spacing: self.desc.h(),
        })
    }

    /// Writes `<stem>.dds` and `<stem>.ktx2` into `dir` (created if missing), both or
    /// neither. Returns the paths written.
    pub fn write(&self, dir: &Path, stem: &str) -> Result<Vec<PathBuf>, ExportError> {
        let files = self.files(dir, stem)?;
        create_dir(dir)?;
        lightgrid_core::file::write_all_atomic(&files)?;
        Ok(files.into_iter().map(|(p, _)| p).collect())
    }

    /// The two files of [`BevyVolume::write`], encoded.
    fn files(&self, dir: &Path, stem: &str) -> Result<Vec<(PathBuf, Vec<u8>)>, ExportError> {
        check_stem(stem)?;
        let _span = tracing::info_span!("encode volume", dir = %dir.display(), stem).entered();
        Ok(vec![
            (dir.join(format!("{stem}.dds")), self.to_dds()?),
            (dir.join(format!("{stem}.ktx2")), self.to_ktx2()),
        ])
    }
}

/// What light an export holds. The sky belongs in the volume either way: inside an
/// irradiance volume Bevy's environment map adds no diffuse light
/// (`pbr_functions.wgsl`: the volume sets `found_diffuse_indirect`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Content {
    /// Sky light and the sun's scattered light, without the direct sun: for engines that
    /// add their own directional light (Bevy's `DirectionalLight`). The default.
    Indirect,
    /// Everything the sweep computed, the direct sun included.
    All,
}

/// Bevy's `Transform` of a light probe: translation, rotation (quaternion `x, y, z, w`),
/// scale.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Centre of the volume's box.
    pub translation: [f32; 3],
    /// Always the identity: grids are axis-aligned.
    pub rotation: [f32; 4],
    /// Size of the volume's box.
    pub scale: [f32; 3],
}

/// One volume in the sidecar.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VolumeInfo {
    /// File stem.
    pub name: String,
    /// DDS file, relative to the sidecar.
    pub dds: String,
    /// KTX2 file, relative to the sidecar.
    pub ktx2: String,
    /// wgpu texture format of both files.
    pub format: String,
    /// Grid points `(Rx, Ry, Rz)`.
    pub resolution: [u32; 3],
    /// Texture size `(Rx, 2 Ry, 3 Rz)`.
    pub texture_size: [u32; 3],
    /// The light probe's transform.
    pub transform: Transform,
    /// `IrradianceVolume::intensity`: texel × intensity = irradiance / pi in Bevy's units.
    pub intensity: f32,
    /// Which light the texels hold.
    pub content: Content,
    /// World position of grid point (0, 0, 0).
    pub grid_origin: [f32; 3],
    /// Distance between grid points.
    pub grid_spacing: f32,
}

/// The sidecar file (`<name>.json`): every volume, first = coarsest (the world grid),
/// then finer ones. Where volumes overlap, Bevy (0.17, 0.18) lights a fragment from one of
/// them: it sorts a view's irradiance volumes by the distance from the camera to each
/// volume's centre, nearest first, and takes the first that contains the fragment. The
/// viewer's near volumes are centred on the nodes around the camera, so the finer ones
/// usually come first; each volume is complete on its own, so either choice is right to
/// within the resampling error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    /// `"lightgrid-bevy-irradiance-volumes"`.
    pub kind: String,
    /// Sidecar format version (2: `units` and `sun` added).
    pub version: u32,
    /// Where the texels go in the texture.
    pub face_order: String,
    /// What the numbers mean in Bevy's units ([`UNITS`]).
    #[serde(default)]
    pub units: String,
    /// The sun a volume of [`Content::Indirect`] leaves out, for the engine's own
    /// directional light (absent where the volume holds it, or there is none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sun: Option<SidecarSun>,
    /// The volumes.
    pub volumes: Vec<VolumeInfo>,
}

/// The sidecar's note on units: `unit_scale` takes the grid's light to Bevy's (radiance
/// in cd/m², irradiance in lux), and Bevy's camera exposure decides how bright that
/// looks.
pub const UNITS: &str = "texel * intensity = irradiance / pi on the face's axis, in Bevy's units: \
the grid's light times the unit_scale the volume was written with (radiance in cd/m2, \
irradiance in lux). Pick unit_scale so that sun.illuminance suits the camera's exposure: \
Bevy's Exposure::SUNLIGHT (EV100 15) is made for a sun of about 100,000 lux \
(light_consts::lux::DIRECT_SUNLIGHT); each EV100 step halves it, so the default \
Exposure::BLENDER (EV100 9.7) suits about 2,500 lux. unit_scale = wanted lux / the \
sun's illuminance in the grid's units (sun.illuminance / unit_scale).";

/// The sun in Bevy's terms: a `DirectionalLight` with `illuminance` and `color` and a
/// transform `Transform::default().looking_to(-direction_to_sun, Vec3::Y)` (it shines
/// along its forward axis).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SidecarSun {
    /// Unit vector towards the sun (world axes, `+Y` up).
    pub direction_to_sun: [f32; 3],
    /// `DirectionalLight::illuminance`, lux: the luminance of the sun's irradiance on a
    /// surface facing it, times `unit_scale`.
    pub illuminance: f32,
    /// `DirectionalLight::color`: the irradiance's colour as linear RGB of luminance 1
    /// (`Color::linear_rgb`).
    pub color: [f32; 3],
}

impl SidecarSun {
    /// The sun towards `to_sun` with irradiance `irradiance` (RGB, the grid's units)
    /// facing it, for a volume written with `unit_scale`. `None` for a sun without light
    /// or below the horizon (it lights nothing there).
    pub fn new(
        to_sun: Vec3,
        irradiance: Vec3,
        unit_scale: f32,
    ) -> Result<Option<Self>, ExportError> {
        let Some(dir) = lightgrid_core::unit(to_sun) else {
            return Err(ExportError::Invalid {
                field: "sun direction",
                value: format!("{to_sun:?}"),
                reason: "must be finite and non-zero",
            });
        };
        if !(irradiance.is_finite() && irradiance.min_element() >= 0.0) {
            return Err(ExportError::Invalid {
                field: "sun irradiance",
                value: format!("{irradiance:?}"),
                reason: "must be finite and >= 0",
            });
        }
        if !(unit_scale.is_finite() && unit_scale > 0.0) {
            return Err(ExportError::Invalid {
                field: "unit_scale",
                value: format!("{unit_scale:?}"),
                reason: "must be finite and > 0",
            });
        }
        let luminance = lightgrid_core::light::luminance(irradiance);
        let lux = luminance * unit_scale;
        if !lux.is_finite() {
            return Err(ExportError::Invalid {
                field: "unit_scale",
                value: format!("{unit_scale:?}"),
                reason: "times the sun's illuminance it must stay finite",
            });
        }
        if luminance <= 0.0 || dir.y <= 0.0 {
            return Ok(None);
        }
        if lux <= 0.0 {
            return Err(ExportError::Invalid {
                field: "unit_scale",
                value: format!("{unit_scale:?}"),
                reason: "times the sun's illuminance it must stay above 0 in f32",
            });
        }
        // (In f64: a luminance near f32's smallest would overflow the division.)
        let color = (irradiance.as_dvec3() / luminance as f64).as_vec3();
        Ok(Some(Self {
            direction_to_sun: dir.to_array(),
            illuminance: lux,
            color: color.to_array(),
        }))
    }
}

impl Sidecar {
    /// The sidecar of `volumes`, with the sun they leave out (if any).
    pub fn new(volumes: Vec<VolumeInfo>, sun: Option<SidecarSun>) -> Self {
        Self {
            kind: "lightgrid-bevy-irradiance-volumes".into(),
            version: 2,
            face_order: "Bevy's shader: s = x; t = y for +X, +Y, +Z and y + Ry for -X, -Y, -Z; \
                         p = z + Rz * axis (X 0, Y 1, Z 2)"
                .into(),
            units: UNITS.into(),
            sun,
            volumes,
        }
    }
    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
    /// Writes the sidecar as `<dir>/<stem>.json`, atomically.
    pub fn write(&self, dir: &Path, stem: &str) -> Result<PathBuf, ExportError> {
        let (path, bytes) = self.file(dir, stem)?;
        lightgrid_core::file::write_atomic(&path, &bytes)?;
        Ok(path)
    }

    /// The sidecar's file, encoded.
    fn file(&self, dir: &Path, stem: &str) -> Result<(PathBuf, Vec<u8>), ExportError> {
        check_stem(stem)?;
        Ok((
            dir.join(format!("{stem}.json")),
            self.to_json().into_bytes(),
        ))
    }
}

/// `dir` and its parents, created where missing.
fn create_dir(dir: &Path) -> Result<(), ExportError> {
    std::fs::create_dir_all(dir).map_err(|source| {
        GridError::Io {
            path: dir.to_path_buf(),
            source,
        }
        .into()
    })
}

/// Exports several volumes (coarsest first) into `dir`: `<stem>-<i>.dds`, `.ktx2` each
/// and one `<stem>.json`. `sun` (direction towards it, irradiance facing it in the
/// grid's units) is the sun the light was swept under: with [`Content::Indirect`] the
/// sidecar describes it for the engine's directional light ([`SidecarSun`]); a volume
/// of [`Content::All`] holds it already and the sidecar leaves it out. Returns every
/// path written.
pub fn write_volumes(
    dir: &Path,
    stem: &str,
    volumes: &[BevyVolume],
    content: Content,
    unit_scale: f32,
    sun: Option<(Vec3, Vec3)>,
) -> Result<Vec<PathBuf>, ExportError> {
    if !(unit_scale.is_finite() && unit_scale > 0.0) {
        return Err(ExportError::Invalid {
            field: "unit_scale",
            value: format!("{unit_scale:?}"),
            reason: "must be finite and > 0",
        });
    }
    let sun = match (content, sun) {
        (Content::Indirect, Some((to_sun, e))) => SidecarSun::new(to_sun, e, unit_scale)?,
        _ => None,
    };
    // Every file encoded first, then written as one set: all of them or none.
    let mut files = Vec::new();
    let mut infos = Vec::new();
    for (i, v) in volumes.iter().enumerate() {
        let name = if volumes.len() == 1 {
            stem.to_string()
        } else {
            format!("{stem}-{i}")
        };
        files.extend(v.files(dir, &name)?);
        infos.push(v.sidecar(&name, content, unit_scale)?);
    }
    files.push(Sidecar::new(infos, sun).file(dir, stem)?);
    create_dir(dir)?;
    lightgrid_core::file::write_all_atomic(&files)?;
    Ok(files.into_iter().map(|(p, _)| p).collect())
}

/// The indirect light of `material` under `sky_and_sun`: everything the sweep computes
/// minus the sun's direct light, which is the same sweep under `sun` alone with every
/// reflectance set to zero ([`NoScatter`]): the light of the sun beam as the sweep
/// carries it, shadows and all, before any scattering. What remains is the sky and
/// every bounce of the sun, the light an engine that draws its own sun needs.
/// `sun = None` (no sun) returns the full sweep. Options must ask for the 26 bins.
pub fn indirect_light(
    sweeper: &mut dyn Sweeper,
    material: &MaterialGrid,
    sky_and_sun: &Boundary,
    sun: Option<&Boundary>,
    options: &SweepOptions,
) -> Result<LightGrid, ExportError> {
    Ok(indirect(sweeper, material, sky_and_sun, sun, options)?.0)
}

/// [`indirect_light`] with its horizon halves (the sweeps asked for them,
/// `Outputs::horizon`; the direct sun's halves removed with its bins), so that the
/// volume's faces read each horizontal bin in its two halves: exact across the horizon
/// (over a ground, facing down `a pi` where the bins alone read more). What
/// `lightgrid bake` exports.
pub fn indirect_light_split(
    sweeper: &mut dyn Sweeper,
    material: &MaterialGrid,
    sky_and_sun: &Boundary,
    sun: Option<&Boundary>,
    options: &SweepOptions,
) -> Result<SplitLightGrid, ExportError> {
    let mut o = *options;
    o.outputs = o.outputs.with_horizon();
    match indirect(sweeper, material, sky_and_sun, sun, &o)? {
        (bins, Some(halves)) => Ok(SplitLightGrid::new(bins, halves)?),
        (_, None) => Err(ExportError::Invalid {
            field: "options.outputs.horizon",
            value: sweeper.name().into(),
            reason: "this sweeper returned no horizon halves",
        }),
    }
}

/// The bins (and the halves, where the sweeps returned them) of [`indirect_light`].
fn indirect(
    sweeper: &mut dyn Sweeper,
    material: &MaterialGrid,
    sky_and_sun: &Boundary,
    sun: Option<&Boundary>,
    options: &SweepOptions,
) -> Result<(LightGrid, Option<HorizonGrid>), ExportError> {
    let mut run = |m: &MaterialGrid, b: &Boundary| -> Result<_, ExportError> {
        let out = sweeper.sweep(m, b, options)?;
        let bins = out.bins.ok_or_else(|| ExportError::Invalid {
            field: "options.outputs.bins",
            value: "false".into(),
            reason: "the export needs the 26 bins",
        })?;
        Ok((bins, out.horizon))
    };
    let (mut full, mut halves) = run(material, sky_and_sun)?;
    if let Some(sun) = sun {
        let dark = NoScatter(material).material(material.desc())?;
        let (direct, direct_halves) = run(&dark, sun)?;
        for (a, b) in full.data_mut().iter_mut().zip(direct.data()) {
            *a = a.saturating_sub(b);
        }
        if let (Some(h), Some(d)) = (halves.as_mut(), direct_halves) {
            for ((h, d), bins) in h.data_mut().iter_mut().zip(d.data()).zip(full.data()) {
                *h = (*h + *d * -1.0).within(bins);
            }
        } else {
            halves = None;
        }
    }
    Ok((full, halves))
}

fn check_stem(stem: &str) -> Result<(), ExportError> {
    let ok = !stem.is_empty()
        && stem.len() <= 128
        && stem
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
        && !stem.starts_with('.');
    if ok {
        Ok(())
    } else {
        Err(ExportError::Invalid {
            field: "name",
            value: format!("{stem:?}"),
            reason: "must be 1..=128 ASCII letters, digits, '-', '_' or '.', not starting with '.'",
        })
    }
}

fn texture_size(res: UVec3) -> UVec3 {
    UVec3::new(res.x, res.y.saturating_mul(2), res.z.saturating_mul(3))
}

/// The power of two that brings `max` near [`TARGET_MAX`]; 1 for no light. Any power
/// an `f32` holds: from 2^-149 (the least subnormal; light of 1e-38 keeps its digits)
/// to 2^127 (light near `f32::MAX`).
fn intensity_for(max: f64) -> f32 {
    if !(max.is_finite() && max > 0.0) {
        return 1.0;
    }
    let k = (max / TARGET_MAX as f64).log2().ceil().clamp(-149.0, 127.0) as i32;
    if k >= -126 {
        f32::from_bits(((k + 127) as u32) << 23)
    } else {
        f32::from_bits(1u32 << (k + 149))
    }
}

/// Little-endian bytes of the texels (every target Bevy runs on is little-endian; this
/// spells it out rather than reinterpreting memory).
fn bytemuck_cast(texels: &[u32]) -> &[u8] {
    #[cfg(target_endian = "little")]
    {
        bytemuck::cast_slice(texels)
    }
    #[cfg(not(target_endian = "little"))]
    compile_error!("lightgrid-export writes little-endian textures on little-endian targets only")
}

/// A KTX2 basic data format descriptor (with its total-size prefix) for a packed format:
/// RGBSDA, BT.709 primaries, linear transfer, one 4-byte plane. RGB9E5 has six samples
/// (three 9-bit mantissas and their shared 5-bit exponent, once per channel with the
/// `EXPONENT` qualifier); R11G11B10 three unsigned float samples.
fn basic_dfd(format: TexelFormat) -> Vec<u8> {
    use ktx2::ChannelTypeQualifiers as Q;
    let one = NonZeroU8::MIN;
    let sample = |offset: u16, bits: u8, channel: u8, q: Q, lower: u32, upper: u32| {
        ktx2::SampleInformation {
            bit_offset: offset,
            bit_length: NonZeroU8::new(bits).unwrap_or(one),
            channel_type: channel,
            channel_type_qualifiers: q,
            sample_positions: [0; 4],
            lower,
            upper,
        }
    };
    const F32_ONE: u32 = 0x3f80_0000;
    let samples: Vec<ktx2::SampleInformation> = match format {
        TexelFormat::Rgb9e5 => (0..3u8)
            .flat_map(|c| {
                [
                    sample(9 * c as u16, 9, c, Q::empty(), 0, 8448),
                    sample(27, 5, c, Q::EXPONENT, 15, 31),
                ]
            })
            .collect(),
        TexelFormat::Rg11b10 => vec![
            sample(0, 11, 0, Q::FLOAT, 0, F32_ONE),
            sample(11, 11, 1, Q::FLOAT, 0, F32_ONE),
            sample(22, 10, 2, Q::FLOAT, 0, F32_ONE),
        ],
    };
    let block_size = ktx2::DfdHeader::LENGTH
        + ktx2::DfdBlockHeaderBasic::LENGTH
        + samples.len() * ktx2::SampleInformation::LENGTH;
    let basic = ktx2::DfdBlockHeaderBasic {
        color_model: Some(ktx2::ColorModel::RGBSDA),
        color_primaries: Some(ktx2::ColorPrimaries::BT709),
        transfer_function: Some(ktx2::TransferFunction::Linear),
        flags: ktx2::DataFormatFlags::STRAIGHT_ALPHA,
        texel_block_dimensions: [one; 4],
        bytes_planes: [4, 0, 0, 0, 0, 0, 0, 0],
    };
    let mut out = Vec::with_capacity(4 + block_size);
    out.extend_from_slice(&((4 + block_size) as u32).to_le_bytes());
    out.extend_from_slice(&ktx2::DfdHeader::BASIC.as_bytes(block_size as u16));
    out.extend_from_slice(&basic.as_bytes());
    for s in &samples {
        out.extend_from_slice(&s.as_bytes());
    }
    out
}

/// One KTX2 key/value entry: length, `key\0value\0`, padded to 4 bytes.
fn key_value(key: &str, value: &str) -> Vec<u8> {
    let mut kv = Vec::new();
    kv.extend_from_slice(key.as_bytes());
    kv.push(0);
    kv.extend_from_slice(value.as_bytes());
    kv.push(0);
    let mut out = (kv.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(&kv);
    out.resize(out.len().next_multiple_of(4), 0);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::{BinLight, LightGrid};

    fn grid(dims: UVec3) -> (GridDesc, LightGrid) {
        let desc = GridDesc::new(Vec3::new(1.0, -2.0, 3.0), 0.5, dims).unwrap();
        let data = (0..desc.point_count())
            .map(|i| {
                BinLight(std::array::from_fn(|d| {
                    Vec3::splat((i * 26 + d) as f32 + 1.0)
                }))
            })
            .collect();
        (desc, LightGrid::new(desc, data).unwrap())
    }

    #[test]
    fn every_point_and_face_lands_where_bevy_texel_says() {
        let (desc, g) = grid(UVec3::new(3, 4, 5));
        for format in [TexelFormat::Rgb9e5, TexelFormat::Rg11b10] {
            let v = BevyVolume::from_field(&g, &desc, format).unwrap();
            assert_eq!(v.texels().len(), 3 * 8 * 15);
            for (i, b) in g.data().iter().enumerate() {
                let p = desc.coords(i).unwrap();
                let cube = b.ambient_cube();
                for face in 0..6 {
                    let want = cube.0[face] / std::f32::consts::PI;
                    let got = v.texel(p, face) * v.intensity();
                    let err = ((got - want).abs() / want.max_element()).max_element();
                    assert!(
                        err < 1.0 / 64.0,
                        "{format:?} point {p} face {face}: {got} vs {want}"
                    );
                }
            }
        }
    }

    /// Light that is the sky (radiance 1) above the horizon and a ground of albedo 0.3
    /// below it: with the horizon halves (a [`lightgrid_core::SplitLightGrid`]) the
    /// volume's faces hold the exact irradiance / pi, 1 facing up and 0.3 facing down
    /// (the bins alone read 0.339 facing down); through `from_field_valid` too.
    #[test]
    fn faces_read_the_horizon_halves_where_the_field_keeps_them() {
        use lightgrid_core::{HorizonGrid, HorizonLight, SplitLightGrid, dirs};
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 3, 2)).unwrap();
        let w = dirs::solid_angles();
        let (sky, ground) = (Vec3::ONE, Vec3::splat(0.3));
        let l = BinLight(std::array::from_fn(|d| match dirs::dir_ivec(d).y {
            -1 => sky * w[d],
            1 => ground * w[d],
            _ => (sky + ground) * (0.5 * w[d]),
        }));
        let down = HorizonLight(std::array::from_fn(|k| {
            sky * (0.5 * w[dirs::FIRST_HORIZONTAL + k])
        }));
        let bins = LightGrid::filled(desc, l).unwrap();
        let split =
            SplitLightGrid::new(bins.clone(), HorizonGrid::filled(desc, down).unwrap()).unwrap();
        let valid = vec![true; desc.point_count()];
        let p = UVec3::new(1, 1, 0);
        let (up, below) = (2, 3);
        for v in [
            BevyVolume::from_field(&split, &desc, TexelFormat::Rgb9e5).unwrap(),
            BevyVolume::from_field_valid(&split, &desc, TexelFormat::Rgb9e5, &valid).unwrap(),
        ] {
            let face = |f: usize| v.texel(p, f).x * v.intensity();
            assert!((face(up) - 1.0).abs() < 1.0 / 64.0, "{}", face(up));
            assert!((face(below) - 0.3).abs() < 0.3 / 64.0, "{}", face(below));
        }
        let plain = BevyVolume::from_field(&bins, &desc, TexelFormat::Rgb9e5).unwrap();
        assert!(plain.texel(p, below).x * plain.intensity() > 0.33);
    }

    #[test]
    fn transform_puts_points_at_voxel_centres() {
        let (desc, g) = grid(UVec3::new(4, 2, 3));
        let v = BevyVolume::from_field(&g, &desc, TexelFormat::Rgb9e5).unwrap();
        let t = v.transform();
        let (c, s) = (Vec3::from(t.translation), Vec3::from(t.scale));
        for i in 0..desc.point_count() {
            let p = desc.coords(i).unwrap();
            // Bevy: unit = (world - translation) / scale; texel = (unit + 1/2) * R.
            let unit = (desc.position(p) - c) / s;
            let texel = (unit + 0.5) * desc.dims().as_vec3();
            assert!((texel - (p.as_vec3() + 0.5)).abs().max_element() < 1e-4);
        }
    }

    #[test]
    fn intensity_keeps_texels_inside_the_formats() {
        // Any light an f32 holds, the faces of f32::MAX bins (beyond it) included.
        for max in [1e-38f64, 1e-6, 1e-3, 1.0, 3e4, 1e9, 2.6e35, 3.4e38, 4e39] {
            let k = intensity_for(max);
            assert!(k.is_finite() && k > 0.0, "{max}: {k}");
            let scaled = max / k as f64;
            assert!(
                (TARGET_MAX as f64 / 2.0..=TARGET_MAX as f64).contains(&scaled),
                "{max}: {scaled}"
            );
            assert_eq!(k.log2().fract(), 0.0);
        }
        assert_eq!(intensity_for(0.0), 1.0);
        assert_eq!(intensity_for(f64::NAN), 1.0);
    }

    #[test]
    fn light_at_either_end_of_f32_exports_with_its_digits() {
        for level in [1e-38f32, 1e-30, 1e30, 2.6e35, f32::MAX / 26.0, f32::MAX] {
            let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 2, 2)).unwrap();
            let mut b = BinLight::ZERO;
            b.0[lightgrid_core::dirs::DOWN] = Vec3::new(level, level * 0.5, level * 0.25);
            let g = LightGrid::new(desc, vec![b; 8]).unwrap();
            let v = BevyVolume::from_field(&g, &desc, TexelFormat::Rgb9e5).unwrap();
            assert!(v.intensity().is_finite() && v.intensity() > 0.0);
            // The +Y face (light from above) in the texel's units, back in f64.
            let want = b.ambient_cube_f64()[2] / std::f64::consts::PI;
            let got = v.texel(UVec3::ZERO, 2).as_dvec3() * v.intensity() as f64;
            let err = ((got - want).abs() / want.max_element()).max_element();
            assert!(err < 1.0 / 256.0, "{level}: {got} vs {want}");
        }
    }

    #[test]
    fn oversized_textures_and_bad_names_are_refused() {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 2, 700)).unwrap();
        let g = LightGrid::filled(desc, BinLight::ZERO).unwrap();
        let e = BevyVolume::from_field(&g, &desc, TexelFormat::Rgb9e5).unwrap_err();
        assert!(e.to_string().contains("texture depth = 2100"), "{e}");
        for bad in ["", "../x", "a/b", ".hidden", "a b"] {
            assert!(check_stem(bad).is_err(), "{bad:?}");
        }
        let (desc, g) = grid(UVec3::new(2, 2, 2));
        let v = BevyVolume::from_field(&g, &desc, TexelFormat::Rgb9e5).unwrap();
        let dir = std::env::temp_dir();
        let e = write_volumes(&dir, "x", &[v], Content::All, f32::NAN, None).unwrap_err();
        assert!(e.to_string().contains("unit_scale"), "{e}");
        // A unit scale whose product with the intensity leaves f32: refused, nothing
        // written (a dim grid's intensity is small, a bright one's large).
        let dir = dir.join(format!("lightgrid-unit-scale-{}", std::process::id()));
        for (level, scale) in [(1.0f32, 1e-45f32), (1e30, 1e20)] {
            let mut b = BinLight::ZERO;
            b.0[lightgrid_core::dirs::DOWN] = Vec3::splat(level);
            let g = LightGrid::filled(desc, b).unwrap();
            let v = BevyVolume::from_field(&g, &desc, TexelFormat::Rgb9e5).unwrap();
            let e = write_volumes(&dir, "x", &[v], Content::All, scale, None).unwrap_err();
            assert!(e.to_string().contains("unit_scale"), "{e}");
            assert!(!dir.exists());
        }
    }
}
