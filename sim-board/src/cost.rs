//! What work and links cost in virtual time (ticks: CPU cycles of a node).

use node_fw::Work;

/// Cycles charged per unit of node work.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CostModel {
    /// One unit-cube step of the digital line.
    pub cube_step: u64,
    /// One cube walked beyond the box through the occupancy map's clear
    /// cubes ([`node_fw::occupancy::Occupancy::walk_clear`]).
    pub clear_step: u64,
    /// Looking whether a leaving ray is near enough the grid's end to walk it on.
    pub clear_look: u64,
    /// Looking whether a leaving ray still needs the sphere it ignores
    /// ([`node_fw::Subregion::left_behind`]).
    pub ignore_look: u64,
    /// One ray/sphere test.
    pub sphere_test: u64,
    /// What a test that meets its sphere ahead costs beyond a miss: the
    /// discriminant's root and the hit's depth.
    pub sphere_hit: u64,
    /// Setting up one walk (validating and resuming a ray).
    pub trace: u64,
    /// Shading one hit (evaluating and spawning children).
    pub shade: u64,
    /// Creating one initial ray (camera direction, grid entry).
    pub create: u64,
    /// Handling one received or sent ray message whose acknowledgement
    /// rides on its reply.
    pub ray_message: u64,
    /// Handling one received or sent ray passed on a grant: no reply, so its
    /// acknowledgement goes alone (one for every half window of rays).
    pub granted_ray: u64,
    /// Handling one received or sent ray passed on a grant in a batch, the
    /// frame shared with the rays queued behind a busy link.
    pub batched_ray: u64,
    /// Handling one received or sent message of any other kind: replies,
    /// space notices and control, a few bytes each.
    pub short_message: u64,
    /// Sending a retirement message with one record.
    pub retire_message: u64,
    /// Each further record in a retirement message.
    pub retire_record: u64,
    /// Taking a piece of the map of occupied cubes, beyond its handling as
    /// a short message.
    pub map_take: u64,
    /// Each poll that did work: the rest of the board's pass of its loop
    /// around it (every UART polled and its bytes moved a register at a
    /// time, every channel offered its frames, the pool's and the links'
    /// bookkeeping), which no kernel above measures. A property of how the
    /// board moves bytes, so its link preset sets it
    /// ([`crate::LinkPreset::loop_pass`]); none by default.
    pub pass: u64,
}

impl Default for CostModel {
    /// Cortex-M3 instructions of the node firmware, measured on the emulated
    /// mps2-an385 (`scripts/firmware.sh` runs the `kernels` binary under
    /// `qemu-system-arm -icount shift=0`): a walked cube (step and inside
    /// test) 109.1; a cube walked on through the occupancy map (from ten cubes
    /// before the grid's end, the call and its look included) 174.1, and a
    /// look that finds the end too far 101.0; a look at whether a leaving ray
    /// still needs the sphere it ignores (32 spheres held) 141.3; a sphere test over a
    /// mostly-missing list 211.0, and one that meets its sphere ahead 1 525.7
    /// (the root and the depth: 1 307 more); a walk's
    /// set-up (the received ray's line checked, the walk resumed) 279.7; a
    /// shaded hit with one light and a mirror 5 489.2 (the surface and both
    /// children, evaluated once; a hit waiting for pool room pays again for
    /// the children it spawns later); an initial ray (pixel line, ray, entry
    /// cube) 2 814.2. Messages through a reliable channel, whose
    /// acknowledgements ride on data going back or, with none, go alone once
    /// per half window (eight frames on a board): one end of a hop (the ray in
    /// its compact wire form, packed from where the node keeps it, the reply carrying the ray's ack, the reply's
    /// ack alone every eighth reply) 1 221.9, and of a ray reply with its ack
    /// alone every eighth time 464.8, which stands for every short message; a
    /// ray end is charged the difference, 757 (the UART's bytes are the link
    /// model's). One end of a hop on a grant (the ray, and an ack alone for
    /// every eighth ray) 798.5; of one in a batch of four in one frame
    /// 655.5. The rays are as the paper's 32^3 grid has them: half usual
    /// primaries from the eye, half reflections from inside the grid with
    /// half their pixel's credit, half of those naming the sphere they leave
    /// (33.0 bytes a frame). A node's end of a retirement (the host's acks
    /// taken) 1 082.7 with one record, 2 738.7 with six: 331 a further record.
    /// A piece of the occupancy map taken (256 cubes, a quarter marked) 270.1.
    fn default() -> Self {
        Self {
            cube_step: 109,
            clear_step: 174,
            clear_look: 101,
            ignore_look: 141,
            sphere_test: 213,
            sphere_hit: 1_307,
            trace: 280,
            shade: 5_489,
            create: 2_814,
            ray_message: 757,
            granted_ray: 799,
            batched_ray: 656,
            short_message: 465,
            retire_message: 1_083,
            retire_record: 331,
            map_take: 270,
            pass: 0,
        }
    }
}

