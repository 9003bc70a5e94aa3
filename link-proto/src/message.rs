//! The messages of every conversation in the system.
//!
//! Formats of raw fixed-point fields:
//! - `Q16.16` (`i32`): positions, radii and ray parameters `t`, in unit cubes.
//! - `Q2.30` (`i32`): direction components.
//! - `Q1.15` (`u16`/`u32`): colours, weights and material coefficients; 32768 is 1.0.
//!
//! postcard tags enum variants by index: append new variants at the end only, and
//! bump [`crate::PROTOCOL_VERSION`] whenever a message changes shape.

use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

use crate::board::{BoardInfo, PeerNote};
use crate::health::LinkHealth;
pub use crate::retirements::{Contribution, Retire, Retirements, Totals};

/// A frame's sequence number on its link. It wraps at 2^8: a window holds
/// far fewer frames than half of that, and a link never reorders frames, so
/// eight bits tell every frame in flight apart. One byte on the wire, where
/// a `u16` took postcard's varint two or three bytes once a link had carried
/// 128 frames, in every data frame and again in every acknowledgement.
pub type Seq = u8;

/// One frame on a link: a per-link sequence number, the message it carries,
/// and perhaps an acknowledgement of the opposite direction's frames.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct Frame {
    /// Sequence number of this frame on its link.
    pub seq: Seq,
    /// The message.
    pub msg: Message,
    /// A cumulative acknowledgement riding on this frame, as [`Message::Ack`]
    /// would carry it, so that a reply needs no acknowledgement frame of its
    /// own. It travels as a trailer after the postcard body (see
    /// [`crate::frame`]), not as a serde field: a frame without one decodes
    /// as before, so peers of other protocol versions still read each
    /// other's hellos.
    #[serde(skip)]
    pub ack: Option<Seq>,
}

impl Frame {
    /// A frame with no acknowledgement riding on it.
    pub const fn new(seq: Seq, msg: Message) -> Self {
        Self { seq, msg, ack: None }
    }
}

/// Every message the host and the nodes exchange.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum Message {
    /// Version handshake, sent first in both directions on every link.
    Hello(Hello),
    /// Host to all nodes: a new scene follows; drop the old one.
    SceneBegin(SceneHeader),
    /// Host to each node that keeps it: one sphere; also node to node when a slab moves in a slide.
    Sphere(SphereMsg),
    /// Host broadcast of one point light.
    Light(LightMsg),
    /// Host to each node: its part of the scene is complete; counts let a node check it missed nothing.
    SceneEnd(SceneEnd),
    /// Host to one node: its place in the array and its subregion.
    Assign(Assign),
    /// Host to all nodes: camera, image and initial-ray assignment; start rendering.
    RenderStart(RenderStart),
    /// A ray with its exact traversal state, passed between nodes.
    Ray(RayMsg),
    /// Node to host: rays that ended, their pixel contributions and returned
    /// credit (several records when the host link is behind).
    Retire(Retirements),
    /// Node to host and to driving-axis neighbours: running and waiting time of an interval.
    Load(LoadReport),
    /// Giver to receiver: the slab up to `boundary` is coming; its spheres follow.
    SlideOffer(SlideOffer),
    /// Reply to a [`SlideOffer`]: accepted or refused, with the reason.
    SlideReply(SlideReply),
    /// Giver to receiver: every sphere of the slab has been sent. Receiver to
    /// host: the slide is committed (the host records boundary positions).
    SlideDone(SlideDone),
    /// Host to all nodes: the frame is complete; report final loads and go idle.
    Finish(Finish),
    /// A node reports a failure to the host. Errors are values, never panics.
    Error(ErrorReport),
    /// Link layer: frames up to and including `seq` were received intact.
    Ack(Seq),
    /// Link layer: frame `seq` was lost or corrupted; send again from it.
    Nak(Seq),
    /// Node to node: a [`RayMsg`] was admitted or refused (the sender keeps it until admitted).
    RayReply(RayReply),
    /// Node to node: a pool slot freed; retry rays this node refused.
    Space,
    /// Node to its driving-axis neighbour: give me the slab next to our boundary,
    /// moving it to `boundary` (the lighter node asks the busier one).
    SlideRequest(SlideOffer),
    /// Link layer: the sender's channel starts a stream at sequence number 0;
    /// `.0` names the sender's incarnation (it differs after a restart).
    Sync(u32),
    /// Link layer: reply to [`Message::Sync`], echoing the incarnation taken.
    SyncAck(u32),
    /// Node to host: a slide this node received is committed (the host
    /// rebuilds every boundary's positions from these).
    SlideNote(SlideNote),
    /// Node to node: the sender may pass this many more rays as
    /// [`Message::GrantedRay`]; the receiver has set a pool slot aside for each.
    Grant(u16),
    /// Node to node: a ray passed on a grant. The receiver admits it into a
    /// slot it set aside and answers nothing; the sender forgets it once the
    /// link has taken it.
    GrantedRay(RayMsg),
    /// Node to host: the board at the end of one neighbour link, learnt from
    /// its hello (again for every new host session).
    Peer(PeerNote),
    /// Node to host: frames resent and damaged on each port since the last
    /// such report; sent before a frame's final load, and only after trouble.
    LinkHealth(LinkHealth),
    /// Host to every node: which cubes of the grid some sphere's surface
    /// touches, for [`CUBES_PER_OCCUPANCY`] cubes from `first`.
    Occupancy(OccupancyMsg),
}

