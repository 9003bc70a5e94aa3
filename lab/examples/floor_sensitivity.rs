//! How the family's floor along the view axis answers to what messages and
//! initial rays cost, on the scenes of `bench paper` (128x128, grid 32^3).
//!
//! For each of its 16 balance configurations, on the full frame's cost map
//! with initial rays created where they enter (as the oracle's):
//! - `floor/mean`: the floor against the mean node of the floor's own
//!   partition, crossings priced as measured;
//! - `no crossings`: the same with every crossing priced at nothing, against
//!   a node's mean share of the cubes;
//! - `entry layer`: a row's first layer of cubes along the view axis (which
//!   no cut can split) against a node's mean share of the cubes;
//! - `busiest row`, `busiest in row`: on the floor's partition, the row of
//!   nodes with the most work against the mean row, and the busiest node
//!   against its row's mean node;
//! - `half create`: the floor and its ratio with initial rays at half cost.
//!
//! `cargo run --release -p lab --example floor_sensitivity [SEED]`
//! (seed 1986 by default, as `bench paper`'s; about a minute).

use host_tool::error::{HostError, input};
use host_tool::plan::cost_map::CostMap;
use host_tool::plan::direct::{ByteCpu, add_initial_rays, measure_costs};
use host_tool::plan::fit::floor::floor;
use host_tool::plan::partition::view_axis;
use host_tool::scene::Scene;
use sim_board::CostModel;

const SIZE: [u16; 2] = [128, 128];
const GRID: [u16; 3] = [32; 3];

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), HostError> {
    let seed = match std::env::args().nth(1) {
        Some(s) => s.parse().map_err(|_| input(format!("seed must be a number, got {s}")))?,
        None => 1986,
    };
    println!(
        "array,spheres,volume_ratio,floor/mean,no crossings,entry layer,busiest row,busiest in row,half create floor change,half create floor/mean"
    );
    for count in [1000, 2000] {
        for n in [4u16, 8] {
            for v in [1.0, 0.5, 0.25, 0.125] {
                let scene = Scene::random(count, seed, v, GRID)?;
                println!("{n}x{n}x{n},{count},{v},{}", row(&scene, n)?);
            }
        }
    }
    Ok(())
}

/// One configuration's columns.
fn row(scene: &Scene, n: u16) -> Result<String, HostError> {
    let model = CostModel::default();
    let cubes = measure_costs(scene, SIZE[0], SIZE[1], &model, ByteCpu::default())?;
    let with_rays = |create| -> Result<CostMap, HostError> {
        let mut map = cubes.clone();
        add_initial_rays(&mut map, scene, SIZE, &CostModel { create, ..model }, ByteCpu::default(), true)?;
        Ok(map)
    };
    let axis = view_axis(scene);
    let map = with_rays(model.create)?;
    let full = floor_stats(&map, n, axis)?;
    let mut bare = map.clone();
    for faces in bare.up.iter_mut().chain(bare.down.iter_mut()) {
        faces.iter_mut().for_each(|f| *f = 0);
    }
    let bare = floor_stats(&bare, n, axis)?;
    let half = floor_stats(&with_rays(model.create / 2)?, n, axis)?;
    Ok(format!(
        "{:.3},{:.3},{:.3},{:.3},{:.3},{:+.1}%,{:.3}",
        full.ratio,
        bare.ratio,
        entry_layer(&map, n, axis, scene.camera().eye),
        full.busiest_row,
        full.busiest_in_row,
        100.0 * (half.cost as f64 / full.cost as f64 - 1.0),
        half.ratio
    ))
}

/// The floor along an axis, and how its own partition's work lies.
struct FloorStats {
    /// The floor: the least busiest node of the family.
    cost: u64,
    /// The floor against its partition's mean node.
    ratio: f64,
    /// The busiest row of nodes' work against the mean row's.
    busiest_row: f64,
    /// The busiest node's work against its row's mean node.
    busiest_in_row: f64,
}

fn floor_stats(map: &CostMap, n: u16, axis: u8) -> Result<FloorStats, HostError> {
    let f = floor(map, [n; 3], axis)?.ok_or_else(|| input("grid too large to table"))?;
    let p = &f.partition;
    let costs = p.node_costs(map);
    let mut rows = vec![0u64; costs.len() / usize::from(n)];
    for (id, &c) in costs.iter().enumerate() {
        rows[p.row_of(p.coord(id))] += c;
    }
    let mean = |v: &[u64]| v.iter().sum::<u64>() as f64 / v.len().max(1) as f64;
    let busiest = (0..costs.len()).max_by_key(|&id| costs[id]).unwrap_or(0);
    let its_row = rows[p.row_of(p.coord(busiest))] as f64 / f64::from(n);
    Ok(FloorStats {
        cost: f.cost,
        ratio: f.cost as f64 / mean(&costs),
        busiest_row: rows.iter().copied().max().unwrap_or(0) as f64 / mean(&rows),
        busiest_in_row: costs[busiest] as f64 / its_row,
    })
}

/// The layer of cubes toward the eye (where rays enter), per row of nodes,
/// against a node's mean share of all cubes.
fn entry_layer(map: &CostMap, n: u16, axis: u8, eye: [f64; 3]) -> f64 {
    let g = map.grid.map(usize::from);
    let d = usize::from(axis);
    let (mut layers, mut total) = (vec![0u64; g[d]], 0u64);
    for i in 0..map.compute.len() {
        let cell = [i % g[0], i / g[0] % g[1], i / (g[0] * g[1])];
        layers[cell[d]] += map.cell(i);
        total += map.cell(i);
    }
    let near = if eye[d] < f64::from(map.grid[d]) / 2.0 { layers.first() } else { layers.last() };
    let entry = near.copied().unwrap_or(0);
    let rows = f64::from(n).powi(2);
    (entry as f64 / rows) / (total as f64 / f64::from(n).powi(3))
}
