//! `bench scaling`: does the array pay for itself? For cubic arrays of S
//! nodes it renders one scene on the in-memory board and reports the honest
//! efficiency E = T(1) / (S x T(S)) in virtual cycles, where T is the frame's
//! makespan, beside how the nodes' busy cycles split into compute, walk
//! set-up and messaging. `bench shapes` does the same for every shape of one
//! number of nodes: how to cable the boards one has.

use std::fmt::Write as _;
use std::path::Path;

use sim_board::Busy;

use host_tool::error::HostError;
use host_tool::plan::options::{Layout, RenderOptions};
use host_tool::results::output::write_all_atomic;
use host_tool::results::plot::{Chart, Series, Style, png};
use host_tool::scene::Scene;
use host_tool::session::sim::render_sim;

/// What to run.
#[derive(Debug, Clone)]
pub struct ScalingConfig {
    /// Nodes per axis of each cubic array (1 must come first: it is T(1)).
    pub sides: Vec<u16>,
    /// The first cuts compared (each with a static partition).
    pub layouts: Vec<Layout>,
    /// Image size, links and the rest, for every run (the array is set per run).
    pub base: RenderOptions,
}

impl ScalingConfig {
    /// S = 1, 8, 27, 64, 216, 512, even and preview-fitted cuts.
    pub fn full(base: RenderOptions) -> Self {
        Self { sides: vec![1, 2, 3, 4, 6, 8], layouts: vec![Layout::Even, Layout::Preview], base }
    }

    /// S = 1, 8, 27 (for CI).
    pub fn quick(base: RenderOptions) -> Self {
        Self { sides: vec![1, 2, 3], ..Self::full(base) }
    }
}

/// One run's figures.
#[derive(Debug, Clone)]
pub struct ScalingRow {
    /// Nodes along each axis.
    pub array: [u16; 3],
    /// Nodes.
    pub nodes: u32,
    /// The first cut.
    pub layout: Layout,
    /// Virtual cycles until the last ray retired.
    pub makespan: u64,
    /// T(1) / (S x T(S)).
    pub efficiency: f64,
    /// All nodes' busy cycles, by kind.
    pub busy: Busy,
    /// Busy cycles of all nodes over those of the one node.
    pub work_ratio: f64,
    /// Bytes sent on neighbour links, all nodes.
    pub neighbour_bytes: u64,
    /// Bytes sent to the host, all nodes.
    pub host_bytes: u64,
    /// The busiest host link's wire time over the makespan: near 1, the
    /// frame waits for pixels to reach the host, not for the nodes.
    pub host_link_busiest: f64,
}

impl ScalingRow {
    /// Messaging over all busy cycles.
    pub fn messaging_share(&self) -> f64 {
        self.busy.messaging as f64 / self.busy.total().max(1) as f64
    }

    /// Bytes on the neighbour links per ray passed between nodes: every
    /// frame's framing, and the grants and other messages that flow back,
    /// included (acknowledgements, which the in-memory board's message mode
    /// does not send, are not); `None` with no ray passed (one node).
    pub fn bytes_per_hop(&self) -> Option<f64> {
        (self.busy.rays_sent > 0).then(|| self.neighbour_bytes as f64 / self.busy.rays_sent as f64)
    }
}

/// Runs every configuration; writes `scaling.csv`, `scaling.md` and
/// `scaling.png` to `out` (all or none) and returns the Markdown table.
pub fn bench_scaling(scene: &Scene, cfg: &ScalingConfig, out: &Path) -> Result<String, HostError> {
    if cfg.sides.first() != Some(&1) {
        return Err(host_tool::error::input("bench scaling needs the one-node run first (side 1)"));
    }
    let files = crate::outputs(out, ["scaling.csv", "scaling.md", "scaling.png"])?;
    let rows = rows(scene, cfg)?;
    let table = markdown(cfg, &rows);
    let plot = chart(cfg, &rows)?;
    let [csv_path, md_path, png_path] = &files;
    write_all_atomic(&[(csv_path, csv(&rows).as_bytes()), (md_path, table.as_bytes()), (png_path, &plot)])?;
    Ok(table)
}

/// Renders every configuration of `cfg`, one node first.
pub fn rows(scene: &Scene, cfg: &ScalingConfig) -> Result<Vec<ScalingRow>, HostError> {
    if cfg.sides.first() != Some(&1) {
        return Err(host_tool::error::input("bench scaling needs the one-node run first (side 1)"));
    }
    let mut rows: Vec<ScalingRow> = Vec::new();
    let mut one: Option<(u64, u64)> = None;
    for &side in &cfg.sides {
        // One node has one cut: the layouts differ from S = 8 on.
        let layouts = if side == 1 { &cfg.layouts[..1] } else { &cfg.layouts[..] };
        for &layout in layouts {
            let row = run(scene, &cfg.base, [side; 3], layout, one)?;
            one = one.or(Some((row.makespan, row.busy.total())));
            eprintln!(
                "S = {:3} {:7}: makespan {:.3e}, E {:.3}, messaging {:.0}%",
                row.nodes,
                layout.name(),
                row.makespan as f64,
                row.efficiency,
                100.0 * row.messaging_share()
            );
            rows.push(row);
        }
    }
    Ok(rows)
}

