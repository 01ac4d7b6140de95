//! Grid types: one generic [`Grid`] of per-point values, and the value types it holds.
//!
//! | grid | value | bytes per point | use |
//! |------|-------|-----------------|-----|
//! | [`MaterialGrid`] | [`Material`]: reflectance RGB + pass-through | 16 | input of the sweep |
//! | [`LightGrid`] | [`BinLight`]: 26 bins RGB `f32` | 312 | exact work format, files |
//! | [`PackedLightGrid`] | [`PackedBins`]: 26 × R11G11B10 + one exposure per grid | 104 | what a renderer keeps |
//! | [`AverageGrid`] | [`AverageLight`]: mean light RGB | 12 (4 packed) | vegetation, far objects |
//! | [`DominantGrid`] | [`DominantDir`]: vector, length = sharpness | 12 | per-frame lighting of moving objects |

use glam::Vec3;

use crate::error::check_range;
use crate::light::BinLight;
use crate::pack;
use crate::{GridDesc, GridError, NUM_DIRS};

/// A value stored per grid point: it knows how to validate itself and how it is encoded in
/// grid files.
pub trait GridValue: Copy + Send + Sync + 'static {
    /// The file kind of a grid of these values.
    const KIND: crate::file::GridKind;
    /// Bytes per point in files.
    const FILE_BYTES: usize;
    /// `Ok` when the value may enter a grid; otherwise the reason, for an error naming
    /// the element.
    fn check(&self) -> Result<(), (&'static str, String, &'static str)>;
    /// Whether every one of `values` passes [`GridValue::check`]: a type may answer
    /// faster than value by value (the default asks each).
    fn all_valid(values: &[Self]) -> bool {
        values.iter().all(|v| v.check().is_ok())
    }
    /// Appends the little-endian file encoding.
    fn write_le(&self, out: &mut Vec<u8>);
    /// Reads the value from exactly [`Self::FILE_BYTES`] bytes.
    fn read_le(bytes: &[u8]) -> Self;
}

/// A regular grid of per-point values, laid out as [`GridDesc`] says.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid<T> {
    desc: GridDesc,
    data: Vec<T>,
}

impl<T: GridValue> Grid<T> {
    /// A grid from its values, each validated: errors name the element
    /// (`data[17].pass = NaN: must be finite and in [0, 1]`).
    pub fn new(desc: GridDesc, data: Vec<T>) -> Result<Self, GridError> {
        if data.len() != desc.point_count() {
            return Err(GridError::LengthMismatch {
                field: "data",
                expected: desc.point_count(),
                found: data.len(),
            });
        }
        if !T::all_valid(&data) {
            for (i, v) in data.iter().enumerate() {
                if let Err((field, value, reason)) = v.check() {
                    return Err(GridError::InvalidField {
                        field: format!("data[{i}]{field}"),
                        value,
                        reason,
                    });
                }
            }
        }
        Ok(Self { desc, data })
    }

    /// A grid with every point set to `value` (validated once).
    pub fn filled(desc: GridDesc, value: T) -> Result<Self, GridError> {
        if let Err((field, v, reason)) = value.check() {
            return Err(GridError::InvalidField {
                field: format!("value{field}"),
                value: v,
                reason,
            });
        }
        check_size::<T>(&desc)?;
        Ok(Self {
            desc,
            data: vec![value; desc.point_count()],
        })
    }

    /// Sets point `p` (validated). Errors name the point.
    pub fn set(&mut self, p: glam::UVec3, value: T) -> Result<(), GridError> {
        let i = self
            .desc
            .index(p)
            .ok_or_else(|| GridError::invalid("point", p, "outside the grid"))?;
        if let Err((field, v, reason)) = value.check() {
            return Err(GridError::InvalidField {
                field: format!("value{field}"),
                value: v,
                reason,
            });
        }
        self.data[i] = value;
        Ok(())
    }
}

/// A grid of `desc`'s points of `T` within the memory limit: an error naming its size,
/// not an allocation failure (2^32 points aborted).
fn check_size<T>(desc: &GridDesc) -> Result<(), GridError> {
    crate::limits::check_memory(
        &format!("a grid of {} points", desc.point_count()),
        crate::limits::checked_bytes(
            "points",
            &[desc.point_count() as u64, std::mem::size_of::<T>() as u64],
        )?,
    )
}

