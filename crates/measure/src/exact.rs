//! Transport problems with exact answers that share none of the sweep's assumptions,
//! and the sweep's error on each: the yardstick of issue 13's rules work.
//!
//! - **White furnace**: every cell a white medium (albedo 1) inside uniform radiance 1.
//!   The exact light is radiance 1 from every direction at every point (average light
//!   1, irradiance π on any normal), whatever the medium.
//! - **Lambertian ground**: periodic sides, the bottom levels opaque ground of albedo
//!   `a`: exactly `a` of any incident light leaves through the top.
//! - **Half-space albedo** (Chandrasekhar): a thick slab of isotropic scatterers of
//!   single-scattering albedo `w` under a collimated beam at cosine `μ₀` reflects
//!   `1 − H(μ₀) √(1 − w)` of it, and under a uniform sky `1 − 2 √(1 − w) ∫₀¹ H(μ) μ dμ`,
//!   with Chandrasekhar's H-function ([`h_function`]).
//!
//! [`measure`] runs the sweep on each and reports its error; `cargo xtask bench` prints
//! the table. Every problem checks its parameters first: out of range (a grid past
//! [`MAX_SIDE`] points a side or [`MAX_LEVELS`] levels, a pass-through of 1 in a
//! half-space, an albedo outside `[0, 1]`, passes outside `1..=MAX_PASSES`) is a
//! [`SweepError::Invalid`] naming the parameter, never a panic.

use std::f64::consts::PI;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, GridError, Material, MaterialGrid, SideBoundary, SweepError,
    SweepOptions,
};
pub use lightgrid_sweep_cpu::quadrature::gauss_legendre_01;

/// Most points a side of [`furnace_material`]'s cube.
pub const MAX_SIDE: u32 = 128;
/// Most levels of a slab ([`half_space`], [`convergence`]).
pub const MAX_LEVELS: u32 = 1 << 16;

/// `value` within `lo..=hi`, or an error naming `field` and saying `reason`.
fn within<T: PartialOrd + std::fmt::Debug + Copy>(
    field: &'static str,
    value: T,
    (lo, hi): (T, T),
    reason: &'static str,
) -> Result<T, GridError> {
    if value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(GridError::invalid(field, value, reason))
    }
}

/// Chandrasekhar's H-function for isotropic scattering of albedo `w`, clamped to
/// `[0, 0.99999]` (the iteration does not converge at `w = 1`, where a half-space
/// reflects everything; a non-finite `w` counts as 0),
/// evaluated at the cosines `mu`: the fixed point of
/// `1 / H(μ) = √(1 − w) + (w / 2) ∫₀¹ μ' H(μ') / (μ + μ') dμ'`, iterated on 64
/// Gauss–Legendre nodes and extended to any `μ` through the same integral.
pub fn h_function(w: f64, mu: &[f64]) -> Vec<f64> {
    let w = albedo_in_range(w).min(0.99999);
    let q = gauss_legendre_01(64);
    let s = (1.0 - w).max(0.0).sqrt();
    // One application of the right-hand side at cosine `m`, from H on the nodes.
    let step = |h: &[f64], m: f64| {
        let integral: f64 = q
            .iter()
            .zip(h)
            .map(|(&(m2, wt), &h2)| wt * m2 * h2 / (m + m2))
            .sum();
        1.0 / (s + 0.5 * w * integral)
    };
    let mut h: Vec<f64> = vec![1.0; q.len()];
    for _ in 0..10_000 {
        let next: Vec<f64> = q.iter().map(|&(m, _)| step(&h, m)).collect();
        let change = next
            .iter()
            .zip(&h)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        h = next;
        if change < 1e-13 {
            break;
        }
    }
    mu.iter().map(|&m| step(&h, m)).collect()
}

