//! The cost map the host fits partitions to, against the board it models.

use host_tool::plan::cost_map::CostMap;
use host_tool::plan::direct;
use host_tool::plan::options::{Initial, Layout, RenderOptions};
use host_tool::plan::partition::Partition;
use host_tool::scene::Scene;
use host_tool::scene::path::CameraPath;
use host_tool::session::sim::{render_partitioned, render_sim};

/// Spheres crowded in the middle eighth of the grid, as in Figs. 9/10, on
/// the ideal links: the map prices the nodes' CPU work (messages included),
/// not the CPU a UART's bytes take nor the time they spend on the wire, so
/// it is held to the board where those are nil.
fn options() -> (Scene, RenderOptions) {
    let s = Scene::random(1000, 7, 0.125, [32; 3]).unwrap();
    let mut opts = RenderOptions::new([4, 4, 4]);
    opts.sim = sim_board::SimConfig::with_links([4, 4, 4], sim_board::LinkPreset::Ideal);
    opts.size = [64, 64];
    opts.initial = Initial::Entry;
    (s, opts)
}

/// The map of `s` at `opts`' size, initial rays created by entry tiles.
fn map_of(s: &Scene, opts: &RenderOptions) -> CostMap {
    let bytes = direct::ByteCpu::of(&opts.sim.link, &opts.sim.host_link);
    direct::cost_map(s, opts.size, &opts.sim.cost, bytes, true, opts.clear_walks).unwrap()
}

#[test]
fn the_cost_map_accounts_for_each_nodes_busy_time() {
    let (s, opts) = options();
    let map = map_of(&s, &opts);
    let even = Partition::even(s.grid, opts.array, 2).unwrap();
    let mut staggered = even.clone();
    // Rows cut apart, so rays crossing between rows are forwarded.
    staggered.row_cuts = Some((0..16).map(|r| vec![0, 4 + r % 3 * 4, 16, 20 + r % 5, 32]).collect());
    // Columns cut per slab too, so rays crossing between slabs are forwarded
    // across the columns and then along the rows.
    let mut jagged = staggered.clone();
    jagged.slab_cuts = Some((0..4).map(|s| vec![0, 5 + 2 * s, 16 - s, 22 + s, 32]).collect());
    // The map prices every hop as a ray on a grant; whether a ray goes on
    // one depends on when the grants arrive, which the map cannot see (with a
    // reply per ray it was within 1.9%). It prices every retirement as a
    // message of its own, which is what a node pays when its rays end one at
    // a time; a busy node's retirements wait for company and share messages
    // (eight or so records to one), so it pays less. The map keeps the
    // dearer price on purpose: priced as a record of a full message, the map
    // came within -4.0..+3.6% per node here, but the f413 preview fits ran
    // slower. Before the fit priced the wires, two of the four scenes of
    // docs/results.md' defaults table ran 8% and 16% slower; with the host
    // link's wire priced apart, the 2x2x2 scene ran 10% slower and seed 7's
    // 5% (two others 1% and 3% faster).
    // Before the pool shared its spare slots, refusals made forwarding nodes
    // pay up to 26% more.
    for p in [even, staggered, jagged] {
        holds_each_node_to_the_map(&s, &opts, &map, &p);
    }
}

