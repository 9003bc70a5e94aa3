//! A node's subregion: a box of unit cubes, the spheres that touch it, and the
//! walk of a ray through it.
//!
//! **Registration.** A sphere is listed in every closed unit cube that meets its
//! surface (exact integer test: the distance from the centre to the cube ranges
//! over `[d_min, d_max]`, and the surface meets the cube iff
//! `d_min <= r <= d_max`). Every hit point lies on a surface and in some closed
//! cube the walk visits, so a ray tests each sphere it can hit, including a
//! sphere that merely touches a cube face and one that contains the origin. A
//! sphere that touches several subregions is kept by each of their nodes.
//!
//! **Nearest hit.** The walk keeps the best `(t, id)` over all cubes and stops as
//! soon as `t_best <= t_exit` of the current cube (pbrt's rule): a nearer hit
//! would have to lie in a cube already visited. A hit whose point lies past the
//! cube is not rejected, which would lose hits whose rounded `t` falls just past
//! a boundary.
//!
//! **Mailbox.** Each walk gets a fresh stamp; a sphere listed in several cubes is
//! tested once per walk. Stamps wrap by clearing the mailbox.
//!
//! Storage is fixed at compile time: `S` spheres, `R` sphere references over all
//! cubes, `C` cubes in the box. A sphere that does not fit is handed back.

use crate::cube_box::CubeBox;
use crate::digital_line::DigitalLine;
use crate::error::{Error, Field};
use crate::geometry::{Grid, Line};
use crate::limits::Scalar;
use crate::sphere::{Hit, Sphere};
use heapless::Vec;

/// A sphere the subregion could not take, handed back with the reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rejected {
    /// The sphere.
    pub sphere: Sphere,
    /// Why it was not stored.
    pub error: Error,
}

/// What a walk looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Query {
    /// Sphere the ray leaves from; never hit (no self-intersection of secondary rays).
    pub ignore: Option<u16>,
    /// Only hits with `t < t_max` count (shadow rays: the light).
    pub t_max: Option<Scalar>,
    /// Stop at any hit (shadow rays) instead of the nearest.
    pub any_hit: bool,
}

/// How a walk through the subregion ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// The nearest hit along the ray.
    Hit(Hit),
    /// An any-hit query found a hit before `t_max`.
    Blocked,
    /// The walk reached `t_max` without a hit.
    Clear,
    /// The ray left the grid without a hit.
    LeftGrid,
    /// The ray's current cube belongs to another subregion; pass it on.
    Leave,
}

/// Work counted during walks, for the cost model and load reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TraceStats {
    /// Unit-cube steps taken.
    pub cube_steps: u32,
    /// Ray/sphere tests made.
    pub sphere_tests: u32,
    /// Of those, the tests whose line met the sphere ahead of its origin:
    /// the hit's depth was computed (a root and a division, several times a
    /// miss's cost).
    pub sphere_hits: u32,
}

impl TraceStats {
    /// The work counted since `before`, a copy of these stats taken earlier.
    pub fn since(&self, before: &TraceStats) -> TraceStats {
        TraceStats {
            cube_steps: self.cube_steps - before.cube_steps,
            sphere_tests: self.sphere_tests - before.sphere_tests,
            sphere_hits: self.sphere_hits - before.sphere_hits,
        }
    }
}

/// A box of unit cubes `[lo, hi)` with per-cube sphere lists.
#[derive(Debug, Clone)]
pub struct Subregion<const S: usize, const R: usize, const C: usize> {
    grid: Grid,
    /// Cubes whose sphere lists are kept (storage).
    bounds: CubeBox,
    /// Cubes this node traces in (within `bounds`; smaller while a slab arrives).
    owned: CubeBox,
    spheres: Vec<Sphere, S>,
    mailbox: [u32; S],
    stamp: u32,
    /// Start of each cube's list in `refs` (valid while `indexed`).
    cube_start: [u16; C],
    refs: [u16; R],
    ref_total: usize,
    indexed: bool,
}

impl<const S: usize, const R: usize, const C: usize> Default for Subregion<S, R, C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const S: usize, const R: usize, const C: usize> Subregion<S, R, C> {
    const FITS_U16: () = assert!(S <= u16::MAX as usize && R <= u16::MAX as usize, "S and R index with u16");

