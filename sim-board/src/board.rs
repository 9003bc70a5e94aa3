//! The board: nodes, their wiring, and the round-based virtual-time loop.

use std::fmt;

use std::collections::{BTreeMap, VecDeque};

use link_proto::{BoardId, BoardInfo, Hello, Message};
use node_fw::Port;
use node_fw::reliable::{Channel, ChannelStats, WINDOW};
use rayon::prelude::*;

pub use crate::config::{SIM_INBOX, SimConfig, SimFramed, SimNode};
use crate::cost::{Busy, LinkModel};
use crate::faults::FaultRng;
use crate::link_spec::LinkSpec;
use crate::sim_links::Stamped;
use crate::slot::Slot;

/// Active nodes in a round from which the round runs on all cores.
const PARALLEL_MIN_ACTIVE: usize = 32;

/// The host side of the board: it receives every node-to-host message.
pub trait HostEndpoint {
    /// A message from `node` arrived at virtual time `at`.
    fn receive(&mut self, node: u16, at: u64, msg: Message);
    /// Whether the run may stop.
    fn finished(&self) -> bool;
}

/// Why a run stopped without finishing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SimError {
    /// Nothing can move and the host is not finished.
    Deadlock {
        /// Virtual time of the stall.
        at: u64,
        /// Nodes that still hold work.
        nodes_pending: usize,
    },
    /// No node sent the host anything for the watchdog's time.
    Stalled {
        /// Virtual time of the last message to the host.
        since: u64,
        /// Nodes that still hold work.
        nodes: Vec<u16>,
    },
    /// A node sent through a port with no neighbour.
    Miswired {
        /// The node.
        node: u16,
        /// The port.
        port: Port,
    },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Deadlock { at, nodes_pending } => {
                write!(
                    f,
                    "the array stalled at virtual time {at} with {nodes_pending} nodes still holding work"
                )
            }
            SimError::Miswired { node, port } => {
                write!(f, "node {node} sent through {port:?}, which has no neighbour")
            }
            SimError::Stalled { since, nodes } => {
                write!(
                    f,
                    "no node has answered the host since virtual time {since}; nodes still holding work: {nodes:?}"
                )
            }
        }
    }
}

impl std::error::Error for SimError {}

/// Counters of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RunStats {
    /// Virtual time when the run started.
    pub start: u64,
    /// Virtual time when the run stopped.
    pub end: u64,
    /// Rounds simulated.
    pub rounds: u64,
}

/// A node's message or frame on its way to the host.
enum ToHost {
    /// A whole message (links carry messages).
    Message(Message),
    /// A frame's bytes, for the host's reliable channel (framed mode).
    Frame(Vec<u8>),
}

/// Inserts a frame into a wire kept in arrival order (delays can reorder).
fn arrive(wire: &mut VecDeque<(u64, Vec<u8>)>, at: u64, bytes: Vec<u8>) {
    let pos = wire.iter().rposition(|(t, _)| *t <= at).map_or(0, |i| i + 1);
    wire.insert(pos, (at, bytes));
}

/// Builds `count` boxed nodes on a thread with a large stack: a node is about a
/// megabyte and `Box::new` may build it on the stack first, which overflows the
/// 2 MiB stack of a test thread.
fn build_nodes(first: usize, count: usize) -> Vec<Box<SimNode>> {
    let build =
        move || (first..first + count).map(|id| Box::new(SimNode::new(id as u16))).collect::<Vec<_>>();
    std::thread::Builder::new()
        .name("sim-board-build".into())
        .stack_size(64 << 20)
        .spawn(build)
        .ok()
        .and_then(|h| h.join().ok())
        .unwrap_or_default()
}

/// One boxed node built on the caller's stack, where [`build_nodes`] could
/// not start its thread. Never inlined: inlined, the node's megabyte would
/// sit in the caller's frame even when this is not called (a release build of
/// [`Board::new`] then overflowed a test thread's 2 MiB stack).
#[inline(never)]
fn boxed_node(id: usize) -> Box<SimNode> {
    Box::new(SimNode::new(id as u16))
}

/// A node's reliable channels, saying hello only where it has neighbours.
fn framed_links(config: &SimConfig, wired: [bool; 7]) -> Box<SimFramed> {
    let mut links = Box::new(SimFramed::new(channel_timeout(config)));
    links.set_cabled(wired);
    links
}

