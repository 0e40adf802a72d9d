//! The crate's error type. Library code returns typed errors; the binary adds context and prints them.
//! Every variant says which file, line or stage failed and why, so that a user on a cluster can act
//! on the message without a debugger.

use std::fmt;
use std::path::PathBuf;

/// Everything that can go wrong in volspline.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// A data file is malformed: `location` is e.g. "line 12" or "vertex 5"; empty when the
    /// problem concerns the whole file (too few points, wrong magic number).
    Input { path: PathBuf, location: String, reason: String },
    /// The operating system refused a file operation.
    Io { path: PathBuf, reason: String },
    /// An option or argument is invalid (bad carrier spec, grid size, ...).
    Usage(String),
    /// The data or the system is numerically unusable (singular matrix, points not unisolvent, ...).
    Numerical(String),
    /// The projected block of the spline system is not definite to working precision (the
    /// Cholesky solver's signal to fall back to LU).
    NotDefinite(String),
    /// A rank would need more memory than it can have (the figures and what to do are in the
    /// message).
    Memory(String),
    /// HDF5 failed on a file.
    Hdf5 { path: PathBuf, reason: String },
    /// Another rank failed with `source`; carried whole (kind included) so that every rank reports
    /// the same failure and takes the same branch on its kind.
    Remote { rank: usize, source: Box<Error> },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn input(path: impl Into<PathBuf>, location: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::Input { path: path.into(), location: location.into(), reason: reason.into() }
    }

    pub fn io(path: impl Into<PathBuf>, err: &std::io::Error) -> Self {
        Error::Io { path: path.into(), reason: err.to_string() }
    }

    pub fn hdf5(path: impl Into<PathBuf>, err: impl fmt::Display) -> Self {
        Error::Hdf5 { path: path.into(), reason: err.to_string() }
    }

    /// The failure itself, wherever it happened: the error inside any [`Error::Remote`].
    pub fn root(&self) -> &Error {
        match self {
            Error::Remote { source, .. } => source.root(),
            other => other,
        }
    }

    /// The rank the failure happened on, when it was another one.
    pub fn remote_rank(&self) -> Option<usize> {
        match self {
            Error::Remote { rank, .. } => Some(*rank),
            _ => None,
        }
    }

    /// Whether this is the signal of a Cholesky factorisation that met a non-positive pivot.
    pub fn is_not_definite(&self) -> bool {
        matches!(self.root(), Error::NotDefinite(_))
    }

    /// The process exit status for this error: 2 for usage errors, 1 otherwise.
    pub fn exit_code(&self) -> i32 {
        match self.root() {
            Error::Usage(_) => 2,
            _ => 1,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Input { path, location, reason } if location.is_empty() => {
                write!(f, "{}: {reason}", path.display())
            }
            Error::Input { path, location, reason } => write!(f, "{}: {location}: {reason}", path.display()),
            Error::Io { path, reason } => write!(f, "{}: {reason}", path.display()),
            Error::Usage(msg) => write!(f, "invalid argument: {msg}"),
            Error::Numerical(msg) => write!(f, "numerical failure: {msg}"),
            Error::NotDefinite(msg) => write!(f, "not definite: {msg}"),
            Error::Memory(msg) => write!(f, "not enough memory: {msg}"),
            Error::Hdf5 { path, reason } => write!(f, "{}: HDF5 error: {reason}", path.display()),
            Error::Remote { source, .. } => write!(f, "{source}"),
        }
    }
}

impl std::error::Error for Error {}
