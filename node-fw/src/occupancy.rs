//! Which cubes of the whole grid hold a sphere's surface: what lets a node
//! see that a ray leaving its box meets nothing more.
//!
//! A node holds only the spheres of its own box, so a ray that leaves it is
//! passed on, even when every cube left on its way out of the grid is
//! empty: the nodes behind would walk it through nothing and retire it as
//! it would have been retired here. Most rays end that way (a primary ray
//! that misses, a shadow ray that reaches its light), and each hop costs
//! both ends far more than walking a cube. So the host sends every node one
//! bit a cube, set where some sphere's surface touches it
//! ([`crate::cube_box::CubeBox::for_each_surface_cube`], the test that
//! fills the nodes' own cube lists), and a node walks a leaving ray on
//! through the empty cubes ([`Occupancy::walk_clear`]). If the ray reaches
//! the end of the grid or its `t_max` before a marked cube, the node
//! retires it; otherwise it passes it on from where it left, as without
//! the map. The image cannot change: an unmarked cube lists no sphere in
//! any partition, and the walk through it is the one the nodes behind
//! would make.
//!
//! A node keeps the map in `W` words. A grid of more cubes than `32 W` is
//! kept coarser: one bit for a block of `2^k` cubes a side, set if any of
//! its cubes is marked. A map that is not complete is not used.

use link_proto::{CUBES_PER_OCCUPANCY, OccupancyMsg};

use crate::digital_line::DigitalLine;
use crate::error::{Error, Field};
use crate::geometry::{Grid, Line};
use crate::limits::Scalar;
use crate::subregion::Outcome;

/// The marked cubes of a grid, at the resolution `W` words allow.
#[derive(Debug, Clone)]
pub struct Occupancy<const W: usize> {
    words: [u32; W],
    /// log2 of a block's side in cubes.
    shift: u32,
    /// Blocks along each axis.
    blocks: [u32; 3],
    /// The grid's size in cubes, as [`Occupancy::begin`] was given it.
    size: [u16; 3],
    /// Messages taken since the scene began.
    taken: u32,
    /// Messages the scene brings, once its `SceneEnd` has said.
    expected: Option<u32>,
    /// Complete, and so in use: kept, or every message `expected` taken.
    /// Held apart from them because [`Occupancy::is_clear`], a clear walk's
    /// every cube, reads it.
    ready: bool,
    /// Kept from the last scene: no message may change it.
    kept: bool,
}

impl<const W: usize> Default for Occupancy<W> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize> Occupancy<W> {
    /// An empty map, not in use.
    pub const fn new() -> Self {
        Self {
            words: [0; W],
            shift: 0,
            blocks: [0; 3],
            size: [0; 3],
            taken: 0,
            expected: None,
            ready: false,
            kept: false,
        }
    }

    /// A new scene's map of `grid`: nothing marked, not in use until every
    /// message [`Occupancy::finish`] counts has come (before it or after).
    pub fn begin(&mut self, grid: &Grid) {
        let size = grid.size().map(u32::from);
        let mut shift = 0;
        while blocks_of(size, shift).iter().map(|&b| u64::from(b)).product::<u64>() > (W as u64) * 32 {
            shift += 1;
        }
        self.clear();
        (self.shift, self.blocks, self.size) = (shift, blocks_of(size, shift), grid.size());
    }

    /// A new scene over `grid` that keeps this map ([`link_proto::MapLoad::Kept`]):
    /// an error unless the map is complete and of the same grid.
    pub fn keep(&mut self, grid: &Grid) -> Result<(), Error> {
        if !self.ready || self.size != grid.size() {
            return Err(Error::OutOfRange(Field::Occupancy));
        }
        (self.taken, self.expected, self.kept) = (0, None, true);
        Ok(())
    }

