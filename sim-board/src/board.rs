//! The board: nodes, their wiring, and the round-based virtual-time loop.

use std::fmt;

use link_proto::Message;
use node_fw::{Node, Port};
use rayon::prelude::*;

use crate::cost::{CostModel, LinkModel};
use crate::sim_links::{PortState, SimLinks};

/// The node firmware as the board runs it: 2048 spheres, 32768 sphere
/// references, 32768 cubes (a 32^3 grid on one node) and 4096 ray slots
/// (an 8x8x8 array with sliding needs 661 class levels at depth 3 and more).
pub type SimNode = Node<2048, 32768, 32768, 4096>;

/// Active nodes in a round from which the round runs on all cores.
const PARALLEL_MIN_ACTIVE: usize = 32;

/// Board settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimConfig {
    /// Nodes per axis.
    pub array: [u16; 3],
    /// Node work costs.
    pub cost: CostModel,
    /// Node-to-node links.
    pub link: LinkModel,
    /// Node-to-host links.
    pub host_link: LinkModel,
}

impl SimConfig {
    /// Default costs and links for an array.
    pub fn new(array: [u16; 3]) -> Self {
        Self {
            array,
            cost: CostModel::default(),
            link: LinkModel::default(),
            host_link: LinkModel { capacity: 64, ..LinkModel::default() },
        }
    }
}

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
        }
    }
}

impl std::error::Error for SimError {}

/// Counters of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RunStats {
    /// Virtual time when the run stopped.
    pub end: u64,
    /// Rounds simulated.
    pub rounds: u64,
}

/// One node and its ports.
struct Slot {
    node: Box<SimNode>,
    clock: u64,
    ports: [PortState; 7],
    wired: [bool; 7],
    miswired: Option<Port>,
}

impl Slot {
    fn next_arrival(&self) -> Option<u64> {
        self.ports.iter().filter_map(|p| p.inbox.front().map(|(at, _)| *at)).min()
    }

    /// When this node next has something to do, if ever without new input.
    fn next_event(&self) -> Option<u64> {
        let own = self.node.pending().then_some(self.clock);
        match (own, self.next_arrival()) {
            (Some(a), Some(b)) => Some(a.min(b.max(self.clock))),
            (a, b) => a.or(b.map(|b| b.max(self.clock))),
        }
    }

    /// Runs the node until `end`; returns whether it did any work.
    fn run(&mut self, end: u64, config: &SimConfig) -> bool {
        let mut worked = false;
        while self.clock < end {
            let mut links = SimLinks {
                ports: &mut self.ports,
                wired: self.wired,
                now: self.clock,
                link: config.link,
                host_link: config.host_link,
                miswired: None,
            };
            let work = self.node.poll(self.clock, &mut links);
            self.miswired = self.miswired.or(links.miswired);
            if work.is_busy() {
                worked = true;
                self.clock += config.cost.charge(&work);
                continue;
            }
            // Idle: wait for the next arrival in this round, else to the round's end.
            self.clock = match self.next_arrival() {
                Some(at) if at > self.clock && at < end => at,
                _ => end,
            };
        }
        worked
    }
}

/// Builds `count` boxed nodes on a thread with a large stack: a node is about a
/// megabyte and `Box::new` may build it on the stack first, which overflows the
/// 2 MiB stack of a test thread.
fn build_nodes(count: usize) -> Vec<Box<SimNode>> {
    let build = move || (0..count).map(|id| Box::new(SimNode::new(id as u16))).collect::<Vec<_>>();
    std::thread::Builder::new()
        .name("sim-board-build".into())
        .stack_size(64 << 20)
        .spawn(build)
        .ok()
        .and_then(|h| h.join().ok())
        .unwrap_or_default()
}

/// X x Y x Z nodes running the node firmware, wired to their face neighbours.
pub struct Board {
    config: SimConfig,
    slots: Vec<Slot>,
    neighbours: Vec<[Option<usize>; 6]>,
    rounds: u64,
}

