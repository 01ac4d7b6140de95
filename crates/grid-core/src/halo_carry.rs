//! The halo's light carried through its cells' material
//! ([`SideBoundary::halo_cells`]).
//!
//! A halo point's value is its cell's mean light, as a grid's points hold theirs; a
//! sweep gathers it as the light its paths carry out of the point, as if the cell were
//! empty. Where the caller gives the halo's cells, each value is carried before the
//! sweep: through the rest of its own cell and through the halo's cells after it on
//! its bin's path within its level ([`dirs::level_stencil`]'s cells beyond the grid:
//! a horizontal bin's own and up to two more, any other's own alone), as a sweep
//! carries the paths of the grid's points (`lightgrid-sweep-cpu`'s phase 3). A
//! segment of transmittance `T` (optical depth `τ`, mean `g = (1 − T)/τ`) whose medium
//! emits `S` turns a mean `M` into the light leaving it, `S + (M − S) T / g`, and light
//! `v` entering it into `v T + S (1 − T)`. A medium's `S` is its albedo's share of its
//! cell's mean light over the sphere (the halo point's `average`), spread as a uniform
//! sky's (half of a horizontal bin's to its downward half): exact in a white furnace,
//! where the light is unchanged. The grid's own cells are left to the grid (the paths
//! the halo's points send through them, [`SweepOptions::halo_paths`](crate::SweepOptions));
//! opaque and empty cells
//! leave the light as it is (an opaque cell's halo value is a surface's light, which
//! leaves over its level-mates).
//!
//! The sweepers sweep the carried boundary ([`carried_boundary`]: a copy); a caller
//! that owns its boundary carries it in place first ([`carry_halo`]), and no copy is
//! made.

use std::borrow::Cow;
use std::sync::OnceLock;

use glam::{UVec3, Vec3};

use crate::dirs::{self, NUM_DIRS};
use crate::light::seg_mean;
use crate::{BinLight, Boundary, HALO_WIDTH, HaloLayout, HorizonLight, Material, SideBoundary};

/// `boundary` with its halo's light carried through its given cells ([`carry_halo`]);
/// `boundary` itself where none are given.
pub fn carried_boundary(boundary: &Boundary, dims: UVec3) -> Cow<'_, Boundary> {
    if boundary.sides.halo_cells().is_none() {
        return Cow::Borrowed(boundary);
    }
    let mut b = boundary.clone();
    carry_halo(&mut b, dims);
    Cow::Owned(b)
}

/// Carries the halo's light and downward halves of `boundary` (around a grid of
/// `dims` points) through its given cells, in place, and leaves no cells given (the
/// module's docs). A bin no point of the grid gathers from a halo point (one whose
/// step across a level leads from it to no point of the grid or beside one) keeps its
/// value. Nothing where no cells are given, or where the halo's lengths do
/// not fit `dims` (which [`Boundary::validate`] refuses).
pub fn carry_halo(boundary: &mut Boundary, dims: UVec3) {
    let SideBoundary::GivenHalves { light, down, cells } = &mut boundary.sides else {
        return;
    };
    let Some(c) = cells.take() else {
        return;
    };
    let layout = HaloLayout::new(dims);
    let n = layout.len();
    if c.len() != n || light.len() != n || down.len() != n || n == 0 {
        *cells = Some(c);
        return;
    }
    let per_level = layout.per_level();
    let paths = bin_paths();
    let mut scratch = Scratch::new(dims, paths);
    for ((l, d), c) in light
        .chunks_mut(per_level)
        .zip(down.chunks_mut(per_level))
        .zip(c.chunks(per_level))
    {
        carry_level(paths, &mut scratch, (l, d), c);
    }
}

/// Distinct path lengths through one cell (in `h`) of the bins' paths.
const MAX_LENGTHS: usize = 16;

