//! One versioned binary file format for every grid kind.
//!
//! # Byte layout (version 1)
//!
//! All numbers little-endian; `f32` is IEEE 754 binary32.
//!
//! | offset | size | field | value |
//! |-------:|-----:|-------|-------|
//! | 0 | 8 | magic | ASCII `LTGRID`, then `0x1A 0x0A` |
//! | 8 | 4 | version | `u32` = 1 |
//! | 12 | 4 | kind | `u32`: 1 material, 2 light (26 bins `f32`), 3 packed light (26 × R11G11B10), 4 average, 5 dominant, 6 coded light (26 × 8-bit RGB codes) |
//! | 16 | 4 | encoding | `u32`: 0 = `f32` values, 1 = R11G11B10 words (kind 3 only), 2 = square-root codes (kind 6 only) |
//! | 20 | 12 | origin | 3 × `f32`: world position of point (0, 0, 0), metres |
//! | 32 | 4 | h | `f32`: cell size, metres |
//! | 36 | 12 | dims | 3 × `u32`: points along x, y, z |
//! | 48 | 4 | exposure | `f32`: packed value = light × exposure (kind 3); the value of code 255 (kind 6); 1.0 for the others |
//! | 52 | 4 | reserved | `u32` = 0 |
//! | 56 | 8 | payload length | `u64`: bytes of payload = prefix + points × bytes per point |
//! | 64 | n | payload | kind 6 only: the content key (`u64`, 8 bytes); then the points in memory order (x fastest, then z, then y) |
//! | 64 + n | 4 | checksum | `u32` CRC-32 (IEEE, as zlib) of bytes `0 .. 64 + n` |
//!
//! Bytes per point: material 16 (`r, g, b, pass` as `f32`); light 312 (bin 0 `r, g, b`,
//! bin 1 `r, g, b`, ... in the canonical direction order of [`crate::dirs`]); packed light
//! 104 (26 `u32` words, R in bits 0–10, G 11–21, B 22–31); average 12 (`r, g, b`);
//! dominant 12 (`x, y, z`); coded light 78 (26 × `r, g, b` bytes, value =
//! `(code / 255)² × exposure`: light falls as 1/r², so a square-root curve spends the
//! codes evenly; light-volumes' cache, whose key says which light and scene made it).
//!
//! Reading checks, in order: magic, version, size against the reader's limit, length
//! (truncated or trailing bytes), checksum, header fields (kind, encoding, descriptor,
//! exposure), then every payload value (NaN, infinity and out-of-range values are errors).
//! Writing is atomic: a temporary file beside the target, flushed, then renamed.

use std::io::Write;
use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};

use crate::error::FileErrorKind as K;
use crate::grid::{
    AverageLight, CodedBins, CodedLightGrid, DominantDir, Grid, GridValue, Material, PackedBins,
    PackedLightGrid,
};
use crate::light::BinLight;
use crate::{GridDesc, GridError};

/// The 8 magic bytes.
pub const MAGIC: [u8; 8] = *b"LTGRID\x1a\n";
/// The format version this build writes and reads.
pub const VERSION: u32 = 1;
/// Header size in bytes.
pub const HEADER_BYTES: usize = 64;
/// Default largest payload a reader accepts: 16 GiB.
pub const DEFAULT_MAX_PAYLOAD: u64 = 16 << 30;

/// What a grid file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum GridKind {
    /// Material grid.
    Material = 1,
    /// Light grid, 26 bins `f32`.
    Light = 2,
    /// Light grid packed as R11G11B10.
    PackedLight = 3,
    /// Average-light grid.
    Average = 4,
    /// Dominant-direction grid.
    Dominant = 5,
    /// Light grid as 8-bit square-root codes with a content key (light-volumes' cache).
    CodedLight = 6,
    /// The downward-travelling halves of the 8 horizontal bins (`f32`).
    Horizon = 7,
}

