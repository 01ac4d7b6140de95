//! A clear daylight sky in physical units, consistent with its sun (issue 46).
//!
//! - **Shape and colour**: Preetham, Shirley and Smits, "A Practical Analytic Model for
//!   Daylight" (1999): the Perez distribution
//!   `F(θ, γ) = (1 + A e^{B / cos θ})(1 + C e^{D γ} + E cos² γ)` of luminance and of the
//!   chromaticities `x`, `y`, each relative to the
//!   zenith, with coefficients linear in the turbidity `T` (2: very clear, 3: clear, 6:
//!   hazy), converted to linear sRGB (D65).
//! - **Level**: measured clear skies, not Preetham's zenith luminance (which puts 1.6 to
//!   2.2 times the measured diffuse light on the ground): the sky's luminance is scaled
//!   so that its illuminance on a horizontal surface is the IES clear-sky value
//!   `E_sky = 0.8 + 15.5 √(sin h)` klux at sun elevation `h`, and the sun's illuminance
//!   normal to its beam is the IES clear-sky value `E_sun = 127.5 e^{-0.21 / sin h}` klux
//!   (IES Lighting Handbook, daylight availability). Both from the same measurements, so
//!   sky and sun stay in proportion at every elevation (at 40°: 13.2 klux from the sky,
//!   59.2 klux from the sun on the ground).
//!
//! Units: radiance is luminance in cd/m² (RGB whose luminance `0.2126 R + 0.7152 G +
//! 0.0722 B` is the luminance), illuminance lux. Multiply both by one scale to move into
//! an engine's units (Bevy's `--unit-scale`; the sidecar names the sun's lux). With the
//! sun at or below the horizon the sky is dark (no twilight).

use std::f32::consts::FRAC_PI_2;

use lightgrid_core::glam::Vec3;

use crate::{EnvMap, SkyBins, SkyError, check_direction};

/// The default turbidity: a clear sky.
pub const DEFAULT_TURBIDITY: f32 = 3.0;

/// The turbidities Preetham's fit covers.
pub const TURBIDITY_RANGE: std::ops::RangeInclusive<f32> = 1.7..=10.0;

/// A clear daylight sky (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Daylight {
    /// Haze: 2 very clear, 3 clear, 6 hazy ([`TURBIDITY_RANGE`]).
    pub turbidity: f32,
    /// Direction toward the sun (normalised internally).
    pub sun_direction: Vec3,
}

/// Perez coefficients `A..E`.
type Perez = [f32; 5];

fn perez(p: &Perez, theta_cos: f32, gamma: f32) -> f32 {
    let [a, b, c, d, e] = *p;
    (1.0 + a * (b / theta_cos.max(1e-3)).exp())
        * (1.0 + c * (d * gamma).exp() + e * gamma.cos().powi(2))
}

/// IES clear-sky illuminance of the sky on a horizontal surface, lux.
pub fn ies_sky_illuminance(elevation: f32) -> f32 {
    if elevation <= 0.0 {
        return 0.0;
    }
    (0.8 + 15.5 * elevation.sin().sqrt()) * 1000.0
}

/// IES clear-sky illuminance of the sun normal to its beam, lux.
pub fn ies_sun_illuminance(elevation: f32) -> f32 {
    if elevation <= 0.0 {
        return 0.0;
    }
    127.5e3 * (-0.21 / elevation.sin()).exp()
}

impl Daylight {
    /// A sky of `turbidity` for a sun toward `sun_direction`; errors name a turbidity
    /// outside [`TURBIDITY_RANGE`] or a zero or non-finite direction.
    pub fn new(turbidity: f32, sun_direction: Vec3) -> Result<Self, SkyError> {
        if !TURBIDITY_RANGE.contains(&turbidity) {
            return Err(lightgrid_core::GridError::invalid(
                "turbidity",
                turbidity,
                "must be in 1.7..=10 (Preetham's fit)",
            )
            .into());
        }
        check_direction("sun_direction", sun_direction)?;
        Ok(Self {
            turbidity,
            sun_direction: sun_direction.normalize(),
        })
    }

    /// The sun's elevation, radians.
    pub fn elevation(&self) -> f32 {
        self.sun_direction
            .normalize_or_zero()
            .y
            .clamp(-1.0, 1.0)
            .asin()
    }

