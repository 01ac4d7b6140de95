//! Turns a [`World`] into renderer meshes and draws its views: the lit scene, the same
//! without the grids, the grid points as lit balls, the material cells as cubes.

use anyhow::{Context, Result};
use lightgrid_core::glam::{Mat4, UVec3, Vec2, Vec3, Vec4};
use lightgrid_core::{GridDesc, LightField, LightGrid, MaterialSource};
use lightgrid_material_voxelizer::model::{AlphaMode, Model};
use lightgrid_render::impostor::{Impostor, ImpostorParams, Part};
use lightgrid_render::shading::linear_to_srgb8;
use lightgrid_render::{
    Camera, GpuHorizon, GpuLightGrid, GpuLightSampler, GpuPoints, GpuSampleLayer, GroundLight,
    LayerOwner, LightVolume, Lighting, LightingMode, MeshId, MeshInstance, MeshMaterial, Renderer,
    SamplePoints, TextureRgba8, Vertex, View, sample_points,
};
use lightgrid_render::{GpuLayerSun, LayerLight, transmittance_buffer};

use lightgrid_material_voxelizer::compose::{GroundColour, Heightmap, Instance};

use crate::world::{ModelEntry, World};

/// The terrain mesh: the heightmap's nodes (every `stride`-th), normals from central
/// differences.
pub struct TerrainMesh {
    /// Vertex positions (world).
    pub positions: Vec<Vec3>,
    /// Unit normals.
    pub normals: Vec<Vec3>,
    /// Triangle indices.
    pub indices: Vec<u32>,
    /// Vertices along x and z.
    pub size: (u32, u32),
    /// World (x, z) of vertex (0, 0) and the spacing.
    pub origin: Vec2,
    /// Metres between vertices.
    pub spacing: f32,
}

impl TerrainMesh {
    /// The renderer's ground light from the light at each vertex.
    pub fn ground_light(&self, light: &[Vec3]) -> GroundLight {
        GroundLight {
            origin: self.origin,
            spacing: self.spacing,
            width: self.size.0,
            depth: self.size.1,
            nodes: self
                .positions
                .iter()
                .zip(light)
                .map(|(p, e)| e.extend(p.y).to_array())
                .collect(),
        }
    }

    /// At most `max_side` vertices a side.
    pub fn new(world: &World, max_side: u32) -> Self {
        Self::of(&world.heightmap, max_side)
    }

    /// [`TerrainMesh::new`] of a heightmap.
    pub fn of(hm: &Heightmap, max_side: u32) -> Self {
        let stride = hm.width.max(hm.depth).div_ceil(max_side).max(1);
        let (nx, nz) = ((hm.width - 1) / stride + 1, (hm.depth - 1) / stride + 1);
        let spacing = hm.spacing * stride as f32;
        let mut positions = Vec::with_capacity((nx * nz) as usize);
        let mut normals = Vec::with_capacity((nx * nz) as usize);
        for k in 0..nz {
            for i in 0..nx {
                let (x, z) = (
                    hm.origin.x + (i * stride) as f32 * hm.spacing,
                    hm.origin.y + (k * stride) as f32 * hm.spacing,
                );
                positions.push(Vec3::new(x, hm.height_at(x, z), z));
                let e = hm.spacing;
                let dx = hm.height_at(x + e, z) - hm.height_at(x - e, z);
                let dz = hm.height_at(x, z + e) - hm.height_at(x, z - e);
                normals.push(Vec3::new(-dx, 2.0 * e, -dz).normalize());
            }
        }
        let mut indices = Vec::new();
        for k in 0..nz - 1 {
            for i in 0..nx - 1 {
                let a = k * nx + i;
                let (b, c, d) = (a + 1, a + nx, a + nx + 1);
                // Counter-clockwise seen from above (+Y).
                indices.extend_from_slice(&[a, c, b, b, c, d]);
            }
        }
        Self {
            positions,
            normals,
            indices,
            size: (nx, nz),
            origin: hm.origin,
            spacing,
        }
    }
}