impl Board {
    /// A board of `config.array` fresh nodes, numbered `x + X (y + Y z)`.
    pub fn new(config: SimConfig) -> Self {
        let [nx, ny, nz] = config.array.map(usize::from);
        let count = nx * ny * nz;
        let mut neighbours = Vec::with_capacity(count);
        let mut slots = Vec::with_capacity(count);
        let mut nodes = build_nodes(count).into_iter();
        for id in 0..count {
            let c = [id % nx, (id / nx) % ny, id / (nx * ny)];
            let n: [Option<usize>; 6] = std::array::from_fn(|p| {
                let (axis, positive) = (p / 2, p % 2 == 0);
                let size = [nx, ny, nz][axis];
                let mut d = c;
                if positive && c[axis] + 1 < size {
                    d[axis] += 1;
                } else if !positive && c[axis] > 0 {
                    d[axis] -= 1;
                } else {
                    return None;
                }
                Some(d[0] + nx * (d[1] + ny * d[2]))
            });
            let mut wired = [true; 7];
            for (w, nb) in wired.iter_mut().zip(&n) {
                *w = nb.is_some();
            }
            neighbours.push(n);
            slots.push(Slot {
                node: nodes.next().unwrap_or_else(|| Box::new(SimNode::new(id as u16))),
                clock: 0,
                ports: Default::default(),
                wired,
                miswired: None,
            });
        }
        Self { config, slots, neighbours, rounds: 0 }
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

    /// Queues a host-to-node message; it arrives at the node's current time.
    pub fn send(&mut self, node: usize, msg: Message) {
        let slot = &mut self.slots[node];
        let at = slot.clock;
        slot.ports[Port::Host.index()].inbox.push_back((at, msg));
    }

    /// Runs until the host is finished; fails on a stall or a miswired send.
    pub fn run(&mut self, host: &mut impl HostEndpoint) -> Result<RunStats, SimError> {
        let lookahead = self.config.link.latency.min(self.config.host_link.latency).max(1);
        let mut now = self.slots.iter().map(|s| s.clock).min().unwrap_or(0);
        while !host.finished() {
            let Some(start) = self.slots.iter().filter_map(Slot::next_event).min() else {
                let nodes_pending = self.slots.iter().filter(|s| s.node.pending()).count();
                return Err(SimError::Deadlock { at: now, nodes_pending });
            };
            let end = start + lookahead;
            let worked = self.round(end);
            self.rounds += 1;
            if let Some((node, port)) =
                self.slots.iter().enumerate().find_map(|(i, s)| s.miswired.map(|p| (i, p)))
            {
                return Err(SimError::Miswired { node: node as u16, port });
            }
            let in_flight = self.deliver(host);
            if !worked
                && !in_flight
                && self.slots.iter().all(|s| s.next_arrival().is_none())
                && !host.finished()
            {
                let nodes_pending = self.slots.iter().filter(|s| s.node.pending()).count();
                return Err(SimError::Deadlock { at: end, nodes_pending });
            }
            now = end;
        }
        Ok(RunStats { end: now, rounds: self.rounds })
    }

    /// Runs every node with something to do before `end`; returns whether any worked.
    fn round(&mut self, end: u64) -> bool {
        // Snapshot what each sender sees of its peer's inbox.
        for i in 0..self.slots.len() {
            for p in 0..6 {
                if let Some(j) = self.neighbours[i][p] {
                    let back = Port::NEIGHBOURS[p].opposite().index();
                    let occ = self.slots[j].ports[back].inbox.len();
                    self.slots[i].ports[p].occupancy = occ;
                }
            }
            self.slots[i].ports[Port::Host.index()].occupancy = 0;
        }
        let config = self.config;
        let active = |s: &Slot| s.next_event().is_some_and(|t| t < end);
        let busy = self.slots.iter().filter(|s| active(s)).count();
        let run = |s: &mut Slot| {
            if !active(s) {
                return false;
            }
            if !s.node.pending() {
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
    fn deliver(&mut self, host: &mut impl HostEndpoint) -> bool {
        let mut moved = false;
        let mut to_host = Vec::new();
        for i in 0..self.slots.len() {
            for p in 0..7 {
                let out = std::mem::take(&mut self.slots[i].ports[p].outbox);
                if out.is_empty() {
                    continue;
                }
                moved = true;
                if p == Port::Host.index() {
                    to_host.extend(out.into_iter().map(|(at, m)| (at, i as u16, m)));
                    continue;
                }
                let Some(j) = self.neighbours[i][p] else { continue };
                let back = Port::NEIGHBOURS[p].opposite().index();
                self.slots[j].ports[back].inbox.extend(out);
            }
        }
        // The host takes messages in arrival order (ties by node), whatever the threads did.
        to_host.sort_by_key(|(at, node, _)| (*at, *node));
        for (at, node, msg) in to_host {
            host.receive(node, at, msg);
        }
        moved
    }
}