    /// Marks the cubes `m` marks; a message outside `grid` is an error.
    pub fn take(&mut self, m: &OccupancyMsg, grid: &Grid) -> Result<(), Error> {
        let [gx, gy, gz] = grid.size().map(u32::from);
        let cubes = gx * gy * gz;
        let more_than_said = self.expected.is_some_and(|e| self.taken >= e);
        if self.kept || more_than_said || !m.first.is_multiple_of(CUBES_PER_OCCUPANCY) || m.first >= cubes {
            return Err(Error::OutOfRange(Field::Occupancy));
        }
        if self.shift == 0 {
            self.take_words(m, cubes)?;
        } else {
            for (i, byte) in (0u32..).zip(m.bits) {
                for bit in (0..8).filter(|b| byte & (1 << b) != 0) {
                    let cube = m.first + 8 * i + bit;
                    if cube >= cubes {
                        return Err(Error::OutOfRange(Field::Occupancy));
                    }
                    self.mark([cube % gx, cube / gx % gy, cube / (gx * gy)]);
                }
            }
        }
        self.taken += 1;
        self.ready = self.expected == Some(self.taken);
        Ok(())
    }

    /// [`Occupancy::take`] where a bit is a cube: a block is a cube and is
    /// numbered as the message numbers it, so the message's 256 cubes are
    /// eight words of the map, ORed in whole. On the emulated Cortex-M3 a
    /// message with a quarter of its cubes marked (as the paper's scene
    /// marks them) takes 270 instructions so, and took 7 705 cube by cube
    /// (the `map_take` kernel of `scripts/firmware.sh`): 1e6 a node for a
    /// 32^3 grid's map, in a frame once the map follows its start.
    fn take_words(&mut self, m: &OccupancyMsg, cubes: u32) -> Result<(), Error> {
        let first_word = (m.first / 32) as usize;
        let mut start = m.first;
        for chunk in m.bits.chunks_exact(4) {
            let &[a, b, c, d] = chunk else { continue };
            let bits = u32::from_le_bytes([a, b, c, d]);
            // Cubes `start..start + 32`; none past the grid's last may be set.
            let past_the_grid = match cubes.saturating_sub(start) {
                0 => bits,
                n if n < 32 => bits >> n,
                _ => 0,
            };
            if past_the_grid != 0 {
                return Err(Error::OutOfRange(Field::Occupancy));
            }
            start += 32;
        }
        // Words the map lacks hold only cubes past the grid, checked clear.
        for (word, chunk) in self.words.iter_mut().skip(first_word).zip(m.bits.chunks_exact(4)) {
            if let &[a, b, c, d] = chunk {
                *word |= u32::from_le_bytes([a, b, c, d]);
            }
        }
        Ok(())
    }

    /// The scene's end says it brings `sent` messages of the map: an error
    /// if more came already, or any to a kept map. The map is in use once
    /// all have come, now or later (the host sends none when it has no map
    /// to give), or at once if it was kept.
    pub fn finish(&mut self, sent: u16) -> Result<(), Error> {
        let sent = u32::from(sent);
        if self.taken > sent || (self.kept && sent > 0) {
            return Err(Error::OutOfRange(Field::Occupancy));
        }
        self.expected = Some(sent);
        self.ready = self.kept || (sent > 0 && self.taken == sent);
        Ok(())
    }

    /// Forgets the map, in place: as [`Occupancy::new`] makes it, nothing
    /// known beyond the node's box.
    pub fn clear(&mut self) {
        self.words.iter_mut().for_each(|w| *w = 0);
        (self.shift, self.blocks, self.size) = (0, [0; 3], [0; 3]);
        (self.taken, self.expected, self.ready, self.kept) = (0, None, false, false);
    }

    /// Whether the map is in use.
    pub fn is_ready(&self) -> bool {
        self.ready
    }

    /// Whether `cell` is known to hold no sphere's surface.
    #[inline]
    pub fn is_clear(&self, cell: [i32; 3]) -> bool {
        // A negative coordinate wraps far past every block count.
        let Some(block) = self.block(cell.map(|c| c as u32)) else { return false };
        self.ready && self.words.get(block / 32).is_some_and(|w| w & (1 << (block % 32)) == 0)
    }

