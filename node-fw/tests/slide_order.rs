//! Slide messages to a neighbour stay in order when another port is blocked.
//!
//! A node that has just taken a slab answers the giver with `SlideReply`; if it
//! then decides to give a slab back, its `SlideOffer` must not overtake that
//! reply, or the neighbour, still waiting for the reply, sees an offer while it
//! is giving: a protocol error. Control messages queue in order; once a load
//! report to a busy host sat at the head of that queue, the reply waited behind
//! it and the offer went out first (seen on emulated boards).

mod common;

use std::collections::VecDeque;

use link_proto::*;
use node_fw::{Links, Node, Port};

type Fw = Node<64, 512, 512, 256, 128>;

/// Per-port inboxes, ports that refuse sends, and what went out on each port.
#[derive(Default)]
struct Wires {
    inbox: [VecDeque<Message>; 7],
    full: [bool; 7],
    sent: [Vec<Message>; 7],
}

impl Links for Wires {
    fn recv(&mut self, port: Port) -> Option<Message> {
        self.inbox[port.index()].pop_front()
    }
    fn try_send(&mut self, port: Port, msg: Message) -> Result<(), Message> {
        if self.full[port.index()] {
            return Err(msg);
        }
        self.sent[port.index()].push(msg);
        Ok(())
    }
}

/// Node 0 of a 2x1x1 array over an 8^3 grid, owning x in [0, 4), sliding along x.
fn setup() -> Vec<Message> {
    let balance = Balance { interval: 1000, threshold: u32::MAX, step: 1, policy: SlidePolicy::Paper };
    vec![
        Message::SceneBegin(SceneHeader {
            grid: [8; 3],
            ambient: [8000; 3],
            background: [500; 3],
            max_depth: 1,
        }),
        Message::Assign(Assign {
            array: [2, 1, 1],
            coord: [0; 3],
            lo: [0; 3],
            hi: [4, 8, 8],
            driving_axis: 0,
            boundaries: Boundaries::Whole,
        }),
        Message::SceneEnd(SceneEnd { spheres: 0, lights: 0, occupancy: 0 }),
        Message::RenderStart(common::render_start(balance)),
    ]
}

fn load(interval: u32, running: u64, waiting: u64, extent: u16) -> Message {
    Message::Load(LoadReport {
        node: 1,
        interval,
        running,
        waiting,
        rays: 0,
        sphere_tests: 0,
        cube_steps: 0,
        refused: 0,
        extent,
        busy_polls: 0,
    })
}

#[test]
fn a_slide_reply_is_not_overtaken_by_the_next_offer() {
    let (mut node, mut wires) = (Fw::new(0), Wires::default());
    let (host, east) = (Port::Host.index(), Port::toward(0, true).index());
    wires.inbox[host].extend(setup());
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
        load(0, 0, 1000, 3),
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
