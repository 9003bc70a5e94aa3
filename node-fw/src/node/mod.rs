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
//! **Passing a ray on** never blocks a receiver. Each node sets free level-0
//! pool slots aside for its neighbours and grants them ([`Message::Grant`], up
//! to [`GRANT_TARGET`] each, topped up in batches): a ray sent on a grant
//! ([`Message::GrantedRay`]) takes its slot and is answered by nothing, and
//! the sender forgets it once the reliable link has it. Without a grant the
//! ray goes as [`Message::Ray`]: the receiver admits it or refuses it
//! ([`RayReply`](link_proto::RayReply)), the sender keeps it until it is admitted and retries after
//! the receiver's [`Message::Space`]. With the class-levelled pool
//! ([`crate::pool`], where the argument for grants is written down) this is
//! deadlock-free and loses nothing, whatever the queue depths.
//!
//! One file per part of the conversation: `broadcast` (scene, assignment,
//! frame start), `initial_rays`, `trace` and `shade` (the work),
//! `passing` (rays between neighbours, with back-pressure), `balance`
//! (loads and the slide decision), `slab` (the exchange a slide makes) and
//! `transmit` (what goes out each poll).

use heapless::{Deque, Vec};
use link_proto::board::version_part;
use link_proto::{
    Assign, Balance, BoardId, BoardInfo, BoardKind, Capacity, ClockSource, ErrorCode, ErrorReport,
    FirmwareVersion, Found, Hello, LightMsg, Message, PROTOCOL_VERSION, PortHealth, RayMsg, RenderStart,
    Retire, Retirements, SceneHeader, Site,
};

use crate::error::Error;
use crate::geometry::Grid;
use crate::link::{Links, Port};
use crate::load::{IntervalClock, LoadMeter};
use crate::occupancy::Occupancy;
use crate::pool::RayPool;
use crate::slide::SlideState;
use crate::subregion::Subregion;
use neighbour::Neighbour;

mod balance;
mod broadcast;
mod initial_rays;
mod neighbour;
mod passing;
mod shade;
mod slab;
mod trace;
mod transmit;

pub use initial_rays::scatter_stride;

/// Lights a node holds.
pub const MAX_LIGHTS: usize = 8;
/// A hit's evaluated child rays, each with its candidate number.
type Children = Vec<(u8, RayMsg), { MAX_LIGHTS + 1 }>;
/// Rays a node may have sent to one neighbour without a reply yet.
pub const MAX_OUTSTANDING: usize = 4;
/// Grants a node keeps with each neighbour (slots set aside for its rays);
/// it tops them up once the neighbour holds half or fewer, so one `Grant`
/// answers several rays. 16 rather than 8 halves the `Grant` messages; on
/// 1000 spheres at 128x128 (seed 1986, preview, static) the makespan moved by
/// -8% to +4.5% over 2x2x2 to 8x8x8 and both link presets, -4.5% on 4x4x4
/// (ideal); 32 sets too many slots aside and loses on the real-board links.
pub const GRANT_TARGET: u16 = 16;

/// Work done in one [`Node::poll`], for a cost model or a profiler.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Work {
    /// Unit-cube steps.
    pub cube_steps: u32,
    /// Steps beyond the node's box through cubes the occupancy map shows
    /// clear ([`crate::occupancy::Occupancy::walk_clear`]).
    pub clear_steps: u32,
    /// Leaving rays looked at to see whether to walk them on ([`Work::clear_steps`]).
    pub clear_looks: u32,
    /// Ray/sphere tests.
    pub sphere_tests: u32,
    /// Of those, the tests that met their sphere ahead (the hit's depth computed).
    pub sphere_hits: u32,
    /// Leaving rays that ignore a sphere, looked at to see whether they
    /// still need to ([`crate::Subregion::left_behind`]).
    pub ignore_looks: u32,
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
    /// Of the rays sent and received, those passed on a grant (no reply).
    pub granted_rays: u32,
    /// Of the messages sent, retirements to the host.
    pub retire_messages: u32,
    /// Records those carried beyond each message's first (retirements travel
    /// several to a message when the host link is behind).
    pub extra_records: u32,
    /// Of the messages received, pieces of the map of occupied cubes taken.
    pub map_messages: u32,
}

