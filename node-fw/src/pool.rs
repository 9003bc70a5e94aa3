//! The node's ray pool: fixed slots, admission by class, never a drop.
//!
//! **Deadlock freedom with tiny buffers.** Every ray carries a class that rises
//! by one with each hop to another node and each spawn of a child, and that is
//! bounded by `top` (see [`class_bound`]). The pool is a structured buffer pool
//! (Merlin & Schweitzer, 1980): `top + 1` levels of `depth` slots, and a ray of
//! class `k` may take a free slot at any level `<= k`. A ray of class `top`
//! never needs another slot, so it always finishes; by induction on the class,
//! so does every ray, however small `depth` is. Rays that cannot be admitted
//! stay with their sender (see [`crate::node`]): the pool hands them back.
//!
//! **Grants.** A node may set free level-0 slots aside for a neighbour
//! ([`RayPool::reserve`]) and tell it so; a ray sent on such a grant takes
//! its slot whatever its class ([`RayPool::admit_reserved`]), so it needs no
//! answer. The argument above still holds:
//! 1. a granted ray is a ray admitted in advance into a level-0 slot, which
//!    every class may take; while it travels it holds that slot and none at
//!    the sender, so it waits for nothing;
//! 2. slots are set aside only from free ones at level 0, so the `depth`
//!    slots of every level `1..=top`, on which the induction rests, are
//!    untouched;
//! 3. `depth` slots of level 0 are never set aside (nor more than half of
//!    the rest), so level 0 too keeps what the induction needs for rays
//!    without a grant, among them the class-0 rays a node creates, which
//!    only level 0 takes and which therefore never wait on grants a
//!    neighbour holds and does not use.
//!
//! So a ray with a grant always moves on, and one without moves on as before.
//!
//! **Shared slots.** The argument needs only the levels above 0 to be kept
//! for their classes; level 0 is open to every ray, so any slots the node has
//! beyond one `depth` per level can go there. Without them a node near the
//! eye, taking many rays of low class, refused rays while most of its pool
//! stood empty for classes that never came, and each refusal cost it a ray
//! message, a reply and a space notice.

use link_proto::{Boundaries, RayMsg, Retire};

use crate::credit::Split;
use crate::link::Port;

/// Largest number of class levels a pool supports.
pub const MAX_LEVELS: usize = 1024;

/// Upper bound on the class of any ray in an `array` of nodes with at most
/// `max_depth` reflections, boundaries lined up as `boundaries` says across
/// `driving_axis`.
///
/// A ray's life: routing from its creator to its entry node (at most `h`
/// hops), then per generation a walk and one spawn, for `max_depth`
/// reflections plus one shadow generation. A walk crosses each axis
/// monotonically, so at most `h` node boundaries. With sliding boundaries, a
/// crossing of a non-driving axis may land beside the owner and be forwarded
/// along the driving axis (at most `D - 1` hops, the paper's Fig. 6), and a
/// boundary that moves while a ray is in flight costs a forward more: `D` is
/// allowed per walk for that. With staggered columns a crossing of the first
/// routed axis may also land beside the owner's column and be forwarded
/// across the second (at most `B - 1` hops more). Classes above the bound
/// (only from unusually many boundary moves during one walk) share the top
/// level.
pub fn class_bound(array: [u16; 3], max_depth: u8, driving_axis: usize, boundaries: Boundaries) -> u32 {
    let span = |n: u16| u32::from(n.max(1)) - 1;
    let h: u32 = array.iter().map(|&n| span(n)).sum();
    let n = |a: usize| array.get(a % 3).copied().unwrap_or(1);
    let [along, slabs, columns] = [n(driving_axis), n(driving_axis + 1), n(driving_axis + 2)];
    let rows = (span(slabs) + span(columns)) * span(along) + u32::from(along);
    let forwards = match boundaries {
        Boundaries::Whole => 0,
        Boundaries::StaggeredRows => rows,
        Boundaries::StaggeredColumns => rows + span(slabs) * span(columns),
    };
    let generations = u32::from(max_depth) + 2;
    h + generations * (h + forwards) + generations - 1
}

