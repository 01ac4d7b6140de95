//! Grid points inside geometry, and the light they are given for lookups.
//!
//! A grid point whose cell is opaque (or mostly so) holds the light of the inside of a
//! solid: next to nothing. A trilinear lookup on the solid's surface, half way between
//! that point and the lit one above it, then reads about half the light there (the
//! canopy scene's ground: 0.73 inside, 89.2 above, 45 read on the surface). Engines
//! mark such probes invalid and give them their valid neighbours' light (Unity's
//! adaptive probe volumes: validity and dilation; DDGI: probe relocation). Here:
//!
//! - a point is **invalid** where its cell lets less than [`MIN_VALID_PASS`] of the
//!   light through ([`valid_points`]);
//! - [`fill_invalid`] gives each invalid point the mean of its valid neighbours among
//!   the 26 around it, in rounds, so that a point one layer deeper takes the mean of
//!   the points filled the round before. Valid points never change, so a lookup whose
//!   eight corners are valid reads what it read before.
//!
//! The same rule serves exports (`lightgrid-export`, `lightgrid bake`, the viewer's
//! `--bevy`) and the renderer's light volume read from the hierarchy on the CPU
//! (`lightgrid-terrain-lod`'s volume sampler fills each grid's reduced light with it;
//! the GPU sampling path does not yet, nor do the terrain's vertices, which read half a
//! cell along their normal).
//!
//! ```
//! use lightgrid_core::{validity, BinLight, GridDesc, LightGrid, Material, MaterialGrid};
//! use lightgrid_core::glam::{UVec3, Vec3};
//!
//! // Two levels: opaque ground below, air above lit by a uniform sky.
//! let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(3, 2, 3)).unwrap();
//! let cells = (0..desc.point_count())
//!     .map(|i| if i < 9 { Material::opaque(Vec3::splat(0.3)) } else { Material::EMPTY })
//!     .collect();
//! let material = MaterialGrid::new(desc, cells).unwrap();
//! let sky = BinLight::uniform(Vec3::ONE);
//! let mut light = LightGrid::filled(desc, BinLight::ZERO).unwrap();
//! for x in 0..3 { for z in 0..3 { light.set(UVec3::new(x, 1, z), sky).unwrap(); } }
//! let valid = validity::valid_points(&material);
//! let stats = validity::fill_invalid(&mut light, &valid, validity::DEFAULT_ROUNDS).unwrap();
//! assert_eq!(stats.filled, 9);
//! // The ground points take the sky of the points above them.
//! let filled = light.get(UVec3::new(1, 0, 1)).unwrap().average();
//! assert!((filled - sky.average()).abs().max_element() < 1e-6);
//! ```

use crate::{GridError, MaterialGrid};
use glam::IVec3;

use crate::grid::Grid;

/// Pass-through below which a cell's point is invalid: the cell stops more than half of
/// what crosses it, so its point holds mostly the light of the inside.
pub const MIN_VALID_PASS: f32 = 0.5;

/// Rounds of [`fill_invalid`] the library uses: enough for every lookup near a surface
/// (its corners lie one point deep at most) and for thin walls two points thick.
pub const DEFAULT_ROUNDS: u32 = 2;

/// Whether each point of `material` is valid (its cell's pass-through is at least
/// [`MIN_VALID_PASS`]), in the grid's point order.
pub fn valid_points(material: &MaterialGrid) -> Vec<bool> {
    material
        .data()
        .iter()
        .map(|m| m.pass >= MIN_VALID_PASS)
        .collect()
}

/// What [`fill_invalid`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FillStats {
    /// Invalid points given their neighbours' light.
    pub filled: u64,
    /// Invalid points no valid point reached within the rounds: they keep their light.
    pub left: u64,
    /// Rounds run (fewer than asked where every point was reached).
    pub rounds: u32,
}