impl Message {
    /// The message's variant.
    pub fn kind(&self) -> MessageKind {
        match self {
            Message::Hello(_) => MessageKind::Hello,
            Message::SceneBegin(_) => MessageKind::SceneBegin,
            Message::Sphere(_) => MessageKind::Sphere,
            Message::Light(_) => MessageKind::Light,
            Message::SceneEnd(_) => MessageKind::SceneEnd,
            Message::Assign(_) => MessageKind::Assign,
            Message::RenderStart(_) => MessageKind::RenderStart,
            Message::Ray(_) => MessageKind::Ray,
            Message::Retire(_) => MessageKind::Retire,
            Message::Load(_) => MessageKind::Load,
            Message::SlideOffer(_) => MessageKind::SlideOffer,
            Message::SlideReply(_) => MessageKind::SlideReply,
            Message::SlideDone(_) => MessageKind::SlideDone,
            Message::Finish(_) => MessageKind::Finish,
            Message::Error(_) => MessageKind::Error,
            Message::Ack(_) => MessageKind::Ack,
            Message::Nak(_) => MessageKind::Nak,
            Message::RayReply(_) => MessageKind::RayReply,
            Message::Space => MessageKind::Space,
            Message::SlideRequest(_) => MessageKind::SlideRequest,
            Message::Sync(_) => MessageKind::Sync,
            Message::SyncAck(_) => MessageKind::SyncAck,
            Message::SlideNote(_) => MessageKind::SlideNote,
            Message::Grant(_) => MessageKind::Grant,
            Message::GrantedRay(_) => MessageKind::GrantedRay,
            Message::Peer(_) => MessageKind::Peer,
            Message::LinkHealth(_) => MessageKind::LinkHealth,
            Message::Occupancy(_) => MessageKind::Occupancy,
        }
    }

    /// Whether the message carries a ray (the long messages between nodes).
    pub fn is_ray(&self) -> bool {
        matches!(self, Message::Ray(_) | Message::GrantedRay(_))
    }
}

/// A message's variant without its fields: for error reports and counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum MessageKind {
    /// [`Message::Hello`].
    Hello,
    /// [`Message::SceneBegin`].
    SceneBegin,
    /// [`Message::Sphere`].
    Sphere,
    /// [`Message::Light`].
    Light,
    /// [`Message::SceneEnd`].
    SceneEnd,
    /// [`Message::Assign`].
    Assign,
    /// [`Message::RenderStart`].
    RenderStart,
    /// [`Message::Ray`].
    Ray,
    /// [`Message::Retire`].
    Retire,
    /// [`Message::Load`].
    Load,
    /// [`Message::SlideOffer`].
    SlideOffer,
    /// [`Message::SlideReply`].
    SlideReply,
    /// [`Message::SlideDone`].
    SlideDone,
    /// [`Message::Finish`].
    Finish,
    /// [`Message::Error`].
    Error,
    /// [`Message::Ack`].
    Ack,
    /// [`Message::Nak`].
    Nak,
    /// [`Message::RayReply`].
    RayReply,
    /// [`Message::Space`].
    Space,
    /// [`Message::SlideRequest`].
    SlideRequest,
    /// [`Message::Sync`].
    Sync,
    /// [`Message::SyncAck`].
    SyncAck,
    /// [`Message::SlideNote`].
    SlideNote,
    /// [`Message::Grant`].
    Grant,
    /// [`Message::GrantedRay`].
    GrantedRay,
    /// [`Message::Peer`].
    Peer,
    /// [`Message::LinkHealth`].
    LinkHealth,
    /// [`Message::Occupancy`].
    Occupancy,
}