impl GridKind {
    /// Lower-case name, as used in messages.
    pub fn name(self) -> &'static str {
        match self {
            GridKind::Material => "material",
            GridKind::Light => "light",
            GridKind::PackedLight => "packed light",
            GridKind::Average => "average",
            GridKind::Dominant => "dominant",
            GridKind::CodedLight => "coded light",
            GridKind::Horizon => "horizon",
        }
    }
    fn from_u32(v: u32) -> Option<Self> {
        Some(match v {
            1 => GridKind::Material,
            2 => GridKind::Light,
            3 => GridKind::PackedLight,
            4 => GridKind::Average,
            5 => GridKind::Dominant,
            6 => GridKind::CodedLight,
            7 => GridKind::Horizon,
            _ => return None,
        })
    }
    fn encoding(self) -> u32 {
        match self {
            GridKind::PackedLight => 1,
            GridKind::CodedLight => 2,
            _ => 0,
        }
    }
    /// Bytes of the payload before the points: the content key of a coded light grid.
    fn prefix_bytes(self) -> u64 {
        if self == GridKind::CodedLight { 8 } else { 0 }
    }
}

/// Any grid a file may hold.
#[derive(Debug, Clone, PartialEq)]
pub enum GridFile {
    /// A material grid.
    Material(Grid<Material>),
    /// A light grid.
    Light(Grid<BinLight>),
    /// A packed light grid.
    PackedLight(PackedLightGrid),
    /// An average-light grid.
    Average(Grid<AverageLight>),
    /// A dominant-direction grid.
    Dominant(Grid<DominantDir>),
    /// A coded light grid (light-volumes' cache).
    CodedLight(CodedLightGrid),
    /// A horizon grid (the downward halves of the horizontal bins).
    Horizon(Grid<crate::HorizonLight>),
}

impl GridFile {
    /// The kind held.
    pub fn kind(&self) -> GridKind {
        match self {
            GridFile::Material(_) => GridKind::Material,
            GridFile::Light(_) => GridKind::Light,
            GridFile::PackedLight(_) => GridKind::PackedLight,
            GridFile::Average(_) => GridKind::Average,
            GridFile::Dominant(_) => GridKind::Dominant,
            GridFile::CodedLight(_) => GridKind::CodedLight,
            GridFile::Horizon(_) => GridKind::Horizon,
        }
    }

    /// The file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        match self {
            GridFile::Material(g) => encode(g, 1.0),
            GridFile::Light(g) => encode(g, 1.0),
            GridFile::PackedLight(p) => encode(&p.grid, p.exposure),
            GridFile::Average(g) => encode(g, 1.0),
            GridFile::Dominant(g) => encode(g, 1.0),
            GridFile::CodedLight(c) => encode_with(&c.grid, c.scale, &c.key.to_le_bytes()),
            GridFile::Horizon(g) => encode(g, 1.0),
        }
    }

    /// Parses file bytes with the default size limit.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, GridError> {
        Self::from_bytes_limited(bytes, DEFAULT_MAX_PAYLOAD)
    }

    /// Parses file bytes, refusing payloads over `max_payload` bytes.
    pub fn from_bytes_limited(bytes: &[u8], max_payload: u64) -> Result<Self, GridError> {
        let h = parse_header(bytes, max_payload)?;
        let payload = &bytes[HEADER_BYTES..HEADER_BYTES + h.payload_len as usize];
        Ok(match h.kind {
            GridKind::Material => GridFile::Material(decode(h.desc, payload)?),
            GridKind::Light => GridFile::Light(decode(h.desc, payload)?),
            GridKind::PackedLight => {
                let g = decode(h.desc, payload)?;
                GridFile::PackedLight(PackedLightGrid::new(g, h.exposure).map_err(|_| {
                    GridError::file(K::BadHeader {
                        field: "exposure",
                        value: format!("{:?}", h.exposure),
                    })
                })?)
            }
            GridKind::Average => GridFile::Average(decode(h.desc, payload)?),
            GridKind::Dominant => GridFile::Dominant(decode(h.desc, payload)?),
            GridKind::Horizon => GridFile::Horizon(decode(h.desc, payload)?),
            GridKind::CodedLight => {
                let key = u64::from_le_bytes(payload[..8].try_into().expect("8 bytes"));
                let g = decode(h.desc, &payload[8..])?;
                GridFile::CodedLight(CodedLightGrid::new(g, h.exposure, key)?)
            }
        })
    }

    /// Writes the file atomically: a temporary file in the same folder, flushed to disk,
    /// then renamed over `path`.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), GridError> {
        write_atomic(path.as_ref(), &self.to_bytes())
    }

    /// Reads a file with the default size limit. Errors name the path.
    ///
    /// Only regular files are read (a FIFO or device is an error, not a hang), never more
    /// than [`DEFAULT_MAX_PAYLOAD`] plus the header, and the file plus its decoded grid
    /// must fit the memory limit ([`crate::limits::check_memory`]).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, GridError> {
        let path = path.as_ref();
        let limit = DEFAULT_MAX_PAYLOAD + HEADER_BYTES as u64 + 4;
        if let Ok(meta) = std::fs::metadata(path) {
            if meta.is_file() && meta.len() > limit {
                return Err(GridError::file(K::TooLarge {
                    bytes: meta.len(),
                    limit: DEFAULT_MAX_PAYLOAD,
                })
                .with_path(path));
            }
            crate::limits::check_memory(
                &format!("reading {}", path.display()),
                meta.len().saturating_mul(2),
            )?;
        }
        let bytes = crate::limits::read_file(path, limit)?;
        Self::from_bytes(&bytes).map_err(|e| e.with_path(path))
    }
}

