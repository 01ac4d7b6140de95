//! Typed errors. Every error names the field (or file) and the bad value.

use std::path::PathBuf;

/// Errors of `grid-core`: invalid input values and unreadable files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GridError {
    /// An input value is out of its allowed range (NaN, infinity, negative, zero, ...).
    #[error("invalid {field} = {value}: {reason}")]
    InvalidField {
        /// The field, with an index where it is an element of an array (`cells[12].pass`).
        field: String,
        /// The offending value, as printed by `Debug`.
        value: String,
        /// What the value must be.
        reason: &'static str,
    },
    /// A data array has the wrong number of elements for its grid descriptor.
    #[error("{field} has {found} elements, the descriptor needs {expected}")]
    LengthMismatch {
        /// Which array.
        field: &'static str,
        /// Elements the descriptor implies.
        expected: usize,
        /// Elements given.
        found: usize,
    },
    /// A data array that may hold either of two numbers of elements holds neither
    /// (a [`TopBoundary::PerPoint`](crate::TopBoundary::PerPoint) top: one value per
    /// column of the grid, or per column of the grid and its halo's ring).
    #[error("{field} has {found} elements, the descriptor needs {expected} or {or}")]
    LengthMismatchEither {
        /// Which array.
        field: &'static str,
        /// One number of elements the descriptor allows.
        expected: usize,
        /// The other.
        or: usize,
        /// Elements given.
        found: usize,
    },
    /// Reading or writing a file failed at the operating-system level.
    #[error("I/O error on {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A job would allocate more memory than the limit in force
    /// ([`crate::limits::memory_limit`]).
    #[error(
        "{what} needs {bytes} bytes of memory, over the limit of {limit} bytes (raise it with --memory-limit or LIGHTGRID_MEMORY_LIMIT)"
    )]
    TooMuchMemory {
        /// What would be allocated, with the values that size it.
        what: String,
        /// Bytes it needs.
        bytes: u64,
        /// The limit in force.
        limit: u64,
    },
    /// A file is larger than its reader accepts.
    #[error("{}: {bytes} bytes is over this reader's limit of {limit} bytes", path.display())]
    FileTooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (or the bytes read before giving up).
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// A grid file is malformed.
    #[error("grid file{}: {kind}", .path.as_ref().map(|p| format!(" {}", p.display())).unwrap_or_default())]
    File {
        /// The file, when the bytes came from one.
        path: Option<PathBuf>,
        /// What is wrong with it.
        kind: FileErrorKind,
    },
}

/// What is wrong with a grid file.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FileErrorKind {
    /// The first 8 bytes are not the lightgrid magic.
    #[error("not a lightgrid file (magic {found:02x?})")]
    BadMagic {
        /// The bytes found.
        found: Vec<u8>,
    },
    /// The format version is one this build cannot read.
    #[error("format version {found} is not supported (this build reads version {supported})")]
    UnsupportedVersion {
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },
    /// The file ends before its header or payload does.
    #[error("truncated: {needed} bytes needed, {found} present")]
    Truncated {
        /// Bytes the header says the file has.
        needed: u64,
        /// Bytes present.
        found: u64,
    },
    /// The file has bytes after its checksum.
    #[error("{extra} unexpected bytes after the checksum")]
    TrailingBytes {
        /// How many.
        extra: u64,
    },
    /// The CRC-32 does not match the content.
    #[error("checksum mismatch: stored {stored:#010x}, computed {computed:#010x}")]
    Checksum {
        /// CRC stored in the file.
        stored: u32,
        /// CRC of the content read.
        computed: u32,
    },
    /// A header field has a value no writer produces.
    #[error("header field {field} = {value} is invalid")]
    BadHeader {
        /// Which header field.
        field: &'static str,
        /// Its value.
        value: String,
    },
    /// The grid holds a different kind of data than the caller asked for.
    #[error("holds a {found} grid, expected a {expected} grid")]
    WrongKind {
        /// Kind asked for.
        expected: &'static str,
        /// Kind in the file.
        found: &'static str,
    },
    /// The payload is larger than the reader's limit.
    #[error("payload of {bytes} bytes exceeds the limit of {limit} bytes")]
    TooLarge {
        /// Payload size the header claims.
        bytes: u64,
        /// The limit in force.
        limit: u64,
    },
    /// A payload value is invalid (NaN, infinity, out of range).
    #[error("payload value {field} = {value} is invalid: {reason}")]
    BadValue {
        /// Which value, e.g. `cells[3].pass`.
        field: String,
        /// The value.
        value: String,
        /// What it must be.
        reason: &'static str,
    },
}

impl GridError {
    /// Shorthand for [`GridError::InvalidField`].
    pub fn invalid(
        field: impl Into<String>,
        value: impl std::fmt::Debug,
        reason: &'static str,
    ) -> Self {
        GridError::InvalidField {
            field: field.into(),
            value: format!("{value:?}"),
            reason,
        }
    }

    pub(crate) fn file(kind: FileErrorKind) -> Self {
        GridError::File { path: None, kind }
    }

    /// A file error without a path gets `p` (readers of other crates that parse bytes
    /// first and know the file after); other errors are unchanged.
    pub fn with_path(self, p: &std::path::Path) -> Self {
        match self {
            GridError::File { path: None, kind } => GridError::File {
                path: Some(p.to_path_buf()),
                kind,
            },
            other => other,
        }
    }
}

/// Checks that `v` is finite and inside `[lo, hi]`; the error names `field`.
pub(crate) fn check_range(
    field: impl FnOnce() -> String,
    v: f32,
    lo: f32,
    hi: f32,
) -> Result<(), GridError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(GridError::invalid(field(), v, range_reason(lo, hi)))
    }
}

fn range_reason(lo: f32, hi: f32) -> &'static str {
    if lo == 0.0 && hi == 1.0 {
        "must be finite and in [0, 1]"
    } else if lo == 0.0 && hi == f32::MAX {
        "must be finite and >= 0"
    } else {
        "must be finite and in range"
    }
}
