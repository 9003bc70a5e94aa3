//! Slide messages to a neighbour stay in order when another port is blocked.
//!
//! A node that has just taken a slab answers the giver with `SlideReply`; if it
//! then decides to give a slab back, its `SlideOffer` must not overtake that
//! reply, or the neighbour, still waiting for the reply, sees an offer while it
//! is giving: a protocol error. Control messages queue in order; once a load
//! report to a busy host sat at the head of that queue, the reply waited behind
//! it and the offer went out first (seen on emulated boards).

mod common;

use common::{Wires, neighbour_load, two_nodes_sliding};
use link_proto::*;
use node_fw::{Node, Port};

type Fw = Node<64, 512, 512, 256, 128>;

#[test]
fn a_slide_reply_is_not_overtaken_by_the_next_offer() {
    let (mut node, mut wires) = (Fw::new(0), Wires::default());
    let (host, east) = (Port::Host.index(), Port::toward(0, true).index());
    wires.inbox[host].extend(two_nodes_sliding());
    node.poll(1, &mut wires);
    assert!(!node.failed());
    // The host stops taking messages: this node's load reports queue up.
    wires.full[host] = true;
    for now in [300, 600, 900, 1001] {
        node.poll(now, &mut wires);
    }
    // The neighbour gives us x in [4, 5), then reports itself idle for the
    // same interval: we take the slab, and at once decide to give one back.
    wires.inbox[east].extend([
        Message::Hello(Hello { node: 1, capacity: Fw::capacity(), ..Hello::host() }),
        Message::SlideOffer(SlideOffer { interval: 0, boundary: 5 }),
        Message::SlideDone(SlideDone { boundary: 5, spheres: 0 }),
        neighbour_load(0, 0, 1000, 3),
    ]);
    node.poll(1002, &mut wires);
    wires.full[host] = false;
    for now in 1003..1010 {
        node.poll(now, &mut wires);
    }
    assert!(!node.failed());
    let slide: Vec<&Message> = wires.sent[east]
        .iter()
        .filter(|m| matches!(m, Message::SlideReply(_) | Message::SlideOffer(_)))
        .collect();
    assert!(
        matches!(slide.as_slice(), [Message::SlideReply(r), Message::SlideOffer(o), ..] if r.boundary == 5 && o.boundary == 4),
        "the reply must go before the next offer: {slide:?}"
    );
}
