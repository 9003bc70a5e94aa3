//! The host of the sliding-boundary ray tracer, as a pipeline:
//!
//! ```text
//! scene  ->  plan  ->  session  ->  results
//! ```
//!
//! - [`scene`]: read a scene (JSON or NFF), validate it, fit it into the grid.
//! - [`plan`]: everything computed from the scene and the options before a
//!   node is spoken to, once, as a value: the driving axis, the starting
//!   partition (even or fitted to a preview), each node's assignment and
//!   sub-image tile, checked against what a node holds.
//! - [`session`]: the conversation with the nodes over one
//!   [`session::transport::Transport`] (the in-memory board, emulated
//!   boards, or real boards): broadcast, run, collect.
//! - [`results`]: the image, the summary, the per-node loads, the load and
//!   boundary histories and their plot, written all or none.
//!
//! Beside the pipeline: an independent f64 renderer ([`mod@reference`]) and
//! the comparison of the fixed-point image with it ([`compare`]), and the
//! options the commands share ([`args`]).

pub mod args;
pub mod compare;
pub mod error;
pub mod plan;
pub mod reference;
pub mod results;
pub mod scene;
pub mod session;
pub mod threads;

pub use error::HostError;
