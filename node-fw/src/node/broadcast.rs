//! What the host broadcasts: the scene (its header, this node's assignment,
//! the spheres that touch its box, the lights), the start of a frame, and a
//! new session's reset.

use link_proto::{
    Assign, ErrorCode, LightMsg, MAX_DEPTH, MapLoad, OccupancyMsg, RenderStart, SceneEnd, SceneHeader, Site,
    SphereMsg,
};

use crate::cube_box::CubeBox;
use crate::error::{Error, Field};
use crate::geometry::{Grid, Point};
use crate::link::Port;
use crate::load::{IntervalClock, LoadMeter};
use crate::pool::class_bound;
use crate::slide::SlideState;
use crate::sphere::Sphere;

use super::initial_rays::scatter_stride;
use super::initial_rays::tile_pixels;
use super::{MAX_LIGHTS, NO_HEADER, Node, Phase, Totals};

impl<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> Node<S, R, C, P, O> {
    /// Back to the state of a fresh start, in place (a node is too large to
    /// build anew on a board's stack), saying hello again.
    pub(super) fn start_over(&mut self) {
        self.phase = Phase::Idle;
        self.header = NO_HEADER;
        self.grid = Grid::UNIT;
        self.assign = None;
        self.region.clear();
        self.occupancy.clear();
        self.lights.clear();
        self.spheres_seen = 0;
        self.render = None;
        self.cursor = 0;
        self.pool.clear();
        self.retiring = None;
        for n in &mut self.ports {
            n.forget_rays();
            n.present = false;
            (n.ends_seen, n.end_due) = (0, false);
        }
        self.frames_ended = 0;
        self.hello_due = true;
        // A new host session learns the cabling afresh (the cables stay).
        for n in &mut self.ports {
            n.note_due = n.peer.is_some();
        }
        self.error_due = None;
        self.load_due = None;
        self.meter = LoadMeter::new();
        self.totals = Totals::default();
        self.balance = None;
        self.intervals = IntervalClock::idle();
        self.slide = SlideState::new();
        self.control.clear();
    }

    /// A new scene: its header checked, whatever the last one left cleared.
    pub(super) fn begin_scene(&mut self, header: SceneHeader) {
        // Deeper, a pixel's credit could split to nothing (see `credit`).
        if header.max_depth > MAX_DEPTH {
            return self.fail_with(Error::OutOfRange(Field::Depth));
        }
        match Grid::new(header.grid) {
            Ok(grid) => {
                match header.map {
                    MapLoad::Sent => self.occupancy.begin(&grid),
                    MapLoad::Kept => {
                        if self.occupancy.keep(&grid).is_err() {
                            return self.fail_at(ErrorCode::Unexpected, 0, Site::KeptMapNotHeld);
                        }
                    }
                }
                self.header = header;
                self.grid = grid;
                self.assign = None;
                self.region.clear();
                self.lights.clear();
                self.spheres_seen = 0;
                self.render = None;
                self.pool.clear();
                self.retiring = None;
                // Grants we hold stand unless a frame is cut short: after a
                // frame's end they are void already (a neighbour's end note
                // voids its grants) or a neighbour that started the next
                // frame before our scene came gave them, and would wait for
                // their use all frame.
                if self.phase == Phase::Rendering {
                    for n in &mut self.ports {
                        (n.grants_held, n.grants_given, n.grants_due) = (0, 0, 0);
                    }
                }
                self.phase = Phase::Loading;
            }
            Err(e) => self.fail_with(e),
        }
    }

    /// This node's place in the array and its box of the grid.
    pub(super) fn take_assignment(&mut self, a: Assign) {
        if self.phase != Phase::Loading || a.driving_axis > 2 {
            return self.fail_at(ErrorCode::Unexpected, 0, Site::AssignOutOfPhase);
        }
        let Some(id) = crate::wiring::index_of(a.coord, a.array) else {
            return self.fail_at(ErrorCode::Unexpected, 0, Site::AssignOutsideArray);
        };
        match self.region.assign(self.grid, CubeBox { lo: a.lo, hi: a.hi }) {
            Ok(()) => {
                // A board learns which node it is from its assignment.
                self.id = id;
                self.assign = Some(a);
                for (n, p) in self.ports.iter_mut().zip(Port::NEIGHBOURS) {
                    n.present = crate::wiring::neighbour_of(usize::from(id), p, a.array).is_some();
                }
            }
            Err(e) => self.fail_with(e),
        }
    }