/// What a pooled ray is waiting for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// To be traced through this node's subregion.
    Trace,
    /// Hit found (the ray's `best`); children `next..` still to spawn, each
    /// with its share of the credit as `split` says.
    Shade {
        /// Next child candidate (lights in order, then the reflection).
        next: u8,
        /// Children the hit spawns in all.
        children: u8,
        /// The children's shares of the credit.
        split: Split,
        /// The parent's own contribution (ambient, and children resolved at once).
        rgb: [u32; 3],
    },
    /// Ended; the retirement record waits for room on the host link.
    Retire(Retire),
    /// To be sent to the neighbour on this port.
    Outbound(Port),
    /// Sent; waiting for the neighbour's admission reply.
    Sent(Port),
    /// Refused by the neighbour; waiting for its `Space` notice.
    Refused(Port),
}

impl Stage {
    fn kind(&self) -> Kind {
        match *self {
            Stage::Trace => Kind::Trace,
            Stage::Shade { .. } => Kind::Shade,
            Stage::Retire(_) => Kind::Retire,
            Stage::Outbound(p) => Kind::Outbound(p),
            Stage::Sent(p) => Kind::Sent(p),
            Stage::Refused(p) => Kind::Refused(p),
        }
    }
}

/// A slot's stage without its payload: two bytes, kept beside the slots so
/// that the scans a node makes on every poll read these, not whole slots (a
/// slot is some 150 bytes; on a board of 96 slots, copying stages out of them
/// cost more per poll than the messages the poll handled).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Free,
    Trace,
    Shade,
    Retire,
    Outbound(Port),
    Sent(Port),
    Refused(Port),
}

/// One occupied slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slot {
    /// The ray, in its wire form (exact state).
    pub ray: RayMsg,
    /// What it waits for; changed through [`RayPool::set_stage`].
    stage: Stage,
    level: u16,
}

impl Slot {
    /// What the ray waits for.
    pub fn stage(&self) -> Stage {
        self.stage
    }
}

/// Why a pool cannot be configured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PoolTooSmall {
    /// Slots the pool has.
    pub capacity: u32,
    /// Slots needed for one `depth` per class level and the shared slots.
    pub needed: u32,
}

/// Fixed-capacity ray pool with class levels.
#[derive(Debug, Clone)]
pub struct RayPool<const P: usize> {
    slots: [Option<Slot>; P],
    /// Each slot's stage kind (`Free` for an empty slot).
    kinds: [Kind; P],
    /// Slots waiting to leave (`Retire` and `Outbound`), oldest first.
    leaving: heapless::Vec<u16, P>,
    /// How many of them leave by each port (retirements by the host's).
    leaving_by: [u16; 7],
    /// Slots with work here (`Trace` and `Shade`), in no order.
    ready: heapless::Vec<u16, P>,
    /// Indices of occupied slots (scans touch only these).
    held: heapless::Vec<u16, P>,
    /// Indices of free slots, lowest on top.
    free: heapless::Vec<u16, P>,
    used_per_level: [u16; MAX_LEVELS],
    depth: u16,
    /// Level 0's slots: `depth` and the shared ones.
    base: u16,
    /// Level-0 slots set aside for granted rays (`used[0] + reserved <= base`).
    reserved: u16,
    top: u16,
}

impl<const P: usize> Default for RayPool<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const P: usize> RayPool<P> {
    /// An empty, unconfigured pool (admits nothing).
    pub const fn new() -> Self {
        Self {
            slots: [None; P],
            kinds: [Kind::Free; P],
            leaving: heapless::Vec::new(),
            leaving_by: [0; 7],
            ready: heapless::Vec::new(),
            held: heapless::Vec::new(),
            free: heapless::Vec::new(),
            used_per_level: [0; MAX_LEVELS],
            depth: 0,
            base: 0,
            reserved: 0,
            top: 0,
        }
    }

