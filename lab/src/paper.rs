//! `lab bench paper`: the paper's experiments on the in-memory board.
//!
//! - Fig. 7: time against the number of subregions S, for A (one node holding
//!   the whole grid), B (the array, initial rays from the eye's node) and C
//!   (the array, initial rays in parallel); beyond the paper, D (the array,
//!   initial rays created on the node where they enter, [`host_tool::plan::entry`]).
//! - Fig. 8: C for several sphere counts.
//! - Figs. 9 and 10: sliding against the static partition over the volume
//!   ratio of the region the spheres are confined to, 1000 and 2000 spheres;
//!   the same with entry tiles.
//!
//! Times are makespans in virtual cycles of the board's cost model.

use std::fmt::Write as _;
use std::path::Path;

use link_proto::{Balance, Boundaries, SlidePolicy};

use host_tool::error::HostError;
use host_tool::plan::options::{Initial, Layout, RenderOptions};
use host_tool::plan::partition::Partition;
use host_tool::results::output::write_atomic;
use host_tool::results::plot::{Chart, Series, Style, png};
use host_tool::scene::Scene;
use host_tool::session::clock::Cycles;
use host_tool::session::sim::render_sim;

/// Experiment sizes.
#[derive(Debug, Clone)]
pub struct PaperConfig {
    /// Image size.
    pub size: [u16; 2],
    /// Arrays (n x n x n) for Figs. 7 and 8.
    pub sides: Vec<u16>,
    /// Sphere counts for Fig. 8.
    pub counts: Vec<usize>,
    /// Arrays for Figs. 9 and 10.
    pub balance_arrays: Vec<u16>,
    /// Sphere counts for Figs. 9 and 10.
    pub balance_counts: Vec<usize>,
    /// Volume ratios for Figs. 9 and 10.
    pub ratios: Vec<f64>,
    /// Grid.
    pub grid: [u16; 3],
    /// Seed of the random scenes.
    pub seed: u64,
}

impl PaperConfig {
    /// The full experiment.
    pub fn full() -> Self {
        Self {
            size: [128, 128],
            sides: vec![1, 2, 3, 4, 6, 8],
            counts: vec![250, 500, 1000, 2000],
            balance_arrays: vec![4, 8],
            balance_counts: vec![1000, 2000],
            ratios: vec![1.0, 0.5, 0.25, 0.125],
            grid: [32; 3],
            seed: 1986,
        }
    }

    /// A reduced run for CI (a minute or two).
    pub fn quick() -> Self {
        Self {
            size: [48, 48],
            sides: vec![1, 2, 4],
            counts: vec![250, 1000],
            balance_arrays: vec![4],
            balance_counts: vec![1000],
            ratios: vec![1.0, 0.25],
            grid: [32; 3],
            seed: 1986,
        }
    }
}

/// How a balanced run slides.
#[derive(Debug, Clone, Copy)]
enum Policy {
    Static,
    /// The paper's rule with its driving axis.
    Paper,
    /// The paper's rule along the view axis.
    PaperView,
    /// Proportional, damped steps along the view axis.
    ProportionalView,
}

/// What one benchmark run measured.
#[derive(Debug, Clone, Copy)]
struct Run {
    makespan: u64,
    imbalance: f64,
    slides: usize,
    axis: u8,
    /// Sum of the nodes' running time (W).
    busy: u64,
    /// Share of boundaries that move per interval over the whole frame.
    churn: f64,
    /// The same in steady state: the middle half of the frame, after the
    /// boundaries left the even partition and before the work drains.
    steady_churn: f64,
    /// Share of the steady state's moves that undo the boundary's previous move.
    reversals: f64,
}

fn run(
    scene: &Scene,
    side: [u16; 3],
    cfg: &PaperConfig,
    initial: Initial,
    policy: Policy,
    static_makespan: u64,
) -> Result<Run, HostError> {
    run_on(scene, side, cfg, initial, policy, static_makespan, None)
}

