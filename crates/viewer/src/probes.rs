//! The scene's light probes (`[probes]` in the scene file): The Division's relightable
//! probes as a second light beside the sweep's. The probed region's terrain and
//! instances become one triangle model; probes are placed over it (columns, and along
//! walls), baked, relit for the scene's sky and sun, and merged into the renderer's
//! light volume box ([`lightgrid_light_probes::ProbeVolume`]). The direct sun is not in the
//! probes: its shadow comes from the sweep's transmittance (so `[probes]` needs
//! `sun.split`).

use std::time::Instant;

use anyhow::{Context, Result};
use lightgrid_core::glam::{Mat4, Vec2, Vec3};
use lightgrid_core::{BinLight, GridDesc, GridError, LightField};
use lightgrid_light_probes::{
    Lighting, ProbeLight, ProbeSet, ProbeVolume, ResolvedVolume, place, place_walls,
};
use lightgrid_material_voxelizer::model::{Model, SurfaceMaterial, Triangle};
use lightgrid_material_voxelizer::voxelize::RayScene;

use crate::world::World;

/// Most probe columns a scene's `[probes]` region may hold (a spacing far too fine for
/// the region is refused, naming the field, before anything is baked).
pub const MAX_PROBE_COLUMNS: usize = 1 << 18;

/// Probes of a world and their current light.
pub struct Probes {
    /// The probed region's triangles (terrain and instances), for ray queries.
    pub model: Model,
    /// The baked probes.
    pub set: ProbeSet,
    /// Their light (relit by [`Probes::relight`]).
    pub light: ProbeLight,
    /// Probes placed along walls (the rest are columns).
    pub wall_probes: usize,
    /// The weights merging them into the light volume.
    pub volume: ProbeVolume,
    /// Seconds: building the model, baking, the volume's weights.
    pub timings: [f64; 3],
    /// Milliseconds of the last relight: sun visibility, one frame (the mean).
    pub relight_ms: [f64; 2],
}

fn bvh() -> obvhs::BvhBuildParams {
    obvhs::BvhBuildParams::fast_build()
}

/// The region's terrain (two triangles a heightmap cell) and the instances that stand in
/// it, as one model.
fn region_model(world: &World, lo: Vec2, hi: Vec2) -> Model {
    let mut model = Model::default();
    let ground = match &world.ground {
        lightgrid_material_voxelizer::compose::GroundColour::Uniform(c) => *c,
        _ => Vec3::new(0.25, 0.22, 0.16),
    };
    model.materials.push(SurfaceMaterial {
        base_colour: ground.extend(1.0),
        ..Default::default()
    });
    let hm = &world.heightmap;
    let s = hm.spacing;
    let (i0, k0) = (
        ((lo.x - hm.origin.x) / s).floor().max(0.0) as u32,
        ((lo.y - hm.origin.y) / s).floor().max(0.0) as u32,
    );
    let (i1, k1) = (
        (((hi.x - hm.origin.x) / s).ceil() as u32).min(hm.width - 1),
        (((hi.y - hm.origin.y) / s).ceil() as u32).min(hm.depth - 1),
    );
    let at = |i: u32, k: u32| {
        let (x, z) = (hm.origin.x + i as f32 * s, hm.origin.y + k as f32 * s);
        Vec3::new(x, hm.height_at(x, z), z)
    };
    let tri = |positions: [Vec3; 3], material: u32, part: u32| Triangle {
        positions,
        uvs: [Vec2::ZERO; 3],
        material,
        part,
    };
    for k in k0..k1 {
        for i in i0..i1 {
            let (a, b, c, d) = (at(i, k), at(i + 1, k), at(i, k + 1), at(i + 1, k + 1));
            model.triangles.push(tri([a, c, b], 0, 0));
            model.triangles.push(tri([b, c, d], 0, 0));
        }
    }
    for inst in &world.instances {
        let p = Vec2::new(inst.position.x, inst.position.z);
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            continue;
        }
        model.append(
            &world.models[inst.model as usize].model,
            Mat4::from_scale_rotation_translation(
                Vec3::splat(inst.scale),
                inst.rotation,
                inst.position,
            ),
        );
    }
    model
}

