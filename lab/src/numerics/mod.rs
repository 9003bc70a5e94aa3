//! References and cases for the exact arithmetic, independent of the code
//! under test: an exact rational digital line (sorting all plane crossings
//! instead of stepping a DDA), an exact big-integer sphere decision (classic
//! discriminant instead of Lagrange's form), and the stiff and extreme cases of
//! `shared/notes/numerics.md` as named data, with the table `report stiff` prints.

pub mod exact_sphere;
pub mod quantise;
pub mod rational_walk;
pub mod stiff;
pub mod stiff_table;
pub mod variants;