/// The id of the in-memory board's node `id`: its index plus one (zero is no id).
pub fn board_id(id: usize) -> BoardId {
    BoardId([id as u32 + 1, 0, 0])
}

/// What the in-memory board's node `id` says it runs on.
pub fn board_info(id: usize) -> BoardInfo {
    BoardInfo { id: board_id(id), ..node_fw::node::UNNAMED_BOARD }
}

/// X x Y x Z nodes running the node firmware, wired to their face neighbours.
pub struct Board {
    config: SimConfig,
    slots: Vec<Slot>,
    neighbours: Vec<[Option<usize>; 6]>,
    rounds: u64,
    /// Framed mode: the host's channel to each node, what waits to enter it,
    /// and the fault generator of each host-to-node wire.
    host_channels: Vec<Channel<WINDOW>>,
    host_backlog: Vec<VecDeque<Message>>,
    host_rng: Vec<FaultRng>,
    /// Arrival time of the latest node-to-host message.
    last_to_host: u64,
    /// The host's time: when its last run ended. What it sends after a run
    /// leaves no earlier, though a node idle since before still holds the
    /// time it went idle.
    host_clock: u64,
    /// Per node, when the host's wire to it is free: what the host sends a
    /// node crosses that wire a byte at a time, as a node's messages to the
    /// host cross the wire back.
    host_wire: Vec<u64>,
    /// What nodes sent the host, by arrival time (then node, then order of
    /// sending): handed over once the board's time reaches it, so the host
    /// sees messages in the order they arrive even when a slow host link
    /// queues them far ahead of the round that sent them.
    to_host: BTreeMap<(u64, u16, u64), ToHost>,
    /// Order of sending, for `to_host`'s keys.
    to_host_seq: u64,
    /// Per node, how many of `to_host` are its: what its host link holds.
    to_host_held: Vec<usize>,
    restarted: bool,
}

impl Board {
    /// A board of `config.array` fresh nodes, numbered `x + X (y + Y z)`.
    pub fn new(config: SimConfig) -> Self {
        let [nx, ny, nz] = config.array.map(usize::from);
        let count = nx * ny * nz;
        let mut neighbours = Vec::with_capacity(count);
        let mut slots = Vec::with_capacity(count);
        let mut nodes = build_nodes(0, count).into_iter();
        for id in 0..count {
            let n: [Option<usize>; 6] = std::array::from_fn(|p| {
                node_fw::wiring::neighbour_of(id, Port::NEIGHBOURS[p], config.array).map(usize::from)
            });
            let mut wired = [true; 7];
            for (w, nb) in wired.iter_mut().zip(&n) {
                *w = nb.is_some();
            }
            neighbours.push(n);
            let mut node = nodes.next().unwrap_or_else(|| boxed_node(id));
            node.set_board(board_info(id));
            slots.push(Slot {
                node,
                clock: 0,
                busy: Busy::default(),
                ports: Default::default(),
                wired,
                miswired: None,
                framed: config.faults.map(|_| framed_links(&config, wired)),
                rng: std::array::from_fn(|p| FaultRng::new(config.faults.map_or(0, |f| f.seed), id, p)),
                queued: Vec::new(),
            });
        }
        let framed = config.faults.is_some();
        let seed = config.faults.map_or(0, |f| f.seed);
        Self {
            host_channels: (0..if framed { count } else { 0 })
                .map(|_| Channel::new(channel_timeout(&config)))
                .collect(),
            // The host speaks first, as a serial host does: a node says hello
            // once its host link is synchronised, and a channel synchronises
            // only when it has something to send.
            host_backlog: vec![
                VecDeque::from([Message::Hello(Hello::host())]);
                if framed { count } else { 0 }
            ],
            host_rng: (0..count).map(|id| FaultRng::new(seed ^ 0x5EED, id, 7)).collect(),
            config,
            slots,
            neighbours,
            rounds: 0,
            last_to_host: 0,
            host_clock: 0,
            host_wire: vec![0; count],
            to_host: BTreeMap::new(),
            to_host_seq: 0,
            to_host_held: vec![0; count],
            restarted: false,
        }
    }

