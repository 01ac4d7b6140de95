//! The single sweeps of the region the path sees: the full-resolution one (1 m, the
//! finest nodes' cell) every figure is measured against, and one at each coarser node
//! depth's own cell, which parts a coarse grid's error into what its cell size costs
//! (that sweep against the 1 m one) and what nesting costs (the hierarchy against it).

use anyhow::{Context, Result};
use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, LightField, LightGrid, MaterialSource, SunBoundary, SunResponse,
    Sweeper,
};
use lightgrid_render::sampling::SampledLight;
use lightgrid_terrain_lod::HierarchyParams;
use std::time::Instant;

use super::{FrameConfig, Parts, Probe, SUN_E, World, read};

/// A single sweep of the region at one cell size: sky bins, and per sun its scattered
/// bins and transmittance.
pub(super) struct Reference {
    pub(super) material: lightgrid_core::MaterialGrid,
    /// The sky's bins, and their horizon halves where the hierarchy's options keep them
    /// (then the sweep is read through them, as the hierarchy is).
    pub(super) sky: Option<(LightGrid, Option<lightgrid_core::HorizonGrid>)>,
    /// The sun's responses and its direction.
    pub(super) sun: Option<(SunResponse, Vec3)>,
}

impl Reference {
    /// The region's material at node depth `d`'s cell on its nodes' lattice, composed
    /// once for every sweep of it.
    pub(super) fn new(world: &World, desc: GridDesc) -> Result<Self> {
        let _span =
            tracing::info_span!("reference material", points = desc.point_count()).entered();
        Ok(Self {
            material: world.composer()?.material(&desc)?,
            sky: None,
            sun: None,
        })
    }

    /// The sweep options of the reference: the hierarchy's, with the bins.
    fn options(params: &HierarchyParams) -> lightgrid_core::SweepOptions {
        let mut o = params.sweep;
        o.outputs.bins = true;
        o
    }

    /// Sweeps the region's sky; returns the seconds it took.
    pub(super) fn sweep_sky(&mut self, params: &HierarchyParams, sky: BinLight) -> Result<f64> {
        let _span = tracing::info_span!("reference sky").entered();
        let t = Instant::now();
        let out = lightgrid_sweep_cpu::CpuSweeper::new().sweep(
            &self.material,
            &Boundary::open_sky(sky),
            &Self::options(params),
        )?;
        self.sky = Some((out.bins.context("bins asked for")?, out.horizon));
        Ok(t.elapsed().as_secs_f64())
    }

    /// The region's sun responses for `to_sun` (sunlight entering unshadowed).
    pub(super) fn sweep_sun(&mut self, params: &HierarchyParams, to_sun: Vec3) -> Result<()> {
        let _span = tracing::info_span!("reference sun").entered();
        let boundary = SunBoundary {
            to_sun,
            scattered: Boundary::open_sky(BinLight::ZERO),
            outside: &|_| 1.0,
        };
        let s = lightgrid_sweep_cpu::CpuSweeper::new().sweep_sun(
            &self.material,
            &boundary,
            &Self::options(params),
        )?;
        self.sun = Some((s, to_sun));
        Ok(())
    }

    /// Sky and sun luminance at every probe, read as the hierarchy is ([`read`]).
    /// The sun's response is for unit irradiance: its scattered light is scaled by the
    /// runs' [`SUN_E`] here, as the hierarchy's is by `set_sun` (its direct part by
    /// [`Parts::of`]).
    pub(super) fn sky_and_sun(&self, probes: &[Probe]) -> Result<Vec<Parts>> {
        let (response, to_sun) = self.sun.as_ref().context("reference sun")?;
        let sky = match self.sky.as_ref().context("reference sky")? {
            (bins, Some(halves)) => read(&Halves(bins, halves), probes)?,
            (bins, None) => read(bins, probes)?,
        };
        let sun = read(response, probes)?;
        Ok(probes
            .iter()
            .zip(sky.iter().zip(&sun))
            .map(|(p, (a, b))| {
                let b = SampledLight {
                    light: b.light * SUN_E,
                    ..*b
                };
                Parts::of(a, &b, p, *to_sun)
            })
            .collect())
    }
}

/// A grid read through its horizon halves, borrowed (`SplitLightGrid` would own them:
/// a copy of the region's grids).
struct Halves<'a>(&'a LightGrid, &'a lightgrid_core::HorizonGrid);

impl LightField for Halves<'_> {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, lightgrid_core::GridError> {
        self.0.light(p, n)
    }
    fn horizon(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<Option<lightgrid_core::HorizonLight>, lightgrid_core::GridError> {
        Ok(Some(match n {
            Some(n) => self.1.sample_biased(p, n)?,
            None => self.1.sample(p)?,
        }))
    }
}

/// What a ray toward the sun may still meet above the ground the region's probes lie
/// on, metres: the forest's tallest trees (8 m broadleaves scaled up to 1.3) and the
/// ground's rise beyond them.
const SHADE_HEIGHT: f32 = 16.0;

/// The region every frame's probes lie in, plus the margin, and toward the lowest sun
/// as far as its rays climb [`SHADE_HEIGHT`], at node depth `d`'s cell on its nodes'
/// lattice: their points and cells are the reference's.
pub(super) fn reference_desc(
    world: &World,
    cfg: &FrameConfig,
    params: &HierarchyParams,
    d: u32,
) -> Result<GridDesc> {
    // The coarser depths' sweeps reach the far probes too (`far.rs`).
    let reach = if d < params.depths() {
        super::far::REACH
    } else {
        super::NEAR_REACH
    };
    let (mut lo, mut hi) = (Vec2::splat(f32::MAX), Vec2::splat(f32::MIN));
    for f in 0..cfg.frames {
        let c = world.camera(cfg, f);
        lo = lo.min(Vec2::new(c.x, c.z) - reach - cfg.margin);
        hi = hi.max(Vec2::new(c.x, c.z) + reach + cfg.margin);
    }
    // Toward the lowest sun, as far as its rays climb [`SHADE_HEIGHT`] (beyond the
    // region nothing shades them: a 10° sun's rise 7 m in 40 m, under the trees' tops).
    if let Some(e) = cfg.elevations.iter().copied().reduce(f32::min) {
        let s = super::sun_dir(e);
        let across = Vec2::new(s.x, s.z);
        let reach = SHADE_HEIGHT * across.length() / s.y.max(1e-3);
        let extra = across.normalize_or_zero() * reach.min(1000.0);
        lo = lo.min(lo + extra);
        hi = hi.max(hi + extra);
    }
    let (mut g_lo, mut g_hi) = (f32::MAX, f32::MIN);
    let mut x = lo.x;
    while x <= hi.x {
        let mut z = lo.y;
        while z <= hi.y {
            let g = world.hm.height_at(x, z);
            (g_lo, g_hi) = (g_lo.min(g), g_hi.max(g));
            z += 2.0;
        }
        x += 2.0;
    }
    let h = params.cell(d);
    let datum = params.lattice(&world.hm, d);
    let snap = |v: f32, d: f32| d + ((v - d) / h).floor() * h;
    let lo = Vec2::new(snap(lo.x, datum.x), snap(lo.y, datum.z));
    let bottom = snap(g_lo - 2.0 * h, datum.y);
    let top = g_hi + params.margin;
    let dims = UVec3::new(
        ((hi.x - lo.x) / h).ceil() as u32 + 1,
        ((top - bottom) / h).ceil() as u32 + 1,
        ((hi.y - lo.y) / h).ceil() as u32 + 1,
    );
    Ok(GridDesc::new(Vec3::new(lo.x, bottom, lo.y), h, dims)?)
}