/// The bins' paths through a level: per bin, `(dx, dz, length index)` of each cell it
/// crosses from its point's own (the own cell's first), and the distinct lengths.
struct BinPaths {
    paths: [Vec<(i32, i32, usize)>; NUM_DIRS],
    lengths: Vec<f32>,
    /// Each bin's step across a level in x and z: a grid point gathers it from the
    /// point one step back (and that point's four neighbours, the smoothing's taps).
    steps: [(i32, i32); NUM_DIRS],
}

/// The [`BinPaths`] of [`dirs::level_stencil`] and [`dirs::bin_channel_length`].
fn bin_paths() -> &'static BinPaths {
    static PATHS: OnceLock<BinPaths> = OnceLock::new();
    PATHS.get_or_init(|| {
        let mut lengths: Vec<f32> = Vec::new();
        let paths = std::array::from_fn(|d| {
            let stencil = dirs::level_stencil(dirs::dir_ivec(d));
            let kc = stencil
                .iter()
                .position(|t| t.0 == 0 && t.1 == 0)
                .expect("a stencil holds its own cell");
            stencil[kc..]
                .iter()
                .map(|&(dx, dz, f)| {
                    let l = f * dirs::bin_channel_length(d);
                    let k = match lengths.iter().position(|x| (x - l).abs() < 1e-6) {
                        Some(k) => k,
                        None => {
                            lengths.push(l);
                            lengths.len() - 1
                        }
                    };
                    (dx, dz, k)
                })
                .collect()
        });
        assert!(lengths.len() <= MAX_LENGTHS, "more path lengths than kept");
        let steps = std::array::from_fn(|d| {
            let v = dirs::dir_ivec(d);
            let s = if v.y == 0 { dirs::HORIZONTAL_STEP } else { 1 };
            (v.x * s, v.z * s)
        });
        BinPaths {
            paths,
            lengths,
            steps,
        }
    })
}

/// A medium cell of a level's halo, as the carry reads it: what it lets through along
/// each path exponent, the share of a mean that leaves it along each, and its source
/// radiance over the sphere.
#[derive(Clone, Copy)]
struct HaloMedium {
    pass: [f32; MAX_LENGTHS],
    mean_out: [f32; MAX_LENGTHS],
    source: Vec3,
}

/// A cell's transmittances and mean-to-exit shares along each path length, by its
/// pass-through's bits: composed media hold few distinct values (a direct-mapped cache
/// of [`SEEN`] entries; a miss recomputes).
type Seen = Vec<(u32, [f32; MAX_LENGTHS], [f32; MAX_LENGTHS])>;

/// Entries of [`Seen`].
const SEEN: usize = 64;

impl HaloMedium {
    fn of(m: &Material, light: &BinLight, lengths: &[f32], seen: &mut Seen) -> Option<Self> {
        if !(m.pass > 0.0 && m.pass < 1.0) {
            return None;
        }
        let bits = m.pass.to_bits();
        let slot = (bits.wrapping_mul(0x9E37_79B9) >> 26) as usize % SEEN;
        if seen.len() < SEEN {
            seen.resize(SEEN, (u32::MAX, [0.0; MAX_LENGTHS], [0.0; MAX_LENGTHS]));
        }
        if seen[slot].0 != bits {
            let lnp = m.pass.ln();
            let (mut pass, mut mean_out) = ([1.0; MAX_LENGTHS], [1.0; MAX_LENGTHS]);
            for ((p, o), &e) in pass.iter_mut().zip(&mut mean_out).zip(lengths) {
                let t = (e * lnp).exp();
                *p = t;
                *o = t / seg_mean(t, -e * lnp);
            }
            seen[slot] = (bits, pass, mean_out);
        }
        let (_, pass, mean_out) = seen[slot];
        Some(Self {
            pass,
            mean_out,
            source: m.reflectance * light.average(),
        })
    }
}

/// Cells of the media square beyond the halo's on each side: a path's cells lie
/// within two cells of its point along x and z (`dirs::level_stencil`), so no look-up
/// leaves the square.
const PAD: i32 = 2;

/// A halo point's place in the media square, and the bins a grid point gathers from it
/// (bit `d`).
#[derive(Clone, Copy)]
struct Column {
    at: usize,
    gathered: u32,
}