macro_rules! into_kind {
    ($fn:ident, $variant:ident, $ty:ty) => {
        /// The grid if the file holds this kind; a `WrongKind` error otherwise.
        pub fn $fn(self) -> Result<$ty, GridError> {
            let found = self.kind().name();
            match self {
                GridFile::$variant(g) => Ok(g),
                _ => Err(GridError::file(K::WrongKind {
                    expected: GridKind::$variant.name(),
                    found,
                })),
            }
        }
    };
}

impl GridFile {
    into_kind!(into_material, Material, Grid<Material>);
    into_kind!(into_light, Light, Grid<BinLight>);
    into_kind!(into_packed_light, PackedLight, PackedLightGrid);
    into_kind!(into_average, Average, Grid<AverageLight>);
    into_kind!(into_dominant, Dominant, Grid<DominantDir>);
    into_kind!(into_coded_light, CodedLight, CodedLightGrid);
    into_kind!(into_horizon, Horizon, Grid<crate::HorizonLight>);
}

struct Header {
    kind: GridKind,
    desc: GridDesc,
    exposure: f32,
    payload_len: u64,
}

fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}
fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}

fn parse_header(b: &[u8], max_payload: u64) -> Result<Header, GridError> {
    let fail = |k| Err(GridError::file(k));
    if b.len() < 8 || b[..8] != MAGIC {
        return fail(K::BadMagic {
            found: b[..b.len().min(8)].to_vec(),
        });
    }
    if b.len() < HEADER_BYTES {
        return fail(K::Truncated {
            needed: HEADER_BYTES as u64,
            found: b.len() as u64,
        });
    }
    let version = u32_at(b, 8);
    if version != VERSION {
        return fail(K::UnsupportedVersion {
            found: version,
            supported: VERSION,
        });
    }
    let payload_len = u64::from_le_bytes(b[56..64].try_into().unwrap());
    if payload_len > max_payload {
        return fail(K::TooLarge {
            bytes: payload_len,
            limit: max_payload,
        });
    }
    // (A payload length near u64::MAX, allowed by a limit of u64::MAX, must not wrap.)
    let needed = payload_len.saturating_add(HEADER_BYTES as u64 + 4);
    if (b.len() as u64) < needed {
        return fail(K::Truncated {
            needed,
            found: b.len() as u64,
        });
    }
    if b.len() as u64 > needed {
        return fail(K::TrailingBytes {
            extra: b.len() as u64 - needed,
        });
    }
    let body = needed as usize - 4;
    let stored = u32_at(b, body);
    let computed = crc32fast::hash(&b[..body]);
    if stored != computed {
        return fail(K::Checksum { stored, computed });
    }
    let bad =
        |field: &'static str, value: String| Err(GridError::file(K::BadHeader { field, value }));
    let kind_raw = u32_at(b, 12);
    let Some(kind) = GridKind::from_u32(kind_raw) else {
        return bad("kind", kind_raw.to_string());
    };
    let encoding = u32_at(b, 16);
    if encoding != kind.encoding() {
        return bad("encoding", encoding.to_string());
    }
    let origin = Vec3::new(f32_at(b, 20), f32_at(b, 24), f32_at(b, 28));
    let h = f32_at(b, 32);
    let dims = UVec3::new(u32_at(b, 36), u32_at(b, 40), u32_at(b, 44));
    let desc = GridDesc::new(origin, h, dims).map_err(|e| {
        GridError::file(K::BadHeader {
            field: "descriptor",
            value: e.to_string(),
        })
    })?;
    let exposure = f32_at(b, 48);
    if !(exposure.is_finite() && exposure > 0.0)
        || (!matches!(kind, GridKind::PackedLight | GridKind::CodedLight) && exposure != 1.0)
    {
        return bad("exposure", format!("{exposure:?}"));
    }
    if u32_at(b, 52) != 0 {
        return bad("reserved", u32_at(b, 52).to_string());
    }
    let per_point = match kind {
        GridKind::Material => Material::FILE_BYTES,
        GridKind::Light => BinLight::FILE_BYTES,
        GridKind::PackedLight => PackedBins::FILE_BYTES,
        GridKind::Average => AverageLight::FILE_BYTES,
        GridKind::Dominant => DominantDir::FILE_BYTES,
        GridKind::CodedLight => CodedBins::FILE_BYTES,
        GridKind::Horizon => crate::HorizonLight::FILE_BYTES,
    } as u64;
    let expected = kind.prefix_bytes() + desc.point_count() as u64 * per_point;
    if expected != payload_len {
        return bad(
            "payload length",
            format!("{payload_len} (dims {dims} need {expected})"),
        );
    }
    Ok(Header {
        kind,
        desc,
        exposure,
        payload_len,
    })
}

