//! Hand-made bad inputs for light-volume cache files and light sets.

use std::path::{Path, PathBuf};

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{BinLight, GridDesc, LightGrid};
use lightgrid_light_volumes::{CompressedVolume, LightSet};

const KEY: u64 = 77;

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("light-volumes-bad-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn volume() -> (GridDesc, CompressedVolume) {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 3, 4)).unwrap();
    let mut data = vec![BinLight::ZERO; d.point_count()];
    data[5].0[3] = Vec3::new(2.0, 1.0, 0.5);
    data[20].0[7] = Vec3::ONE;
    (
        d,
        CompressedVolume::compress(&LightGrid::new(d, data).unwrap(), KEY),
    )
}

fn resign(mut b: Vec<u8>) -> Vec<u8> {
    let n = b.len() - 4;
    let crc = crc32fast::hash(&b[..n]);
    b[n..].copy_from_slice(&crc.to_le_bytes());
    b
}

#[test]
fn corrupt_cache_files_are_errors() {
    let (_, v) = volume();
    let good = v.to_bytes();
    assert!(CompressedVolume::from_bytes(&good, KEY).is_ok());
    for cut in 0..good.len() {
        assert!(
            CompressedVolume::from_bytes(&good[..cut], KEY).is_err(),
            "cut {cut}"
        );
    }
    // Dims that wrap (2^22 cubed), zero cell size, NaN scale: with a valid checksum
    // (offsets of lightgrid_core::file's header: h 32, dims 36, exposure = scale 48).
    let dims_at = 36;
    let mut b = good.clone();
    for k in 0..3 {
        b[dims_at + 4 * k..dims_at + 4 * k + 4].copy_from_slice(&(1u32 << 22).to_le_bytes());
    }
    assert!(CompressedVolume::from_bytes(&resign(b), KEY).is_err());
    let mut b = good.clone();
    b[32..36].copy_from_slice(&0f32.to_le_bytes());
    let e = CompressedVolume::from_bytes(&resign(b), KEY)
        .unwrap_err()
        .to_string();
    assert!(e.contains("invalid h = 0"), "{e}");
    let mut b = good.clone();
    b[48..52].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = CompressedVolume::from_bytes(&resign(b), KEY)
        .unwrap_err()
        .to_string();
    assert!(e.contains("exposure"), "{e}");
}

#[test]
fn cache_readers_refuse_devices_fifos_and_folders_and_name_the_file() {
    let dir = scratch("special");
    let mut bad: Vec<PathBuf> = vec![dir.clone()];
    if Path::new("/dev/zero").exists() {
        bad.push("/dev/zero".into());
    }
    let fifo = dir.join("v.lvol");
    if std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        bad.push(fifo);
    }
    for p in bad {
        assert!(CompressedVolume::load(&p, KEY).is_err(), "{}", p.display());
    }
    // A corrupt file's error names the file.
    let f = dir.join("corrupt.lvol");
    std::fs::write(
        &f,
        b"LGVOL\0garbage-garbage-garbage-garbage-garbage-garbage-garbage",
    )
    .unwrap();
    let e = CompressedVolume::load(&f, KEY).unwrap_err().to_string();
    assert!(e.contains("corrupt.lvol"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn colour_times_intensity_cannot_overflow_to_infinity() {
    let (d, v) = volume();
    let mut set = LightSet::new(d).unwrap();
    let e = set
        .add(&v, Vec3::splat(1e30), 1e30)
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("colour x intensity"), "{e}");
    // The largest allowed factor, many times over: sums saturate, never infinity or NaN.
    let ids: Vec<_> = (0..8)
        .map(|_| set.add(&v, Vec3::ONE, 1e30).unwrap())
        .collect();
    assert!(set.grid().data().iter().all(|b| b.is_valid()));
    for id in ids {
        set.set_on(id, false).unwrap();
    }
    assert!(set.grid().data().iter().all(|b| b.is_valid()));
}
