//! Errors as values: the firmware reports them to the host and never panics on input.

use link_proto::{ErrorCode, ErrorReport};

/// The input field an out-of-range error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    /// Grid size (1..=256 cubes per axis).
    Grid,
    /// A ray origin, eye or light position.
    Origin,
    /// A ray direction (zero, or not of unit length).
    Direction,
    /// A sphere centre (must lie in the closed grid box).
    Center,
    /// A sphere radius.
    Radius,
    /// A traversal cell that does not lie on its ray's digital line.
    Cell,
    /// A subregion box (empty, outside the grid, or larger than the node holds).
    Subregion,
    /// A ray parameter.
    Parameter,
    /// The reflection depth (at most [`link_proto::MAX_DEPTH`]).
    Depth,
    /// An occupancy message: a cube outside the grid, or not as many as the scene's end counts.
    Occupancy,
}

impl Field {
    /// The field's number in an [`ErrorReport`] (`a`), 1 to 10 in the
    /// order above. Not the enum's discriminant: a node's storage starts
    /// zero-filled ([`crate::node::Node::renew`]), so every enum it holds
    /// must have a variant at zero.
    pub const fn code(self) -> u32 {
        match self {
            Field::Grid => 1,
            Field::Origin => 2,
            Field::Direction => 3,
            Field::Center => 4,
            Field::Radius => 5,
            Field::Cell => 6,
            Field::Subregion => 7,
            Field::Parameter => 8,
            Field::Depth => 9,
            Field::Occupancy => 10,
        }
    }
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
            Error::OutOfRange(field) => (ErrorCode::OutOfRange, field.code(), 0),
            Error::SphereCapacity { capacity } => (ErrorCode::SphereCapacity, capacity, capacity + 1),
            Error::RefCapacity { capacity, needed } => (ErrorCode::RefCapacity, capacity, needed),
            Error::CubeCapacity { capacity, needed } => (ErrorCode::CubeCapacity, capacity, needed),
        };
        ErrorReport { node, code, a, b }
    }
}
