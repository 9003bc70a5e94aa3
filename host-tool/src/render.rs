//! Driving a frame on the in-memory board: broadcast, render, collect, finish.

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};
use link_proto::{Balance, InitialRays, Message, RenderStart, SceneEnd};
use node_fw::pool::class_bound;
use sim_board::{Board, HostEndpoint, RunStats, SimConfig, SimNode};

use crate::camera::PixelBasis;
use crate::error::{HostError, input};
use crate::frame::FrameBuffer;
use crate::partition::{Partition, tiles};
use crate::scene::Scene;

/// Credit of one initial ray: children split it, so it must survive
/// `(lights + 2)^max_depth` divisions (at most 10^8 < 2^32).
pub const PIXEL_CREDIT: u64 = 1 << 32;

/// How to render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Nodes per axis.
    pub array: [u16; 3],
    /// Image width and height.
    pub size: [u16; 2],
    /// Who creates the initial rays.
    pub initial: InitialRays,
    /// Ray pool slots per class level.
    pub level_depth: u16,
    /// Board costs and links.
    pub sim: SimConfig,
    /// Sliding boundaries, or `None` for the static partition.
    pub balance: Option<Balance>,
    /// Driving axis; `None` picks the paper's (most varied sphere counts).
    pub driving_axis: Option<u8>,
}

impl RenderOptions {
    /// Defaults for an array: 256 x 256 pixels, parallel initial rays, depth 4.
    pub fn new(array: [u16; 3]) -> Self {
        Self {
            array,
            size: [256, 256],
            initial: InitialRays::Parallel,
            level_depth: 4,
            sim: SimConfig::new(array),
            balance: None,
            driving_axis: None,
        }
    }
}

/// A rendered frame and how it went.
#[derive(Debug, Clone)]
pub struct RenderResult {
    /// Pixels, accounting and loads.
    pub frame: FrameBuffer,
    /// The partition used.
    pub partition: Partition,
    /// Board counters.
    pub stats: RunStats,
    /// Bytes each node sent, per port.
    pub bytes: Vec<[u64; 7]>,
    /// Host wall time of the run.
    pub wall: Duration,
    /// Retransmissions and damaged frames on the links (framed mode).
    pub links: node_fw::reliable::ChannelStats,
}

/// Renders `scene` on the in-memory board with the even partition.
pub fn render_sim(scene: &Scene, opts: &RenderOptions) -> Result<RenderResult, HostError> {
    let axis = match opts.driving_axis {
        Some(a) if a > 2 => return Err(input(format!("driving axis {a} must be 0, 1 or 2"))),
        Some(a) => a,
        None => crate::partition::driving_axis(scene, opts.array)?,
    };
    let partition = Partition::even(scene.grid, opts.array, axis)?;
    render_partitioned(scene, opts, partition)
}

/// Renders `scene` on the in-memory board with a given partition.
pub fn render_partitioned(
    scene: &Scene,
    opts: &RenderOptions,
    partition: Partition,
) -> Result<RenderResult, HostError> {
    let [w, h] = opts.size;
    if w == 0 || h == 0 {
        return Err(HostError::ZeroSize(format!("image size {w}x{h} must be at least 1x1")));
    }
    let axis = partition.driving_axis;
    partition.check_capacity(scene, SimNode::capacity())?;
    let sliding = opts.balance.is_some() || partition.row_cuts.is_some();
    let top = class_bound(opts.array, scene.max_depth, sliding.then_some(usize::from(axis)));
    let needed = (top + 1) * u32::from(opts.level_depth);
    if opts.level_depth == 0 || needed > u32::from(SimNode::capacity().rays) {
        return Err(HostError::Capacity(format!(
            "queue depth {} needs {needed} ray slots per node for this array and max_depth; a node has {}",
            opts.level_depth,
            SimNode::capacity().rays
        )));
    }
    let started = Instant::now();
    let mut board = Board::new(SimConfig { array: opts.array, ..opts.sim });
    let mut frame = FrameBuffer::new(w, h, board.len(), PIXEL_CREDIT);
    broadcast(&mut board, scene, &partition, opts);

    let mut tracked = Tracked { frame: &mut frame, started, bar: None };
    let run = board.run(&mut tracked);
    if let Some(bar) = tracked.bar.take() {
        bar.finish_and_clear();
    }
    // A node's own report (or restart) explains a failed run better than the stall it causes.
    node_errors(&frame, &partition)?;
    let stats = run.map_err(|e| HostError::Node(format!("render failed: {e}")))?;

    frame.finishing = true;
    for id in 0..board.len() {
        board.send(id, Message::Finish(link_proto::Finish { frame: 0 }));
    }
    board.run(&mut frame).map_err(|e| HostError::Node(format!("collecting loads failed: {e}")))?;
    node_errors(&frame, &partition)?;
    let bytes = (0..board.len()).map(|i| board.bytes_sent(i)).collect();
    Ok(RenderResult { frame, partition, stats, bytes, wall: started.elapsed(), links: board.link_stats() })
}