    /// An empty subregion of an empty box; [`Subregion::assign`] gives it one.
    pub const fn new() -> Self {
        let () = Self::FITS_U16;
        Self {
            grid: Grid::UNIT,
            bounds: CubeBox { lo: [0; 3], hi: [0; 3] },
            owned: CubeBox { lo: [0; 3], hi: [0; 3] },
            spheres: Vec::new(),
            mailbox: [0; S],
            stamp: 0,
            cube_start: [0; C],
            refs: [0; R],
            ref_total: 0,
            indexed: false,
        }
    }

    /// Makes this subregion what [`Subregion::new`] makes, in place: for
    /// storage that was not built by `new` (a board's node is zero-filled
    /// at boot), where a new one built on the stack and moved would take
    /// more stack than the board has.
    pub fn renew(&mut self) {
        self.grid = Grid::UNIT;
        self.bounds = CubeBox { lo: [0; 3], hi: [0; 3] };
        self.owned = self.bounds;
        self.spheres.clear();
        self.mailbox.fill(0);
        self.stamp = 0;
        self.cube_start.fill(0);
        self.refs.fill(0);
        self.ref_total = 0;
        self.indexed = false;
    }

    /// Takes the box `[lo, hi)` of `grid` and drops every sphere.
    pub fn assign(&mut self, grid: Grid, bounds: CubeBox) -> Result<(), Error> {
        let size = grid.size();
        let inside =
            (0..3).all(|a| at(&bounds.lo, a) < at(&bounds.hi, a) && at(&bounds.hi, a) <= at(&size, a));
        if !inside {
            return Err(Error::OutOfRange(Field::Subregion));
        }
        let cubes = bounds.volume();
        if cubes > C as u64 {
            return Err(Error::CubeCapacity {
                capacity: C as u32,
                needed: u32::try_from(cubes).unwrap_or(u32::MAX),
            });
        }
        self.grid = grid;
        self.bounds = bounds;
        self.owned = bounds;
        self.clear();
        Ok(())
    }

    /// Changes the storage box, keeping the spheres that touch it and listing them
    /// in its cubes. Fails without any change if the node cannot hold the result.
    pub fn set_storage(&mut self, bounds: CubeBox) -> Result<(), Error> {
        let cubes = bounds.volume();
        if cubes > C as u64 {
            let needed = u32::try_from(cubes).unwrap_or(u32::MAX);
            return Err(Error::CubeCapacity { capacity: C as u32, needed });
        }
        let mut total = 0usize;
        for s in &self.spheres {
            bounds.for_each_surface_cube(s, |_| total += 1);
        }
        if total > R {
            let needed = u32::try_from(total).unwrap_or(u32::MAX);
            return Err(Error::RefCapacity { capacity: R as u32, needed });
        }
        self.spheres.retain(|s| {
            let mut touches = false;
            bounds.for_each_surface_cube(s, |_| touches = true);
            touches
        });
        self.bounds = bounds;
        self.ref_total = total;
        self.indexed = false;
        Ok(())
    }

    /// Changes the box this node traces in (must lie within the storage box).
    pub fn set_owned(&mut self, owned: CubeBox) -> Result<(), Error> {
        let inside = (0..3)
            .all(|a| owned.lo.get(a) >= self.bounds.lo.get(a) && owned.hi.get(a) <= self.bounds.hi.get(a));
        if !inside || owned.volume() == 0 {
            return Err(Error::OutOfRange(Field::Subregion));
        }
        self.owned = owned;
        Ok(())
    }

    /// The box this node traces in.
    pub fn owned(&self) -> CubeBox {
        self.owned
    }

    /// Drops every sphere.
    pub fn clear(&mut self) {
        self.spheres.clear();
        self.ref_total = 0;
        self.indexed = false;
    }

    /// The storage box of cubes.
    pub fn bounds(&self) -> CubeBox {
        self.bounds
    }

    /// The grid the box lies in.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// The spheres kept.
    pub fn spheres(&self) -> &[Sphere] {
        &self.spheres
    }

    /// The kept sphere with scene id `id`.
    pub fn sphere(&self, id: u16) -> Option<&Sphere> {
        let at = self.spheres.binary_search_by_key(&id, Sphere::id).ok()?;
        self.spheres.get(at)
    }

