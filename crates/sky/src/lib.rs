//! # sky
//!
//! Skies and the sun as boundary light for lightgrid's sweeps: a uniform sky, an
//! analytic clear sky, an equirectangular HDR environment map (EXR), and a sun disc,
//! each integrated over the 26 bins' solid angles; [`SkySpec`], a sky as a scene file or
//! a command line names it, resolved once (an EXR read once, not on every sun move),
//! which the viewer and the `lightgrid` command share.
//!
//! Sky and sun are kept apart so that their colours and intensities can change by a
//! multiply, without a new sweep (`lightgrid_sweep_cpu::Responses`).
//!
//! ```
//! use lightgrid_core::glam::Vec3;
//! use lightgrid_sky::{Sun, uniform_sky};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // A uniform sky of radiance 1 above the horizon, nothing below: it lights an upward
//! // surface, and a downward one only through the bins that straddle the horizon.
//! let sky = uniform_sky(Vec3::ONE)?;
//! assert!(sky.top.irradiance(Vec3::Y).x > 10.0 * sky.top.irradiance(-Vec3::Y).x);
//! // A sun 40° up (angles in radians) of illuminance 1 normal to the beam, in the bins.
//! let sun = Sun::at(40f32.to_radians(), 2.0, Vec3::ONE).bins()?;
//! assert!(sun.is_valid() && sun.total().x > 0.0);
//! # Ok(())
//! # }
//! ```
//!
//! **Environment maps** are equirectangular: texel `(x, y)` of a `w × h` map covers the
//! directions (towards where the light comes from) with azimuth
//! `φ = 2π (x + 1/2)/w - π` measured from `-Z` towards `+X` and polar angle
//! `θ = π (y + 1/2)/h` from `+Y` (row 0 is the zenith). Each texel's radiance is constant
//! over its exact solid angle `(2π/w)(cos θ_top - cos θ_bottom)`; a texel's light goes to
//! the bin of its centre direction. With `h` even the horizon falls on a texel border, so
//! light from above (the top boundary) and from below (the bottom boundary) split
//! exactly.

use std::f32::consts::{PI, TAU};
use std::path::{Path, PathBuf};

use lightgrid_core::dirs;
use lightgrid_core::glam::Vec3;
use lightgrid_core::{BinLight, GridError};

use lightgrid_core::MAX_LIGHT;

mod daylight;
pub use daylight::{
    DEFAULT_TURBIDITY, Daylight, TURBIDITY_RANGE, ies_sky_illuminance, ies_sun_illuminance,
};

/// Errors of sky construction and loading.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SkyError {
    /// A parameter is out of range (the error names it).
    #[error(transparent)]
    Invalid(#[from] GridError),
    /// An EXR file could not be read.
    #[error("{path}: cannot read EXR: {message}")]
    Exr {
        /// The file.
        path: PathBuf,
        /// What the EXR reader said.
        message: String,
    },
}

/// Light from the sky, as it enters a grid: through the top (travelling downward) and
/// through the bottom (travelling upward, e.g. a lower hemisphere of an environment map).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkyBins {
    /// Light entering through the top: downward bins and downward halves of horizontal
    /// bins.
    pub top: BinLight,
    /// Light entering through the bottom.
    pub bottom: BinLight,
}

/// Most texels of one environment map (2^28: 3 GiB as RGB `f32`).
pub const MAX_TEXELS: u64 = 1 << 28;

/// Largest EXR file [`EnvMap::load_exr`] reads: 2 GiB.
pub const MAX_EXR_BYTES: u64 = 2 << 30;

/// `width × height` if it is at most [`MAX_TEXELS`].
fn check_texels(width: u32, height: u32) -> Result<u64, GridError> {
    lightgrid_core::limits::checked_count("width x height", width, height, MAX_TEXELS)
}

/// An equirectangular radiance map (see the module docs for the mapping).
#[derive(Debug, Clone, PartialEq)]
pub struct EnvMap {
    width: u32,
    height: u32,
    texels: Vec<Vec3>,
}

