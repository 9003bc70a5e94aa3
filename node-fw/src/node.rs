//! The node: a sans-IO state machine over [`Links`].
//!
//! The caller passes the time and the links in ([`Node::poll`]); the node never
//! reads a clock, so the in-memory board, emulated boards and real boards all
//! run this same code, and tests are deterministic.
//!
//! Conversation: the host sends `SceneBegin`, `Assign`, every `Sphere` and
//! `Light`, `SceneEnd`, then `RenderStart`. The node creates the initial rays of
//! its tile, traces rays through its subregion, passes rays on to neighbours
//! with their exact state, shades hits, and retires finished rays to the host
//! with their pixel contribution and credit. `Finish` ends the frame; the node
//! answers with its load report.
//!
//! **Passing a ray on** never blocks a receiver: a node always takes a ray off
//! the link and admits it into its pool or refuses it ([`RayReply`]). The sender
//! keeps the ray until it is admitted and retries after the receiver's
//! [`Message::Space`]. With the class-levelled pool ([`crate::pool`]) this is
//! deadlock-free and loses nothing, whatever the queue depths.

use heapless::{Deque, Vec};
use link_proto::{
    Assign, Balance, Capacity, ErrorCode, ErrorReport, Hello, HitMsg, LightMsg, LoadReport, Message,
    PROTOCOL_VERSION, RayKind, RayMsg, RayReply, RenderStart, Retire, SceneHeader, SlideDone, SlideOffer,
    SlidePolicy, SlideRefusal, SlideReply, SphereMsg,
};

use crate::camera::{primary_line, primary_ray};
use crate::cube_box::CubeBox;
use crate::digital_line::DigitalLine;
use crate::error::Error;
use crate::geometry::{Direction, Grid, Line, Point};
use crate::limits::Scalar;
use crate::link::{Links, Port};
use crate::load::{IntervalClock, Load, LoadMeter};
use crate::pool::{RayPool, Stage, class_bound};
use crate::route;
use crate::shading::{Child, Scene, Surface};
use crate::slide::{self, Incoming, Outgoing, Side, SlideState};
use crate::sphere::{Hit, Sphere};
use crate::subregion::{Outcome, Query, Subregion, TraceStats};

/// Lights a node holds.
pub const MAX_LIGHTS: usize = 8;
/// A hit's evaluated child rays, each with its candidate number.
type Children = Vec<(u8, RayMsg), { MAX_LIGHTS + 1 }>;
/// Rays a node may have sent to one neighbour without a reply yet.
pub const MAX_OUTSTANDING: usize = 4;

/// Work done in one [`Node::poll`], for a cost model or a profiler.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Work {
    /// Unit-cube steps.
    pub cube_steps: u32,
    /// Ray/sphere tests.
    pub sphere_tests: u32,
    /// Ray walks through the subregion.
    pub traces: u32,
    /// Hits shaded (children evaluated).
    pub shades: u32,
    /// Initial rays created.
    pub created: u32,
    /// Messages received.
    pub received: u32,
    /// Messages sent.
    pub sent: u32,
    /// Of the messages received, rays (long messages; the rest are short).
    pub rays_received: u32,
    /// Of the messages sent, rays.
    pub rays_sent: u32,
}

impl Work {
    /// Whether anything was done.
    pub fn is_busy(&self) -> bool {
        *self != Work::default()
    }
}

/// Totals of the current frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Totals {
    /// Rays traced (walks through this subregion).
    pub rays: u32,
    /// Ray/sphere tests.
    pub sphere_tests: u32,
    /// Cube steps.
    pub cube_steps: u32,
    /// Rays refused for want of a pool slot.
    pub refused: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Waiting for a scene.
    Idle,
    /// Receiving a scene.
    Loading,
    /// Scene loaded, waiting for `RenderStart`.
    Loaded,
    /// Rendering a frame.
    Rendering,
    /// Stopped after reporting an error.
    Failed,
}

/// A node with `S` spheres, `R` sphere references, `C` cubes and `P` ray slots.
pub struct Node<const S: usize, const R: usize, const C: usize, const P: usize> {
    id: u16,
    phase: Phase,
    header: SceneHeader,
    grid: Grid,
    assign: Option<Assign>,
    region: Subregion<S, R, C>,
    lights: Vec<LightMsg, MAX_LIGHTS>,
    spheres_seen: u32,
    render: Option<RenderStart>,
    cursor: u32,
    /// Step through the tile's pixels (see [`scatter_stride`]).
    stride: u32,
    pool: RayPool<P>,
    outstanding: [u8; 6],
    replies: [Deque<RayReply, MAX_OUTSTANDING>; 6],
    refused: [bool; 6],
    space_due: [bool; 6],
    hello_due: bool,
    error_due: Option<ErrorReport>,
    load_due: Option<u32>,
    meter: LoadMeter,
    totals: Totals,
    balance: Option<Balance>,
    intervals: IntervalClock,
    slide: SlideState,
    /// Small control messages (loads, slide replies, notices) waiting for room.
    control: Deque<(Port, Message), 16>,
}

/// Interval of the final load report sent after `Finish`.
pub const FINAL_INTERVAL: u32 = u32::MAX;

const NO_HEADER: SceneHeader =
    SceneHeader { grid: [1; 3], ambient: [0; 3], background: [0; 3], max_depth: 0 };

impl<const S: usize, const R: usize, const C: usize, const P: usize> Node<S, R, C, P> {
    /// A node with index `id` (row-major over the array), waiting for a scene.
    pub const fn new(id: u16) -> Self {
        Self {
            id,
            phase: Phase::Idle,
            header: NO_HEADER,
            grid: Grid::UNIT,
            assign: None,
            region: Subregion::new(),
            lights: Vec::new(),
            spheres_seen: 0,
            render: None,
            cursor: 0,
            stride: 1,
            pool: RayPool::new(),
            outstanding: [0; 6],
            replies: [const { Deque::new() }; 6],
            refused: [false; 6],
            space_due: [false; 6],
            hello_due: true,
            error_due: None,
            load_due: None,
            meter: LoadMeter::new(),
            totals: Totals { rays: 0, sphere_tests: 0, cube_steps: 0, refused: 0 },
            balance: None,
            intervals: IntervalClock::idle(),
            slide: SlideState::new(),
            control: Deque::new(),
        }
    }