impl<T: bytemuck::Zeroable + Clone> Grid<T> {
    /// A grid of zeros from pages the system hands out zeroed and maps on first touch:
    /// a placeholder that is replaced before it is read costs no page faults (a 26-bin
    /// grid made by [`Grid::filled`] with zeros writes its 312 bytes a point).
    pub fn zeroed(desc: GridDesc) -> Result<Self, GridError> {
        check_size::<T>(&desc)?;
        Ok(Self {
            desc,
            data: bytemuck::zeroed_vec(desc.point_count()),
        })
    }
}

impl<T> Grid<T> {
    /// Wraps values the caller guarantees valid (used by sweepers whose output is valid by
    /// construction). Panics if the length is wrong: that is a bug, not user input.
    pub fn from_trusted(desc: GridDesc, data: Vec<T>) -> Self {
        assert_eq!(data.len(), desc.point_count(), "grid data length");
        Self { desc, data }
    }
    /// The descriptor.
    pub fn desc(&self) -> &GridDesc {
        &self.desc
    }
    /// All values in memory order.
    pub fn data(&self) -> &[T] {
        &self.data
    }
    /// The value at point `p`, `None` outside.
    pub fn get(&self, p: glam::UVec3) -> Option<&T> {
        self.desc.index(p).map(|i| &self.data[i])
    }
    /// The values of level `j`; empty for `j` at or past the grid's levels.
    pub fn level(&self, j: u32) -> &[T] {
        self.data.get(self.desc.level_range(j)).unwrap_or(&[])
    }
    /// The values, mutable (the caller keeps them valid, as with [`Grid::from_trusted`]):
    /// for in-place updates such as merging light volumes.
    pub fn data_mut(&mut self) -> &mut [T] {
        &mut self.data
    }
    /// The grid's values, consumed.
    pub fn into_data(self) -> Vec<T> {
        self.data
    }
    /// Applies `f` to every value (the result is not validated: `U`'s invariants are the
    /// caller's promise, as in [`Grid::from_trusted`]).
    pub fn map<U>(&self, f: impl Fn(&T) -> U) -> Grid<U> {
        Grid {
            desc: self.desc,
            data: self.data.iter().map(f).collect(),
        }
    }
}

/// Material of one cell: diffuse reflectance (albedo) RGB and pass-through, each in
/// `[0, 1]`.
///
/// Pass-through `p` is the fraction of light that crosses a cell of side `h` (one cell
/// length) without meeting material; a path of length `l * h` through the cell passes
/// `p^l`. Light not passed is absorbed or, with probability `reflectance`, scattered.
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Material {
    /// Diffuse reflectance RGB, each in `[0, 1]`.
    pub reflectance: Vec3,
    /// Pass-through per cell length, in `[0, 1]`.
    pub pass: f32,
}

impl Material {
    /// Empty space: passes everything.
    pub const EMPTY: Self = Self {
        reflectance: Vec3::ZERO,
        pass: 1.0,
    };
    /// Opaque material of the given colour.
    pub const fn opaque(reflectance: Vec3) -> Self {
        Self {
            reflectance,
            pass: 0.0,
        }
    }
    /// True when the cell holds no material (`pass == 1`).
    pub fn is_empty(&self) -> bool {
        self.pass >= 1.0
    }
}