impl EnvMap {
    /// A map from texels in row-major order (row 0 = zenith). Texels must be finite and
    /// not negative; `width >= 1`, `height >= 2` and even.
    pub fn new(width: u32, height: u32, texels: Vec<Vec3>) -> Result<Self, SkyError> {
        if width == 0 {
            return Err(GridError::invalid("width", width, "must be at least 1").into());
        }
        if height < 2 || !height.is_multiple_of(2) {
            return Err(GridError::invalid("height", height, "must be even and at least 2").into());
        }
        let count = check_texels(width, height)?;
        if texels.len() as u64 != count {
            return Err(GridError::LengthMismatch {
                field: "texels",
                expected: count as usize,
                found: texels.len(),
            }
            .into());
        }
        if let Some(i) = texels.iter().position(|t| {
            !(t.is_finite() && t.cmpge(Vec3::ZERO).all() && t.max_element() <= MAX_LIGHT)
        }) {
            return Err(GridError::invalid(
                format!("texels[{i}]"),
                texels[i],
                "radiance must be finite, >= 0 and <= 1e30",
            )
            .into());
        }
        Ok(Self {
            width,
            height,
            texels,
        })
    }

    /// A map filled by `radiance(direction towards the light)` at texel centres.
    pub fn from_fn(
        width: u32,
        height: u32,
        radiance: impl Fn(Vec3) -> Vec3,
    ) -> Result<Self, SkyError> {
        check_texels(width, height)?;
        let mut texels = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                texels.push(radiance(texel_direction(x, y, width, height)));
            }
        }
        Self::new(width, height, texels)
    }

    /// Loads the first RGB(A) layer of an EXR file. Pixels with NaN, infinity, negative
    /// values or values over 1e30 are an error naming the pixel.
    ///
    /// The file is read only if it is a regular file of at most [`MAX_EXR_BYTES`]; its
    /// headers are read first and every layer must have at most [`MAX_TEXELS`] texels
    /// within the memory limit ([`lightgrid_core::limits`]) before any pixel is allocated.
    pub fn load_exr(path: impl AsRef<Path>) -> Result<Self, SkyError> {
        let path = path.as_ref();
        let bytes = lightgrid_core::limits::read_file(path, MAX_EXR_BYTES)?;
        Self::from_exr_bytes(&bytes).map_err(|e| match e {
            SkyError::Exr { message, .. } => SkyError::Exr {
                path: path.to_path_buf(),
                message,
            },
            other => other,
        })
    }

    /// [`EnvMap::load_exr`] from bytes in memory (errors carry an empty path).
    pub fn from_exr_bytes(bytes: &[u8]) -> Result<Self, SkyError> {
        use exr::prelude::{ReadChannels, ReadLayers};
        let fail = |message: String| SkyError::Exr {
            path: PathBuf::new(),
            message,
        };
        // The exr crate sizes buffers from header values: check them before it does, and
        // turn any panic of its parser into an error.
        let guarded = |f: &dyn Fn() -> Result<Self, SkyError>| {
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
                .unwrap_or_else(|_| Err(fail("malformed EXR (the EXR reader failed on it)".into())))
        };
        guarded(&|| {
            let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
                .map_err(|e| fail(e.to_string()))?;
            for (i, h) in meta.headers.iter().enumerate() {
                let (w, hgt) = (h.layer_size.width() as u64, h.layer_size.height() as u64);
                let texels = w.saturating_mul(hgt);
                if texels > MAX_TEXELS {
                    return Err(GridError::invalid(
                        format!("layer {i} size"),
                        (w, hgt),
                        "more than 2^28 texels in one environment map",
                    )
                    .into());
                }
                // Every EXR compression ends in deflate, RLE or a fixed-rate code, none
                // of which packs more than about 1032 : 1, and a texel takes at least 2
                // bytes: a header claiming more texels than 512 per file byte is a lie
                // that would make the reader allocate and fill gigabytes.
                // The reader allocates a whole tile per chunk: tiles obey the same rule.
                if let exr::meta::BlockDescription::Tiles(t) = h.blocks {
                    let area =
                        (t.tile_size.width() as u64).saturating_mul(t.tile_size.height() as u64);
                    if area > MAX_TEXELS || area > bytes.len() as u64 * 512 {
                        return Err(GridError::invalid(
                            format!("layer {i} tile size"),
                            (t.tile_size.width(), t.tile_size.height()),
                            "tiles larger than the file can hold",
                        )
                        .into());
                    }
                }
                // Each chunk takes at least an 8-byte offset and an 8-byte chunk header.
                if h.chunk_count as u64 > bytes.len() as u64 / 16 {
                    return Err(GridError::invalid(
                        format!("layer {i} chunk count"),
                        h.chunk_count,
                        "more chunks than the file can hold",
                    )
                    .into());
                }
                if texels > bytes.len() as u64 * 512 {
                    return Err(GridError::invalid(
                        format!("layer {i} size"),
                        (w, hgt),
                        "more texels than the file can hold (over 512 per byte)",
                    )
                    .into());
                }
                lightgrid_core::limits::check_memory(
                    &format!("EXR layer {i} of {w} x {hgt} texels"),
                    texels * 32,
                )?;
            }
            let image = exr::prelude::read()
                .no_deep_data()
                .largest_resolution_level()
                .rgba_channels(
                    |resolution, _| {
                        (
                            resolution.width(),
                            vec![Vec3::ZERO; resolution.width() * resolution.height()],
                        )
                    },
                    |(w, px): &mut (usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                        if let Some(t) = px.get_mut(pos.y() * *w + pos.x()) {
                            *t = Vec3::new(r, g, b);
                        }
                    },
                )
                .first_valid_layer()
                .all_attributes()
                .from_buffered(std::io::Cursor::new(bytes))
                .map_err(|e| fail(e.to_string()))?;
            let (w, texels) = image.layer_data.channel_data.pixels;
            let h = texels.len() / w.max(1);
            Self::new(w as u32, h as u32, texels).map_err(|e| fail(e.to_string()))
        })
    }

    /// Writes the map as an RGB EXR (f32), e.g. to inspect an analytic sky.
    pub fn save_exr(&self, path: impl AsRef<Path>) -> Result<(), SkyError> {
        let path = path.as_ref();
        let w = self.width as usize;
        exr::prelude::write_rgb_file(path, w, self.height as usize, |x, y| {
            let t = self.texels[y * w + x];
            (t.x, t.y, t.z)
        })
        .map_err(|e| SkyError::Exr {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Texels, row-major, row 0 at the zenith.
    pub fn texels(&self) -> &[Vec3] {
        &self.texels
    }

    /// Illuminance of the map's upper half on an upward-facing surface,
    /// `Σ Y(L) cos θ ω` over the texels (luminance units: lux for a map in cd/m²), each
    /// texel's cosine exact over its band (`∫ cos θ sin θ dθ dφ`).
    pub fn horizontal_illuminance(&self) -> f32 {
        let (w, h) = (self.width, self.height);
        let mut e = 0.0f64;
        for y in 0..h / 2 {
            let t0 = PI as f64 * y as f64 / h as f64;
            let t1 = PI as f64 * (y + 1) as f64 / h as f64;
            // ∫ cos θ sin θ dθ over the band, times the texel's share of 2π.
            let band = 0.5 * (t1.sin().powi(2) - t0.sin().powi(2));
            let k = std::f64::consts::TAU / w as f64 * band;
            for x in 0..w {
                e += lightgrid_core::light::luminance(self.texels[(y * w + x) as usize]) as f64 * k;
            }
        }
        e as f32
    }

    /// The map integrated over the bins: light travels opposite to the texel direction.
    pub fn bins(&self) -> SkyBins {
        let (w, h) = (self.width, self.height);
        let mut top = [lightgrid_core::glam::DVec3::ZERO; dirs::NUM_DIRS];
        let mut bottom = top;
        for y in 0..h {
            let t0 = PI as f64 * y as f64 / h as f64;
            let t1 = PI as f64 * (y + 1) as f64 / h as f64;
            let omega = std::f64::consts::TAU / w as f64 * (t0.cos() - t1.cos());
            let from_above = y < h / 2;
            for x in 0..w {
                let l = self.texels[(y * w + x) as usize];
                if l == Vec3::ZERO {
                    continue;
                }
                let bin = dirs::nearest_dir(-texel_direction(x, y, w, h));
                let target = if from_above { &mut top } else { &mut bottom };
                target[bin] += l.as_dvec3() * omega;
            }
        }
        SkyBins {
            top: BinLight(top.map(|v| v.as_vec3())),
            bottom: BinLight(bottom.map(|v| v.as_vec3())),
        }
    }
}

/// Direction towards the light of texel `(x, y)`'s centre.
fn texel_direction(x: u32, y: u32, w: u32, h: u32) -> Vec3 {
    let phi = TAU * (x as f32 + 0.5) / w as f32 - PI;
    let theta = PI * (y as f32 + 0.5) / h as f32;
    Vec3::new(
        theta.sin() * phi.sin(),
        theta.cos(),
        -theta.sin() * phi.cos(),
    )
}

/// A sky as a scene file or a command line names it, resolved once (an environment map
/// is read and integrated here, not again when the sun moves): its bins for any sun
/// direction ([`SkySpec::bins`]). The viewer and the `lightgrid` command both resolve
/// their skies through it.
#[derive(Debug, Clone, PartialEq)]
pub enum SkySpec {
    /// No sky light.
    None,
    /// Uniform radiance above the horizon ([`uniform_sky`]).
    Uniform(Vec3),
    /// The analytic clear sky around the sun ([`ClearSky::blue`]): its shape follows
    /// the sun.
    Clear,
    /// An environment map's bins, integrated once.
    Map(Box<SkyBins>),
    /// A clear daylight sky in cd/m² of this turbidity ([`Daylight`]): its shape and
    /// level follow the sun.
    Daylight(f32),
}

impl SkySpec {
    /// An environment map read from an EXR file ([`EnvMap::load_exr`]) and integrated
    /// over the bins.
    pub fn exr(path: &Path) -> Result<Self, SkyError> {
        Ok(Self::Map(Box::new(EnvMap::load_exr(path)?.bins())))
    }

    /// The sky's bins with the sun toward `sun_direction` (only the clear sky reads it).
    pub fn bins(&self, sun_direction: Vec3) -> Result<SkyBins, SkyError> {
        match self {
            Self::None => Ok(SkyBins {
                top: BinLight::ZERO,
                bottom: BinLight::ZERO,
            }),
            Self::Uniform(radiance) => uniform_sky(*radiance),
            Self::Clear => ClearSky::blue(sun_direction).bins(),
            Self::Map(bins) => Ok(**bins),
            Self::Daylight(turbidity) => {
                let d = Daylight::new(*turbidity, sun_direction)?;
                if d.elevation() <= 0.0 {
                    return Self::None.bins(sun_direction);
                }
                d.bins()
            }
        }
    }

    /// Whether the sky's light changes when the sun moves (the clear sky's glow, the
    /// daylight sky).
    pub fn follows_sun(&self) -> bool {
        matches!(self, Self::Clear | Self::Daylight(_))
    }
}

/// A uniform sky of `radiance` above the horizon, nothing below.
pub fn uniform_sky(radiance: Vec3) -> Result<SkyBins, SkyError> {
    check_colour("radiance", radiance)?;
    let (top, _) = BinLight::uniform(radiance).split_vertical();
    Ok(SkyBins {
        top,
        bottom: BinLight::ZERO,
    })
}

/// A simple analytic clear sky: radiance blends from `horizon` to `zenith` with the
/// square root of the sine of the elevation, plus a circumsolar glow of
/// `glow · exp(-angle / 0.25 rad)` around `sun_direction`; nothing below the horizon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClearSky {
    /// Radiance straight up.
    pub zenith: Vec3,
    /// Radiance at the horizon.
    pub horizon: Vec3,
    /// Peak radiance of the glow around the sun (not the sun disc itself).
    pub glow: Vec3,
    /// Direction towards the sun (normalised internally).
    pub sun_direction: Vec3,
}

impl ClearSky {
    /// A blue sky with a warm glow, for a sun at `sun_direction`.
    pub fn blue(sun_direction: Vec3) -> Self {
        Self {
            zenith: Vec3::new(0.25, 0.45, 1.0),
            horizon: Vec3::new(0.7, 0.8, 1.0),
            glow: Vec3::new(1.0, 0.9, 0.7),
            sun_direction,
        }
    }

    /// Radiance arriving from direction `dir` (unit, towards the light).
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        if dir.y <= 0.0 {
            return Vec3::ZERO;
        }
        let base = self.horizon.lerp(self.zenith, dir.y.sqrt());
        let angle = dir
            .dot(self.sun_direction.normalize_or_zero())
            .clamp(-1.0, 1.0)
            .acos();
        base + self.glow * (-angle / 0.25).exp()
    }

    /// Rendered into a `width × height` map.
    pub fn env_map(&self, width: u32, height: u32) -> Result<EnvMap, SkyError> {
        check_colour("zenith", self.zenith)?;
        check_colour("horizon", self.horizon)?;
        check_colour("glow", self.glow)?;
        check_direction("sun_direction", self.sun_direction)?;
        EnvMap::from_fn(width, height, |d| self.radiance(d))
    }

    /// Integrated over the bins (through a 512 × 256 map).
    pub fn bins(&self) -> Result<SkyBins, SkyError> {
        Ok(self.env_map(512, 256)?.bins())
    }
}