    /// Walks `walk` on from its cube while the cubes are clear, as a node
    /// holding them would walk a ray that has no hit: `Some(LeftGrid)` if it
    /// leaves the grid, `Some(Clear)` if it reaches `t_max`, `None` at the
    /// first cube that may hold a surface. Counts the steps taken.
    pub fn walk_clear(
        &self,
        line: &Line,
        walk: &mut DigitalLine,
        grid: &Grid,
        t_max: Option<Scalar>,
        steps: &mut u32,
    ) -> Option<Outcome> {
        if !self.ready || !near_the_end(line.dir(), walk.cell(), grid) {
            return None;
        }
        loop {
            if !self.is_clear(walk.cell()) {
                return None;
            }
            // The order of the nodes' own walk (`Subregion::trace`) through
            // a cube with nothing to test.
            if t_max.is_some_and(|m| walk.exits_at_or_after(line, m)) {
                return Some(Outcome::Clear);
            }
            walk.step();
            *steps += 1;
            if !grid.contains(walk.cell()) {
                return Some(Outcome::LeftGrid);
            }
        }
    }

    #[inline]
    fn block(&self, cell: [u32; 3]) -> Option<usize> {
        let [x, y, z] = cell.map(|c| c >> self.shift);
        let [bx, by, bz] = self.blocks;
        (x < bx && y < by && z < bz).then(|| ((z * by + y) * bx + x) as usize)
    }

    fn mark(&mut self, cell: [u32; 3]) {
        if let Some(block) = self.block(cell)
            && let Some(w) = self.words.get_mut(block / 32)
        {
            *w |= 1 << (block % 32);
        }
    }
}

/// The most cubes a ray is walked on beyond its node's box, roughly: a ray
/// further from the grid's end is passed on without looking. A clear path
/// saves every hop to the end, but the walk costs more than a walked cube
/// of the node's own ([`Occupancy::walk_clear`] tests the map as well) and
/// is wasted where a marked cube comes first, which far from the end it
/// almost always does. Measured on the paper's scene (1000 spheres, a
/// quarter of the cubes marked), 4x4x4: 12 saves the most.
pub const CLEAR_WALK_CUBES: u32 = 12;

/// Whether a ray along `dir` from `cell` leaves `grid` within about
/// [`CLEAR_WALK_CUBES`] cubes. It leaves through the first axis `a` to run
/// out of cubes, after about `r_a / |d_a|` units, crossing about
/// `sum_b |d_b|` cubes a unit: so within `K` cubes where, for some axis,
/// `r_a sum_b |d_b| <= K |d_a|`.
pub fn near_the_end(dir: [i32; 3], cell: [i32; 3], grid: &Grid) -> bool {
    // In units of 2^-20: |d_a| < 2^21, their sum < 2^23 and r_a < 2^8, so
    // no product reaches 2^32. A rough test needs no more.
    let d = dir.map(|c| c.unsigned_abs() >> 10);
    let sum: u32 = d.iter().sum();
    let axes = dir.iter().zip(cell).zip(grid.size()).zip(d);
    axes.into_iter().any(|(((&toward, c), n), da)| {
        let left = if toward > 0 { i32::from(n) - 1 - c } else { c };
        da != 0 && (left.clamp(0, 255) as u32) * sum <= CLEAR_WALK_CUBES * da
    })
}

