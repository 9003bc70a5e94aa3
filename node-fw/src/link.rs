//! The node's seven ports and the abstract link trait over them.
//!
//! A node has six links to its neighbours (+X, -X, +Y, -Y, +Z, -Z) and one to
//! the host. [`Links`] is all the node knows of them: the same node code runs
//! over in-memory queues (sim-board), UARTs on emulated Cortex-M boards, and
//! UARTs on real boards. Receiving never blocks the node; sending hands the
//! message back when the link is full (back-pressure, never a drop).

use link_proto::{Message, OutgoingRay, PortHealth};

/// One of a node's seven ports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum Port {
    /// Neighbour at +X.
    PosX = 0,
    /// Neighbour at -X.
    NegX = 1,
    /// Neighbour at +Y.
    PosY = 2,
    /// Neighbour at -Y.
    NegY = 3,
    /// Neighbour at +Z.
    PosZ = 4,
    /// Neighbour at -Z.
    NegZ = 5,
    /// The host (scene broadcast, frame buffer, load reports).
    Host = 6,
}

impl Port {
    /// The six neighbour ports.
    pub const NEIGHBOURS: [Port; 6] =
        [Port::PosX, Port::NegX, Port::PosY, Port::NegY, Port::PosZ, Port::NegZ];
    /// All seven ports.
    pub const ALL: [Port; 7] =
        [Port::PosX, Port::NegX, Port::PosY, Port::NegY, Port::PosZ, Port::NegZ, Port::Host];

    /// The neighbour port along `axis` (0..3) in the positive or negative direction.
    pub fn toward(axis: usize, positive: bool) -> Port {
        match (axis, positive) {
            (0, true) => Port::PosX,
            (0, false) => Port::NegX,
            (1, true) => Port::PosY,
            (1, false) => Port::NegY,
            (_, true) => Port::PosZ,
            (_, false) => Port::NegZ,
        }
    }

    /// Index 0..7, usable for per-port arrays.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The axis of a neighbour port (`None` for the host).
    pub fn axis(self) -> Option<usize> {
        (self != Port::Host).then(|| self.index() / 2)
    }

    /// The port on the neighbour that faces back to this one.
    pub fn opposite(self) -> Port {
        match self {
            Port::PosX => Port::NegX,
            Port::NegX => Port::PosX,
            Port::PosY => Port::NegY,
            Port::NegY => Port::PosY,
            Port::PosZ => Port::NegZ,
            Port::NegZ => Port::PosZ,
            Port::Host => Port::Host,
        }
    }
}

/// The node's view of its links. Implementations decide what "arrived" means
/// (a virtual clock, a UART FIFO); the node never reads a clock.
pub trait Links {
    /// The next message that has arrived on `port`, if any.
    fn recv(&mut self, port: Port) -> Option<Message>;
    /// Queues `msg` on `port`, or hands it back if the link is full.
    // Handing the message back is the point (the caller keeps it for the
    // next poll); a message is a ray's size, 128 bytes, and stays on the stack.
    #[allow(clippy::result_large_err)]
    fn try_send(&mut self, port: Port, msg: Message) -> Result<(), Message>;
    /// Queues the message `ray` stands for on `port`; whether the link took
    /// it (the caller still holds the ray when not). Links that keep
    /// messages whole build it; a framed link packs the ray from where it
    /// lies, without the copy.
    fn try_send_ray(&mut self, port: Port, ray: &OutgoingRay<'_>) -> bool {
        self.try_send(port, ray.message()).is_ok()
    }
    /// A port whose peer has restarted since the last call (a new incarnation
    /// on a framed link). Links that cannot tell, such as in-memory queues,
    /// never report one.
    fn peer_restarted(&mut self) -> Option<Port> {
        None
    }
    /// The host session the node is in: the incarnation of the host at the
    /// other end of the host link, once it has spoken. Every node of a run
    /// sees the same one; links without sessions, such as in-memory queues,
    /// are in session 0 for ever.
    fn session(&self) -> Option<u32> {
        Some(0)
    }
    /// Whether a cable may be plugged in at `port`. The node says its
    /// neighbour hello only where one is; links that cannot tell a missing
    /// cable from a silent peer, such as framed UARTs, say yes, and the hello
    /// waits in the channel for a peer that may never come.
    fn cabled(&self, _port: Port) -> bool {
        true
    }
    /// Frames resent on `port`, frames that reached it damaged and received
    /// bytes its byte link lost, counted since the links began. Links that
    /// lose nothing, such as in-memory queues, count none.
    fn health(&self, _port: Port) -> PortHealth {
        PortHealth::default()
    }
}