impl Default for Material {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl GridValue for Material {
    const KIND: crate::file::GridKind = crate::file::GridKind::Material;
    const FILE_BYTES: usize = 16;
    fn check(&self) -> Result<(), (&'static str, String, &'static str)> {
        let r = self.reflectance;
        for (name, v) in [
            (".reflectance.x", r.x),
            (".reflectance.y", r.y),
            (".reflectance.z", r.z),
            (".pass", self.pass),
        ] {
            check_range(String::new, v, 0.0, 1.0)
                .map_err(|_| (name, format!("{v:?}"), "must be finite and in [0, 1]"))?;
        }
        Ok(())
    }
    /// Every float in `[0, 1]` (false for NaN and the infinities, as `check`), in one
    /// pass that vectorises: checked cell by cell, composed materials took 9 % of
    /// composing's samples on the fly-through (`perf`).
    fn all_valid(values: &[Self]) -> bool {
        bytemuck::cast_slice::<Material, f32>(values)
            .iter()
            .fold(true, |ok, x| ok & (0.0..=1.0).contains(x))
    }
    fn write_le(&self, out: &mut Vec<u8>) {
        write_f32s(
            out,
            &[
                self.reflectance.x,
                self.reflectance.y,
                self.reflectance.z,
                self.pass,
            ],
        );
    }
    fn read_le(b: &[u8]) -> Self {
        let f = read_f32s::<4>(b);
        Self {
            reflectance: Vec3::new(f[0], f[1], f[2]),
            pass: f[3],
        }
    }
}

fn check_light(v: Vec3, field: &'static str) -> Result<(), (&'static str, String, &'static str)> {
    if v.is_finite() && v.cmpge(Vec3::ZERO).all() {
        Ok(())
    } else {
        Err((field, format!("{v:?}"), "light must be finite and >= 0"))
    }
}

impl GridValue for BinLight {
    const KIND: crate::file::GridKind = crate::file::GridKind::Light;
    const FILE_BYTES: usize = NUM_DIRS * 12;
    fn check(&self) -> Result<(), (&'static str, String, &'static str)> {
        for v in &self.0 {
            check_light(*v, ".bins")?;
        }
        Ok(())
    }
    /// [`BinLight::all_valid`]: one pass over the floats.
    fn all_valid(values: &[Self]) -> bool {
        BinLight::all_valid(values)
    }
    fn write_le(&self, out: &mut Vec<u8>) {
        for v in &self.0 {
            write_f32s(out, &v.to_array());
        }
    }
    fn read_le(b: &[u8]) -> Self {
        BinLight(std::array::from_fn(|d| {
            Vec3::from_array(read_f32s::<3>(&b[d * 12..]))
        }))
    }
}

impl GridValue for crate::HorizonLight {
    const KIND: crate::file::GridKind = crate::file::GridKind::Horizon;
    const FILE_BYTES: usize = crate::dirs::HORIZONTAL_BINS * 12;
    fn check(&self) -> Result<(), (&'static str, String, &'static str)> {
        for v in &self.0 {
            check_light(*v, ".down")?;
        }
        Ok(())
    }
    fn write_le(&self, out: &mut Vec<u8>) {
        for v in &self.0 {
            write_f32s(out, &v.to_array());
        }
    }
    fn read_le(b: &[u8]) -> Self {
        crate::HorizonLight(std::array::from_fn(|k| {
            Vec3::from_array(read_f32s::<3>(&b[k * 12..]))
        }))
    }
}

/// Mean light over the sphere at a point (linear RGB).
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct AverageLight(pub Vec3);

impl GridValue for AverageLight {
    const KIND: crate::file::GridKind = crate::file::GridKind::Average;
    const FILE_BYTES: usize = 12;
    fn check(&self) -> Result<(), (&'static str, String, &'static str)> {
        check_light(self.0, "")
    }
    fn write_le(&self, out: &mut Vec<u8>) {
        write_f32s(out, &self.0.to_array());
    }
    fn read_le(b: &[u8]) -> Self {
        Self(Vec3::from_array(read_f32s::<3>(b)))
    }
}

/// Dominant light direction at a point: the direction light travels, with length in
/// `[0, 1]` saying how sharply it comes from there (see [`BinLight::dominant`]).
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct DominantDir(pub Vec3);

impl GridValue for DominantDir {
    const KIND: crate::file::GridKind = crate::file::GridKind::Dominant;
    const FILE_BYTES: usize = 12;
    fn check(&self) -> Result<(), (&'static str, String, &'static str)> {
        if self.0.is_finite() && self.0.length() <= 1.0 + 1e-5 {
            Ok(())
        } else {
            Err((
                "",
                format!("{:?}", self.0),
                "must be finite with length <= 1",
            ))
        }
    }
    fn write_le(&self, out: &mut Vec<u8>) {
        write_f32s(out, &self.0.to_array());
    }
    fn read_le(b: &[u8]) -> Self {
        Self(Vec3::from_array(read_f32s::<3>(b)))
    }
}

/// 26 bins packed as R11G11B10 words (see [`crate::pack`]); scale by the grid's exposure.
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct PackedBins(pub [u32; NUM_DIRS]);

impl GridValue for PackedBins {
    const KIND: crate::file::GridKind = crate::file::GridKind::PackedLight;
    const FILE_BYTES: usize = NUM_DIRS * 4;
    fn check(&self) -> Result<(), (&'static str, String, &'static str)> {
        // Exponent 31 (infinity or NaN) is never written by the packer.
        for w in self.0 {
            if (w & 0x7c0) == 0x7c0 || ((w >> 11) & 0x7c0) == 0x7c0 || ((w >> 22) & 0x3e0) == 0x3e0
            {
                return Err((
                    ".bins",
                    format!("{w:#010x}"),
                    "R11G11B10 word holds infinity or NaN",
                ));
            }
        }
        Ok(())
    }
    fn write_le(&self, out: &mut Vec<u8>) {
        for w in self.0 {
            out.extend_from_slice(&w.to_le_bytes());
        }
    }
    fn read_le(b: &[u8]) -> Self {
        Self(std::array::from_fn(|d| {
            u32::from_le_bytes(b[d * 4..d * 4 + 4].try_into().unwrap())
        }))
    }
}

fn write_f32s(out: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

fn read_f32s<const N: usize>(b: &[u8]) -> [f32; N] {
    std::array::from_fn(|i| f32::from_le_bytes(b[i * 4..i * 4 + 4].try_into().unwrap()))
}

/// Material grid: the sweep's input.
pub type MaterialGrid = Grid<Material>;
/// Light grid: 26 bins RGB `f32` per point.
pub type LightGrid = Grid<BinLight>;
/// Horizon grid: the downward-travelling halves of the 8 horizontal bins per point.
pub type HorizonGrid = Grid<crate::HorizonLight>;
/// Average-light grid.
pub type AverageGrid = Grid<AverageLight>;
/// Dominant-direction grid.
pub type DominantGrid = Grid<DominantDir>;

impl LightGrid {
    /// The average-light grid of this grid.
    pub fn average_grid(&self) -> AverageGrid {
        self.map(|b| AverageLight(b.average()))
    }
    /// The dominant-direction grid of this grid.
    pub fn dominant_grid(&self) -> DominantGrid {
        self.map(|b| DominantDir(b.dominant()))
    }
    /// Largest single channel value of any bin (0 for an empty grid).
    pub fn max_value(&self) -> f32 {
        self.data()
            .iter()
            .flat_map(|b| b.0.iter())
            .fold(0.0f32, |m, v| m.max(v.max_element()))
    }
    /// Packs to R11G11B10 with a per-grid exposure chosen by [`pack::exposure_for`]: the
    /// brightest value lands just under the format's largest finite value, so HDR sun light
    /// does not saturate and dim light keeps its relative precision.
    pub fn pack(&self) -> PackedLightGrid {
        let exposure = pack::exposure_for(self.max_value());
        PackedLightGrid {
            grid: self.map(|b| PackedBins(b.0.map(|v| pack::pack_r11g11b10(v * exposure)))),
            exposure,
        }
    }
}

/// A light grid packed as R11G11B10 with one exposure scale: stored value = light ×
/// `exposure`; [`PackedLightGrid::unpack`] divides it out.
#[derive(Debug, Clone, PartialEq)]
pub struct PackedLightGrid {
    /// The packed bins.
    pub grid: Grid<PackedBins>,
    /// Scale applied before packing (a power of two, finite, > 0).
    pub exposure: f32,
}

impl PackedLightGrid {
    /// Validates the exposure (the words are validated by [`Grid::new`]).
    pub fn new(grid: Grid<PackedBins>, exposure: f32) -> Result<Self, GridError> {
        // The largest code divided by the exposure must stay finite: a subnormal exposure
        // has an infinite reciprocal and would unpack to NaN (0 × inf) and infinity.
        if !(exposure.is_finite() && exposure > 0.0 && (pack::MAX_UF11 / exposure).is_finite()) {
            return Err(GridError::invalid(
                "exposure",
                exposure,
                "must be finite, > 0 and at least 65024 / f32::MAX",
            ));
        }
        Ok(Self { grid, exposure })
    }
    /// The light of one packed point.
    pub fn unpack_point(&self, b: &PackedBins) -> BinLight {
        let inv = 1.0 / self.exposure;
        BinLight(b.0.map(|w| pack::unpack_r11g11b10(w) * inv))
    }
    /// Unpacks the whole grid.
    pub fn unpack(&self) -> LightGrid {
        self.grid.map(|b| self.unpack_point(b))
    }
}

/// 26 bins of 8-bit RGB codes on a square-root curve (`value = (code / 255)² × scale`):
/// the compressed light volumes of `light-volumes`, 78 bytes a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CodedBins(pub [[u8; 3]; NUM_DIRS]);

impl GridValue for CodedBins {
    const KIND: crate::file::GridKind = crate::file::GridKind::CodedLight;
    const FILE_BYTES: usize = NUM_DIRS * 3;
    fn check(&self) -> Result<(), (&'static str, String, &'static str)> {
        Ok(())
    }
    fn write_le(&self, out: &mut Vec<u8>) {
        for c in self.0 {
            out.extend_from_slice(&c);
        }
    }
    fn read_le(b: &[u8]) -> Self {
        Self(std::array::from_fn(|d| {
            [b[3 * d], b[3 * d + 1], b[3 * d + 2]]
        }))
    }
}

/// A light grid coded as [`CodedBins`], with the value of code 255 (`scale`) and the
/// content key of what made it (a cache key: readers refuse a file made for another).
#[derive(Debug, Clone, PartialEq)]
pub struct CodedLightGrid {
    /// The codes.
    pub grid: Grid<CodedBins>,
    /// Value of code 255 (finite, > 0).
    pub scale: f32,
    /// Content key of what the grid was made from.
    pub key: u64,
}

impl CodedLightGrid {
    /// Validates the scale.
    pub fn new(grid: Grid<CodedBins>, scale: f32, key: u64) -> Result<Self, GridError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(GridError::invalid("scale", scale, "must be finite and > 0"));
        }
        Ok(Self { grid, scale, key })
    }
    /// Decodes every point.
    pub fn decode(&self) -> LightGrid {
        let table: [f32; 256] = std::array::from_fn(|c| {
            let s = c as f32 / 255.0;
            s * s * self.scale
        });
        self.grid.map(|b| {
            BinLight(std::array::from_fn(|d| {
                let [r, g, bl] = b.0[d];
                Vec3::new(table[r as usize], table[g as usize], table[bl as usize])
            }))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::UVec3;

    /// `Material::all_valid` agrees with `check` value by value: over floats in and
    /// out of `[0, 1]` (signed zeros, the ends, NaN, the infinities, tiny and huge
    /// values) in every field, a material grid is made exactly when every cell
    /// checks, and its error names the first bad cell's field as before.
    #[test]
    fn a_material_grid_is_made_exactly_when_every_cell_checks() {
        let floats = [
            0.0,
            -0.0,
            1.0,
            0.5,
            f32::MIN_POSITIVE,
            1.0 + f32::EPSILON,
            -f32::MIN_POSITIVE,
            -1.0,
            2.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(3, 1, 1)).unwrap();
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut pick = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            floats[(s % floats.len() as u64) as usize]
        };
        let (mut made, mut refused) = (0, 0);
        for n in 0..4000usize {
            // Mostly valid cells, one field at a time made anything.
            let cells: Vec<Material> = (0..3)
                .map(|c| {
                    let mut f = [0.25f32, 0.5, 0.75, 0.9];
                    f[(n / 3 + c) % 4] = pick();
                    Material {
                        reflectance: Vec3::new(f[0], f[1], f[2]),
                        pass: f[3],
                    }
                })
                .collect();
            let each = cells.iter().all(|c| c.check().is_ok());
            assert_eq!(Material::all_valid(&cells), each, "{cells:?}");
            match Grid::new(desc, cells.clone()) {
                Ok(_) => {
                    assert!(each);
                    made += 1;
                }
                Err(e) => {
                    let (i, c) = cells
                        .iter()
                        .enumerate()
                        .find(|(_, c)| c.check().is_err())
                        .expect("a bad cell");
                    let field = c.check().unwrap_err().0;
                    assert!(e.to_string().contains(&format!("data[{i}]{field}")), "{e}");
                    refused += 1;
                }
            }
        }
        assert!(
            made > 100 && refused > 100,
            "{made} made, {refused} refused"
        );
    }

    /// `zeroed` is `filled` with zeros, bit for bit.
    #[test]
    fn a_zeroed_grid_is_a_grid_filled_with_zeros() {
        let desc = GridDesc::new(glam::Vec3::ONE, 0.5, UVec3::new(3, 4, 5)).unwrap();
        let z = crate::LightGrid::zeroed(desc).unwrap();
        let f = crate::LightGrid::filled(desc, crate::BinLight::ZERO).unwrap();
        assert_eq!(z.desc(), f.desc());
        let (a, b): (&[f32], &[f32]) = (
            bytemuck::cast_slice(z.data()),
            bytemuck::cast_slice(f.data()),
        );
        assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
    }

    #[test]
    fn levels_past_the_top_are_empty_and_huge_grids_are_refused_not_aborted() {
        let g = Grid::filled(desc(), BinLight::ZERO).unwrap();
        assert_eq!(g.level(2).len(), 4);
        assert!(g.level(3).is_empty() && g.level(u32::MAX).is_empty());
        // 2^32 points of 312 bytes: over any memory limit, an error naming the grid.
        let huge = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4096, 1024, 1024)).unwrap();
        let e = Grid::filled(huge, BinLight::ZERO).unwrap_err().to_string();
        assert!(e.contains("4294967296 points"), "{e}");
    }