/// An albedo clamped to `[0, 1]`; NaN and infinities count as 0 (no NaN out).
fn albedo_in_range(w: f64) -> f64 {
    if w.is_finite() {
        w.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Fraction of a collimated beam at cosine `mu0` that a half-space of isotropic
/// scatterers of albedo `w` reflects: `1 − H(μ₀) √(1 − w)`.
pub fn half_space_albedo_beam(w: f64, mu0: f64) -> f64 {
    let w = albedo_in_range(w);
    if w >= 1.0 {
        return 1.0;
    }
    1.0 - h_function(w, &[mu0])[0] * (1.0 - w).sqrt()
}

/// Fraction of uniform (isotropic) incident radiance that the half-space reflects:
/// `1 − 2 √(1 − w) ∫₀¹ H(μ) μ dμ`.
pub fn half_space_albedo_diffuse(w: f64) -> f64 {
    let w = albedo_in_range(w);
    if w >= 1.0 {
        return 1.0;
    }
    let q = gauss_legendre_01(64);
    let mu: Vec<f64> = q.iter().map(|p| p.0).collect();
    let h = h_function(w, &mu);
    let integral: f64 = q.iter().zip(&h).map(|(p, h)| p.1 * p.0 * h).sum();
    1.0 - 2.0 * (1.0 - w).sqrt() * integral
}

/// One measured exact-answer case.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    /// What was swept.
    pub name: String,
    /// The exact answer.
    pub exact: f64,
    /// The sweep's answer (for the furnace: its largest deviation, added to 1).
    pub swept: f64,
    /// `swept / exact − 1`.
    pub error: f64,
    /// Passes the sweep ran.
    pub passes: u32,
    /// Flux still pending when it stopped, as a fraction of the input.
    pub pending: f64,
    /// Wall time of the sweep, seconds.
    pub seconds: f64,
    /// The sweep's energy balance error ([`lightgrid_sweep_cpu::EnergyBalance::relative_error`]).
    pub balance: f64,
}

fn options(max_passes: u32, tolerance: f32) -> SweepOptions {
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = max_passes;
    o.tolerance = tolerance;
    o
}

fn case(
    name: String,
    exact: f64,
    swept: f64,
    s: &lightgrid_sweep_cpu::Sweep,
    seconds: f64,
) -> Case {
    Case {
        name,
        exact,
        swept,
        error: swept / exact - 1.0,
        passes: s.output.stats.passes,
        pending: s.balance.pending.x / s.balance.input().x.max(1e-300),
        seconds,
        balance: s.balance.relative_error(),
    }
}

/// A deterministic random material of white medium blobs (pass-through 0.02..1,
/// albedo 1) in empty space, `n³` cells.
pub fn furnace_material(n: u32, seed: u64) -> Result<MaterialGrid, SweepError> {
    let n = within("n", n, (1, MAX_SIDE), "must be within 1..=MAX_SIDE (128)")?;
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(n))?;
    let mut rng = fastrand::Rng::with_seed(seed);
    let blobs: Vec<(Vec3, f32, f32)> = (0..6)
        .map(|_| {
            (
                Vec3::new(rng.f32(), rng.f32(), rng.f32()) * n as f32,
                1.0 + rng.f32() * n as f32 * 0.25,
                0.02 + 0.9 * rng.f32(),
            )
        })
        .collect();
    let cells = (0..d.point_count())
        .map(|i| {
            let p = d.coords(i).expect("in range").as_vec3();
            let pass = blobs
                .iter()
                .filter(|b| p.distance(b.0) < b.1)
                .map(|b| b.2)
                .fold(1.0f32, f32::min);
            Material {
                reflectance: Vec3::ONE,
                pass,
            }
        })
        .collect();
    Ok(MaterialGrid::new(d, cells)?)
}

/// The white furnace on [`furnace_material`]: the largest deviation of the average
/// light from 1 and of the irradiance on the six axes from π, over all points.
pub fn furnace(n: u32, seed: u64, smoothing: f32) -> Result<(Case, Case), SweepError> {
    let mut o = options(400, 1e-6);
    o.smoothing = smoothing;
    furnace_with(n, seed, &o)
}

