//! Driving a frame on an array: broadcast, render, collect, finish.
//!
//! The conversation with the nodes is the same whatever carries it: the
//! in-memory board, emulated boards under QEMU, or real boards over serial
//! devices ([`Array`]).

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};
use link_proto::{Balance, Boundaries, Capacity, ErrorCode, InitialRays, Message, RenderStart, SceneEnd};
use node_fw::Port;
use node_fw::pool::class_bound;
use node_fw::reliable::ChannelStats;
use sim_board::{Board, Busy, HostEndpoint, LinkPreset, RunStats, SimConfig, SimNode};

use crate::camera::PixelBasis;
use crate::entry::entry_tiles;
use crate::error::{HostError, input};
use crate::frame::FrameBuffer;
use crate::partition::{Partition, tiles, view_axis};
use crate::scene::Scene;

/// Credit of one initial ray: children split it, so it must survive
/// `(lights + 2)^max_depth` divisions (at most 10^8 < 2^32). The wire knows
/// it too: a ray with exactly this credit carries none.
pub use link_proto::ray_wire::PIXEL_CREDIT;

/// Who creates the initial rays: a sub-image per node, chosen by the host.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Initial {
    /// Every node creates the rays of a regular sub-image (the paper's
    /// parallel mode, Fig. 7 C).
    Parallel,
    /// The node holding the eye creates all of them (Fig. 7 B).
    EyeNode,
    /// The nodes on the face toward the eye create the rays that enter
    /// through their part of it ([`crate::entry`]; beyond the paper).
    Entry,
}

impl Initial {
    /// What the nodes are told: they create their tile's rays either way.
    pub fn wire(self) -> InitialRays {
        match self {
            Self::Parallel | Self::Entry => InitialRays::Parallel,
            Self::EyeNode => InitialRays::EyeNode,
        }
    }

    /// The name on the command line and in summaries.
    pub fn name(self) -> &'static str {
        match self {
            Self::Parallel => "parallel",
            Self::EyeNode => "eye",
            Self::Entry => "entry",
        }
    }
}

/// How the grid is first cut into subregions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Even boxes (the paper's start).
    Even,
    /// Cut to a preview: the host renders the frame at half the resolution
    /// per axis with the node kernels, measures each cube's cost and fits the
    /// partition to it ([`Partition::fitted`]; beyond the paper).
    Preview,
}

impl Layout {
    /// The name on the command line and in summaries.
    pub fn name(self) -> &'static str {
        match self {
            Self::Even => "even",
            Self::Preview => "preview",
        }
    }
}

/// Pixels per preview pixel along each image axis. A quarter per axis (a
/// sixteenth of the rays) left the map noisy enough that fits with columns
/// per slab followed the noise: at 2 the busiest node the full map predicts
/// was lower in 8 of 10 bench configurations (2.5% on average), and the
/// preview still takes milliseconds.
pub const PREVIEW_STRIDE: u16 = 2;

/// The proportional policy's settings: gamma 4 (ALL's stable choice), a 15% dead band
/// (at 10% two of the 16 `bench paper` configurations moved over 1% of their
/// boundaries per interval in steady state; see docs/partition-and-sliding.md).
pub const PROPORTIONAL: link_proto::SlidePolicy =
    link_proto::SlidePolicy::Proportional { gamma: 4 << 16, deadband: 9830 };

/// How to render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Nodes per axis.
    pub array: [u16; 3],
    /// Image width and height.
    pub size: [u16; 2],
    /// Who creates the initial rays.
    pub initial: Initial,
    /// Ray pool slots kept for each class level.
    pub level_depth: u16,
    /// Ray pool slots beyond those, open to every class; `None`: all a node
    /// has left over.
    pub shared_slots: Option<u16>,
    /// Board costs and links.
    pub sim: SimConfig,
    /// The preset `sim`'s links started from (for summaries; the settings
    /// themselves are `sim.link` and `sim.host_link`).
    pub link_preset: LinkPreset,
    /// Sliding boundaries, or `None` for the static partition.
    pub balance: Option<Balance>,
    /// Driving axis; `None` picks the paper's (most varied sphere counts).
    pub driving_axis: Option<u8>,
    /// How the grid is first cut.
    pub layout: Layout,
}

