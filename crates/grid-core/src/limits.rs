//! Limits on what user input may make the library do: how much memory one job may
//! allocate, and how many bytes a reader takes from one file.
//!
//! Every size a file or a scene value implies is checked **before** the allocation it
//! would drive, so a bad value is a typed error that names the field, not an abort in the
//! allocator or a machine swapping to death.
//!
//! # The memory limit
//!
//! One number for the process, read by [`memory_limit`]:
//!
//! 1. the value given to [`set_memory_limit`] (the command-line tools' `--memory-limit`),
//! 2. else the environment variable `LIGHTGRID_MEMORY_LIMIT` (bytes, or with a `K`, `M`,
//!    `G` or `T` suffix: `LIGHTGRID_MEMORY_LIMIT=12G`),
//! 3. else half of the machine's memory (`MemTotal` in `/proc/meminfo`), or 8 GiB where
//!    that cannot be read.
//!
//! [`check_memory`] compares an estimate with it; estimates are made with checked
//! arithmetic ([`checked_bytes`]) so that an overflowing product is an error too.
//!
//! # Reading files
//!
//! [`read_file`] reads a whole file only if it is a regular file (a FIFO would block the
//! reader forever, `/dev/zero` never ends) of at most the given number of bytes, and reads
//! at most that many bytes even if the file grows meanwhile. Errors name the path.
//!
//! ```
//! use lightgrid_core::limits;
//! // 2^22 cubed points of 312 bytes: the product overflows u64 and is an error.
//! let e = limits::checked_bytes("dims", &[1 << 22, 1 << 22, 1 << 22, 312]).unwrap_err();
//! assert!(e.to_string().contains("dims"));
//! // A job that asks for more than the limit is refused before it allocates.
//! assert!(limits::check_memory("light grid", u64::MAX / 2).is_err());
//! assert!(limits::check_memory("light grid", 1 << 20).is_ok());
//! ```

use std::io::Read;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::GridError;

/// Fallback memory limit where the machine's memory cannot be read: 8 GiB.
pub const FALLBACK_MEMORY_LIMIT: u64 = 8 << 30;

/// The environment variable that sets the memory limit.
pub const MEMORY_LIMIT_ENV: &str = "LIGHTGRID_MEMORY_LIMIT";

static OVERRIDE: AtomicU64 = AtomicU64::new(0);

/// Sets the process-wide memory limit in bytes (0 returns to the default).
pub fn set_memory_limit(bytes: u64) {
    OVERRIDE.store(bytes, Ordering::Relaxed);
}

/// The memory limit in force, bytes (see the module docs for where it comes from).
pub fn memory_limit() -> u64 {
    let o = OVERRIDE.load(Ordering::Relaxed);
    if o > 0 {
        return o;
    }
    // The environment and the machine do not change while the process runs: read once.
    static DEFAULT: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *DEFAULT.get_or_init(|| {
        let half = || machine_memory().map_or(FALLBACK_MEMORY_LIMIT, |m| m / 2);
        match std::env::var(MEMORY_LIMIT_ENV) {
            Ok(text) => parse_size(&text).unwrap_or_else(|e| {
                // Said once, on stderr: a limit the user meant to set must not vanish.
                tracing::warn!("{MEMORY_LIMIT_ENV}: {e}; using half the machine's memory");
                half()
            }),
            Err(_) => half(),
        }
    })
}

/// Total memory of the machine in bytes, from `/proc/meminfo` (Linux); `None` elsewhere.
pub fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Parses a size: a whole number of bytes, optionally followed by `K`, `M`, `G` or `T`
/// (powers of 1024; a trailing `B` or `iB` is accepted). Errors name the text.
pub fn parse_size(text: &str) -> Result<u64, GridError> {
    let t = text.trim();
    let t = t
        .strip_suffix("iB")
        .or_else(|| t.strip_suffix('B'))
        .unwrap_or(t);
    let (digits, shift) = match t.chars().last() {
        Some('K' | 'k') => (&t[..t.len() - 1], 10),
        Some('M' | 'm') => (&t[..t.len() - 1], 20),
        Some('G' | 'g') => (&t[..t.len() - 1], 30),
        Some('T' | 't') => (&t[..t.len() - 1], 40),
        _ => (t, 0),
    };
    let bad = || GridError::invalid("size", text, "must be a whole number of bytes, e.g. 512M");
    let n: u64 = digits.trim().parse().map_err(|_| bad())?;
    n.checked_mul(1u64 << shift)
        .filter(|&v| v > 0)
        .ok_or_else(bad)
}