    /// Retransmissions, corrupted frames and discarded frames over every
    /// channel (framed mode).
    pub fn link_stats(&self) -> ChannelStats {
        let nodes = self.slots.iter().filter_map(|s| s.framed.as_ref().map(|f| f.stats()));
        let host = self.host_channels.iter().map(|c| c.stats);
        nodes.chain(host).sum()
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Whether the board has no node.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// The settings.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Node `i`, for inspection.
    pub fn node(&self, i: usize) -> &SimNode {
        &self.slots[i].node
    }

    /// Bytes node `i` sent on each port.
    pub fn bytes_sent(&self, i: usize) -> [u64; 7] {
        std::array::from_fn(|p| self.slots[i].ports[p].bytes)
    }

    /// Bytes node `i` took from each port.
    pub fn bytes_received(&self, i: usize) -> [u64; 7] {
        std::array::from_fn(|p| self.slots[i].ports[p].bytes_in)
    }

    /// Node `i`'s busy cycles so far, by what they were spent on.
    pub fn busy(&self, i: usize) -> Busy {
        self.slots[i].busy
    }

    /// Queues a host-to-node message. It leaves at the node's current time,
    /// or when the host's last run ended if the node has been idle since
    /// before (the host sends it no earlier), once the wire to the node is
    /// free, and arrives when its last byte has crossed.
    pub fn send(&mut self, node: usize, msg: Message) {
        if let Some(backlog) = self.host_backlog.get_mut(node) {
            backlog.push_back(msg);
            return;
        }
        let slot = &mut self.slots[node];
        let len = crate::sim_links::frame_len(&msg) as u64;
        let model = self.config.host_link.model();
        let wire = &mut self.host_wire[node];
        *wire = slot.clock.max(self.host_clock).max(*wire) + len * model.byte;
        let at = *wire + model.latency;
        slot.ports[Port::Host.index()].inbox.push_back(Stamped {
            at,
            msg,
            len,
            joined: false,
            frame_start: at,
        });
    }

    /// Runs until the host is finished; fails on a stall or a miswired send.
    pub fn run(&mut self, host: &mut impl HostEndpoint) -> Result<RunStats, SimError> {
        let lookahead = self.config.link.latency.min(self.config.host_link.latency).max(1);
        // The run starts when the host sends its first message: no earlier
        // than its last run ended (idle nodes' clocks stay where they went
        // idle), nor than every node's clock.
        let mut now = self.slots.iter().map(|s| s.clock).min().unwrap_or(0).max(self.host_clock);
        let start = now;
        while !host.finished() {
            let host_busy = self.host_channels.iter().any(Channel::busy)
                || self.host_backlog.iter().any(|b| !b.is_empty());
            let arriving = self.to_host.keys().next().map(|&(at, _, _)| at);
            let next = self.slots.iter().filter_map(Slot::next_event).chain(arriving).min();
            let Some(start) = next.or(host_busy.then_some(now)) else {
                let nodes_pending = self.slots.iter().filter(|s| s.node.pending()).count();
                return Err(SimError::Deadlock { at: now, nodes_pending });
            };
            let end = start + lookahead;
            self.restart_if_due(end);
            if end.saturating_sub(self.last_to_host) > self.config.watchdog {
                let nodes = (0..self.slots.len())
                    .filter(|&i| self.slots[i].node.pending())
                    .map(|i| i as u16)
                    .collect();
                return Err(SimError::Stalled { since: self.last_to_host, nodes });
            }
            let worked = self.round(end);
            self.rounds += 1;
            if let Some((node, port)) =
                self.slots.iter().enumerate().find_map(|(i, s)| s.miswired.map(|p| (i, p)))
            {
                return Err(SimError::Miswired { node: node as u16, port });
            }
            let in_flight = self.deliver(host, end);
            let quiet = self.slots.iter().all(|s| s.next_arrival().is_none() && !s.channels_busy())
                && !host_busy
                && self.to_host.is_empty();
            // A node whose clock ran past this round (a long poll) has not had
            // its turn yet: the array is stuck only once no node is ahead.
            let ahead = self.slots.iter().any(|s| s.next_event().is_some_and(|t| t >= end));
            if !worked && !in_flight && quiet && !ahead && !host.finished() {
                let nodes_pending = self.slots.iter().filter(|s| s.node.pending()).count();
                return Err(SimError::Deadlock { at: end, nodes_pending });
            }
            now = end;
        }
        self.host_clock = now;
        Ok(RunStats { start, end: now, rounds: self.rounds })
    }

    /// Runs every node with something to do before `end`; returns whether any worked.
    fn round(&mut self, end: u64) -> bool {
        // Snapshot what each sender sees of its peer's inbox, and of its
        // host link the messages still on their way (a board's window and
        // transmit buffer hold only so many).
        for i in 0..self.slots.len() {
            for p in 0..6 {
                if let Some(j) = self.neighbours[i][p] {
                    let back = Port::NEIGHBOURS[p].opposite().index();
                    let occ = self.slots[j].ports[back].inbox.len() + self.slots[j].ports[back].wire.len();
                    self.slots[i].ports[p].occupancy = occ;
                }
            }
            self.slots[i].ports[Port::Host.index()].occupancy =
                self.to_host_held.get(i).copied().unwrap_or(0);
        }
        let config = self.config;
        let active = |s: &Slot| s.next_event().is_some_and(|t| t < end);
        let busy = self.slots.iter().filter(|s| active(s)).count();
        let run = |s: &mut Slot| {
            if !active(s) {
                return false;
            }
            if !s.node.pending() {
                // Its last poll (perhaps a round ago) was busy: the time until
                // the next arrival is waiting, as on a board polling in a loop.
                s.node.idle(s.clock);
                s.clock = s.clock.max(s.next_arrival().unwrap_or(s.clock));
            }
            s.run(end, &config)
        };
        // Fork-join costs microseconds: worth it only when a round has many active nodes.
        if busy >= PARALLEL_MIN_ACTIVE {
            let chunk = self.slots.len().div_ceil(rayon::current_num_threads().max(1));
            self.slots.par_iter_mut().with_min_len(chunk).map(run).reduce(|| false, |a, b| a | b)
        } else {
            self.slots.iter_mut().map(run).fold(false, |a, b| a | b)
        }
    }

    /// Moves this round's sends into the receivers' inboxes in a fixed order;
    /// returns whether any message moved.
    fn deliver(&mut self, host: &mut impl HostEndpoint, now: u64) -> bool {
        let mut moved = self.deliver_frames(host, now);
        for i in 0..self.slots.len() {
            for p in 0..7 {
                let out = std::mem::take(&mut self.slots[i].ports[p].outbox);
                if out.is_empty() {
                    continue;
                }
                moved = true;
                if p == Port::Host.index() {
                    for m in out {
                        self.send_to_host(m.at, i, ToHost::Message(m.msg));
                    }
                    continue;
                }
                let Some(j) = self.neighbours[i][p] else { continue };
                let back = Port::NEIGHBOURS[p].opposite().index();
                let inbox = &mut self.slots[j].ports[back].inbox;
                // A batch begun in an earlier round that messages joined in
                // this one arrives whole, with its last.
                if let Some(first) = out.first().filter(|m| m.joined) {
                    let batch = first.frame_start;
                    let at =
                        out.iter().filter(|m| m.frame_start == batch).map(|m| m.at).max().unwrap_or(first.at);
                    inbox.iter_mut().rev().take_while(|m| m.frame_start == batch).for_each(|m| m.at = at);
                }
                inbox.extend(out);
            }
        }
        self.hand_to_host(host, now);
        moved
    }

    /// Queues what node `node` sent the host, to arrive at `at`.
    fn send_to_host(&mut self, at: u64, node: usize, what: ToHost) {
        self.to_host_seq += 1;
        self.to_host.insert((at, node as u16, self.to_host_seq), what);
        if let Some(held) = self.to_host_held.get_mut(node) {
            *held += 1;
        }
    }

    /// Hands the host what has arrived by `now`, in arrival order (ties by
    /// node), whatever the threads did: messages to it, frames to its
    /// channel for the node.
    fn hand_to_host(&mut self, host: &mut impl HostEndpoint, now: u64) {
        while let Some(entry) = self.to_host.first_entry() {
            let (at, node, _) = *entry.key();
            if at > now {
                break;
            }
            if let Some(held) = self.to_host_held.get_mut(usize::from(node)) {
                *held = held.saturating_sub(1);
            }
            // Progress is a message delivered to the host, not a frame resent.
            let last = &mut self.last_to_host;
            let mut take = |m: Message| {
                if progresses(&m) {
                    *last = (*last).max(at);
                }
                host.receive(node, at, m);
            };
            match entry.remove() {
                ToHost::Message(msg) => take(msg),
                ToHost::Frame(bytes) => {
                    if let Some(channel) = self.host_channels.get_mut(usize::from(node)) {
                        channel.receive(&bytes, |m| {
                            take(m);
                            true
                        });
                    }
                }
            }
        }
    }

    /// Resets the configured node to a fresh firmware state (and fresh link
    /// channels), as a reset or brown-out would, once its time has come.
    fn restart_if_due(&mut self, now: u64) {
        let Some((node, at)) = self.config.restart else { return };
        let i = usize::from(node);
        if self.restarted || now < at || i >= self.slots.len() {
            return;
        }
        self.restarted = true;
        if let Some(mut fresh) = build_nodes(i, 1).pop() {
            fresh.set_board(board_info(i));
            self.slots[i].node = fresh;
        }
        if self.slots[i].framed.is_some() {
            // A new incarnation, as a board's boot counter would give it.
            let mut links = framed_links(&self.config, self.slots[i].wired);
            links.set_incarnation(1);
            self.slots[i].framed = Some(links);
        }
    }

    /// Framed mode: moves this round's frames onto the peers' wires, runs the
    /// host's channels (frames in, acks and backlog out); returns whether any moved.
    fn deliver_frames(&mut self, host: &mut impl HostEndpoint, now: u64) -> bool {
        if self.host_channels.is_empty() {
            return false;
        }
        let faults = self.config.faults.unwrap_or_default();
        let mut moved = false;
        for i in 0..self.slots.len() {
            for p in 0..7 {
                let out = std::mem::take(&mut self.slots[i].ports[p].wire_out);
                moved |= !out.is_empty();
                for (at, bytes) in out {
                    if p == Port::Host.index() {
                        self.send_to_host(at, i, ToHost::Frame(bytes));
                    } else if let Some(j) = self.neighbours[i][p] {
                        let back = Port::NEIGHBOURS[p].opposite().index();
                        arrive(&mut self.slots[j].ports[back].wire, at, bytes);
                    }
                }
            }
        }
        self.hand_to_host(host, now);
        let model = self.config.host_link.model();
        for node in 0..self.host_channels.len() {
            let channel = &mut self.host_channels[node];
            while channel.can_send() {
                let Some(msg) = self.host_backlog[node].pop_front() else { break };
                if let Err(msg) = channel.send(msg) {
                    self.host_backlog[node].push_front(msg);
                    break;
                }
            }
            let (rng, wire) =
                (&mut self.host_rng[node], &mut self.slots[node].ports[Port::Host.index()].wire);
            let free = &mut self.host_wire[node];
            channel.transmit(now, |bytes| {
                let fate = rng.fate(&faults, bytes);
                // A frame crosses the wire a byte at a time, after those before it.
                *free = now.max(*free) + bytes.len() as u64 * model.byte;
                let at = *free + model.latency * if fate.delayed { 5 } else { 1 };
                for _ in 0..fate.copies {
                    arrive(wire, at, fate.bytes.clone());
                }
                moved = true;
                true
            });
        }
        moved
    }
}

/// Whether a message to the host shows the frame moving (periodic load
/// reports do not: they keep coming from a stuck array; a node's final
/// report, the answer to `Finish`, does). The host's watchdogs, on this
/// board and over serial links, count only these.
pub fn progresses(msg: &Message) -> bool {
    match msg {
        Message::Load(l) => l.interval == node_fw::node::FINAL_INTERVAL,
        // Boundaries may slide for ever while rays are stuck: not progress.
        // Nor is news of the cables and links.
        Message::SlideNote(_) | Message::SlideReply(_) | Message::Peer(_) | Message::LinkHealth(_) => false,
        _ => true,
    }
}

/// Resend time-out of the reliable channels: a few round trips of the slowest
/// link, plus the longest a receiver may take before it acknowledges: one
/// poll that handles a full inbox on every port and does its costliest work.
fn channel_timeout(config: &SimConfig) -> u64 {
    let frame = link_proto::MAX_FRAME_LEN as u64;
    let trip = |l: &LinkSpec| {
        let l: LinkModel = l.model();
        2 * (l.latency + frame * (l.byte + l.byte_cpu) + l.frame_cpu)
    };
    let c = &config.cost;
    let work = c.shade.max(c.create).max(c.trace + WALK_CUBES * c.cube_step);
    let poll = 7 * SIM_INBOX as u64 * c.ray_message.max(c.short_message) + work;
    4 * trip(&config.link).max(trip(&config.host_link)) + 2 * poll
}

/// Cubes a walk through one subregion may take, for the time-out's bound.
const WALK_CUBES: u64 = 256;
