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

use std::path::{Path, PathBuf};

use host_tool::error::HostError;

/// The paths of an experiment's `names` in `out`, checked before the
/// experiment runs (the directory made, each file writable), so a long run
/// never ends unable to write what it measured.
pub fn outputs<const N: usize>(out: &Path, names: [&str; N]) -> Result<[PathBuf; N], HostError> {
    std::fs::create_dir_all(out)
        .map_err(|e| HostError::Io(format!("cannot create {}: {e}", out.display())))?;
    let files = names.map(|f| out.join(f));
    host_tool::results::output::check_writable(&files.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    Ok(files)
}