/// [`parse_size`] for command-line parsers (clap's `value_parser`): the error as text.
pub fn parse_size_arg(text: &str) -> Result<u64, String> {
    parse_size(text).map_err(|e| e.to_string())
}

/// The product of `factors` (counts and a size in bytes), or an error naming `field` when
/// it overflows `u64`.
pub fn checked_bytes(field: &str, factors: &[u64]) -> Result<u64, GridError> {
    factors
        .iter()
        .try_fold(1u64, |acc, &f| acc.checked_mul(f))
        .ok_or_else(|| GridError::invalid(field, factors, "size overflows 64 bits"))
}

/// `a × b` (the sides of an image, a heightmap, ...) if it is at most `max`; else an
/// error naming `field`.
pub fn checked_count(field: &str, a: u32, b: u32, max: u64) -> Result<u64, GridError> {
    let count = a as u64 * b as u64;
    if count > max {
        return Err(GridError::InvalidField {
            field: field.to_string(),
            value: format!("{a} x {b}"),
            reason: "too many samples for one map",
        });
    }
    Ok(count)
}

/// Checks that allocating `bytes` for `what` stays within [`memory_limit`].
pub fn check_memory(what: &str, bytes: u64) -> Result<(), GridError> {
    let limit = memory_limit();
    if bytes > limit {
        return Err(GridError::TooMuchMemory {
            what: what.to_string(),
            bytes,
            limit,
        });
    }
    Ok(())
}

/// Reads a whole regular file of at most `max_bytes` bytes. FIFOs, devices and folders
/// are refused before they are opened; a file larger than the limit is refused (checked
/// before reading and again while reading). Errors name the path.
pub fn read_file(path: &Path, max_bytes: u64) -> Result<Vec<u8>, GridError> {
    let io = |source| GridError::Io {
        path: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(GridError::invalid(
            "path",
            path,
            "is not a regular file (a folder, FIFO or device)",
        ));
    }
    let too_large = |bytes| GridError::FileTooLarge {
        path: path.to_path_buf(),
        bytes,
        limit: max_bytes,
    };
    if meta.len() > max_bytes {
        return Err(too_large(meta.len()));
    }
    let f = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    f.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// [`read_file`] for text: the bytes must be UTF-8 (the error names the path).
pub fn read_text(path: &Path, max_bytes: u64) -> Result<String, GridError> {
    let bytes = read_file(path, max_bytes)?;
    String::from_utf8(bytes).map_err(|e| GridError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_suffixes_and_refuse_nonsense() {
        assert_eq!(parse_size("512").unwrap(), 512);
        assert_eq!(parse_size("4K").unwrap(), 4096);
        assert_eq!(parse_size("3M").unwrap(), 3 << 20);
        assert_eq!(parse_size(" 12G ").unwrap(), 12 << 30);
        assert_eq!(parse_size("2GiB").unwrap(), 2 << 30);
        assert_eq!(parse_size("1T").unwrap(), 1 << 40);
        for bad in [
            "",
            "G",
            "-1",
            "0",
            "1.5G",
            "lots",
            "99999999999999999999",
            "20000000T",
        ] {
            assert!(parse_size(bad).is_err(), "{bad:?} accepted");
        }
    }

    #[test]
    fn checked_products_name_the_field() {
        assert_eq!(checked_bytes("x", &[2, 3, 4]).unwrap(), 24);
        let e = checked_bytes("dims", &[u64::MAX, 2])
            .unwrap_err()
            .to_string();
        assert!(e.contains("dims") && e.contains("overflow"), "{e}");
    }

    #[test]
    fn memory_limit_is_positive_and_can_be_overridden() {
        assert!(memory_limit() > 0);
        let e = check_memory("test grid", u64::MAX).unwrap_err().to_string();
        assert!(e.contains("test grid"), "{e}");
    }

    #[test]
    fn read_file_refuses_devices_folders_and_large_files() {
        let dir = std::env::temp_dir().join(format!("grid-core-limits-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("ten.bin");
        std::fs::write(&f, [7u8; 10]).unwrap();
        assert_eq!(read_file(&f, 10).unwrap(), vec![7u8; 10]);
        let e = read_file(&f, 9).unwrap_err().to_string();
        assert!(e.contains("ten.bin") && e.contains("limit"), "{e}");
        assert!(read_file(&dir, 100).is_err());
        if Path::new("/dev/zero").exists() {
            let e = read_file(Path::new("/dev/zero"), 100)
                .unwrap_err()
                .to_string();
            assert!(e.contains("regular file"), "{e}");
        }
        assert!(read_file(&dir.join("missing"), 100).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}
