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
//! `cargo run --release -p host-tool --example floor_sensitivity [SEED]`
//! (seed 1986 by default, as `bench paper`'s; about a minute).

use host_tool::cost_map::CostMap;
use host_tool::direct::{add_initial_rays, measure_costs};
use host_tool::error::{HostError, input};
use host_tool::fit::floor::floor;
use host_tool::partition::view_axis;
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
    let cubes = measure_costs(scene, SIZE[0], SIZE[1], &model)?;
    let with_rays = |create| -> Result<CostMap, HostError> {
        let mut map = cubes.clone();
        add_initial_rays(&mut map, scene, SIZE, &CostModel { create, ..model }, true)?;
        Ok(map)
    };
    let axis = view_axis(scene);
    let map = with_rays(model.create)?;
    let (full, full_ratio) = floor_ratio(&map, n, axis)?;
    let (row, in_row) = granularity(&map, n, axis)?;
    let mut bare = map.clone();
    for faces in bare.up.iter_mut().chain(bare.down.iter_mut()) {
        faces.iter_mut().for_each(|f| *f = 0);
    }
    let (_, bare_ratio) = floor_ratio(&bare, n, axis)?;
    let (half, half_ratio) = floor_ratio(&with_rays(model.create / 2)?, n, axis)?;
    Ok(format!(
        "{full_ratio:.3},{bare_ratio:.3},{:.3},{row:.3},{in_row:.3},{:+.1}%,{half_ratio:.3}",
        entry_layer(&map, n, axis, scene.camera().eye),
        100.0 * (half as f64 / full as f64 - 1.0)
    ))
}

/// The floor along `axis`, and it against its partition's mean node.
fn floor_ratio(map: &CostMap, n: u16, axis: u8) -> Result<(u64, f64), HostError> {
    let f = table(map, n, axis)?;
    let costs = f.partition.node_costs(map);
    let mean = costs.iter().sum::<u64>() as f64 / costs.len().max(1) as f64;
    Ok((f.cost, f.cost as f64 / mean))
}

fn table(map: &CostMap, n: u16, axis: u8) -> Result<host_tool::fit::floor::Floor, HostError> {
    floor(map, [n; 3], axis)?.ok_or_else(|| input("grid too large to table"))
}

/// On the floor's partition: the busiest row's work against the mean row's,
/// and the busiest node's against its row's mean node.
fn granularity(map: &CostMap, n: u16, axis: u8) -> Result<(f64, f64), HostError> {
    let p = table(map, n, axis)?.partition;
    let costs = p.node_costs(map);
    let mut rows = vec![0u64; costs.len() / usize::from(n)];
    for (id, &c) in costs.iter().enumerate() {
        rows[p.row_of(p.coord(id))] += c;
    }
    let mean_row = rows.iter().sum::<u64>() as f64 / rows.len().max(1) as f64;
    let busiest_row = rows.iter().copied().max().unwrap_or(0) as f64;
    let busiest = (0..costs.len()).max_by_key(|&id| costs[id]).unwrap_or(0);
    let its_row = rows[p.row_of(p.coord(busiest))] as f64 / f64::from(n);
    Ok((busiest_row / mean_row, costs[busiest] as f64 / its_row))
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
    let near = if eye[d] < 0.0 { layers.first() } else { layers.last() };
    let entry = near.copied().unwrap_or(0);
    let rows = f64::from(n).powi(2);
    (entry as f64 / rows) / (total as f64 / f64::from(n).powi(3))
}
