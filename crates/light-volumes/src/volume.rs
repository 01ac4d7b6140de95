//! One light's volume, compressed as 3DWorld caches it: cropped to the bounding box of
//! the cells holding more than 1/256 of the light's largest value, 8-bit RGB per bin
//! with one scale per file. Beyond 3DWorld, codes are on a square-root curve
//! (`v = (code / 255)² · scale`): light falls as 1/r², and a linear code would leave
//! most cells a few levels (relative RMS error 5.7 % on the town example; 2.5 % with the
//! curve). And the cache file, keyed by a hash of the light and the
//! scene, written atomically, checked on load.
//!
//! File layout (little endian): `b"LGVOL\0"`, version `u16` = 2, key `u64`, cropped
//! origin `3 × f32`, cell size `f32`, dims `3 × u32`, scale `f32`, then `26 × 3` bytes
//! per point (x fastest, then z, then y), then CRC-32 of everything before it.

use std::path::Path;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{BinLight, Grid, GridDesc, GridError, LightGrid, NUM_DIRS};

/// Cells below this fraction of the largest value are dropped from the bounding box.
pub const THRESHOLD: f32 = 1.0 / 256.0;

const MAGIC: &[u8; 6] = b"LGVOL\0";
const VERSION: u16 = 2;
const HEADER: usize = 6 + 2 + 8 + 12 + 4 + 12 + 4;

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
    /// largest value rounds to the nearest of 256 levels).
    pub fn compress(volume: &LightGrid, key: u64) -> Self {
        let max = volume.max_value();
        let d = volume.desc();
        if max.is_nan() || max <= 0.0 {
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
            if b.0.iter().any(|v| v.max_element() > cut) {
                let c = d.coords(i).expect("in range");
                lo = lo.min(c);
                hi = hi.max(c);
            }
        }
        let dims = hi - lo + UVec3::ONE;
        let desc = GridDesc::new(d.position(lo), d.h(), dims).expect("a box inside a grid");
        let q = |v: f32| {
            (((v / max).max(0.0).sqrt() * 255.0)
                .round()
                .clamp(0.0, 255.0)) as u8
        };
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
        HEADER + self.codes.len() * 3 + 4
    }

    /// Serialises (see the module docs).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(self.file_bytes());
        b.extend_from_slice(MAGIC);
        b.extend_from_slice(&VERSION.to_le_bytes());
        b.extend_from_slice(&self.key.to_le_bytes());
        let (o, h, dims) = match self.desc {
            Some(d) => (d.origin(), d.h(), d.dims()),
            None => (Vec3::ZERO, 0.0, UVec3::ZERO),
        };
        for v in o.to_array() {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&h.to_le_bytes());
        for v in dims.to_array() {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&self.scale.to_le_bytes());
        for c in &self.codes {
            b.extend_from_slice(c);
        }
        let crc = crc32fast::hash(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b
    }

    /// Parses and checks a file's bytes: magic, version, checksum, sizes, and that it
    /// was made for `key` (a stale volume is an error, never used).
    pub fn from_bytes(bytes: &[u8], key: u64) -> Result<Self, GridError> {
        let bad = |field: &'static str, value: String, reason: &'static str| {
            GridError::invalid(field, value, reason)
        };
        if bytes.len() < HEADER + 4 {
            return Err(bad("file", format!("{} bytes", bytes.len()), "truncated"));
        }
        if &bytes[..6] != MAGIC {
            return Err(bad(
                "magic",
                format!("{:02x?}", &bytes[..6]),
                "not a light volume",
            ));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 4);
        let stored = u32::from_le_bytes(tail.try_into().expect("4 bytes"));
        if crc32fast::hash(body) != stored {
            return Err(bad(
                "checksum",
                format!("{stored:#010x}"),
                "does not match: corrupt",
            ));
        }
        let u16_at = |i: usize| u16::from_le_bytes(bytes[i..i + 2].try_into().expect("2"));
        let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().expect("4"));
        let f32_at = |i: usize| f32::from_le_bytes(bytes[i..i + 4].try_into().expect("4"));
        let version = u16_at(6);
        if version != VERSION {
            return Err(bad("version", version.to_string(), "not supported"));
        }
        let found = u64::from_le_bytes(bytes[8..16].try_into().expect("8"));
        if found != key {
            return Err(bad(
                "key",
                format!("{found:#018x}"),
                "made for another light or scene: stale",
            ));
        }
        let origin = Vec3::new(f32_at(16), f32_at(20), f32_at(24));
        let h = f32_at(28);
        let dims = UVec3::new(u32_at(32), u32_at(36), u32_at(40));
        let scale = f32_at(44);
        let codes_bytes = &body[HEADER..];
        if dims == UVec3::ZERO {
            return Ok(Self {
                key,
                desc: None,
                scale,
                codes: Vec::new(),
            });
        }
        let desc = GridDesc::new(origin, h, dims)?;
        if !(scale.is_finite() && scale > 0.0) {
            return Err(bad("scale", scale.to_string(), "must be finite and > 0"));
        }
        if codes_bytes.len() != desc.point_count() * NUM_DIRS * 3 {
            return Err(bad(
                "codes",
                codes_bytes.len().to_string(),
                "length does not match the dims",
            ));
        }
        Ok(Self {
            key,
            desc: Some(desc),
            scale,
            codes: codes_bytes.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
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
            other => other,
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