fn encode<T: GridValue>(g: &Grid<T>, exposure: f32) -> Vec<u8> {
    encode_with(g, exposure, &[])
}

/// The file of `g`, its payload starting with `prefix` (the kind's prefix bytes).
fn encode_with<T: GridValue>(g: &Grid<T>, exposure: f32, prefix: &[u8]) -> Vec<u8> {
    let payload = prefix.len() + g.data().len() * T::FILE_BYTES;
    let mut out = Vec::with_capacity(HEADER_BYTES + payload + 4);
    out.extend_from_slice(&MAGIC);
    let d = g.desc();
    for v in [VERSION, T::KIND as u32, T::KIND.encoding()] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [d.origin().x, d.origin().y, d.origin().z, d.h()] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in d.dims().to_array() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&exposure.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(payload as u64).to_le_bytes());
    out.extend_from_slice(prefix);
    for v in g.data() {
        v.write_le(&mut out);
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

fn decode<T: GridValue>(desc: GridDesc, payload: &[u8]) -> Result<Grid<T>, GridError> {
    let data: Vec<T> = payload
        .chunks_exact(T::FILE_BYTES)
        .map(T::read_le)
        .collect();
    Grid::new(desc, data).map_err(|e| match e {
        GridError::InvalidField {
            field,
            value,
            reason,
        } => GridError::file(K::BadValue {
            field,
            value,
            reason,
        }),
        other => other,
    })
}

impl GridFile {
    /// A few lines for people: kind, origin, cell size, dims, points, and a summary of
    /// the values (cells with material; largest bin value and mean average light).
    pub fn describe(&self) -> String {
        let light_summary = |g: &crate::LightGrid| {
            let n = g.data().len().max(1) as f32;
            let mean = g.data().iter().map(|b| b.average()).sum::<glam::Vec3>() / n;
            format!(
                "largest bin value: {}\nmean average light: {mean}\n",
                g.max_value()
            )
        };
        let (desc, extra) = match self {
            GridFile::Material(g) => {
                let filled = g.data().iter().filter(|m| !m.is_empty()).count();
                (*g.desc(), format!("cells with material: {filled}\n"))
            }
            GridFile::Light(g) => (*g.desc(), light_summary(g)),
            GridFile::PackedLight(p) => (
                *p.grid.desc(),
                format!("exposure: {}\n{}", p.exposure, light_summary(&p.unpack())),
            ),
            GridFile::Average(g) => (*g.desc(), String::new()),
            GridFile::Dominant(g) => (*g.desc(), String::new()),
            GridFile::Horizon(g) => (*g.desc(), String::new()),
            GridFile::CodedLight(c) => (
                *c.grid.desc(),
                format!(
                    "scale: {}\nkey: {:#018x}\n{}",
                    c.scale,
                    c.key,
                    light_summary(&c.decode())
                ),
            ),
        };
        format!(
            "kind: {}\norigin: {}\ncell size: {} m\ndims: {}\npoints: {}\n{extra}",
            self.kind().name(),
            desc.origin(),
            desc.h(),
            desc.dims(),
            desc.point_count()
        )
    }
}

/// Writes `bytes` to `path` atomically (temporary file in the same folder, synced, renamed).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), GridError> {
    write_all_atomic(&[(path.to_path_buf(), bytes)])
}