impl Probes {
    /// Builds the region's model, places and bakes the probes, and works out the
    /// weights that merge them into `desc` (the renderer's light volume).
    pub fn build(world: &World, desc: GridDesc) -> Result<Self> {
        let spec = world
            .scene
            .probes
            .as_ref()
            .context("no [probes] in the scene")?;
        let params = spec.params();
        let t = Instant::now();
        let hm = &world.heightmap;
        let terrain_hi = hm.origin
            + Vec2::new(
                (hm.width - 1) as f32 * hm.spacing,
                (hm.depth - 1) as f32 * hm.spacing,
            );
        let (lo, hi) = match spec.region {
            Some(r) => (Vec2::new(r[0], r[1]), Vec2::new(r[2], r[3])),
            None if !world.instances.is_empty() => {
                let xz = |i: &lightgrid_material_voxelizer::compose::Instance| {
                    Vec2::new(i.position.x, i.position.z)
                };
                let (lo, hi) = world.instances.iter().fold(
                    (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
                    |(lo, hi), i| (lo.min(xz(i)), hi.max(xz(i))),
                );
                let pad = Vec2::splat(2.0 * params.spacing);
                (lo - pad, hi + pad)
            }
            None => (hm.origin, terrain_hi),
        };
        let (lo, hi) = (lo.max(hm.origin), hi.min(terrain_hi));
        // Columns of probes over the region: bounded before anything is allocated.
        let columns = ((hi - lo) / params.spacing).max(Vec2::ZERO) + Vec2::ONE;
        if columns.x as f64 * columns.y as f64 > MAX_PROBE_COLUMNS as f64 {
            anyhow::bail!(
                "probes.spacing = {}: {:.0} x {:.0} probe columns over the region, at most {MAX_PROBE_COLUMNS}",
                params.spacing,
                columns.x,
                columns.y
            );
        }
        let model = region_model(world, lo, hi);
        let (blo, bhi) = model
            .bounds()
            .context("the probes' region holds no terrain")?;
        let scene = RayScene::new(&model, bvh());
        let model_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let columns = place(&scene, blo, bhi, &params);
        let walls = place_walls(&scene, &columns, &params);
        let wall_probes = walls.len();
        let positions: Vec<Vec3> = columns.into_iter().chain(walls).collect();
        let set =
            ProbeSet::bake(&scene, &positions, &params, &|_, _| {}).context("baking the probes")?;
        let bake_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let volume = ProbeVolume::new(&scene, desc, &[&set], &|_, _| {})
            .context("merging the probes into the light volume")?;
        let volume_s = t.elapsed().as_secs_f64();
        drop(scene);
        let mut probes = Self {
            light: ProbeLight::new(&set),
            model,
            set,
            wall_probes,
            volume,
            timings: [model_s, bake_s, volume_s],
            relight_ms: [0.0; 2],
        };
        probes.relight(world, 8)?;
        Ok(probes)
    }

    /// Relights for the world's sky and sun: the surfels' sun visibility (shadow rays, or
    /// the sweep's transmittance with `probes.sun = "sweep"`), then `frames` frames (each
    /// adds a bounce).
    pub fn relight(&mut self, world: &World, frames: u32) -> Result<()> {
        let t = Instant::now();
        let scene = RayScene::new(&self.model, bvh());
        let to_sun = -world.sun.0;
        let lit = world.sun.1.max_element() > 0.0;
        let by_sweep = world
            .scene
            .probes
            .as_ref()
            .is_some_and(|p| p.sun == crate::scene::ProbeSun::Sweep);
        let vis = if !lit {
            vec![0.0; self.set.surfels().len()]
        } else if by_sweep {
            self.set
                .sun_visibility_from(&world.hierarchy, to_sun)
                .context("the surfels' sun from the sweep's transmittance")?
        } else {
            self.set.sun_visibility(&scene, to_sun)
        };
        let vis_ms = t.elapsed().as_secs_f64() * 1e3;
        let lighting = Lighting {
            sky: world.sky_top,
            sun: lit.then_some((to_sun, world.sun.1)),
        };
        let t = Instant::now();
        for _ in 0..frames {
            self.light.frame(&self.set, &lighting, &vis)?;
        }
        self.relight_ms = [
            vis_ms,
            t.elapsed().as_secs_f64() * 1e3 / frames.max(1) as f64,
        ];
        Ok(())
    }

    /// This frame's probe light on the volume.
    pub fn resolved(&self) -> Result<ResolvedVolume> {
        Ok(self.volume.resolve(&[&self.light])?)
    }

    /// One line for the summary.
    pub fn summary(&self) -> String {
        let n = self.set.probes().len();
        format!(
            "{n} ({} along walls), {} surfels, {} bricks, {:.1} KB a probe; model {:.2} s, bake {:.2} s, volume weights {:.2} s ({} of {} points see a probe); relight: sun visibility {:.1} ms, {:.2} ms a frame ({:.2} ms per 1000 probes)",
            self.wall_probes,
            self.set.surfels().len(),
            self.set.brick_count(),
            self.set.bytes() as f64 / n.max(1) as f64 / 1e3,
            self.timings[0],
            self.timings[1],
            self.timings[2],
            self.volume.covered(),
            self.volume.desc().point_count(),
            self.relight_ms[0],
            self.relight_ms[1],
            self.relight_ms[1] * 1000.0 / n.max(1) as f64,
        )
    }
}

/// The probes' light with the sweep's sun transmittance (the direct sun's shadow), as
/// one field for the renderer's samplers. Away from the probes (outside the probed
/// region, [`ResolvedVolume::coverage`] below 1) the sweep's light makes up the rest.
pub struct ProbeLit<'a> {
    /// The probes' light.
    pub probes: &'a ResolvedVolume,
    /// The sweep, for the sun's transmittance.
    pub sweep: &'a lightgrid_terrain_lod::Hierarchy,
}

impl LightField for ProbeLit<'_> {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        let c = self.probes.coverage(p)?;
        let mut l = self.probes.light(p, n)?;
        if c < 1.0 {
            l += self.sweep.light(p, n)?.scaled(1.0 - c);
        }
        Ok(l)
    }
    fn irradiance(&self, p: Vec3, n: Vec3) -> Result<Vec3, GridError> {
        let c = self.probes.coverage(p)?;
        let mut e = self.probes.irradiance(p, n)?;
        if c < 1.0 {
            e += self.sweep.irradiance(p, n)? * (1.0 - c);
        }
        Ok(e)
    }
    fn sun_transmittance(&self, p: Vec3, n: Option<Vec3>) -> Result<f32, GridError> {
        self.sweep.sun_transmittance(p, n)
    }
}