/// [`furnace`] with any sweep options (acceleration on, say).
pub fn furnace_with(n: u32, seed: u64, o: &SweepOptions) -> Result<(Case, Case), SweepError> {
    let smoothing = o.smoothing;
    let m = furnace_material(n, seed)?;
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::surrounding(&BinLight::uniform(Vec3::ONE))
    };
    let t = std::time::Instant::now();
    let s = lightgrid_sweep_cpu::run(&m, &b, o)?;
    let secs = t.elapsed().as_secs_f64();
    let g = s.output.bins.as_ref().ok_or_else(no_bins)?;
    let (mut avg, mut irr) = (0f64, 0f64);
    for l in g.data() {
        avg = avg.max((l.average().x as f64 - 1.0).abs());
        for n in lightgrid_core::light::AMBIENT_AXES {
            irr = irr.max((l.irradiance(n).x as f64 / PI - 1.0).abs());
        }
    }
    let name = |what: &str| format!("furnace {n}³, smoothing {smoothing}: {what}");
    Ok((
        case(name("average light"), 1.0, 1.0 + avg, &s, secs),
        case(name("irradiance"), 1.0, 1.0 + irr, &s, secs),
    ))
}

/// The error of options that asked for no bins (the problems read them).
fn no_bins() -> SweepError {
    GridError::invalid(
        "options.outputs.bins",
        false,
        "the exact problems read the bins",
    )
    .into()
}

/// `levels` levels of 4 × 4 cells of a uniform medium (albedo `w`, pass-through `pass`),
/// periodic sides, no boundary light, and a collimated beam of irradiance 1 travelling
/// straight down, given as its exact first collisions (a [`lightgrid_sweep_cpu::CellSource`]: level
/// `k` from the top takes `p^k (1 − p)`), as the sun enters a sweep. (A beam in the
/// vertical bin of the top boundary would be light spread over that bin, whose
/// half-space albedo is not Chandrasekhar's `μ₀ = 1` value.)
fn beam_slab(
    w: f32,
    pass: f32,
    levels: u32,
) -> Result<(MaterialGrid, Boundary, lightgrid_sweep_cpu::CellSource), SweepError> {
    let levels = within(
        "levels",
        levels,
        (2, MAX_LEVELS),
        "must be within 2..=MAX_LEVELS (65536)",
    )?;
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, levels, 4))?;
    let m = MaterialGrid::filled(
        d,
        Material {
            reflectance: Vec3::splat(w),
            pass,
        },
    )?;
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let removed = (0..d.point_count())
        .map(|i| {
            let k = levels - 1 - d.coords(i).expect("in range").y;
            Vec3::splat((pass as f64).powi(k as i32) as f32 * (1.0 - pass))
        })
        .collect();
    let src = lightgrid_sweep_cpu::CellSource::new(d, removed, Vec3::NEG_Y)?;
    Ok((m, b, src))
}

/// The white furnace in a uniform medium (every cell pass-through `pass`, albedo 1,
/// periodic): the largest deviation of any bin from its exact value (radiance 1 times
/// the bin's solid angle). It isolates the per-channel balance of removal and emission
/// from the geometry of heterogeneous media.
pub fn uniform_furnace(pass: f32) -> Result<Case, SweepError> {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(8))?;
    let m = MaterialGrid::filled(
        d,
        Material {
            reflectance: Vec3::ONE,
            pass,
        },
    )?;
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::surrounding(&BinLight::uniform(Vec3::ONE))
    };
    let t = std::time::Instant::now();
    // Thick white cells converge slowly (plain passes: pass-through 0.02 takes 524
    // passes to 1e-7 under the flat rule, 868 under the profile rule): run to
    // convergence, the test asserts it (`Case::pending`).
    let s = lightgrid_sweep_cpu::run(&m, &b, &options(lightgrid_core::MAX_PASSES, 1e-7))?;
    let secs = t.elapsed().as_secs_f64();
    let omega = lightgrid_core::dirs::solid_angles();
    let worst = s
        .output
        .bins
        .as_ref()
        .ok_or_else(no_bins)?
        .data()
        .iter()
        .flat_map(|l| (0..lightgrid_core::NUM_DIRS).map(move |b| (l.0[b].x / omega[b] - 1.0).abs()))
        .fold(0f32, f32::max);
    Ok(case(
        format!("furnace, uniform medium of pass-through {pass}: worst bin"),
        1.0,
        1.0 + worst as f64,
        &s,
        secs,
    ))
}

