//! Light sampled on the device equals the CPU's: the sampling buffer, layered sampling
//! (owned layers, the sun kept apart, horizon halves, seams), and drawing what the
//! device sampled where it lies. Runs on any adapter (lavapipe in CI); fails without
//! one unless LIGHTGRID_ALLOW_NO_GPU=1.

mod common;

use std::sync::Arc;

use lightgrid_core::glam::{Mat4, UVec3, Vec2, Vec3, Vec4};
use lightgrid_core::{BinLight, Grid, GridDesc, HorizonGrid, HorizonLight, LightGrid, NUM_DIRS};
use lightgrid_gpu::GpuContext;
use lightgrid_render::{
    GpuLightGrid, GpuLightSampler, GpuPoints, GpuSampleLayer, GroundLight, LayerOwner, LightVolume,
    Lighting, LightingMode, MeshInstance, MeshMaterial, SamplePoints, Vertex, sample_points,
};

use common::*;

#[test]
fn gpu_sampler_equals_cpu_sampler() {
    let Some(ctx) = context() else { return };
    let sampler = GpuLightSampler::new(ctx);
    let grid = test_grid();
    // Points inside, on the edges and outside (clamped), with odd normals.
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for i in 0..500 {
        let t = i as f32;
        positions.push(Vec3::new(
            -1.5 + (t * 0.37) % 4.5,
            0.2 + (t * 0.53) % 3.0,
            1.8 + (t * 0.29) % 2.0,
        ));
        normals.push(Vec3::new(
            (t * 1.3).sin(),
            (t * 0.7).cos(),
            (t * 2.1).sin() + 0.01,
        ));
    }
    for with_normals in [false, true] {
        let pts = SamplePoints {
            positions: &positions,
            normals: with_normals.then_some(&normals[..]),
        };
        let cpu = sample_points(&grid, pts).unwrap();
        let gpu = sampler.sample(&grid, pts).unwrap();
        assert_eq!(cpu.len(), gpu.len());
        for (i, (c, g)) in cpu.iter().zip(&gpu).enumerate() {
            assert!(
                c.light.min_element() > 0.0,
                "point {i}: light must be non-zero here"
            );
            let tol = 1e-5 * c.light.abs().max_element() + 1e-6;
            assert!(
                (c.light - g.light).abs().max_element() <= tol,
                "normals {with_normals} point {i}: cpu {} gpu {}",
                c.light,
                g.light
            );
            assert!(
                (c.dominant - g.dominant).abs().max_element() <= 1e-5,
                "point {i}: cpu {} gpu {}",
                c.dominant,
                g.dominant
            );
        }
    }
    // Empty batches and bad input.
    let none = SamplePoints {
        positions: &[],
        normals: None,
    };
    assert!(sampler.sample(&grid, none).unwrap().is_empty());
    let bad = [Vec3::ZERO];
    let err = sampler
        .sample(
            &grid,
            SamplePoints {
                positions: &positions[..1],
                normals: Some(&bad),
            },
        )
        .unwrap_err();
    assert!(err.to_string().contains("normals"), "{err}");
    assert_eq!(NUM_DIRS, 26);
}

/// A grid on `desc` whose bins vary with position, direction and `seed` (all > 0).
fn varied_grid(desc: GridDesc, seed: usize) -> LightGrid {
    let data = (0..desc.point_count())
        .map(|i| {
            BinLight(std::array::from_fn(|d| {
                let x = (i * 31 + d * 17 + seed * 7) % 23;
                Vec3::new(
                    0.1 + x as f32,
                    0.5 + ((d + seed) % 5) as f32,
                    0.2 + (i % 7) as f32,
                ) * 0.1
            }))
        })
        .collect();
    Grid::from_trusted(desc, data)
}

/// The layer rule, on the CPU: the last layer owning `p` (lightgrid_terrain_lod::Owner::owns).
fn owning<'a>(layers: &[(&'a LightGrid, Option<LayerOwner>)], p: Vec3) -> Option<&'a LightGrid> {
    layers.iter().rev().find_map(|(g, o)| {
        let owns = o.is_none_or(|o| {
            ((Vec2::new(p.x, p.z) - o.origin) / o.size)
                .floor()
                .as_ivec2()
                == o.index
                && g.desc().contains(p)
        });
        owns.then_some(*g)
    })
}