fn srgb_texture(t: &lightgrid_material_voxelizer::model::Texture) -> TextureRgba8 {
    TextureRgba8 {
        width: t.width,
        height: t.height,
        texels: t
            .texels
            .iter()
            .map(|c| {
                [
                    linear_to_srgb8(c.x),
                    linear_to_srgb8(c.y),
                    linear_to_srgb8(c.z),
                    (c.w.clamp(0.0, 1.0) * 255.0 + 0.5) as u8,
                ]
            })
            .collect(),
    }
}

/// What a world's meshes are made of ([`World::mesh_sources`]): its terrain, models,
/// instances and dynamic lights, without the hierarchy (which may build grids while the
/// meshes are uploaded).
#[derive(Clone, Copy)]
pub struct MeshSources<'a> {
    /// The terrain's heights.
    pub heightmap: &'a Heightmap,
    /// The ground's colour.
    pub ground: &'a GroundColour,
    /// The models.
    pub models: &'a [ModelEntry],
    /// Their instances.
    pub instances: &'a [Instance],
    /// Dynamic lights.
    pub dynamic: &'a lightgrid_render::DynamicLights,
    /// Metres from the eye beyond which models are drawn as their impostors (`None`:
    /// every instance whole).
    pub far_detail: Option<f32>,
}

/// One mesh per material of `model` (flat normals, UV transform applied), and beyond
/// `far` metres from the eye ([`Renderer::set_draw_range`]) its impostor in their
/// place (last in the list; [`ImpostorParams::trees`]: at the demo's 120 m a texel is
/// about half a pixel of a 20 m tree in a 960 × 540 view's 60° field). Only foliage
/// gets one: it is lit as foliage, which ignores the normal, where a rock's or a
/// house's picture would lose its faces' shading.
pub fn model_meshes(
    r: &mut Renderer,
    model: &Model,
    foliage: bool,
    far: Option<f32>,
) -> Result<Vec<MeshId>> {
    let parts = model_parts(model, foliage);
    let mut ids = Vec::new();
    for (vertices, indices, material) in &parts {
        ids.push(r.add_mesh(vertices, indices, material)?);
    }
    if let Some(far) = far.filter(|_| foliage && !parts.is_empty()) {
        let list: Vec<Part<'_>> = parts
            .iter()
            .map(|(vertices, indices, material)| Part {
                vertices,
                indices,
                material,
            })
            .collect();
        let imp = Impostor::of(&list, &ImpostorParams::trees())?;
        for id in &ids {
            r.set_draw_range(*id, 0.0..far)?;
        }
        let id = r.add_mesh(&imp.vertices, &imp.indices, &imp.material)?;
        r.set_draw_range(id, far..f32::INFINITY)?;
        ids.push(id);
    }
    Ok(ids)
}

/// One part per material of `model` that has triangles: flat-normal vertices, their
/// indices and the material.
fn model_parts(model: &Model, foliage: bool) -> Vec<(Vec<Vertex>, Vec<u32>, MeshMaterial)> {
    let mut parts = Vec::new();
    for (mi, mat) in model.materials.iter().enumerate() {
        let mut vertices = Vec::new();
        for tri in model.triangles.iter().filter(|t| t.material == mi as u32) {
            let [a, b, c] = tri.positions;
            let n = (b - a).cross(c - a).normalize_or_zero();
            if n == Vec3::ZERO {
                continue;
            }
            for k in 0..3 {
                vertices.push(Vertex {
                    position: tri.positions[k].to_array(),
                    normal: n.to_array(),
                    uv: mat.uv_transform.apply(tri.uvs[k]).to_array(),
                    light: [0.0; 4],
                });
            }
        }
        if vertices.is_empty() {
            continue;
        }
        let masked = !matches!(mat.alpha, AlphaMode::Opaque);
        let indices: Vec<u32> = (0..vertices.len() as u32).collect();
        let material = MeshMaterial {
            base_colour: mat.base_colour,
            texture: mat.texture.map(|t| srgb_texture(&model.textures[t])),
            alpha_cutoff: match mat.alpha {
                AlphaMode::Mask(c) => Some(c),
                AlphaMode::Blend => Some(0.5),
                AlphaMode::Opaque => None,
            },
            lighting: if foliage && masked {
                Lighting::Foliage
            } else {
                Lighting::Surface
            },
            double_sided: masked,
            specular: if masked { 0.0 } else { 0.15 },
            shininess: 24.0,
            billboard: false,
        };
        parts.push((vertices, indices, material));
    }
    parts
}

