//! What `host-tool render` writes beside the image: the run summary, the
//! per-node loads, the load and boundary histories over virtual time, and
//! their plot.

use std::collections::BTreeMap;

use link_proto::PortHealth;
use serde_json::json;
use sim_board::Busy;

use crate::error::HostError;
use crate::plan::options::RenderOptions;
use crate::results::RenderResult;
use crate::results::history::boundary_history;
use crate::results::plot::{Chart, Series, Style, png};
use crate::scene::Scene;
use crate::session::clock::Clock;

/// Busy cycles by kind, and waiting.
fn busy_json(b: &Busy, waiting: u64) -> serde_json::Value {
    json!({"compute": b.compute, "setup": b.setup, "messaging": b.messaging, "pass": b.pass, "waiting": waiting, "polls": b.polls, "rays_sent": b.rays_sent})
}

/// Per neighbour port and the host port: bytes sent and received, and the
/// fraction of the frame's makespan the wire out spent carrying them (where
/// the links are modelled in the cycles the makespan counts).
fn ports_json<T: Clock>(opts: &RenderOptions, r: &RenderResult<T>, id: usize) -> serde_json::Value {
    let mut ports = serde_json::Map::new();
    for (p, name) in PORT_NAMES.iter().enumerate() {
        let bytes = r.bytes[id][p];
        let received = r.bytes_in.get(id).map_or(0, |b| b[p]);
        let spec = if p == 6 { &opts.sim.host_link } else { &opts.sim.link };
        let utilisation =
            r.frame.makespan.cycles().map(|end| (bytes * spec.byte_cycles()) as f64 / end.max(1) as f64);
        if bytes > 0 || received > 0 {
            let port = json!({"bytes": bytes, "received": received, "utilisation": utilisation});
            ports.insert(name.to_string(), port);
        }
    }
    serde_json::Value::Object(ports)
}

/// The names of a node's ports, in port order.
pub const PORT_NAMES: [&str; 7] = ["+x", "-x", "+y", "-y", "+z", "-z", "host"];

/// The ports of one node whose links had trouble, with what went wrong.
fn link_troubles_json(ports: &[PortHealth; 7]) -> serde_json::Value {
    let troubled = PORT_NAMES.iter().zip(ports).filter(|(_, p)| !p.is_clean());
    let map = troubled.map(|(name, p)| {
        (name.to_string(), json!({"resent": p.resent, "damaged": p.damaged, "lost": p.lost}))
    });
    serde_json::Value::Object(map.collect())
}

/// The frame's link troubles over every node and port, as the nodes told them.
pub fn link_troubles<T>(r: &RenderResult<T>) -> PortHealth {
    let mut total = PortHealth::default();
    for p in r.frame.link_health.iter().flatten() {
        total += *p;
    }
    total
}

/// The node and port that resent and took damaged the most frames and lost
/// the most bytes, if any did.
fn worst_link<T>(r: &RenderResult<T>) -> Option<(usize, &'static str, PortHealth)> {
    let ports = r
        .frame
        .link_health
        .iter()
        .enumerate()
        .flat_map(|(id, ports)| ports.iter().zip(PORT_NAMES).map(move |(p, name)| (id, name, *p)));
    ports
        .filter(|(_, _, p)| !p.is_clean())
        .max_by_key(|(_, _, p)| u64::from(p.resent) + u64::from(p.damaged) + u64::from(p.lost))
}

/// The one-line warning `render` prints when the nodes told of link
/// troubles, naming the worst port and what to do about it; `None` when the
/// links were clean. `summary` is where the rest is.
pub fn link_warning<T>(r: &RenderResult<T>, summary: &std::path::Path) -> Option<String> {
    let (node, port, worst) = worst_link(r)?;
    let all = link_troubles(r);
    // A lost byte never reached the board's memory: the board read its
    // UART too late, and a new cable would not help.
    let advice = if worst.lost > 0 {
        "that board read its UART too late (an interrupt held off or a loop too slow), not the cable"
    } else {
        "check that link's cable"
    };
    Some(format!(
        "warning: the nodes resent {} frames, took {} damaged and lost {} received bytes; the most on node \
         {node} port {port} ({} resent, {} damaged, {} lost): {advice}; per node and port in {}",
        all.resent,
        all.damaged,
        all.lost,
        worst.resent,
        worst.damaged,
        worst.lost,
        summary.display()
    ))
}

/// max / mean of the nodes' running time.
pub fn imbalance<T>(r: &RenderResult<T>) -> f64 {
    let busy: Vec<f64> = r.frame.loads.iter().map(|l| l.map_or(0.0, |l| l.running as f64)).collect();
    let mean = busy.iter().sum::<f64>() / busy.len().max(1) as f64;
    busy.iter().cloned().fold(0.0, f64::max) / mean.max(f64::MIN_POSITIVE)
}

