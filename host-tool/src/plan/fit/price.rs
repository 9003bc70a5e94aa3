//! What each node pays under a cost map, every boundary crossing charged
//! hop by hop as the nodes route it.

use std::ops::ControlFlow;

use node_fw::CubeBox;

use super::rows::{RowCache, RowProfile};
use super::sums::{BoxSums, LayerSums, MapSums};
use crate::plan::cost_map::CostMap;
use crate::plan::partition::Partition;

/// A fit's score, lowest best ([`Pricing::score`]).
pub(super) type Score = (u64, u64, u128);

/// A score worse than any partition's.
pub(super) const WORST: Score = (u64::MAX, u64::MAX, u128::MAX);

/// A box of cubes, `lo <= c < hi` on every axis.
type Cubes = ([usize; 3], [usize; 3]);

/// The rays leaving one face of a node's box, routed together: where what
/// they charge a hop is kept.
struct Crossing<'a> {
    /// The cycles they charge ([`CostMap::up`] or [`CostMap::down`] along
    /// `axis`) and the bytes they put on the wire.
    sums: &'a BoxSums,
    axis: usize,
    /// The charges are kept at the cube below the face: for rays leaving
    /// upward, a cube before the one they are bound for.
    upward: bool,
}

impl Crossing<'_> {
    /// What the rays bound for `cubes` charge each side of a hop, and the
    /// bytes they put on its wire.
    fn price(&self, (mut lo, mut hi): Cubes) -> (u64, u64) {
        if self.upward {
            lo[self.axis] -= 1;
            hi[self.axis] -= 1;
        }
        let [cycles, bytes] = self.sums.sum(lo, hi);
        (cycles, bytes)
    }
}

/// Per axis, what the rays crossing each face upward and downward charge.
type Faces<'a> = [&'a [BoxSums; 3]; 2];

/// What the fit prices the candidates of one map with: the map's sums, and
/// the rows met so far.
pub(super) struct Pricing<'a> {
    map: &'a CostMap,
    sums: MapSums,
    layers: LayerSums,
    rows: RowCache,
}

impl<'a> Pricing<'a> {
    /// Ready to price partitions of `map` along `driving_axis`.
    pub(super) fn new(map: &'a CostMap, driving_axis: u8) -> Self {
        let layers = LayerSums::new(map, driving_axis);
        Self { map, sums: MapSums::new(map), layers, rows: RowCache::default() }
    }

    /// Cubes per axis.
    pub(super) fn grid(&self) -> [u16; 3] {
        self.map.grid
    }

    /// How well `p` fits: the longest node time (the longer of its CPU's
    /// and its busiest wire's, [`Partition::node_times`]), then the
    /// busiest CPU, then the sum of the squared times. Where the wires
    /// bound the frame, many cuts share its longest wire; among them the
    /// CPU is still balanced, since a wire's time is an estimate.
    pub(super) fn score(&self, p: &Partition) -> Score {
        // No node's time is past the largest u64.
        self.score_within(p, u64::MAX).unwrap_or(WORST)
    }

    /// `p`'s [`Self::score`], unless some node's time is past `limit`:
    /// then it scores worse than any partition whose nodes all keep within
    /// it, and is given up as soon as that shows. Most candidates of the
    /// local search are worse than the partition they would replace, and
    /// most show it early.
    pub(super) fn score_within(&self, p: &Partition, limit: u64) -> Option<Score> {
        let (cpu, times) = p.cpu_and_times(self.map.grid, &self.sums, limit)?;
        Some(score_of(&cpu, &times))
    }

    /// `p`'s rows, each profiled and cut on its own ([`RowCache::rows`]).
    pub(super) fn rows(&mut self, p: &Partition) -> (Vec<RowProfile>, Vec<Vec<u16>>) {
        self.rows.rows(p, &self.layers)
    }
}

/// The score of the nodes' CPUs and times.
fn score_of(cpu: &[u64], times: &[u64]) -> Score {
    let most = |v: &[u64]| v.iter().copied().max().unwrap_or(0);
    (most(times), most(cpu), times.iter().map(|&c| u128::from(c) * u128::from(c)).sum())
}

impl Partition {
    /// Every node's cost under `map`, rays routed as the nodes route them
    /// ([`node_fw::route`]): a ray leaving a node across a non-driving axis
    /// goes to the neighbour at the same place along the driving axis, which
    /// forwards it along that axis to the owner, every node on the way paying
    /// both sides of a hop.
    pub fn node_costs(&self, map: &CostMap) -> Vec<u64> {
        self.cpu_and_wires(map.grid, &MapSums::new(map), u64::MAX).map(|(cpu, _)| cpu).unwrap_or_default()
    }

