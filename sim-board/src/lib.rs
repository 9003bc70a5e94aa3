//! An in-memory board of X x Y x Z nodes running the real node firmware, joined
//! by in-memory links, with deterministic virtual time.
//!
//! Each node's work is charged by a [`CostModel`] (cube steps, sphere tests,
//! shading, messages, bytes over links of configurable bandwidth and latency),
//! so running and waiting time are counted as in the paper's simulator. The
//! simulation is a conservative parallel discrete-event simulation: in a round
//! of one link latency no message can both be sent and arrive, so the nodes of
//! a round are independent and run on all cores, and the result does not depend
//! on thread scheduling.

pub mod board;
pub mod config;
pub mod cost;
pub mod faults;
pub mod link_spec;
pub mod sim_links;
mod slot;

pub use board::{Board, HostEndpoint, RunStats, SimConfig, SimError, SimNode, progresses};
pub use cost::{Busy, CostModel, LinkModel};
pub use faults::{Faults, FaultyStream};
pub use link_spec::{LinkPreset, LinkSpec, Transfer};
