//! The node below a boundary decides on its latest interval and its
//! neighbour's latest report, whatever their numbers. An emulated board's
//! clock falls behind while it is busy, so the two sides' interval counts
//! drift apart by tens within a frame; compared only on equal numbers, the
//! loads met by chance and boundaries rarely moved (CI saw none in three
//! frames).

mod common;

use std::collections::VecDeque;

use link_proto::*;
use node_fw::{Links, Node, Port};

type Fw = Node<64, 512, 512, 256, 128>;

/// Per-port inboxes and what went out on each port.
#[derive(Default)]
struct Wires {
    inbox: [VecDeque<Message>; 7],
    sent: [Vec<Message>; 7],
}

impl Links for Wires {
    fn recv(&mut self, port: Port) -> Option<Message> {
        self.inbox[port.index()].pop_front()
    }
    fn try_send(&mut self, port: Port, msg: Message) -> Result<(), Message> {
        self.sent[port.index()].push(msg);
        Ok(())
    }
}

/// Node 0 of a 2x1x1 array over an 8^3 grid, owning x in [0, 4), sliding
/// along x every 1000 cycles with the paper's rule.
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

/// The neighbour's report of an idle `interval`.
fn idle_neighbour(interval: u32) -> Message {
    Message::Load(LoadReport {
        node: 1,
        interval,
        running: 0,
        waiting: 1000,
        rays: 0,
        sphere_tests: 0,
        cube_steps: 0,
        refused: 0,
        extent: 4,
        busy_polls: 0,
    })
}

#[test]
fn loads_of_different_interval_numbers_are_compared() {
    let (mut node, mut wires) = (Fw::new(0), Wires::default());
    let (host, east) = (Port::Host.index(), Port::toward(0, true).index());
    wires.inbox[host].extend(setup());
    // Busy with its initial rays through its first interval.
    for now in [1, 300, 600, 900, 1001] {
        node.poll(now, &mut wires);
    }
    let own = wires.sent[host].iter().find_map(|m| match m {
        Message::Load(l) if l.node == 0 => Some(*l),
        _ => None,
    });
    assert!(own.is_some_and(|l| l.interval == 0 && l.running > 0), "own first interval: {own:?}");
    // The neighbour's clock is 37 intervals ahead; it was idle.
    wires.inbox[east].extend([
        Message::Hello(Hello { node: 1, capacity: Fw::capacity(), ..Hello::host() }),
        idle_neighbour(37),
    ]);
    for now in 1002..1010 {
        node.poll(now, &mut wires);
    }
    assert!(!node.failed());
    let offers: Vec<&Message> =
        wires.sent[east].iter().filter(|m| matches!(m, Message::SlideOffer(_))).collect();
    assert!(
        matches!(offers.as_slice(), [Message::SlideOffer(o)] if o.boundary == 3),
        "the busier node gives one layer to the idle one: {offers:?}"
    );
}