/// The render options of a run: one slot kept per class level and the rest
/// shared, as `host-tool render` does by default. The links are the ideal
/// preset's: the paper's experiments are about balancing the nodes' work,
/// What the CPU pays per byte on the ideal links the paper's runs use.
fn ideal_bytes() -> host_tool::plan::direct::ByteCpu {
    let ideal = sim_board::LinkPreset::Ideal;
    host_tool::plan::direct::ByteCpu::of(&ideal.neighbour(), &ideal.host())
}

/// and its tables in docs/partition-and-sliding.md were measured on these links.
fn options(side: [u16; 3], cfg: &PaperConfig, initial: Initial) -> RenderOptions {
    let mut opts = RenderOptions::new(side);
    opts.sim = sim_board::SimConfig::with_links(side, sim_board::LinkPreset::Ideal);
    opts.link_preset = sim_board::LinkPreset::Ideal;
    opts.size = cfg.size;
    opts.initial = initial;
    opts
}

fn run_on(
    scene: &Scene,
    side: [u16; 3],
    cfg: &PaperConfig,
    initial: Initial,
    policy: Policy,
    static_makespan: u64,
    partition: Option<host_tool::plan::partition::Partition>,
) -> Result<Run, HostError> {
    let mut opts = options(side, cfg, initial);
    // About 64 load comparisons over a frame, threshold 3 (loads are running / waiting).
    let interval = (static_makespan / 64).max(10_000);
    if !matches!(policy, Policy::Static) {
        let slide = if matches!(policy, Policy::ProportionalView) {
            host_tool::plan::options::PROPORTIONAL
        } else {
            SlidePolicy::Paper
        };
        opts.balance = Some(Balance { interval, threshold: 3 << 16, step: 1, policy: slide });
    }
    if matches!(policy, Policy::PaperView | Policy::ProportionalView) {
        opts.driving_axis = Some(host_tool::plan::partition::view_axis(scene));
    }
    let r = match partition {
        Some(p) => host_tool::session::sim::render_partitioned(scene, &opts, p)?,
        None => render_sim(scene, &opts)?,
    };
    if r.frame.rays_created != r.frame.rays_terminated {
        return Err(HostError::Node("rays lost in a benchmark run".into()));
    }
    let imbalance = host_tool::results::files::imbalance(&r);
    let history = host_tool::results::history::boundary_history(&r.partition, &r.frame.slides);
    let t = r.frame.makespan.0;
    let per_interval = |moves: usize, span: u64| {
        moves as f64 / (boundaries(&r.partition) * (span as f64 / interval as f64).max(1.0))
    };
    let steady = host_tool::results::history::churn(&history, Cycles(t / 4), Cycles(t - t / 4));
    Ok(Run {
        makespan: t,
        imbalance,
        slides: r.frame.slides.len(),
        axis: r.partition.driving_axis,
        busy: r.frame.loads.iter().flatten().map(|l| l.running).sum(),
        churn: per_interval(r.frame.slides.len(), t),
        steady_churn: per_interval(steady.moves, t - t / 4 - t / 4),
        reversals: steady.reversals as f64 / steady.moves.max(1) as f64,
    })
}

/// The partition fitted to a half-resolution preview (`--layout preview`),
/// along the view axis, for rays started as `initial` says.
fn preview(
    scene: &Scene,
    side: [u16; 3],
    cfg: &PaperConfig,
    initial: Initial,
) -> Result<Partition, HostError> {
    let mut opts = options(side, cfg, initial);
    opts.layout = Layout::Preview;
    opts.driving_axis = Some(host_tool::plan::partition::view_axis(scene));
    host_tool::plan::initial_partition(scene, &opts, sim_board::SimNode::capacity())
}

/// Boundaries perpendicular to the driving axis (one per adjacent node pair along it).
fn boundaries(p: &Partition) -> f64 {
    let d = usize::from(p.driving_axis);
    let along = f64::from(p.array[d]);
    p.array.iter().map(|&n| f64::from(n)).product::<f64>() / along * (along - 1.0)
}

/// Least-squares slope of log(y) against log(x).
pub fn loglog_slope(points: &[(f64, f64)]) -> f64 {
    let pts: Vec<(f64, f64)> =
        points.iter().filter(|p| p.0 > 0.0 && p.1 > 0.0).map(|p| (p.0.ln(), p.1.ln())).collect();
    let n = pts.len() as f64;
    let (sx, sy) = pts.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
    let (mx, my) = (sx / n, sy / n);
    let cov: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let var: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if var == 0.0 { 0.0 } else { cov / var }
}