    /// Every node's time under `map`: the longer of its CPU's
    /// ([`Self::node_costs`]) and its busiest wire's (its host link's bytes,
    /// or those one of its neighbour links carries either way, each way a
    /// wire of its own), at what a byte takes there. The CPU alone where the
    /// map prices no wire.
    pub fn node_times(&self, map: &CostMap) -> Vec<u64> {
        self.cpu_and_times(map.grid, &MapSums::new(map), u64::MAX).map(|(_, times)| times).unwrap_or_default()
    }

    /// Every node's CPU ([`Self::node_costs`]) and time ([`Self::node_times`]),
    /// every crossing routed once for both; `None` once some node's time is
    /// past `limit`.
    fn cpu_and_times(&self, grid: [u16; 3], sums: &MapSums, limit: u64) -> Option<(Vec<u64>, Vec<u64>)> {
        let (cpu, wires) = self.cpu_and_wires(grid, sums, limit)?;
        let times = match wires {
            Some(wires) => cpu.iter().zip(wires).map(|(&c, w)| c.max(w)).collect(),
            None => cpu.clone(),
        };
        Some((cpu, times))
    }

    /// Every node's CPU, and its busiest wire's time where `sums` prices the
    /// wires: its host link's bytes, or those one of its neighbour links
    /// carries either way, at what a byte takes there. `None` as soon as
    /// some node's CPU or wire is past `limit`: every charge only adds.
    ///
    /// Every crossing lies on one face of the box it leaves: a node pays its
    /// cubes, and each face of its box inside the grid sends the rays leaving
    /// through it on their way, all together ([`Routes::send`]), their cycles
    /// and bytes summed at each hop.
    fn cpu_and_wires(
        &self,
        grid: [u16; 3],
        sums: &MapSums,
        limit: u64,
    ) -> Option<(Vec<u64>, Option<Vec<u64>>)> {
        let routes = Routes::new(self);
        let wire = sums.wire;
        let cells = routes.cubes(&sums.cells);
        let mut cpu: Vec<u64> = cells.iter().map(|c| c[0]).collect();
        let host = wire.map(|w| cells.iter().map(|c| c[1] * w.host).collect::<Vec<_>>());
        if cpu.iter().chain(host.iter().flatten()).any(|&t| t > limit) {
            return None;
        }
        // A port's bytes past this take its wire past `limit`.
        let byte_limit = wire.map_or(u64::MAX, |w| limit.checked_div(w.neighbour).unwrap_or(u64::MAX));
        // Per node and port (axis, upward): bytes sent and bytes received.
        let mut sent = vec![[0u64; 6]; routes.boxes.len()];
        let mut received = sent.clone();
        let mut sink = |at: usize, next: usize, axis: usize, (price, bytes): (u64, u64)| {
            cpu[at] += price;
            cpu[next] += price;
            let up = usize::from(next > at);
            let out = &mut sent[at][2 * axis + up];
            *out += bytes;
            let back = &mut received[next][2 * axis + 1 - up];
            *back += bytes;
            let past = cpu[at] > limit || cpu[next] > limit || *out > byte_limit || *back > byte_limit;
            if past { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
        };
        if routes.every_face(grid, [&sums.up, &sums.down], &mut sink).is_break() {
            return None;
        }
        let wires = wire.zip(host).map(|(wire, host)| {
            let busiest =
                |(sent, received): (&[u64; 6], &[u64; 6])| sent.iter().chain(received).copied().max();
            sent.iter()
                .zip(&received)
                .zip(host)
                .map(|(ports, host)| (busiest(ports).unwrap_or(0) * wire.neighbour).max(host))
                .collect()
        });
        Some((cpu, wires))
    }
}

/// How the nodes of a partition route a ray ([`node_fw::route::toward`]):
/// their boxes, and the order and strides of the axes.
struct Routes {
    boxes: Vec<Cubes>,
    /// The non-driving axes, then the driving axis.
    order: [usize; 3],
    /// How far apart neighbours along each axis are in node order.
    stride: [usize; 3],
}

impl Routes {
    fn new(p: &Partition) -> Self {
        let d = usize::from(p.driving_axis);
        let [x, y, _] = p.array.map(usize::from);
        let boxes = (0..p.len()).map(|id| p.bounds(id)).map(|b| (lo(&b), hi(&b))).collect();
        Self { boxes, order: [(d + 1) % 3, (d + 2) % 3, d], stride: [1, x, x * y] }
    }

    /// What each node's cubes cost, and the bytes they send the host.
    fn cubes(&self, cells: &BoxSums) -> Vec<[u64; 2]> {
        self.boxes.iter().map(|&(lo, hi)| cells.sum(lo, hi)).collect()
    }