    /// Makes this pool what [`RayPool::new`] makes, in place, a slot at a
    /// time: for a pool in storage that was not built by `new` (a board's
    /// node is zero-filled at boot), where a new pool built on the stack
    /// and moved would take more stack than the board has.
    pub fn renew(&mut self) {
        for slot in &mut self.slots {
            *slot = None;
        }
        self.kinds.fill(Kind::Free);
        self.leaving.clear();
        self.leaving_by = [0; 7];
        self.ready.clear();
        self.held.clear();
        self.free.clear();
        self.used_per_level = [0; MAX_LEVELS];
        (self.depth, self.base, self.reserved, self.top) = (0, 0, 0, 0);
    }

    /// Sets `depth` slots for each class level `0..=top`, and `shared` more
    /// at level 0, open to every class (`None`: every slot left over), and
    /// empties the pool.
    pub fn configure(&mut self, top: u32, depth: u16, shared: Option<u16>) -> Result<(), PoolTooSmall> {
        let levels = (top + 1).saturating_mul(u32::from(depth));
        let shared = shared.map_or((P as u32).saturating_sub(levels), u32::from);
        let needed = levels.saturating_add(shared);
        if needed > P as u32 || top as usize >= MAX_LEVELS || depth == 0 {
            return Err(PoolTooSmall { capacity: P as u32, needed });
        }
        self.top = top as u16;
        self.depth = depth;
        // At most P, and P fits a u16 (slot indices are u16).
        self.base = u16::try_from(u32::from(depth) + shared).unwrap_or(u16::MAX);
        self.clear();
        Ok(())
    }

    /// Drops every ray.
    pub fn clear(&mut self) {
        for &i in &self.held {
            if let Some(slot) = self.slots.get_mut(usize::from(i)) {
                *slot = None;
            }
            if let Some(kind) = self.kinds.get_mut(usize::from(i)) {
                *kind = Kind::Free;
            }
        }
        self.leaving.clear();
        self.leaving_by = [0; 7];
        self.ready.clear();
        self.held.clear();
        self.free.clear();
        for i in (0..P as u16).rev() {
            // Cannot fail: `free` holds P entries.
            let _ = self.free.push(i);
        }
        self.used_per_level = [0; MAX_LEVELS];
        self.reserved = 0;
    }

    /// Sets a free level-0 slot aside for a granted ray, if one beyond the
    /// `depth` that stay open is free and grants hold at most half of level
    /// 0's other slots (the rest stay for rays this node creates, and for
    /// neighbours' rays that come without a grant).
    pub fn reserve(&mut self) -> bool {
        let used = self.used_per_level.first().copied().unwrap_or(u16::MAX);
        let open = u32::from(self.base.saturating_sub(self.depth));
        let room = u32::from(used) + u32::from(self.reserved) + u32::from(self.depth) < u32::from(self.base)
            && 2 * u32::from(self.reserved) < open;
        let reserved = room && self.free.len() > usize::from(self.reserved);
        if reserved {
            self.reserved += 1;
        }
        reserved
    }

    /// Slots set aside for granted rays.
    pub fn reserved(&self) -> u16 {
        self.reserved
    }

    /// Admits a granted ray into a slot set aside for it; hands it back if
    /// none is.
    pub fn admit_reserved(&mut self, ray: RayMsg, stage: Stage) -> Result<u16, RayMsg> {
        if self.reserved == 0 {
            return Err(ray);
        }
        let Some(index) = self.free.pop() else { return Err(ray) };
        match (self.slots.get_mut(usize::from(index)), self.used_per_level.first_mut()) {
            (Some(slot), Some(used)) if self.held.push(index).is_ok() => {
                *slot = Some(Slot { ray, stage: Stage::Trace, level: 0 });
                *used += 1;
                self.reserved -= 1;
                self.set_stage(index, stage);
                Ok(index)
            }
            _ => {
                let _ = self.free.push(index);
                Err(ray)
            }
        }
    }

    /// Highest class the pool is sized for.
    pub fn top(&self) -> u16 {
        self.top
    }

