//! The one contract between the host and whatever carries its messages: the
//! in-memory board, emulated boards behind ptys, or real boards behind serial
//! devices all implement [`Transport`] as equals, and the session speaks to
//! nodes through nothing else.
//!
//! A transport stamps what it hands the host with its own [`Clock`]; the
//! type says which, so a run's times never mix units.

use link_proto::{Capacity, Message};
use node_fw::reliable::ChannelStats;
use sim_board::Busy;

use crate::error::HostError;
use crate::session::clock::Clock;

/// What the host does with the nodes' messages during a run.
pub trait Endpoint<T> {
    /// A message from node `node` arrived at time `at`.
    fn receive(&mut self, node: u16, at: T, msg: Message);
    /// Whether the run may stop.
    fn finished(&self) -> bool;
}

/// How a run ended, on the transport's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RunEnd<T> {
    /// When the run started.
    pub start: T,
    /// When the run stopped.
    pub end: T,
    /// Rounds of the transport's loop.
    pub rounds: u64,
}

/// Nodes that render a frame, and what carries their messages.
pub trait Transport {
    /// The clock the transport's times are counted on.
    type Time: Clock;
    /// Number of nodes.
    fn nodes(&self) -> usize;
    /// What every node can hold.
    fn capacity(&self) -> Capacity;
    /// Queues a message from the host to node `node`.
    fn send(&mut self, node: usize, msg: Message);
    /// Moves messages until `host` is finished.
    fn run(&mut self, host: &mut impl Endpoint<Self::Time>) -> Result<RunEnd<Self::Time>, HostError>;
    /// Bytes node `node` sent, per port (as far as the transport counts them).
    fn bytes_sent(&self, node: usize) -> [u64; 7];
    /// Resends and damaged frames on the links.
    fn link_stats(&self) -> ChannelStats;
    /// Bytes node `node` took in, per port, where the transport can see them.
    fn bytes_received(&self, _node: usize) -> [u64; 7] {
        [0; 7]
    }
    /// Node `node`'s busy cycles by what they were spent on, where the
    /// transport can see inside its nodes.
    fn busy(&self, _node: usize) -> Option<Busy> {
        None
    }
    /// Whether the map of occupied cubes follows a frame's start
    /// ([`crate::session::load`]): where a node takes the host's bytes as
    /// they come, while it works (a board's UART by DMA, the in-memory
    /// board). QEMU's boards take a byte only when QEMU's loop runs, which
    /// a busy guest holds off, so a map sent after the start came after
    /// most of a small frame there; they are sent it first.
    fn map_follows_start(&self) -> bool {
        true
    }
}