/// A ball's outline for the debug views: a regular polygon of [`DISC_SIDES`] sides in
/// the xy plane, drawn as a billboard (`MeshMaterial::billboard`) of one flat colour,
/// where it looks as a ball does. The debug views draw a ball per grid point, thousands
/// of them, and a software rasteriser's cost is per triangle: 10 triangles instead of
/// an icosphere's 80 (the clearing view's 13,000 balls: about 0.2 s less CPU a run on
/// lavapipe). Its area is the mean outline of the icosphere of radius 1 it replaces
/// (a convex body's mean shadow is a quarter of its surface: 0.928 π), so the views
/// show balls as large as before.
pub fn disc() -> (Vec<Vertex>, Vec<u32>) {
    let n = DISC_SIDES as f32;
    let area = 0.9283 * std::f32::consts::PI;
    // A regular n-gon of circumradius r has area n r² sin(2π / n) / 2.
    let r = (2.0 * area / (n * (std::f32::consts::TAU / n).sin())).sqrt();
    let v = (0..DISC_SIDES)
        .map(|k| {
            let a = std::f32::consts::TAU * k as f32 / n;
            Vertex {
                position: [r * a.cos(), r * a.sin(), 0.0],
                normal: [0.0, 0.0, 1.0],
                uv: [0.0; 2],
                light: [0.0; 4],
            }
        })
        .collect();
    // A fan from the first corner, counter-clockwise seen from +z (the eye's side).
    let idx = (1..DISC_SIDES - 1).flat_map(|k| [0, k, k + 1]).collect();
    (v, idx)
}

/// Sides of [`disc`].
pub const DISC_SIDES: u32 = 12;

/// A unit cube centred on the origin (24 vertices, flat faces).
pub fn cube() -> (Vec<Vertex>, Vec<u32>) {
    let mut v = Vec::new();
    let mut idx = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            let a = n.any_orthonormal_vector();
            let b = n.cross(a);
            let base = v.len() as u32;
            for (s, t) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                v.push(Vertex {
                    position: ((n + a * s + b * t) * 0.5).to_array(),
                    normal: n.to_array(),
                    uv: [0.0; 2],
                    light: [0.0; 4],
                });
            }
            idx.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    (v, idx)
}

/// The meshes of a world in a renderer.
pub struct SceneMeshes {
    /// The terrain.
    pub terrain: MeshId,
    /// The terrain's vertices (light refreshed per view).
    pub terrain_mesh: TerrainMesh,
    /// Model meshes (instanced).
    pub models: Vec<MeshId>,
    /// Debug: a ball per grid point.
    pub balls: MeshId,
    /// Debug: a cube per material cell.
    pub cubes: MeshId,
    /// Probes debug: a ball per probe, a cube per surfel.
    pub probe_balls: MeshId,
    /// Probes debug: a cube per surfel.
    pub surfel_cubes: MeshId,
    /// Samples grids where they lie, on the renderer's device.
    sampler: GpuLightSampler,
}

/// What [`SceneMeshes::relight`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relit {
    /// Bytes of the light volume.
    pub volume_bytes: u64,
    /// Whether the light was sampled on the device from the grids the GPU sweeper left
    /// there (no grid went through the CPU), rather than on the CPU.
    pub on_device: bool,
    /// Grids sampled (the world grid and the ready nodes).
    pub grids: usize,
    /// Points of the light volume.
    pub volume_points: u64,
    /// Seconds sampling the light volume took.
    pub volume_seconds: f64,
}

impl SceneMeshes {
    /// Uploads the terrain, the models with their instances, and the debug meshes.
    pub fn new(r: &mut Renderer, world: &World) -> Result<Self> {
        Self::from_sources(r, world.mesh_sources())
    }

