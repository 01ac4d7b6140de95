//! The benchmark's scenes: sweep-cpu's five canonical scenes, a line source, a lattice
//! (checkerboard absorber) and a forest composed from a real model over terrain.

use std::path::Path;

use anyhow::{Context, Result};
use lightgrid_core::glam::{Quat, UVec3, Vec2, Vec3};
use lightgrid_core::{
    Boundary, GridDesc, Material, MaterialGrid, MaterialSource, SideBoundary, TopBoundary,
};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundColour, Heightmap, Instance, Terrain,
};
use lightgrid_material_voxelizer::model::Model;
use lightgrid_material_voxelizer::procedural::{TreeParams, tree};
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};
use lightgrid_measure::scenes::{Scene, sky_and_sun};

/// A benchmark problem: material and boundary light.
pub struct BenchScene {
    /// Short name.
    pub name: String,
    /// One line on what it tests.
    pub about: String,
    /// Cells.
    pub material: MaterialGrid,
    /// Light entering.
    pub boundary: Boundary,
}

/// Every scene at `n` cells a side (the forest reads `assets` if present).
pub fn all(n: u32, assets: &Path) -> Result<Vec<BenchScene>> {
    let mut v: Vec<BenchScene> = Scene::ALL
        .iter()
        .map(|s| {
            let (material, boundary) = s.build(n);
            BenchScene {
                name: s.name().replace(' ', "-"),
                about: "sweep-cpu canonical scene".into(),
                material,
                boundary,
            }
        })
        .collect();
    v.push(line_source(n));
    v.push(lattice(n));
    v.push(forest(n, assets)?);
    Ok(v)
}

/// A slit of sky light: a black opaque roof over the whole grid with one open row
/// (x = n/2) lets the sky and sun in along a line, into a scattering fog with open
/// sides. Tests how a narrow source spreads (the ray effects of few directions).
pub fn line_source(n: u32) -> BenchScene {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(n)).expect("valid");
    let cells = (0..desc.point_count())
        .map(|i| {
            let p = desc.coords(i).expect("in range");
            if p.y == n - 1 && p.x != n / 2 {
                Material {
                    reflectance: Vec3::ZERO,
                    pass: 0.0,
                }
            } else {
                Material {
                    reflectance: Vec3::splat(0.9),
                    pass: 0.7,
                }
            }
        })
        .collect();
    BenchScene {
        name: "line-source".into(),
        about: "sky and sun through a slit in a black roof, into a scattering fog".into(),
        material: MaterialGrid::new(desc, cells).expect("valid"),
        boundary: Boundary {
            sides: SideBoundary::Open,
            ..sky_and_sun()
        },
    }
}

/// The lattice problem (after Brunner): a 3D checkerboard of strong absorbers (pass 0.02,
/// black) and scatterers (pass 0.8, albedo 0.95) in blocks of n/8 cells, lit by the sky
/// and sun, periodic sides.
pub fn lattice(n: u32) -> BenchScene {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(n)).expect("valid");
    let block = (n / 8).max(1);
    let cells = (0..desc.point_count())
        .map(|i| {
            let p = desc.coords(i).expect("in range") / block;
            if (p.x + p.y + p.z).is_multiple_of(2) {
                Material {
                    reflectance: Vec3::ZERO,
                    pass: 0.02,
                }
            } else {
                Material {
                    reflectance: Vec3::splat(0.95),
                    pass: 0.8,
                }
            }
        })
        .collect();
    BenchScene {
        name: "lattice".into(),
        about: "checkerboard of absorbers and scatterers, periodic".into(),
        material: MaterialGrid::new(desc, cells).expect("valid"),
        boundary: Boundary {
            sides: SideBoundary::Periodic,
            ..sky_and_sun()
        },
    }
}

