//! Errors of the desktop tools: one line naming the file (and line) and the reason.

use std::fmt;
use std::path::{Path, PathBuf};
use vtsm_core::FailureCode;

/// Exit code for a relocalization that failed cleanly.
pub const EXIT_RELOC_FAILED: u8 = 1;
/// Exit code for bad input (file, arguments).
pub const EXIT_BAD_INPUT: u8 = 2;

/// A user-facing error.
#[derive(Debug, Clone, PartialEq)]
pub struct Error {
    /// The file the problem is in, if any.
    pub file: Option<PathBuf>,
    /// 1-based line in that file, if known.
    pub line: Option<usize>,
    /// What is wrong.
    pub msg: String,
    /// The core failure code behind it, if any.
    pub code: Option<FailureCode>,
}

/// Result with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An error not tied to a file.
    pub fn msg(msg: impl Into<String>) -> Self {
        Self {
            file: None,
            line: None,
            msg: msg.into(),
            code: None,
        }
    }

    /// An error in `file`.
    pub fn file(file: impl AsRef<Path>, msg: impl Into<String>) -> Self {
        Self {
            file: Some(file.as_ref().to_path_buf()),
            line: None,
            msg: msg.into(),
            code: None,
        }
    }

    /// An error at `line` of `file`.
    pub fn at(file: impl AsRef<Path>, line: usize, msg: impl Into<String>) -> Self {
        Self {
            line: Some(line),
            ..Self::file(file, msg)
        }
    }

    /// Attach a core failure code.
    pub fn with_code(mut self, code: FailureCode) -> Self {
        self.code = Some(code);
        self
    }
}

impl From<FailureCode> for Error {
    fn from(code: FailureCode) -> Self {
        Self::msg(format!(
            "{} (0x{:04x}): {}",
            code.name(),
            code.code(),
            code.description()
        ))
        .with_code(code)
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.file, self.line) {
            (Some(p), Some(l)) => write!(f, "{}:{}: {}", p.display(), l, self.msg),
            (Some(p), None) => write!(f, "{}: {}", p.display(), self.msg),
            _ => write!(f, "{}", self.msg),
        }
    }
}

impl std::error::Error for Error {}