    /// Sends the rays leaving every face of every box inside the grid on
    /// their way: `faces` what they charge crossing upward and downward
    /// per axis, and the bytes they put on the wire.
    ///
    /// `sink` takes each hop: the node it leaves, the node it reaches, the
    /// axis it crosses, and what the rays charge there and their bytes.
    fn every_face<F>(&self, grid: [u16; 3], faces: Faces<'_>, sink: &mut F) -> ControlFlow<()>
    where
        F: FnMut(usize, usize, usize, (u64, u64)) -> ControlFlow<()>,
    {
        let grid = grid.map(usize::from);
        for (id, &(lo, hi)) in self.boxes.iter().enumerate() {
            for axis in 0..3 {
                let crossing = |way: usize, upward| Crossing { sums: &faces[way][axis], axis, upward };
                if hi[axis] < grid[axis] {
                    let mut beyond = (lo, hi);
                    (beyond.0[axis], beyond.1[axis]) = (hi[axis], hi[axis] + 1);
                    self.send(sink, id, beyond, &crossing(0, true))?;
                }
                if lo[axis] > 0 {
                    let mut beyond = (lo, hi);
                    (beyond.0[axis], beyond.1[axis]) = (lo[axis] - 1, lo[axis]);
                    self.send(sink, id, beyond, &crossing(1, false))?;
                }
            }
        }
        ControlFlow::Continue(())
    }

    /// Charges both ends of every hop of the rays at node `at` bound for
    /// `cubes`, as the nodes route each ray: the first axis in routing
    /// order on which a cube lies outside the node's box decides its port.
    /// So the cubes are split by the box's bounds on that axis: those below
    /// and above hop to the neighbour that way, and those within go on to
    /// the next axis from the same node.
    fn send<F: FnMut(usize, usize, usize, (u64, u64)) -> ControlFlow<()>>(
        &self,
        sink: &mut F,
        at: usize,
        cubes: Cubes,
        rays: &Crossing<'_>,
    ) -> ControlFlow<()> {
        let (blo, bhi) = self.boxes[at];
        let outside = |a: usize| cubes.0[a] < blo[a] || cubes.1[a] > bhi[a];
        let Some(axis) = self.order.into_iter().find(|&a| outside(a)) else {
            return ControlFlow::Continue(());
        };
        let (lo, hi) = (cubes.0[axis], cubes.1[axis]);
        let part = |from: usize, to: usize| {
            let mut p = cubes;
            (p.0[axis], p.1[axis]) = (from, to);
            p
        };
        if lo < blo[axis] {
            self.hop(sink, (at, at - self.stride[axis], axis), part(lo, hi.min(blo[axis])), rays)?;
        }
        if hi > bhi[axis] {
            self.hop(sink, (at, at + self.stride[axis], axis), part(lo.max(bhi[axis]), hi), rays)?;
        }
        let within = part(lo.max(blo[axis]), hi.min(bhi[axis]));
        if within.0[axis] < within.1[axis] {
            return self.send(sink, at, within, rays);
        }
        ControlFlow::Continue(())
    }

    /// One hop of the rays bound for `cubes`, from `at` to its neighbour
    /// `next` along `axis`, charged; and on from there unless they are home
    /// (most are: checked here, it spares a call).
    fn hop<F: FnMut(usize, usize, usize, (u64, u64)) -> ControlFlow<()>>(
        &self,
        sink: &mut F,
        (at, next, axis): (usize, usize, usize),
        cubes: Cubes,
        rays: &Crossing<'_>,
    ) -> ControlFlow<()> {
        sink(at, next, axis, rays.price(cubes))?;
        let (nlo, nhi) = self.boxes[next];
        if (0..3).any(|a| cubes.0[a] < nlo[a] || cubes.1[a] > nhi[a]) {
            return self.send(sink, next, cubes, rays);
        }
        ControlFlow::Continue(())
    }
}

fn lo(b: &CubeBox) -> [usize; 3] {
    b.lo.map(usize::from)
}

fn hi(b: &CubeBox) -> [usize; 3] {
    b.hi.map(usize::from)
}

#[cfg(test)]
mod tests {
    use node_fw::CubeBox;
    use proptest::prelude::*;

    use super::super::testing::partitions_and_maps;
    use super::Pricing;
    use crate::plan::cost_map::{CostMap, WireCycles};
    use crate::plan::partition::Partition;

