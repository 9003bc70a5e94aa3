//! Node firmware for boards: node-fw's [`Node`](node_fw::Node) over UARTs.
//!
//! The node code is the same as in the in-memory board; this crate only adds
//! what a board needs: a [`clock`], UART drivers for each [`board`], and the
//! [`run`] loop that moves bytes between UARTs and the node's reliable
//! channels ([`wires`]). Storage is static and fixed ([`capacity`]).
#![no_std]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
#![warn(missing_docs)]

pub mod board;
pub mod capacity;
pub mod clock;
pub mod fault;
pub mod lights;
pub mod log;
pub mod memcpy;
pub mod run;
pub mod tx_ring;
pub mod wires;

pub use capacity::{BoardLinks, BoardNode};
pub use clock::Clock;