/// Renders `s` on `p` and holds each node's busy time to what `map` places
/// on it, beside the scene's share and the frame's fixed messages.
fn holds_each_node_to_the_map(s: &Scene, opts: &RenderOptions, map: &CostMap, p: &Partition) {
    let want = direct::render(s, opts.size[0], opts.size[1]).unwrap();
    let r = render_partitioned(s, opts, p.clone()).unwrap();
    assert!(r.frame.sums == want.sums, "the partition changed the image");
    let costs = p.node_costs(map);
    // The board's count of each node's busy cycles: the scene's handling,
    // which a node does before its frame starts and so leaves out of the
    // running time it reports, included.
    let busy_of = |id: usize| r.busy[id].expect("the board sees its nodes").total() as f64;
    let busiest = (0..costs.len()).map(busy_of).fold(0.0, f64::max);
    let (mut busy_sum, mut placed_sum) = (0.0, 0.0);
    for (id, &cost) in costs.iter().enumerate() {
        let busy = busy_of(id);
        // Beside what the map places: its part of the scene and the
        // messages that begin and end the frame.
        let fixed = direct::fixed_cost(p.spheres_sent(id, s), p.neighbours(id), s, &opts.sim.cost);
        let placed = (cost + fixed) as f64;
        // What a fit balances is the busiest node, so each node is held
        // to the busiest's time. Measured: the map -4.0% to +9.3% of it
        // off; it prices every retirement as a message of its own, which
        // busy nodes do not pay.
        assert!(
            (busy - placed).abs() < 0.10 * busiest,
            "node {id}: busy {busy:.4e}, the map says {placed:.4e} (busiest {busiest:.4e})"
        );
        (busy_sum, placed_sum) = (busy_sum + busy, placed_sum + placed);
    }
    // Measured: the map +0.3% to +1.8% over, for the same reason.
    assert!(
        (busy_sum - placed_sum).abs() < 0.05 * busy_sum,
        "busy {busy_sum:.4e}, the map says {placed_sum:.4e}"
    );
}

#[test]
fn a_preview_fitted_with_messages_lowers_the_busiest_node() {
    let (s, mut opts) = options();
    let busiest = |opts: &RenderOptions| {
        let r = render_sim(&s, opts).unwrap();
        assert!(r.frame.sums == direct::render(&s, opts.size[0], opts.size[1]).unwrap().sums);
        r.frame.loads.iter().map(|l| l.unwrap().running).max().unwrap()
    };
    opts.driving_axis = Some(2);
    let even = busiest(&opts);
    opts.layout = Layout::Preview;
    let fitted = busiest(&opts);
    // Measured: 4.65e6 even, 2.67e6 fitted to a 32 x 32 preview.
    assert!(fitted < even * 3 / 4, "busiest node: even {even}, preview {fitted}");
}

/// Seen at an angle, rays enter the grid through its side faces too. Entry
/// tiles have those entering through the side face toward the eye created
/// where they enter, and the others on the face toward the eye, whence they
/// go along the view axis: the map charges each where the tiles create it.
/// When the map charged creation where the rays entered while the tiles
/// created every ray on the front face, node 0 (a corner of the front face)
/// was busy 2.78e6 cycles against the map's 1.95e6, 22% of the busiest
/// node's time; the map charging the front face for every ray fails too,
/// now that the side face creates its own.
#[test]
fn the_cost_map_accounts_for_initial_rays_seen_at_an_angle() {
    let (s, opts) = options();
    let s = CameraPath::Orbit { degrees: 360.0 }.frame(&s, 1, 6).unwrap();
    let map = map_of(&s, &opts);
    holds_each_node_to_the_map(&s, &opts, &map, &Partition::even(s.grid, opts.array, 2).unwrap());
}

/// On slow links the wires, not the CPUs, bound a frame. Fitted to the CPU
/// alone, the preview cut 4x4x4 into boxes slower than even ones here
/// (3.10e7 cycles against 2.54e7 at 1 Mbaud, 2.67e8 against 2.33e8 at
/// 115 200 baud, measured before the host's sends took their wire time,
/// which adds each node's load to both). The fit prices each node's busiest wire as well, and
/// keeps even boxes where its prices put them ahead.
#[test]
fn on_slow_links_the_preview_fit_never_loses_to_even_boxes() {
    let s = Scene::random(1000, 1986, 1.0, [32; 3]).unwrap();
    let mut opts = RenderOptions::new([4, 4, 4]);
    opts.sim = sim_board::SimConfig::with_links([4, 4, 4], sim_board::LinkPreset::F413);
    opts.sim.link.baud = 1_000_000;
    opts.sim.host_link.baud = 1_000_000;
    opts.size = [128, 128];
    opts.driving_axis = Some(2);
    opts.balance = None;
    let makespan = |layout| {
        let opts = RenderOptions { layout, ..opts };
        let r = render_sim(&s, &opts).unwrap();
        (r.frame.makespan, r.frame.sums)
    };
    let (even, even_image) = makespan(Layout::Even);
    let (fitted, fitted_image) = makespan(Layout::Preview);
    assert!(fitted_image == even_image, "the partition changed the image");
    assert!(fitted <= even, "1 Mbaud: preview {fitted}, even boxes {even}");
}