    /// Every node's cost found the plain way: each pair of neighbouring
    /// cubes of two owners charged hop by hop, with owners, boxes and routes
    /// worked out here ([`node_fw::route::toward`], the nodes' rule); and
    /// its bytes on each port (axis, upward) sent and received.
    fn walked(p: &Partition, map: &CostMap) -> (Vec<u64>, Vec<[[u64; 6]; 2]>) {
        let n = map.grid.map(usize::from);
        let boxes: Vec<CubeBox> = (0..p.len()).map(|id| p.bounds(id)).collect();
        let owner = |c: [usize; 3]| {
            let cell = c.map(|v| v as i32);
            boxes.iter().position(|b| node_fw::route::toward(b, cell, 0).is_none()).unwrap()
        };
        let a = p.array.map(usize::from);
        let mut cost = vec![0u64; p.len()];
        let mut ports = vec![[[0u64; 6]; 2]; p.len()];
        let mut route = |from: usize, cell: [usize; 3], per_side: u64, bytes: u64| {
            let mut at = from;
            let target = owner(cell);
            while at != target {
                let port =
                    node_fw::route::toward(&boxes[at], cell.map(|v| v as i32), usize::from(p.driving_axis))
                        .unwrap();
                let axis = port.axis().unwrap();
                let up = port == node_fw::link::Port::toward(axis, true);
                let mut c = node_fw::wiring::coord_of(at, p.array).map(usize::from);
                if up {
                    c[axis] += 1
                } else {
                    c[axis] -= 1
                }
                let next = c[0] + a[0] * (c[1] + a[1] * c[2]);
                cost[at] += per_side;
                cost[next] += per_side;
                ports[at][0][2 * axis + usize::from(up)] += bytes;
                ports[next][1][2 * axis + usize::from(!up)] += bytes;
                at = next;
            }
        };
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    let i = x + n[0] * (y + n[1] * z);
                    let here = owner([x, y, z]);
                    for ax in 0..3 {
                        let mut up = [x, y, z];
                        up[ax] += 1;
                        if up[ax] < n[ax] && owner(up) != here {
                            route(here, up, map.up[ax][i], map.wire.up[ax][i]);
                            route(owner(up), [x, y, z], map.down[ax][i], map.wire.down[ax][i]);
                        }
                    }
                }
            }
        }
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    cost[owner([x, y, z])] += map.cell(x + n[0] * (y + n[1] * z));
                }
            }
        }
        (cost, ports)
    }

    /// A partition priced within a limit, its nodes' times `times`: the
    /// whole score where every node keeps within the limit, else none.
    fn priced_within_a_limit(p: &Partition, map: &CostMap, times: &[u64]) -> Result<(), TestCaseError> {
        let pricing = Pricing::new(map, p.driving_axis);
        let longest = times.iter().copied().max().unwrap_or(0);
        prop_assert_eq!(pricing.score(p).0, longest);
        for limit in [longest.saturating_sub(1), longest, longest + 1, u64::MAX] {
            let within = pricing.score_within(p, limit);
            prop_assert_eq!(within, (longest <= limit).then(|| pricing.score(p)), "limit {}", limit);
        }
        Ok(())
    }

    proptest! {
        #[test]
        fn node_costs_by_sums_agree_with_walking_every_face((p, map) in partitions_and_maps(true)) {
            let cpu = walked(&p, &map).0;
            prop_assert_eq!(p.node_costs(&map), cpu.clone());
            priced_within_a_limit(&p, &map, &cpu)?;
        }

        #[test]
        fn node_times_are_the_longer_of_the_cpus_and_the_busiest_wires(
            (p, mut map) in partitions_and_maps(true),
            bytes in prop::collection::vec(0u64..100, 1..=200),
            cycles in (0u64..400, 0u64..1200),
        ) {
            let mut b = bytes.iter().cycle().copied();
            for i in 0..map.compute.len() {
                map.wire.host[i] = b.next().unwrap_or(0);
                for a in 0..3 {
                    map.wire.up[a][i] = b.next().unwrap_or(0);
                    map.wire.down[a][i] = b.next().unwrap_or(0) / 3;
                }
            }
            map.wire.cycles = WireCycles { neighbour: cycles.0, host: cycles.1 };
            let (cpu, ports) = walked(&p, &map);
            let host = |id: usize| {
                let b = p.bounds(id);
                let mut sum = 0;
                for z in b.lo[2]..b.hi[2] {
                    for y in b.lo[1]..b.hi[1] {
                        for x in b.lo[0]..b.hi[0] {
                            sum += map.wire.host[map.index([x, y, z].map(i32::from)).unwrap()];
                        }
                    }
                }
                sum
            };
            let expected: Vec<u64> = (0..p.len())
                .map(|id| {
                    let wire = ports[id].iter().flatten().copied().max().unwrap_or(0) * cycles.0;
                    cpu[id].max(wire).max(host(id) * cycles.1)
                })
                .collect();
            prop_assert_eq!(p.node_times(&map), expected.clone());
            priced_within_a_limit(&p, &map, &expected)?;
        }
    }
}
