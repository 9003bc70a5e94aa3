//! Errors of the host tool: each names the problem in one line and maps to a
//! documented, distinct exit code (see docs/cli.md).

use std::fmt;

/// A host-side failure, by kind, with its one-line message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HostError {
    /// A scene file is not valid JSON for the schema (exit 10).
    Malformed(String),
    /// A NaN or infinite number (exit 11).
    NonFinite(String),
    /// A zero, negative or out-of-range radius (exit 12).
    Radius(String),
    /// A sphere outside the grid, or sticking out of it (exit 13).
    OutsideGrid(String),
    /// An image size out of range: zero, or over [`crate::session::frame::MAX_PIXELS`] (exit 14).
    ImageSize(String),
    /// An array larger than the grid (exit 15).
    ArrayTooLarge(String),
    /// A node cannot hold its part of the scene (exit 16; the node is named).
    Capacity(String),
    /// Any other invalid input (exit 17).
    Input(String),
    /// A file could not be read or written (exit 20).
    Io(String),
    /// A serial device is missing or busy (exit 21).
    Serial(String),
    /// A node or the array failed during a run (exit 30).
    Node(String),
    /// A node speaks another protocol version (exit 31).
    Version(String),
    /// The boards are not cabled as the array needs (exit 32).
    Cabling(String),
}

impl HostError {
    /// The process exit code of this kind of error.
    pub fn exit_code(&self) -> i32 {
        match self {
            HostError::Malformed(_) => 10,
            HostError::NonFinite(_) => 11,
            HostError::Radius(_) => 12,
            HostError::OutsideGrid(_) => 13,
            HostError::ImageSize(_) => 14,
            HostError::ArrayTooLarge(_) => 15,
            HostError::Capacity(_) => 16,
            HostError::Input(_) => 17,
            HostError::Io(_) => 20,
            HostError::Serial(_) => 21,
            HostError::Node(_) => 30,
            HostError::Version(_) => 31,
            HostError::Cabling(_) => 32,
        }
    }

    /// The same kind of error, its message prefixed with `context: `.
    pub fn context(self, context: &str) -> HostError {
        self.map_message(|m| format!("{context}: {m}"))
    }

    /// The same kind of error, `more` added to its message.
    pub fn append(self, more: &str) -> HostError {
        self.map_message(|m| format!("{m}{more}"))
    }

    /// The same kind of error with its message rewritten.
    fn map_message(self, wrap: impl FnOnce(String) -> String) -> HostError {
        match self {
            HostError::Malformed(m) => HostError::Malformed(wrap(m)),
            HostError::NonFinite(m) => HostError::NonFinite(wrap(m)),
            HostError::Radius(m) => HostError::Radius(wrap(m)),
            HostError::OutsideGrid(m) => HostError::OutsideGrid(wrap(m)),
            HostError::ImageSize(m) => HostError::ImageSize(wrap(m)),
            HostError::ArrayTooLarge(m) => HostError::ArrayTooLarge(wrap(m)),
            HostError::Capacity(m) => HostError::Capacity(wrap(m)),
            HostError::Input(m) => HostError::Input(wrap(m)),
            HostError::Io(m) => HostError::Io(wrap(m)),
            HostError::Serial(m) => HostError::Serial(wrap(m)),
            HostError::Node(m) => HostError::Node(wrap(m)),
            HostError::Version(m) => HostError::Version(wrap(m)),
            HostError::Cabling(m) => HostError::Cabling(wrap(m)),
        }
    }

    /// The one-line message.
    pub fn message(&self) -> &str {
        match self {
            HostError::Malformed(m)
            | HostError::NonFinite(m)
            | HostError::Radius(m)
            | HostError::OutsideGrid(m)
            | HostError::ImageSize(m)
            | HostError::ArrayTooLarge(m)
            | HostError::Capacity(m)
            | HostError::Input(m)
            | HostError::Io(m)
            | HostError::Serial(m)
            | HostError::Node(m)
            | HostError::Version(m)
            | HostError::Cabling(m) => m,
        }
    }
}

impl fmt::Display for HostError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.message())
    }
}

impl std::error::Error for HostError {}

/// Shorthand for an invalid-input error (exit 17).
pub fn input(msg: impl Into<String>) -> HostError {
    HostError::Input(msg.into())
}