/// One render of `array` with a static partition cut by `layout`; `one` is
/// the one-node run's makespan and busy cycles (`None`: this is it).
fn run(
    scene: &Scene,
    base: &RenderOptions,
    array: [u16; 3],
    layout: Layout,
    one: Option<(u64, u64)>,
) -> Result<ScalingRow, HostError> {
    let mut opts = *base;
    opts.array = array;
    opts.sim.array = array;
    opts.layout = layout;
    opts.balance = None;
    let [x, y, z] = array;
    let r = render_sim(scene, &opts).map_err(|e| e.context(&format!("{x}x{y}x{z} {}", layout.name())))?;
    let busy = r.busy.iter().flatten().copied().sum::<Busy>();
    let nodes = array.iter().map(|&n| u32::from(n)).product::<u32>();
    let makespan = r.frame.makespan.0;
    let host_wire = r.bytes.iter().map(|b| b[6]).max().unwrap_or(0) * opts.sim.host_link.byte_cycles();
    let (t1, busy1) = one.unwrap_or((makespan, busy.total()));
    Ok(ScalingRow {
        array,
        nodes,
        layout,
        makespan,
        efficiency: t1 as f64 / (f64::from(nodes) * makespan.max(1) as f64),
        busy,
        work_ratio: busy.total() as f64 / busy1.max(1) as f64,
        neighbour_bytes: r.bytes.iter().map(|b| b[..6].iter().sum::<u64>()).sum(),
        host_bytes: r.bytes.iter().map(|b| b[6]).sum(),
        host_link_busiest: host_wire as f64 / makespan.max(1) as f64,
    })
}

fn csv(rows: &[ScalingRow]) -> String {
    let mut s = String::from(
        "array,nodes,layout,makespan,efficiency,messaging_share,work_ratio,compute,setup,messaging,neighbour_bytes,host_bytes,host_link_busiest,ray_hops,bytes_per_hop\n",
    );
    for r in rows {
        let [x, y, z] = r.array;
        let _ = writeln!(
            s,
            "{x}x{y}x{z},{},{},{},{:.4},{:.4},{:.3},{},{},{},{},{},{:.3},{},{}",
            r.nodes,
            r.layout.name(),
            r.makespan,
            r.efficiency,
            r.messaging_share(),
            r.work_ratio,
            r.busy.compute,
            r.busy.setup,
            r.busy.messaging,
            r.neighbour_bytes,
            r.host_bytes,
            r.host_link_busiest,
            r.busy.rays_sent,
            r.bytes_per_hop().map_or(String::new(), |b| format!("{b:.1}"))
        );
    }
    s
}

/// The rows as a Markdown table, headed by the links and image they ran with.
pub fn markdown(cfg: &ScalingConfig, rows: &[ScalingRow]) -> String {
    table(cfg, rows, false)
}

/// [`markdown`], the first column each row's node count or (`by_shape`) its array.
fn table(cfg: &ScalingConfig, rows: &[ScalingRow], by_shape: bool) -> String {
    let o = &cfg.base;
    let cpu = |l: &sim_board::LinkSpec| {
        let (t, m) = (l.transfer, l.model());
        format!("{} ({} cycles of CPU a byte, {} a frame)", t.name(), m.byte_cpu, m.frame_cpu)
    };
    let mut s = format!(
        "Links: {} (neighbours {} baud, {} cycles a byte on the wire, {}; host {} baud, {}); \
         image {}x{}; static partitions.\n\n",
        o.link_preset.name(),
        o.sim.link.baud,
        o.sim.link.byte_cycles(),
        cpu(&o.sim.link),
        o.sim.host_link.baud,
        cpu(&o.sim.host_link),
        o.size[0],
        o.size[1]
    );
    s.push_str(
        "Messaging, set-up and compute are shares of all nodes' busy cycles; the busiest host link \
         is the share of the makespan its wire was busy (near 100%, pixels waiting to reach the \
         host bound the frame); bytes a hop are the neighbour links' bytes over the rays passed \
         between nodes (framing, grants and batches included; acknowledgements, which the \
         in-memory board does not send, not).\n\n",
    );
    s.push_str(if by_shape { "| array " } else { "| S " });
    s.push_str(
        "| cut | makespan (cycles) | E | messaging | set-up | compute | work / one node | busiest host link | bytes a hop |\n",
    );
    s.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let share = |x: u64| 100.0 * x as f64 / r.busy.total().max(1) as f64;
        let [x, y, z] = r.array;
        let first = if by_shape { format!("{x}x{y}x{z}") } else { r.nodes.to_string() };
        let _ = writeln!(
            s,
            "| {first} | {} | {:.3e} | {:.3} | {:.0}% | {:.0}% | {:.0}% | {:.2} | {:.0}% | {} |",
            r.layout.name(),
            r.makespan as f64,
            r.efficiency,
            share(r.busy.messaging),
            share(r.busy.setup),
            share(r.busy.compute),
            r.work_ratio,
            100.0 * r.host_link_busiest,
            r.bytes_per_hop().map_or("-".into(), |b| format!("{b:.1}"))
        );
    }
    s
}