/// Layered sampling on the device (a coarse grid under two owned finer ones, as the
/// hierarchy draws) equals the CPU: per point, the last owning layer's
/// `sample_points`; for listed points with and without normals and for a generated
/// lattice. Points no layer owns keep the zero the output starts with.
#[test]
fn layered_device_sampling_equals_the_cpu_rule() {
    let Some(ctx) = context() else { return };
    let sampler = GpuLightSampler::new(ctx.clone());
    let world = varied_grid(
        GridDesc::new(Vec3::new(-8.0, 0.0, -8.0), 2.0, UVec3::new(9, 4, 9)).unwrap(),
        0,
    );
    let a = varied_grid(
        GridDesc::new(Vec3::new(-4.0, 0.0, -4.0), 1.0, UVec3::new(5, 5, 5)).unwrap(),
        1,
    );
    let b = varied_grid(
        GridDesc::new(Vec3::new(0.0, 0.0, 0.0), 0.5, UVec3::new(9, 9, 9)).unwrap(),
        2,
    );
    let owner = |x, z| {
        Some(LayerOwner {
            origin: Vec2::splat(-8.0),
            size: 4.0,
            index: lightgrid_core::glam::IVec2::new(x, z),
        })
    };
    let cpu_layers = [(&world, None), (&a, owner(1, 1)), (&b, owner(2, 2))];
    let dev: Vec<GpuLightGrid> = cpu_layers
        .iter()
        .map(|(g, _)| GpuLightGrid::new(ctx.clone(), g).unwrap())
        .collect();
    let layers: Vec<GpuSampleLayer> = dev
        .iter()
        .zip(&cpu_layers)
        .map(|(g, (_, o))| GpuSampleLayer::bins(g, *o))
        .collect();
    let (positions, normals) = point_cloud(3);
    let compare = |cpu: &[lightgrid_render::SampledLight],
                   gpu: &[lightgrid_render::SampledLight],
                   what: &str| {
        assert_eq!(cpu.len(), gpu.len());
        for (i, (c, g)) in cpu.iter().zip(gpu).enumerate() {
            let tol = 1e-5 * c.light.abs().max_element() + 1e-6;
            assert!(
                (c.light - g.light).abs().max_element() <= tol
                    && (c.dominant - g.dominant).abs().max_element() <= 1e-5,
                "{what} point {i}: cpu {c:?} gpu {g:?}"
            );
        }
    };
    let cpu_sample = |pts: &[Vec3], ns: Option<&[Vec3]>| -> Vec<lightgrid_render::SampledLight> {
        pts.iter()
            .enumerate()
            .map(|(i, p)| {
                let g = owning(&cpu_layers, *p).unwrap();
                let n = ns.map(|n| &n[i..i + 1]);
                sample_points(
                    g,
                    SamplePoints {
                        positions: &pts[i..i + 1],
                        normals: n,
                    },
                )
                .unwrap()[0]
            })
            .collect()
    };
    let mut fine = [0usize; 3];
    for p in &positions {
        let g = owning(&cpu_layers, *p).unwrap();
        fine[[&world, &a, &b]
            .iter()
            .position(|x| std::ptr::eq(*x, g))
            .unwrap()] += 1;
    }
    assert!(fine.iter().all(|&n| n > 100), "{fine:?}");
    for with_normals in [false, true] {
        let ns = with_normals.then_some(&normals[..]);
        let pts = SamplePoints {
            positions: &positions,
            normals: ns,
        };
        let gpu = sampler
            .sample_layers(&layers, GpuPoints::List(pts))
            .unwrap()
            .read()
            .unwrap();
        compare(
            &cpu_sample(&positions, ns),
            &gpu,
            &format!("normals {with_normals}"),
        );
    }
    // A lattice generated on the device, including points on the owners' edges.
    let lattice = GridDesc::new(Vec3::new(-8.0, -0.5, -8.0), 0.5, UVec3::new(33, 12, 33)).unwrap();
    let lpos: Vec<Vec3> = (0..lattice.point_count())
        .map(|i| lattice.position(lattice.coords(i).unwrap()))
        .collect();
    let gpu = sampler
        .sample_layers(&layers, GpuPoints::Lattice(lattice))
        .unwrap();
    assert_eq!(gpu.count(), lattice.point_count());
    compare(&cpu_sample(&lpos, None), &gpu.read().unwrap(), "lattice");
    // Without the world layer, points outside both nodes are untouched: zero.
    let only_nodes = sampler
        .sample_layers(
            &layers[1..],
            GpuPoints::List(SamplePoints {
                positions: &positions,
                normals: None,
            }),
        )
        .unwrap()
        .read()
        .unwrap();
    for (p, s) in positions.iter().zip(&only_nodes) {
        let owned = owning(&cpu_layers[1..], *p).is_some();
        assert_eq!(owned, s.light != Vec3::ZERO, "{p}: {s:?}");
    }
    // A grid of another device is refused, naming the layer.
    let other = Arc::new(GpuContext::new().unwrap());
    let foreign = GpuLightGrid::new(other, &world).unwrap();
    let e = sampler
        .sample_layers(
            &[GpuSampleLayer::bins(&foreign, None)],
            GpuPoints::Lattice(lattice),
        )
        .err()
        .unwrap();
    assert!(e.to_string().contains("layers[0]"), "{e}");
    // An owner whose side is not a finite positive length is refused, naming it.
    for size in [0.0, -4.0, f32::NAN, f32::INFINITY] {
        let mut bad = layers.clone();
        bad[2].owner = Some(LayerOwner {
            size,
            ..owner(2, 2).unwrap()
        });
        let e = sampler
            .sample_layers(&bad, GpuPoints::Lattice(lattice))
            .err()
            .unwrap();
        assert!(e.to_string().contains("layers[2].owner"), "{size}: {e}");
    }
}