impl MessageKind {
    /// Every kind, in variant order.
    pub const ALL: [MessageKind; 28] = [
        MessageKind::Hello,
        MessageKind::SceneBegin,
        MessageKind::Sphere,
        MessageKind::Light,
        MessageKind::SceneEnd,
        MessageKind::Assign,
        MessageKind::RenderStart,
        MessageKind::Ray,
        MessageKind::Retire,
        MessageKind::Load,
        MessageKind::SlideOffer,
        MessageKind::SlideReply,
        MessageKind::SlideDone,
        MessageKind::Finish,
        MessageKind::Error,
        MessageKind::Ack,
        MessageKind::Nak,
        MessageKind::RayReply,
        MessageKind::Space,
        MessageKind::SlideRequest,
        MessageKind::Sync,
        MessageKind::SyncAck,
        MessageKind::SlideNote,
        MessageKind::Grant,
        MessageKind::GrantedRay,
        MessageKind::Peer,
        MessageKind::LinkHealth,
        MessageKind::Occupancy,
    ];
}

/// A committed slide, as the receiving node tells the host.
///
/// The two nodes of a boundary report over different host links, so their
/// notes may reach the host in another order than the slides happened;
/// `count` puts each boundary's notes back in order (only the boundary's low
/// node decides its slides, one at a time, and both nodes count them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct SlideNote {
    /// New boundary position, in unit cubes along the driving axis.
    pub boundary: u16,
    /// The boundary is on the reporting node's high side (else its low side).
    pub high_side: bool,
    /// Slides of this boundary in this frame so far, this one included.
    pub count: u16,
}

/// Dynamic load balancing by sliding boundaries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct Balance {
    /// Ticks between load comparisons.
    pub interval: u64,
    /// A node under this load (running / waiting, Q16.16) may take a slab.
    pub threshold: u32,
    /// Cubes a boundary moves per slide (1 in the paper).
    pub step: u16,
    /// How far a boundary moves.
    pub policy: SlidePolicy,
}

/// How far a boundary moves when the loads call for a slide.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum SlidePolicy {
    /// The paper's: `step` cubes when one load is lower and under the threshold.
    Paper,
    /// Proportional to the running-time difference, under-relaxed and capped
    /// (after ALL's staggered method and GROMACS): shift
    /// `(W_b - W_l) / (W_b + W_l) * (d_b + d_l) / (2 gamma)` cubes toward the busier
    /// node, on running times smoothed over intervals, at most 0.49 of its extent,
    /// none below `deadband` (Q16.16 relative difference). A boundary that moved
    /// holds for two intervals.
    Proportional {
        /// Under-relaxation, Q16.16 (4.0 is stable per ALL).
        gamma: u32,
        /// Relative running-time difference below which nothing moves, Q16.16.
        deadband: u32,
    },
}

/// Answer to a ray passed over a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct RayReply {
    /// The [`RayMsg::tag`] of the ray.
    pub tag: u16,
    /// Admitted into the receiver's pool; if false the sender retries after [`Message::Space`].
    pub accepted: bool,
}

/// Version handshake: who the sender is and what it was built with. Sent to
/// the host, and by nodes on every neighbour link too, so each learns which
/// board its cables reach.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct Hello {
    /// [`crate::PROTOCOL_VERSION`] of the sender. First, so that a peer of
    /// any version can read it.
    pub version: u16,
    /// Sender's node index (row-major over the array), or `u16::MAX` for the host.
    pub node: u16,
    /// Capacities compiled into the sender (zero for the host).
    pub capacity: Capacity,
    /// The board the sender runs on.
    pub board: BoardInfo,
    /// The host session the sender is in: the incarnation of the host on its
    /// host link (0 from the host itself, and where links have no sessions).
    /// A node drops what a neighbour sends from a session other than its
    /// own: what was still in flight when one of them began a new session.
    pub session: u32,
}

impl Hello {
    /// The host's hello: its protocol version (nodes check it), no
    /// capacities, no session of its own (its incarnation is the session).
    pub const fn host() -> Self {
        Self {
            version: crate::PROTOCOL_VERSION,
            node: u16::MAX,
            capacity: Capacity { spheres: 0, refs: 0, cubes: 0, rays: 0 },
            board: BoardInfo::HOST,
            session: 0,
        }
    }
}