/// Runs every experiment and writes CSV tables and PNG plots into `out`.
pub fn bench_paper(cfg: &PaperConfig, out: &Path) -> Result<String, HostError> {
    std::fs::create_dir_all(out)
        .map_err(|e| HostError::Io(format!("cannot create {}: {e}", out.display())))?;
    let mut report = format!("Random scenes from seed {}.\n", cfg.seed);

    // Figs. 7 and 8.
    let mut fig7 = String::from("S,mode,spheres,makespan,imbalance\n");
    let mut fig8 = String::from("S,spheres,makespan\n");
    let mut series7: Vec<Series> = ["A one node", "B eye node", "C parallel", "D entry (beyond the paper)"]
        .iter()
        .map(|n| Series { name: n.to_string(), points: Vec::new(), style: Style::LineWithMarkers })
        .collect();
    let mut series8: Vec<Series> = Vec::new();
    for &count in &cfg.counts {
        let scene = Scene::random(count, cfg.seed, 1.0, cfg.grid)?;
        let mut s8 =
            Series { name: format!("C, {count} spheres"), points: Vec::new(), style: Style::LineWithMarkers };
        let single = run(&scene, [1; 3], cfg, Initial::Parallel, Policy::Static, 0)?.makespan;
        for &n in &cfg.sides {
            let s = u32::from(n).pow(3) as f64;
            let rc = run(&scene, [n; 3], cfg, Initial::Parallel, Policy::Static, 0)?;
            let (c, imb_c) = (rc.makespan, rc.imbalance);
            s8.points.push((s, c as f64));
            let _ = writeln!(fig8, "{s},{count},{c}");
            if count == 1000 {
                let rb = run(&scene, [n; 3], cfg, Initial::EyeNode, Policy::Static, 0)?;
                let (b, imb_b) = (rb.makespan, rb.imbalance);
                let rd = run(&scene, [n; 3], cfg, Initial::Entry, Policy::Static, 0)?;
                let (d, imb_d) = (rd.makespan, rd.imbalance);
                for (i, (t, imb, mode)) in
                    [(single, 1.0, "A"), (b, imb_b, "B"), (c, imb_c, "C"), (d, imb_d, "D")]
                        .into_iter()
                        .enumerate()
                {
                    series7[i].points.push((s, t as f64));
                    let _ = writeln!(fig7, "{s},{mode},{count},{t},{imb:.3}");
                }
            }
        }
        series8.push(s8);
    }
    let _ = writeln!(
        report,
        "Fig. 7 (1000 spheres, {}x{} pixels, grid {:?}): log-log slope of time against S",
        cfg.size[0], cfg.size[1], cfg.grid
    );
    for s in &series7 {
        let _ = writeln!(report, "  {}: S^{:.2}", s.name, loglog_slope(&s.points));
    }
    let _ = writeln!(
        report,
        "  paper: A ~ S^-0.67 (subdivision on one computer), C ~ S^-1.5 (against the unsubdivided computer)"
    );
    let _ = writeln!(
        report,
        "  here the unit-cube grid already subdivides the space on one node, so A does not change with S."
    );
    let _ =
        writeln!(report, "Honest efficiency E = T(one node, same grid) / (S T(S)), 1000 spheres, static:");
    if let (Some(one), Some(c), Some(d)) = (series7[0].points.first(), series7.get(2), series7.get(3)) {
        for (&(s, tc), &(_, td)) in c.points.iter().zip(&d.points) {
            let _ = writeln!(
                report,
                "  S = {s}: E = {:.3} (C parallel), {:.3} (D entry)",
                one.1 / (s * tc),
                one.1 / (s * td)
            );
        }
    }
    let _ = writeln!(report, "Fig. 8: slope of C against S per sphere count");
    for s in &series8 {
        let _ = writeln!(report, "  {}: S^{:.2}", s.name, loglog_slope(&s.points));
    }
    let chart = |title: &str, x: &str| Chart {
        title: title.into(),
        x_label: x.into(),
        y_label: "makespan (cycles)".into(),
        log_x: true,
        log_y: true,
    };
    write_atomic(&out.join("fig7.csv"), fig7.as_bytes())?;
    write_atomic(&out.join("fig8.csv"), fig8.as_bytes())?;
    write_atomic(
        &out.join("fig7.png"),
        &png(&[(chart("Fig. 7: space subdivision effect", "S (nodes)"), series7)], 900, 500)?,
    )?;
    write_atomic(
        &out.join("fig8.png"),
        &png(&[(chart("Fig. 8: C for several sphere counts", "S (nodes)"), series8)], 900, 500)?,
    )?;

    // Figs. 9 and 10.
    let mut fig9 = String::from(
        "array,spheres,volume_ratio,policy,driving_axis,makespan,ratio_to_static,imbalance,slides,moves_per_boundary_interval,steady_moves_per_boundary_interval,steady_reversals\n",
    );
    let mut floors = String::from(
        "array,spheres,volume_ratio,floor,floor_axis,broadcast,oracle_predicted_max,oracle_predicted_mean,oracle_max_busy,oracle_mean_busy,floor_over_oracle_mean,floor_over_static\n",
    );
    let mut panels = Vec::new();
    for &count in &cfg.balance_counts {
        let mut series: Vec<Series> = Vec::new();
        for &n in &cfg.balance_arrays {
            let line = |what: &str| Series {
                name: format!("{n}x{n}x{n}, {what}"),
                points: Vec::new(),
                style: Style::LineWithMarkers,
            };
            let (mut paper, mut view) = (line("paper's axis"), line("view axis"));
            let (mut prop, mut entry) = (line("proportional"), line("entry tiles, proportional"));
            for &v in &cfg.ratios {
                let scene = Scene::random(count, cfg.seed, v, cfg.grid)?;
                let base = run(&scene, [n; 3], cfg, Initial::Parallel, Policy::Static, 0)?;
                let (st, imb, axis) = (base.makespan, base.imbalance, base.axis);
                let _ = writeln!(fig9, "{n}x{n}x{n},{count},{v},static,{axis},{st},1.000,{imb:.3},0,0,0,0");
                let model = sim_board::CostModel::default();
                let mut map = host_tool::plan::direct::measure_costs(
                    &scene,
                    cfg.size[0],
                    cfg.size[1],
                    &model,
                    ideal_bytes(),
                )?;
                // A strict lower bound: the compute work is the same whatever
                // the partition (every cube's walks, tests and shading, and
                // every pixel's initial ray); messages only add to it.
                let heaviest = map.compute.iter().copied().max().unwrap_or(0);
                let s_nodes = u64::from(n).pow(3);
                let pixels = u64::from(cfg.size[0]) * u64::from(cfg.size[1]);
                let compute = map.compute.iter().sum::<u64>() + pixels * model.create;
                // Oracle: the partition fitted to the full frame's cost map,
                // messages included, initial rays created where they enter.
                host_tool::plan::direct::add_initial_rays(
                    &mut map,
                    &scene,
                    cfg.size,
                    &model,
                    ideal_bytes(),
                    true,
                )?;
                let view_ax = host_tool::plan::partition::view_axis(&scene);
                let oracle_p =
                    Partition::fitted(scene.grid, [n; 3], view_ax, &map, Boundaries::StaggeredColumns)?;
                let predicted = oracle_p.node_costs(&map);
                let oracle = run_on(&scene, [n; 3], cfg, Initial::Entry, Policy::Static, st, Some(oracle_p))?;
                // The least busiest node any partition the nodes route can have
                // (over the three driving axes), and the oracle against it.
                // Beside its cells, a node pays at least for its lights and
                // the messages that begin and end the frame (the spheres it
                // is sent depend on its box, its neighbours on its place).
                let broadcast = host_tool::plan::direct::fixed_cost(0, 0, &scene, &model);
                let mut floor: Option<(u64, u8)> = None;
                for axis in 0..3 {
                    if let Some(f) = host_tool::plan::fit::floor::floor(&map, [n; 3], axis)? {
                        floor = Some(floor.map_or((f.cost, axis), |best| best.min((f.cost, axis))));
                    }
                }
                let predicted_max = predicted.iter().copied().max().unwrap_or(0);
                let predicted_mean = predicted.iter().sum::<u64>() as f64 / predicted.len().max(1) as f64;
                let oracle_mean = oracle.busy as f64 / s_nodes as f64;
                if let Some((f, axis)) = floor {
                    let _ = writeln!(
                        floors,
                        "{n}x{n}x{n},{count},{v},{f},{axis},{broadcast},{predicted_max},{predicted_mean:.0},{:.0},{oracle_mean:.0},{:.3},{:.3}",
                        oracle.imbalance * oracle_mean,
                        (f + broadcast) as f64 / oracle_mean,
                        (f + broadcast) as f64 / st as f64
                    );
                }
                let strict = (compute / s_nodes).max(heaviest);
                // The bound, per run: max(W/S, heaviest cube) with W the
                // run's own busy time, messages included (a partition that
                // passes fewer rays does less work, so W is the run's).
                let bound = |r: &Run| (r.busy / s_nodes).max(heaviest) as f64;
                let messaging = 1.0 - compute as f64 / base.busy.max(1) as f64;
                // Boundaries slide only along the driving axis, so no policy
                // moves work between rows: the busiest row's share is a floor
                // under the imbalance of any of them (cutting a row only adds
                // the crossings of its cuts).
                let rows = Partition::even(scene.grid, [n; 3], view_ax)?.row_loads(&map);
                let totals: Vec<f64> = rows.iter().map(|&l| l as f64).collect();
                let row_floor = totals.iter().cloned().fold(0.0, f64::max)
                    / (totals.iter().sum::<f64>() / totals.len().max(1) as f64).max(1.0);
                let _ = writeln!(
                    fig9,
                    "{n}x{n}x{n},{count},{v},oracle-entry,{view_ax},{},{:.3},{:.3},0,0,0,0",
                    oracle.makespan,
                    oracle.makespan as f64 / st as f64,
                    oracle.imbalance
                );
                let _ = writeln!(
                    report,
                    "Fig. 9/10: {n}^3 nodes, {count} spheres, volume ratio {v}: static makespan {st}, imbalance {imb:.2}; \
                     makespan / max(W/S, heaviest cube) = {:.2}; compute-only bound {strict} (messages are {:.0}% of \
                     the static run's busy time), static/compute-only bound = {:.2}; \
                     oracle-entry/static = {:.3} (imbalance {:.2}, makespan/bound {:.2}); \
                     imbalance floor of sliding along the view axis (busiest row / mean row) = {row_floor:.2}",
                    st as f64 / bound(&base),
                    messaging * 100.0,
                    st as f64 / strict as f64,
                    oracle.makespan as f64 / st as f64,
                    oracle.imbalance,
                    oracle.makespan as f64 / bound(&oracle)
                );
                if let Some((f, axis)) = floor {
                    let _ = writeln!(
                        report,
                        "Fig. 9/10: {n}^3 nodes, {count} spheres, volume ratio {v}: family floor {f} (axis {axis}; \
                         busiest node on its own box, forwarding and the scene's {broadcast} aside); the oracle's \
                         busiest node as the map prices it {predicted_max} ({:.3} of the floor); floor and scene \
                         against the oracle's mean busy time {:.2}, against the static makespan {:.3} (no partition the \
                         nodes can route does better with entry tiles)",
                        predicted_max as f64 / f.max(1) as f64,
                        (f + broadcast) as f64 / oracle_mean,
                        (f + broadcast) as f64 / st as f64
                    );
                }
                // Beyond the paper: initial rays created where they enter.
                // Ratios stay against the paper's static run (parallel tiles).
                let base_d = run(&scene, [n; 3], cfg, Initial::Entry, Policy::Static, 0)?;
                let st_d = base_d.makespan;
                let _ = writeln!(
                    fig9,
                    "{n}x{n}x{n},{count},{v},static-entry,{},{st_d},{:.3},{:.3},0,0,0,0",
                    base_d.axis,
                    st_d as f64 / st as f64,
                    base_d.imbalance
                );
                let _ = writeln!(
                    report,
                    "Fig. 9/10: {n}^3 nodes, {count} spheres, volume ratio {v}: static-entry/static = {:.3}, \
                     imbalance {:.2}, makespan/bound {:.2}",
                    st_d as f64 / st as f64,
                    base_d.imbalance,
                    st_d as f64 / bound(&base_d)
                );
                // Beyond the paper: the partition fitted to a preview, static and sliding.
                let fitted = preview(&scene, [n; 3], cfg, Initial::Entry)?;
                let pre =
                    run_on(&scene, [n; 3], cfg, Initial::Entry, Policy::Static, st_d, Some(fitted.clone()))?;
                for (initial, policy, name, line, start) in [
                    (Initial::Parallel, Policy::Paper, "slide", Some(&mut paper), None),
                    (Initial::Parallel, Policy::PaperView, "slide-view", Some(&mut view), None),
                    (Initial::Parallel, Policy::ProportionalView, "proportional-view", Some(&mut prop), None),
                    (Initial::Entry, Policy::PaperView, "slide-view-entry", None, None),
                    (
                        Initial::Entry,
                        Policy::ProportionalView,
                        "proportional-view-entry",
                        Some(&mut entry),
                        None,
                    ),
                    (Initial::Entry, Policy::Static, "static-preview-entry", None, Some(&fitted)),
                    (
                        Initial::Entry,
                        Policy::ProportionalView,
                        "proportional-preview-entry",
                        None,
                        Some(&fitted),
                    ),
                ] {
                    // The interval is a 64th of the matching static run.
                    let own_static = match (initial, start) {
                        (_, Some(_)) => pre.makespan,
                        (Initial::Entry, None) => st_d,
                        _ => st,
                    };
                    let r = match start {
                        Some(_) if matches!(policy, Policy::Static) => pre,
                        Some(p) => run_on(&scene, [n; 3], cfg, initial, policy, own_static, Some(p.clone()))?,
                        None => run(&scene, [n; 3], cfg, initial, policy, own_static)?,
                    };
                    let (t, imb, slides, axis) = (r.makespan, r.imbalance, r.slides, r.axis);
                    let ratio = t as f64 / st as f64;
                    let (churn, steady, back) = (r.churn, r.steady_churn, r.reversals);
                    if let Some(line) = line {
                        line.points.push((v, ratio));
                    }
                    let _ = writeln!(
                        fig9,
                        "{n}x{n}x{n},{count},{v},{name},{axis},{t},{ratio:.3},{imb:.3},{slides},{churn:.4},{steady:.4},{back:.3}"
                    );
                    let _ = writeln!(
                        report,
                        "Fig. 9/10: {n}^3 nodes, {count} spheres, volume ratio {v}: {name} (axis {axis})/static = {ratio:.3} \
                         (/its own static {:.3}), imbalance {imb:.2}, {slides} slides, boundaries moving per interval \
                         {:.1}% (steady state {:.1}%, {:.0}% of those reversing), makespan/bound {:.2}",
                        t as f64 / own_static as f64,
                        churn * 100.0,
                        steady * 100.0,
                        back * 100.0,
                        t as f64 / bound(&r)
                    );
                }
            }
            series.push(paper);
            series.push(view);
            series.push(prop);
            series.push(entry);
        }
        series.push(Series {
            name: "paper: 3/4 at 1, 1/5 at 1/4".into(),
            points: vec![(1.0, 0.75), (0.25, 0.2)],
            style: Style::LineWithMarkers,
        });
        panels.push((
            Chart {
                title: format!("Figs. 9/10: sliding against static, {count} spheres"),
                x_label: "volume ratio of the object region".into(),
                y_label: "makespan, slide / static".into(),
                log_x: true,
                log_y: false,
            },
            series,
        ));
    }
    write_atomic(&out.join("fig9_10.csv"), fig9.as_bytes())?;
    write_atomic(&out.join("fig9_10.png"), &png(&panels, 900, 450)?)?;
    write_atomic(&out.join("floors.csv"), floors.as_bytes())?;
    write_atomic(&out.join("report.txt"), report.as_bytes())?;
    Ok(report)
}
