//! Errors as values: the firmware reports them to the host and never panics on input.

use link_proto::{ErrorCode, ErrorReport};

/// The input field an out-of-range error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Field {
    /// Grid size (1..=256 cubes per axis).
    Grid = 1,
    /// A ray origin, eye or light position.
    Origin = 2,
    /// A ray direction (zero, or not of unit length).
    Direction = 3,
    /// A sphere centre (must lie in the closed grid box).
    Center = 4,
    /// A sphere radius.
    Radius = 5,
    /// A traversal cell that does not lie on its ray's digital line.
    Cell = 6,
    /// A subregion box (empty, outside the grid, or larger than the node holds).
    Subregion = 7,
    /// A ray parameter.
    Parameter = 8,
    /// The reflection depth (at most [`link_proto::MAX_DEPTH`]).
    Depth = 9,
}

/// Everything that can go wrong in a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// A value outside its documented range (see [`crate::limits`]).
    OutOfRange(Field),
    /// More spheres than the node was built to hold.
    SphereCapacity {
        /// Spheres the node holds.
        capacity: u32,
    },
    /// More sphere references (sphere x cube) than the node was built to hold.
    RefCapacity {
        /// References the node holds.
        capacity: u32,
        /// References the rejected sphere would have brought the total to.
        needed: u32,
    },
    /// A subregion with more cubes than the node was built to hold.
    CubeCapacity {
        /// Cubes the node holds.
        capacity: u32,
        /// Cubes of the requested subregion.
        needed: u32,
    },
}

impl Error {
    /// The report sent to the host for this error.
    pub fn report(self, node: u16) -> ErrorReport {
        let (code, a, b) = match self {
            Error::OutOfRange(field) => (ErrorCode::OutOfRange, field as u32, 0),
            Error::SphereCapacity { capacity } => (ErrorCode::SphereCapacity, capacity, capacity + 1),
            Error::RefCapacity { capacity, needed } => (ErrorCode::RefCapacity, capacity, needed),
            Error::CubeCapacity { capacity, needed } => (ErrorCode::CubeCapacity, capacity, needed),
        };
        ErrorReport { node, code, a, b }
    }
}