    /// [`SceneMeshes::new`] from a world's parts.
    pub fn from_sources(r: &mut Renderer, world: MeshSources<'_>) -> Result<Self> {
        let terrain_mesh = TerrainMesh::of(world.heightmap, 320);
        let ground = match world.ground {
            lightgrid_material_voxelizer::compose::GroundColour::Uniform(c) => c.extend(1.0),
            _ => Vec4::new(0.25, 0.22, 0.16, 1.0),
        };
        let vertices = terrain_vertices(
            &terrain_mesh,
            &vec![Vec3::ZERO; terrain_mesh.positions.len()],
        );
        let terrain = r.add_mesh(
            &vertices,
            &terrain_mesh.indices,
            &MeshMaterial {
                base_colour: ground,
                lighting: Lighting::Vertex,
                ..Default::default()
            },
        )?;
        r.set_instances(terrain, &[MeshInstance::new(Mat4::IDENTITY, Vec4::ONE)])?;
        let mut models = Vec::new();
        for (mi, entry) in world.models.iter().enumerate() {
            let ids = model_meshes(r, &entry.model, entry.foliage, world.far_detail)
                .with_context(|| format!("meshes of model {}", entry.name))?;
            let inst: Vec<MeshInstance> = world
                .instances
                .iter()
                .filter(|i| i.model == mi as u32)
                .map(|i| {
                    MeshInstance::new(
                        Mat4::from_scale_rotation_translation(
                            Vec3::splat(i.scale),
                            i.rotation,
                            i.position,
                        ),
                        Vec4::ONE,
                    )
                })
                .collect();
            for id in &ids {
                r.set_instances(*id, &inst)?;
            }
            models.extend(ids);
        }
        r.set_dynamic_lights(world.dynamic)?;
        let marker = MeshMaterial {
            lighting: Lighting::Emissive,
            billboard: true,
            ..Default::default()
        };
        let (v, i) = disc();
        let balls = r.add_mesh(&v, &i, &marker)?;
        let (v, i) = cube();
        let cubes = r.add_mesh(
            &v,
            &i,
            &MeshMaterial {
                lighting: Lighting::Flat,
                ..Default::default()
            },
        )?;
        let emissive = MeshMaterial {
            lighting: Lighting::Emissive,
            ..Default::default()
        };
        let (v, i) = disc();
        let probe_balls = r.add_mesh(&v, &i, &marker)?;
        let (v, i) = cube();
        let surfel_cubes = r.add_mesh(&v, &i, &emissive)?;
        Ok(Self {
            terrain,
            terrain_mesh,
            models,
            balls,
            cubes,
            probe_balls,
            surfel_cubes,
            sampler: GpuLightSampler::new(r.context().clone()),
        })
    }

