//! The slab exchange behind a slide: the busier node streams the slab's
//! spheres to the lighter one, which grows its storage, takes them, and
//! commits or refuses the slide as a whole.

use link_proto::{
    ErrorCode, Message, Site, SlideDone, SlideNote, SlideOffer, SlideRefusal, SlideReply, SphereMsg,
};

use crate::link::{Links, Port};
use crate::load::Load;
use crate::slide::{self, Incoming, Outgoing, Side};
use crate::sphere::Sphere;

use super::{Node, Phase};

impl<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> Node<S, R, C, P, O> {
    /// Begins giving the slab up to `boundary` on `side` away.
    pub(super) fn start_giving(&mut self, side: Side, boundary: u16) {
        self.slide.outgoing[side] =
            Some(Outgoing { boundary, offered: false, next_id: 0, sent: 0, done: false });
    }

    /// A load or slide message from the driving-axis neighbour on `side`.
    pub(super) fn handle_slide(&mut self, port: Port, side: Side, msg: Message) {
        let (lo, hi) = self.extent_after_giving();
        match msg {
            Message::Load(l) => {
                self.slide.neighbour_load[side] =
                    Some((Load { running: l.running, waiting: l.waiting }, l.extent));
                self.decide();
            }
            Message::SlideRequest(o) => {
                // The neighbour is lighter and asks for our slab on this side.
                let keeps_a_layer = match side {
                    Side::Lo => o.boundary > lo && o.boundary < hi,
                    Side::Hi => o.boundary < hi && o.boundary > lo,
                };
                // After the frame's end nothing new starts: the host takes
                // the final reports as every boundary's last word.
                let refused = if self.slide.busy(side) || self.phase != Phase::Rendering {
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
            _ => self.fail_at(ErrorCode::Unexpected, port as u32, Site::SlideMessage),
        }
    }

    /// An offered slab: storage grows to hold it (a failure is kept, to refuse at the end).
    fn begin_receiving(&mut self, port: Port, side: Side, boundary: u16) {
        if self.slide.incoming[side].is_some() || self.slide.outgoing[side].is_some() {
            return self.fail_at(ErrorCode::Unexpected, port as u32, Site::OfferDuringSlide);
        }
        self.slide.requested[side] = false;
        let d = self.driving_axis();
        let old_storage = self.region.bounds();
        let grown = slide::with_face(old_storage, d, side, boundary);
        let failed = self.region.set_storage(grown).err();
        self.slide.incoming[side] = Some(Incoming { boundary, old_storage, received: 0, failed });
    }

    /// One sphere of an incoming slab; on overflow the storage shrinks back.
    fn receive_slab_sphere(&mut self, side: Side, s: SphereMsg) {
        let Some(mut incoming) = self.slide.incoming[side] else {
            return self.fail_at(ErrorCode::Unexpected, 0, Site::SlabSphereWithoutOffer);
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

    /// The slab is complete: the box grows, or the slide is refused whole.
    fn finish_receiving(&mut self, port: Port, side: Side, done: SlideDone) {
        let Some(incoming) = self.slide.incoming[side].take() else {
            return self.fail_at(ErrorCode::Unexpected, port as u32, Site::SlabEndWithoutOffer);
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
            let count = self.slide.moves[side].wrapping_add(1);
            self.slide.moves[side] = count;
            let note = SlideNote { boundary: incoming.boundary, high_side: side == Side::Hi, count };
            self.queue_control(Port::Host, Message::SlideNote(note));
        }
    }

    /// The neighbour's answer to a slab given (the box shrinks if it took it)
    /// or to a request.
    fn slide_answered(&mut self, side: Side, reply: SlideReply) {
        if let Some(out) = self.slide.outgoing[side].filter(|o| o.done) {
            self.slide.outgoing[side] = None;
            if reply.refused.is_none() {
                self.slide.moves[side] = self.slide.moves[side].wrapping_add(1);
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
            self.fail_at(ErrorCode::Unexpected, side as u32, Site::SlideReplyUnasked);
        }
    }

    /// Sends the offer, the spheres and the end of every slab being given, as
    /// far as the links take them.
    pub(super) fn stream_slabs<L: Links>(
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
}