    /// The capacities this node was built with.
    pub const fn capacity() -> Capacity {
        Capacity { spheres: S as u32, refs: R as u32, cubes: C as u32, rays: P as u16 }
    }

    /// Node index.
    pub fn id(&self) -> u16 {
        self.id
    }

    /// The assignment taken from the host, once one arrived.
    pub fn assignment(&self) -> Option<Assign> {
        self.assign
    }

    /// The subregion (for inspection and tests).
    pub fn region(&self) -> &Subregion<S, R, C> {
        &self.region
    }

    /// Running and waiting time of the current frame.
    pub fn meter(&self) -> LoadMeter {
        self.meter
    }

    /// Work totals of the current frame.
    pub fn totals(&self) -> Totals {
        self.totals
    }

    /// Whether the node stopped after an error.
    pub fn failed(&self) -> bool {
        self.phase == Phase::Failed
    }

    /// Whether the node holds anything to do or send: rays, initial rays not yet
    /// created, replies, notices or reports. An idle node only waits for input.
    pub fn pending(&self) -> bool {
        !self.pool.is_empty()
            || self.creation_left()
            || self.hello_due
            || self.error_due.is_some()
            || self.load_due.is_some()
            || self.space_due.iter().any(|&s| s)
            || self.replies.iter().any(|q| !q.is_empty())
            || !self.control.is_empty()
            || [self.slide.outgoing.lo, self.slide.outgoing.hi].iter().flatten().any(|o| !o.done)
    }

    /// Tells the node it sat idle from `now` on (its last poll found nothing
    /// more to do): the time until the next poll is waiting, not running. A
    /// board that sleeps until input need not call it, since it polls once
    /// more before sleeping; a simulator that skips that poll must.
    pub fn idle(&mut self, now: u64) {
        if !self.pending() {
            self.meter.tick(now);
            self.meter.set_busy(false);
        }
    }

    /// Handles what has arrived, does one unit of work, and sends what it can.
    /// `now` is the caller's clock; it only splits time into running and waiting.
    pub fn poll<L: Links>(&mut self, now: u64, links: &mut L) -> Work {
        self.meter.tick(now);
        let mut work = Work::default();
        self.receive(links, &mut work);
        if self.phase == Phase::Rendering {
            self.balance_tick(now);
            self.compute(&mut work);
        }
        self.transmit(links, &mut work);
        self.meter.set_busy(work.is_busy());
        work
    }

    fn receive<L: Links>(&mut self, links: &mut L, work: &mut Work) {
        while let Some(port) = links.peer_restarted() {
            match port {
                // A new host session: whatever the old one set up is moot.
                Port::Host => self.start_over(),
                _ => self.fail(ErrorCode::PeerRestarted, port as u32, 0),
            }
        }
        for port in Port::ALL {
            while let Some(msg) = links.recv(port) {
                work.received += 1;
                if matches!(msg, Message::Ray(_)) {
                    work.rays_received += 1;
                }
                if self.phase != Phase::Failed {
                    self.handle(port, msg);
                }
            }
        }
    }

    fn fail(&mut self, code: ErrorCode, a: u32, b: u32) {
        if self.phase != Phase::Failed {
            self.error_due = Some(ErrorReport { node: self.id, code, a, b });
            self.phase = Phase::Failed;
        }
    }

    fn fail_with(&mut self, error: Error) {
        let r = error.report(self.id);
        self.fail(r.code, r.a, r.b);
    }

    fn handle(&mut self, port: Port, msg: Message) {
        match (port, msg) {
            (_, Message::Hello(h)) if h.version != PROTOCOL_VERSION => {
                self.fail(ErrorCode::Version, u32::from(h.version), u32::from(PROTOCOL_VERSION))
            }
            (_, Message::Hello(_)) => {}
            (Port::Host, Message::SceneBegin(header)) => self.begin_scene(header),
            (Port::Host, Message::Assign(a)) => self.take_assignment(a),
            (Port::Host, Message::Sphere(s)) => self.take_sphere(s),
            (Port::Host, Message::Light(l)) => self.take_light(l),
            (Port::Host, Message::SceneEnd(end)) => self.end_scene(end.spheres, end.lights),
            (Port::Host, Message::RenderStart(r)) => self.start_render(r),
            (Port::Host, Message::Finish(_)) => self.load_due = Some(FINAL_INTERVAL),
            (p, Message::Ray(ray)) if p != Port::Host => self.admit_ray(p, ray),
            (
                p,
                m @ (Message::Load(_)
                | Message::SlideRequest(_)
                | Message::SlideOffer(_)
                | Message::Sphere(_)
                | Message::SlideDone(_)
                | Message::SlideReply(_)),
            ) if p != Port::Host => match self.side_of(p) {
                Some(side) => self.handle_slide(p, side, m),
                None => self.fail(ErrorCode::Unexpected, port as u32, 3),
            },
            (p, Message::RayReply(r)) if p != Port::Host => self.take_reply(p, r),
            (p, Message::Space) if p != Port::Host => self.retry_refused(p),
            (port, msg) => self.fail(ErrorCode::Unexpected, port as u32, 100 + kind(&msg)),
        }
    }

    /// Back to the state of a fresh start, in place (a node is too large to
    /// build anew on a board's stack), saying hello again.
    fn start_over(&mut self) {
        self.phase = Phase::Idle;
        self.header = NO_HEADER;
        self.grid = Grid::UNIT;
        self.assign = None;
        self.region.clear();
        self.lights.clear();
        self.spheres_seen = 0;
        self.render = None;
        self.cursor = 0;
        self.pool.clear();
        self.outstanding = [0; 6];
        self.replies.iter_mut().for_each(Deque::clear);
        self.refused = [false; 6];
        self.space_due = [false; 6];
        self.hello_due = true;
        self.error_due = None;
        self.load_due = None;
        self.meter = LoadMeter::new();
        self.totals = Totals { rays: 0, sphere_tests: 0, cube_steps: 0, refused: 0 };
        self.balance = None;
        self.intervals = IntervalClock::idle();
        self.slide = SlideState::new();
        self.control.clear();
    }

