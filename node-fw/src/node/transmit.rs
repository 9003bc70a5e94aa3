//! Sending: replies, notices, rays and retirements, control messages and
//! slabs, as far as the links take them this poll.

use core::cell::Cell;

use link_proto::{
    ErrorCode, Finish, LinkHealth, LoadReport, Message, OutgoingRay, PeerNote, PortHealth, Retirements, Site,
};

use crate::link::{Links, Port};
use crate::pool::Stage;
use crate::slide::Side;

use super::{FINAL_INTERVAL, MAX_OUTSTANDING, Node, Work};

impl<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> Node<S, R, C, P, O> {
    /// Queues a control message; loads beyond half the queue are dropped (a
    /// newer one follows), everything else always fits (at most one per side).
    pub(super) fn queue_control(&mut self, port: Port, msg: Message) {
        let is_load = matches!(msg, Message::Load(_));
        if is_load && self.control.len() >= self.control.capacity() / 2 {
            return;
        }
        if self.control.push_back((port, msg)).is_err() {
            self.fail_at(ErrorCode::Unexpected, port as u32, Site::ControlQueueFull);
        }
    }

    /// Sends what is due, in order of urgency, as far as the links take it.
    pub(super) fn transmit<L: Links>(&mut self, links: &mut L, work: &mut Work) {
        let sends = Sends::default();
        self.send_due(links, &sends, work.computed());
        sends.add_to(work);
    }

