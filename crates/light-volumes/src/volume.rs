//! One light's volume, compressed as 3DWorld caches it: cropped to the bounding box of
//! the cells holding more than 1/256 of the light's largest value, 8-bit RGB per bin
//! with one scale per file. Beyond 3DWorld, codes are on a square-root curve
//! (`v = (code / 255)² · scale`): light falls as 1/r², and a linear code would leave
//! most cells a few levels (relative RMS error 5.7 % on the town example; 2.5 % with the
//! curve). And the cache file, keyed by a hash of the light and the
//! scene, written atomically, checked on load.
//!
//! The file is lightgrid's one grid format (`lightgrid_core::file`), kind 6 "coded
//! light": the cropped box as the descriptor, the scale in the exposure field, the key
//! at the head of the payload, then `26 × 3` code bytes a point; its reader checks
//! magic, version, length, checksum and header before this crate checks the key. A light
//! that lit nothing is stored as one zero point at the origin (and read back as such).

use std::path::Path;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, CodedBins, CodedLightGrid, Grid, GridDesc, GridError, GridFile, LightGrid, NUM_DIRS,
};

/// Cells below this fraction of the largest value are dropped from the bounding box.
pub const THRESHOLD: f32 = 1.0 / 256.0;

/// A compressed light volume.
#[derive(Debug, Clone, PartialEq)]
pub struct CompressedVolume {
    /// Hash of the light's shape and the scene it was traced in.
    pub key: u64,
    /// The cropped box (`None` for a light that lit nothing).
    pub desc: Option<GridDesc>,
    /// Value of the code 255 (codes decode as `(code / 255)² · scale`).
    pub scale: f32,
    /// 26 RGB codes per point.
    pub codes: Vec<[u8; 3]>,
}

impl CompressedVolume {
    /// Crops and quantises `volume` (the square root of each value over `scale` = the
    /// largest value rounds to the nearest of 256 levels). Values a grid can hold only
    /// through `data_mut` are read as light: NaN and negatives as 0, infinity as
    /// `f32::MAX`.
    pub fn compress(volume: &LightGrid, key: u64) -> Self {
        let clean = |v: f32| {
            if v.is_nan() {
                0.0
            } else {
                v.clamp(0.0, f32::MAX)
            }
        };
        // Per component: `max_element` of a vector holding NaN may return the NaN.
        let peak = |v: Vec3| clean(v.x).max(clean(v.y)).max(clean(v.z));
        let max = volume
            .data()
            .iter()
            .flat_map(|b| b.0.iter())
            .fold(0.0f32, |m, v| m.max(peak(*v)));
        let d = volume.desc();
        if max <= 0.0 {
            return Self {
                key,
                desc: None,
                scale: 0.0,
                codes: Vec::new(),
            };
        }
        let cut = max * THRESHOLD;
        let (mut lo, mut hi) = (UVec3::MAX, UVec3::ZERO);
        for (i, b) in volume.data().iter().enumerate() {
            if b.0.iter().any(|v| peak(*v) > cut) {
                let c = d.coords(i).expect("in range");
                lo = lo.min(c);
                hi = hi.max(c);
            }
        }
        let dims = hi - lo + UVec3::ONE;
        let desc = GridDesc::new(d.position(lo), d.h(), dims).expect("a box inside a grid");
        let q = |v: f32| (((clean(v) / max).sqrt() * 255.0).round().clamp(0.0, 255.0)) as u8;
        let mut codes = Vec::with_capacity(desc.point_count() * NUM_DIRS);
        for y in lo.y..=hi.y {
            for z in lo.z..=hi.z {
                for x in lo.x..=hi.x {
                    let b = volume.get(UVec3::new(x, y, z)).expect("inside");
                    codes.extend(b.0.iter().map(|v| [q(v.x), q(v.y), q(v.z)]));
                }
            }
        }
        Self {
            key,
            desc: Some(desc),
            scale: max,
            codes,
        }
    }

    /// The cropped volume, decoded.
    pub fn decode(&self) -> Option<LightGrid> {
        let desc = self.desc?;
        let table: [f32; 256] = std::array::from_fn(|c| {
            let s = c as f32 / 255.0;
            s * s * self.scale
        });
        let data = self
            .codes
            .chunks(NUM_DIRS)
            .map(|c| {
                BinLight(std::array::from_fn(|d| {
                    Vec3::new(
                        table[c[d][0] as usize],
                        table[c[d][1] as usize],
                        table[c[d][2] as usize],
                    )
                }))
            })
            .collect();
        Some(Grid::from_trusted(desc, data))
    }