/// Light sampled on the device and drawn from where it lies (light volume, vertex
/// light, ground light) gives the image that uploading the CPU samples gives.
#[test]
fn drawing_device_samples_equals_drawing_uploaded_samples() {
    let Some(r) = renderer() else { return };
    let mut r = r.lock().unwrap_or_else(|e| e.into_inner());
    let ctx = r.context().clone();
    let sampler = GpuLightSampler::new(ctx.clone());
    let grid = varied_grid(
        GridDesc::new(Vec3::new(-12.0, -1.0, -12.0), 3.0, UVec3::new(9, 4, 9)).unwrap(),
        5,
    );
    let dev = GpuLightGrid::new(ctx, &grid).unwrap();
    let layer = [GpuSampleLayer::bins(&dev, None)];
    let close = |a: &lightgrid_render::Image, b: &lightgrid_render::Image, what: &str| {
        let mut lit = 0;
        for (i, (p, q)) in a.hdr.iter().zip(&b.hdr).enumerate() {
            let (p, q) = (Vec3::new(p[0], p[1], p[2]), Vec3::new(q[0], q[1], q[2]));
            assert!(
                (p - q).abs().max_element() <= 1e-4 * p.max_element().max(1e-3),
                "{what}: pixel {i} uploaded {p} device {q}"
            );
            lit += (p.max_element() > 0.01) as usize;
        }
        assert!(lit > a.hdr.len() / 2, "{what}: {lit} lit pixels");
    };
    // Light volume.
    let desc = GridDesc::new(Vec3::new(-11.0, -0.5, -11.0), 1.0, UVec3::new(23, 4, 23)).unwrap();
    let surface = lit_quad(&mut r, 1.0, Lighting::Surface);
    r.set_light_volume(&LightVolume::from_field(&grid, desc).unwrap())
        .unwrap();
    let uploaded = r.render(&view(LightingMode::Grid, vec![surface])).unwrap();
    let samples = sampler
        .sample_layers(&layer, GpuPoints::Lattice(desc))
        .unwrap();
    r.set_light_volume_samples(desc, &samples).unwrap();
    let device = r.render(&view(LightingMode::Grid, vec![surface])).unwrap();
    close(&uploaded, &device, "light volume");
    // Vertex light: irradiance on the quad's normals at its vertices.
    let (v, i) = quad(0.5, Vec3::ZERO);
    let vertex = r
        .add_mesh(
            &v,
            &i,
            &MeshMaterial {
                lighting: Lighting::Vertex,
                ..Default::default()
            },
        )
        .unwrap();
    r.set_instances(vertex, &[MeshInstance::new(Mat4::IDENTITY, Vec4::ONE)])
        .unwrap();
    let positions: Vec<Vec3> = v.iter().map(|v| Vec3::from(v.position)).collect();
    let normals: Vec<Vec3> = v.iter().map(|v| Vec3::from(v.normal)).collect();
    let pts = SamplePoints {
        positions: &positions,
        normals: Some(&normals),
    };
    let cpu = sample_points(&grid, pts).unwrap();
    let lit: Vec<Vertex> = v
        .iter()
        .zip(&cpu)
        .map(|(v, s)| Vertex {
            light: s.light.extend(1.0).to_array(),
            ..*v
        })
        .collect();
    r.update_vertices(vertex, &lit).unwrap();
    let uploaded = r.render(&view(LightingMode::Grid, vec![vertex])).unwrap();
    r.update_vertices(vertex, &v).unwrap();
    let dark = r.render(&view(LightingMode::Grid, vec![vertex])).unwrap();
    assert!(
        dark.hdr.iter().all(|p| p[..3] == [0.0; 3]),
        "unlit vertices draw black"
    );
    let samples = sampler.sample_layers(&layer, GpuPoints::List(pts)).unwrap();
    r.set_vertex_light_samples(vertex, &samples).unwrap();
    let device = r.render(&view(LightingMode::Grid, vec![vertex])).unwrap();
    close(&uploaded, &device, "vertex light");
    // Ground light: 7 x 7 nodes at height 0.5 under the Surface quad, blended in.
    let nodes: Vec<Vec3> = (0..49)
        .map(|k| {
            Vec3::new(
                -30.0 + 10.0 * (k % 7) as f32,
                0.5,
                -30.0 + 10.0 * (k / 7) as f32,
            )
        })
        .collect();
    let up = vec![Vec3::Y; 49];
    let npts = SamplePoints {
        positions: &nodes,
        normals: Some(&up),
    };
    let ground = |light: &[Vec3]| GroundLight {
        origin: Vec2::splat(-30.0),
        spacing: 10.0,
        width: 7,
        depth: 7,
        nodes: light.iter().map(|e| e.extend(0.5).to_array()).collect(),
    };
    let cpu: Vec<Vec3> = sample_points(&grid, npts)
        .unwrap()
        .iter()
        .map(|s| s.light)
        .collect();
    r.set_ground(&ground(&cpu)).unwrap();
    let mut v = view(LightingMode::Grid, vec![surface]);
    v.ground_blend = 1.0;
    let uploaded = r.render(&v).unwrap();
    r.set_ground(&ground(&[Vec3::ZERO; 49])).unwrap();
    let samples = sampler
        .sample_layers(&layer, GpuPoints::List(npts))
        .unwrap();
    r.set_ground_light_samples(&samples).unwrap();
    let device = r.render(&v).unwrap();
    close(&uploaded, &device, "ground light");
    // Wrong counts are refused.
    let e = r.set_ground_light_samples(
        &sampler
            .sample_layers(&layer, GpuPoints::Lattice(desc))
            .unwrap(),
    );
    assert!(e.unwrap_err().to_string().contains("samples.count()"));
}

