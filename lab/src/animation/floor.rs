//! The least busiest node any partition the nodes can route could have in
//! each frame of a sequence: how far from even the frame's work allows.
//!
//! Each frame's full cost map (the frame's own camera, every traced pixel,
//! initial rays charged where the frame's start creates them) is cut by the
//! family's exact floor ([`host_tool::plan::fit::floor`]) along each of the
//! three driving axes, and the least is kept. No partition of the family has
//! a busiest node below it, whatever the balancing; a mode's frames can be
//! held against it. The partition reaching it is then run, the frame alone:
//! an oracle that knows the frame's work before it is rendered, and shows
//! what the least busiest node gives on the board, where forwarding, the
//! host's links and the order of the work count too.

use rayon::prelude::*;

use host_tool::error::HostError;
use host_tool::plan::direct::{ByteCpu, cost_map, fixed_cost};
use host_tool::plan::fit::floor::floor;
use host_tool::plan::options::{Initial, RenderOptions};
use host_tool::plan::partition::Partition;
use host_tool::results::files;
use host_tool::scene::Scene;
use host_tool::scene::path::CameraPath;
use host_tool::session::sim::render_partitioned;

/// One frame's floor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameFloor {
    /// The frame.
    pub frame: u32,
    /// The least busiest node over the family and the three driving axes,
    /// with what every node pays beside its cubes (its lights and the
    /// messages that begin and end a frame), in cycles.
    pub cycles: u64,
    /// The busiest node over the mean node of the partition reaching it.
    /// No partition has a lower busiest node; one more even than this must
    /// do more work in all ([`FrameFloor::extra_work_for`]).
    pub imbalance: f64,
    /// The frame rendered alone on the floor's partition, static.
    pub ran: Ran,
}

/// A frame as the in-memory board rendered it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ran {
    /// Its makespan, in cycles (the whole scene sent first).
    pub makespan: u64,
    /// The busiest node's running time over the mean.
    pub imbalance: f64,
}

impl FrameFloor {
    /// How much more work in all than the floor's own partition a partition
    /// must do to reach `imbalance` with a busiest node at least the floor:
    /// its mean must be at least the floor over `imbalance` (a fraction;
    /// zero where the floor's partition already reaches it).
    pub fn extra_work_for(&self, imbalance: f64) -> f64 {
        (self.imbalance / imbalance - 1.0).max(0.0)
    }
}

/// The floor of frames `from..frames` of a sequence of `frames` along
/// `path` over `scene` on `array`, as `base` renders them (image, samples,
/// costs and links); `None` for a frame whose grid is too large to table.
pub fn frame_floors(
    scene: &Scene,
    base: &RenderOptions,
    (path, frames): (CameraPath, u32),
    array: [u16; 3],
    from: u32,
) -> Result<Vec<Option<FrameFloor>>, HostError> {
    let steady: Vec<u32> = (from..frames).collect();
    steady.into_par_iter().map(|k| frame_floor(&path.frame(scene, k, frames)?, base, array, k)).collect()
}