    /// A broadcast sphere: kept if it touches the box, counted either way.
    pub(super) fn take_sphere(&mut self, s: SphereMsg) {
        if self.phase != Phase::Loading || self.assign.is_none() {
            return self.fail_at(ErrorCode::Unexpected, 0, Site::SphereOutOfPhase);
        }
        self.spheres_seen += 1;
        let sphere = Sphere::from_msg(&s, &self.grid);
        let sphere = sphere.and_then(|s| {
            if s.within(&self.grid) { Ok(s) } else { Err(Error::OutOfRange(crate::error::Field::Center)) }
        });
        match sphere.map(|sphere| self.region.insert(sphere)) {
            Ok(Ok(_)) => {}
            Ok(Err(rejected)) => self.fail_with(rejected.error),
            Err(e) => self.fail_with(e),
        }
    }

    /// A light; every node holds them all.
    pub(super) fn take_light(&mut self, l: LightMsg) {
        if self.phase != Phase::Loading {
            return self.fail_at(ErrorCode::Unexpected, 0, Site::LightOutOfPhase);
        }
        if Point::from_bits(l.position).is_err() {
            return self.fail(ErrorCode::OutOfRange, crate::error::Field::Origin as u32, 0);
        }
        if self.lights.push(l).is_err() {
            self.fail(ErrorCode::OutOfRange, MAX_LIGHTS as u32, 0);
        }
    }

    /// Part of the map of the grid's occupied cubes; every node gets all of
    /// it. The map is used only once complete, so the host may send it
    /// after the frame's start: it does not hold the first rays back.
    pub(super) fn take_occupancy(&mut self, m: &OccupancyMsg) {
        if !matches!(self.phase, Phase::Loading | Phase::Loaded | Phase::Rendering) {
            return self.fail_at(ErrorCode::Unexpected, 0, Site::OccupancyOutOfPhase);
        }
        if let Err(e) = self.occupancy.take(m, &self.grid) {
            self.fail_with(e);
        }
    }

    /// The scene is complete if the counts match what arrived.
    pub(super) fn end_scene(&mut self, end: SceneEnd) {
        let SceneEnd { spheres, lights, occupancy } = end;
        if self.phase != Phase::Loading || self.assign.is_none() {
            return self.fail_at(ErrorCode::Unexpected, 0, Site::SceneEndOutOfPhase);
        }
        if let Err(e) = self.occupancy.finish(occupancy) {
            return self.fail_with(e);
        }
        if spheres != self.spheres_seen {
            return self.fail(ErrorCode::SceneCount, spheres, self.spheres_seen);
        }
        if usize::from(lights) != self.lights.len() {
            return self.fail(ErrorCode::SceneCount, u32::from(lights), self.lights.len() as u32);
        }
        self.phase = Phase::Loaded;
    }

    /// A frame: the pool sized by class levels, the tile, the balancing.
    pub(super) fn start_render(&mut self, r: RenderStart) {
        let Some(assign) = self.assign.filter(|_| self.phase == Phase::Loaded) else {
            return self.fail_at(ErrorCode::Unexpected, 0, Site::RenderStartOutOfPhase);
        };
        let boundaries = assign.boundaries.when_sliding(r.balance.is_some());
        let top =
            class_bound(assign.array, self.header.max_depth, usize::from(assign.driving_axis), boundaries);
        if let Err(e) = self.pool.configure(top, r.level_depth, r.shared_slots) {
            return self.fail(ErrorCode::PoolCapacity, e.capacity, e.needed);
        }
        // The pool starts empty, with nothing set aside. Grants neighbours
        // gave us stand: they may have started first.
        for n in &mut self.ports {
            (n.grants_given, n.grants_due, n.outstanding) = (0, 0, 0);
        }
        self.render = Some(r);
        self.cursor = 0;
        self.stride = scatter_stride(tile_pixels(&r.tile));
        self.totals = Totals::default();
        let now = self.meter.last();
        self.meter.restart(now);
        self.balance = r.balance;
        self.intervals = r.balance.map_or(IntervalClock::idle(), |b| IntervalClock::new(now, b.interval));
        self.slide = SlideState::new();
        self.phase = Phase::Rendering;
        // Neighbours refused while we were loading may send now.
        self.slot_freed();
    }
}