/// The CPU's read of `field` at point `i` of `positions` (with its normal, if any), and
/// the light it gives there with the direct sun `e` toward `to_sun` added where the
/// point has a normal (`E T max(0, n · s)`, as vertex light holds it).
fn cpu_read<F: lightgrid_core::LightField + Sync + ?Sized>(
    field: &F,
    (positions, normals): (&[Vec3], Option<&[Vec3]>),
    i: usize,
    (e, to_sun): (Vec3, Vec3),
) -> (lightgrid_render::SampledLight, Vec3) {
    let c = sample_points(
        field,
        SamplePoints {
            positions: &positions[i..i + 1],
            normals: normals.map(|n| &n[i..i + 1]),
        },
    )
    .unwrap()[0];
    let lit = match normals {
        Some(n) => c.light + e * (c.sun * n[i].dot(to_sun).max(0.0)),
        None => c.light,
    };
    (c, lit)
}

/// 3000 random points in a 10 x 5 x 10 m box and random (not unit) normals.
fn point_cloud(seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = fastrand::Rng::with_seed(seed);
    let positions: Vec<Vec3> = (0..3000)
        .map(|_| {
            Vec3::new(
                rng.f32() * 10.0 - 5.0,
                rng.f32() * 5.0 - 0.5,
                rng.f32() * 10.0 - 5.0,
            )
        })
        .collect();
    let normals: Vec<Vec3> = (0..3000)
        .map(|_| Vec3::new(rng.f32() - 0.5, rng.f32() - 0.3, rng.f32() - 0.5))
        .collect();
    (positions, normals)
}

/// A layer lit as the hierarchy lights it with the sun kept apart: `sky × scale +
/// scattered × E`, and the transmittance (the CPU rule of `sample_layers_lit`).
/// With horizon halves, those of the sky scaled plus the sun's (its bins split evenly
/// where it has none) times `E`, as `lightgrid_terrain_lod::Hierarchy` reads them.
struct LitLayer<'a> {
    sky: &'a LightGrid,
    scattered: &'a LightGrid,
    t: &'a Grid<f32>,
    scale: Vec3,
    sun: Vec3,
    halves: (Option<&'a HorizonGrid>, Option<&'a HorizonGrid>),
}

