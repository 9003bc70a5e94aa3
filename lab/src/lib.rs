//! Experiments and test oracles of the sliding-boundary ray tracer, apart
//! from the product: the paper's experiments ([`paper`]), efficiency against
//! array size ([`scaling`]), the generated tables of docs/results.md
//! ([`results`]), error against run time over a user's settings
//! ([`tradeoff`]), and the arithmetic's references and reports
//! ([`numerics`]: an exact rational traversal and a big-integer sphere test
//! that the tests hold the kernels to, the stiff cases, and error against run
//! time of arithmetic variants), and sequences: balancing modes over a
//! camera orbit ([`animation`]) and a long run under link faults ([`soak`]).

pub mod animation;
pub mod numerics;
pub mod paper;
pub mod results;
pub mod scaling;
pub mod scenes;
pub mod soak;
pub mod tradeoff;