/// A forest on rolling ground: the shipped Kenney `grass-trees.glb` (a real CC0 model;
/// a procedural broadleaf tree where the test data is missing), 0.25 m voxels, scattered
/// over an `n × n` m area of 1 m cells, lit by the sky and sun, periodic sides.
pub fn forest(n: u32, assets: &Path) -> Result<BenchScene> {
    let path = assets.join("kenney-city-builder/grass-trees.glb");
    let (model, source) = if path.exists() {
        (
            Model::load_gltf(&path).with_context(|| format!("{}", path.display()))?,
            "Kenney grass-trees.glb",
        )
    } else {
        (
            tree(&TreeParams::young(3))?,
            "procedural tree (test data missing)",
        )
    };
    let (grid, _) = voxelize(&model, &VoxelizeParams::standard(0.25), &|_, _| {})?;
    let size = n as f32;
    let heightmap = Heightmap::from_fn(Vec2::ZERO, 1.0, n + 1, n + 1, |x, z| {
        1.5 + 0.8 * (x * 0.31).sin() * (z * 0.23).cos()
    })?;
    let mut r = fastrand::Rng::with_seed(7);
    let mut rng = move || r.f32();
    let count = (n * n / 12).max(4);
    let instances: Vec<Instance> = (0..count)
        .map(|_| {
            let (x, z) = (rng() * size, rng() * size);
            Instance {
                model: 0,
                position: Vec3::new(x, heightmap.height_at(x, z) - 0.1, z),
                rotation: Quat::from_rotation_y(rng() * std::f32::consts::TAU),
                scale: 3.0 + 2.0 * rng(),
            }
        })
        .collect();
    let composer = AreaComposer::new(
        vec![grid],
        &instances,
        Some(Terrain {
            heightmap,
            colour: GroundColour::Uniform(Vec3::new(0.25, 0.22, 0.15)),
        }),
        ComposeParams::default(),
    )?;
    let desc = GridDesc::new(Vec3::new(0.0, 0.0, 0.0), 1.0, UVec3::splat(n))?;
    Ok(BenchScene {
        name: "forest".into(),
        about: format!("{count} instances of {source} on rolling ground"),
        material: composer.material(&desc)?,
        boundary: Boundary {
            sides: SideBoundary::Periodic,
            ..sky_and_sun()
        },
    })
}

/// The scene at half the resolution (cells of 2 h): each coarse cell's pass-through is
/// the squared mean of its 8 fine cells' (a path of 2 h through the mean medium), its
/// reflectance the density-weighted mean; the boundary is resampled the same way.
pub fn coarsen(s: &BenchScene) -> Result<BenchScene> {
    let d = *s.material.desc();
    let dims = (d.dims() + UVec3::ONE) / 2;
    let cd = GridDesc::new(d.origin() + Vec3::splat(0.5 * d.h()), 2.0 * d.h(), dims)?;
    let cells = (0..cd.point_count())
        .map(|i| {
            let c = cd.coords(i).expect("in range");
            let (mut pass, mut refl, mut dens, mut k) = (0.0, Vec3::ZERO, 0.0, 0.0);
            for o in 0..8u32 {
                let f = c * 2 + UVec3::new(o & 1, (o >> 1) & 1, (o >> 2) & 1);
                if let Some(m) = s.material.get(f) {
                    pass += m.pass;
                    refl += m.reflectance * (1.0 - m.pass);
                    dens += 1.0 - m.pass;
                    k += 1.0;
                }
            }
            let pass = pass / k;
            Material {
                reflectance: if dens > 0.0 { refl / dens } else { Vec3::ZERO },
                pass: pass * pass,
            }
        })
        .collect();
    let top = match &s.boundary.top {
        TopBoundary::Uniform(b) => TopBoundary::Uniform(b.clone()),
        TopBoundary::PerPoint(v) => {
            let (nx, cnx) = (d.dims().x, dims.x);
            TopBoundary::PerPoint(
                (0..dims.x * dims.z)
                    .map(|i| {
                        let (x, z) = ((i % cnx) * 2, (i / cnx) * 2);
                        v[(x + nx * z.min(d.dims().z - 1)) as usize]
                    })
                    .collect(),
            )
        }
    };
    Ok(BenchScene {
        name: s.name.clone(),
        about: s.about.clone(),
        material: MaterialGrid::new(cd, cells)?,
        boundary: Boundary {
            top,
            bottom: s.boundary.bottom,
            sides: match &s.boundary.sides {
                SideBoundary::Given(_) | SideBoundary::GivenHalves { .. } => SideBoundary::Open,
                o => o.clone(),
            },
        },
    })
}