impl lightgrid_core::LightField for LitLayer<'_> {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, lightgrid_core::GridError> {
        Ok(self.sky.light(p, n)? * self.scale + self.scattered.light(p, n)? * self.sun)
    }
    fn horizon(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<Option<HorizonLight>, lightgrid_core::GridError> {
        let read = |h: &HorizonGrid| match n {
            Some(n) => h.sample_biased(p, n),
            None => h.sample(p),
        };
        let Some(sky) = self.halves.0 else {
            return Ok(None);
        };
        let sun = match self.halves.1 {
            Some(h) => read(h)?,
            None => HorizonLight::even(&self.scattered.light(p, n)?),
        };
        Ok(Some(read(sky)? * self.scale + sun * self.sun))
    }
    fn sun_transmittance(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<f32, lightgrid_core::GridError> {
        Ok(match n {
            Some(n) => self.t.sample_biased(p, n)?,
            None => self.t.sample(p)?,
        }
        .clamp(0.0, 1.0))
    }
}

/// Random downward halves of `bins`' horizontal bins (each a share of its bin).
fn varied_halves(bins: &LightGrid, seed: u64) -> HorizonGrid {
    let mut rng = fastrand::Rng::with_seed(seed);
    let data = bins
        .data()
        .iter()
        .map(|b| {
            HorizonLight(std::array::from_fn(|k| {
                b.0[lightgrid_core::dirs::FIRST_HORIZONTAL + k] * rng.f32()
            }))
        })
        .collect();
    Grid::from_trusted(*bins.desc(), data)
}

/// Layers lit as the hierarchy lights them, on the CPU and on the device: per grid
/// descriptor its sky bins, scattered sun and transmittance (varied, seeded by layer).
struct LitGrids {
    sky: Vec<LightGrid>,
    scat: Vec<LightGrid>,
    ts: Vec<Grid<f32>>,
    dev_sky: Vec<GpuLightGrid>,
    dev_scat: Vec<GpuLightGrid>,
    dev_t: Vec<wgpu::Buffer>,
}

impl LitGrids {
    fn new(ctx: &Arc<GpuContext>, descs: &[GridDesc]) -> Self {
        let sky: Vec<LightGrid> = descs
            .iter()
            .enumerate()
            .map(|(i, d)| varied_grid(*d, i))
            .collect();
        let scat: Vec<LightGrid> = descs
            .iter()
            .enumerate()
            .map(|(i, d)| varied_grid(*d, 10 + i))
            .collect();
        let ts: Vec<Grid<f32>> = descs
            .iter()
            .enumerate()
            .map(|(k, d)| {
                Grid::from_trusted(
                    *d,
                    (0..d.point_count())
                        .map(|i| ((i * 37 + k * 11) % 101) as f32 / 100.0)
                        .collect(),
                )
            })
            .collect();
        let up = |g: &LightGrid| GpuLightGrid::new(ctx.clone(), g).unwrap();
        Self {
            dev_sky: sky.iter().map(up).collect(),
            dev_scat: scat.iter().map(up).collect(),
            dev_t: ts
                .iter()
                .map(|t| lightgrid_render::transmittance_buffer(ctx, t.data()))
                .collect(),
            sky,
            scat,
            ts,
        }
    }

    /// Layer `i` on the device, owned by `owner`, with `horizon` halves.
    fn layer<'a>(
        &'a self,
        i: usize,
        owner: Option<LayerOwner>,
        horizon: Option<&'a lightgrid_render::GpuHorizon>,
    ) -> GpuSampleLayer<'a> {
        GpuSampleLayer {
            grid: &self.dev_sky[i],
            owner,
            sun: Some(lightgrid_render::GpuLayerSun {
                scattered: &self.dev_scat[i],
                transmittance: &self.dev_t[i],
            }),
            horizon,
        }
    }
}

/// `points` (with `normals` if given) sampled on the device from `layers` under `light`.
fn read_lit(
    sampler: &GpuLightSampler,
    layers: &[GpuSampleLayer<'_>],
    (positions, normals): (&[Vec3], Option<&[Vec3]>),
    light: &lightgrid_render::LayerLight,
) -> Vec<lightgrid_render::SampledLight> {
    sampler
        .sample_layers_lit(
            layers,
            GpuPoints::List(SamplePoints { positions, normals }),
            light,
        )
        .unwrap()
        .read()
        .unwrap()
}

/// Layered device sampling with the sky scaled and the sun kept apart equals the CPU
/// rule: per point the last owning layer's `sky × scale + scattered × E` through
/// `sample_points`, the transmittance in `w`, and for points with normals the direct sun
/// `E T max(0, n · s)` added (as vertex light holds it); with horizon halves (the
/// coarse layer the sky's alone, the fine one the sky's and the sun's), read through
/// them as the CPU sampler reads them. A layer without sun responses, or with halves
/// not on its grid, is refused by name.
#[test]
fn layered_device_sampling_with_the_sun_apart() {
    use lightgrid_render::{GpuHorizon, LayerLight};
    let Some(ctx) = context() else { return };
    let sampler = GpuLightSampler::new(ctx.clone());
    let descs = [
        GridDesc::new(Vec3::new(-8.0, 0.0, -8.0), 2.0, UVec3::new(9, 4, 9)).unwrap(),
        GridDesc::new(Vec3::new(0.0, 0.0, 0.0), 0.5, UVec3::new(9, 9, 9)).unwrap(),
    ];
    let grids = LitGrids::new(&ctx, &descs);
    let (sky, scat, ts) = (&grids.sky, &grids.scat, &grids.ts);
    let owners = [
        None,
        Some(LayerOwner {
            origin: Vec2::splat(-8.0),
            size: 4.0,
            index: lightgrid_core::glam::IVec2::new(2, 2),
        }),
    ];
    let (scale, e, to_sun) = (
        Vec3::new(0.5, 0.8, 1.2),
        Vec3::new(3.0, 2.5, 2.0),
        Vec3::new(0.3, 0.8, -0.4).normalize(),
    );
    let sky_h: Vec<HorizonGrid> = sky
        .iter()
        .enumerate()
        .map(|(i, g)| varied_halves(g, 20 + i as u64))
        .collect();
    let scat_h = varied_halves(&scat[1], 30);
    let dev_h = [
        GpuHorizon::new(ctx.clone(), &sky_h[0], None).unwrap(),
        GpuHorizon::new(ctx.clone(), &sky_h[1], Some(&scat_h)).unwrap(),
    ];
    let cpu_h = [(Some(&sky_h[0]), None), (Some(&sky_h[1]), Some(&scat_h))];
    let light = LayerLight {
        sky_scale: scale,
        sun: Some((to_sun, e)),
    };
    let (positions, normals) = point_cloud(9);
    let normals: Vec<Vec3> = normals.iter().map(|n| n.normalize()).collect();
    let cpu_layers: Vec<(&LightGrid, Option<LayerOwner>)> = sky.iter().zip(owners).collect();
    for (with_normals, with_halves) in [(false, false), (true, false), (true, true)] {
        let layers: Vec<GpuSampleLayer> = (0..2)
            .map(|i| grids.layer(i, owners[i], with_halves.then_some(&dev_h[i])))
            .collect();
        let ns = with_normals.then_some(&normals[..]);
        let gpu = read_lit(&sampler, &layers, (&positions, ns), &light);
        for (i, p) in positions.iter().enumerate() {
            let g = owning(&cpu_layers, *p).unwrap();
            let k = sky.iter().position(|s| std::ptr::eq(s, g)).unwrap();
            let field = LitLayer {
                sky: &sky[k],
                scattered: &scat[k],
                t: &ts[k],
                scale,
                sun: e,
                halves: if with_halves { cpu_h[k] } else { (None, None) },
            };
            let (c, want) = cpu_read(&field, (&positions, ns), i, (e, to_sun));
            let got = gpu[i];
            assert!(
                (want - got.light).abs().max_element() <= 1e-5 * want.abs().max_element() + 1e-5
                    && (c.sun - got.sun).abs() <= 1e-5,
                "normals {with_normals} halves {with_halves} point {i}: cpu {want} T {} gpu {} T {}",
                c.sun,
                got.light,
                got.sun
            );
        }
    }
    // A layer without its sun responses: refused by name.
    let bare = [GpuSampleLayer::bins(&grids.dev_sky[0], None)];
    let e = sampler
        .sample_layers_lit(&bare, GpuPoints::Lattice(descs[0]), &light)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("layers[0].sun"), "{e}");
    // Halves on another grid, or the sun's without a sun: refused by name.
    let unlike = [GpuSampleLayer {
        grid: &grids.dev_sky[0],
        owner: None,
        sun: None,
        horizon: Some(&dev_h[1]),
    }];
    let e = sampler
        .sample_layers(&unlike, GpuPoints::Lattice(descs[0]))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("layers[0].horizon"), "{e}");
}