/// Storage a node was built with; the host checks a scene against it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct Capacity {
    /// Spheres the subregion can hold.
    pub spheres: u32,
    /// Sphere references over all unit cubes of the subregion.
    pub refs: u32,
    /// Unit cubes the subregion box can span.
    pub cubes: u32,
    /// Rays the node can queue.
    pub rays: u16,
}

/// The most reflections along one path a scene may ask for: it bounds ray
/// classes and how often a pixel's credit is split (see `node_fw::credit`).
pub const MAX_DEPTH: u8 = 8;

/// Scene-wide settings, sent before the spheres and lights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct SceneHeader {
    /// Grid size in unit cubes per axis (1..=256).
    pub grid: [u16; 3],
    /// Ambient light colour, Q1.15.
    pub ambient: [u16; 3],
    /// Colour of rays that leave the grid, Q1.15.
    pub background: [u16; 3],
    /// Maximum number of reflections along one path (at most [`MAX_DEPTH`]).
    pub max_depth: u8,
    /// Whether the scene brings its own map of the occupied cubes.
    pub map: MapLoad,
}

/// Where a scene's map of the occupied cubes ([`Message::Occupancy`]) comes
/// from. The map depends on the spheres and the grid, not on the boxes: a
/// scene sent again only because boxes moved keeps it, and spares each
/// node's host link the map (128 messages, 5.5 KB, on a 32^3 grid).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum MapLoad {
    /// The scene's own [`Message::Occupancy`] messages make the map (none:
    /// the node has no map).
    Sent,
    /// The node keeps the map it holds, complete, from a scene over the
    /// same grid and the same spheres; no [`Message::Occupancy`] follows.
    Kept,
}

/// Surface parameters of a sphere (Whitted's model).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct MaterialMsg {
    /// Surface colour, Q1.15.
    pub color: [u16; 3],
    /// Ambient coefficient, Q1.15.
    pub ambient: u16,
    /// Diffuse coefficient, Q1.15.
    pub diffuse: u16,
    /// Specular coefficient, Q1.15.
    pub specular: u16,
    /// Phong exponent of the highlight.
    pub shininess: u8,
    /// Mirror reflection coefficient, Q1.15 (0 = no reflection rays).
    pub reflect: u16,
}

/// One sphere of the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct SphereMsg {
    /// Scene-wide identifier; nearest-hit ties go to the lowest id.
    pub id: u16,
    /// Centre, Q16.16 unit cubes.
    pub center: [i32; 3],
    /// Radius, Q16.16 unit cubes.
    pub radius: i32,
    /// Surface parameters.
    pub material: MaterialMsg,
}

/// One point light.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct LightMsg {
    /// Scene-wide identifier.
    pub id: u8,
    /// Position, Q16.16 unit cubes.
    pub position: [i32; 3],
    /// Colour and intensity, Q1.15.
    pub color: [u16; 3],
}

/// End of a node's part of the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct SceneEnd {
    /// Number of spheres sent to this node (the host sends a node only the
    /// spheres that meet its box).
    pub spheres: u32,
    /// Number of lights broadcast.
    pub lights: u8,
    /// Number of [`Message::Occupancy`] messages the scene brings, before
    /// its end or after it, even after the frame's start: the node uses the
    /// map once all have come (none: the node knows nothing of the cubes
    /// beyond its box, unless it keeps its map, [`MapLoad::Kept`]).
    pub occupancy: u16,
}

/// Cubes an [`OccupancyMsg`] covers.
pub const CUBES_PER_OCCUPANCY: u32 = 256;

/// Which of [`CUBES_PER_OCCUPANCY`] cubes some sphere's surface touches: the
/// cubes a ray must be walked through by the node that holds them. The
/// cubes are numbered `(z * grid_y + y) * grid_x + x`; bit `i % 8` of byte
/// `i / 8` is cube `first + i`, set where a surface touches it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct OccupancyMsg {
    /// The first cube, a multiple of [`CUBES_PER_OCCUPANCY`].
    pub first: u32,
    /// One bit a cube.
    pub bits: [u8; 32],
}