/// A slab of isotropic scatterers (albedo `w`, cells of pass-through `pass`) thick enough
/// to be a half-space (total optical depth `depth`), periodic sides, lit from above by
/// a zenith beam; compared with [`half_space_albedo_beam`] at `μ₀ = 1`.
pub fn half_space(w: f32, pass: f32, depth: f32, max_passes: u32) -> Result<Case, SweepError> {
    half_space_with(w, pass, depth, &options(max_passes, 1e-5))
}

/// [`half_space`] with any sweep options (the medium emission rule, say).
pub fn half_space_with(
    w: f32,
    pass: f32,
    depth: f32,
    options: &SweepOptions,
) -> Result<Case, SweepError> {
    if !(0.0..1.0).contains(&pass) {
        return Err(GridError::invalid(
            "pass",
            pass,
            "must be within [0, 1): a half-space needs a medium",
        )
        .into());
    }
    if !(depth.is_finite() && depth > 0.0) {
        return Err(GridError::invalid("depth", depth, "must be finite and > 0").into());
    }
    let tau = -(pass as f64).ln();
    let levels = (depth as f64 / tau)
        .ceil()
        .clamp(2.0, MAX_LEVELS as f64 + 1.0) as u32;
    let (m, b, src) = beam_slab(w, pass, levels)?;
    let t = std::time::Instant::now();
    let s = lightgrid_sweep_cpu::run_with_source(&m, &b, Some(&src), options)?;
    let secs = t.elapsed().as_secs_f64();
    // The beam's irradiance is 1 on every column: what leaves through the top per
    // column is the albedo.
    let swept = s.balance.top_out.x / m.desc().level_len() as f64;
    Ok(case(
        format!("half-space w {w}, cell optical depth {tau:.2}, {levels} levels"),
        half_space_albedo_beam(w as f64, 1.0),
        swept,
        &s,
        secs,
    ))
}

/// An 8³ grid of 1 m cells whose `levels` bottom levels are opaque ground of albedo
/// `albedo`, the rest empty (sweep it with periodic sides: an infinite ground).
pub fn ground_material(levels: u32, albedo: f32) -> Result<MaterialGrid, SweepError> {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(8))?;
    let mut cells = vec![Material::EMPTY; d.point_count()];
    for j in 0..levels.min(8) {
        for c in &mut cells[d.level_range(j)] {
            *c = Material::opaque(Vec3::splat(albedo));
        }
    }
    Ok(MaterialGrid::new(d, cells)?)
}

/// The light above an infinite Lambertian ground of albedo `a` under a uniform sky of
/// radiance 1 (`sky`: the sky's top boundary bins): `(exact, rule)`.
///
/// `exact` is the continuous field in bins: radiance 1 from above the horizon, `a` (the
/// Lambertian `a E / π` with `E = π`) from below, a horizontal bin half each; a bin holds
/// radiance times its solid angle. `rule` is what the sweep's rules must give: it turns
/// light into flux through a level with each channel's `μ_c = 1 / path length per
/// level` (where the continuous field has the bin's mean cosine), so the sky brings
/// `E_s = Σ_c sky_c μ_c` to the ground, the ground sends `a E_s / π ·
/// clipped_cosine(b, +Y)` (its exact Lambertian share) into the upward half of bin `b`,
/// and the channel turns that back into light dividing by `μ_c`.
pub fn ground_fields(albedo: f32, sky: &BinLight) -> Result<(BinLight, BinLight), SweepError> {
    within("albedo", albedo, (0.0, 1.0), "must be within [0, 1]")?;
    if !sky.is_valid() {
        return Err(GridError::invalid("sky", "a bin", "must be finite and >= 0").into());
    }
    let omega = lightgrid_core::dirs::solid_angles();
    let up = lightgrid_sweep_cpu::sweep::channels(true);
    let field = |ground_half: &dyn Fn(usize) -> f32| {
        BinLight(std::array::from_fn(|b| {
            let dy = lightgrid_core::dirs::dir_unit(b).y;
            let from_sky = if dy <= 0.0 { sky.0[b].x } else { 0.0 };
            Vec3::splat(from_sky + if dy >= 0.0 { ground_half(b) } else { 0.0 })
        }))
    };
    let exact = field(&|b| {
        let half = if lightgrid_core::dirs::dir_unit(b).y == 0.0 {
            0.5
        } else {
            1.0
        };
        albedo * omega[b] * half
    });
    let e_sweep: f32 = lightgrid_sweep_cpu::sweep::channels(false)
        .iter()
        .map(|c| sky.0[c.bin].x * c.mu)
        .sum();
    let rule = field(&|b| {
        // Every bin pointing up or sideways has an upward channel.
        let Some(chn) = up.iter().find(|c| c.bin == b) else {
            return 0.0;
        };
        let cc = lightgrid_core::dirs::clipped_cosine(b, lightgrid_core::glam::DVec3::Y) as f32;
        albedo * e_sweep / std::f32::consts::PI * cc / chn.mu
    });
    Ok((exact, rule))
}

