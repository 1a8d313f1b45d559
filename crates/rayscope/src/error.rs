//! The library's error type: every failure names the file (and line, where known).

use std::path::PathBuf;

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can go wrong loading a scene or writing an image.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A file's contents are malformed.
    #[error("{path}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line, where known.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// A path names something other than a regular file (a directory, a FIFO, a device).
    #[error("{path}: is {kind}, not a regular file; rayscope reads only regular files")]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What it names instead ("a directory", "a FIFO", "a device", ...).
        kind: &'static str,
    },
    /// A file is larger than the loaders read ([`crate::scene::max_file_bytes`]).
    #[error(
        "{path}: larger than the limit of {limit} bytes; to read it, raise the limit with --max-file-bytes N or \
         the RAYSCOPE_MAX_FILE_BYTES environment variable (a number of bytes)"
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// The limit in force.
        limit: u64,
    },
    /// A mesh needs more memory than the process can allocate ([`crate::io`]'s estimate, or
    /// an allocation that failed).
    #[error(
        "{path}: {triangles} triangles need about {} MB of memory to load and build the BVH, more than this \
         process can allocate (an address-space limit, `ulimit -v`, or the machine's memory)",
        bytes.div_ceil(1 << 20)
    )]
    OutOfMemory {
        /// The mesh file.
        path: PathBuf,
        /// Its triangles.
        triangles: u64,
        /// The bytes it needs.
        bytes: u64,
    },
    /// A scene needs a course file that is not in the asset folder.
    #[error(
        "{path}: not found; scene '{scene}' needs the course's scene files. {searched}. Point --assets DIR \
         (or the RAYSCOPE_ASSETS environment variable) at the folder that holds them"
    )]
    MissingAsset {
        /// The scene that needs it.
        scene: String,
        /// Where it was looked for.
        path: PathBuf,
        /// Which folder was searched and how it was chosen (or why there was none).
        searched: String,
    },
    /// No built-in scene has this name.
    #[error("unknown scene '{name}'; built-in scenes: {known}")]
    UnknownScene {
        /// The name asked for.
        name: String,
        /// The names that exist, comma separated.
        known: String,
    },
    /// A path given as the scene names no format rayscope reads (and is not a built-in scene's
    /// name either: those have no extension and no folder).
    #[error(
        "{path}: not a scene rayscope reads: give a .toml scene file, a .obj, .ply, .gltf or .glb \
         mesh, or a built-in scene's name ({known})"
    )]
    UnsupportedScene {
        /// The path given.
        path: PathBuf,
        /// The built-in scenes' names, comma separated.
        known: String,
    },
    /// A setting or scene value is out of its range.
    #[error("{0}")]
    Invalid(String),
}

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Error {
        Error::Io { path: path.into(), source }
    }

    /// A parse error in `path` at `line`.
    pub fn parse(path: impl Into<PathBuf>, line: Option<usize>, message: impl Into<String>) -> Error {
        Error::Parse { path: path.into(), line, message: message.into() }
    }
}
