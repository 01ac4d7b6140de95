//! Hand-made bad inputs for grid-core's readers: sizes that wrap, files that are not
//! files, exposures that would unpack to NaN, concurrent atomic writes.

use std::path::{Path, PathBuf};

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{BinLight, GridDesc, GridError, GridFile, LightGrid};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("grid-core-bad-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A header for `dims` with a payload length of 0 and a valid checksum: 68 bytes.
fn header_only(kind: u32, dims: [u32; 3], payload_len: u64, exposure: f32) -> Vec<u8> {
    let mut b = lightgrid_core::file::MAGIC.to_vec();
    let encoding = u32::from(kind == 3); // R11G11B10 words for packed light
    for v in [lightgrid_core::file::VERSION, kind, encoding] {
        b.extend(v.to_le_bytes());
    }
    for v in [0f32, 0.0, 0.0, 1.0] {
        b.extend(v.to_le_bytes());
    }
    for v in dims {
        b.extend(v.to_le_bytes());
    }
    b.extend(exposure.to_le_bytes());
    b.extend(0u32.to_le_bytes());
    b.extend(payload_len.to_le_bytes());
    let crc = crc32fast::hash(&b);
    b.extend(crc.to_le_bytes());
    b
}

#[test]
fn dims_whose_product_wraps_are_refused() {
    // 2^22 cubed points = 2^66: a plain u64 product wraps to 0 and a 68-byte file with
    // an empty payload looked valid.
    let b = header_only(1, [1 << 22, 1 << 22, 1 << 22], 0, 1.0);
    assert_eq!(b.len(), 68);
    let e = GridFile::from_bytes(&b).unwrap_err().to_string();
    assert!(e.contains("dims"), "{e}");
    // Every other wrapping product as well.
    for dims in [
        [u32::MAX; 3],
        [1 << 31, 1 << 31, 4],
        [1 << 16, 1 << 16, 1 << 16],
    ] {
        assert!(GridFile::from_bytes(&header_only(2, dims, 0, 1.0)).is_err());
    }
}

#[test]
fn packed_files_with_a_subnormal_exposure_are_refused() {
    // One point of 26 words of 0: valid except for the exposure.
    for exposure in [1e-40f32, f32::MIN_POSITIVE, 1e-37] {
        let mut b = header_only(3, [1, 1, 1], 104, exposure);
        b.truncate(64);
        b.extend([0u8; 104]);
        let crc = crc32fast::hash(&b);
        b.extend(crc.to_le_bytes());
        let e = GridFile::from_bytes(&b).unwrap_err().to_string();
        assert!(e.contains("exposure"), "{exposure}: {e}");
    }
}

#[cfg(unix)]
fn mkfifo(p: &Path) -> bool {
    std::process::Command::new("mkfifo")
        .arg(p)
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn readers_refuse_devices_fifos_and_folders_without_blocking() {
    let dir = scratch("special");
    let mut specials = vec![dir.clone()];
    if Path::new("/dev/zero").exists() {
        specials.push("/dev/zero".into());
    }
    #[cfg(unix)]
    {
        let fifo = dir.join("fifo.lgrid");
        assert!(mkfifo(&fifo), "mkfifo failed");
        specials.push(fifo);
    }
    for p in &specials {
        let e = GridFile::load(p).unwrap_err().to_string();
        assert!(e.contains("regular file"), "{}: {e}", p.display());
        assert!(lightgrid_core::limits::read_file(p, 1 << 20).is_err());
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_file_over_the_memory_limit_is_refused_before_reading() {
    // Memory limit 1 KiB: a 10 KiB grid file (file plus decoded grid) does not fit.
    let dir = scratch("limit");
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 4, 2)).unwrap();
    let g = LightGrid::filled(d, BinLight::uniform(Vec3::ONE)).unwrap();
    let p = dir.join("g.lgrid");
    GridFile::Light(g).save(&p).unwrap();
    // The limit is process-wide: no other test of this binary checks memory meanwhile.
    lightgrid_core::limits::set_memory_limit(1 << 10);
    let r = GridFile::load(&p);
    lightgrid_core::limits::set_memory_limit(0);
    match r {
        Err(GridError::TooMuchMemory { bytes, limit, .. }) => {
            assert!(bytes > limit && limit == 1 << 10)
        }
        other => panic!("expected TooMuchMemory, got {other:?}"),
    }
    assert!(GridFile::load(&p).is_ok());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn concurrent_atomic_writes_to_one_target_never_mix_or_leave_temporaries() {
    let dir = scratch("atomic");
    let target = dir.join("out.bin");
    std::thread::scope(|s| {
        for t in 0..8u8 {
            let target = &target;
            s.spawn(move || {
                for _ in 0..20 {
                    lightgrid_core::file::write_atomic(target, &vec![t; 4096]).unwrap();
                }
            });
        }
    });
    let b = std::fs::read(&target).unwrap();
    assert_eq!(b.len(), 4096);
    assert!(b.iter().all(|&x| x == b[0]), "bytes of two writers mixed");
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "leftovers: {names:?}");
    std::fs::remove_dir_all(&dir).ok();
}
