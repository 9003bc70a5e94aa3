//! Errors of the host tool: each names the problem in one line.

use std::fmt;

/// A host-side failure, with the process exit code it maps to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HostError {
    /// The command line or a scene is invalid.
    Input(String),
    /// A file could not be read or written.
    Io(String),
    /// A node or the array reported a failure.
    Node(String),
}

impl HostError {
    /// Exit code: 2 bad input, 3 file trouble, 4 a node or the array failed.
    pub fn exit_code(&self) -> i32 {
        match self {
            HostError::Input(_) => 2,
            HostError::Io(_) => 3,
            HostError::Node(_) => 4,
        }
    }
}

impl fmt::Display for HostError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HostError::Input(m) | HostError::Io(m) | HostError::Node(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for HostError {}

/// Shorthand for an input error.
pub fn input(msg: impl Into<String>) -> HostError {
    HostError::Input(msg.into())
}