impl Work {
    /// Whether anything was done.
    pub fn is_busy(&self) -> bool {
        *self != Work::default()
    }

    /// Whether the node's own work went on: a walk, a shaded hit or an
    /// initial ray (each makes progress: see `Node::compute`).
    pub fn computed(&self) -> bool {
        self.pieces() > 0
    }

    /// Pieces of the node's own work: walks, shaded hits, initial rays.
    pub fn pieces(&self) -> u32 {
        self.traces + self.shades + self.created
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
    /// Polls that did work.
    pub busy_polls: u32,
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

/// A node with `S` spheres, `R` sphere references, `C` cubes, `P` ray slots
/// and `O` words of the grid's occupancy ([`crate::occupancy`]).
#[derive(Debug)]
pub struct Node<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> {
    id: u16,
    phase: Phase,
    header: SceneHeader,
    grid: Grid,
    assign: Option<Assign>,
    region: Subregion<S, R, C>,
    /// Which cubes of the whole grid hold a surface.
    occupancy: Occupancy<O>,
    lights: Vec<LightMsg, MAX_LIGHTS>,
    spheres_seen: u32,
    render: Option<RenderStart>,
    cursor: u32,
    /// Step through the tile's pixels (see [`scatter_stride`]).
    stride: u32,
    pool: RayPool<P>,
    /// Each neighbour port's state, in port order.
    ports: [Neighbour; 6],
    hello_due: bool,
    /// The host session this node is in ([`Links::session`]), once its host
    /// has spoken. Until then it says no hello: so by the time the host has
    /// every node's hello, every node is in its session.
    session: Option<u32>,
    /// The board this node runs on, as its hellos name it.
    board: BoardInfo,
    error_due: Option<ErrorReport>,
    load_due: Option<u32>,
    meter: LoadMeter,
    totals: Totals,
    balance: Option<Balance>,
    intervals: IntervalClock,
    slide: SlideState,
    /// Small control messages (loads, slide replies, notices) waiting for room.
    control: Deque<(Port, Message), 16>,
    /// Frames this node has ended since its session began.
    frames_ended: u32,
    /// Each port's counts ([`Links::health`]) when the host last heard them.
    health_told: [PortHealth; 7],
    /// Records of rays that ended, gathered for the host (their slots are
    /// free already); sent when full, or once the node has no work.
    retiring: Option<Retirements>,
}

/// Pieces of work (walks, shaded hits, initial rays) a poll does at most
/// before it sends what they made.
///
/// What one poll sends a neighbour leaves in one frame, a batch, whose
/// ends each handle it for 184 instructions less a ray than a frame of its
/// own (`hop_batched` against `hop_granted`), and whose framing crosses the
/// wire once. But a ray waits for the poll's other pieces before it leaves,
/// and the node behind it for the ray. On the in-memory board (1000
/// spheres, 256x256, preview cut), against one piece a poll: six took
/// 2.3-3.6% off the frame on ideal links and 3.3-4.1% on the real-board
/// ones; eight about as much; twelve made the 4x4x4 cube's frame 2.7%
/// slower on ideal links, sixteen 28%.
pub const PIECES_PER_POLL: usize = 6;

/// Interval of the final load report sent after `Finish`.
pub const FINAL_INTERVAL: u32 = u32::MAX;

/// node-fw's own version: what a node reports unless its board says otherwise.
pub const NODE_FW_VERSION: FirmwareVersion = FirmwareVersion {
    major: version_part(env!("CARGO_PKG_VERSION_MAJOR")),
    minor: version_part(env!("CARGO_PKG_VERSION_MINOR")),
    patch: version_part(env!("CARGO_PKG_VERSION_PATCH")),
};

/// A node's board until its owner says which: no id, virtual time (the
/// in-memory board gives each node an id on top).
pub const UNNAMED_BOARD: BoardInfo = BoardInfo {
    id: BoardId::NONE,
    kind: BoardKind::Simulated,
    firmware: NODE_FW_VERSION,
    clock_hz: 0,
    clock_source: ClockSource::Virtual,
    link_baud: 0,
    host_baud: 0,
};

const NO_HEADER: SceneHeader = SceneHeader {
    grid: [1; 3],
    ambient: [0; 3],
    background: [0; 3],
    max_depth: 0,
    map: link_proto::MapLoad::Sent,
};

impl<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> Node<S, R, C, P, O> {
    /// A node with index `id` (row-major over the array), waiting for a scene.
    pub const fn new(id: u16) -> Self {
        Self {
            id,
            phase: Phase::Idle,
            header: NO_HEADER,
            grid: Grid::UNIT,
            assign: None,
            region: Subregion::new(),
            occupancy: Occupancy::new(),
            lights: Vec::new(),
            spheres_seen: 0,
            render: None,
            cursor: 0,
            stride: 1,
            pool: RayPool::new(),
            ports: [Neighbour::NEW; 6],
            hello_due: true,
            session: None,
            board: UNNAMED_BOARD,
            error_due: None,
            load_due: None,
            meter: LoadMeter::new(),
            totals: Totals { rays: 0, sphere_tests: 0, cube_steps: 0, refused: 0, busy_polls: 0 },
            balance: None,
            intervals: IntervalClock::idle(),
            slide: SlideState::new(),
            control: Deque::new(),
            frames_ended: 0,
            health_told: [PortHealth { resent: 0, damaged: 0, lost: 0 }; 7],
            retiring: None,
        }
    }

    /// Makes this node what [`Node::new`]`(id)` makes, in place, field by
    /// field. For a node in storage that `new` did not build: a board's
    /// node is a zero-filled static (in `.bss`, so that its tens of
    /// kilobytes of initial value take no flash), and a node built on the
    /// stack and moved there would need more stack than the board has.
    pub fn renew(&mut self, id: u16) {
        // What a new host session resets, then what it keeps: the node's
        // identity, its cables and board, and storage it only empties.
        self.start_over();
        self.id = id;
        self.stride = 1;
        self.region.renew();
        self.pool.renew();
        for port in &mut self.ports {
            *port = Neighbour::NEW;
        }
        self.session = None;
        self.board = UNNAMED_BOARD;
        self.health_told = [PortHealth::default(); 7];
    }

    /// The capacities this node was built with.
    pub const fn capacity() -> Capacity {
        Capacity { spheres: S as u32, refs: R as u32, cubes: C as u32, rays: P as u16 }
    }

    /// Names the board the node runs on, for its hellos (call before the
    /// first poll).
    pub fn set_board(&mut self, board: BoardInfo) {
        self.board = board;
    }

    /// The board at each neighbour port (port order), as far as its hello
    /// has come.
    pub fn peers(&self) -> [Option<BoardId>; 6] {
        self.ports.each_ref().map(|n| n.peer)
    }

    /// This node's hello.
    fn hello(&self) -> Hello {
        Hello {
            version: PROTOCOL_VERSION,
            node: self.id,
            capacity: Self::capacity(),
            board: self.board,
            session: self.session.unwrap_or(0),
        }
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
            || self.retiring.is_some()
            || self.creation_left()
            || self.hello_due
            || self.error_due.is_some()
            || self.load_due.is_some()
            || self.ports.iter().any(Neighbour::owes)
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

    /// Handles what has arrived, does up to [`PIECES_PER_POLL`] pieces of
    /// work, and sends what it can.
    /// `now` is the caller's clock; it only splits time into running and waiting.
    pub fn poll<L: Links>(&mut self, now: u64, links: &mut L) -> Work {
        self.meter.tick(now);
        let mut work = Work::default();
        self.receive(links, &mut work);
        if self.phase == Phase::Rendering {
            self.balance_tick(now);
            for _ in 0..PIECES_PER_POLL {
                let before = work.pieces();
                self.compute(&mut work);
                if work.pieces() == before {
                    break;
                }
            }
        }
        self.transmit(links, &mut work);
        if work.is_busy() {
            self.totals.busy_polls += 1;
        }
        self.meter.set_busy(work.is_busy());
        work
    }

    /// Takes everything that arrived on every port.
    fn receive<L: Links>(&mut self, links: &mut L, work: &mut Work) {
        while let Some(port) = links.peer_restarted() {
            match port {
                // A new host session: whatever the old one set up is moot.
                Port::Host => self.start_over(),
                _ => self.fail(ErrorCode::PeerRestarted, port as u32, 0),
            }
        }
        self.follow_session(links.session());
        for port in Port::ALL {
            while let Some(msg) = links.recv(port) {
                work.received += 1;
                if msg.is_ray() {
                    work.rays_received += 1;
                }
                if matches!(msg, Message::GrantedRay(_)) {
                    work.granted_rays += 1;
                }
                if matches!(msg, Message::Occupancy(_)) {
                    work.map_messages += 1;
                }
                if self.phase != Phase::Failed && self.in_session(port, &msg) {
                    self.handle(port, msg);
                }
            }
        }
    }

    /// Takes the host session from the links, and says a new one on every
    /// neighbour port: each neighbour judges what we send by the session our
    /// last hello named, as we judge theirs ([`Self::in_session`]).
    fn follow_session(&mut self, session: Option<u32>) {
        if session != self.session {
            self.session = session;
            for n in &mut self.ports {
                n.hello_due = true;
            }
        }
    }

    /// Whether `msg` from `port` belongs to this node's host session: not
    /// when a neighbour's last hello named another. Those are what was still
    /// in flight when one of the two began a new session: a reply to a ray
    /// this node forgot when it started over, a grant of slots the neighbour
    /// no longer sets aside. Until both have a session (a node says hello
    /// once its host has spoken) nothing is stale, for neither has left one.
    /// And none can be of a session this node has yet to join: a serial host
    /// starts no frame before every node has said hello in its session.
    fn in_session(&self, port: Port, msg: &Message) -> bool {
        let theirs = self.ports.get(port.index()).and_then(|n| n.session);
        matches!(msg, Message::Hello(_)) || theirs.zip(self.session).is_none_or(|(t, ours)| t == ours)
    }

    /// Stops the node, reporting the first error to the host.
    fn fail(&mut self, code: ErrorCode, a: u32, b: u32) {
        if self.phase != Phase::Failed {
            self.error_due = Some(ErrorReport { node: self.id, code, a, b });
            self.phase = Phase::Failed;
        }
    }

    /// [`Self::fail`] naming where the check failed.
    fn fail_at(&mut self, code: ErrorCode, a: u32, at: impl Into<Found>) {
        self.fail(code, a, at.into().to_wire());
    }

    /// [`Self::fail`] with an [`Error`] value.
    fn fail_with(&mut self, error: Error) {
        let r = error.report(self.id);
        self.fail(r.code, r.a, r.b);
    }

    /// The host's `Finish`: the frame is over. The final load report is due
    /// once every slide under way has settled (so the host, having all final
    /// reports, knows where every boundary is), and no more interval reports:
    /// over a slow host link a report each interval can fill the link faster
    /// than it drains and hold the final one back for ever (seen at
    /// 20 000-cycle intervals over 921 600 baud).
    ///
    /// The node keeps its subregion and its spheres, ready for the next
    /// frame's `RenderStart`. It gives no more grants and tells each
    /// neighbour the frame ended: the grants it gave are void, and the
    /// neighbour, which takes our `Finish` after every grant we sent on
    /// that link, knows which of its grants are.
    fn finish_frame(&mut self) {
        self.load_due = Some(FINAL_INTERVAL);
        self.intervals = IntervalClock::idle();
        if self.phase == Phase::Rendering {
            self.phase = Phase::Loaded;
            self.frames_ended = self.frames_ended.wrapping_add(1);
            for n in self.ports.iter_mut().filter(|n| n.present) {
                (n.grants_given, n.grants_due) = (0, 0);
                n.end_due = true;
            }
        }
    }

    /// A neighbour ended its frame: every grant it gave before is void.
    fn neighbour_ended(&mut self, port: Port) {
        if let Some(n) = self.ports.get_mut(port.index()) {
            n.ends_seen = n.ends_seen.wrapping_add(1);
            n.grants_held = 0;
        }
    }

    /// Dispatches one message by its port and kind.
    fn handle(&mut self, port: Port, msg: Message) {
        match (port, msg) {
            (_, Message::Hello(h)) if h.version != PROTOCOL_VERSION => {
                self.fail(ErrorCode::Version, u32::from(h.version), u32::from(PROTOCOL_VERSION))
            }
            // The host's hello (also its heartbeat) needs no answer.
            (Port::Host, Message::Hello(_)) => {}
            (p, Message::Hello(h)) => {
                if let Some(n) = self.ports.get_mut(p.index()) {
                    n.peer = Some(h.board.id);
                    n.session = Some(h.session);
                    n.note_due = true;
                }
            }
            (Port::Host, Message::SceneBegin(header)) => self.begin_scene(header),
            (Port::Host, Message::Assign(a)) => self.take_assignment(a),
            (Port::Host, Message::Sphere(s)) => self.take_sphere(s),
            (Port::Host, Message::Light(l)) => self.take_light(l),
            (Port::Host, Message::Occupancy(m)) => self.take_occupancy(&m),
            (Port::Host, Message::SceneEnd(end)) => self.end_scene(end),
            (Port::Host, Message::RenderStart(r)) => self.start_render(r),
            (Port::Host, Message::Finish(_)) => self.finish_frame(),
            (p, Message::Finish(_)) => self.neighbour_ended(p),
            (p, Message::Ray(ray)) if p != Port::Host => self.admit_ray(p, ray),
            (p, Message::GrantedRay(ray)) if p != Port::Host => self.admit_granted(p, ray),
            (p, Message::Grant(n)) if p != Port::Host => self.take_grant(p, n),
            // A neighbour that began its frame first may report an interval
            // while this node is still loading: the host starts the nodes one
            // by one, and a lossy host link delays some by resends. Until this
            // node has its assignment it does not know its driving axis, so
            // it cannot tell which side the load came from; and the slide
            // decision pairs loads of this node's own frame only. The report
            // is moot here, so it is dropped.
            (p, Message::Load(_)) if p != Port::Host && self.phase != Phase::Rendering => {}
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
                None => self.fail_at(ErrorCode::Unexpected, port as u32, Site::SlideOffDrivingAxis),
            },
            (p, Message::RayReply(r)) if p != Port::Host => self.take_reply(p, r),
            (p, Message::Space) if p != Port::Host => self.retry_refused(p),
            (port, msg) => self.fail_at(ErrorCode::Unexpected, port as u32, Found::Message(msg.kind())),
        }
    }
}

fn retire(ray: &RayMsg, rgb: [u32; 3], credit: u64, spawned: u8) -> Retire {
    Retire { pixel: ray.pixel, rgb, credit, spawned, rays: 1, background: 0 }
}

/// The record of `ray` leaving the scene. At full strength its
/// contribution is the background colour itself, which the host holds: the
/// record counts it instead of carrying it (six bytes fewer on the host
/// link, which the nodes behind the scene fill with such records).
fn retire_to_background(scene: &crate::shading::Scene<'_>, ray: &RayMsg) -> Retire {
    let rgb = scene.background(ray);
    if rgb == scene.background_colour() {
        Retire { rgb: [0; 3], background: 1, ..retire(ray, rgb, ray.credit, 0) }
    } else {
        retire(ray, rgb, ray.credit, 0)
    }
}
