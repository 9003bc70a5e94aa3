//! Integration tests across crates. The references they check against live in
//! [`lab::numerics`] (independent of the kernels under test), so the
//! host tool can regenerate the stiff-case table from the same code.

pub use lab::numerics::{exact_sphere, quantise, rational_walk, stiff};