/// A node's place in the array and its subregion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct Assign {
    /// Array size in nodes per axis.
    pub array: [u16; 3],
    /// This node's coordinate in the array.
    pub coord: [u16; 3],
    /// Lower corner of the subregion, in unit cubes (inclusive).
    pub lo: [u16; 3],
    /// Upper corner of the subregion, in unit cubes (exclusive).
    pub hi: [u16; 3],
    /// Driving axis of the sliding boundaries (0 = x, 1 = y, 2 = z).
    pub driving_axis: u8,
    /// Which boundaries need not line up with the neighbours' (rays crossing
    /// them may be forwarded; the node sizes its pool for that).
    pub boundaries: Boundaries,
}

/// How far the subregions' boundaries line up across the array, from most
/// to least: each kind lets rays be forwarded along more axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize, MaxSize)]
pub enum Boundaries {
    /// Every boundary a whole plane: a ray crossing one lands on its owner.
    Whole,
    /// Boundaries across the driving axis differ from row to row (as sliding
    /// leaves them, the paper's Fig. 6): forwarded along the driving axis.
    StaggeredRows,
    /// As `StaggeredRows`, and the columns across the second routed axis
    /// (`(driving + 2) % 3`) differ from slab to slab across the first
    /// (`(driving + 1) % 3`): forwarded along the second axis too. A fitted
    /// partition's, beyond the paper.
    StaggeredColumns,
}

impl Boundaries {
    /// How far they line up during a render: sliding staggers the rows
    /// whatever the start.
    pub fn when_sliding(self, sliding: bool) -> Self {
        if sliding { self.max(Self::StaggeredRows) } else { self }
    }
}

/// How initial rays are created.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum InitialRays {
    /// Every node creates the rays of its own sub-image (the paper's method).
    Parallel,
    /// The node holding the eye creates them all (the paper's Fig. 7 result B).
    EyeNode,
}

/// Pinhole camera: ray of pixel (i, j) has direction `corner + i du + j dv`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct CameraMsg {
    /// Eye position, Q16.16.
    pub eye: [i32; 3],
    /// Direction through the centre of pixel (0, 0), Q2.30.
    pub corner: [i32; 3],
    /// Direction step per pixel to the right, Q2.30.
    pub du: [i32; 3],
    /// Direction step per pixel downward, Q2.30.
    pub dv: [i32; 3],
}

/// Camera, image and the sub-image this node creates initial rays for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct RenderStart {
    /// Frame number, echoed in load reports.
    pub frame: u32,
    /// Image width and height in pixels.
    pub size: [u16; 2],
    /// Camera.
    pub camera: CameraMsg,
    /// Initial-ray mode.
    pub initial: InitialRays,
    /// Pixel rectangle `[x0, y0, x1, y1)` whose initial rays this node creates.
    pub tile: [u16; 4],
    /// Credit of one initial ray (see [`Retire::credit`]).
    pub credit: u64,
    /// Pool slots per ray class level (the deadlock-free buffer pool's depth).
    pub level_depth: u16,
    /// Pool slots beyond those, open to rays of every class; `None`: every
    /// slot the node has left over.
    pub shared_slots: Option<u16>,
    /// Sliding boundaries, or `None` for a static partition.
    pub balance: Option<Balance>,
}

/// What a ray is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum RayKind {
    /// From the eye through a pixel.
    Primary,
    /// Mirror reflection off a surface.
    Reflected,
    /// Toward a light; adds its weight to the pixel unless blocked before `t_max`.
    Shadow,
}

/// Nearest hit found so far along a ray, with the sphere itself: whichever
/// node ends up shading it need not hold the sphere (its rounded depth may fall
/// past the node's boundary, or a slide may have moved the sphere away).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct HitMsg {
    /// Ray parameter of the hit, Q16.16.
    pub t: i32,
    /// The sphere hit.
    pub sphere: SphereMsg,
}

/// A ray with its exact traversal state. The digital line is fully determined by
/// `origin`, `dir` and `cell`, so a receiver continues it bit-identically.
///
/// On the wire it takes the hand-packed form of [`crate::ray_wire`], not
/// postcard's field by field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RayMsg {
    /// Origin, Q16.16.
    pub origin: [i32; 3],
    /// Direction, Q2.30.
    pub dir: [i32; 3],
    /// Current unit cube of the traversal.
    pub cell: [u16; 3],
    /// Pixel index `y * width + x`.
    pub pixel: u32,
    /// Throughput per channel, Q1.15 (for shadow rays: the light's contribution).
    pub weight: [u32; 3],
    /// Termination credit carried by this ray.
    pub credit: u64,
    /// What the ray is for.
    pub kind: RayKind,
    /// Reflections so far along this path.
    pub depth: u8,
    /// Sphere the ray leaves (never hit by it), if any.
    pub ignore: Option<u16>,
    /// Nearest hit found so far, if any.
    pub best: Option<HitMsg>,
    /// Largest ray parameter of interest (shadow rays: the light), Q16.16.
    pub t_max: Option<i32>,
    /// Buffer class: rises by one with every hop and every spawn (bounds deadlock-free pools).
    pub class: u16,
    /// Sender's handle for the [`RayReply`].
    pub tag: u16,
}