    /// Rays held.
    pub fn len(&self) -> usize {
        self.held.len()
    }

    /// Whether the pool holds no ray.
    pub fn is_empty(&self) -> bool {
        self.held.is_empty()
    }

    /// Whether a ray of class `class` would be admitted now.
    pub fn can_admit(&self, class: u16) -> bool {
        self.free_level(class).is_some()
    }

    /// Admits `ray` at the highest free level `<= class`; returns its slot
    /// index (its tag), or hands the ray back.
    pub fn admit(&mut self, ray: RayMsg, stage: Stage) -> Result<u16, RayMsg> {
        let Some(level) = self.free_level(ray.class) else {
            return Err(ray);
        };
        let Some(index) = self.free.pop() else {
            return Err(ray);
        };
        match (self.slots.get_mut(usize::from(index)), self.used_per_level.get_mut(usize::from(level))) {
            (Some(slot), Some(used)) if self.held.push(index).is_ok() => {
                *slot = Some(Slot { ray, stage: Stage::Trace, level });
                *used += 1;
                self.set_stage(index, stage);
                Ok(index)
            }
            _ => {
                let _ = self.free.push(index);
                Err(ray)
            }
        }
    }

    /// Frees slot `index`, returning its ray.
    pub fn remove(&mut self, index: u16) -> Option<Slot> {
        self.set_kind(index, Kind::Free);
        let slot = self.slots.get_mut(usize::from(index))?.take()?;
        if let Some(used) = self.used_per_level.get_mut(usize::from(slot.level)) {
            *used = used.saturating_sub(1);
        }
        if let Some(pos) = self.held.iter().position(|&i| i == index) {
            self.held.swap_remove(pos);
        }
        let _ = self.free.push(index);
        Some(slot)
    }

    /// The slot at `index`.
    pub fn get(&self, index: u16) -> Option<&Slot> {
        self.slots.get(usize::from(index))?.as_ref()
    }

    /// Replaces the ray at `index` (its state after a walk).
    pub fn set_ray(&mut self, index: u16, ray: RayMsg) {
        if let Some(Some(slot)) = self.slots.get_mut(usize::from(index)) {
            slot.ray = ray;
        }
    }

    /// Moves the ray at `index` on to `stage`.
    pub fn set_stage(&mut self, index: u16, stage: Stage) {
        if let Some(Some(slot)) = self.slots.get_mut(usize::from(index)) {
            slot.stage = stage;
            self.set_kind(index, stage.kind());
        }
    }

    fn set_kind(&mut self, index: u16, kind: Kind) {
        let Some(k) = self.kinds.get_mut(usize::from(index)) else { return };
        let was = core::mem::replace(k, kind);
        if let Some(n) = Self::port_of(was).and_then(|p| self.leaving_by.get_mut(p.index())) {
            *n = n.saturating_sub(1);
        }
        if let Some(n) = Self::port_of(kind).and_then(|p| self.leaving_by.get_mut(p.index())) {
            *n += 1;
        }
        let leaves = |k: Kind| matches!(k, Kind::Retire | Kind::Outbound(_));
        let works = |k: Kind| matches!(k, Kind::Trace | Kind::Shade);
        enlist(&mut self.leaving, index, leaves(was), leaves(kind));
        enlist(&mut self.ready, index, works(was), works(kind));
    }

    /// Whether any ray waits to leave (to the host or a neighbour).
    pub fn any_leaving(&self) -> bool {
        !self.leaving.is_empty()
    }

    /// The `n`-th ray waiting to leave, oldest first. A ray that leaves (or
    /// is sent and awaits its reply) drops out, and the next takes its place.
    pub fn leaving_at(&self, n: usize) -> Option<u16> {
        self.leaving.get(n).copied()
    }

    /// Where the ray at `index` leaves by: the neighbour's port, or the host's
    /// for a retirement; `None` if it does not wait to leave.
    pub fn leaves_by(&self, index: u16) -> Option<Port> {
        Self::port_of(*self.kinds.get(usize::from(index))?)
    }