    /// Relights the terrain vertices (sampling buffer with normals) and the ground light,
    /// and resamples the light volume, from the hierarchy's current grids: on the device
    /// when every grid lies there (the GPU sweeper keeps them on the renderer's device),
    /// else on the CPU. Both follow `Hierarchy::grid_at` (a GPU test holds them equal).
    pub fn relight(&self, r: &mut Renderer, world: &World) -> Result<Relit> {
        let layers = world.hierarchy.layers();
        let desc = volume_desc(world)?;
        let t = &self.terrain_mesh;
        let terrain_points = SamplePoints {
            positions: &t.positions,
            normals: Some(&t.normals),
        };
        let ground = |light: &[Vec3]| t.ground_light(light);
        let volume_bytes = desc.point_count() as u64 * 32;
        // On the device when every grid (and, with the sun kept apart, every grid's
        // scattered sun) lies on the renderer's device; the transmittances are uploaded.
        let sun = world.hierarchy.sun();
        fn on_device<'a>(
            res: Option<&'a lightgrid_core::Resident>,
            ctx: &std::sync::Arc<lightgrid_gpu::GpuContext>,
        ) -> Option<&'a GpuLightGrid> {
            res.and_then(|r| r.get::<GpuLightGrid>())
                .filter(|g| std::sync::Arc::ptr_eq(g.context(), ctx))
        }
        let ctx = r.context().clone();
        let on_this_device = |res| on_device(res, &ctx);
        // (Uploaded only when every grid lies on this device: the CPU sweeper's never do.)
        let all_here = layers.iter().all(|l| {
            on_this_device(l.resident).is_some()
                && (sun.is_none() || l.sun.is_some_and(|s| on_this_device(s.resident).is_some()))
        });
        let t_buffers: Vec<Option<wgpu::Buffer>> = layers
            .iter()
            .map(|l| {
                l.sun
                    .filter(|_| sun.is_some() && all_here)
                    .map(|s| transmittance_buffer(r.context(), s.transmittance.data()))
            })
            .collect();
        // The horizon halves, uploaded likewise (the sun's beside the sky's when kept;
        // halves that cannot be uploaded send the sampling to the CPU).
        let h_buffers: Vec<Option<GpuHorizon>> = layers
            .iter()
            .map(|l| {
                let halves = l.horizon.filter(|_| all_here)?;
                let scattered = l.sun.filter(|_| sun.is_some()).and_then(|s| s.horizon);
                GpuHorizon::new(r.context().clone(), halves, scattered).ok()
            })
            .collect();
        let device: Option<Vec<GpuSampleLayer>> = layers
            .iter()
            .zip(t_buffers.iter().zip(&h_buffers))
            .map(|(l, (t, h))| {
                if l.horizon.is_some() && h.is_none() {
                    return None;
                }
                let grid = on_this_device(l.resident)?;
                let layer_sun = match (sun, l.sun, t) {
                    (None, _, _) => None,
                    (Some(_), Some(s), Some(t)) => Some(GpuLayerSun {
                        scattered: on_this_device(s.resident)?,
                        transmittance: t,
                    }),
                    _ => return None,
                };
                Some(GpuSampleLayer {
                    grid,
                    owner: l.owner.map(|o| LayerOwner {
                        origin: o.origin,
                        size: o.size,
                        index: o.index,
                    }),
                    sun: layer_sun,
                    horizon: h.as_ref(),
                })
            })
            .collect();
        let layer_light = LayerLight {
            sky_scale: world.hierarchy.sky_scale(),
            sun: sun.map(|s| (s.to_sun, s.irradiance)),
        };
        if let Some(device) = device {
            let lit = self.sampler.sample_layers_lit(
                &device,
                GpuPoints::List(terrain_points),
                &layer_light,
            )?;
            r.set_vertex_light_samples(self.terrain, &lit)?;
            r.set_ground(&ground(&vec![Vec3::ZERO; t.positions.len()]))?;
            r.set_ground_light_samples(&lit)?;
            let t = std::time::Instant::now();
            let volume =
                self.sampler
                    .sample_layers_lit(&device, GpuPoints::Lattice(desc), &layer_light)?;
            let volume_seconds = t.elapsed().as_secs_f64();
            r.set_light_volume_samples(desc, &volume)?;
            return Ok(Relit {
                volume_bytes,
                on_device: true,
                grids: layers.len(),
                volume_points: desc.point_count() as u64,
                volume_seconds,
            });
        }
        self.relight_cpu(r, world, &world.hierarchy)
    }

    /// Relights on the CPU from any light field (the hierarchy, or the probes with the
    /// sweep's sun transmittance): terrain vertices and ground light from `field` plus
    /// the direct sun kept apart, and the light volume.
    pub fn relight_cpu<F: LightField + Sync>(
        &self,
        r: &mut Renderer,
        world: &World,
        field: &F,
    ) -> Result<Relit> {
        let desc = volume_desc(world)?;
        let t = &self.terrain_mesh;
        let terrain_points = SamplePoints {
            positions: &t.positions,
            normals: Some(&t.normals),
        };
        let sun = world.hierarchy.sun();
        let lit = sample_points(field, terrain_points)?;
        // Vertex and ground light hold everything, the direct sun kept apart included
        // (E T max(0, n·s) with the exact direction and the vertex's own transmittance).
        let light: Vec<Vec3> = lit
            .iter()
            .zip(&t.normals)
            .map(|(s, n)| match sun {
                Some(sun) => {
                    s.light
                        + lightgrid_render::shading::direct_sun(
                            sun.irradiance,
                            s.sun,
                            sun.to_sun,
                            *n,
                            Vec3::Y,
                            1.0,
                        )
                        .0
                }
                None => s.light,
            })
            .collect();
        r.update_vertices(self.terrain, &terrain_vertices(t, &light))?;
        r.set_ground(&t.ground_light(&light))?;
        let t = std::time::Instant::now();
        let volume = LightVolume::from_field(field, desc)?;
        let volume_seconds = t.elapsed().as_secs_f64();
        r.set_light_volume(&volume)?;
        Ok(Relit {
            volume_bytes: desc.point_count() as u64 * 32,
            on_device: false,
            grids: world.hierarchy.layers().len(),
            volume_points: desc.point_count() as u64,
            volume_seconds,
        })
    }

    /// Relights from the world's light probes (the sweep's light where no probe
    /// reaches, its transmittance for the direct sun; [`crate::probes::ProbeLit`]) and
    /// sets the probes' debug instances. `None` without `[probes]`.
    pub fn relight_probes(&self, r: &mut Renderer, world: &World) -> Result<Option<Relit>> {
        let Some(probes) = &world.probes else {
            return Ok(None);
        };
        let resolved = probes.resolved()?;
        let field = crate::probes::ProbeLit {
            probes: &resolved,
            sweep: &world.hierarchy,
        };
        let relit = self.relight_cpu(r, world, &field)?;
        self.set_probe_debug(r, probes)?;
        Ok(Some(relit))
    }

    /// Instances for the probes' debug view: a ball per probe (radius a tenth of the
    /// spacing, shown as a mid-grey card of albedo 0.18 under the probe's mean
    /// irradiance) and a cube per surfel (half a surfel cell, glowing with the radiance
    /// it had this frame).
    pub fn set_probe_debug(
        &self,
        r: &mut Renderer,
        probes: &crate::probes::Probes,
    ) -> Result<(usize, usize)> {
        let params = probes.set.params();
        let balls: Vec<MeshInstance> = probes
            .set
            .probes()
            .iter()
            .zip(probes.light.probes())
            .map(|(p, c)| {
                let mean = c.0.iter().copied().sum::<Vec3>() / 6.0;
                MeshInstance::new(
                    Mat4::from_scale_rotation_translation(
                        Vec3::splat(0.1 * params.spacing),
                        Default::default(),
                        p.position,
                    ),
                    (mean * 0.18).extend(1.0),
                )
            })
            .collect();
        let cubes: Vec<MeshInstance> = probes
            .set
            .surfels()
            .iter()
            .zip(probes.light.surfels())
            .map(|(s, l)| {
                MeshInstance::new(
                    Mat4::from_scale_rotation_translation(
                        Vec3::splat(0.5 * params.cell),
                        Default::default(),
                        s.position,
                    ),
                    l.extend(1.0),
                )
            })
            .collect();
        r.set_instances(self.probe_balls, &balls)?;
        r.set_instances(self.surfel_cubes, &cubes)?;
        Ok((balls.len(), cubes.len()))
    }

    /// Instances for the debug views of `grid`: balls at its points above the ground
    /// (radius 0.18 h, shown as a mid-grey card of albedo 0.18 under the point's light) and cubes at its
    /// material cells (side h × density^(1/3), coloured by reflectance).
    pub fn set_debug(
        &self,
        r: &mut Renderer,
        world: &World,
        grid: &LightGrid,
    ) -> Result<(usize, usize)> {
        let d = *grid.desc();
        let h = d.h();
        let ground = |p: Vec3| world.heightmap.height_at(p.x, p.z);
        let mut balls = Vec::new();
        for (i, b) in grid.data().iter().enumerate() {
            let p = d.position(d.coords(i).expect("in range"));
            if p.y < ground(p) - 0.25 * h {
                continue;
            }
            // All the point's light: with the sun kept apart, the hierarchy's bins (sky
            // and scattered sun) and the direct beam's average, E T / 4π.
            let average = match world.hierarchy.sun() {
                Some(sun) => {
                    world.hierarchy.average(p)?
                        + lightgrid_render::shading::direct_sun_foliage(
                            sun.irradiance,
                            world.hierarchy.sun_transmittance(p, None)?,
                        ) / std::f32::consts::PI
                }
                None => b.average(),
            };
            let light = average * std::f32::consts::PI * 0.18;
            balls.push(MeshInstance::new(
                Mat4::from_scale_rotation_translation(Vec3::splat(0.18 * h), Default::default(), p),
                light.extend(1.0),
            ));
        }
        let material = world.composer.material(&d)?;
        let mut cubes = Vec::new();
        for (i, m) in material.data().iter().enumerate() {
            let p = d.position(d.coords(i).expect("in range"));
            let density = 1.0 - m.pass;
            if density < 0.03 || p.y < ground(p) - 1.5 * h {
                continue;
            }
            cubes.push(MeshInstance::new(
                Mat4::from_scale_rotation_translation(
                    Vec3::splat(h * density.cbrt()),
                    Default::default(),
                    p,
                ),
                m.reflectance.extend(1.0),
            ));
        }
        r.set_instances(self.balls, &balls)?;
        r.set_instances(self.cubes, &cubes)?;
        Ok((balls.len(), cubes.len()))
    }
}

