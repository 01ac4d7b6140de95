//! `--bevy`: the light around a view as Bevy irradiance volumes (see `lightgrid_export`).
//!
//! One volume for the world grid, then one per quadtree depth (coarse to fine, at most
//! [`MAX_NEAR_VOLUMES`], Bevy's per-view limit with the world one) covering the ready
//! nodes of that depth at its cell size. Each volume is sampled from the hierarchy,
//! which answers with the finest ready grid at every point, so a volume is never coarser
//! than the grids it covers. By default the light is indirect (Bevy's `DirectionalLight`
//! draws the direct sun): with the sun kept apart (`sun.split`, the default) that is the
//! hierarchy's bins as they are; with the sun in the bins, the hierarchy's light minus a
//! second hierarchy swept under the sun alone with no scattering, built only for the
//! export. With the direct sun asked for and kept apart, the sun's bins times the
//! transmittance are added back ([`WithDirectSun`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{DifferenceField, GridDesc, NoScatter};
use lightgrid_export::{BevyVolume, Content, TexelFormat, write_volumes};
use lightgrid_terrain_lod::Hierarchy;

use crate::world::World;

/// Near volumes after the world one: Bevy binds at most 8 light probes of a kind per
/// view.
pub const MAX_NEAR_VOLUMES: usize = 7;

/// The world box and one box per depth around the ready nodes, coarse to fine, finest
/// `MAX_NEAR_VOLUMES` kept.
fn volume_descs(h: &Hierarchy) -> Result<Vec<GridDesc>> {
    let mut descs = vec![*h.world().desc()];
    let mut near = Vec::new();
    for depth in 1..=h.params().depths() {
        let grids: Vec<&GridDesc> = h
            .ready_nodes()
            .into_iter()
            .filter(|k| k.depth == depth)
            .filter_map(|k| h.node(k).map(|g| g.desc()))
            .collect();
        if grids.is_empty() {
            continue;
        }
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for g in &grids {
            let (a, b) = g.point_bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        let cell = h.params().cell(depth);
        let dims = ((hi - lo) / cell).round().as_uvec3() + UVec3::ONE;
        near.push(GridDesc::new(lo, cell, dims).with_context(|| format!("depth {depth} volume"))?);
    }
    let skip = near.len().saturating_sub(MAX_NEAR_VOLUMES);
    descs.extend(near.into_iter().skip(skip));
    Ok(descs)
}

/// A field that keeps the direct sun apart, with the sun put back into its bins: the
/// sun's bins (its disc as the sweep reads it) times the field's transmittance, for
/// consumers that only read bins.
pub struct WithDirectSun<'a, F: ?Sized> {
    /// The field (its bins without the direct sun).
    pub field: &'a F,
    /// The sun's bins at full strength.
    pub sun_bins: lightgrid_core::BinLight,
}

impl<F: lightgrid_core::LightField + ?Sized> lightgrid_core::LightField for WithDirectSun<'_, F> {
    fn light(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<lightgrid_core::BinLight, lightgrid_core::GridError> {
        let t = self.field.sun_transmittance(p, n)?;
        Ok(self.field.light(p, n)? + self.sun_bins * t)
    }
}

/// One volume of `field` at `desc`, its points inside the scene's geometry filled from
/// their valid neighbours (`lightgrid_core::validity`, with the scene's material there).
fn volume(
    world: &World,
    field: &impl lightgrid_core::LightField,
    desc: &lightgrid_core::GridDesc,
    format: TexelFormat,
) -> Result<BevyVolume> {
    use lightgrid_core::MaterialSource;
    let material = world
        .composer
        .material(desc)
        .context("the scene's material for a volume")?;
    let valid = lightgrid_core::validity::valid_points(&material);
    Ok(BevyVolume::from_field_valid(field, desc, format, &valid)?)
}

/// Writes `<dir>/<name>.json` and a DDS and KTX2 file per volume for the camera at
/// `eye` (the world's hierarchy must be prepared for it). Returns the files written.
pub fn export(
    world: &World,
    eye: Vec3,
    dir: &Path,
    name: &str,
    with_direct_sun: bool,
) -> Result<Vec<PathBuf>> {
    let descs = volume_descs(&world.hierarchy)?;
    let format = TexelFormat::Rgb9e5;
    let split = world.hierarchy.sun().is_some();
    let (volumes, content) = if split && with_direct_sun {
        let (elevation, azimuth) = world.scene.sun.angles();
        let sun_bins = if elevation > 0.0 {
            lightgrid_sky::Sun::at(elevation, azimuth, world.sun.1).bins()?
        } else {
            lightgrid_core::BinLight::ZERO
        };
        let field = WithDirectSun {
            field: &world.hierarchy,
            sun_bins,
        };
        let v = descs
            .iter()
            .map(|d| volume(world, &field, d, format))
            .collect::<Result<Vec<_>>>()?;
        (v, Content::All)
    } else if split || with_direct_sun || world.sun.1 == Vec3::ZERO {
        let v = descs
            .iter()
            .map(|d| volume(world, &world.hierarchy, d, format))
            .collect::<Result<Vec<_>>>()?;
        (
            v,
            if with_direct_sun {
                Content::All
            } else {
                Content::Indirect
            },
        )
    } else {
        let mut direct = Hierarchy::new(
            &world.heightmap,
            Box::new(NoScatter(world.composer.clone())),
            Box::new(lightgrid_sweep_cpu::CpuSweeper::new()),
            crate::world::boundary_light(&lightgrid_core::BinLight::ZERO, &world.scene)?,
            *world.hierarchy.params(),
        )
        .context("building the direct-sun grids")?;
        direct
            .settle(eye, 400, |_| {})
            .context("sweeping the direct sun")?;
        let field = DifferenceField(&world.hierarchy, &direct);
        let v = descs
            .iter()
            .map(|d| volume(world, &field, d, format))
            .collect::<Result<Vec<_>>>()?;
        (v, Content::Indirect)
    };
    // (`world.sun` is the way sunlight travels; the sidecar names the way to the sun.)
    let sun = crate::world::sun_light(world.sun);
    let sun = Some((sun.to_sun, sun.irradiance));
    Ok(write_volumes(dir, name, &volumes, content, 1.0, sun)?)
}