    /// How many rays wait to leave by `port`.
    pub fn leaving_by(&self, port: Port) -> u16 {
        self.leaving_by.get(port.index()).copied().unwrap_or(0)
    }

    fn port_of(kind: Kind) -> Option<Port> {
        match kind {
            Kind::Outbound(port) => Some(port),
            Kind::Retire => Some(Port::Host),
            _ => None,
        }
    }

    /// Whether the ray at `index` was sent to `port` and awaits its reply.
    pub fn is_sent(&self, index: u16, port: Port) -> bool {
        self.kinds.get(usize::from(index)) == Some(&Kind::Sent(port))
    }

    /// Slot capacity.
    pub const fn capacity(&self) -> u16 {
        P as u16
    }

    /// Indices and slots of every held ray.
    pub fn iter(&self) -> impl Iterator<Item = (u16, &Slot)> {
        self.held.iter().filter_map(|&i| self.get(i).map(|s| (i, s)))
    }

    /// The ray of the highest class among those held back after a refusal
    /// by the neighbour on `port` (ties: lowest slot): the one a freed slot
    /// at any level can take.
    pub fn highest_refused(&self, port: Port) -> Option<u16> {
        let key = |&(i, s): &(u16, &Slot)| (s.ray.class, core::cmp::Reverse(i));
        self.of_kind(Kind::Refused(port)).max_by_key(key).map(|(i, _)| i)
    }

    /// Whether a ray of at least `class` is held back for `port`.
    pub fn refused_at_least(&self, port: Port, class: u16) -> bool {
        self.of_kind(Kind::Refused(port)).any(|(_, s)| s.ray.class >= class)
    }

    /// The ray of the lowest class among those to trace, and those to shade
    /// that `can_shade` accepts (ties: lowest slot): the one earliest in its
    /// life, whose work further on (its walk through the next nodes, its
    /// children) is the longest still to come.
    pub fn lowest_ready(&self, can_shade: impl Fn(&Slot) -> bool) -> Option<u16> {
        let mut best: Option<(u16, u16)> = None;
        for &i in &self.ready {
            let Some(slot) = self.get(i) else { continue };
            let key = (slot.ray.class, i);
            if best.is_none_or(|b| key < b) && (matches!(slot.stage, Stage::Trace) || can_shade(slot)) {
                best = Some(key);
            }
        }
        best.map(|(_, i)| i)
    }

    /// Held rays whose stage is of `kind`.
    fn of_kind(&self, kind: Kind) -> impl Iterator<Item = (u16, &Slot)> {
        let matching = self.held.iter().filter(move |&&i| self.kinds.get(usize::from(i)) == Some(&kind));
        matching.filter_map(|&i| self.get(i).map(|s| (i, s)))
    }

    fn free_level(&self, class: u16) -> Option<u16> {
        let class = class.min(self.top);
        let room = |l: u16| if l == 0 { self.base.saturating_sub(self.reserved) } else { self.depth };
        (0..=class).rev().find(|&l| self.used_per_level.get(usize::from(l)).is_some_and(|&u| u < room(l)))
    }
}

