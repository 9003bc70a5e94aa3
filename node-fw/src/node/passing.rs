//! Passing rays between neighbours: admitting or refusing what arrives,
//! taking the replies to what was sent, and retrying refused rays when the
//! neighbour has room again. Back-pressure, never a dropped ray.

use link_proto::ray_wire;
use link_proto::{ErrorCode, RayKind, RayMsg, RayReply, Site};

use crate::link::Port;
use crate::pool::Stage;

use super::{GRANT_TARGET, Node, Phase};

impl<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> Node<S, R, C, P, O> {
    /// A neighbour passes a ray on: admitted to the pool or refused, and
    /// answered either way.
    pub(super) fn admit_ray(&mut self, port: Port, ray: RayMsg) {
        let ray = self.off_the_wire(ray);
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

    /// A neighbour passes a ray on a grant we gave: it takes the slot we set
    /// aside for it, and nothing is answered.
    pub(super) fn admit_granted(&mut self, port: Port, ray: RayMsg) {
        let ray = self.off_the_wire(ray);
        let Some(given) = self.ports.get_mut(port.index()).map(|n| &mut n.grants_given).filter(|g| **g > 0)
        else {
            // A node its host has not spoken to gave no grants: it restarted,
            // and a neighbour's channel resent it the old stream.
            if self.session.is_none() {
                return self.fail(ErrorCode::Restarted, port as u32, 0);
            }
            // More rays than grants: a protocol violation.
            return self.fail_at(ErrorCode::Unexpected, port as u32, Site::GrantedRayWithoutGrant);
        };
        *given -= 1;
        if ray.class > self.pool.top() {
            return self.fail(ErrorCode::ClassOverflow, u32::from(ray.class), u32::from(self.pool.top()));
        }
        if self.pool.admit_reserved(ray, Stage::Trace).is_err() {
            self.fail_at(ErrorCode::Unexpected, port as u32, Site::GrantedRayWithoutSlot);
        }
    }

    /// Whether `ray` leaves for a neighbour with [`ray_wire::ORIGIN_AT_EYE`] for its
    /// origin: a primary ray still on its way from the eye, whose origin the
    /// wire leaves out (every node knows the eye).
    pub(super) fn origin_at_eye(&self, ray: &RayMsg) -> bool {
        ray.kind == RayKind::Primary
            && self.render.as_ref().is_some_and(|r| r.camera.eye.iter().zip(&ray.origin).all(|(a, b)| a == b))
    }

    /// A ray as it arrives: the eye back in place of [`ray_wire::ORIGIN_AT_EYE`]. Before
    /// a frame starts there is no eye, and the ray keeps an origin that its
    /// walk's set-up refuses.
    fn off_the_wire(&self, mut ray: RayMsg) -> RayMsg {
        if ray_wire::at_eye(ray.origin)
            && let Some(r) = &self.render
        {
            ray.origin = r.camera.eye;
        }
        ray
    }

    /// A neighbour grants us `n` more rays: rays held back after its
    /// refusals may go on them at once.
    pub(super) fn take_grant(&mut self, port: Port, n: u16) {
        if let Some(p) = self.ports.get_mut(port.index()) {
            p.grants_held = p.grants_held.saturating_add(n);
        }
        for _ in 0..n.min(GRANT_TARGET) {
            self.retry_refused(port);
        }
    }

    /// Sets free slots aside for every neighbour holding half its grants or
    /// fewer, up to [`GRANT_TARGET`] each, as far as the pool allows (it
    /// keeps slots open for rays not granted: see [`crate::pool::RayPool::reserve`]).
    pub(super) fn top_up_grants(&mut self) {
        if self.phase != Phase::Rendering {
            return;
        }
        for n in self.ports.iter_mut().filter(|n| n.present) {
            if n.grants_given - n.grants_due > GRANT_TARGET / 2 {
                continue;
            }
            let mut more = 0;
            while n.grants_given + more < GRANT_TARGET && self.pool.reserve() {
                more += 1;
            }
            n.grants_given += more;
            n.grants_due += more;
        }
    }

    /// Queues the reply to a ray from `port`.
    fn reply_to_ray(&mut self, port: Port, tag: u16, accepted: bool) {
        let reply = RayReply { tag, accepted };
        let Some(n) = self.ports.get_mut(port.index()) else { return };
        n.refused |= !accepted;
        if n.replies.push_back(reply).is_err() {
            // The neighbour exceeded MAX_OUTSTANDING: a protocol violation.
            self.fail_at(ErrorCode::Unexpected, port as u32, Site::TooManyOutstandingRays);
        }
    }

    /// A neighbour answered a ray we sent: forget it if admitted, hold it back if not.
    pub(super) fn take_reply(&mut self, port: Port, reply: RayReply) {
        let sent = self.pool.is_sent(reply.tag, port);
        if !sent {
            return self.fail_at(ErrorCode::Unexpected, port as u32, Site::ReplyToUnsentRay);
        }
        if let Some(n) = self.ports.get_mut(port.index()) {
            n.outstanding = n.outstanding.saturating_sub(1);
        }
        if reply.accepted {
            self.pool.remove(reply.tag);
            self.slot_freed();
            // The neighbour had room: the next ray held back may have it too.
            self.retry_refused(port);
        } else if self.holds_grant(port) {
            // Refused for room, but a grant needs none.
            self.pool.set_stage(reply.tag, Stage::Outbound(port));
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
    pub(super) fn retry_refused(&mut self, port: Port) {
        if let Some(i) = self.pool.highest_refused(port) {
            self.pool.set_stage(i, Stage::Outbound(port));
        }
    }

    /// How a ray of `class` leaves through `port`: behind the rays held back
    /// for it if one of them has at least its class (the neighbour had no
    /// slot for that one, so none for this), else at once. A higher class must
    /// not wait: it may take levels the held ones cannot, and holding it back
    /// would break the class levels' guarantee of progress. With a grant in
    /// hand nothing waits: a granted ray needs no room.
    pub(super) fn leave_by(&self, port: Port, class: u16) -> Stage {
        if !self.holds_grant(port) && self.pool.refused_at_least(port, class) {
            Stage::Refused(port)
        } else {
            Stage::Outbound(port)
        }
    }

    /// Whether the neighbour on `port` has granted us a ray of this frame
    /// we have not used.
    pub(super) fn holds_grant(&self, port: Port) -> bool {
        self.ports.get(port.index()).is_some_and(|n| n.grants_held > 0 && n.grants_current(self.frames_ended))
    }

    /// A slot freed: tell every neighbour we refused that it may retry.
    pub(super) fn slot_freed(&mut self) {
        for n in self.ports.iter_mut().filter(|n| n.refused) {
            n.space_due = true;
            n.refused = false;
        }
    }
}