impl CostModel {
    /// What a message spares each end by sharing a frame with the messages
    /// before it: the frame's own handling, from the `hop_batched` kernel's
    /// four rays to a frame against `hop_granted`'s one (the frame's part
    /// `f` and a ray's `r` from `f + r = granted_ray`, `f + 4r = 4 batched_ray`).
    pub fn frame_spared(&self) -> u64 {
        (4 * self.granted_ray).saturating_sub(4 * self.batched_ray) / 3
    }

    /// Cycles for one poll's work (at least one if anything was done).
    pub fn charge(&self, w: &Work) -> u64 {
        self.split(w).total().max(u64::from(w.is_busy()))
    }

    /// Cycles for one poll's work, by what they were spent on.
    pub fn split(&self, w: &Work) -> Busy {
        let short = w.received + w.sent - w.rays_received - w.rays_sent - w.retire_messages;
        let answered = w.rays_received + w.rays_sent - w.granted_rays;
        Busy {
            compute: u64::from(w.cube_steps) * self.cube_step
                + u64::from(w.clear_steps) * self.clear_step
                + u64::from(w.clear_looks) * self.clear_look
                + u64::from(w.ignore_looks) * self.ignore_look
                + u64::from(w.sphere_tests) * self.sphere_test
                + u64::from(w.sphere_hits) * self.sphere_hit
                + u64::from(w.shades) * self.shade
                + u64::from(w.created) * self.create,
            setup: u64::from(w.traces) * self.trace,
            messaging: u64::from(answered) * self.ray_message
                + u64::from(w.granted_rays) * self.granted_ray
                + u64::from(short) * self.short_message
                + u64::from(w.retire_messages) * self.retire_message
                + u64::from(w.extra_records) * self.retire_record
                + u64::from(w.map_messages) * self.map_take,
            pass: if w.is_busy() { self.pass } else { 0 },
            polls: u64::from(w.is_busy()),
            sent: u64::from(w.sent),
            rays_sent: u64::from(w.rays_sent),
        }
    }
}

/// A node's busy cycles by what they were spent on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Busy {
    /// Walking cubes, testing spheres, shading hits and creating initial rays:
    /// the work a single node would do too.
    pub compute: u64,
    /// Setting up walks: checking a ray that arrived or was spawned and
    /// resuming its line.
    pub setup: u64,
    /// Handling messages (framing, checks, the reliable channel) and moving
    /// their bytes between the UARTs and memory.
    pub messaging: u64,
    /// The board's loop around polls that did work: its passes over the
    /// UARTs, channels and pool.
    pub pass: u64,
    /// Polls that did work (a count, not cycles).
    pub polls: u64,
    /// Messages sent, to neighbours and the host (a count, not cycles).
    pub sent: u64,
    /// Of those, rays: the hops rays made from this node (a count).
    pub rays_sent: u64,
}

impl Busy {
    /// All busy cycles.
    pub fn total(&self) -> u64 {
        self.compute + self.setup + self.messaging + self.pass
    }
}

impl std::iter::Sum for Busy {
    fn sum<I: Iterator<Item = Busy>>(iter: I) -> Busy {
        iter.fold(Busy::default(), |mut total, b| {
            total += b;
            total
        })
    }
}

impl std::ops::AddAssign for Busy {
    fn add_assign(&mut self, other: Busy) {
        self.compute += other.compute;
        self.setup += other.setup;
        self.messaging += other.messaging;
        self.pass += other.pass;
        self.polls += other.polls;
        self.sent += other.sent;
        self.rays_sent += other.rays_sent;
    }
}