impl RenderOptions {
    /// Defaults for an array: 256 x 256 pixels, initial rays created where they
    /// enter, one slot kept per class level and every slot left over shared.
    pub fn new(array: [u16; 3]) -> Self {
        Self {
            array,
            size: [256, 256],
            initial: Initial::Entry,
            level_depth: 1,
            shared_slots: None,
            sim: SimConfig::new(array),
            link_preset: LinkPreset::default(),
            balance: None,
            driving_axis: None,
            layout: Layout::Even,
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
    /// Bytes each node took in, per port (the in-memory board; zeros where
    /// the transport cannot see them).
    pub bytes_in: Vec<[u64; 7]>,
    /// Each node's busy cycles by what they were spent on (the in-memory
    /// board; `None` where the transport cannot see inside the nodes).
    pub busy: Vec<Option<Busy>>,
    /// Host wall time of the run.
    pub wall: Duration,
    /// Retransmissions and damaged frames on the links (framed mode).
    pub links: node_fw::reliable::ChannelStats,
}

/// Nodes that render a frame, and what carries their messages.
pub trait Array {
    /// Number of nodes.
    fn nodes(&self) -> usize;
    /// What every node can hold.
    fn capacity(&self) -> Capacity;
    /// Queues a message from the host to node `node`.
    fn send(&mut self, node: usize, msg: Message);
    /// Moves messages until `host` is finished.
    fn run<H: HostEndpoint>(&mut self, host: &mut H) -> Result<RunStats, HostError>;
    /// Bytes node `node` sent, per port (as far as the transport counts them).
    fn bytes_sent(&self, node: usize) -> [u64; 7];
    /// Resends and damaged frames on the links.
    fn link_stats(&self) -> ChannelStats;
    /// Bytes node `node` took in, per port, where the transport can see them.
    fn bytes_received(&self, _node: usize) -> [u64; 7] {
        [0; 7]
    }
    /// Node `node`'s busy cycles by what they were spent on, where the
    /// transport can see them.
    fn busy(&self, _node: usize) -> Option<Busy> {
        None
    }
}

impl Array for Board {
    fn nodes(&self) -> usize {
        self.len()
    }

    fn capacity(&self) -> Capacity {
        SimNode::capacity()
    }

    fn send(&mut self, node: usize, msg: Message) {
        Board::send(self, node, msg);
    }

    fn run<H: HostEndpoint>(&mut self, host: &mut H) -> Result<RunStats, HostError> {
        Board::run(self, host).map_err(|e| HostError::Node(e.to_string()))
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

/// The starting partition of `scene` over `opts.array` along the chosen
/// driving axis, cut as `opts.layout` says, for nodes of `capacity`.
pub fn initial_partition(
    scene: &Scene,
    opts: &RenderOptions,
    capacity: Capacity,
) -> Result<Partition, HostError> {
    crate::frame::check_size(opts.size[0], opts.size[1])?;
    let axis = match opts.driving_axis {
        Some(a) if a > 2 => return Err(input(format!("driving axis {a} must be 0, 1 or 2"))),
        Some(a) => a,
        None => crate::partition::driving_axis(scene, opts.array)?,
    };
    match opts.layout {
        Layout::Even => Partition::even(scene.grid, opts.array, axis),
        Layout::Preview => {
            // Checked first so a bad array gets the even partition's error.
            Partition::even(scene.grid, opts.array, axis)?;
            // And the pool, before the preview takes its time.
            check_pool(scene, opts, axis, Boundaries::Whole, capacity)?;
            let [w, h] = opts.size.map(|n| n.div_ceil(PREVIEW_STRIDE).max(1));
            // Entry tiles create each ray on its entry cube's node: that is
            // work of the cube. Other modes spread creation by tiles.
            let creation = opts.initial == Initial::Entry;
            let costs = crate::direct::cost_map(scene, w, h, &opts.sim.cost, creation)
                .map_err(|e| e.context("the preview for --layout preview"))?;
            // Staggered no further than the nodes' pools can route at this depth.
            let most = [Boundaries::StaggeredColumns, Boundaries::StaggeredRows]
                .into_iter()
                .find(|&b| check_pool(scene, opts, axis, b, capacity).is_ok())
                .unwrap_or(Boundaries::Whole);
            Partition::fitted(scene.grid, opts.array, axis, &costs, most)
        }
    }
}

/// Renders `scene` on the in-memory board with its starting partition.
pub fn render_sim(scene: &Scene, opts: &RenderOptions) -> Result<RenderResult, HostError> {
    render_partitioned(scene, opts, initial_partition(scene, opts, SimNode::capacity())?)
}

/// Renders `scene` on the in-memory board with a given partition.
pub fn render_partitioned(
    scene: &Scene,
    opts: &RenderOptions,
    partition: Partition,
) -> Result<RenderResult, HostError> {
    check_frame(scene, opts, &partition, SimNode::capacity())?;
    let mut board = Board::new(SimConfig { array: opts.array, ..opts.sim });
    render_on(&mut board, scene, opts, partition)
}

/// Checks the image size, each node's share of the scene and the pool
/// depth against `capacity` before anything is sent.
pub fn check_frame(
    scene: &Scene,
    opts: &RenderOptions,
    partition: &Partition,
    capacity: Capacity,
) -> Result<(), HostError> {
    let [w, h] = opts.size;
    crate::frame::check_size(w, h)?;
    partition.check_capacity(scene, capacity)?;
    check_pool(scene, opts, partition.driving_axis, partition.boundaries(), capacity)
}

/// Checks that a node's ray pool can take the class levels and slots a frame
/// needs ([`node_fw::pool`]): the node would refuse the start otherwise, after
/// the whole scene had been sent.
fn check_pool(
    scene: &Scene,
    opts: &RenderOptions,
    axis: u8,
    boundaries: Boundaries,
    capacity: Capacity,
) -> Result<(), HostError> {
    if opts.level_depth == 0 {
        return Err(input("--queue-depth must be at least 1 (one ray slot per class level)"));
    }
    let lined_up = boundaries.when_sliding(opts.balance.is_some());
    let levels = class_bound(opts.array, scene.max_depth, usize::from(axis), lined_up) + 1;
    let sliding = if opts.balance.is_some() { " with sliding boundaries" } else { "" };
    let [x, y, z] = opts.array;
    if levels as usize > node_fw::pool::MAX_LEVELS {
        return Err(HostError::Capacity(format!(
            "rays on the {x}x{y}x{z} array{sliding} at max_depth {} take {levels} class levels; a node's pool \
             has at most {}: use a smaller array, a lower max_depth, or --balance static",
            scene.max_depth,
            node_fw::pool::MAX_LEVELS
        )));
    }
    let needed = slots_needed(scene, opts, axis, boundaries);
    if needed > u32::from(capacity.rays) {
        let shared = opts.shared_slots.map_or(0, u32::from);
        return Err(HostError::Capacity(format!(
            "{levels} class levels ({x}x{y}x{z} array{sliding}, max_depth {}) at --queue-depth {} and \
             {shared} --shared-slots need {needed} ray slots per node; a node has {}: lower --queue-depth \
             or --shared-slots, or use a smaller array or --balance static",
            scene.max_depth, opts.level_depth, capacity.rays
        )));
    }
    Ok(())
}

/// Ray slots per node a frame of `scene` needs from a start whose boundaries
/// line up as `boundaries` across driving axis `axis`.
fn slots_needed(scene: &Scene, opts: &RenderOptions, axis: u8, boundaries: Boundaries) -> u32 {
    let lined_up = boundaries.when_sliding(opts.balance.is_some());
    let top = class_bound(opts.array, scene.max_depth, usize::from(axis), lined_up);
    (top + 1) * u32::from(opts.level_depth) + opts.shared_slots.map_or(0, u32::from)
}

/// Renders one frame on `array` (already checked with [`check_frame`]).
pub fn render_on(
    array: &mut impl Array,
    scene: &Scene,
    opts: &RenderOptions,
    partition: Partition,
) -> Result<RenderResult, HostError> {
    let [w, h] = opts.size;
    let started = Instant::now();
    let mut frame = FrameBuffer::new(w, h, array.nodes(), PIXEL_CREDIT);
    broadcast(array, scene, &partition, opts);

    let mut tracked = Tracked { frame: &mut frame, started, bar: None };
    let run = array.run(&mut tracked);
    if let Some(bar) = tracked.bar.take() {
        bar.finish_and_clear();
    }
    // A node's own report (or restart) explains a failed run better than the stall it causes.
    node_errors(&frame, &partition)?;
    let stats = run.map_err(|e| e.context("render failed"))?;

    frame.finishing = true;
    for id in 0..array.nodes() {
        array.send(id, Message::Finish(link_proto::Finish { frame: 0 }));
    }
    array.run(&mut frame).map_err(|e| e.context("collecting loads failed"))?;
    node_errors(&frame, &partition)?;
    let bytes = (0..array.nodes()).map(|i| array.bytes_sent(i)).collect();
    let bytes_in = (0..array.nodes()).map(|i| array.bytes_received(i)).collect();
    let busy = (0..array.nodes()).map(|i| array.busy(i)).collect();
    let links = array.link_stats();
    Ok(RenderResult { frame, partition, stats, bytes, bytes_in, busy, wall: started.elapsed(), links })
}

/// Sends the scene, assignments and render start to every node.
fn broadcast(board: &mut impl Array, scene: &Scene, partition: &Partition, opts: &RenderOptions) {
    let [w, h] = opts.size;
    let basis = PixelBasis::new(&scene.camera(), w, h);
    let camera = basis.msg();
    let tiles = match opts.initial {
        Initial::Parallel => tiles(w, h, partition.len()),
        Initial::Entry => {
            entry_tiles(&basis, scene.grid, partition, usize::from(view_axis(scene)), opts.size)
        }
        Initial::EyeNode => {
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
                initial: opts.initial.wire(),
                tile: *tile,
                credit: PIXEL_CREDIT,
                level_depth: opts.level_depth,
                shared_slots: opts.shared_slots,
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
    let restarted = |node: u16, how: String| {
        let c = partition.coord(usize::from(node));
        HostError::Node(format!(
            "node {node} ({},{},{}) restarted mid-render ({how}); no image written",
            c[0], c[1], c[2]
        ))
    };
    if let Some(&node) = frame.restarted.first() {
        return Err(restarted(node, "it said hello again".into()));
    }
    let Some(e) = frame.errors.first() else { return Ok(()) };
    let port = Port::ALL.get(e.a as usize).copied().unwrap_or(Port::Host);
    if e.code == ErrorCode::PeerRestarted
        && let Some(peer) = node_fw::wiring::neighbour_of(usize::from(e.node), port, partition.array)
    {
        return Err(restarted(peer, format!("its neighbour node {} saw it start again", e.node)));
    }
    let c = partition.coord(usize::from(e.node));
    let what = match (e.code, link_proto::Found::from_wire(e.b)) {
        (ErrorCode::Unexpected, Some(link_proto::Found::Message(kind))) => {
            format!("an unexpected {kind:?} message on port {}", crate::cabling::port_name(port))
        }
        (ErrorCode::Unexpected | ErrorCode::BadRay, Some(link_proto::Found::Site(site))) => {
            format!("{:?} at {site:?} (a = {})", e.code, e.a)
        }
        _ => format!("{:?} (a = {}, b = {})", e.code, e.a, e.b),
    };
    Err(HostError::Node(format!("node {} ({},{},{}) reported {what}", e.node, c[0], c[1], c[2])))
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