/// The sun: a disc of uniform radiance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sun {
    /// Direction towards the sun (normalised internally).
    pub direction: Vec3,
    /// Angular radius, radians (the real sun: 0.00465).
    pub angular_radius: f32,
    /// Irradiance on a surface facing the sun (white light: 1 for a unit response).
    pub illuminance: Vec3,
}

impl Sun {
    /// A sun at `elevation` above the horizon and `azimuth` from `-Z` towards `+X`
    /// (radians), of the real sun's size.
    pub fn at(elevation: f32, azimuth: f32, illuminance: Vec3) -> Self {
        Self {
            direction: Vec3::new(
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
                -elevation.cos() * azimuth.cos(),
            ),
            angular_radius: 0.00465,
            illuminance,
        }
    }

    /// The disc split over the bins by the area of it each covers (4096 stratified
    /// samples): a sun near a bin border lights both bins. A sun below the horizon (its
    /// centre) gives no light; one straddling it gives only its upper part.
    ///
    /// Exact in flux: the sweep turns a bin's light into flux through a level with its
    /// downward channel's cosine (the bin's mean cosine), so each sample's share is
    /// scaled by its true cosine over that one. The beam brings `E sin(elevation)` to
    /// a horizontal plane at every elevation and azimuth (issue 44: at 25° it brought 9 %
    /// more), and a surface facing up reads that irradiance.
    pub fn bins(&self) -> Result<BinLight, SkyError> {
        check_direction("direction", self.direction)?;
        check_colour("illuminance", self.illuminance)?;
        if !(self.angular_radius.is_finite()
            && self.angular_radius > 0.0
            && self.angular_radius < 0.5)
        {
            return Err(GridError::invalid(
                "angular_radius",
                self.angular_radius,
                "must be in (0, 0.5) radians",
            )
            .into());
        }
        let c = self.direction.normalize();
        let t1 = c.any_orthonormal_vector();
        let t2 = c.cross(t1);
        let n = 64u32;
        let mut out = BinLight::ZERO;
        let share = self.illuminance / (n * n) as f32;
        // The sweep's downward channel cosines (`μ_c = 1 / ℓ_c`, its flux per unit light).
        let mut mu = [1.0f32; dirs::NUM_DIRS];
        for sd in dirs::sweep_dirs() {
            mu[sd.bin] = 1.0 / dirs::channel_length(sd.bin);
        }
        let tan_r = self.angular_radius.tan();
        for i in 0..n {
            for j in 0..n {
                // Concentric square-to-disc mapping of stratified samples (equal areas).
                let a = 2.0 * (i as f32 + 0.5) / n as f32 - 1.0;
                let b = 2.0 * (j as f32 + 0.5) / n as f32 - 1.0;
                let (r, phi) = if a.abs() > b.abs() {
                    (a, PI / 4.0 * (b / a))
                } else {
                    (b, PI / 2.0 - PI / 4.0 * (a / b))
                };
                let d = (c + (t1 * phi.cos() + t2 * phi.sin()) * (r * tan_r)).normalize();
                if d.y <= 0.0 {
                    continue; // below the horizon
                }
                let bin = dirs::nearest_dir(-d);
                out.0[bin] += share * (d.y / mu[bin]);
            }
        }
        Ok(out)
    }
}