impl std::ops::Sub for Busy {
    type Output = Busy;

    /// What was spent between two readings of one node, `self` the later.
    fn sub(self, earlier: Busy) -> Busy {
        Busy {
            compute: self.compute.saturating_sub(earlier.compute),
            setup: self.setup.saturating_sub(earlier.setup),
            messaging: self.messaging.saturating_sub(earlier.messaging),
            pass: self.pass.saturating_sub(earlier.pass),
            polls: self.polls.saturating_sub(earlier.polls),
            sent: self.sent.saturating_sub(earlier.sent),
            rays_sent: self.rays_sent.saturating_sub(earlier.rays_sent),
        }
    }
}

/// A link's timing and what its bytes cost the node's CPU. Built from a
/// clock, a line rate and a way of moving bytes by [`crate::LinkSpec`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinkModel {
    /// Cycles to put one byte on the wire.
    pub byte: u64,
    /// Cycles of the node's CPU to move one byte between the UART and
    /// memory, paid by the sender and again by the receiver.
    pub byte_cpu: u64,
    /// Cycles of the sender's CPU to start a frame on its way (a DMA
    /// transfer's set-up and its completion interrupt).
    pub frame_cpu: u64,
    /// Cycles from the last byte sent to the message's arrival.
    pub latency: u64,
    /// Messages a link holds before the sender sees it full.
    pub capacity: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_and_short_messages_are_charged_apart() {
        let c =
            CostModel { cube_step: 100, ray_message: 5_000, short_message: 2_000, ..CostModel::default() };
        let w =
            Work { received: 3, sent: 4, rays_received: 1, rays_sent: 2, cube_steps: 10, ..Work::default() };
        assert_eq!(c.charge(&w), 3 * 5_000 + 4 * 2_000 + 10 * 100);
        // Anything done costs at least a cycle; nothing costs nothing.
        let free = CostModel { cube_step: 0, ..c };
        assert_eq!(free.charge(&Work { cube_steps: 5, ..Work::default() }), 1);
        assert_eq!(c.charge(&Work::default()), 0);
    }

    #[test]
    fn a_message_sharing_a_frame_spares_the_frames_part() {
        // One ray alone 1 200, four in one frame 900 each: the frame's part
        // f and a ray's r solve f + r = 1 200, f + 4 r = 3 600, so f = 400.
        let c = CostModel { granted_ray: 1_200, batched_ray: 900, ..CostModel::default() };
        assert_eq!(c.frame_spared(), 400);
        // A batch that costs more than frames alone spares nothing.
        assert_eq!(CostModel { batched_ray: 1_300, ..c }.frame_spared(), 0);
    }

    #[test]
    fn the_split_adds_up_to_the_charge() {
        // Prices of their own, so that the sums below do not follow the
        // measured defaults.
        let c = CostModel {
            cube_step: 114,
            clear_step: 170,
            clear_look: 95,
            ignore_look: 150,
            sphere_test: 224,
            sphere_hit: 1_290,
            trace: 440,
            shade: 7_186,
            create: 2_924,
            ray_message: 1_545,
            granted_ray: 1_872,
            batched_ray: 1_500,
            short_message: 984,
            retire_message: 1_603,
            retire_record: 462,
            map_take: 301,
            pass: 0,
        };
        let w = Work {
            cube_steps: 7,
            clear_steps: 4,
            clear_looks: 2,
            ignore_looks: 3,
            sphere_tests: 3,
            sphere_hits: 2,
            traces: 2,
            shades: 1,
            created: 1,
            received: 5,
            sent: 4,
            rays_received: 2,
            rays_sent: 1,
            granted_rays: 1,
            retire_messages: 2,
            extra_records: 3,
            map_messages: 1,
        };
        let split = c.split(&w);
        assert_eq!(split.compute, 7 * 114 + 4 * 170 + 2 * 95 + 3 * 150 + 3 * 224 + 2 * 1_290 + 7_186 + 2_924);
        assert_eq!(split.setup, 2 * 440);
        assert_eq!(split.messaging, 2 * 1_545 + 1_872 + 4 * 984 + 2 * 1_603 + 3 * 462 + 301);
        assert_eq!(split.total(), c.charge(&w));
    }
}
