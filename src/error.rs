//! The one error type of pipetrack.

use std::path::PathBuf;

/// Everything that can go wrong in pipetrack, as one enum.
///
/// Input problems ([`Error::Input`], [`Error::Io`]) name the file they
/// concern, so a command-line user sees one line that says what to fix.
/// Errors from wgpu keep their own type ([`Error::NoAdapter`],
/// [`Error::RequestDevice`], [`Error::Poll`], [`Error::BufferMap`],
/// [`Error::MappedRange`]), reachable through
/// [`std::error::Error::source`].
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
    NoAdapter(#[from] wgpu::RequestAdapterError),
    /// The adapter exists but the device could not be created.
    #[error("GPU device request failed: {0}")]
    RequestDevice(#[from] wgpu::RequestDeviceError),
    /// The caller's device has a limit pipetrack cannot work within (see
    /// [`crate::required_limits`]).
    #[error(
        "GPU device unsuitable: its limit {limit} is {available}, pipetrack needs {needed} \
         (create the device with pipetrack::required_limits())"
    )]
    Limit {
        /// The field of [`wgpu::Limits`], e.g. `max_storage_buffers_per_shader_stage`.
        limit: &'static str,
        /// The value pipetrack needs.
        needed: u64,
        /// The value the device has.
        available: u64,
    },
    /// The caller's device lacks features pipetrack needs (see
    /// [`crate::required_features`]).
    #[error("GPU device unsuitable: it lacks the features {0:?}")]
    MissingFeatures(wgpu::Features),
    /// A frame texture's format is not one pipetrack reads (see
    /// [`crate::early::ingest::TEXTURE_FORMATS`]).
    #[error(
        "texture format {0:?} is not supported: pipetrack takes R8Unorm, Rgba8Unorm, Bgra8Unorm, \
         Rgba8UnormSrgb or Bgra8UnormSrgb"
    )]
    TextureFormat(wgpu::TextureFormat),
    /// A frame texture cannot be read as a frame (its usage, dimension or
    /// sample count).
    #[error("unusable frame texture: {0}")]
    Texture(String),
    /// A texture frame was given to a backend that runs on the CPU.
    #[error(
        "the {backend} backend cannot read wgpu textures: use the GPU backend on the texture's device, \
         or read the texture back and pass bytes"
    )]
    TextureOnCpu {
        /// The backend's name.
        backend: String,
    },
    /// Waiting for the GPU failed (a timeout, or a bad submission index).
    #[error("GPU wait failed: {0}")]
    Poll(#[from] wgpu::PollError),
    /// Mapping a buffer for readback failed.
    #[error("GPU buffer mapping failed: {0}")]
    BufferMap(#[from] wgpu::BufferAsyncError),
    /// A mapped buffer's range could not be viewed.
    #[error("GPU buffer view failed: {0}")]
    MappedRange(#[from] wgpu::MapRangeError),
    /// pipetrack's own GPU bookkeeping went wrong: a ticket used twice, too
    /// many frames in flight, a stage's buffers missing, an inconsistent list
    /// header read back.
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
    /// What is wrong, for a message that names the file it lies in: a
    /// parameter error without its `invalid parameter:` lead, any other
    /// error as it displays.
    #[must_use]
    pub fn message(&self) -> String {
        match self {
            Error::Parameter(message) => message.clone(),
            other => other.to_string(),
        }
    }

    /// An input error for `path` with a one-line message.
    pub fn input(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Input { path: path.into(), message: message.into() }
    }

    /// An I/O error for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
}

/// `Result` with pipetrack's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