/// One level of opaque ground of albedo `a` under a zenith beam, periodic sides: the
/// fraction reflected against `a`.
pub fn lambertian_ground(a: f32) -> Result<Case, SweepError> {
    let m = ground_material(1, a)?;
    let mut top = BinLight::ZERO;
    top.0[lightgrid_core::dirs::DOWN] = Vec3::ONE;
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(top)
    };
    let t = std::time::Instant::now();
    let s = lightgrid_sweep_cpu::run(&m, &b, &options(64, 1e-7))?;
    let secs = t.elapsed().as_secs_f64();
    let swept = s.balance.top_out.x / s.balance.top_in.x;
    Ok(case(
        format!("one-level Lambertian ground, albedo {a}"),
        a as f64,
        swept,
        &s,
        secs,
    ))
}

/// The horizon (issue 44): irradiance on a surface facing up (`up`) or down just above
/// `levels` levels of Lambertian ground of albedo `a` under a uniform sky of radiance 1,
/// periodic sides, against the exact `pi` and `a pi`; each horizontal bin read in its
/// two halves (`Outputs::horizon`, `BinLight::irradiance_split`), or as even across the
/// horizon (`BinLight::irradiance`) if not `halves`.
pub fn horizon(levels: u32, a: f32, up: bool, halves: bool) -> Result<Case, SweepError> {
    let m = ground_material(levels, a)?;
    let top = BinLight::uniform(Vec3::ONE).split_vertical().0;
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(top)
    };
    let mut o = options(64, 1e-7);
    o.outputs = o.outputs.with_horizon();
    let t = std::time::Instant::now();
    let s = lightgrid_sweep_cpu::run(&m, &b, &o)?;
    let secs = t.elapsed().as_secs_f64();
    let i = m.desc().level_len() * levels as usize;
    let (Some(g), Some(h)) = (&s.output.bins, &s.output.horizon) else {
        return Err(SweepError::Backend {
            backend: "cpu",
            message: "bins and horizon halves asked for, not returned".into(),
        });
    };
    let (bins, down) = (g.data()[i], h.data()[i]);
    let n = if up { Vec3::Y } else { Vec3::NEG_Y };
    let swept = if halves {
        bins.irradiance_split(n, &down)
    } else {
        bins.irradiance(n)
    };
    let exact = PI * if up { 1.0 } else { a as f64 };
    Ok(case(
        format!(
            "horizon: {levels}-level ground, albedo {a}, facing {}, {}",
            if up { "up" } else { "down" },
            if halves { "halves" } else { "bins read even" }
        ),
        exact,
        swept.x as f64,
        &s,
        secs,
    ))
}