    /// [`Self::transmit`], noting in `sends` what went.
    fn send_due<L: Links>(&mut self, links: &mut L, sends: &Sends, computed: bool) {
        let mut send = |links: &mut L, port: Port, msg: Message| {
            let ray = msg.is_ray();
            let granted = matches!(msg, Message::GrantedRay(_));
            let records = match &msg {
                Message::Retire(b) => Some(b.len() as u32),
                _ => None,
            };
            let ok = links.try_send(port, msg).is_ok();
            if ok {
                sends.note(ray, granted, records);
            }
            ok
        };
        if self.hello_due && self.session.is_some() {
            self.hello_due = !send(links, Port::Host, Message::Hello(self.hello()));
        }
        self.greet_neighbours(links, &mut send);
        if let Some(e) = self.error_due
            && send(links, Port::Host, Message::Error(e))
        {
            self.error_due = None;
        }
        for (n, port) in self.ports.iter_mut().zip(Port::NEIGHBOURS) {
            while let Some(&reply) = n.replies.front() {
                if !send(links, port, Message::RayReply(reply)) {
                    break;
                }
                n.replies.pop_front();
            }
            if n.space_due {
                n.space_due = !send(links, port, Message::Space);
            }
        }
        self.top_up_grants();
        for (n, port) in self.ports.iter_mut().zip(Port::NEIGHBOURS) {
            if n.grants_due > 0 && send(links, port, Message::Grant(n.grants_due)) {
                n.grants_due = 0;
            }
            // After any grant: the end voids every grant before it.
            if n.end_due {
                n.end_due = !send(links, port, Message::Finish(Finish { frame: self.frames_ended }));
            }
        }
        self.send_rays(links, &mut send, sends, computed);
        while let Some((port, msg)) = self.control.front().cloned() {
            if !send(links, port, msg) {
                break;
            }
            self.control.pop_front();
        }
        self.stream_slabs(links, &mut send);
        if let Some(frame) = self.load_due.filter(|&f| f != FINAL_INTERVAL || self.settled()) {
            // The host has the frame's link troubles by the time it has every
            // final report: both travel the host link, in order.
            if frame == FINAL_INTERVAL && !self.tell_link_health(links, &mut send) {
                return;
            }
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
                busy_polls: self.totals.busy_polls,
            };
            if send(links, Port::Host, Message::Load(report)) {
                self.load_due = None;
            }
        }
    }

    /// Tells the host what went wrong on each port since it last heard, if
    /// anything did; whether nothing is left to tell.
    fn tell_link_health<L: Links>(
        &mut self,
        links: &mut L,
        send: &mut impl FnMut(&mut L, Port, Message) -> bool,
    ) -> bool {
        let now = Port::ALL.map(|p| links.health(p));
        let mut ports = now;
        for (p, told) in ports.iter_mut().zip(&self.health_told) {
            *p = p.since(*told);
        }
        if ports.iter().all(PortHealth::is_clean) {
            return true;
        }
        let told = send(links, Port::Host, Message::LinkHealth(LinkHealth { node: self.id, ports }));
        if told {
            self.health_told = now;
        }
        told
    }

    /// Whether nothing of the frame is still under way: no slide, and no
    /// note or reply still to go ahead of the final load report.
    fn settled(&self) -> bool {
        self.control.is_empty()
            && self.retiring.is_none()
            && !self.slide.busy(Side::Lo)
            && !self.slide.busy(Side::Hi)
    }

    /// Says hello on every cabled neighbour port once a session, and tells
    /// the host who answered. The hellos are not pending work (a port may
    /// have no cable, and an idle node must still rest); the notes are, the
    /// host being always there.
    fn greet_neighbours<L: Links>(
        &mut self,
        links: &mut L,
        send: &mut impl FnMut(&mut L, Port, Message) -> bool,
    ) {
        // Built only while one is due: this runs on every poll.
        let due = self.session.is_some() && self.ports.iter().any(|n| n.hello_due);
        let hello = due.then(|| Message::Hello(self.hello()));
        for (n, port) in self.ports.iter_mut().zip(Port::NEIGHBOURS) {
            if let Some(hello) = hello.as_ref().filter(|_| n.hello_due && links.cabled(port)) {
                n.hello_due = !send(links, port, hello.clone());
            }
            if let Some(board) = n.peer.filter(|_| n.note_due) {
                n.note_due = !send(links, Port::Host, Message::Peer(PeerNote { port: port as u8, board }));
            }
        }
    }

    /// Sends the ray in `slot` to `port`, packed from its slot: its class
    /// one higher for the hop, tagged with its slot for the reply unless it
    /// goes on a grant; whether the link took it.
    fn send_ray<L: Links>(&self, links: &mut L, port: Port, slot: u16, granted: bool, sends: &Sends) -> bool {
        let Some(ray) = self.pool.get(slot).map(|s| &s.ray) else { return false };
        let out = OutgoingRay {
            ray,
            class: ray.class.saturating_add(1),
            tag: if granted { 0 } else { slot },
            origin_at_eye: self.origin_at_eye(ray),
            granted,
        };
        let ok = links.try_send_ray(port, &out);
        if ok {
            sends.note(true, granted, None);
        }
        ok
    }

    /// The ray in `slot` ended and its record joined the retirements on
    /// their way to the host, which hold all the host needs of it: the slot
    /// is free.
    fn retired(&mut self, slot: u16) {
        self.pool.remove(slot);
        self.slot_freed();
    }

    /// Sends rays bound for neighbours and retirements for the host, oldest
    /// first; `computed` says whether this poll traced, shaded or created.
    fn send_rays<L: Links>(
        &mut self,
        links: &mut L,
        send: &mut impl FnMut(&mut L, Port, Message) -> bool,
        sends: &Sends,
        computed: bool,
    ) {
        if !self.pool.any_leaving() && self.retiring.is_none() {
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
        // Retirements gathered for the host, kept from pass to pass until
        // they go, so that each record is packed once, as it joins.
        let mut batch = self.retiring.take();
        while let Some(i) = self.pool.leaving_at(n) {
            n += 1;
            // Whether the port can take it, before the ray is copied out.
            let Some(port) = self.pool.leaves_by(i) else { continue };
            // A ray on a grant needs no reply, so it does not wait for one.
            let granted = self.holds_grant(port);
            let neighbour = self.ports.get(port.index());
            let waiting =
                !granted && neighbour.is_some_and(|n| usize::from(n.outstanding) >= MAX_OUTSTANDING);
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
                    // Joins the records on their way to the host; a full batch
                    // goes first, and this ray starts the next. While the
                    // full one cannot go, the ray keeps its slot: back-pressure.
                    let r = match batch.as_mut().map(|b| b.push(r)) {
                        Some(Ok(())) => {
                            self.retired(i);
                            n -= 1;
                            continue;
                        }
                        Some(Err(r)) => r,
                        None => r,
                    };
                    if let Some(full_batch) = batch
                        && !send(links, Port::Host, Message::Retire(full_batch))
                    {
                        if close(port_full, &mut open) {
                            break;
                        }
                        continue;
                    }
                    batch = Some(Retirements::new(r));
                    self.retired(i);
                    n -= 1;
                }
                Stage::Outbound(port) if granted => {
                    if !self.send_ray(links, port, i, true, sends) {
                        if close(port_full, &mut open) {
                            break;
                        }
                        continue;
                    }
                    // The link delivers it and the neighbour set a slot aside:
                    // the ray is theirs now.
                    if let Some(n) = self.ports.get_mut(port.index()) {
                        n.grants_held -= 1;
                    }
                    self.pool.remove(i);
                    self.slot_freed();
                    n -= 1;
                }
                Stage::Outbound(port) => {
                    if !self.send_ray(links, port, i, false, sends) {
                        if close(port_full, &mut open) {
                            break;
                        }
                        continue;
                    }
                    if let Some(n) = self.ports.get_mut(port.index()) {
                        n.outstanding += 1;
                    }
                    self.pool.set_stage(i, Stage::Sent(port));
                    n -= 1;
                }
                _ => {}
            }
        }
        // A batch with room waits for company while this poll's work went
        // on (the next poll adds to it); it goes once the node has no work it
        // can do, so the last retirements of a frame never wait.
        let host_full = full.get(Port::Host.index()).is_some_and(|&f| f);
        if let Some(b) = batch {
            let due = b.is_full() || !computed;
            // A message that does not go is kept whole (the send took a copy).
            if host_full || !due || !send(links, Port::Host, Message::Retire(b)) {
                self.retiring = Some(b);
            }
        }
    }
}