fn frame_floor(
    scene: &Scene,
    o: &RenderOptions,
    array: [u16; 3],
    frame: u32,
) -> Result<Option<FrameFloor>, HostError> {
    let bytes = ByteCpu::of(&o.sim.link, &o.sim.host_link);
    let creation = o.initial == Initial::Entry;
    let map = cost_map(scene, o.trace_size()?, &o.sim.cost, bytes, creation, o.clear_walks)?;
    let fixed = fixed_cost(0, 0, scene, &o.sim.cost);
    let mut best: Option<(u64, f64, Partition)> = None;
    for axis in 0..3 {
        let Some(f) = floor(&map, array, axis)? else { continue };
        let costs = f.partition.node_costs(&map);
        let mean = costs.iter().sum::<u64>() as f64 / costs.len().max(1) as f64 + fixed as f64;
        let cycles = f.cost + fixed;
        let imbalance = cycles as f64 / mean.max(1.0);
        if best.as_ref().is_none_or(|b| (cycles, imbalance) < (b.0, b.1)) {
            best = Some((cycles, imbalance, f.partition));
        }
    }
    let Some((cycles, imbalance, partition)) = best else { return Ok(None) };
    let mut alone = RenderOptions { array, balance: None, ..*o };
    alone.sim.array = array;
    let r = render_partitioned(scene, &alone, partition)?;
    if r.frame.rays_created != r.frame.rays_terminated {
        return Err(HostError::Node(format!("frame {frame} on the floor's partition lost rays")));
    }
    let ran = Ran { makespan: r.frame.makespan.0, imbalance: files::imbalance(&r) };
    Ok(Some(FrameFloor { frame, cycles, imbalance, ran }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every partition of the routed family on a 2x2x2 array over a 4^3
    /// grid along driving axis `d`: each cut of the slabs, of each slab's
    /// columns and of each row, one cube at least a part.
    fn family(d: u8) -> Vec<Partition> {
        let cut = |k: u16| vec![0, k, 4];
        let mut all = Vec::new();
        for slab in 1..4 {
            for columns in 0..9u16 {
                for rows in 0..81u16 {
                    let mut p = Partition::even([4; 3], [2; 3], d).expect("even");
                    let [s, c] = p.routed_axes();
                    p.cuts[s] = cut(slab);
                    p.slab_cuts = Some(vec![cut(columns % 3 + 1), cut(columns / 3 + 1)]);
                    p.cuts[c] = cut(columns % 3 + 1);
                    p.row_cuts = Some((0..4).map(|r| cut(rows / 3u16.pow(r) % 3 + 1)).collect());
                    all.push(p);
                }
            }
        }
        all
    }

    /// Each frame's floor is the least busiest node over every partition
    /// of the family along every axis, found by trying them all, priced by
    /// the frame's own map, plus what every node pays beside its cubes.
    #[test]
    fn each_frame_floor_is_the_least_busiest_node_of_every_partition() {
        let scene = Scene::random(12, 3, 1.0, [4; 3]).expect("scene");
        let mut o = RenderOptions::new([2, 2, 2]);
        o.size = [24, 24];
        let path = CameraPath::Orbit { degrees: 90.0 };
        let floors = frame_floors(&scene, &o, (path, 4), [2; 3], 1).expect("floors");
        assert_eq!(
            floors.iter().map(|f| f.map(|f| f.frame)).collect::<Vec<_>>(),
            [Some(1), Some(2), Some(3)]
        );
        let every: Vec<Partition> = (0..3).flat_map(family).collect();
        for f in floors.into_iter().flatten() {
            let frame = path.frame(&scene, f.frame, 4).expect("frame");
            let bytes = ByteCpu::of(&o.sim.link, &o.sim.host_link);
            let map = cost_map(&frame, o.size, &o.sim.cost, bytes, true, o.clear_walks).expect("map");
            let busiest = |p: &Partition| p.node_costs(&map).into_iter().max().unwrap_or(0);
            let least = every.iter().map(busiest).min().unwrap_or(0);
            assert_eq!(f.cycles, least + fixed_cost(0, 0, &frame, &o.sim.cost), "frame {}", f.frame);
            assert!(f.imbalance >= 1.0, "frame {}: imbalance {}", f.frame, f.imbalance);
            assert!(f.ran.imbalance >= 1.0, "frame {}: ran at imbalance {}", f.frame, f.ran.imbalance);
        }
    }

    #[test]
    fn extra_work_is_what_lifts_the_mean_to_the_floor_over_the_goal() {
        // The floor's partition: busiest node 1100 over a mean node of 1000.
        let ran = Ran { makespan: 0, imbalance: 0.0 };
        let f = FrameFloor { frame: 0, cycles: 1100, imbalance: 1.1, ran };
        let lifted_mean = 1000.0 * (1.0 + f.extra_work_for(1.05));
        assert!((1100.0 / lifted_mean - 1.05).abs() < 1e-12);
        assert_eq!(FrameFloor { imbalance: 1.02, ..f }.extra_work_for(1.05), 0.0);
    }
}