/// A low sun's first scatterings gathered by rays (issue 44; `SweepOptions::gather`,
/// `Gather::LOW_SUN`): over `levels` levels of Lambertian ground of albedo `a` under a
/// sun at `elevation_deg` (unit irradiance facing it, periodic sides, no sky), a
/// surface facing down just above the ground receives the ground's exitance `a sin e`
/// exactly; read with the horizon halves (`BinLight::irradiance_split`).
pub fn gathered_ground(levels: u32, a: f32, elevation_deg: f32) -> Result<Case, SweepError> {
    use lightgrid_core::Sweeper;
    let m = ground_material(levels, a)?;
    let (e, az) = (elevation_deg.to_radians(), 20f32.to_radians());
    let to_sun = Vec3::new(e.cos() * az.cos(), e.sin(), e.cos() * az.sin());
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let mut o = options(64, 1e-7);
    o.outputs = o.outputs.with_horizon();
    o.gather = lightgrid_core::Gather::LOW_SUN;
    let t = std::time::Instant::now();
    let src = lightgrid_sweep_cpu::sun::first_collision(&m, to_sun, Vec3::ONE, true, &|_| 1.0)?;
    let mut cpu = lightgrid_sweep_cpu::CpuSweeper::new();
    let out = cpu.sweep_with_source(&m, &b, &src, &o)?;
    let secs = t.elapsed().as_secs_f64();
    let i = m.desc().level_len() * levels as usize;
    let (Some(g), Some(h)) = (&out.bins, &out.horizon) else {
        return Err(SweepError::Backend {
            backend: "cpu",
            message: "bins and horizon halves asked for, not returned".into(),
        });
    };
    let swept = g.data()[i].irradiance_split(Vec3::NEG_Y, &h.data()[i]).x as f64;
    let balance = cpu.last_balance().map_or(0.0, |b| b.relative_error());
    let exact = a as f64 * (e as f64).sin();
    Ok(Case {
        name: format!(
            "sun {elevation_deg}°, gathered: {levels}-level ground, albedo {a}, facing down"
        ),
        exact,
        swept,
        error: swept / exact - 1.0,
        passes: out.stats.passes,
        pending: 0.0,
        seconds: secs,
        balance,
    })
}

/// [`patchy_low_sun`]'s errors in full: the patchy canopy under a 10° sun (azimuth
/// 20°, periodic) against 8 M Monte Carlo paths, multi-bounce to tolerance 1e-6: swept
/// (`Gather::OFF`) or with the preset's gather (`SweepOptions::multi_bounce`'s
/// `Gather::AUTO`, which gathers a 10° sun as `Gather::LOW_SUN`).
pub fn patchy_low_sun_errors(
    gathered: bool,
) -> Result<crate::sun_measure::MediumErrors, Box<dyn std::error::Error>> {
    let m = crate::sun_measure::patchy_canopy(16, 3);
    // The preset's gather (`Gather::AUTO`: a 10° sun gathered), or none.
    let mut o = options(64, 1e-6);
    if !gathered {
        o.gather = lightgrid_core::Gather::OFF;
    }
    crate::sun_measure::medium_errors(
        &m,
        true,
        10f32.to_radians(),
        20f32.to_radians(),
        8_000_000,
        &o,
    )
}

/// A low sun over a patchy canopy, cell by cell (issue 44's 5 % a cell): the sweep's sun
/// light in the medium cells of [`crate::sun_measure::patchy_canopy`] (16 × 10 × 16,
/// periodic, 10°, azimuth 20°) against a Monte Carlo reference of 8 M paths, swept
/// (`Gather::OFF`) or at the preset's default (`Gather::AUTO`: its first two
/// scatterings gathered, as `Gather::LOW_SUN`): `exact` and `swept`
/// are the reference's and the sweep's light at the worst cell whose reference noise is
/// under 1 % (0.3–0.6 % at 8 M paths), `pending` the share of those cells over 5 % off,
/// `seconds` the whole measurement's (the reference's paths included: about a minute).
pub fn patchy_low_sun(gathered: bool) -> Result<Case, SweepError> {
    let t = std::time::Instant::now();
    let e = patchy_low_sun_errors(gathered).map_err(|e| SweepError::Backend {
        backend: "cpu",
        message: e.to_string(),
    })?;
    let [swept, exact] = e.worst;
    Ok(Case {
        name: format!(
            "sun 10°, patchy canopy, {}: worst of {} cells, {} over 5 %",
            if gathered {
                "gathered (the default)"
            } else {
                "swept (gather off)"
            },
            e.quiet,
            e.over_5
        ),
        exact,
        swept,
        error: swept / exact - 1.0,
        passes: 0,
        pending: e.over_5 as f64 / e.quiet.max(1) as f64,
        seconds: t.elapsed().as_secs_f64(),
        balance: 0.0,
    })
}