/// Running and waiting time of one node over one interval, in virtual ticks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct LoadReport {
    /// Reporting node.
    pub node: u16,
    /// Interval number.
    pub interval: u32,
    /// Ticks spent processing rays.
    pub running: u64,
    /// Ticks spent waiting with nothing to process.
    pub waiting: u64,
    /// Rays processed in the interval.
    pub rays: u32,
    /// Ray/sphere tests in the interval.
    pub sphere_tests: u32,
    /// Unit-cube steps in the interval.
    pub cube_steps: u32,
    /// Rays this node refused for want of a pool slot (back-pressure events).
    pub refused: u32,
    /// The node's extent along the driving axis, in cubes (for proportional slides).
    pub extent: u16,
    /// Polls in the interval that did work (each is charged as running
    /// until the next poll: its work and the rest of the loop's pass).
    pub busy_polls: u32,
}

/// Proposal to move a shared driving-axis boundary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct SlideOffer {
    /// Interval the decision was taken in.
    pub interval: u32,
    /// New position of the boundary, in unit cubes along the driving axis.
    pub boundary: u16,
}

/// Why a slide was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum SlideRefusal {
    /// The receiver cannot hold the slab's spheres or cubes.
    Capacity,
    /// The boundary would leave a subregion empty.
    Empty,
    /// Another slide of the same boundary is in progress.
    Busy,
}

/// Answer to a [`SlideOffer`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct SlideReply {
    /// Boundary position that was offered.
    pub boundary: u16,
    /// `None` if accepted, else why not.
    pub refused: Option<SlideRefusal>,
}

/// All spheres of a slab were sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct SlideDone {
    /// New boundary position.
    pub boundary: u16,
    /// Number of spheres sent.
    pub spheres: u32,
}

/// End of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct Finish {
    /// Frame number.
    pub frame: u32,
}

/// What went wrong in a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub enum ErrorCode {
    /// The peer speaks another protocol version (`a` = its version).
    Version,
    /// A frame failed its CRC or could not be decoded.
    BadFrame,
    /// A message arrived that the node cannot use in its state.
    Unexpected,
    /// More spheres than the node can hold (`a` = capacity, `b` = needed).
    SphereCapacity,
    /// More sphere references than the node can hold (`a` = capacity, `b` = needed).
    RefCapacity,
    /// The subregion spans more cubes than the node can hold (`a` = capacity, `b` = needed).
    CubeCapacity,
    /// A value outside the documented range (`a` = which field).
    OutOfRange,
    /// A ray arrived that does not lie on its own digital line.
    BadRay,
    /// The scene counts in `SceneEnd` disagree with what arrived (`a` = expected, `b` = got).
    SceneCount,
    /// The ray pool cannot hold one slot per class level (`a` = capacity, `b` = needed).
    PoolCapacity,
    /// A ray's class exceeded the bound the pool was sized for (`a` = class).
    ClassOverflow,
    /// The node needs a neighbour link its board has no UART for (`a` = port
    /// index, `b` = neighbour UARTs on the board).
    PortCapacity,
    /// The neighbour on port `a` restarted (a new incarnation on its link): the
    /// rays and spheres it held are gone.
    PeerRestarted,
    /// This node started afresh mid-frame: before its host spoke to it, the
    /// neighbour on port `a` passed it a ray on a grant it never gave, the
    /// rest of a frame its previous incarnation was in.
    Restarted,
}

/// A node's error, sent to the host. Firmware never panics on input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, MaxSize)]
pub struct ErrorReport {
    /// Node index.
    pub node: u16,
    /// What went wrong.
    pub code: ErrorCode,
    /// First detail (see [`ErrorCode`]).
    pub a: u32,
    /// Second detail (see [`ErrorCode`]).
    pub b: u32,
}