fn terrain_vertices(t: &TerrainMesh, light: &[Vec3]) -> Vec<Vertex> {
    t.positions
        .iter()
        .zip(&t.normals)
        .zip(light)
        .map(|((p, n), e)| Vertex {
            position: p.to_array(),
            normal: n.to_array(),
            uv: [p.x / 8.0, p.z / 8.0],
            light: e.extend(1.0).to_array(),
        })
        .collect()
}

/// The light volume's box: the whole terrain, from 2 m under its lowest point to 24 m
/// over its highest, in cells of at least twice the finest grid's, at most ~1.5 M points.
pub fn volume_desc(world: &World) -> Result<GridDesc> {
    let hm = &world.heightmap;
    let (lo, hi) = hm.range();
    let size = Vec2::new(
        (hm.width - 1) as f32 * hm.spacing,
        (hm.depth - 1) as f32 * hm.spacing,
    );
    let height = hi - lo + 26.0;
    let volume = size.x * size.y * height;
    let h = (2.0 * world.scene.grid.finest_cell).max((volume / 1.5e6).cbrt());
    let dims = (Vec3::new(size.x, height, size.y) / h).ceil().as_uvec3() + UVec3::ONE;
    Ok(GridDesc::new(
        Vec3::new(hm.origin.x, lo - 2.0, hm.origin.y),
        h,
        dims,
    )?)
}