/// What [`carry_level`] keeps between levels: the media square (each cell's medium, an
/// index into `media`, [`NONE`] where it is none; the halo's square and [`PAD`] cells
/// beyond it), the level's media, and what is the same at every level: the halo's
/// points' places and gathered bins, and the bins' paths as offsets in the square.
struct Scratch {
    square: Vec<u32>,
    /// The square's width (cells along x).
    width: usize,
    media: Vec<HaloMedium>,
    /// The halo's points, in the layout's order within a level.
    columns: Vec<Column>,
    /// Per bin, `(offset in the square, length index)` of each cell its path crosses
    /// from its point's own.
    offsets: [Vec<(isize, usize)>; NUM_DIRS],
    /// Whether a medium lies within two cells (in x and z) of each cell of the square.
    near: Vec<bool>,
    /// `near` along x alone.
    near_x: Vec<bool>,
    seen: Seen,
}

/// No medium in [`Scratch::square`].
const NONE: u32 = u32::MAX;

impl Scratch {
    fn new(dims: UVec3, paths: &BinPaths) -> Self {
        let (w, nx, nz) = (HALO_WIDTH, dims.x as i32, dims.z as i32);
        let width = (nx + 2 * w + 2 * PAD) as usize;
        let depth = (nz + 2 * w + 2 * PAD) as usize;
        let inside = |x: i32, z: i32| (0..nx).contains(&x) && (0..nz).contains(&z);
        let mut columns = Vec::new();
        for z in -w..nz + w {
            for x in (-w..nx + w).filter(|&x| !inside(x, z)) {
                // A value no grid point gathers is left as it is: the grid's points
                // one step on from it (and their neighbours) lie beyond the grid.
                let mut gathered = 0u32;
                for (d, &(sx, sz)) in paths.steps.iter().enumerate() {
                    let (gx, gz) = (x + sx, z + sz);
                    if ((-1..=nx).contains(&gx) && (0..nz).contains(&gz))
                        || ((0..nx).contains(&gx) && (-1..=nz).contains(&gz))
                    {
                        gathered |= 1 << d;
                    }
                }
                let at = (z + w + PAD) as usize * width + (x + w + PAD) as usize;
                columns.push(Column { at, gathered });
            }
        }
        let offsets = std::array::from_fn(|d| {
            paths.paths[d]
                .iter()
                .map(|&(dx, dz, e)| {
                    debug_assert!(dx.abs() <= PAD && dz.abs() <= PAD);
                    (dz as isize * width as isize + dx as isize, e)
                })
                .collect()
        });
        Self {
            square: vec![NONE; width * depth],
            width,
            media: Vec::new(),
            columns,
            offsets,
            near: vec![false; width * depth],
            near_x: vec![false; width * depth],
            seen: Vec::new(),
        }
    }
}