/// Every case: the furnace (smoothing 0 and the default; uniform media of pass-through
/// 0.9, 0.5, 0.1), one-level ground, the horizon over one and three ground levels, beam
/// conservation, a 10° sun's light gathered over one and three ground levels and over a
/// patchy canopy (swept and gathered, cell by cell against Monte Carlo), and the
/// half-space for `w` in {0.1, 0.5, 0.9, 0.99} and cell optical depths 0.05, 0.69, 3
/// (total depth 40), at most `max_passes` passes each, under the default rule and again
/// under the flat source (`MediumEmission::Source`).
pub fn measure(max_passes: u32) -> Result<Vec<Case>, SweepError> {
    within(
        "max_passes",
        max_passes,
        (1, lightgrid_core::MAX_PASSES),
        "must be within 1..=MAX_PASSES (4096)",
    )?;
    let mut out = Vec::new();
    for smoothing in [0.0, SweepOptions::multi_bounce().smoothing] {
        let (a, i) = furnace(12, 7, smoothing)?;
        out.push(a);
        out.push(i);
    }
    for pass in [0.9, 0.5, 0.1] {
        out.push(uniform_furnace(pass)?);
    }
    out.push(lambertian_ground(0.3)?);
    for levels in [1, 3] {
        for up in [true, false] {
            for halves in [false, true] {
                out.push(horizon(levels, 0.3, up, halves)?);
            }
        }
    }
    for elevation in [2.0, 10.0, 25.0, 60.0, 90.0] {
        out.push(beam_conservation(elevation)?);
    }
    for levels in [1, 3] {
        out.push(gathered_ground(levels, 0.3, 10.0)?);
    }
    for gathered in [false, true] {
        out.push(patchy_low_sun(gathered)?);
    }
    for w in [0.1, 0.5, 0.9, 0.99] {
        for pass in [0.95f32, 0.5, 0.05] {
            out.push(half_space(w, pass, 40.0, max_passes)?);
        }
    }
    // The option of a flat source (`lightgrid_sweep_cpu::medium`).
    let mut o = options(max_passes, 1e-5);
    o.medium = lightgrid_core::MediumEmission::Source;
    for w in [0.1, 0.5, 0.9, 0.99] {
        for pass in [0.95f32, 0.5, 0.05] {
            let mut c = half_space_with(w, pass, 40.0, &o)?;
            c.name += ", flat source";
            out.push(c);
        }
    }
    Ok(out)
}

/// Beam conservation (issue 44): the sun's first collisions
/// (`lightgrid_sweep_cpu::beam`) plus the beam leaving through the bottom and the open
/// sides, against the exact flux entering through the faces facing the sun,
/// `E (s_y nx nz + |s_x| ny nz + |s_z| nx ny)` (unit irradiance, open sky), on the
/// patchy canopy ([`crate::sun_measure::patchy_canopy`]) with open sides, azimuth 20°.
/// `passes` is 0 (no sweep); `pending` is the fraction of the beam deposited.
pub fn beam_conservation(elevation_deg: f32) -> Result<Case, SweepError> {
    let m = crate::sun_measure::patchy_canopy(16, 3);
    let (e, a) = (elevation_deg.to_radians(), 20f32.to_radians());
    let s = lightgrid_core::glam::Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin());
    let open = |_: lightgrid_core::glam::Vec3| 1.0;
    let t = std::time::Instant::now();
    let f = lightgrid_sweep_cpu::sun::first_collisions(
        &m,
        s,
        lightgrid_core::glam::Vec3::ONE,
        false,
        &open,
        &lightgrid_sweep_cpu::sun::BeamOptions::DEFAULT,
    )?;
    let seconds = t.elapsed().as_secs_f64();
    let d = m.desc().dims().as_dvec3();
    let sd = s.normalize().as_dvec3();
    let exact = sd.y * d.x * d.z + sd.x.abs() * d.y * d.z + sd.z.abs() * d.x * d.y;
    let b = f.budget;
    let swept = b.collided + b.left_bottom + b.left_sides + b.stopped;
    Ok(Case {
        name: format!("beam conservation, patchy canopy, open sides, sun {elevation_deg}°"),
        exact,
        swept,
        error: swept / exact - 1.0,
        passes: 0,
        pending: b.collided / exact,
        seconds,
        balance: b.relative_error(),
    })
}

