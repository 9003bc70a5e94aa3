//! Cost maps and partitions made from drawn numbers, for the fit's property
//! tests.

use proptest::prelude::*;

use crate::plan::cost_map::CostMap;
use crate::plan::partition::Partition;

/// A partition of a small grid over an array no larger, every cut drawn,
/// and a map of the grid drawn the same way ([`map_of`]); its rows cut
/// their own cuts only where `staggered_rows` allows.
pub fn partitions_and_maps(staggered_rows: bool) -> impl Strategy<Value = (Partition, CostMap)> {
    (
        prop::array::uniform3(2u16..=6),
        prop::array::uniform3(1u16..=3),
        0u8..3,
        prop::collection::vec(prop::collection::vec(0u16..100, 4), 40),
        prop::collection::vec(0u64..1000, 1..=200),
        (any::<bool>(), any::<bool>()),
    )
        .prop_filter("an array no larger than its grid", |(grid, array, ..)| {
            (0..3).all(|a| array[a] <= grid[a])
        })
        .prop_map(move |(grid, array, d, seeds, values, (slabs, rows))| {
            let p = partition_of(grid, array, d, &seeds, (slabs, rows && staggered_rows));
            (p, map_of(grid, &values))
        })
}

/// A map of `grid` whose every entry is the next of `values`, over and over
/// (messages and downward crossings a fraction, so that entries differ).
pub fn map_of(grid: [u16; 3], values: &[u64]) -> CostMap {
    let mut map = CostMap::new(grid);
    let mut v = values.iter().cycle().copied();
    for i in 0..map.compute.len() {
        map.compute[i] = v.next().unwrap_or(0);
        map.messages[i] = v.next().unwrap_or(0) / 4;
        for a in 0..3 {
            map.up[a][i] = v.next().unwrap_or(0);
            map.down[a][i] = v.next().unwrap_or(0) / 2;
        }
    }
    map
}

/// Cuts of `len` cubes into `parts` non-empty parts, placed by `seed`.
pub fn cuts(len: u16, parts: u16, seed: &[u16]) -> Vec<u16> {
    let mut c = vec![0u16];
    for i in 1..parts {
        let least = c[usize::from(i) - 1] + 1;
        let most = len - (parts - i);
        let pick = seed.get(usize::from(i)).copied().unwrap_or(0) % (most - least + 1);
        c.push(least + pick);
    }
    c.push(len);
    c
}

/// A partition of `grid` over `array` (no larger) along driving axis `d`,
/// every cut placed by `seeds`; its slabs cut their own columns and its rows
/// their own cuts where `staggered` says.
pub fn partition_of(
    grid: [u16; 3],
    array: [u16; 3],
    d: u8,
    seeds: &[Vec<u16>],
    (slabs, rows): (bool, bool),
) -> Partition {
    let mut p = Partition::even(grid, array, d).expect("an array no larger than the grid");
    let mut seed = seeds.iter().cycle().map(Vec::as_slice);
    let mut next = || seed.next().unwrap_or(&[]);
    for a in 0..3 {
        p.cuts[a] = cuts(grid[a], array[a], next());
    }
    let [s, c] = p.routed_axes();
    if slabs {
        p.slab_cuts = Some((0..array[s]).map(|_| cuts(grid[c], array[c], next())).collect());
    }
    let du = usize::from(d);
    if rows {
        let count = p.len() / usize::from(array[du]);
        p.row_cuts = Some((0..count).map(|_| cuts(grid[du], array[du], next())).collect());
    }
    p
}