/// Sends the scene, assignments and render start to every node.
fn broadcast(board: &mut Board, scene: &Scene, partition: &Partition, opts: &RenderOptions) {
    let [w, h] = opts.size;
    let camera = PixelBasis::new(&scene.camera(), w, h).msg();
    let tiles = match opts.initial {
        InitialRays::Parallel => tiles(w, h, partition.len()),
        InitialRays::EyeNode => {
            let eye = partition.owner_of(scene.camera().eye, scene.grid);
            (0..partition.len()).map(|i| if i == eye { [0, 0, w, h] } else { [0; 4] }).collect()
        }
    };
    let spheres = scene.sphere_msgs();
    let lights = scene.light_msgs();
    for (id, tile) in tiles.iter().enumerate() {
        board.send(id, Message::SceneBegin(scene.header()));
        board.send(id, Message::Assign(partition.assign(id)));
        for s in &spheres {
            board.send(id, Message::Sphere(*s));
        }
        for l in &lights {
            board.send(id, Message::Light(*l));
        }
        board.send(
            id,
            Message::SceneEnd(SceneEnd { spheres: spheres.len() as u32, lights: lights.len() as u8 }),
        );
        board.send(
            id,
            Message::RenderStart(RenderStart {
                frame: 0,
                size: [w, h],
                camera,
                initial: opts.initial,
                tile: *tile,
                credit: PIXEL_CREDIT,
                level_depth: opts.level_depth,
                balance: opts.balance,
            }),
        );
    }
}

/// The first node error as a one-line host error.
fn node_errors(frame: &FrameBuffer, partition: &Partition) -> Result<(), HostError> {
    if let Some(&(node, version)) = frame.version_mismatch.first() {
        return Err(HostError::Version(format!(
            "node {node} speaks protocol version {version}, the host {}",
            link_proto::PROTOCOL_VERSION
        )));
    }
    if let Some(&node) = frame.restarted.first() {
        let c = partition.coord(usize::from(node));
        return Err(HostError::Node(format!(
            "node {node} ({},{},{}) restarted mid-render (it said hello again); no image written",
            c[0], c[1], c[2]
        )));
    }
    let Some(e) = frame.errors.first() else { return Ok(()) };
    let c = partition.coord(usize::from(e.node));
    Err(HostError::Node(format!(
        "node {} ({},{},{}) reported {:?} (a = {}, b = {})",
        e.node, c[0], c[1], c[2], e.code, e.a, e.b
    )))
}

/// Forwards to the frame buffer and shows progress once a render passes a second.
struct Tracked<'a> {
    frame: &'a mut FrameBuffer,
    started: Instant,
    bar: Option<ProgressBar>,
}

impl HostEndpoint for Tracked<'_> {
    fn receive(&mut self, node: u16, at: u64, msg: link_proto::Message) {
        self.frame.receive(node, at, msg);
        if self.bar.is_none() && self.started.elapsed() > Duration::from_secs(1) {
            let bar = ProgressBar::new(1000);
            if let Ok(style) =
                ProgressStyle::with_template("rendering {bar:40} {percent}% ({elapsed} elapsed, ~{eta} left)")
            {
                bar.set_style(style);
            }
            self.bar = Some(bar);
        }
        if let Some(bar) = &self.bar {
            let done = self.frame.credit_back * 1000 / self.frame.credit_total.max(1);
            bar.set_position(done as u64);
        }
    }

    fn finished(&self) -> bool {
        self.frame.finished()
    }
}
