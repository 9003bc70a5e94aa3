//! One node of the board and its ports: run until the end of a round, its
//! messages passed whole or, with faults injected, as frames through its
//! reliable channels.

use node_fw::Port;

use crate::config::{SimConfig, SimFramed, SimNode};
use crate::cost::{Busy, LinkModel};
use crate::faults::{FaultRng, Faults};
use crate::sim_links::{PortState, SimLinks};

/// One node and its ports.
pub(crate) struct Slot {
    pub(crate) node: Box<SimNode>,
    /// The node's own virtual time (it may run ahead within a round).
    pub(crate) clock: u64,
    /// Busy cycles so far, by what they were spent on.
    pub(crate) busy: Busy,
    /// Per port: messages or bytes in flight and the wire's occupancy.
    pub(crate) ports: [PortState; 7],
    /// Which ports have a node (or the host) at the other end.
    pub(crate) wired: [bool; 7],
    /// The first port the node sent to with nothing there, an error of the run.
    pub(crate) miswired: Option<Port>,
    /// Framed mode: the node's reliable channels and one fault generator per port.
    pub(crate) framed: Option<Box<SimFramed>>,
    pub(crate) rng: [FaultRng; 7],
    /// What a poll sent, until the board puts it on the wires (kept to
    /// spare an allocation a poll).
    pub(crate) queued: Vec<(Port, link_proto::Message)>,
}

impl Slot {
    /// When the earliest message or frame waiting for this node arrives.
    pub(crate) fn next_arrival(&self) -> Option<u64> {
        let messages = self.ports.iter().filter_map(|p| p.inbox.front().map(|m| m.at));
        let bytes = self.ports.iter().filter_map(|p| p.wire.front().map(|(at, _)| *at));
        messages.chain(bytes).min()
    }

    /// Whether the reliable channels still have frames to send or confirm.
    pub(crate) fn channels_busy(&self) -> bool {
        self.framed.as_ref().is_some_and(|f| f.busy())
    }

    /// When this node next has something to do, if ever without new input.
    pub(crate) fn next_event(&self) -> Option<u64> {
        let own = (self.node.pending() || self.channels_busy()).then_some(self.clock);
        match (own, self.next_arrival()) {
            (Some(a), Some(b)) => Some(a.min(b.max(self.clock))),
            (a, b) => a.or(b.map(|b| b.max(self.clock))),
        }
    }

    /// Runs the node until `end`; returns whether it did any work.
    pub(crate) fn run(&mut self, end: u64, config: &SimConfig) -> bool {
        if self.framed.is_some() {
            return self.run_framed(end, config);
        }
        let mut worked = false;
        while self.clock < end {
            let mut links = SimLinks {
                ports: &mut self.ports,
                wired: self.wired,
                now: self.clock,
                link: config.link.model(),
                host_link: config.host_link.model(),
                miswired: None,
                byte_cpu: 0,
                joined: 0,
                queued: &mut self.queued,
            };
            let work = self.node.poll(self.clock, &mut links);
            let charged = work.is_busy().then(|| config.cost.split(&work));
            // The board sends once the poll's work is done.
            links.transmit(self.clock + charged.map_or(0, |c| c.total().max(1)));
            let (miswired, byte_cpu) = (links.miswired, links.byte_cpu);
            self.miswired = self.miswired.or(miswired);
            let spared = links.joined * config.cost.frame_spared();
            worked |= self.advance(charged, byte_cpu, spared, end);
        }
        worked
    }

    /// Moves the clock past a poll: by its work's cost (`charged`, none for
    /// a poll that did no work) and the CPU cycles its bytes took
    /// (`byte_cpu`), less what messages sharing a frame spared (`spared`),
    /// or, idle, to the next arrival in this round or the round's end.
    /// Returns whether work was done.
    ///
    /// A poll that did no work of the node's (only acknowledgements moved)
    /// is not charged its bytes: the node's load meter counts it as waiting.
    fn advance(&mut self, charged: Option<Busy>, byte_cpu: u64, spared: u64, end: u64) -> bool {
        if let Some(mut split) = charged {
            split.messaging = (split.messaging + byte_cpu).saturating_sub(spared);
            self.busy += split;
            self.clock += split.total().max(1);
            return true;
        }
        self.clock = match self.next_arrival() {
            Some(at) if at > self.clock && at < end => at,
            _ => end,
        };
        false
    }

    /// Framed mode: bytes in, node poll through its reliable channels, bytes out.
    fn run_framed(&mut self, end: u64, config: &SimConfig) -> bool {
        let faults = config.faults.unwrap_or_default();
        let (link, host_link) = (config.link.model(), config.host_link.model());
        let model = |port: Port| if port == Port::Host { host_link } else { link };
        let mut worked = false;
        while self.clock < end {
            let Some(framed) = self.framed.as_mut() else { return worked };
            let mut byte_cpu = 0;
            for port in Port::ALL {
                let wire = &mut self.ports[port.index()].wire;
                while wire.front().is_some_and(|(at, _)| *at <= self.clock) {
                    if let Some((_, bytes)) = wire.pop_front() {
                        byte_cpu += bytes.len() as u64 * model(port).byte_cpu;
                        self.ports[port.index()].bytes_in += bytes.len() as u64;
                        framed.ingest(port, &bytes);
                    }
                }
            }
            let work = self.node.poll(self.clock, framed.as_mut());
            let (clock, wired, ports, rng) = (self.clock, self.wired, &mut self.ports, &mut self.rng);
            let mut miswired = None;
            framed.transmit(clock, |port, bytes| {
                let p = port.index();
                if !wired[p] {
                    miswired = Some(port);
                    return false;
                }
                let written = write_frame(&mut ports[p], &mut rng[p], &faults, model(port), clock, bytes);
                if written {
                    byte_cpu += bytes.len() as u64 * model(port).byte_cpu + model(port).frame_cpu;
                }
                written
            });
            self.miswired = self.miswired.or(miswired);
            worked |= self.advance(work.is_busy().then(|| config.cost.split(&work)), byte_cpu, 0, end);
        }
        worked
    }
}

/// Puts one frame on a port's wire through the fault injector; false when the
/// wire is full (the channel keeps the frame and tries again).
fn write_frame(
    state: &mut PortState,
    rng: &mut FaultRng,
    faults: &Faults,
    model: LinkModel,
    now: u64,
    bytes: &[u8],
) -> bool {
    if state.occupancy + state.wire_out.len() >= model.capacity {
        return false;
    }
    let start = now.max(state.busy_until);
    state.busy_until = start + bytes.len() as u64 * model.byte;
    state.bytes += bytes.len() as u64;
    let fate = rng.fate(faults, bytes);
    let arrival = state.busy_until + model.latency * if fate.delayed { 5 } else { 1 };
    for _ in 0..fate.copies {
        state.wire_out.push((arrival, fate.bytes.clone()));
    }
    true
}