/// What a poll sent, counted as it goes by every path that sends (a count
/// each, shared, so that rays packed from their slots count as messages do).
#[derive(Default)]
struct Sends {
    sent: Cell<u32>,
    rays: Cell<u32>,
    granted: Cell<u32>,
    retire_messages: Cell<u32>,
    extra_records: Cell<u32>,
}

impl Sends {
    /// One message went: a ray (on a grant or not), a retirement of
    /// `records`, or anything else.
    fn note(&self, ray: bool, granted: bool, records: Option<u32>) {
        // Not `sent += u32::from(ok)` at the caller: rustc 1.95 at opt-level
        // >= 2 drops the increment when the same bool is branched on after
        // inlining (rust-lang/rust#158206, SimplifyComparisonIntegral), and
        // release builds undercounted sends. The fuzz tests check the count.
        bump(&self.sent, 1);
        if ray {
            bump(&self.rays, 1);
        }
        if granted {
            bump(&self.granted, 1);
        }
        if let Some(records) = records {
            bump(&self.retire_messages, 1);
            bump(&self.extra_records, records.saturating_sub(1));
        }
    }

    /// Adds the counts to the poll's work.
    fn add_to(&self, work: &mut Work) {
        work.sent += self.sent.get();
        work.rays_sent += self.rays.get();
        work.granted_rays += self.granted.get();
        work.retire_messages += self.retire_messages.get();
        work.extra_records += self.extra_records.get();
    }
}

fn bump(count: &Cell<u32>, by: u32) {
    count.set(count.get() + by);
}
