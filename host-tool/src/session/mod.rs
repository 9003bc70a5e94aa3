//! The session: one frame's conversation with the nodes over a
//! [`Transport`]: broadcast the scene and each node's share of the plan, run
//! until every ray is accounted for, then collect the nodes' final loads.
//!
//! The conversation is the same whatever carries it: the in-memory board
//! ([`sim`]), emulated boards under QEMU ([`qemu`]), or real boards over
//! serial devices ([`serial`]); [`backend`] picks one.

pub mod backend;
pub mod boards;
pub mod cabling;
pub mod clock;
pub mod frame;
pub mod links;
mod progress;
pub mod qemu;
pub mod relay;
pub mod sequence;
pub mod serial;
pub mod sim;
pub mod transport;

use std::time::Instant;

use link_proto::{ErrorCode, MapLoad, Message, OccupancyMsg, RenderStart, SceneEnd, SceneHeader};
use node_fw::Port;

use crate::error::HostError;
use crate::plan::Plan;
use crate::results::RenderResult;
use crate::scene::Scene;
use crate::scene::occupancy::occupancy_msgs;
use frame::FrameBuffer;
use progress::Tracked;
use transport::Transport;

/// Credit of one initial ray: children split it, so it must survive
/// `(lights + 2)^max_depth` divisions (at most 10^8 < 2^32). The wire knows
/// it too: a ray with exactly this credit carries none.
pub use link_proto::ray_wire::PIXEL_CREDIT;

/// Runs one planned frame on `transport`: broadcast, render, collect.
pub fn run<T: Transport>(
    transport: &mut T,
    scene: &Scene,
    plan: &Plan,
) -> Result<RenderResult<T::Time>, HostError> {
    let loaded = load(transport, scene, plan, MapLoad::Sent);
    frame(transport, plan, 0, &loaded.after_start)
}

/// Renders frame `number` on nodes that hold the scene and the subregions
/// `plan.partition` names (sent by [`load`], or left there by the frame
/// before): start, render until every ray is accounted for, then collect the
/// final loads, which the nodes send once their slides have settled. Bytes
/// and busy cycles are the frame's own. `map` is what [`load`] left to send
/// after the start: every node gets it.
pub fn frame<T: Transport>(
    transport: &mut T,
    plan: &Plan,
    number: u32,
    map: &[OccupancyMsg],
) -> Result<RenderResult<T::Time>, HostError> {
    let [w, h] = plan.trace_size;
    let started = Instant::now();
    let nodes = 0..transport.nodes();
    let before: Vec<_> = nodes
        .clone()
        .map(|i| (transport.bytes_sent(i), transport.bytes_received(i), transport.busy(i)))
        .collect();
    let links_before = transport.link_stats();
    let mut frame =
        FrameBuffer::new(w, h, transport.nodes(), PIXEL_CREDIT, plan.background).sampled(plan.sample_side());
    start(transport, plan, number);
    for id in nodes.clone() {
        for m in map {
            transport.send(id, Message::Occupancy(*m));
        }
    }

    let mut tracked = Tracked::new(&mut frame);
    let run = transport.run(&mut tracked);
    tracked.done();
    // A node's own report (or restart) explains a failed run better than the stall it causes.
    node_errors(&frame, plan)?;
    let stats = run.map_err(|e| e.context("render failed"))?;

    frame.finishing = true;
    for id in nodes.clone() {
        transport.send(id, Message::Finish(link_proto::Finish { frame: number }));
    }
    transport.run(&mut frame).map_err(|e| e.context("collecting loads failed"))?;
    node_errors(&frame, plan)?;
    let since = |now: [u64; 7], then: [u64; 7]| std::array::from_fn(|p| now[p].saturating_sub(then[p]));
    Ok(RenderResult {
        frame,
        partition: plan.partition.clone(),
        stats,
        bytes: nodes.clone().map(|i| since(transport.bytes_sent(i), before[i].0)).collect(),
        bytes_in: nodes.clone().map(|i| since(transport.bytes_received(i), before[i].1)).collect(),
        busy: nodes.map(|i| transport.busy(i).zip(before[i].2).map(|(now, then)| now - then)).collect(),
        wall: started.elapsed(),
        links: transport.link_stats() - links_before,
    })
}