    fn begin_scene(&mut self, header: SceneHeader) {
        match Grid::new(header.grid) {
            Ok(grid) => {
                self.header = header;
                self.grid = grid;
                self.assign = None;
                self.region.clear();
                self.lights.clear();
                self.spheres_seen = 0;
                self.render = None;
                self.pool.clear();
                self.phase = Phase::Loading;
            }
            Err(e) => self.fail_with(e),
        }
    }

    fn take_assignment(&mut self, a: Assign) {
        if self.phase != Phase::Loading || a.driving_axis > 2 {
            return self.fail(ErrorCode::Unexpected, 0, 0);
        }
        let Some(id) = crate::wiring::index_of(a.coord, a.array) else {
            return self.fail(ErrorCode::Unexpected, 0, 1);
        };
        match self.region.assign(self.grid, CubeBox { lo: a.lo, hi: a.hi }) {
            Ok(()) => {
                // A board learns which node it is from its assignment.
                self.id = id;
                self.assign = Some(a);
            }
            Err(e) => self.fail_with(e),
        }
    }

    fn take_sphere(&mut self, s: SphereMsg) {
        if self.phase != Phase::Loading || self.assign.is_none() {
            return self.fail(ErrorCode::Unexpected, 0, 0);
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

    fn take_light(&mut self, l: LightMsg) {
        if self.phase != Phase::Loading {
            return self.fail(ErrorCode::Unexpected, 0, 0);
        }
        if Point::from_bits(l.position).is_err() {
            return self.fail(ErrorCode::OutOfRange, crate::error::Field::Origin as u32, 0);
        }
        if self.lights.push(l).is_err() {
            self.fail(ErrorCode::OutOfRange, MAX_LIGHTS as u32, 0);
        }
    }

    fn end_scene(&mut self, spheres: u32, lights: u8) {
        if self.phase != Phase::Loading || self.assign.is_none() {
            return self.fail(ErrorCode::Unexpected, 0, 0);
        }
        if spheres != self.spheres_seen {
            return self.fail(ErrorCode::SceneCount, spheres, self.spheres_seen);
        }
        if usize::from(lights) != self.lights.len() {
            return self.fail(ErrorCode::SceneCount, u32::from(lights), self.lights.len() as u32);
        }
        self.phase = Phase::Loaded;
    }

    fn start_render(&mut self, r: RenderStart) {
        let Some(assign) = self.assign.filter(|_| self.phase == Phase::Loaded) else {
            return self.fail(ErrorCode::Unexpected, 0, 0);
        };
        let boundaries = assign.boundaries.when_sliding(r.balance.is_some());
        let top =
            class_bound(assign.array, self.header.max_depth, usize::from(assign.driving_axis), boundaries);
        if let Err(e) = self.pool.configure(top, r.level_depth, r.shared_slots) {
            return self.fail(ErrorCode::PoolCapacity, e.capacity, e.needed);
        }
        self.render = Some(r);
        self.cursor = 0;
        self.stride = scatter_stride(tile_pixels(&r.tile));
        self.outstanding = [0; 6];
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

    fn admit_ray(&mut self, port: Port, ray: RayMsg) {
        if self.phase != Phase::Rendering {
            // A neighbour may start before the host's RenderStart reaches us (the
            // links are independent): refuse; our Space follows once we start.
            return self.reply_to_ray(port, ray.tag, false);
        }
        if ray.class > self.pool.top() {
            return self.fail(ErrorCode::ClassOverflow, u32::from(ray.class), u32::from(self.pool.top()));
        }
        let accepted = self.pool.admit(ray, Stage::Trace).is_ok();
        // Counted with `if`, not `u32::from(bool)`: see `transmit`.
        if !accepted {
            self.totals.refused += 1;
        }
        self.reply_to_ray(port, ray.tag, accepted);
    }

    fn reply_to_ray(&mut self, port: Port, tag: u16, accepted: bool) {
        let reply = RayReply { tag, accepted };
        let (Some(queue), Some(refused)) =
            (self.replies.get_mut(port.index()), self.refused.get_mut(port.index()))
        else {
            return;
        };
        *refused |= !accepted;
        if queue.push_back(reply).is_err() {
            // The neighbour exceeded MAX_OUTSTANDING: a protocol violation.
            self.fail(ErrorCode::Unexpected, port as u32, 1);
        }
    }

    fn take_reply(&mut self, port: Port, reply: RayReply) {
        let sent = self.pool.is_sent(reply.tag, port);
        if !sent {
            return self.fail(ErrorCode::Unexpected, port as u32, 2);
        }
        if let Some(n) = self.outstanding.get_mut(port.index()) {
            *n = n.saturating_sub(1);
        }
        if reply.accepted {
            self.pool.remove(reply.tag);
            self.slot_freed();
            // The neighbour had room: the next ray held back may have it too.
            self.retry_refused(port);
        } else {
            self.pool.set_stage(reply.tag, Stage::Refused(port));
        }
    }

    /// Sends again the one ray held back for `port` that the neighbour is
    /// likeliest to admit: the highest class (a class-`k` ray may take any free
    /// level up to `k`).
    ///
    /// One at a time, not all at once: a `Space` means one slot, so resending
    /// every held ray mostly bought refusals (each a ray and a reply on the
    /// link). Nothing waits for ever: while rays are held back for a port,
    /// either one of them is in flight (its acceptance retries the next) or the
    /// neighbour has refused us since its last `Space` (its next freed slot
    /// sends another).
    fn retry_refused(&mut self, port: Port) {
        if let Some(i) = self.pool.highest_refused(port) {
            self.pool.set_stage(i, Stage::Outbound(port));
        }
    }

    /// How a ray of `class` leaves through `port`: behind the rays held back
    /// for it if one of them has at least its class (the neighbour had no
    /// slot for that one, so none for this), else at once. A higher class must
    /// not wait: it may take levels the held ones cannot, and holding it back
    /// would break the class levels' guarantee of progress.
    fn leave_by(&self, port: Port, class: u16) -> Stage {
        if self.pool.refused_at_least(port, class) { Stage::Refused(port) } else { Stage::Outbound(port) }
    }

    /// A slot freed: tell every neighbour we refused that it may retry.
    fn slot_freed(&mut self) {
        for (refused, due) in self.refused.iter_mut().zip(self.space_due.iter_mut()) {
            if *refused {
                *due = true;
                *refused = false;
            }
        }
    }

    fn creation_left(&self) -> bool {
        self.phase == Phase::Rendering && self.render.is_some_and(|r| self.cursor < tile_pixels(&r.tile))
    }

    /// One piece of work: the ready ray of the lowest class, else a new
    /// initial ray. Low classes are early in their lives, so serving them
    /// first hands the nodes further on their work soonest: on 8x8x8 with
    /// spheres in the middle, serving the highest class first left nodes there
    /// half idle until late, for a makespan 1.5x the busiest node's time (1.28x
    /// this way). Admission alone keeps the pool deadlock-free; the order only
    /// decides when.
    fn compute(&mut self, work: &mut Work) {
        let ready = self.pool.lowest_ready(|slot| self.pool.can_admit(slot.ray.class.saturating_add(1)));
        if let Some(i) = ready {
            match self.pool.get(i).map(|s| s.stage()) {
                Some(Stage::Trace) => self.trace(i, work),
                Some(Stage::Shade { .. }) => self.shade(i, work),
                _ => {}
            }
        } else if self.creation_left() && self.pool.can_admit(0) {
            self.create_initial(work);
        }
    }

    fn scene(&self) -> Scene<'_> {
        Scene { header: &self.header, grid: &self.grid, lights: &self.lights }
    }

    fn line_of(ray: &RayMsg) -> Result<Line, Error> {
        Ok(Line::new(Point::from_bits(ray.origin)?, Direction::from_bits(ray.dir)?))
    }

    fn trace(&mut self, i: u16, work: &mut Work) {
        let Some(mut ray) = self.pool.get(i).map(|s| s.ray) else { return };
        let line = match Self::line_of(&ray) {
            Ok(line) => line,
            Err(_) => return self.fail(ErrorCode::BadRay, ray.pixel, 0),
        };
        let Ok(mut walk) = DigitalLine::resume(&line, ray.cell.map(i32::from)) else {
            return self.fail(ErrorCode::BadRay, ray.pixel, 1);
        };
        let carried = ray.best;
        let mut best = carried.map(|h| Hit { t: Scalar::from_bits(h.t), sphere: h.sphere.id });
        let query = Query {
            ignore: ray.ignore,
            t_max: ray.t_max.map(Scalar::from_bits),
            any_hit: ray.kind == RayKind::Shadow,
        };
        let mut stats = TraceStats::default();
        let mut spawned = Children::new();
        let outcome = self.region.trace(&line, &mut walk, &mut best, &query, &mut stats);
        work.traces += 1;
        work.cube_steps += stats.cube_steps;
        work.sphere_tests += stats.sphere_tests;
        self.totals.rays += 1;
        self.totals.cube_steps += stats.cube_steps;
        self.totals.sphere_tests += stats.sphere_tests;
        // A hit found here names a sphere this node holds; one carried in keeps
        // the sphere it came with.
        ray.best = match best {
            Some(h) if carried.is_none_or(|c| c.t != h.t.to_bits() || c.sphere.id != h.sphere) => {
                match self.region.sphere(h.sphere) {
                    Some(s) => Some(HitMsg { t: h.t.to_bits(), sphere: s.to_msg() }),
                    None => return self.fail(ErrorCode::BadRay, ray.pixel, 5),
                }
            }
            _ => carried,
        };
        let stage = match outcome {
            Outcome::Leave => {
                ray.cell = walk.cell().map(|c| c as u16);
                let driving = self.assign.map_or(0, |a| usize::from(a.driving_axis));
                match route::toward(&self.region.owned(), walk.cell(), driving) {
                    Some(port) => self.leave_by(port, ray.class),
                    None => return self.fail(ErrorCode::BadRay, ray.pixel, 2),
                }
            }
            Outcome::LeftGrid | Outcome::Clear => {
                let rgb =
                    if ray.kind == RayKind::Shadow { ray.weight } else { self.scene().background(&ray) };
                Stage::Retire(retire(&ray, rgb, ray.credit, 0))
            }
            Outcome::Blocked => Stage::Retire(retire(&ray, [0; 3], ray.credit, 0)),
            Outcome::Hit(_) => {
                work.shades += 1;
                match self.begin_shading(&ray, &line, &mut spawned) {
                    Some(stage) => stage,
                    None => return self.fail(ErrorCode::BadRay, ray.pixel, 3),
                }
            }
        };
        self.pool.set_ray(i, ray);
        self.pool.set_stage(i, stage);
        if let Stage::Shade { children, share, rgb, .. } = stage {
            self.spawn_evaluated(i, &ray, (children, share, rgb), &spawned);
        }
    }

    /// The sphere of a ray's best hit, from the ray itself.
    fn hit_sphere(&self, ray: &RayMsg) -> Option<(Scalar, Sphere)> {
        let hit = ray.best?;
        let sphere = Sphere::from_msg(&hit.sphere, &self.grid).ok()?;
        Some((Scalar::from_bits(hit.t), sphere))
    }

    /// Evaluates the children of a hit into `spawned` (each with its candidate
    /// number), counts them to split the credit, and folds the ambient term
    /// and any child resolved at once into the parent's contribution.
    fn begin_shading(&self, ray: &RayMsg, line: &Line, spawned: &mut Children) -> Option<Stage> {
        let (t, sphere) = self.hit_sphere(ray)?;
        let sphere = &sphere;
        let surface = Surface::at(line, t, sphere)?;
        let scene = self.scene();
        let mut rgb = scene.ambient(ray, sphere);
        for k in 0..scene.candidates() {
            match scene.child(ray, line, &surface, sphere, k) {
                Some(Child::Ray(child)) => spawned.push((k, child)).ok()?,
                Some(Child::Done(c)) => rgb = add3(rgb, c),
                None => {}
            }
        }
        let children = spawned.len() as u8;
        if children == 0 {
            return Some(Stage::Retire(retire(ray, rgb, ray.credit, 0)));
        }
        let share = ray.credit / (u64::from(children) + 1);
        Some(Stage::Shade { next: 0, children, share, rgb })
    }

    /// Admits the children `begin_shading` evaluated while the pool has room,
    /// so a hit is evaluated once; only children the pool refuses now are
    /// evaluated again later, by [`Self::shade`].
    fn spawn_evaluated(&mut self, i: u16, ray: &RayMsg, hit: (u8, u64, [u32; 3]), spawned: &Children) {
        let (children, share, rgb) = hit;
        let mut next = self.scene().candidates();
        for &(k, mut child) in spawned {
            child.credit = share;
            if self.pool.admit(child, Stage::Trace).is_err() {
                next = k;
                break;
            }
        }
        self.shaded_up_to(i, ray, Stage::Shade { next, children, share, rgb });
    }

    /// Records how far a hit's children are spawned: the parent retires with
    /// its own share once all are out.
    fn shaded_up_to(&mut self, i: u16, ray: &RayMsg, progress: Stage) {
        let Stage::Shade { next, children, share, rgb } = progress else { return };
        let stage = if next < self.scene().candidates() {
            progress
        } else {
            let own = ray.credit - u64::from(children) * share;
            Stage::Retire(retire(ray, rgb, own, children))
        };
        self.pool.set_stage(i, stage);
    }

    /// Spawns the rest of a hit's children, evaluated again, while the pool
    /// admits them; retires the parent once all are out.
    fn shade(&mut self, i: u16, work: &mut Work) {
        let Some(slot) = self.pool.get(i).copied() else { return };
        let Stage::Shade { mut next, children, share, rgb } = slot.stage() else { return };
        let ray = slot.ray;
        let Ok(line) = Self::line_of(&ray) else { return self.fail(ErrorCode::BadRay, ray.pixel, 4) };
        let Some((t, sphere)) = self.hit_sphere(&ray) else {
            return self.fail(ErrorCode::BadRay, ray.pixel, 5);
        };
        let Some(surface) = Surface::at(&line, t, &sphere) else {
            return self.fail(ErrorCode::BadRay, ray.pixel, 6);
        };
        work.shades += 1;
        let candidates = self.scene().candidates();
        while next < candidates {
            if let Some(Child::Ray(mut child)) = self.scene().child(&ray, &line, &surface, &sphere, next) {
                child.credit = share;
                if self.pool.admit(child, Stage::Trace).is_err() {
                    break;
                }
            }
            next += 1;
        }
        self.shaded_up_to(i, &ray, Stage::Shade { next, children, share, rgb });
    }

    fn create_initial(&mut self, work: &mut Work) {
        let Some(r) = self.render else { return };
        let [x0, y0, x1, _] = r.tile.map(u32::from);
        let width = x1.saturating_sub(x0).max(1);
        let pixels = u64::from(tile_pixels(&r.tile).max(1));
        // The cursor-th pixel of a scattered order (stride coprime to the
        // pixel count, so every pixel comes once); below u32 as `% pixels`.
        let k = u32::try_from(u64::from(self.cursor) * u64::from(self.stride) % pixels).unwrap_or(0);
        let (x, y) = (x0 + k % width, y0 + k / width);
        self.cursor += 1;
        work.created += 1;
        let Ok(line) = primary_line(&r.camera, x as u16, y as u16) else {
            return self.fail(ErrorCode::OutOfRange, crate::error::Field::Direction as u32, 0);
        };
        let mut ray = primary_ray(&line, y * u32::from(r.size[0]) + x, r.credit);
        let stage = match DigitalLine::enter(&line, &self.grid) {
            Some(walk) => {
                ray.cell = walk.cell().map(|c| c as u16);
                Stage::Trace
            }
            None => Stage::Retire(retire(&ray, self.scene().background(&ray), ray.credit, 0)),
        };
        if self.pool.admit(ray, stage).is_err() {
            // can_admit(0) was checked: unreachable, but never lose the ray.
            self.cursor -= 1;
        }
    }

    fn driving_axis(&self) -> usize {
        self.assign.map_or(0, |a| usize::from(a.driving_axis))
    }

    /// The side a driving-axis port faces, `None` for other ports.
    fn side_of(&self, port: Port) -> Option<Side> {
        let d = self.driving_axis();
        match port {
            p if p == Port::toward(d, true) => Some(Side::Hi),
            p if p == Port::toward(d, false) => Some(Side::Lo),
            _ => None,
        }
    }

    fn has_neighbour(&self, side: Side) -> bool {
        let d = self.driving_axis();
        self.assign.is_some_and(|a| {
            let (c, n) = (a.coord.get(d).copied().unwrap_or(0), a.array.get(d).copied().unwrap_or(1));
            match side {
                Side::Lo => c > 0,
                Side::Hi => c + 1 < n,
            }
        })
    }

    /// Queues a control message; loads beyond half the queue are dropped (a
    /// newer one follows), everything else always fits (at most one per side).
    fn queue_control(&mut self, port: Port, msg: Message) {
        let is_load = matches!(msg, Message::Load(_));
        if is_load && self.control.len() >= self.control.capacity() / 2 {
            return;
        }
        if self.control.push_back((port, msg)).is_err() {
            self.fail(ErrorCode::Unexpected, port as u32, 9);
        }
    }

    /// Ends load intervals: reports them and decides this node's high boundary.
    fn balance_tick(&mut self, now: u64) {
        let Some((k, load)) = self.intervals.due(now, &self.meter) else { return };
        self.slide.own_load = Some((k, load));
        let report = LoadReport {
            node: self.id,
            interval: k,
            running: load.running,
            waiting: load.waiting,
            rays: self.totals.rays,
            sphere_tests: self.totals.sphere_tests,
            cube_steps: self.totals.cube_steps,
            refused: self.totals.refused,
            extent: {
                let (lo, hi) = self.extent_after_giving();
                hi.saturating_sub(lo)
            },
        };
        self.queue_control(Port::Host, Message::Load(report));
        if self.has_neighbour(Side::Lo) {
            self.queue_control(Port::toward(self.driving_axis(), false), Message::Load(report));
        }
        self.decide();
    }

    /// The paper's rule for the boundary on this node's high side: if one load is
    /// lower and under the threshold, the boundary slides one step toward the busier node.
    fn decide(&mut self) {
        let (Some(balance), Some((k, own))) = (self.balance, self.slide.own_load) else { return };
        let Some((kn, theirs, their_extent)) = self.slide.neighbour_load[Side::Hi] else { return };
        if k != kn || self.slide.busy(Side::Hi) || !self.has_neighbour(Side::Hi) {
            return;
        }
        self.slide.neighbour_load[Side::Hi] = None;
        let d = self.driving_axis();
        let (lo, hi) = self.extent_after_giving();
        let own_extent = hi.saturating_sub(lo);
        let (take, give) = match balance.policy {
            SlidePolicy::Paper => {
                let step = balance.step.max(1);
                let take = own.lighter_than(&theirs) && own.under(balance.threshold);
                let give = theirs.lighter_than(&own) && theirs.under(balance.threshold);
                (take.then_some(step), give.then_some(step))
            }
            SlidePolicy::Proportional { gamma, deadband } => {
                // A boundary that just moved holds still while its slab is in
                // transit, then decides on both running times averaged over the
                // intervals since (see `slide::average`): one interval is a
                // handful of shaded hits, too noisy to act on alone.
                if self.slide.hold > 0 {
                    self.slide.hold -= 1;
                    return;
                }
                let n = (self.slide.samples + 1).min(slide::AVERAGE_WINDOW);
                let mine = slide::average(self.slide.smoothed.lo, own.running, n);
                let yours = slide::average(self.slide.smoothed.hi, theirs.running, n);
                self.slide.smoothed = slide::PerSide { lo: mine, hi: yours };
                self.slide.samples = n;
                if n < slide::MIN_SAMPLES {
                    return;
                }
                let take = slide::proportional_shift(mine, yours, own_extent, their_extent, gamma, deadband);
                let give = slide::proportional_shift(yours, mine, their_extent, own_extent, gamma, deadband);
                if take.is_some() || give.is_some() {
                    self.slide.hold = 2;
                    self.slide.samples = 0;
                }
                (take, give)
            }
        };
        if let Some(step) = take {
            let offer = SlideOffer { interval: k, boundary: hi.saturating_add(step) };
            self.slide.requested[Side::Hi] = true;
            self.queue_control(Port::toward(d, true), Message::SlideRequest(offer));
        } else if let Some(step) = give.filter(|&s| hi > lo + s) {
            self.start_giving(Side::Hi, hi - step);
        }
    }

    /// The node's extent along the driving axis once the slabs it is giving are gone.
    fn extent_after_giving(&self) -> (u16, u16) {
        let d = self.driving_axis();
        let owned = self.region.owned();
        let lo = self.slide.outgoing[Side::Lo].map_or(owned.lo.get(d).copied().unwrap_or(0), |o| o.boundary);
        let hi = self.slide.outgoing[Side::Hi].map_or(owned.hi.get(d).copied().unwrap_or(0), |o| o.boundary);
        (lo, hi)
    }

    fn start_giving(&mut self, side: Side, boundary: u16) {
        self.slide.outgoing[side] =
            Some(Outgoing { boundary, offered: false, next_id: 0, sent: 0, done: false });
    }

    fn handle_slide(&mut self, port: Port, side: Side, msg: Message) {
        let (lo, hi) = self.extent_after_giving();
        match msg {
            Message::Load(l) => {
                self.slide.neighbour_load[side] =
                    Some((l.interval, Load { running: l.running, waiting: l.waiting }, l.extent));
                self.decide();
            }
            Message::SlideRequest(o) => {
                // The neighbour is lighter and asks for our slab on this side.
                let keeps_a_layer = match side {
                    Side::Lo => o.boundary > lo && o.boundary < hi,
                    Side::Hi => o.boundary < hi && o.boundary > lo,
                };
                let refused = if self.slide.busy(side) {
                    Some(SlideRefusal::Busy)
                } else if !keeps_a_layer {
                    Some(SlideRefusal::Empty)
                } else {
                    None
                };
                match refused {
                    Some(r) => self.queue_control(
                        port,
                        Message::SlideReply(SlideReply { boundary: o.boundary, refused: Some(r) }),
                    ),
                    None => self.start_giving(side, o.boundary),
                }
            }
            Message::SlideOffer(o) => self.begin_receiving(port, side, o.boundary),
            Message::Sphere(s) => self.receive_slab_sphere(side, s),
            Message::SlideDone(done) => self.finish_receiving(port, side, done),
            Message::SlideReply(r) => self.slide_answered(side, r),
            _ => self.fail(ErrorCode::Unexpected, port as u32, 4),
        }
    }

    fn begin_receiving(&mut self, port: Port, side: Side, boundary: u16) {
        if self.slide.incoming[side].is_some() || self.slide.outgoing[side].is_some() {
            return self.fail(ErrorCode::Unexpected, port as u32, 5);
        }
        self.slide.requested[side] = false;
        let d = self.driving_axis();
        let old_storage = self.region.bounds();
        let grown = slide::with_face(old_storage, d, side, boundary);
        let failed = self.region.set_storage(grown).err();
        self.slide.incoming[side] = Some(Incoming { boundary, old_storage, received: 0, failed });
    }

    fn receive_slab_sphere(&mut self, side: Side, s: SphereMsg) {
        let Some(mut incoming) = self.slide.incoming[side] else {
            return self.fail(ErrorCode::Unexpected, 0, 6);
        };
        incoming.received += 1;
        if incoming.failed.is_none() {
            let sphere = Sphere::from_msg(&s, &self.grid);
            let inserted = match sphere {
                Ok(sphere) => self.region.insert(sphere).map(|_| ()).map_err(|r| r.error),
                Err(e) => Err(e),
            };
            if let Err(e) = inserted {
                incoming.failed = Some(e);
                // Shrinking this side back always fits: it only drops the slab's spheres.
                let d = self.driving_axis();
                let face = match side {
                    Side::Lo => incoming.old_storage.lo.get(d),
                    Side::Hi => incoming.old_storage.hi.get(d),
                };
                let back = slide::with_face(self.region.bounds(), d, side, face.copied().unwrap_or(0));
                if let Err(e) = self.region.set_storage(back) {
                    self.fail_with(e);
                }
            }
        }
        self.slide.incoming[side] = Some(incoming);
    }

    fn finish_receiving(&mut self, port: Port, side: Side, done: SlideDone) {
        let Some(incoming) = self.slide.incoming[side].take() else {
            return self.fail(ErrorCode::Unexpected, port as u32, 7);
        };
        if incoming.received != done.spheres {
            return self.fail(ErrorCode::SceneCount, done.spheres, incoming.received);
        }
        let d = self.driving_axis();
        let owned = slide::with_face(self.region.owned(), d, side, incoming.boundary);
        let outcome = match incoming.failed {
            None => self.region.set_owned(owned),
            Some(e) => Err(e),
        };
        let refused = outcome.is_err().then_some(SlideRefusal::Capacity);
        let reply = SlideReply { boundary: incoming.boundary, refused };
        self.queue_control(port, Message::SlideReply(reply));
        if refused.is_some() {
            self.slide.refused += 1;
            self.queue_control(Port::Host, Message::SlideReply(reply));
        } else {
            self.slide.committed += 1;
            let note = SlideDone { boundary: incoming.boundary, spheres: done.spheres };
            self.queue_control(Port::Host, Message::SlideDone(note));
        }
    }

    fn slide_answered(&mut self, side: Side, reply: SlideReply) {
        if let Some(out) = self.slide.outgoing[side].filter(|o| o.done) {
            self.slide.outgoing[side] = None;
            if reply.refused.is_none() {
                let d = self.driving_axis();
                let owned = slide::with_face(self.region.owned(), d, side, out.boundary);
                let storage = slide::with_face(self.region.bounds(), d, side, out.boundary);
                if let Err(e) = self.region.set_owned(owned).and_then(|()| self.region.set_storage(storage)) {
                    self.fail_with(e);
                }
            }
        } else if self.slide.requested[side] {
            self.slide.requested[side] = false;
        } else {
            self.fail(ErrorCode::Unexpected, side as u32, 8);
        }
    }

    /// Sends the offer, the spheres and the end of every slab being given, as
    /// far as the links take them.
    fn stream_slabs<L: Links>(
        &mut self,
        links: &mut L,
        send: &mut impl FnMut(&mut L, Port, Message) -> bool,
    ) {
        let d = self.driving_axis();
        for side in [Side::Lo, Side::Hi] {
            let Some(mut out) = self.slide.outgoing[side].filter(|o| !o.done) else { continue };
            let port = Port::toward(d, side == Side::Hi);
            // Control messages for this neighbour (a reply to its last slab)
            // go first: the queue may be stuck behind a message to another port.
            if self.control.iter().any(|(p, _)| *p == port) {
                continue;
            }
            if !out.offered {
                out.offered = send(
                    links,
                    port,
                    Message::SlideOffer(SlideOffer { interval: 0, boundary: out.boundary }),
                );
            }
            let slab = slide::slab(self.region.owned(), d, side, out.boundary);
            let mut blocked = !out.offered;
            while !blocked {
                let spheres = self.region.spheres();
                let at = spheres.partition_point(|s| u32::from(s.id()) < out.next_id);
                let Some(sphere) = spheres.get(at).copied() else { break };
                let mut touches = false;
                slab.for_each_surface_cube(&sphere, |_| touches = true);
                if touches && !send(links, port, Message::Sphere(sphere.to_msg())) {
                    blocked = true;
                } else {
                    if touches {
                        out.sent += 1;
                    }
                    out.next_id = u32::from(sphere.id()) + 1;
                }
            }
            if !blocked {
                out.done = send(
                    links,
                    port,
                    Message::SlideDone(SlideDone { boundary: out.boundary, spheres: out.sent }),
                );
            }
            self.slide.outgoing[side] = Some(out);
        }
    }

    fn transmit<L: Links>(&mut self, links: &mut L, work: &mut Work) {
        let mut send = |links: &mut L, port: Port, msg: Message| {
            let ray = matches!(msg, Message::Ray(_));
            let ok = links.try_send(port, msg).is_ok();
            // Not `work.sent += u32::from(ok)`: rustc 1.95 at opt-level >= 2
            // drops the increment when the same bool is branched on after
            // inlining (rust-lang/rust#158206, SimplifyComparisonIntegral), and
            // release builds undercounted sends. The fuzz tests check the count.
            if ok {
                work.sent += 1;
                if ray {
                    work.rays_sent += 1;
                }
            }
            ok
        };
        if self.hello_due {
            let hello = Hello { version: PROTOCOL_VERSION, node: self.id, capacity: Self::capacity() };
            self.hello_due = !send(links, Port::Host, Message::Hello(hello));
        }
        if let Some(e) = self.error_due
            && send(links, Port::Host, Message::Error(e))
        {
            self.error_due = None;
        }
        for port in Port::NEIGHBOURS {
            let p = port.index();
            while let Some(&reply) = self.replies.get(p).and_then(|q| q.front()) {
                if !send(links, port, Message::RayReply(reply)) {
                    break;
                }
                if let Some(q) = self.replies.get_mut(p) {
                    q.pop_front();
                }
            }
            if let Some(due) = self.space_due.get_mut(p).filter(|due| **due) {
                *due = !send(links, port, Message::Space);
            }
        }
        self.send_rays(links, &mut send);
        while let Some((port, msg)) = self.control.front().cloned() {
            if !send(links, port, msg) {
                break;
            }
            self.control.pop_front();
        }
        self.stream_slabs(links, &mut send);
        if let Some(frame) = self.load_due {
            let report = LoadReport {
                node: self.id,
                interval: frame,
                running: self.meter.running,
                waiting: self.meter.waiting,
                rays: self.totals.rays,
                sphere_tests: self.totals.sphere_tests,
                cube_steps: self.totals.cube_steps,
                refused: self.totals.refused,
                extent: 0,
            };
            if send(links, Port::Host, Message::Load(report)) {
                self.load_due = None;
            }
        }
    }

    fn send_rays<L: Links>(&mut self, links: &mut L, send: &mut impl FnMut(&mut L, Port, Message) -> bool) {
        if !self.pool.any_leaving() {
            return;
        }
        // Ports that refused a message in this pass stay full for the rest of
        // it (room comes back only with what arrives), so nothing more is
        // built for them: a board offered every waiting ray on every poll.
        let mut full = [false; 7];
        // Ports with rays for them and room so far: once none is left, the
        // rest of the list cannot go either.
        let mut open = Port::ALL.iter().filter(|&&p| self.pool.leaving_by(p) > 0).count();
        // Marks a port full for the pass; whether none is left open.
        let close = |port_full: &mut bool, open: &mut usize| {
            *port_full = true;
            *open = open.saturating_sub(1);
            *open == 0
        };
        // Oldest first. A ray that goes drops out of the list and the next
        // takes its place, so `n` moves on only past a ray that stays.
        let mut n = 0;
        while let Some(i) = self.pool.leaving_at(n) {
            n += 1;
            // Whether the port can take it, before the ray is copied out.
            let Some(port) = self.pool.leaves_by(i) else { continue };
            let waiting =
                self.outstanding.get(port.index()).is_some_and(|&o| usize::from(o) >= MAX_OUTSTANDING);
            let Some(port_full) = full.get_mut(port.index()).filter(|f| !**f) else { continue };
            if waiting {
                // Replies come back only with what arrives: full for this pass.
                if close(port_full, &mut open) {
                    break;
                }
                continue;
            }
            let Some(stage) = self.pool.get(i).map(|s| s.stage()) else { continue };
            match stage {
                Stage::Retire(r) => {
                    if !send(links, Port::Host, Message::Retire(r)) {
                        if close(port_full, &mut open) {
                            break;
                        }
                        continue;
                    }
                    self.pool.remove(i);
                    self.slot_freed();
                    n -= 1;
                }
                Stage::Outbound(port) => {
                    let Some(mut ray) = self.pool.get(i).map(|s| s.ray) else { continue };
                    ray.class = ray.class.saturating_add(1);
                    ray.tag = i;
                    if !send(links, port, Message::Ray(ray)) {
                        if close(port_full, &mut open) {
                            break;
                        }
                        continue;
                    }
                    if let Some(out) = self.outstanding.get_mut(port.index()) {
                        *out += 1;
                    }
                    self.pool.set_stage(i, Stage::Sent(port));
                    n -= 1;
                }
                _ => {}
            }
        }
    }
}

/// A message's variant, for error reports (`b = 100 + kind`).
fn kind(msg: &Message) -> u32 {
    match msg {
        Message::Hello(_) => 0,
        Message::SceneBegin(_) => 1,
        Message::Sphere(_) => 2,
        Message::Light(_) => 3,
        Message::SceneEnd(_) => 4,
        Message::Assign(_) => 5,
        Message::RenderStart(_) => 6,
        Message::Ray(_) => 7,
        Message::Retire(_) => 8,
        Message::Load(_) => 9,
        Message::SlideOffer(_) => 10,
        Message::SlideReply(_) => 11,
        Message::SlideDone(_) => 12,
        Message::Finish(_) => 13,
        Message::Error(_) => 14,
        Message::Ack(_) => 15,
        Message::Nak(_) => 16,
        Message::RayReply(_) => 17,
        Message::Space => 18,
        Message::SlideRequest(_) => 19,
        Message::Sync(_) => 20,
        Message::SyncAck(_) => 21,
    }
}

fn retire(ray: &RayMsg, rgb: [u32; 3], credit: u64, spawned: u8) -> Retire {
    Retire { pixel: ray.pixel, rgb, credit, spawned }
}

fn add3(a: [u32; 3], b: [u32; 3]) -> [u32; 3] {
    [a[0].saturating_add(b[0]), a[1].saturating_add(b[1]), a[2].saturating_add(b[2])]
}

/// A stride through `n` pixels near `n / phi`, coprime to `n`: creating
/// initial rays in the order `k * stride mod n` spreads each stretch of time's
/// rays over the whole tile, so the work's distribution over the scene stays
/// the same all frame (scanline order sweeps it across the scene, and sliding
/// boundaries would chase it).
pub fn scatter_stride(n: u32) -> u32 {
    let gcd = |mut a: u64, mut b: u64| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let n64 = u64::from(n.max(1));
    // 0.6180339887 in Q16 is 40503.
    let mut s = ((n64 * 40503) >> 16).max(1);
    while gcd(s, n64) != 1 {
        s += 1;
    }
    // s < n unless n = 1, where any stride gives pixel 0.
    u32::try_from(s % n64).unwrap_or(1)
}

fn tile_pixels(tile: &[u16; 4]) -> u32 {
    let [x0, y0, x1, y1] = tile.map(u32::from);
    x1.saturating_sub(x0) * y1.saturating_sub(y0)
}

#[cfg(test)]
mod tests {
    use super::scatter_stride;

    #[test]
    fn the_scattered_order_visits_every_pixel_once() {
        for n in 1..=3000u32 {
            let s = u64::from(scatter_stride(n));
            let mut seen = [false; 3000];
            for k in 0..u64::from(n) {
                let p = (k * s % u64::from(n)) as usize;
                assert!(!seen[p], "n = {n}: pixel {p} twice");
                seen[p] = true;
            }
            if n >= 100 {
                // Near n / phi: consecutive rays land far apart.
                assert!((0.6..0.65).contains(&(s as f64 / f64::from(n))), "n = {n}: stride {s}");
            }
        }
    }
}
