//! Grants a neighbour gives between frames stand when the scene is sent
//! again.
//!
//! A neighbour that has its scene and its start first grants us slots for
//! the next frame before our own `SceneBegin` arrives (a host writes one
//! node's scene after another). Zeroing the grants we held when the scene
//! began left that neighbour waiting all frame for grants never used, and
//! every ray to it took a reply of its own. Only a scene that cuts a frame
//! short voids them; after a frame's end, the neighbour's end note has
//! voided the old ones already.

mod common;

use common::{Wires, two_nodes_sliding};
use link_proto::*;
use node_fw::{Node, Port};

type Fw = Node<64, 512, 512, 256, 128>;

/// Node 0 of 2x1x1 (x in [0, 4) of an 8^3 grid) on static boxes, a frame's
/// initial rays all made here: those entering x in [4, 8) go east.
fn static_frame(frame: u32) -> Vec<Message> {
    two_nodes_sliding()
        .into_iter()
        .map(|m| match m {
            Message::RenderStart(r) => Message::RenderStart(RenderStart { frame, balance: None, ..r }),
            m => m,
        })
        .collect()
}

/// Rays node 0 sent east in the frame: (on a grant, without one).
fn rays_east(wires: &Wires) -> (usize, usize) {
    let east = &wires.sent[Port::toward(0, true).index()];
    let granted = east.iter().filter(|m| matches!(m, Message::GrantedRay(_))).count();
    let plain = east.iter().filter(|m| matches!(m, Message::Ray(_))).count();
    (granted, plain)
}

#[test]
fn grants_given_before_the_scene_is_sent_again_stand() {
    let (mut node, mut wires) = (Fw::new(0), Wires::default());
    let (host, east) = (Port::Host.index(), Port::toward(0, true).index());
    wires.inbox[host].extend(static_frame(0));
    for now in 1..20 {
        node.poll(now, &mut wires);
    }
    // The frame ends: the host's Finish, the neighbour's end note.
    wires.inbox[host].push_back(Message::Finish(Finish { frame: 0 }));
    wires.inbox[east].push_back(Message::Finish(Finish { frame: 0 }));
    for now in 20..30 {
        node.poll(now, &mut wires);
    }
    assert!(!node.failed());
    // The neighbour starts frame 1 first and grants us slots; then our
    // scene comes again, and our start.
    wires.inbox[east].push_back(Message::Grant(4));
    node.poll(30, &mut wires);
    wires.sent.iter_mut().for_each(Vec::clear);
    wires.inbox[host].extend(static_frame(1));
    for now in 31..60 {
        node.poll(now, &mut wires);
    }
    assert!(!node.failed());
    let (granted, plain) = rays_east(&wires);
    assert_eq!(granted, 4, "the four grants are used ({plain} rays went without one)");
}

/// A scene that keeps a map of occupied cubes the node was never sent is
/// refused, and the host is told where: the node would otherwise walk rays
/// on through cubes it knows nothing of.
#[test]
fn a_scene_that_keeps_a_map_never_sent_is_refused() {
    let (mut node, mut wires) = (Fw::new(0), Wires::default());
    let host = Port::Host.index();
    let keeps = |m| match m {
        Message::SceneBegin(h) => Message::SceneBegin(SceneHeader { map: MapLoad::Kept, ..h }),
        m => m,
    };
    wires.inbox[host].extend(static_frame(0).into_iter().map(keeps));
    for now in 1..20 {
        node.poll(now, &mut wires);
    }
    assert!(node.failed());
    let errors: Vec<ErrorReport> = wires.sent[host]
        .iter()
        .filter_map(|m| match m {
            Message::Error(e) => Some(*e),
            _ => None,
        })
        .collect();
    let first = errors.first().expect("an error report to the host");
    assert_eq!(
        (first.code, Found::from_wire(first.b)),
        (ErrorCode::Unexpected, Some(Found::Site(Site::KeptMapNotHeld)))
    );
}