/// Sends each node its assignment and its part of the scene: what every
/// frame on this partition needs, sent once. A node gets only the spheres it
/// keeps ([`Partition::needs`](crate::plan::partition::Partition::needs)),
/// not the whole scene: on 64 nodes the whole scene was a thousand messages a
/// node before its first ray, 7% of a frame.
///
/// The map of occupied cubes is not sent here where it may follow the
/// start ([`Transport::map_follows_start`]): a node uses it only once
/// complete, and it is most of a node's scene (5.5 KB of about 6 on a 32^3
/// grid), so it follows the frame's start ([`frame()`]), on a wire that
/// carries little else the host's way during a frame, and the first rays
/// do not wait for it. With [`MapLoad::Kept`] the nodes keep the map the
/// last load sent them, which the caller knows was of these spheres on this
/// grid, and none is sent.
pub fn load(transport: &mut impl Transport, scene: &Scene, plan: &Plan, map: MapLoad) -> Loaded {
    let spheres = scene.sphere_msgs();
    let lights = scene.light_msgs();
    // A grid the nodes refuse gets the whole scene: they report the error.
    let grid = node_fw::Grid::new(scene.grid).ok();
    let occupancy = match (map, grid.as_ref().filter(|_| plan.options.clear_walks)) {
        (MapLoad::Sent, Some(g)) => occupancy_msgs(&spheres, g),
        _ => Vec::new(),
    };
    let header = SceneHeader { map, ..scene.header() };
    let follows = transport.map_follows_start();
    for id in 0..plan.tiles.len() {
        transport.send(id, Message::SceneBegin(header));
        transport.send(id, Message::Assign(plan.assign(id)));
        let mut sent = 0u32;
        for s in spheres.iter().filter(|s| grid.as_ref().is_none_or(|g| plan.partition.needs(id, s, g))) {
            transport.send(id, Message::Sphere(*s));
            sent += 1;
        }
        for l in &lights {
            transport.send(id, Message::Light(*l));
        }
        if !follows {
            for m in &occupancy {
                transport.send(id, Message::Occupancy(*m));
            }
        }
        let end = SceneEnd { spheres: sent, lights: lights.len() as u8, occupancy: occupancy.len() as u16 };
        transport.send(id, Message::SceneEnd(end));
    }
    let mapped = map == MapLoad::Kept || !occupancy.is_empty();
    let after_start = if follows { occupancy } else { Vec::new() };
    Loaded { after_start, mapped }
}

/// What a [`load`] leaves for the frame.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The map of occupied cubes, counted by `SceneEnd`, still to send:
    /// after the frame's start ([`frame()`]).
    pub after_start: Vec<OccupancyMsg>,
    /// Whether the nodes hold a map of occupied cubes (or will, once
    /// `after_start` is sent).
    pub mapped: bool,
}

/// Starts frame `number` on every node: its camera and tile.
fn start(transport: &mut impl Transport, plan: &Plan, number: u32) {
    let opts = &plan.options;
    let camera = plan.camera();
    for (id, tile) in plan.tiles.iter().enumerate() {
        transport.send(
            id,
            Message::RenderStart(RenderStart {
                frame: number,
                size: plan.trace_size,
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
fn node_errors<T>(frame: &FrameBuffer<T>, plan: &Plan) -> Result<(), HostError> {
    if let Some(&(node, version)) = frame.version_mismatch.first() {
        return Err(HostError::Version(format!(
            "node {node} speaks protocol version {version}, the host {}",
            link_proto::PROTOCOL_VERSION
        )));
    }
    let restarted = |node: u16, how: String| {
        let c = plan.partition.coord(usize::from(node));
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
        && let Some(peer) = node_fw::wiring::neighbour_of(usize::from(e.node), port, plan.partition.array)
    {
        return Err(restarted(peer, format!("its neighbour node {} saw it start again", e.node)));
    }
    if e.code == ErrorCode::Restarted {
        return Err(restarted(e.node, "a neighbour passed it a ray of the frame it left".into()));
    }
    let c = plan.partition.coord(usize::from(e.node));
    let what = match (e.code, link_proto::Found::from_wire(e.b)) {
        (ErrorCode::Unexpected, Some(link_proto::Found::Message(kind))) => {
            format!("an unexpected {kind:?} message on port {}", crate::session::cabling::port_name(port))
        }
        (ErrorCode::Unexpected | ErrorCode::BadRay, Some(link_proto::Found::Site(site))) => {
            format!("{:?} at {site:?} (a = {})", e.code, e.a)
        }
        _ => format!("{:?} (a = {}, b = {})", e.code, e.a, e.b),
    };
    Err(HostError::Node(format!("node {} ({},{},{}) reported {what}", e.node, c[0], c[1], c[2])))
}
