//! The node's links over byte streams: one reliable channel per port.
//!
//! [`FramedLinks`] is what a node sees as its [`Links`] when its ports are
//! byte streams (UARTs on boards, faulty wires in the simulator): messages
//! travel as CRC-checked frames through a go-back-N [`Channel`] per port, so a
//! corrupted, lost or duplicated frame costs time, never a message. The owner
//! moves bytes: [`FramedLinks::ingest`] what arrived, [`FramedLinks::transmit`]
//! what is due.

use heapless::Deque;
use link_proto::{MAX_FRAME_LEN, Message, OutgoingRay, PortHealth};

use crate::link::{Links, Port};
use crate::reliable::{Channel, ChannelStats};

/// Seven reliable channels with a window of `W` frames and `Q` received
/// messages waiting per port.
pub struct FramedLinks<const W: usize, const Q: usize> {
    channels: [Channel<W>; 7],
    inbox: [Deque<Message, Q>; 7],
    /// Where frames are encoded on their way out, one for all channels.
    scratch: [u8; MAX_FRAME_LEN],
    /// Ports the owner knows no cable is plugged into (none, unless told):
    /// kept as the ports without one, so that a new value is all zeros.
    uncabled: [bool; 7],
    /// Received bytes each port's byte link lost, as its owner told them.
    lost: [u32; 7],
}

impl<const W: usize, const Q: usize> FramedLinks<W, Q> {
    /// Channels that resend after `timeout` ticks without progress.
    ///
    /// With a `timeout` of 0 the value is all zero bytes, which a board's
    /// linker keeps in zero-filled RAM rather than copying from flash: a
    /// board builds its links so, and sets the time-out at boot
    /// ([`FramedLinks::set_timeout`]).
    pub const fn new(timeout: u64) -> Self {
        let t = timeout;
        let channels = [
            Channel::new(t),
            Channel::new(t),
            Channel::new(t),
            Channel::new(t),
            Channel::new(t),
            Channel::new(t),
            Channel::new(t),
        ];
        Self {
            channels,
            inbox: [const { Deque::new() }; 7],
            scratch: [0; MAX_FRAME_LEN],
            uncabled: [false; 7],
            lost: [0; 7],
        }
    }

    /// Tells which ports have a cable (port order), where the owner knows:
    /// the node says no hello on the others ([`Links::cabled`]).
    pub fn set_cabled(&mut self, cabled: [bool; 7]) {
        self.uncabled = cabled.map(|c| !c);
    }

    /// Every channel resends after `timeout` ticks without progress.
    pub fn set_timeout(&mut self, timeout: u64) {
        for channel in &mut self.channels {
            channel.set_timeout(timeout);
        }
    }

    /// Sets the incarnation every channel announces: pick a new one on every
    /// start (a boot counter, a clock), so peers notice the restart.
    pub fn set_incarnation(&mut self, incarnation: u32) {
        for channel in &mut self.channels {
            channel.set_incarnation(incarnation);
        }
    }

    /// `n` more received bytes `port`'s byte link lost (a UART's overruns,
    /// a full receive ring), as its owner counted them: the channel sees
    /// only the frames they damaged.
    pub fn note_lost(&mut self, port: Port, n: u32) {
        if let Some(lost) = self.lost.get_mut(port.index()) {
            *lost = lost.wrapping_add(n);
        }
    }

    /// Feeds bytes that arrived on `port`.
    pub fn ingest(&mut self, port: Port, bytes: &[u8]) {
        let i = port.index();
        if let (Some(channel), Some(inbox)) = (self.channels.get_mut(i), self.inbox.get_mut(i)) {
            channel.receive(bytes, |m| inbox.push_back(m).is_ok());
        }
    }

    /// Whether messages of a batch that arrived on `port` wait for room in
    /// its inbox ([`FramedLinks::can_ingest`]).
    pub fn holds_back(&self, port: Port) -> bool {
        self.channels.get(port.index()).is_some_and(Channel::holds_back)
    }

    /// Whether `port` can take another received message. A byte stream that
    /// can wait (a UART whose sender is flow-controlled) should stop feeding
    /// the port until this is true again, so no frame is dropped for room.
    ///
    /// Nor while the rest of a batch waits for room: it is in the buffer the
    /// next bytes would go to. An [`FramedLinks::ingest`] with no bytes
    /// hands it over once the inbox has room.
    pub fn can_ingest(&self, port: Port) -> bool {
        self.inbox.get(port.index()).is_some_and(|q| !q.is_full()) && !self.holds_back(port)
    }

    /// Writes what is due on every port at `now`; `write` returns false when a
    /// port's byte link is full.
    pub fn transmit(&mut self, now: u64, mut write: impl FnMut(Port, &[u8]) -> bool) {
        for (channel, port) in self.channels.iter_mut().zip(Port::ALL) {
            channel.transmit_via(now, &mut self.scratch, |bytes| write(port, bytes));
        }
    }

    /// Whether frames await acknowledgement or control frames are due.
    pub fn busy(&self) -> bool {
        self.channels.iter().any(Channel::busy) || self.inbox.iter().any(|q| !q.is_empty())
    }

    /// The longest any peer has left our data unacknowledged, and on which port.
    pub fn unanswered_for(&self, now: u64) -> (u64, Port) {
        let mut worst = (0, Port::Host);
        for (channel, port) in self.channels.iter().zip(Port::ALL) {
            let t = channel.unanswered_for(now);
            if t > worst.0 {
                worst = (t, port);
            }
        }
        worst
    }

    /// Counters summed over the seven channels.
    pub fn stats(&self) -> ChannelStats {
        self.channels.iter().map(|c| c.stats).sum()
    }
}

impl<const W: usize, const Q: usize> Links for FramedLinks<W, Q> {
    fn cabled(&self, port: Port) -> bool {
        self.uncabled.get(port.index()).is_some_and(|&u| !u)
    }

    fn health(&self, port: Port) -> PortHealth {
        self.channels.get(port.index()).map_or_else(PortHealth::default, |c| PortHealth {
            resent: c.stats.retransmitted,
            damaged: c.stats.corrupted,
            lost: self.lost.get(port.index()).copied().unwrap_or(0),
        })
    }

    fn recv(&mut self, port: Port) -> Option<Message> {
        self.inbox.get_mut(port.index())?.pop_front()
    }

    fn try_send(&mut self, port: Port, msg: Message) -> Result<(), Message> {
        match self.channels.get_mut(port.index()) {
            Some(channel) => channel.send(msg),
            None => Err(msg),
        }
    }

    fn try_send_ray(&mut self, port: Port, ray: &OutgoingRay<'_>) -> bool {
        self.channels.get_mut(port.index()).is_some_and(|channel| channel.send_ray(ray))
    }

    fn session(&self) -> Option<u32> {
        self.channels.get(Port::Host.index()).and_then(Channel::peer_incarnation)
    }

    fn peer_restarted(&mut self) -> Option<Port> {
        let mut channels = self.channels.iter_mut().zip(Port::ALL);
        channels.find_map(|(c, port)| c.take_peer_restart().then_some(port))
    }
}