/// Several layers' reads blended (`lightgrid_core::seam`): bins, halves and the
/// transmittance each the weighted sum of the parts', as the hierarchy's `LightField`
/// reads across a seam.
struct Blended<'a>(Vec<(LitLayer<'a>, f32)>);

impl lightgrid_core::LightField for Blended<'_> {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, lightgrid_core::GridError> {
        let mut acc = BinLight::ZERO;
        for (l, w) in &self.0 {
            acc += l.light(p, n)? * *w;
        }
        Ok(acc)
    }
    fn horizon(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<Option<HorizonLight>, lightgrid_core::GridError> {
        let mut acc = HorizonLight::default();
        for (l, w) in &self.0 {
            let Some(h) = l.horizon(p, n)? else {
                return Ok(None);
            };
            acc = acc + h * *w;
        }
        Ok(Some(acc))
    }
    fn sun_transmittance(
        &self,
        p: Vec3,
        n: Option<Vec3>,
    ) -> Result<f32, lightgrid_core::GridError> {
        let mut t = 0.0;
        for (l, w) in &self.0 {
            t += l.sun_transmittance(p, n)? * *w;
        }
        Ok(t.clamp(0.0, 1.0))
    }
}

/// Layered device sampling across the seams between owned layers that tile (one
/// quadtree, one cell size and points across, each the next one's neighbour) equals
/// the CPU rule: where a point's read (half a cell along its normal) falls between the
/// owning layer's outermost points and a neighbour's, the reads of the layers holding
/// the lookup's corners weighted by their shares (`lightgrid_core::seam::seam_shares`),
/// with the sun kept apart and horizon halves; the owner's read alone where one of
/// them is missing, does not reach the point's height, or does not tile (another cell
/// size beside the block). Across the block's inner seams the light is continuous.
#[test]
fn layered_device_sampling_reads_across_seams() {
    use lightgrid_core::glam::IVec2;
    use lightgrid_core::seam::seam_shares;
    use lightgrid_render::{GpuHorizon, LayerLight};
    let Some(ctx) = context() else { return };
    let sampler = GpuLightSampler::new(ctx.clone());
    let owner = |x, z| LayerOwner {
        origin: Vec2::splat(-8.0),
        size: 4.0,
        index: IVec2::new(x, z),
    };
    // The world grid; a 2 x 2 block of tiles over -4..4 (0.5 m, 8 points across; one
    // lower than the others); beside it a layer of another cell size (no seam).
    let tile = |x: i32, z: i32, levels: u32| {
        let o = Vec3::new(
            -8.0 + 4.0 * x as f32 + 0.25,
            0.0,
            -8.0 + 4.0 * z as f32 + 0.25,
        );
        GridDesc::new(o, 0.5, UVec3::new(8, levels, 8)).unwrap()
    };
    let mut descs =
        vec![GridDesc::new(Vec3::new(-8.0, 0.0, -8.0), 2.0, UVec3::new(9, 4, 9)).unwrap()];
    let mut owners = vec![None];
    for (x, z, levels) in [(1, 1, 9), (2, 1, 9), (1, 2, 9), (2, 2, 7)] {
        descs.push(tile(x, z, levels));
        owners.push(Some(owner(x, z)));
    }
    descs.push(GridDesc::new(Vec3::new(-7.5, 0.0, -3.5), 1.0, UVec3::new(4, 5, 4)).unwrap());
    owners.push(Some(owner(0, 1)));
    let n = descs.len();
    let grids = LitGrids::new(&ctx, &descs);
    let (sky, scat, ts) = (&grids.sky, &grids.scat, &grids.ts);
    let sky_h: Vec<HorizonGrid> = (0..n)
        .map(|i| varied_halves(&sky[i], 40 + i as u64))
        .collect();
    let scat_h: Vec<HorizonGrid> = (0..n)
        .map(|i| varied_halves(&scat[i], 50 + i as u64))
        .collect();
    let dev_h: Vec<GpuHorizon> = (0..n)
        .map(|i| GpuHorizon::new(ctx.clone(), &sky_h[i], Some(&scat_h[i])).unwrap())
        .collect();
    let (scale, e, to_sun) = (
        Vec3::new(0.5, 0.8, 1.2),
        Vec3::new(3.0, 2.5, 2.0),
        Vec3::new(0.3, 0.8, -0.4).normalize(),
    );
    let light = LayerLight {
        sky_scale: scale,
        sun: Some((to_sun, e)),
    };
    let lit = |k: usize| LitLayer {
        sky: &sky[k],
        scattered: &scat[k],
        t: &ts[k],
        scale,
        sun: e,
        halves: (Some(&sky_h[k]), Some(&scat_h[k])),
    };
    let layers: Vec<GpuSampleLayer> = (0..n)
        .map(|i| grids.layer(i, owners[i], Some(&dev_h[i])))
        .collect();
    let (positions, normals) = seam_points();
    // The owner (lightgrid_terrain_lod::Owner::owns: the quadtree cell, and the height
    // within the grid's levels; the strips beside a tile's outermost points are its).
    let owner_of = |p: Vec3| -> usize {
        (0..n)
            .rev()
            .find(|&k| {
                owners[k].is_none_or(|o| {
                    ((Vec2::new(p.x, p.z) - o.origin) / o.size)
                        .floor()
                        .as_ivec2()
                        == o.index
                        && p.y >= descs[k].origin().y
                        && p.y <= descs[k].point_bounds().1.y
                })
            })
            .unwrap()
    };
    // The CPU rule: the owner, and across a seam the layers of the block that tile.
    let parts = |p: Vec3, nrm: Option<Vec3>| -> Vec<(usize, f32)> {
        let a = owner_of(p);
        let Some(oa) = owners[a] else {
            return vec![(a, 1.0)];
        };
        let d = descs[a];
        let q = nrm.map_or(p, |nv| p + nv * (0.5 * d.h()));
        let (w, count) = seam_shares(&d, q);
        let mut out = Vec::new();
        for &(off, wt) in &w[..count] {
            let found = (0..n).rev().find(|&j| {
                owners[j].is_some_and(|o| o.index == oa.index + off)
                    && descs[j].h() == d.h()
                    && descs[j].dims().x == d.dims().x
            });
            match found {
                Some(j) if p.y <= descs[j].point_bounds().1.y && p.y >= descs[j].origin().y => {
                    out.push((j, wt))
                }
                _ => return vec![(a, 1.0)],
            }
        }
        out
    };
    // Each point's device read against the CPU rule's; the reads across a seam counted.
    let check = |pts: &[Vec3],
                 ns: Option<&[Vec3]>,
                 gpu: &[lightgrid_render::SampledLight],
                 what: &str|
     -> usize {
        let mut across = 0;
        for (i, p) in pts.iter().enumerate() {
            let ps = parts(*p, ns.map(|v| v[i]));
            across += (ps.len() > 1) as usize;
            let field = Blended(ps.iter().map(|&(k, w)| (lit(k), w)).collect());
            let (c, want) = cpu_read(&field, (pts, ns), i, (e, to_sun));
            let got = gpu[i];
            assert!(
                (want - got.light).abs().max_element() <= 1e-5 * want.abs().max_element() + 1e-5
                    && (c.sun - got.sun).abs() <= 1e-5
                    && (c.dominant - got.dominant).abs().max_element() <= 1e-4,
                "{what} point {i} at {p} from {ps:?}: cpu {want} T {} dominant {} gpu {} T {} dominant {}",
                c.sun,
                c.dominant,
                got.light,
                got.sun,
                got.dominant
            );
        }
        across
    };
    let mut across = 0;
    for with_normals in [false, true] {
        let ns = with_normals.then_some(&normals[..]);
        let gpu = read_lit(&sampler, &layers, (&positions, ns), &light);
        across += check(&positions, ns, &gpu, &format!("normals {with_normals}"));
    }
    assert!(across > 1000, "{across} reads across a seam");
    let lattice_across = lattice_reads(&sampler, &layers, &light, &check);
    assert!(
        lattice_across > 500,
        "{lattice_across} lattice reads across a seam"
    );
    assert_continuous_across_inner_seams(&sampler, &layers, &light, sky, &owner_of);
}