/// Passes to tolerance 1e-4 (at most `max_passes`) of a slab of total optical depth
/// `depth` (cells of optical depth 1) and albedo `w` under a zenith beam: the source
/// iteration slows down as the slab thickens and `w` nears 1 (issue 13 item 4). The
/// case's `exact` is the half-space albedo (the slab's own is lower when it is thin).
pub fn convergence(depth: u32, w: f32, max_passes: u32) -> Result<Case, SweepError> {
    convergence_with(depth, w, &options(max_passes, 1e-4))
}

/// [`convergence`] with any sweep options (acceleration on, say).
pub fn convergence_with(depth: u32, w: f32, options: &SweepOptions) -> Result<Case, SweepError> {
    let (m, b, src) = beam_slab(w, (-1.0f32).exp(), depth.max(2))?;
    let t = std::time::Instant::now();
    let s = lightgrid_sweep_cpu::run_with_source(&m, &b, Some(&src), options)?;
    let secs = t.elapsed().as_secs_f64();
    Ok(case(
        format!("slab of optical depth {depth}, w {w}: passes to 1e-4"),
        half_space_albedo_beam(w as f64, 1.0),
        s.balance.top_out.x / m.desc().level_len() as f64,
        &s,
        secs,
    ))
}

/// One line per case: name, exact, swept, error, passes, pending, milliseconds.
pub fn table(cases: &[Case]) -> String {
    use std::fmt::Write;
    let mut s = format!(
        "{:80} {:>8} {:>8} {:>8} {:>6} {:>9} {:>9}\n",
        "case", "exact", "sweep", "error", "passes", "pending", "ms"
    );
    for c in cases {
        let _ = writeln!(
            s,
            "{:80} {:>8.4} {:>8.4} {:>+7.1}% {:>6} {:>9.1e} {:>9.1}",
            c.name,
            c.exact,
            c.swept,
            100.0 * c.error,
            c.passes,
            c.pending,
            c.seconds * 1e3
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn h_function_matches_known_values() {
        for w in [0.1, 0.5, 0.9, 0.99] {
            let h = h_function(w, &[0.0, 1.0]);
            assert!((h[0] - 1.0).abs() < 1e-9, "w {w}: H(0) = {}", h[0]);
            assert!(h[1] > 1.0, "w {w}: H(1) = {}", h[1]);
        }
        // The zeroth moment identity: ∫₀¹ H(μ) dμ = 2 (1 − √(1 − w)) / w.
        for w in [0.1, 0.5, 0.9, 0.99] {
            let q = gauss_legendre_01(64);
            let mu: Vec<f64> = q.iter().map(|p| p.0).collect();
            let h = h_function(w, &mu);
            let m0: f64 = q.iter().zip(&h).map(|(p, h)| p.1 * h).sum();
            let exact = 2.0 * (1.0 - (1.0 - w).sqrt()) / w;
            assert!((m0 - exact).abs() < 1e-6, "w {w}: {m0} vs {exact}");
        }
        // The figures: 0.1152 (w = 0.5) and 0.4150 (w = 0.9) at normal incidence.
        assert!((half_space_albedo_beam(0.5, 1.0) - 0.1152).abs() < 1e-4);
        assert!((half_space_albedo_beam(0.9, 1.0) - 0.4150).abs() < 1e-4);
        // Nearly white half-spaces reflect nearly everything, monotonically in w.
        let r: Vec<f64> = [0.1, 0.5, 0.9, 0.99]
            .map(half_space_albedo_diffuse)
            .to_vec();
        assert!(
            r.windows(2).all(|p| p[0] < p[1]) && r[3] < 1.0 && r[3] > 0.7,
            "{r:?}"
        );
    }

    #[test]
    fn the_ground_case_is_exact_and_the_furnace_conserves_energy() {
        let g = lambertian_ground(0.3).unwrap();
        assert!(g.error.abs() < 1e-3, "{g:?}");
        let (a, _) = furnace(6, 3, 0.0).unwrap();
        assert!(a.pending < 1e-3, "{a:?}");
    }
}