fn check_colour(field: &str, c: Vec3) -> Result<(), SkyError> {
    if c.is_finite() && c.cmpge(Vec3::ZERO).all() && c.max_element() <= MAX_LIGHT {
        Ok(())
    } else {
        Err(GridError::invalid(field, c, "must be finite, >= 0 and <= 1e30").into())
    }
}

fn check_direction(field: &str, d: Vec3) -> Result<(), SkyError> {
    if d.is_finite() && d.length_squared() > 1e-12 {
        Ok(())
    } else {
        Err(GridError::invalid(field, d, "must be finite and non-zero").into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::dirs::{dir_index, dir_ivec};
    use lightgrid_core::glam::IVec3;

    #[test]
    fn uniform_env_map_matches_uniform_bins() {
        let l = Vec3::new(1.0, 2.0, 0.5);
        let map = EnvMap::from_fn(720, 360, |_| l).unwrap();
        let b = map.bins();
        let full = BinLight::uniform(l);
        for d in 0..dirs::NUM_DIRS {
            let got = b.top.0[d] + b.bottom.0[d];
            // Texels are assigned whole to a bin: error of order one texel row per bin edge.
            assert!(
                (got - full.0[d]).abs().max_element() < 0.01 * full.0[d].max_element(),
                "bin {d}"
            );
            match dir_ivec(d).y {
                -1 => assert_eq!(b.bottom.0[d], Vec3::ZERO),
                1 => assert_eq!(b.top.0[d], Vec3::ZERO),
                _ => assert!(
                    (b.top.0[d] - b.bottom.0[d]).abs().max_element() < 1e-4 * l.max_element()
                ),
            }
        }
    }

    /// The downward channels' cosines per bin (1 for bins without one).
    fn down_cosines() -> [f32; dirs::NUM_DIRS] {
        let mut mu = [1.0f32; dirs::NUM_DIRS];
        for sd in dirs::sweep_dirs() {
            mu[sd.bin] = 1.0 / dirs::channel_length(sd.bin);
        }
        mu
    }

    /// The flux `bins` bring through a level of the sweep.
    fn flux(b: &BinLight) -> Vec3 {
        let mu = down_cosines();
        (0..dirs::NUM_DIRS)
            .filter(|&d| dir_ivec(d).y <= 0)
            .map(|d| b.0[d] * mu[d])
            .sum()
    }

    /// Issue 44: a sun in the bins brings the beam's exact flux, `E sin(elevation)`, at
    /// every elevation from 2° to 90° and any azimuth (before: the bin's mean cosine
    /// instead of the beam's, +9 % at 25°, -5 % at the zenith), and a surface facing up
    /// reads that irradiance where the sun is in a bin above the horizontal ones (a
    /// horizontal bin is read as uniform across the horizon, half of it below: the
    /// horizon defect of issue 44).
    #[test]
    fn a_sun_in_the_bins_is_exact_in_flux() {
        for elevation in [
            2.0f32, 5.0, 10.0, 17.0, 22.5, 25.0, 33.0, 45.0, 60.0, 75.0, 90.0,
        ] {
            for azimuth in [0.0f32, 0.3, 1.1, 2.9, 4.0] {
                let e = Vec3::new(3.0, 2.0, 1.0);
                let b = Sun::at(elevation.to_radians(), azimuth, e).bins().unwrap();
                let want = e * elevation.to_radians().sin();
                let got = flux(&b);
                assert!(
                    ((got - want) / want).abs().max_element() < 1e-4,
                    "{elevation}° {azimuth}: flux {got} vs {want}"
                );
                let up = b.irradiance(Vec3::Y);
                assert!(
                    elevation < 25.0 || ((up - want) / want).abs().max_element() < 1e-4,
                    "{elevation}° {azimuth}: irradiance facing up {up} vs {want}"
                );
            }
        }
    }

    #[test]
    fn sun_straight_overhead_lands_in_one_bin_and_splits_at_a_border() {
        let e = Vec3::new(1000.0, 900.0, 800.0);
        let b = Sun {
            direction: Vec3::Y,
            angular_radius: 0.00465,
            illuminance: e,
        }
        .bins()
        .unwrap();
        // Its flux through a level (light times the channel's cosine) is `e`.
        let mu = down_cosines();
        assert!(
            ((b.0[dirs::DOWN] * mu[dirs::DOWN] - e) / e)
                .abs()
                .max_element()
                < 1e-4
        );
        assert!(((flux(&b) - e) / e).abs().max_element() < 1e-4);
        // On the border between the bins of (0,-1,0) and (1,-1,0) (travel), half the
        // flux each.
        let border = (Vec3::Y + Vec3::new(-1.0, 1.0, 0.0).normalize()).normalize();
        let b = Sun {
            direction: border,
            angular_radius: 0.02,
            illuminance: Vec3::ONE,
        }
        .bins()
        .unwrap();
        let diag = dir_index(IVec3::new(1, -1, 0)).unwrap();
        let half = 0.5 * border.y;
        let f_down = b.0[dirs::DOWN].x * mu[dirs::DOWN];
        assert!((f_down - half).abs() < 0.02 * half, "{f_down} vs {half}");
        assert!((b.0[diag].x * mu[diag] - half).abs() < 0.02 * half);
        // Below the horizon: dark.
        let b = Sun::at(-0.3, 0.0, Vec3::ONE).bins().unwrap();
        assert_eq!(b.total(), Vec3::ZERO);
    }

    #[test]
    fn a_sky_spec_gives_its_models_bins_and_only_the_clear_sky_follows_the_sun() {
        let (s1, s2) = (Vec3::new(0.3, 0.8, 0.1), Vec3::new(-0.5, 0.4, 0.2));
        let map = ClearSky::blue(s1).bins().unwrap();
        let none = SkySpec::None.bins(s1).unwrap();
        assert_eq!((none.top, none.bottom), (BinLight::ZERO, BinLight::ZERO));
        let r = Vec3::new(0.2, 0.3, 0.4);
        assert_eq!(
            SkySpec::Uniform(r).bins(s2).unwrap(),
            uniform_sky(r).unwrap()
        );
        assert_eq!(SkySpec::Clear.bins(s1).unwrap(), map);
        assert_ne!(SkySpec::Clear.bins(s2).unwrap(), map);
        // A map is the same whatever the sun.
        assert_eq!(SkySpec::Map(Box::new(map)).bins(s2).unwrap(), map);
        assert!(SkySpec::Clear.follows_sun());
        assert!(
            ![
                SkySpec::None,
                SkySpec::Uniform(r),
                SkySpec::Map(Box::new(map))
            ]
            .iter()
            .any(SkySpec::follows_sun)
        );
    }

    #[test]
    fn clear_sky_is_brighter_near_the_sun_and_dark_below() {
        let sun = Sun::at(0.5, 1.0, Vec3::ONE);
        let sky = ClearSky::blue(sun.direction).bins().unwrap();
        assert_eq!(sky.bottom.total(), Vec3::ZERO);
        let toward = dirs::nearest_dir(-sun.direction);
        let away = dirs::nearest_dir(-Vec3::new(
            -sun.direction.x,
            sun.direction.y,
            -sun.direction.z,
        ));
        let w = dirs::solid_angles();
        assert!(sky.top.0[toward].x / w[toward] > sky.top.0[away].x / w[away]);
    }

    #[test]
    fn exr_round_trip_and_errors() {
        let dir = std::env::temp_dir().join(format!("sweep-cpu-sky-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("sky.exr");
        let map = ClearSky::blue(Vec3::new(0.3, 0.8, 0.1))
            .env_map(64, 32)
            .unwrap();
        map.save_exr(&path).unwrap();
        let back = EnvMap::load_exr(&path).unwrap();
        assert_eq!(back, map);
        let e = EnvMap::load_exr(dir.join("missing.exr"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.exr"), "{e}");
        std::fs::write(dir.join("bad.exr"), b"not an exr").unwrap();
        assert!(EnvMap::load_exr(dir.join("bad.exr")).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(
            EnvMap::new(4, 3, vec![Vec3::ONE; 12])
                .unwrap_err()
                .to_string()
                .contains("height")
        );
        assert!(
            EnvMap::new(2, 2, vec![Vec3::ONE, Vec3::NAN, Vec3::ONE, Vec3::ONE])
                .unwrap_err()
                .to_string()
                .contains("texels[1]")
        );
        assert!(Sun::at(0.5, 0.0, Vec3::NAN).bins().is_err());
    }
}