fn blocks_of(size: [u32; 3], shift: u32) -> [u32; 3] {
    size.map(|s| s.div_ceil(1 << shift))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(first: u32, cubes: &[u32]) -> OccupancyMsg {
        let mut bits = [0u8; 32];
        for &c in cubes {
            bits[(c / 8) as usize] |= 1 << (c % 8);
        }
        OccupancyMsg { first, bits }
    }

    #[test]
    fn a_map_is_used_only_once_complete() {
        let grid = Grid::new([8, 8, 8]).unwrap();
        let mut map = Occupancy::<16>::new();
        map.begin(&grid);
        assert!(!map.is_clear([0, 0, 0]), "nothing is clear before the map is complete");
        map.take(&msg(0, &[1]), &grid).unwrap();
        map.take(&msg(256, &[]), &grid).unwrap();
        assert_eq!(map.finish(1), Err(Error::OutOfRange(Field::Occupancy)), "more than the scene said");
        map.begin(&grid);
        map.take(&msg(0, &[1]), &grid).unwrap();
        map.finish(2).unwrap();
        assert!(!map.is_clear([0, 0, 0]), "a message still to come");
        map.take(&msg(256, &[]), &grid).unwrap();
        assert!(map.is_clear([0, 0, 0]) && !map.is_clear([1, 0, 0]), "complete after the scene's end");
        assert_eq!(map.take(&msg(256, &[]), &grid), Err(Error::OutOfRange(Field::Occupancy)), "one too many");
        map.begin(&grid);
        map.take(&msg(0, &[1]), &grid).unwrap();
        map.take(&msg(256, &[]), &grid).unwrap();
        assert!(!map.is_clear([0, 0, 0]), "not in use before the scene says how many");
        map.finish(2).unwrap();
        assert!(map.is_clear([0, 0, 0]) && !map.is_clear([1, 0, 0]));
        assert!(!map.is_clear([-1, 0, 0]) && !map.is_clear([8, 0, 0]), "outside the grid is never clear");
        map.clear();
        assert!(!map.is_clear([0, 0, 0]));
    }

    /// Words ORed in whole mark what marking cube by cube marks, and refuse
    /// what it refuses: a cube past the grid's last.
    #[test]
    fn a_message_taken_a_word_at_a_time_marks_its_cubes() {
        extern crate std;
        use std::{vec, vec::Vec};
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for size in [[8, 8, 8], [7, 5, 9], [16, 16, 3], [1, 2, 150], [20, 20, 20]] {
            let grid = Grid::new(size).unwrap();
            let cubes: u32 = size.iter().map(|&s| u32::from(s)).product();
            let mut map = Occupancy::<256>::new();
            map.begin(&grid);
            assert_eq!(map.shift, 0, "{size:?}");
            let mut marked = vec![false; cubes as usize];
            for first in (0..cubes).step_by(256) {
                let set: Vec<u32> =
                    (0..256).filter(|_| next() % 4 == 0).filter(|&i| first + i < cubes).collect();
                set.iter().for_each(|&i| marked[(first + i) as usize] = true);
                map.take(&msg(first, &set), &grid).unwrap();
                let past = cubes - first;
                if past < 256 {
                    let mut bad = map.clone();
                    assert_eq!(
                        bad.take(&msg(first, &[past]), &grid),
                        Err(Error::OutOfRange(Field::Occupancy))
                    );
                    assert_eq!(
                        bad.take(&msg(first, &[255]), &grid),
                        Err(Error::OutOfRange(Field::Occupancy))
                    );
                }
            }
            map.finish(cubes.div_ceil(256) as u16).unwrap();
            for (cube, &m) in marked.iter().enumerate() {
                let c = cube as i32;
                let (gx, gy) = (i32::from(size[0]), i32::from(size[1]));
                let cell = [c % gx, c / gx % gy, c / (gx * gy)];
                assert_eq!(map.is_clear(cell), !m, "{size:?}: cube {cell:?}");
            }
        }
    }

    #[test]
    fn a_kept_map_stays_as_it_was_and_takes_no_message() {
        let grid = Grid::new([8, 8, 8]).unwrap();
        let mut map = Occupancy::<16>::new();
        assert_eq!(map.keep(&grid), Err(Error::OutOfRange(Field::Occupancy)), "no map to keep");
        map.begin(&grid);
        map.take(&msg(0, &[1]), &grid).unwrap();
        assert_eq!(map.keep(&grid), Err(Error::OutOfRange(Field::Occupancy)), "an incomplete map");
        map.begin(&grid);
        map.take(&msg(0, &[1]), &grid).unwrap();
        map.take(&msg(256, &[]), &grid).unwrap();
        map.finish(2).unwrap();
        let other = Grid::new([8, 8, 4]).unwrap();
        assert_eq!(map.keep(&other), Err(Error::OutOfRange(Field::Occupancy)), "another grid");
        map.keep(&grid).unwrap();
        assert_eq!(map.take(&msg(0, &[]), &grid), Err(Error::OutOfRange(Field::Occupancy)));
        map.keep(&grid).unwrap();
        assert_eq!(map.finish(1), Err(Error::OutOfRange(Field::Occupancy)), "a message where none may come");
        map.keep(&grid).unwrap();
        map.finish(0).unwrap();
        assert!(map.is_clear([0, 0, 0]) && !map.is_clear([1, 0, 0]), "the map is the one kept");
        // Kept again, and then a scene that brings its own.
        map.keep(&grid).unwrap();
        map.finish(0).unwrap();
        map.begin(&grid);
        map.take(&msg(0, &[0]), &grid).unwrap();
        map.take(&msg(256, &[]), &grid).unwrap();
        map.finish(2).unwrap();
        assert!(!map.is_clear([0, 0, 0]) && map.is_clear([1, 0, 0]), "a sent map replaces it");
    }

    #[test]
    fn a_grid_larger_than_the_map_is_kept_in_blocks() {
        // 8^3 = 512 cubes in 4 words = 128 bits: blocks of 2^3 cubes (64).
        let grid = Grid::new([8, 8, 8]).unwrap();
        let mut map = Occupancy::<4>::new();
        map.begin(&grid);
        // Cube (3, 2, 5): index (5 * 8 + 2) * 8 + 3 = 339, in the second message.
        map.take(&msg(0, &[]), &grid).unwrap();
        map.take(&msg(256, &[339 - 256]), &grid).unwrap();
        map.finish(2).unwrap();
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..8 {
                    let in_block = x / 2 == 1 && y / 2 == 1 && z / 2 == 2;
                    assert_eq!(map.is_clear([x, y, z]), !in_block, "({x}, {y}, {z})");
                }
            }
        }
    }

    #[test]
    fn a_message_outside_the_grid_is_refused() {
        let grid = Grid::new([4, 4, 4]).unwrap();
        let mut map = Occupancy::<2>::new();
        map.begin(&grid);
        assert!(map.take(&msg(256, &[]), &grid).is_err(), "starts past the grid");
        assert!(map.take(&msg(3, &[]), &grid).is_err(), "not a multiple of 256");
        assert!(map.take(&msg(0, &[64]), &grid).is_err(), "marks cube 64 of 64");
        map.take(&msg(0, &[63]), &grid).unwrap();
    }

    #[test]
    fn a_clear_walk_ends_where_the_grid_does_or_at_a_marked_cube() {
        let grid = Grid::new([32, 4, 4]).unwrap();
        let line = Line::new(
            crate::geometry::Point::from_bits([20 << 16 | 0x8000, 0x18000, 0x18000]).unwrap(),
            crate::geometry::Direction::from_bits([1 << 30, 0, 0]).unwrap(),
        );
        let walk_from = |map: &Occupancy<16>| {
            let mut walk = DigitalLine::enter(&line, &grid).unwrap();
            let mut steps = 0;
            (map.walk_clear(&line, &mut walk, &grid, None, &mut steps), steps)
        };
        let mut map = Occupancy::<16>::new();
        map.begin(&grid);
        map.take(&msg(0, &[]), &grid).unwrap();
        map.finish(1).unwrap();
        // From cube 20 along +x: 11 steps to cube 31, the 12th leaves.
        assert_eq!(walk_from(&map), (Some(Outcome::LeftGrid), 12));
        // Cube (27, 1, 1) marked: index (1 * 4 + 1) * 32 + 27 = 187.
        map.begin(&grid);
        map.take(&msg(0, &[187]), &grid).unwrap();
        map.finish(1).unwrap();
        assert_eq!(walk_from(&map), (None, 7));
    }
}