    /// Bytes of the file.
    pub fn file_bytes(&self) -> usize {
        lightgrid_core::file::HEADER_BYTES + 8 + self.codes.len().max(NUM_DIRS) * 3 + 4
    }

    /// As a coded light grid (the dark volume: one zero point at the origin).
    fn to_coded(&self) -> CodedLightGrid {
        let (desc, scale) = match self.desc {
            Some(d) => (d, self.scale),
            None => (
                GridDesc::new(Vec3::ZERO, 1.0, UVec3::ONE).expect("valid"),
                1.0,
            ),
        };
        let data = if self.desc.is_some() {
            self.codes
                .chunks_exact(NUM_DIRS)
                .map(|c| CodedBins(c.try_into().expect("26 codes")))
                .collect()
        } else {
            vec![CodedBins([[0; 3]; NUM_DIRS])]
        };
        CodedLightGrid {
            grid: Grid::from_trusted(desc, data),
            scale,
            key: self.key,
        }
    }

    /// Serialises (see the module docs).
    pub fn to_bytes(&self) -> Vec<u8> {
        GridFile::CodedLight(self.to_coded()).to_bytes()
    }

    /// Parses and checks a file's bytes (the grid format's checks, then that it was made
    /// for `key`: a stale volume is an error, never used).
    pub fn from_bytes(bytes: &[u8], key: u64) -> Result<Self, GridError> {
        let c = GridFile::from_bytes(bytes)?.into_coded_light()?;
        if c.key != key {
            return Err(GridError::invalid(
                "key",
                format!("{:#018x}", c.key),
                "made for another light or scene: stale",
            ));
        }
        let codes: Vec<[u8; 3]> = c.grid.data().iter().flat_map(|b| b.0).collect();
        if c.grid.desc().point_count() == 1 && codes.iter().all(|c| *c == [0; 3]) {
            return Ok(Self {
                key,
                desc: None,
                scale: 0.0,
                codes: Vec::new(),
            });
        }
        Ok(Self {
            key,
            desc: Some(*c.grid.desc()),
            scale: c.scale,
            codes,
        })
    }

    /// Writes the cache file atomically.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), GridError> {
        lightgrid_core::file::write_atomic(path.as_ref(), &self.to_bytes())
    }

    /// Reads a cache file made for `key`.
    pub fn load(path: impl AsRef<Path>, key: u64) -> Result<Self, GridError> {
        let path = path.as_ref();
        if let Ok(meta) = std::fs::metadata(path)
            && meta.is_file()
        {
            // The codes, then one f32 per code once the volume is expanded.
            lightgrid_core::limits::check_memory(
                &format!("light volume {}", path.display()),
                meta.len().saturating_mul(5),
            )?;
        }
        let bytes = lightgrid_core::limits::read_file(path, MAX_FILE_BYTES)?;
        Self::from_bytes(&bytes, key).map_err(|e| match e {
            GridError::InvalidField {
                field,
                value,
                reason,
            } => GridError::InvalidField {
                field: format!("{}: {field}", path.display()),
                value,
                reason,
            },
            other => other.with_path(path),
        })
    }
}

/// Largest cache file read: 4 GiB (a volume of 55 M points).
pub const MAX_FILE_BYTES: u64 = 4 << 30;

/// Where a volume came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CacheOutcome {
    /// Read from a valid cache file.
    Hit,
    /// No file: traced and written.
    Missing,
    /// A stale or corrupt file: traced again and replaced.
    Replaced,
}

/// The volume for `key`: from `path` if it holds a valid volume for that key, else made
/// by `make` and written there (atomically).
pub fn load_or_make(
    path: impl AsRef<Path>,
    key: u64,
    make: impl FnOnce() -> Result<CompressedVolume, GridError>,
) -> Result<(CompressedVolume, CacheOutcome), GridError> {
    let path = path.as_ref();
    let outcome = match CompressedVolume::load(path, key) {
        Ok(v) => return Ok((v, CacheOutcome::Hit)),
        Err(GridError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            CacheOutcome::Missing
        }
        Err(_) => CacheOutcome::Replaced,
    };
    let v = make()?;
    v.save(path)?;
    Ok((v, outcome))
}