    /// Whether a ray that ignores sphere `id` no longer needs to: this node
    /// holds the sphere, and a walk from `cell` along `dir` has every cube
    /// that lists it behind ([`crate::cube_box::leaves_behind`]). A node
    /// that does not hold it cannot tell, and keeps the ray as it is.
    pub fn left_behind(&self, id: u16, cell: [i32; 3], dir: [i32; 3]) -> bool {
        self.sphere(id).is_some_and(|s| crate::cube_box::leaves_behind(s, cell, dir))
    }

    /// Sphere references over all cubes.
    pub fn ref_count(&self) -> usize {
        self.ref_total
    }

    /// Whether `cell` lies in the box this node traces in.
    pub fn contains(&self, cell: [i32; 3]) -> bool {
        self.owned.index(cell).is_some()
    }

    /// Keeps `sphere` if it touches the box: `Ok(true)` kept, `Ok(false)` not ours.
    /// A sphere beyond capacity is handed back, never dropped.
    pub fn insert(&mut self, sphere: Sphere) -> Result<bool, Rejected> {
        let mut count = 0usize;
        self.bounds.for_each_surface_cube(&sphere, |_| count += 1);
        if count == 0 {
            return Ok(false);
        }
        if self.sphere(sphere.id()).is_some() {
            // Already kept (a slab's spheres may include ours).
            return Ok(true);
        }
        if self.spheres.is_full() {
            let error = Error::SphereCapacity { capacity: S as u32 };
            return Err(Rejected { sphere, error });
        }
        let total = self.ref_total + count;
        if total > R {
            let error =
                Error::RefCapacity { capacity: R as u32, needed: u32::try_from(total).unwrap_or(u32::MAX) };
            return Err(Rejected { sphere, error });
        }
        // Kept sorted by id, so a hit's sphere is found by binary search.
        let at = match self.spheres.binary_search_by_key(&sphere.id(), Sphere::id) {
            Ok(at) | Err(at) => at,
        };
        self.spheres
            .insert(at, sphere)
            .map_err(|sphere| Rejected { sphere, error: Error::SphereCapacity { capacity: S as u32 } })?;
        self.ref_total = total;
        self.indexed = false;
        Ok(true)
    }

    /// Walks `walk` through the box from its current cube, testing spheres, until
    /// the query is answered, the ray leaves the grid, or it leaves the box.
    pub fn trace(
        &mut self,
        line: &Line,
        walk: &mut DigitalLine,
        best: &mut Option<Hit>,
        query: &Query,
        stats: &mut TraceStats,
    ) -> Outcome {
        self.trace_observed(line, walk, best, query, stats, |_, _| {})
    }

    /// [`Subregion::trace`], calling `visit(cell, stats)` with each cube's own
    /// [`TraceStats`] (its tests and hits) for every cube
    /// walked (for cost maps; a no-op closure compiles away).
    pub fn trace_observed(
        &mut self,
        line: &Line,
        walk: &mut DigitalLine,
        best: &mut Option<Hit>,
        query: &Query,
        stats: &mut TraceStats,
        mut visit: impl FnMut([i32; 3], TraceStats),
    ) -> Outcome {
        self.ensure_index();
        let stamp = self.next_stamp();
        loop {
            let cell = walk.cell();
            let Some(cube) = self.bounds.index(cell).filter(|_| self.owned.index(cell).is_some()) else {
                return Outcome::Leave;
            };
            let before = *stats;
            let done = self.test_cube(cube, line, best, query, stamp, stats);
            visit(cell, stats.since(&before));
            if let Some(done) = done {
                return done;
            }
            if let Some(b) = best.filter(|b| walk.exits_at_or_after(line, b.t)) {
                return Outcome::Hit(b);
            }
            if query.t_max.is_some_and(|m| walk.exits_at_or_after(line, m)) {
                return Outcome::Clear;
            }
            walk.step();
            stats.cube_steps += 1;
            if !self.grid.contains(walk.cell()) {
                // Spheres lie inside the grid, so a hit still pending here is one
                // whose rounded t fell just past the grid's boundary.
                return best.map_or(Outcome::LeftGrid, Outcome::Hit);
            }
        }
    }