/// [`carry_halo`] over one level's halo points (`light`, `down`, `cells` in the
/// layout's order).
fn carry_level(
    paths: &BinPaths,
    scratch: &mut Scratch,
    (light, down): (&mut [BinLight], &mut [HorizonLight]),
    cells: &[Material],
) {
    let Scratch {
        square,
        width,
        media,
        columns,
        offsets,
        near,
        near_x,
        seen,
    } = scratch;
    let width = *width;
    // The level's medium cells on the halo's square, found before any value is
    // carried (their sources read the means). (The square holds no medium inside the
    // grid, nor beyond the halo: those cells are the grid's, or none.)
    square.fill(NONE);
    media.clear();
    for (i, c) in columns.iter().enumerate() {
        if let Some(m) = HaloMedium::of(&cells[i], &light[i], &paths.lengths, seen) {
            square[c.at] = media.len() as u32;
            media.push(m);
        }
    }
    if media.is_empty() {
        return;
    }
    // A point none of whose paths' cells holds a medium keeps its light: found by
    // widening the media by two cells along x, then along z (sliding counts of media
    // over five cells).
    let depth = square.len() / width;
    for r in 0..depth {
        let row = &square[r * width..][..width];
        let mut count = row[..2.min(width)].iter().filter(|&&m| m != NONE).count();
        for c in 0..width {
            if c + 2 < width {
                count += (row[c + 2] != NONE) as usize;
            }
            if c >= 3 {
                count -= (row[c - 3] != NONE) as usize;
            }
            near_x[r * width + c] = count > 0;
        }
    }
    for c in 0..width {
        let at = |q: usize| near_x[q * width + c] as usize;
        let mut count: usize = (0..2.min(depth)).map(at).sum();
        for r in 0..depth {
            if r + 2 < depth {
                count += at(r + 2);
            }
            if r >= 3 {
                count -= at(r - 3);
            }
            near[r * width + c] = count > 0;
        }
    }
    let omega = dirs::solid_angles();
    let horizontal = dirs::FIRST_HORIZONTAL..dirs::FIRST_HORIZONTAL + dirs::HORIZONTAL_BINS;
    for (i, c) in columns.iter().enumerate() {
        if !near[c.at] {
            continue;
        }
        // Without a medium in its own cell, only the horizontal bins' paths cross
        // others.
        let bins = if square[c.at] != NONE {
            0..NUM_DIRS
        } else {
            horizontal.clone()
        };
        for d in bins.filter(|&d| c.gathered & (1 << d) != 0) {
            let h = horizontal.contains(&d).then(|| d - dirs::FIRST_HORIZONTAL);
            let (mut v, mut half) = (light[i].0[d], h.map(|k| down[i].0[k]));
            let mut changed = false;
            for (k, &(off, e)) in offsets[d].iter().enumerate() {
                let q = square[(c.at as isize + off) as usize];
                let Some(m) = media.get(q as usize) else {
                    continue;
                };
                let s = m.source * omega[d];
                // The own cell: from its mean to where the path leaves it.
                let keep = if k == 0 { m.mean_out[e] } else { m.pass[e] };
                let add = 1.0 - keep;
                v = v * keep + s * add;
                half = half.map(|h| h * keep + s * (0.5 * add));
                changed = true;
            }
            if changed {
                light[i].0[d] = v.max(Vec3::ZERO);
                if let (Some(k), Some(hv)) = (h, half) {
                    down[i].0[k] = hv.max(Vec3::ZERO);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DIMS: UVec3 = UVec3::new(12, 3, 10);

    /// A boundary of `light` at every halo point (downward halves even) and `cell` in
    /// every halo cell.
    fn given(light: BinLight, cell: Material) -> Boundary {
        let n = HaloLayout::new(DIMS).len();
        Boundary {
            sides: SideBoundary::GivenHalves {
                light: vec![light; n],
                down: vec![HorizonLight::even(&light); n],
                cells: Some(vec![cell; n]),
            },
            ..Boundary::open_sky(BinLight::ZERO)
        }
    }

    fn carried(b: &Boundary) -> Boundary {
        let mut c = b.clone();
        carry_halo(&mut c, DIMS);
        assert!(c.sides.halo_cells().is_none(), "the cells are consumed");
        c
    }

    /// Bins that differ from bin to bin and colour to colour.
    fn varied() -> BinLight {
        BinLight(std::array::from_fn(|d| {
            Vec3::new(0.2, 0.3, 0.4) * (1 + (d * 7) % 11) as f32
        }))
    }

    fn medium(albedo: f32, pass: f32) -> Material {
        Material {
            reflectance: Vec3::splat(albedo),
            pass,
        }
    }

    #[test]
    fn a_white_furnace_is_left_as_it_is() {
        let light = BinLight::uniform(Vec3::new(0.5, 1.0, 2.0));
        for pass in [0.01, 0.3, 0.9, 0.999] {
            let b = given(light, medium(1.0, pass));
            let c = carried(&b);
            let (h, d) = (c.sides.halo().unwrap(), c.sides.halo_down().unwrap());
            for (got, want) in h.iter().flat_map(|l| l.0).zip(light.0.iter().cycle()) {
                assert!(
                    (got - *want).abs().max_element() <= 2e-6 * want.max_element(),
                    "{pass}: {got} against {want}"
                );
            }
            let even = HorizonLight::even(&light);
            for got in d {
                for (g, w) in got.0.iter().zip(even.0) {
                    assert!(
                        (*g - w).abs().max_element() <= 2e-6 * w.max_element(),
                        "{pass}: half {g} against {w}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_dark_cell_lets_out_its_mean_times_t_over_g() {
        let (pass, m) = (0.4f32, varied());
        let c = carried(&given(m, medium(0.0, pass)));
        let layout = HaloLayout::new(DIMS);
        let h = c.sides.halo().unwrap();
        // Straight down, beside the grid's -x side: its own cell alone.
        let i = layout.index(-1, 1, 4).unwrap();
        let tau = -pass.ln() * dirs::bin_channel_length(dirs::DOWN);
        let t = (-tau).exp();
        let want = m.0[dirs::DOWN] * (tau * t / (1.0 - t));
        let got = h[i].0[dirs::DOWN];
        assert!(
            (got - want).abs().max_element() <= 1e-6,
            "{got} against {want}"
        );
        // Along +x from three cells out: its own cell's mean out, then two more cells.
        let d = dirs::dir_index(glam::IVec3::new(1, 0, 0)).unwrap();
        let l = dirs::bin_channel_length(d);
        let i = layout.index(-3, 1, 4).unwrap();
        let (tau, t2, t1) = (
            -pass.ln() * 0.25 * l,
            pass.powf(0.25 * l),
            pass.powf(0.125 * l),
        );
        let own = (-tau).exp();
        let want = m.0[d] * (tau * own / (1.0 - own)) * t2 * t1;
        let got = h[i].0[d];
        assert!(
            (got - want).abs().max_element() <= 1e-5 * want.max_element(),
            "{got} against {want}"
        );
    }

    #[test]
    fn light_no_grid_point_gathers_keeps_its_value() {
        let m = varied();
        let c = carried(&given(m, medium(0.0, 0.2)));
        let layout = HaloLayout::new(DIMS);
        // Straight down five cells out: no grid point gathers it (nor along -x).
        let i = layout.index(-5, 0, 4).unwrap();
        let h = &c.sides.halo().unwrap()[i];
        assert_eq!(h.0[dirs::DOWN], m.0[dirs::DOWN]);
        let d = dirs::dir_index(glam::IVec3::new(-1, 0, 0)).unwrap();
        assert_eq!(h.0[d], m.0[d]);
        // Along +x it is gathered, and darkened.
        let d = dirs::dir_index(glam::IVec3::new(1, 0, 0)).unwrap();
        assert!(h.0[d].max_element() < 0.5 * m.0[d].max_element());
    }

    #[test]
    fn empty_opaque_or_no_cells_change_nothing() {
        let m = varied();
        for cell in [Material::EMPTY, Material::opaque(Vec3::splat(0.5))] {
            let b = given(m, cell);
            let c = carried(&b);
            assert_eq!(c.sides.halo(), b.sides.halo());
            assert_eq!(c.sides.halo_down(), b.sides.halo_down());
        }
        let mut b = given(m, medium(0.5, 0.5));
        if let SideBoundary::GivenHalves { cells, .. } = &mut b.sides {
            *cells = None;
        }
        assert_eq!(carried(&b), b);
        assert!(matches!(carried_boundary(&b, DIMS), Cow::Borrowed(_)));
    }

    #[test]
    fn the_carry_is_linear_in_the_light() {
        let m = varied();
        let cell = medium(0.7, 0.35);
        let one = carried(&given(m, cell));
        let three = carried(&given(m.scaled(3.0), cell));
        for (a, b) in one
            .sides
            .halo()
            .unwrap()
            .iter()
            .zip(three.sides.halo().unwrap())
        {
            for (x, y) in a.0.iter().zip(b.0) {
                assert!((*x * 3.0 - y).abs().max_element() <= 1e-5 * y.max_element().max(1e-6));
            }
        }
    }
}