    fn desc() -> GridDesc {
        GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 3, 2)).unwrap()
    }

    #[test]
    fn exposures_that_would_unpack_to_nan_or_infinity_are_refused() {
        let g = Grid::filled(
            desc(),
            PackedBins([pack::pack_r11g11b10(Vec3::ONE); NUM_DIRS]),
        )
        .unwrap();
        for bad in [
            0.0,
            -1.0,
            1e-40,
            f32::MIN_POSITIVE,
            1e-34,
            f32::NAN,
            f32::INFINITY,
        ] {
            let e = PackedLightGrid::new(g.clone(), bad)
                .unwrap_err()
                .to_string();
            assert!(e.contains("exposure"), "{bad}: {e}");
        }
        for good in [2f32.powi(-111), 1.0, 2f32.powi(126)] {
            let p = PackedLightGrid::new(g.clone(), good).unwrap();
            assert!(
                p.unpack()
                    .data()
                    .iter()
                    .all(|b| b.0.iter().all(|v| v.is_finite()))
            );
        }
        // Packing the largest finite light gives a valid, finite grid.
        let huge = Grid::filled(desc(), BinLight::uniform(Vec3::splat(f32::MAX))).unwrap();
        let p = huge.pack();
        assert!(PackedLightGrid::new(p.grid.clone(), p.exposure).is_ok());
        assert!(
            p.unpack()
                .data()
                .iter()
                .all(|b| b.0.iter().all(|v| v.is_finite()))
        );
    }

    #[test]
    fn material_validation_names_the_element() {
        let mut cells = vec![Material::EMPTY; 12];
        cells[7].pass = f32::NAN;
        let e = MaterialGrid::new(desc(), cells).unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid data[7].pass = NaN: must be finite and in [0, 1]"
        );
        let mut cells = vec![Material::EMPTY; 12];
        cells[3].reflectance.y = 1.5;
        let e = MaterialGrid::new(desc(), cells).unwrap_err().to_string();
        assert!(e.contains("data[3].reflectance.y = 1.5"), "{e}");
        let e = MaterialGrid::new(desc(), vec![Material::EMPTY; 5])
            .unwrap_err()
            .to_string();
        assert!(e.contains("5 elements") && e.contains("12"), "{e}");
        // The extremes are valid.
        let ok = vec![
            Material {
                reflectance: Vec3::ONE,
                pass: 0.0
            };
            12
        ];
        assert!(MaterialGrid::new(desc(), ok).is_ok());
    }

    #[test]
    fn light_validation_rejects_nan_inf_negative() {
        for bad in [f32::NAN, f32::INFINITY, -1.0] {
            let mut b = BinLight::ZERO;
            b.0[5].z = bad;
            let mut g = LightGrid::filled(desc(), BinLight::ZERO).unwrap();
            let e = g.set(UVec3::new(1, 2, 1), b).unwrap_err().to_string();
            assert!(e.contains("value.bins"), "{e}");
            assert!(g.set(UVec3::new(2, 0, 0), BinLight::ZERO).is_err());
        }
    }

    #[test]
    fn pack_uses_exposure_so_hdr_fits() {
        let sun = 1e6f32; // far beyond R11G11B10's range
        let mut g = LightGrid::filled(desc(), BinLight::uniform(Vec3::splat(0.01))).unwrap();
        g.set(
            UVec3::new(0, 0, 0),
            BinLight::single(4, Vec3::new(sun, sun * 0.9, sun * 0.8)),
        )
        .unwrap();
        let p = g.pack();
        assert!(p.exposure < 1.0);
        let u = p.unpack();
        for (a, b) in g.data().iter().zip(u.data()) {
            for d in 0..NUM_DIRS {
                let err = (a.0[d] - b.0[d]).abs();
                assert!(
                    err.cmple(a.0[d] * 2f32.powi(-6) + 1e-12).all(),
                    "{} vs {}",
                    a.0[d],
                    b.0[d]
                );
            }
        }
    }
}
