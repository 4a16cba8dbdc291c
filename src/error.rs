//! The library's one error type.
//!
//! Every variant that comes from a file names the file; variants about a record name the record
//! (0-based record index for binary files, 1-based line number for text files) and say what is
//! wrong, so a surveyor can find and fix the input without reading code.

use std::path::PathBuf;

/// Everything that can go wrong in kinescan.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The operating system refused a read or write.
    #[error("{}: {source}", path.display())]
    Io {
        /// File being read or written.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// A file as a whole is unusable (wrong size, wrong magic, empty, unknown column...).
    #[error("{}: {problem}", path.display())]
    BadFile {
        /// Offending file.
        path: PathBuf,
        /// What is wrong, in words.
        problem: String,
    },
    /// One record (binary) or line (text) of a file is unusable.
    #[error("{}: {at}: {problem}", path.display())]
    BadRecord {
        /// Offending file.
        path: PathBuf,
        /// Where: "record 17" (0-based) or "line 18" (1-based).
        at: String,
        /// What is wrong, in words.
        problem: String,
    },
    /// A pipeline, scenario or calibration file, or a `--set` override, is invalid.
    #[error("{source_name}: key `{key}`: {problem}")]
    Config {
        /// File name, or `--set` for command-line overrides.
        source_name: String,
        /// Dotted key path, e.g. `sensor.lever_arm_b_m`.
        key: String,
        /// What is wrong, in words.
        problem: String,
    },
    /// An output would overwrite an input, or two outputs are one file (`io::paths`).
    #[error(
        "`{output_key}` ({}) {problem} `{other_key}` ({}): choose another path for `{output_key}`",
        output.display(),
        other.display()
    )]
    Collision {
        /// Key (config key or argument) that sets the output.
        output_key: String,
        /// The output path as given.
        output: PathBuf,
        /// Key of the input or output it collides with.
        other_key: String,
        /// That file's path as given.
        other: PathBuf,
        /// "is the same file as the input" or "... output".
        problem: String,
    },
    /// SIGINT or SIGTERM stopped the command ([`crate::interrupt`]).
    #[error("interrupted (SIGINT or SIGTERM): nothing published, temporary files removed")]
    Interrupted,
    /// Arguments that cannot be processed (not tied to one file).
    #[error("{0}")]
    Invalid(String),
    /// A numerical method could not produce a trustworthy answer.
    #[error("{what}: {problem}")]
    Numerical {
        /// Which computation.
        what: String,
        /// Why it failed (singular system, no convergence, unobservable parameter...).
        problem: String,
    },
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
    /// An [`Error::BadFile`] for `path`.
    pub fn bad_file(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        Error::BadFile {
            path: path.into(),
            problem: problem.into(),
        }
    }
    /// An [`Error::BadRecord`] for `path` at `at` ("record N" or "line N").
    pub fn bad_record(
        path: impl Into<PathBuf>,
        at: impl Into<String>,
        problem: impl Into<String>,
    ) -> Self {
        Error::BadRecord {
            path: path.into(),
            at: at.into(),
            problem: problem.into(),
        }
    }
    /// An [`Error::Config`].
    pub fn config(
        source_name: impl Into<String>,
        key: impl Into<String>,
        problem: impl Into<String>,
    ) -> Self {
        Error::Config {
            source_name: source_name.into(),
            key: key.into(),
            problem: problem.into(),
        }
    }
}
