//! The one error type of pipetrack.

use std::path::PathBuf;

/// Everything that can go wrong in pipetrack, as one enum.
///
/// Input problems (`Input`, `Io`, `Json`) name the file they concern, so a
/// command-line user sees one line that says what to fix.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or stream a user gave us is missing, unreadable or malformed.
    #[error("{path}: {message}")]
    Input {
        /// The file (or `-` for stdin) the problem is in.
        path: PathBuf,
        /// What is wrong with it, in one line.
        message: String,
    },
    /// A parameter is out of its documented range.
    #[error("invalid parameter: {0}")]
    Parameter(String),
    /// Images given to one operation do not have matching sizes.
    #[error("size mismatch: {0}")]
    Size(String),
    /// No GPU adapter could be found (the CPU backend still works).
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    /// The adapter exists but the device could not be created.
    #[error("GPU device request failed: {0}")]
    RequestDevice(#[from] wgpu::RequestDeviceError),
    /// The caller's device lacks a limit or feature pipetrack needs.
    #[error("GPU device unsuitable: {0}")]
    Unsuitable(String),
    /// A GPU operation failed (validation, mapping, timeout).
    #[error("GPU error: {0}")]
    Gpu(String),
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

impl Error {
    /// An input error for `path` with a one-line message.
    pub fn input(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Input { path: path.into(), message: message.into() }
    }

    /// An I/O error for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
}

impl From<wgpu::PollError> for Error {
    fn from(e: wgpu::PollError) -> Self {
        Error::Gpu(format!("poll: {e}"))
    }
}

impl From<wgpu::BufferAsyncError> for Error {
    fn from(e: wgpu::BufferAsyncError) -> Self {
        Error::Gpu(format!("buffer mapping: {e}"))
    }
}

/// `Result` with pipetrack's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