/// Writes several files as one: each to a temporary file beside it first (as
/// [`write_atomic`]), then all renamed into place. A failure while writing leaves none of
/// them; one while renaming (rare: the temporaries sit in the targets' folders) removes
/// those already renamed and the rest, so the set appears whole or not at all (a file
/// it replaced is then gone too). Targets must differ.
pub fn write_all_atomic<B: AsRef<[u8]>>(files: &[(PathBuf, B)]) -> Result<(), GridError> {
    for (i, (p, _)) in files.iter().enumerate() {
        if files[..i].iter().any(|(q, _)| q == p) {
            return Err(GridError::invalid("files", p, "must name each target once"));
        }
    }
    // Unique per process and per call: two threads (or two processes) writing the same
    // target never share a temporary file; `create_new` refuses to reuse a stale one.
    static SERIAL: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let mut temps: Vec<PathBuf> = Vec::with_capacity(files.len());
    let cleanup = |temps: &[PathBuf]| {
        for t in temps {
            let _ = std::fs::remove_file(t);
        }
    };
    for (path, bytes) in files {
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let Some(name) = path.file_name() else {
            cleanup(&temps);
            return Err(GridError::invalid("path", path, "must name a file"));
        };
        let serial = SERIAL.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tmp = dir.join(format!(
            ".{}.{}-{serial}.tmp",
            name.to_string_lossy(),
            std::process::id()
        ));
        let written = (|| {
            let mut f = std::fs::File::options()
                .write(true)
                .create_new(true)
                .open(&tmp)?;
            temps.push(tmp.clone());
            f.write_all(bytes.as_ref())?;
            f.sync_all()
        })();
        if let Err(source) = written {
            cleanup(&temps);
            return Err(GridError::Io {
                path: path.clone(),
                source,
            });
        }
    }
    for (k, ((path, _), tmp)) in files.iter().zip(&temps).enumerate() {
        if let Err(source) = std::fs::rename(tmp, path) {
            let placed: Vec<PathBuf> = files[..k].iter().map(|(p, _)| p.clone()).collect();
            cleanup(&placed);
            cleanup(&temps[k..]);
            return Err(GridError::Io {
                path: path.clone(),
                source,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_payload_length_near_u64_max_is_an_error_not_a_wrap() {
        let mut b = GridFile::Light(sample_light()).to_bytes();
        b[56..64].copy_from_slice(&(u64::MAX - 8).to_le_bytes());
        let e = GridFile::from_bytes_limited(&b, u64::MAX)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("truncated: 18446744073709551615 bytes needed"),
            "{e}"
        );
    }

    #[test]
    fn a_set_of_files_appears_whole_or_not_at_all() {
        let dir = std::env::temp_dir().join(format!("lightgrid-set-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let set = |names: &[&str]| -> Vec<(PathBuf, Vec<u8>)> {
            names
                .iter()
                .map(|n| (dir.join(n), n.as_bytes().to_vec()))
                .collect()
        };
        write_all_atomic(&set(&["a", "b", "c"])).unwrap();
        for n in ["a", "b", "c"] {
            assert_eq!(std::fs::read(dir.join(n)).unwrap(), n.as_bytes());
        }
        // The last target is a folder: its rename fails; the others are taken back.
        std::fs::create_dir(dir.join("z")).unwrap();
        assert!(write_all_atomic(&set(&["x", "y", "z"])).is_err());
        assert!(!dir.join("x").exists() && !dir.join("y").exists());
        // A folder that does not exist: nothing is written.
        let mut bad = set(&["p"]);
        bad.push((dir.join("missing/q"), vec![1]));
        assert!(write_all_atomic(&bad).is_err());
        assert!(!dir.join("p").exists());
        // No temporaries are left behind, and a target named twice is refused.
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        assert!(write_all_atomic(&set(&["a", "a"])).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn sample_light() -> Grid<BinLight> {
        let d = GridDesc::new(Vec3::new(1.0, 2.0, 3.0), 0.5, UVec3::new(3, 2, 2)).unwrap();
        let data = (0..d.point_count())
            .map(|i| BinLight(std::array::from_fn(|b| Vec3::new(i as f32, b as f32, 0.5))))
            .collect();
        Grid::new(d, data).unwrap()
    }

    fn all_kinds() -> Vec<GridFile> {
        let l = sample_light();
        let m = l.map(|b| Material {
            reflectance: Vec3::splat(0.5),
            pass: (b.0[0].x / 20.0).min(1.0),
        });
        vec![
            GridFile::Material(m),
            GridFile::PackedLight(l.pack()),
            GridFile::Average(l.average_grid()),
            GridFile::Dominant(l.dominant_grid()),
            GridFile::CodedLight(
                CodedLightGrid::new(
                    l.map(|b| CodedBins(b.0.map(|v| [v.x as u8 * 9, v.y as u8, 200]))),
                    3.5,
                    0xfeed_beef_0123_4567,
                )
                .unwrap(),
            ),
            GridFile::Horizon(l.map(crate::HorizonLight::even)),
            GridFile::Light(l),
        ]
    }

    /// The coded kind's payload: the key first, then 78 bytes a point; the exposure
    /// field holds the scale; codes decode on the square-root curve.
    #[test]
    fn coded_light_layout_and_decoding() {
        let f = &all_kinds()[4];
        let GridFile::CodedLight(c) = f else { panic!() };
        let b = f.to_bytes();
        assert_eq!(u32_at(&b, 12), 6);
        assert_eq!(u32_at(&b, 16), 2);
        assert_eq!(f32_at(&b, 48), 3.5);
        assert_eq!(b[64..72], 0xfeed_beef_0123_4567u64.to_le_bytes());
        assert_eq!(b.len(), 64 + 8 + 12 * 78 + 4);
        assert_eq!(b[72..75], c.grid.data()[0].0[0]);
        let d = c.decode();
        let code = c.grid.data()[1].0[2];
        let want = |k: u8| (k as f32 / 255.0).powi(2) * 3.5;
        assert!(
            (d.data()[1].0[2] - Vec3::new(want(code[0]), want(code[1]), want(code[2]))).length()
                < 1e-6
        );
        // A zero or NaN scale is refused when reading.
        for bad in [0.0f32, f32::NAN] {
            let mut b = b.clone();
            b[48..52].copy_from_slice(&bad.to_le_bytes());
            assert!(matches!(
                kind_of(GridFile::from_bytes(&resign(b))),
                K::BadHeader {
                    field: "exposure",
                    ..
                }
            ));
        }
    }

    #[test]
    fn round_trip_every_kind_through_disk() {
        let dir = std::env::temp_dir().join(format!("grid-core-file-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for f in all_kinds() {
            let path = dir.join(format!("{}.lgrid", f.kind() as u32));
            f.save(&path).unwrap();
            let back = GridFile::load(&path).unwrap();
            assert_eq!(back, f);
            // No temporary file is left behind.
            let leftovers: Vec<_> = std::fs::read_dir(&dir)
                .unwrap()
                .filter(|e| {
                    e.as_ref()
                        .unwrap()
                        .file_name()
                        .to_string_lossy()
                        .ends_with(".tmp")
                })
                .collect();
            assert!(leftovers.is_empty());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn header_layout_matches_the_table() {
        let b = GridFile::Light(sample_light()).to_bytes();
        assert_eq!(&b[..8], b"LTGRID\x1a\n");
        assert_eq!(u32_at(&b, 8), 1);
        assert_eq!(u32_at(&b, 12), 2);
        assert_eq!(f32_at(&b, 20), 1.0);
        assert_eq!(f32_at(&b, 32), 0.5);
        assert_eq!(u32_at(&b, 36), 3);
        assert_eq!(u64::from_le_bytes(b[56..64].try_into().unwrap()), 12 * 312);
        assert_eq!(b.len(), 64 + 12 * 312 + 4);
        // Point 1, bin 2: r = 1.0 (point index), g = 2.0 (bin index).
        let o = 64 + 312 + 2 * 12;
        assert_eq!((f32_at(&b, o), f32_at(&b, o + 4)), (1.0, 2.0));
    }

    fn kind_of(r: Result<GridFile, GridError>) -> K {
        match r {
            Err(GridError::File { kind, .. }) => kind,
            other => panic!("expected a file error, got {other:?}"),
        }
    }

    #[test]
    fn typed_errors() {
        let good = GridFile::Light(sample_light()).to_bytes();
        assert!(matches!(
            kind_of(GridFile::from_bytes(b"PNG")),
            K::BadMagic { .. }
        ));
        assert!(matches!(
            kind_of(GridFile::from_bytes(&good[..40])),
            K::Truncated { .. }
        ));
        assert!(matches!(
            kind_of(GridFile::from_bytes(&good[..good.len() - 1])),
            K::Truncated { .. }
        ));
        let mut long = good.clone();
        long.push(0);
        assert!(matches!(
            kind_of(GridFile::from_bytes(&long)),
            K::TrailingBytes { extra: 1 }
        ));
        let mut v2 = good.clone();
        v2[8] = 2;
        assert_eq!(
            kind_of(GridFile::from_bytes(&v2)),
            K::UnsupportedVersion {
                found: 2,
                supported: 1
            }
        );
        let mut flip = good.clone();
        flip[100] ^= 1;
        assert!(matches!(
            kind_of(GridFile::from_bytes(&flip)),
            K::Checksum { .. }
        ));
        assert!(matches!(
            kind_of(GridFile::from_bytes_limited(&good, 100)),
            K::TooLarge { limit: 100, .. }
        ));
        let e = GridFile::from_bytes(&good)
            .unwrap()
            .into_material()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("holds a light grid, expected a material grid"),
            "{e}"
        );
        // A NaN written into the payload (with a valid checksum) is a typed error too.
        let mut nan = good.clone();
        nan[64..68].copy_from_slice(&f32::NAN.to_le_bytes());
        let n = nan.len() - 4;
        let crc = crc32fast::hash(&nan[..n]);
        nan[n..].copy_from_slice(&crc.to_le_bytes());
        assert!(matches!(
            kind_of(GridFile::from_bytes(&nan)),
            K::BadValue { .. }
        ));
        let missing = GridFile::load("/nonexistent/x.lgrid")
            .unwrap_err()
            .to_string();
        assert!(missing.contains("/nonexistent/x.lgrid"), "{missing}");
    }

    /// Re-signs a mutated body so the mutation reaches the header and payload checks.
    fn resign(mut b: Vec<u8>) -> Vec<u8> {
        if b.len() >= 4 {
            let n = b.len() - 4;
            let crc = crc32fast::hash(&b[..n]);
            b[n..].copy_from_slice(&crc.to_le_bytes());
        }
        b
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]
        #[test]
        fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
            let _ = GridFile::from_bytes(&bytes);
            let mut with_magic = MAGIC.to_vec();
            with_magic.extend_from_slice(&bytes);
            let _ = GridFile::from_bytes(&with_magic);
        }

        #[test]
        fn mutated_files_never_panic(which in 0usize..7, pos in any::<prop::sample::Index>(), val in any::<u8>(), cut in any::<prop::sample::Index>(), sign in any::<bool>()) {
            let good = all_kinds()[which].to_bytes();
            let mut b = good.clone();
            let i = pos.index(b.len());
            b[i] = val;
            if sign { b = resign(b); }
            match GridFile::from_bytes(&b) {
                Ok(f) => prop_assert!(b == good || f.to_bytes() == b),
                Err(e) => prop_assert!(!e.to_string().is_empty()),
            }
            let t = cut.index(good.len());
            prop_assert!(GridFile::from_bytes(&good[..t]).is_err());
        }
    }

    #[test]
    fn describe_names_kind_size_and_values() {
        let d = GridDesc::new(Vec3::new(1.0, 2.0, 3.0), 0.5, UVec3::new(2, 3, 4)).unwrap();
        let light = GridFile::Light(
            crate::LightGrid::filled(d, crate::BinLight::uniform(Vec3::ONE)).unwrap(),
        );
        let t = light.describe();
        for want in [
            "kind: light",
            "cell size: 0.5 m",
            "points: 24",
            "mean average light: [1, 1, 1]",
        ] {
            assert!(t.contains(want), "{want:?} in {t}");
        }
        let mut m = crate::MaterialGrid::filled(d, crate::Material::EMPTY).unwrap();
        m.data_mut()[5] = crate::Material::opaque(Vec3::ONE);
        assert!(
            GridFile::Material(m)
                .describe()
                .contains("cells with material: 1")
        );
    }
}