    /// The sun's illuminance normal to its beam, lux (white; [`ies_sun_illuminance`]).
    pub fn sun_illuminance(&self) -> f32 {
        ies_sun_illuminance(self.elevation())
    }

    /// Luminance `Y` and chromaticity `(x, y)` of the sky toward unit `dir`, relative
    /// to the zenith's luminance; `None` below the horizon.
    fn relative(&self, dir: Vec3) -> Option<(f32, f32, f32)> {
        if dir.y <= 0.0 {
            return None;
        }
        let t = self.turbidity;
        let s = self.sun_direction;
        let theta_s = (FRAC_PI_2 - self.elevation()).clamp(0.0, FRAC_PI_2);
        let gamma = dir.dot(s).clamp(-1.0, 1.0).acos();
        let py: Perez = [
            0.1787 * t - 1.4630,
            -0.3554 * t + 0.4275,
            -0.0227 * t + 5.3251,
            0.1206 * t - 2.5771,
            -0.0670 * t + 0.3703,
        ];
        let px: Perez = [
            -0.0193 * t - 0.2592,
            -0.0665 * t + 0.0008,
            -0.0004 * t + 0.2125,
            -0.0641 * t - 0.8989,
            -0.0033 * t + 0.0452,
        ];
        let pyc: Perez = [
            -0.0167 * t - 0.2608,
            -0.0950 * t + 0.0092,
            -0.0079 * t + 0.2102,
            -0.0441 * t - 1.6537,
            -0.0109 * t + 0.0529,
        ];
        let (th, th2, th3) = (theta_s, theta_s * theta_s, theta_s * theta_s * theta_s);
        let xz = t * t * (0.00166 * th3 - 0.00375 * th2 + 0.00209 * th)
            + t * (-0.02903 * th3 + 0.06377 * th2 - 0.03202 * th + 0.00394)
            + (0.11693 * th3 - 0.21196 * th2 + 0.06052 * th + 0.25886);
        let yz = t * t * (0.00275 * th3 - 0.00610 * th2 + 0.00317 * th)
            + t * (-0.04214 * th3 + 0.08970 * th2 - 0.04153 * th + 0.00516)
            + (0.15346 * th3 - 0.26756 * th2 + 0.06670 * th + 0.26688);
        let rel = |p: &Perez| perez(p, dir.y, gamma) / perez(p, 1.0, theta_s);
        Some((rel(&py), xz * rel(&px), yz * rel(&pyc)))
    }

    /// Radiance toward unit `dir` (towards the light) before the level is set: RGB of
    /// luminance `Y / Y_zenith`.
    fn shape(&self, dir: Vec3) -> Vec3 {
        let Some((y, cx, cy)) = self.relative(dir) else {
            return Vec3::ZERO;
        };
        if !(y.is_finite() && cy > 0.0) {
            return Vec3::ZERO;
        }
        let (x, z) = (cx * y / cy, (1.0 - cx - cy) * y / cy);
        let rgb = Vec3::new(
            3.2406 * x - 1.5372 * y - 0.4986 * z,
            -0.9689 * x + 1.8758 * y + 0.0415 * z,
            0.0557 * x - 0.2040 * y + 1.0570 * z,
        )
        .max(Vec3::ZERO);
        // Clipping negative channels changes the luminance a little: keep it `y`.
        let l = lightgrid_core::light::luminance(rgb);
        if l > 0.0 { rgb * (y / l) } else { Vec3::ZERO }
    }

    /// Rendered into a `width × height` map, in cd/m² (the level set so that the map's
    /// horizontal illuminance is [`ies_sky_illuminance`]).
    pub fn env_map(&self, width: u32, height: u32) -> Result<EnvMap, SkyError> {
        check_direction("sun_direction", self.sun_direction)?;
        let shape = EnvMap::from_fn(width, height, |d| self.shape(d))?;
        let horizontal = shape.horizontal_illuminance();
        let want = ies_sky_illuminance(self.elevation());
        let k = if horizontal > 0.0 && want > 0.0 {
            want / horizontal
        } else {
            0.0
        };
        EnvMap::from_fn(width, height, |d| self.shape(d) * k)
    }

    /// Integrated over the bins (through a 512 × 256 map).
    pub fn bins(&self) -> Result<SkyBins, SkyError> {
        Ok(self.env_map(512, 256)?.bins())
    }
}