/// Gives every invalid point of `grid` the mean of its valid neighbours (the 26 around
/// it), in up to `rounds` rounds: a point filled in one round counts as valid in the
/// next. Valid points are left as they are, bit for bit. `valid` holds one flag per
/// point ([`valid_points`]). The mean of finite values is finite: nothing non-finite
/// comes out of a grid that held none.
pub fn fill_invalid<T>(
    grid: &mut Grid<T>,
    valid: &[bool],
    rounds: u32,
) -> Result<FillStats, GridError>
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<f32, Output = T> + Default,
{
    let desc = *grid.desc();
    if valid.len() != desc.point_count() {
        return Err(GridError::invalid(
            "valid.len()",
            valid.len(),
            "must equal the grid's point count",
        ));
    }
    let dims = desc.dims().as_ivec3();
    let mut ok = valid.to_vec();
    let mut stats = FillStats::default();
    let mut pending: Vec<usize> = (0..ok.len()).filter(|&i| !ok[i]).collect();
    for _ in 0..rounds {
        if pending.is_empty() {
            break;
        }
        stats.rounds += 1;
        let data = grid.data();
        let fills: Vec<(usize, T)> = pending
            .iter()
            .filter_map(|&i| {
                let q = desc.coords(i).expect("index in range").as_ivec3();
                let mut sum = T::default();
                let mut n = 0u32;
                for dz in -1..=1 {
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            let p = q + IVec3::new(dx, dy, dz);
                            if (dx, dy, dz) == (0, 0, 0)
                                || p.cmplt(IVec3::ZERO).any()
                                || p.cmpge(dims).any()
                            {
                                continue;
                            }
                            let j = desc.index_unchecked(p.as_uvec3());
                            if ok[j] {
                                sum = sum + data[j];
                                n += 1;
                            }
                        }
                    }
                }
                (n > 0).then(|| (i, sum * (1.0 / n as f32)))
            })
            .collect();
        if fills.is_empty() {
            break;
        }
        for &(i, v) in &fills {
            grid.data_mut()[i] = v;
            ok[i] = true;
        }
        stats.filled += fills.len() as u64;
        pending.retain(|&i| !ok[i]);
    }
    stats.left = pending.len() as u64;
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BinLight, GridDesc, LightGrid, Material};
    use glam::{UVec3, Vec3};

    fn slab(levels_solid: u32) -> (MaterialGrid, LightGrid) {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 5, 4)).unwrap();
        let cells = (0..desc.point_count())
            .map(|i| {
                if desc.coords(i).unwrap().y < levels_solid {
                    Material::opaque(Vec3::splat(0.3))
                } else {
                    Material::EMPTY
                }
            })
            .collect();
        let m = MaterialGrid::new(desc, cells).unwrap();
        // Light growing with height and varying across: valid points differ.
        let light = Grid::from_trusted(
            desc,
            (0..desc.point_count())
                .map(|i| {
                    let q = desc.coords(i).unwrap().as_vec3();
                    BinLight::uniform(Vec3::new(1.0 + q.y, 2.0 + q.x, 3.0 + q.z))
                        * if q.y < levels_solid as f32 { 0.01 } else { 1.0 }
                })
                .collect(),
        );
        (m, light)
    }

    #[test]
    fn valid_points_leave_light_as_it_was_and_the_first_layer_takes_its_neighbours() {
        let (m, mut light) = slab(2);
        let before = light.clone();
        let valid = valid_points(&m);
        let s = fill_invalid(&mut light, &valid, DEFAULT_ROUNDS).unwrap();
        assert_eq!(s.filled, 32);
        assert_eq!(s.left, 0);
        for (i, ok) in valid.iter().enumerate() {
            if *ok {
                assert_eq!(light.data()[i], before.data()[i]);
            }
        }
        // The top solid layer (y = 1): the mean of the valid points above it (y = 2).
        let q = UVec3::new(1, 1, 2);
        let mut want = BinLight::ZERO;
        let mut n = 0;
        for dx in -1i32..=1 {
            for dz in -1i32..=1 {
                let p = UVec3::new((1 + dx) as u32, 2, (2 + dz) as u32);
                want += *before.get(p).unwrap();
                n += 1;
            }
        }
        let got = *light.get(q).unwrap();
        assert!(
            (got.0[0] - want.0[0] * (1.0 / n as f32))
                .abs()
                .max_element()
                < 1e-5
        );
    }

    #[test]
    fn deeper_layers_need_more_rounds() {
        let (m, mut light) = slab(3);
        let valid = valid_points(&m);
        let s = fill_invalid(&mut light, &valid, 1).unwrap();
        assert_eq!((s.filled, s.left, s.rounds), (16, 32, 1));
        let s = fill_invalid(&mut light, &valid, 5).unwrap();
        assert_eq!((s.filled, s.left, s.rounds), (48, 0, 3));
        // All solid: nothing to take from; the light stays.
        let (m, mut light) = slab(5);
        let before = light.clone();
        let s = fill_invalid(&mut light, &valid_points(&m), 5).unwrap();
        assert_eq!((s.filled, s.left), (0, 80));
        assert_eq!(light, before);
        // A wrong mask is an error naming it.
        let e = fill_invalid(&mut light, &[true; 3], 1).unwrap_err();
        assert!(e.to_string().contains("valid.len()"), "{e}");
    }

    #[test]
    fn mostly_opaque_cells_are_invalid() {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(3, 1, 1)).unwrap();
        let cells = [0.0, 0.49, 0.5]
            .map(|pass| Material {
                reflectance: Vec3::splat(0.5),
                pass,
            })
            .to_vec();
        let m = MaterialGrid::new(desc, cells).unwrap();
        assert_eq!(valid_points(&m), vec![false, false, true]);
        // A scalar grid (the sun's transmittance) fills the same way.
        let mut t: Grid<f32> = Grid::from_trusted(desc, vec![0.0, 0.1, 0.8]);
        fill_invalid(&mut t, &valid_points(&m), 2).unwrap();
        assert_eq!(t.data(), &[0.8, 0.8, 0.8]);
    }
}