/// The views of one camera: what each image shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shot {
    /// The scene lit by the grids.
    Lit,
    /// The scene with the sun unshadowed and a flat sky ambient (no grids).
    NoGrid,
    /// Terrain plus the grid points as balls.
    Points,
    /// The material cells as cubes.
    Material,
    /// The scene lit by the light probes (with `[probes]`; relight with
    /// [`SceneMeshes::relight_probes`] first).
    Probes,
    /// Terrain, the probes as balls and their surfels as glowing cubes.
    ProbesDebug,
}

impl Shot {
    /// The shots every view gets (the probes' two come with `[probes]`).
    pub const ALL: [Shot; 4] = [Shot::Lit, Shot::NoGrid, Shot::Points, Shot::Material];

    /// File name suffix.
    pub fn suffix(self) -> &'static str {
        match self {
            Shot::Lit => "",
            Shot::NoGrid => "-no-grid",
            Shot::Points => "-grid-points",
            Shot::Material => "-material",
            Shot::Probes => "-probes",
            Shot::ProbesDebug => "-probes-debug",
        }
    }
}

/// The renderer view of a shot.
pub fn make_view(world: &World, meshes: &SceneMeshes, camera: Camera, shot: Shot) -> View {
    let sky_ambient = world.sky_top.total() / (2.0 * std::f32::consts::PI);
    let mut list = vec![meshes.terrain];
    match shot {
        Shot::Lit | Shot::NoGrid | Shot::Probes => list.extend(&meshes.models),
        Shot::Points => list.push(meshes.balls),
        Shot::Material => list = vec![meshes.cubes],
        Shot::ProbesDebug => list.extend([meshes.probe_balls, meshes.surfel_cubes]),
    }
    View {
        camera,
        mode: if shot == Shot::NoGrid {
            LightingMode::NoGrid
        } else {
            LightingMode::Grid
        },
        sun_direction: world.sun.0,
        sun_colour: world.sun.1,
        sky_ambient,
        // The sun kept apart from the bins is added per pixel (its transmittance is in
        // the volume); otherwise the bins hold it.
        direct_sun: match world.hierarchy.sun() {
            Some(s) if matches!(shot, Shot::Lit | Shot::Probes) => s.irradiance,
            _ => Vec3::ZERO,
        },
        exposure: 0.6,
        water: None,
        ground_blend: 1.5,
        background: sky_ambient,
        meshes: list,
    }
}