/// Points over [`layered_device_sampling_reads_across_seams`]'s block and beside it, many
/// in the strips along its seams, and a normal for each.
fn seam_points() -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = fastrand::Rng::with_seed(17);
    let positions: Vec<Vec3> = (0..4000)
        .map(|k| {
            let (mut x, mut z) = (rng.f32() * 11.0 - 6.0, rng.f32() * 11.0 - 6.0);
            if k % 2 == 0 {
                x = 0.8 * rng.f32() - 0.4;
            }
            if k % 3 == 0 {
                z = 0.8 * rng.f32() - 0.4;
            }
            Vec3::new(x, rng.f32() * 4.4 - 0.2, z)
        })
        .collect();
    let normals: Vec<Vec3> = (0..4000)
        .map(|_| Vec3::new(rng.f32() - 0.5, rng.f32() - 0.3, rng.f32() - 0.5).normalize())
        .collect();
    (positions, normals)
}

/// Each point's device read (`gpu`) at `points` (with `normals`) against the CPU rule's,
/// named `what`; returns the reads across a seam.
type SeamCheck<'a> =
    dyn Fn(&[Vec3], Option<&[Vec3]>, &[lightgrid_render::SampledLight], &str) -> usize + 'a;

/// The checks of [`layered_device_sampling_reads_across_seams`] (`check`: each read
/// against the CPU rule's, returning the reads across a seam) on a lattice generated on
/// the device, each layer visiting the lattice's points it can own or share alone:
/// points on and between the tiles' outermost points, in the strips along the seams,
/// and beyond the block.
fn lattice_reads(
    sampler: &GpuLightSampler,
    layers: &[GpuSampleLayer<'_>],
    light: &lightgrid_render::LayerLight,
    check: &SeamCheck<'_>,
) -> usize {
    let lattice =
        GridDesc::new(Vec3::new(-6.1, -0.2, -6.05), 0.23, UVec3::new(48, 20, 47)).unwrap();
    let lpos: Vec<Vec3> = (0..lattice.point_count())
        .map(|i| lattice.position(lattice.coords(i).unwrap()))
        .collect();
    let gpu = sampler
        .sample_layers_lit(layers, GpuPoints::Lattice(lattice), light)
        .unwrap()
        .read()
        .unwrap();
    check(&lpos, None, &gpu, "lattice")
}

/// Continuous across the block's inner seams (x = 0, z = 0) of
/// [`layered_device_sampling_reads_across_seams`], away from the lower tile's top: a
/// step of a thousandth of a metre changes the light by little, where the owners' reads
/// (`sky[owner_of(p)]` alone) jump.
fn assert_continuous_across_inner_seams(
    sampler: &GpuLightSampler,
    layers: &[GpuSampleLayer<'_>],
    light: &lightgrid_render::LayerLight,
    sky: &[LightGrid],
    owner_of: &dyn Fn(Vec3) -> usize,
) {
    let eps = 1e-3;
    let pairs: Vec<Vec3> = (0..200)
        .flat_map(|k| {
            let t = -3.5 + 7.0 * k as f32 / 200.0;
            let y = 0.3 + 2.5 * (k % 7) as f32 / 7.0;
            [
                Vec3::new(-eps, y, t),
                Vec3::new(eps, y, t),
                Vec3::new(t, y, -eps),
                Vec3::new(t, y, eps),
            ]
        })
        .collect();
    let gpu = read_lit(sampler, layers, (&pairs, None), light);
    let (mut worst, mut jump) = (0.0f32, 0.0f32);
    for (k, s) in gpu.chunks(2).enumerate() {
        worst = worst.max((s[0].light - s[1].light).abs().max_element());
        let (a, b) = (
            &sky[owner_of(pairs[2 * k])],
            &sky[owner_of(pairs[2 * k + 1])],
        );
        let alone = |g: &LightGrid, p: Vec3| g.sample(p).unwrap().total().max_element();
        jump = jump.max((alone(a, pairs[2 * k]) - alone(b, pairs[2 * k + 1])).abs());
    }
    assert!(
        worst < 0.01 * jump,
        "largest step {worst}, the owners' reads alone {jump}"
    );
}