/// Adds `index` to `list` or takes it out, as its membership changes from
/// `was` to `is`; the others keep their order.
fn enlist<const P: usize>(list: &mut heapless::Vec<u16, P>, index: u16, was: bool, is: bool) {
    match (was, is) {
        // Cannot fail: a list holds at most the P slots.
        (false, true) => drop(list.push(index)),
        (true, false) => {
            if let Some(pos) = list.iter().position(|&i| i == index) {
                list.remove(pos);
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use link_proto::RayKind;

    #[test]
    fn grants_take_at_most_half_of_level_zero_beyond_its_depth() {
        let mut pool = RayPool::<32>::new();
        // Levels 0..=2 of one slot, and 8 shared: level 0 holds 9.
        pool.configure(2, 1, Some(8)).unwrap();
        let granted = (0..10).take_while(|_| pool.reserve()).count();
        assert_eq!(granted, 4, "half of the 8 beyond the depth");
        // Rays without a grant fill level 0's other 5 slots (one each at
        // levels 1 and 2 for class 2), then are refused.
        let admitted = (0..10).take_while(|_| pool.admit(ray(2), Stage::Trace).is_ok()).count();
        assert_eq!(admitted, 1 + 1 + 5);
        // Every granted ray is admitted, whatever its class, and no more.
        for class in [0, 2, 1, 2] {
            assert!(pool.admit_reserved(ray(class), Stage::Trace).is_ok());
        }
        assert!(pool.admit_reserved(ray(2), Stage::Trace).is_err());
        assert_eq!((pool.len(), pool.reserved()), (11, 0));
    }

    #[test]
    fn a_full_level_zero_sets_nothing_aside() {
        let mut pool = RayPool::<16>::new();
        pool.configure(1, 2, Some(2)).unwrap();
        // Level 0 holds 4; with 3 of them taken, only its depth's worth is left.
        for _ in 0..3 {
            pool.admit(ray(0), Stage::Trace).unwrap();
        }
        assert!(!pool.reserve());
        assert!(pool.admit_reserved(ray(0), Stage::Trace).is_err());
    }

    fn ray(class: u16) -> RayMsg {
        RayMsg {
            origin: [0; 3],
            dir: [1 << 30, 0, 0],
            cell: [0; 3],
            pixel: 0,
            weight: [0; 3],
            credit: 0,
            kind: RayKind::Primary,
            depth: 0,
            ignore: None,
            best: None,
            t_max: None,
            class,
            tag: 0,
        }
    }

    /// Rays of `class` admitted until the first refusal.
    fn admitted(pool: &mut RayPool<8>, class: u16) -> usize {
        (0..).take_while(|_| pool.admit(ray(class), Stage::Trace).is_ok()).count()
    }

    #[test]
    fn without_shared_slots_each_class_reaches_only_its_levels() {
        let mut pool = RayPool::<8>::new();
        pool.configure(2, 2, Some(0)).unwrap();
        assert_eq!(admitted(&mut pool, 0), 2, "level 0 only");
        assert_eq!(admitted(&mut pool, 2), 4, "levels 1 and 2");
        assert_eq!(pool.len(), 6, "two slots of eight stay unused");
    }

    #[test]
    fn slots_left_over_are_shared_at_level_zero() {
        let mut pool = RayPool::<8>::new();
        pool.configure(2, 1, None).unwrap();
        assert_eq!(admitted(&mut pool, 0), 6, "level 0: its own slot and the five left over");
        // The levels above stay kept for their classes.
        assert_eq!(admitted(&mut pool, 1), 1);
        assert_eq!(admitted(&mut pool, 2), 1);
        assert!(pool.free.is_empty());
    }

    /// Stages a test drives rays through.
    fn stage_of(code: u8, port: Port) -> Stage {
        match code % 6 {
            0 => Stage::Trace,
            1 => {
                Stage::Shade { next: 0, children: 1, split: Split { shadow: 1, reflection: 0 }, rgb: [0; 3] }
            }
            2 => {
                Stage::Retire(Retire { pixel: 0, rgb: [0; 3], credit: 1, spawned: 0, rays: 1, background: 0 })
            }
            3 => Stage::Outbound(port),
            4 => Stage::Sent(port),
            _ => Stage::Refused(port),
        }
    }

    proptest::proptest! {
        /// The stage kinds kept beside the slots answer every question as a
        /// scan of the slots' own stages does, whatever the admissions,
        /// stage changes and removals.
        #[test]
        fn kinds_answer_as_the_slots_do(
            ops in proptest::collection::vec((0u8..3, 0u16..64, 0u8..6, 0usize..7, 0u16..6), 1..300),
        ) {
            let mut pool = RayPool::<64>::new();
            pool.configure(5, 1, None).unwrap();
            for (op, at, code, p, class) in ops {
                let port = Port::ALL[p];
                match op {
                    0 => { let _ = pool.admit(ray(class), stage_of(code, port)); }
                    1 if pool.get(at).is_some() => pool.set_stage(at, stage_of(code, port)),
                    _ => { pool.remove(at); }
                }
                let all: std::vec::Vec<(u16, Slot)> = pool.iter().map(|(i, s)| (i, *s)).collect();
                // Lowest (or highest) class first, then lowest slot.
                let min_by = |keep: &dyn Fn(&Slot) -> bool, pick_high: bool| {
                    let rank = |s: &Slot| if pick_high { u16::MAX - s.ray.class } else { s.ray.class };
                    all.iter().filter(|(_, s)| keep(s)).map(|(i, s)| (rank(s), *i)).min().map(|(_, i)| i)
                };
                let leaving = |s: &Slot| matches!(s.stage(), Stage::Retire(_) | Stage::Outbound(_));
                proptest::prop_assert_eq!(pool.any_leaving(), all.iter().any(|(_, s)| leaving(s)));
                let mut listed: std::vec::Vec<u16> = (0..).map_while(|n| pool.leaving_at(n)).collect();
                listed.sort_unstable();
                let mut want: std::vec::Vec<u16> = all.iter().filter(|(_, s)| leaving(s)).map(|(i, _)| *i).collect();
                want.sort_unstable();
                proptest::prop_assert_eq!(listed, want);
                for p in Port::ALL {
                    let by = |s: &Slot| match s.stage() {
                        Stage::Outbound(q) => q == p,
                        Stage::Retire(_) => p == Port::Host,
                        _ => false,
                    };
                    let n = all.iter().filter(|(_, s)| by(s)).count();
                    proptest::prop_assert_eq!(usize::from(pool.leaving_by(p)), n);
                }
                for (i, s) in &all {
                    proptest::prop_assert_eq!(pool.is_sent(*i, port), s.stage() == Stage::Sent(port));
                }
                let refused = |s: &Slot| s.stage() == Stage::Refused(port);
                proptest::prop_assert_eq!(pool.highest_refused(port), min_by(&refused, true));
                let at_least = all.iter().any(|(_, s)| refused(s) && s.ray.class >= class);
                proptest::prop_assert_eq!(pool.refused_at_least(port, class), at_least);
                // Shading allowed only for even classes, to exercise the filter.
                let can_shade = |s: &Slot| s.ray.class.is_multiple_of(2);
                let ready = |s: &Slot| match s.stage() {
                    Stage::Trace => true,
                    Stage::Shade { .. } => can_shade(s),
                    _ => false,
                };
                proptest::prop_assert_eq!(pool.lowest_ready(can_shade), min_by(&ready, false));
            }
        }
    }

    #[test]
    fn rays_leave_oldest_first() {
        let mut pool = RayPool::<8>::new();
        pool.configure(2, 1, None).unwrap();
        let [a, b, c] = [0, 1, 2].map(|_| pool.admit(ray(0), Stage::Trace).unwrap());
        for i in [c, a, b] {
            pool.set_stage(i, Stage::Outbound(Port::Host));
        }
        let list = |pool: &RayPool<8>| (0..).map_while(|n| pool.leaving_at(n)).collect::<std::vec::Vec<_>>();
        assert_eq!(list(&pool), [c, a, b]);
        pool.set_stage(a, Stage::Sent(Port::Host));
        assert_eq!(list(&pool), [c, b]);
        pool.set_stage(a, Stage::Outbound(Port::Host));
        pool.remove(c);
        assert_eq!(list(&pool), [b, a]);
    }

    #[test]
    fn slots_that_do_not_fit_are_refused_with_the_need() {
        let mut pool = RayPool::<8>::new();
        assert_eq!(pool.configure(2, 1, Some(6)), Err(PoolTooSmall { capacity: 8, needed: 9 }));
        assert_eq!(pool.configure(2, 3, None), Err(PoolTooSmall { capacity: 8, needed: 9 }));
        assert!(pool.configure(2, 1, Some(5)).is_ok());
        assert_eq!(admitted(&mut pool, 2), 8);
    }
}
