//! One node's view of its in-memory links during a round.

use std::collections::VecDeque;

use link_proto::{MAX_FRAME_LEN, Message, encode_frame};
use node_fw::{Links, Port};

/// A message in a link, stamped with its arrival time and its length as a frame.
#[derive(Debug, Clone)]
pub struct Stamped {
    /// Virtual time of arrival.
    pub at: u64,
    /// The message.
    pub msg: Message,
    /// Bytes it takes on the wire.
    pub len: u64,
}

/// Per-port state a node owns: what has arrived, what it sent this round.
#[derive(Debug, Default)]
pub struct PortState {
    /// Messages sent to this node, in arrival order.
    pub inbox: VecDeque<Stamped>,
    /// Messages this node sent on the port this round.
    pub outbox: Vec<Stamped>,
    /// Messages in the peer's inbox from this port at the round's start.
    pub occupancy: usize,
    /// When the port's wire is free again.
    pub busy_until: u64,
    /// Bytes sent on the port.
    pub bytes: u64,
    /// Bytes taken from the port (whole messages or frames).
    pub bytes_in: u64,
    /// Framed mode: byte chunks (one frame each) arriving on this port, by arrival.
    pub wire: VecDeque<(u64, Vec<u8>)>,
    /// Framed mode: frames this node wrote on the port this round.
    pub wire_out: Vec<(u64, Vec<u8>)>,
}

/// [`Links`] over a node's seven [`PortState`]s at virtual time `now`.
pub struct SimLinks<'a> {
    /// The node's ports, indexed by [`Port::index`].
    pub ports: &'a mut [PortState; 7],
    /// Which neighbour ports exist.
    pub wired: [bool; 7],
    /// The node's clock.
    pub now: u64,
    /// Node-to-node link timing and capacity.
    pub link: crate::cost::LinkModel,
    /// Node-to-host link timing and capacity.
    pub host_link: crate::cost::LinkModel,
    /// Set when the node tried to send through a port with no neighbour.
    pub miswired: Option<Port>,
    /// CPU cycles spent moving the bytes of the messages sent and taken.
    pub byte_cpu: u64,
}

impl SimLinks<'_> {
    fn model(&self, port: Port) -> crate::cost::LinkModel {
        if port == Port::Host { self.host_link } else { self.link }
    }
}

impl Links for SimLinks<'_> {
    fn recv(&mut self, port: Port) -> Option<Message> {
        let byte_cpu = self.model(port).byte_cpu;
        let state = self.ports.get_mut(port.index())?;
        if state.inbox.front().is_some_and(|m| m.at <= self.now) {
            let m = state.inbox.pop_front()?;
            state.bytes_in += m.len;
            self.byte_cpu += m.len * byte_cpu;
            Some(m.msg)
        } else {
            None
        }
    }

    fn cabled(&self, port: Port) -> bool {
        self.wired.get(port.index()).copied().unwrap_or(false)
    }

    fn try_send(&mut self, port: Port, msg: Message) -> Result<(), Message> {
        if !self.wired.get(port.index()).copied().unwrap_or(false) {
            self.miswired = Some(port);
            return Err(msg);
        }
        let model = self.model(port);
        let Some(state) = self.ports.get_mut(port.index()) else { return Err(msg) };
        if state.occupancy + state.outbox.len() >= model.capacity {
            return Err(msg);
        }
        let bytes = frame_len(&msg) as u64;
        let start = self.now.max(state.busy_until);
        state.busy_until = start + bytes * model.byte;
        state.bytes += bytes;
        state.outbox.push(Stamped { at: state.busy_until + model.latency, msg, len: bytes });
        self.byte_cpu += bytes * model.byte_cpu;
        Ok(())
    }
}

/// Bytes the message takes on the wire as a frame.
pub fn frame_len(msg: &Message) -> usize {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let frame = link_proto::Frame::new(0, msg.clone());
    encode_frame(&frame, &mut buf).unwrap_or(MAX_FRAME_LEN)
}
