//! References for the integration tests, written independently of the code under
//! test: an exact rational digital line (sorting all plane crossings instead of
//! stepping a DDA), an exact big-integer sphere decision (classic discriminant
//! instead of Lagrange's form), and the stiff and extreme cases of
//! `shared/notes/numerics.md` as named data.

pub mod exact_sphere;
pub mod quantise;
pub mod rational_walk;
pub mod stiff;
