//! The in-memory board as a transport: every node a [`SimNode`] in this
//! process, messages moved in virtual time.

use link_proto::{Capacity, Message};
use node_fw::reliable::ChannelStats;
use sim_board::{Board, Busy, HostEndpoint, SimConfig, SimNode};

use crate::error::HostError;
use crate::plan::Plan;
use crate::plan::options::RenderOptions;
use crate::plan::partition::Partition;
use crate::results::RenderResult;
use crate::scene::Scene;
use crate::session::clock::Cycles;
use crate::session::transport::{Endpoint, RunEnd, Transport};

/// The host's endpoint as the board sees it: arrival times in its cycles.
struct Stamped<'a, E>(&'a mut E);

impl<E: Endpoint<Cycles>> HostEndpoint for Stamped<'_, E> {
    fn receive(&mut self, node: u16, at: u64, msg: Message) {
        self.0.receive(node, Cycles(at), msg);
    }

    fn finished(&self) -> bool {
        self.0.finished()
    }
}

impl Transport for Board {
    type Time = Cycles;

    fn nodes(&self) -> usize {
        self.len()
    }

    fn capacity(&self) -> Capacity {
        SimNode::capacity()
    }

    fn send(&mut self, node: usize, msg: Message) {
        Board::send(self, node, msg);
    }

    fn run(&mut self, host: &mut impl Endpoint<Cycles>) -> Result<RunEnd<Cycles>, HostError> {
        let stats = Board::run(self, &mut Stamped(host)).map_err(|e| HostError::Node(e.to_string()))?;
        Ok(RunEnd { start: Cycles(stats.start), end: Cycles(stats.end), rounds: stats.rounds })
    }

    fn bytes_sent(&self, node: usize) -> [u64; 7] {
        Board::bytes_sent(self, node)
    }

    fn link_stats(&self) -> ChannelStats {
        Board::link_stats(self)
    }

    fn busy(&self, node: usize) -> Option<Busy> {
        (node < self.len()).then(|| Board::busy(self, node))
    }

    fn bytes_received(&self, node: usize) -> [u64; 7] {
        if node < self.len() { Board::bytes_received(self, node) } else { [0; 7] }
    }
}

/// Renders `scene` on the in-memory board with its starting partition.
pub fn render_sim(scene: &Scene, opts: &RenderOptions) -> Result<RenderResult<Cycles>, HostError> {
    render_plan(scene, &Plan::new(scene, opts, SimNode::capacity())?)
}

/// Renders `scene` on the in-memory board with a given partition.
pub fn render_partitioned(
    scene: &Scene,
    opts: &RenderOptions,
    partition: Partition,
) -> Result<RenderResult<Cycles>, HostError> {
    render_plan(scene, &Plan::with_partition(scene, opts, partition, SimNode::capacity())?)
}

/// Renders a planned frame on a new in-memory board.
pub fn render_plan(scene: &Scene, plan: &Plan) -> Result<RenderResult<Cycles>, HostError> {
    crate::session::run(&mut board(&plan.options), scene, plan)
}

/// A new in-memory board of `opts.array` as `opts.sim` configures it.
pub fn board(opts: &RenderOptions) -> Board {
    Board::new(SimConfig { array: opts.array, ..opts.sim })
}