    /// Tests the spheres of one cube; `Some(Blocked)` ends an any-hit query.
    fn test_cube(
        &mut self,
        cube: usize,
        line: &Line,
        best: &mut Option<Hit>,
        query: &Query,
        stamp: u32,
        stats: &mut TraceStats,
    ) -> Option<Outcome> {
        let end = if (cube as u64) + 1 < self.bounds.volume() {
            usize::from(self.cube_start.get(cube + 1).copied().unwrap_or(0))
        } else {
            self.ref_total
        };
        let start = usize::from(self.cube_start.get(cube).copied().unwrap_or(0));
        for &index in self.refs.get(start..end).unwrap_or_default() {
            let index = usize::from(index);
            let (Some(sphere), Some(seen)) = (self.spheres.get(index), self.mailbox.get_mut(index)) else {
                continue;
            };
            if *seen == stamp || query.ignore == Some(sphere.id()) {
                continue;
            }
            *seen = stamp;
            stats.sphere_tests += 1;
            let Some(root) = sphere.intersect(line) else {
                continue;
            };
            stats.sphere_hits += 1;
            if query.t_max.is_some_and(|m| root.t >= m) {
                continue;
            }
            if query.any_hit {
                return Some(Outcome::Blocked);
            }
            let hit = Hit { t: root.t, sphere: sphere.id() };
            if best.is_none_or(|b| hit < b) {
                *best = Some(hit);
            }
        }
        None
    }

    fn next_stamp(&mut self) -> u32 {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.mailbox = [0; S];
            self.stamp = 1;
        }
        self.stamp
    }

    /// Builds the per-cube lists by counting sort, once after any change.
    /// Works in place: no stack copies of the tables.
    fn ensure_index(&mut self) {
        if self.indexed {
            return;
        }
        let bounds = self.bounds;
        let cubes = usize::try_from(bounds.volume()).unwrap_or(0);
        let start = &mut self.cube_start;
        start.iter_mut().take(cubes).for_each(|c| *c = 0);
        for s in &self.spheres {
            bounds.for_each_surface_cube(s, |k| bump(start, k, 1));
        }
        // Prefix sums give each cube's end; filling backwards turns ends into starts.
        let mut running = 0u16;
        for c in start.iter_mut().take(cubes) {
            running = running.wrapping_add(*c);
            *c = running;
        }
        let refs = &mut self.refs;
        for (i, s) in self.spheres.iter().enumerate() {
            bounds.for_each_surface_cube(s, |k| {
                bump(start, k, -1);
                if let Some(slot) = start.get(k).and_then(|&p| refs.get_mut(usize::from(p))) {
                    *slot = i as u16;
                }
            });
        }
        self.indexed = true;
    }
}

fn at(a: &[u16; 3], i: usize) -> u16 {
    a.get(i).copied().unwrap_or(0)
}

fn bump<const C: usize>(counts: &mut [u16; C], k: usize, delta: i16) {
    if let Some(c) = counts.get_mut(k) {
        *c = c.wrapping_add_signed(delta);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Direction, Point};
    use crate::sphere::Material;

    #[test]
    fn mailbox_stamp_wrap_clears_the_mailbox() {
        let grid = Grid::new([4; 3]).unwrap();
        let mut region: Subregion<4, 64, 64> = Subregion::new();
        region.assign(grid, CubeBox { lo: [0; 3], hi: [4; 3] }).unwrap();
        let center = Point::from_bits([2 << 16; 3]).unwrap();
        let sphere = Sphere::new(9, center, Scalar::from_num(0.5), Material::default(), &grid).unwrap();
        region.insert(sphere).unwrap();
        let origin = Point::from_bits([0, 2 << 16, 2 << 16]).unwrap();
        let line = Line::new(origin, Direction::from_bits([1 << 30, 0, 0]).unwrap());
        for start in [u32::MAX - 2, u32::MAX - 1, u32::MAX] {
            region.stamp = start;
            // A stale entry equal to the stamp after the wrap must not hide the sphere.
            region.mailbox = [1; 4];
            for _ in 0..3 {
                let mut walk = DigitalLine::enter(&line, &grid).unwrap();
                let (mut best, mut stats) = (None, TraceStats::default());
                let out = region.trace(&line, &mut walk, &mut best, &Query::default(), &mut stats);
                assert!(matches!(out, Outcome::Hit(h) if h.sphere == 9), "stamp {}: {out:?}", region.stamp);
                assert_eq!(stats.sphere_tests, 1);
            }
        }
    }
}