/// Where a run came from, for its summary.
#[derive(Debug, Clone)]
pub struct Provenance {
    /// What carried the frame: `sim`, `qemu` (with the board) or `serial`.
    pub backend: String,
    /// The scene's source: a file, a random scene's parameters, or the demo.
    pub scene: serde_json::Value,
}

impl Provenance {
    /// The unit of the frame's and the nodes' times.
    fn time_units<T: Clock>(&self) -> serde_json::Value {
        json!({"makespan": T::UNIT, "running": T::NODE_UNIT, "waiting": T::NODE_UNIT,
               "busy": T::NODE_UNIT, "wall_seconds": "s"})
    }
}

/// The run summary: where it came from, the frame's totals, the options, the
/// links, each node.
pub fn summary_json<T: Clock>(
    scene: &Scene,
    opts: &RenderOptions,
    r: &RenderResult<T>,
    from: &Provenance,
) -> String {
    let f = &r.frame;
    // The in-memory board models its links and sees inside its nodes; boards
    // have links of their own, and their busy time is their own business.
    let modelled = !r.busy.is_empty() && r.busy.iter().all(Option::is_some);
    let nodes: Vec<_> = f
        .loads
        .iter()
        .enumerate()
        .map(|(id, l)| {
            let l = l.unwrap_or(link_proto::LoadReport {
                node: id as u16,
                interval: 0,
                running: 0,
                waiting: 0,
                rays: 0,
                sphere_tests: 0,
                cube_steps: 0,
                refused: 0,
                extent: 0,
                busy_polls: 0,
            });
            let b = r.partition.bounds(id);
            json!({
                "id": id, "coord": r.partition.coord(id), "lo": b.lo, "hi": b.hi,
                "running": l.running, "waiting": l.waiting, "rays": l.rays,
                "sphere_tests": l.sphere_tests, "cube_steps": l.cube_steps, "refused": l.refused,
                "busy_polls": l.busy_polls,
                "bytes_sent": r.bytes[id].iter().sum::<u64>(),
                "busy": r.busy.get(id).copied().flatten().map(|b| busy_json(&b, l.waiting)),
                "ports": modelled.then(|| ports_json(opts, r, id)),
                "link_troubles": f.link_health.get(id).map(link_troubles_json),
            })
        })
        .collect();
    let total = r.busy.iter().flatten().copied().sum::<Busy>();
    let waiting: u64 = f.loads.iter().flatten().map(|l| l.waiting).sum();
    let troubles = link_troubles(r);
    let v = json!({
        "backend": from.backend,
        "versions": {"host_tool": env!("CARGO_PKG_VERSION"), "protocol": link_proto::PROTOCOL_VERSION},
        "scene": from.scene,
        "units": from.time_units::<T>(),
        "makespan": f.makespan.ticks(),
        "imbalance": imbalance(r),
        "rays_created": f.rays_created,
        "rays_terminated": f.rays_terminated,
        // Each refusal cost its node a ray and a reply: see `--queue-depth`.
        "rays_refused": f.loads.iter().flatten().map(|l| u64::from(l.refused)).sum::<u64>(),
        "array": opts.array,
        "grid": scene.grid,
        "size": opts.size,
        "samples": opts.samples,
        "spheres": scene.spheres.len(),
        "lights": scene.lights.len(),
        "initial_rays": opts.initial.name(),
        "layout": opts.layout.name(),
        "queue_depth": opts.level_depth,
        "shared_slots": opts.shared_slots,
        "balance": if opts.balance.is_some() { "slide" } else { "static" },
        "sliding": opts.balance.map(|b| json!({
            "interval": b.interval,
            "threshold": f64::from(b.threshold) / 65536.0,
            "step": b.step,
            "policy": match b.policy { link_proto::SlidePolicy::Paper => "paper", link_proto::SlidePolicy::Proportional { .. } => "proportional" },
        })),
        "driving_axis": r.partition.driving_axis,
        "slides": f.slides.len(),
        "refused_slides": f.refused_slides.len(),
        "rounds": r.stats.rounds,
        // Busy cycles of all nodes by what they were spent on, and their
        // waiting; `messaging_share` is messaging over all busy cycles.
        "busy": modelled.then(|| {
            let mut v = busy_json(&total, waiting);
            v["messaging_share"] = json!(total.messaging as f64 / total.total().max(1) as f64);
            v
        }),
        "link": modelled.then(|| json!({
            "preset": opts.link_preset.name(),
            "neighbour": crate::session::links::spec_json(&opts.sim.link),
            "host": crate::session::links::spec_json(&opts.sim.host_link),
        })),
        "faults": opts.sim.faults.map(|f| json!({"corrupt": f.corrupt, "drop": f.drop, "dup": f.dup, "delay": f.delay, "seed": f.seed})),
        "retransmissions": r.links.retransmitted,
        "corrupted_frames": r.links.corrupted,
        "discarded_frames": r.links.discarded,
        // What the nodes told of their own link ends (on boards, the only
        // word of the links between them).
        "link_troubles": {"resent": troubles.resent, "damaged": troubles.damaged, "lost": troubles.lost},
        // Records share messages when the host link is behind or the node busy.
        "retirements": {"messages": r.frame.retirements.messages, "records": r.frame.retirements.records},
        "wall_seconds": r.wall.as_secs_f64(),
        "nodes": nodes,
    });
    serde_json::to_string_pretty(&v).unwrap_or_default()
}

