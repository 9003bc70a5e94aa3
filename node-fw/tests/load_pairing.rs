//! The node below a boundary decides on its latest interval and its
//! neighbour's latest report, whatever their numbers. An emulated board's
//! clock falls behind while it is busy, so the two sides' interval counts
//! drift apart by tens within a frame; compared only on equal numbers, the
//! loads met by chance and boundaries rarely moved (CI saw none in three
//! frames).

mod common;

use common::{Wires, neighbour_load, two_nodes_sliding};
use link_proto::*;
use node_fw::{Node, Port};

type Fw = Node<64, 512, 512, 256, 128>;

#[test]
fn loads_of_different_interval_numbers_are_compared() {
    let (mut node, mut wires) = (Fw::new(0), Wires::default());
    let (host, east) = (Port::Host.index(), Port::toward(0, true).index());
    wires.inbox[host].extend(two_nodes_sliding());
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
        neighbour_load(37, 0, 1000, 4),
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