fn chart(cfg: &ScalingConfig, rows: &[ScalingRow]) -> Result<Vec<u8>, HostError> {
    let series = |f: fn(&ScalingRow) -> f64| -> Vec<Series> {
        cfg.layouts
            .iter()
            .map(|&layout| Series {
                name: layout.name().into(),
                points: rows
                    .iter()
                    .filter(|r| r.layout == layout || r.nodes == 1)
                    .map(|r| (f64::from(r.nodes), f(r)))
                    .collect(),
                style: Style::LineWithMarkers,
            })
            .collect()
    };
    let chart = |title: &str, y: &str| Chart {
        title: title.into(),
        x_label: "S (nodes)".into(),
        y_label: y.into(),
        log_x: true,
        log_y: false,
    };
    png(
        &[
            (chart("Efficiency E = T(1) / (S T(S))", "E"), series(|r| r.efficiency)),
            (chart("Messaging share of busy cycles", "messaging / busy"), series(|r| r.messaging_share())),
        ],
        900,
        400,
    )
}

/// Every array of `nodes` nodes, as ordered shapes `[x, y, z]` with
/// `x * y * z = nodes`, no side longer than the grid's (a node holds at
/// least one cube a side).
pub fn shapes(nodes: u32, grid: [u16; 3]) -> Vec<[u16; 3]> {
    let divisors = |n: u32, most: u16| (1..=n.min(u32::from(most))).filter(move |d| n.is_multiple_of(*d));
    let mut all = Vec::new();
    for x in divisors(nodes, grid[0]) {
        for y in divisors(nodes / x, grid[1]) {
            let z = nodes / x / y;
            if let Ok(z) = u16::try_from(z)
                && z <= grid[2]
            {
                all.push([x as u16, y as u16, z]);
            }
        }
    }
    all
}

/// `bench shapes`: the one-node run, then every shape of `nodes` nodes
/// with each of `layouts`, fastest first (the one-node run heads the
/// table: E is measured against it); writes `shapes.csv` and
/// `shapes.md` to `out` (both or neither) and returns the Markdown table.
pub fn bench_shapes(
    scene: &Scene,
    base: &RenderOptions,
    nodes: u32,
    layouts: &[Layout],
    out: &Path,
) -> Result<String, HostError> {
    if nodes < 2 {
        return Err(host_tool::error::input(format!(
            "--nodes {nodes}: the shapes of an array need two nodes or more"
        )));
    }
    let arrays = shapes(nodes, scene.grid);
    if arrays.is_empty() {
        let [x, y, z] = scene.grid;
        return Err(host_tool::error::input(format!(
            "--nodes {nodes}: no array of {nodes} nodes fits the {x}x{y}x{z} grid (a node needs a cube a side)"
        )));
    }
    let files = crate::outputs(out, ["shapes.csv", "shapes.md"])?;
    let first = run(scene, base, [1; 3], Layout::Even, None)?;
    let one = Some((first.makespan, first.busy.total()));
    let mut rows = Vec::new();
    for &array in &arrays {
        for &layout in layouts {
            let row = run(scene, base, array, layout, one)?;
            let [x, y, z] = array;
            eprintln!(
                "{x}x{y}x{z} {:7}: makespan {:.3e}, E {:.3}, messaging {:.0}%",
                layout.name(),
                row.makespan as f64,
                row.efficiency,
                100.0 * row.messaging_share()
            );
            rows.push(row);
        }
    }
    rows.sort_by_key(|r| r.makespan);
    rows.insert(0, first);
    let cfg = ScalingConfig { sides: vec![], layouts: layouts.to_vec(), base: *base };
    let mut table = format!("Every shape of {nodes} nodes, fastest first. ");
    table.push_str(&self::table(&cfg, &rows, true));
    let [csv_path, md_path] = &files;
    write_all_atomic(&[(csv_path, csv(&rows).as_bytes()), (md_path, table.as_bytes())])?;
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::shapes;

    #[test]
    fn shapes_are_every_ordered_factorisation_that_fits() {
        // 64 = 2^6 in three ordered factors: C(8, 2) = 28 ways; on a 32^3
        // grid the three with a side of 64 go.
        assert_eq!(shapes(64, [32; 3]).len(), 25);
        let all = shapes(64, [64; 3]);
        assert_eq!(all.len(), 28);
        assert!(all.iter().all(|s| s.iter().map(|&n| u32::from(n)).product::<u32>() == 64));
        let mut unique = all.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), 28);
        // 12 = 2^2 x 3: C(4, 2) x C(3, 2) = 18 ways.
        assert_eq!(shapes(12, [32; 3]).len(), 18);
        let narrow = shapes(12, [4, 32, 32]);
        assert!(narrow.iter().all(|s| s[0] <= 4));
        // x = 6: (1, 2) and (2, 1); x = 12: (1, 1): three shapes fewer.
        assert_eq!(narrow.len(), 15);
        assert_eq!(shapes(7, [4; 3]), Vec::<[u16; 3]>::new(), "7 nodes cannot fit sides of 4");
    }
}