/// One row per node: its place, time, work and bytes sent.
pub fn loads_csv<T>(r: &RenderResult<T>) -> String {
    let mut s = String::from(
        "node,x,y,z,running,waiting,load,rays,sphere_tests,cube_steps,refused,busy_polls,bytes_sent\n",
    );
    for (id, l) in r.frame.loads.iter().enumerate() {
        let c = r.partition.coord(id);
        let (run, wait, rays, tests, steps, refused, polls) = l.map_or((0, 0, 0, 0, 0, 0, 0), |l| {
            (l.running, l.waiting, l.rays, l.sphere_tests, l.cube_steps, l.refused, l.busy_polls)
        });
        let load = load(run, wait);
        s += &format!(
            "{id},{},{},{},{run},{wait},{load:.4},{rays},{tests},{steps},{refused},{polls},{}\n",
            c[0],
            c[1],
            c[2],
            r.bytes[id].iter().sum::<u64>()
        );
    }
    s
}

/// Per-node load and boundary positions over the run's time.
pub fn history_plot<T: Clock>(r: &RenderResult<T>) -> Result<Vec<u8>, HostError> {
    let nodes = r.frame.loads.len();
    let mut per_node: Vec<Vec<(f64, f64)>> = vec![Vec::new(); nodes];
    for (at, l) in &r.frame.history {
        // Clamped for the log axis: idle (0) and never waiting (infinite) stay on the chart.
        let load = load(l.running, l.waiting).clamp(0.01, 100.0);
        if let Some(v) = per_node.get_mut(usize::from(l.node)) {
            v.push((at.ticks() as f64, load));
        }
    }
    let loads: Vec<Series> = per_node
        .into_iter()
        .enumerate()
        .filter(|(_, p)| !p.is_empty())
        .map(|(n, points)| Series { name: format!("node {n}"), points, style: Style::Line })
        .collect();
    let history = boundary_history(&r.partition, &r.frame.slides);
    let mut lines: BTreeMap<(usize, usize), Vec<(f64, f64)>> = BTreeMap::new();
    for b in &history {
        let line = lines.entry((b.row, b.index)).or_default();
        if let Some(&(_, prev)) = line.last() {
            line.push((b.time.ticks() as f64, prev));
        }
        line.push((b.time.ticks() as f64, f64::from(b.position)));
    }
    let end = r.frame.makespan.ticks() as f64;
    let boundaries: Vec<Series> = lines
        .into_iter()
        .map(|((row, index), mut points)| {
            if let Some(&(_, last)) = points.last() {
                points.push((end, last));
            }
            Series { name: format!("row {row} boundary {index}"), points, style: Style::Line }
        })
        .collect();
    let axis = ["x", "y", "z"][usize::from(r.partition.driving_axis)];
    png(
        &[
            (
                Chart {
                    title: "Load (running / waiting) per node and interval, drawn within [0.01, 100]".into(),
                    x_label: format!("time, {}", T::UNIT),
                    y_label: "load".into(),
                    log_x: false,
                    log_y: true,
                },
                loads,
            ),
            (
                Chart {
                    title: format!("Boundary positions along the driving axis ({axis})"),
                    x_label: format!("time, {}", T::UNIT),
                    y_label: "cube".into(),
                    log_x: false,
                    log_y: false,
                },
                boundaries,
            ),
        ],
        1000,
        420,
    )
}

/// The load history: one row per node and interval,
/// `time,node,interval,running,waiting,load` (load `inf` for no waiting).
pub fn load_history_csv<T: Clock>(r: &RenderResult<T>) -> String {
    let mut s = String::from("time,node,interval,running,waiting,load\n");
    for (at, l) in &r.frame.history {
        let load = load(l.running, l.waiting);
        s += &format!("{},{},{},{},{},{load:.4}\n", at.ticks(), l.node, l.interval, l.running, l.waiting);
    }
    s
}

/// The boundary history: every boundary across the driving axis at time 0,
/// then one row per committed slide, `time,row,boundary,position` (row: the
/// line of nodes along the driving axis; boundary: between its nodes
/// `boundary` and `boundary + 1`; position: in cubes along the driving axis).
pub fn boundary_history_csv<T: Clock>(r: &RenderResult<T>) -> String {
    let mut s = String::from("time,row,boundary,position\n");
    for b in boundary_history(&r.partition, &r.frame.slides) {
        s += &format!("{},{},{},{}\n", b.time.ticks(), b.row, b.index, b.position);
    }
    s
}

/// The paper's load, running / waiting; infinite when the node never waited.
fn load(running: u64, waiting: u64) -> f64 {
    if waiting == 0 { f64::INFINITY } else { running as f64 / waiting as f64 }
}
