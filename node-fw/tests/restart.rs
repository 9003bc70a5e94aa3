//! Restarts seen through framed links: a new host session makes a node start
//! over and say hello again; a restarted neighbour is reported to the host;
//! what a neighbour sent in the session before is dropped.

use link_proto::{
    Assign, Boundaries, ErrorCode, ErrorReport, Found, Hello, Message, RayReply, SceneHeader, Site,
};
use node_fw::framed::FramedLinks;
use node_fw::node::Node;
use node_fw::reliable::Channel;
use node_fw::{Links, Port};

type TestNode = Node<8, 64, 64, 16, 8>;
type TestLinks = FramedLinks<4, 4>;

/// A peer of the node on `port`: a channel of its own incarnation.
fn peer(incarnation: u32) -> Channel<4> {
    let mut c = Channel::new(5);
    c.set_incarnation(incarnation);
    c
}

/// Polls the node and moves bytes between it and `peer` on `port` for a while;
/// returns what the peer received.
fn run(
    node: &mut TestNode,
    links: &mut TestLinks,
    port: Port,
    peer: &mut Channel<4>,
    now: &mut u64,
) -> Vec<Message> {
    let mut got = Vec::new();
    for _ in 0..60 {
        *now += 1;
        node.poll(*now, links);
        let mut to_peer = Vec::new();
        links.transmit(*now, |p, bytes| {
            if p == port {
                to_peer.extend_from_slice(bytes);
            }
            true
        });
        let mut to_node = Vec::new();
        peer.transmit(*now, |bytes| {
            to_node.extend_from_slice(bytes);
            true
        });
        links.ingest(port, &to_node);
        peer.receive(&to_peer, |m| {
            got.push(m);
            true
        });
    }
    got
}

fn hello() -> Message {
    Message::Hello(Hello::host())
}

/// A neighbour's hello naming host session `session`.
fn neighbour_hello(session: u32) -> Message {
    Message::Hello(Hello { node: 1, capacity: TestNode::capacity(), session, ..Hello::host() })
}

fn assign() -> Message {
    let c = [0, 0, 0];
    let a = [1, 1, 1];
    Message::Assign(Assign {
        array: a,
        coord: c,
        lo: c,
        hi: [4, 4, 4],
        driving_axis: 0,
        boundaries: Boundaries::Whole,
    })
}

/// A node whose host, of incarnation 500, has said hello, and been greeted
/// back once.
fn greeted_by_host() -> (TestNode, TestLinks, Channel<4>, u64) {
    let (mut node, mut links, mut now) = (TestNode::new(0), TestLinks::new(5), 0);
    links.set_incarnation(1);
    let mut host = peer(500);
    host.send(hello()).unwrap();
    let got = run(&mut node, &mut links, Port::Host, &mut host, &mut now);
    assert_eq!(said_hello(&got), 1);
    (node, links, host, now)
}

/// The first error report among `got`.
fn error_in(got: &[Message]) -> Option<ErrorReport> {
    got.iter().find_map(|m| match m {
        Message::Error(e) => Some(*e),
        _ => None,
    })
}

fn said_hello(got: &[Message]) -> usize {
    got.iter().filter(|m| matches!(m, Message::Hello(_))).count()
}

#[test]
fn a_new_host_session_makes_the_node_start_over() {
    let (mut node, mut links, mut now) = (TestNode::new(0), TestLinks::new(5), 0);
    links.set_incarnation(1);
    let mut host = peer(500);
    let header = SceneHeader {
        grid: [4, 4, 4],
        ambient: [0; 3],
        background: [0; 3],
        max_depth: 1,
        map: link_proto::MapLoad::Sent,
    };
    for m in [hello(), Message::SceneBegin(header), assign()] {
        host.send(m).unwrap();
    }
    let got = run(&mut node, &mut links, Port::Host, &mut host, &mut now);
    assert_eq!(said_hello(&got), 1);
    assert!(node.assignment().is_some());

    // The host program starts again: a new incarnation on the same wire.
    let mut host = peer(501);
    host.send(hello()).unwrap();
    let got = run(&mut node, &mut links, Port::Host, &mut host, &mut now);
    assert_eq!(said_hello(&got), 1, "the node greets the new session: {got:?}");
    assert!(node.assignment().is_none(), "and has dropped the old session's assignment");
    assert!(!node.failed());
}

#[test]
fn a_restarted_neighbour_is_reported_to_the_host() {
    let (mut node, mut links, mut host, mut now) = greeted_by_host();

    // The +x neighbour talks, restarts, and talks again.
    for incarnation in [40, 41] {
        let mut neighbour = peer(incarnation);
        neighbour.send(Message::Space).unwrap();
        run(&mut node, &mut links, Port::PosX, &mut neighbour, &mut now);
    }
    let got = run(&mut node, &mut links, Port::Host, &mut host, &mut now);
    let report = error_in(&got).expect("the node reports the restart");
    assert_eq!((report.code, report.a), (ErrorCode::PeerRestarted, Port::PosX as u32));
    assert!(node.failed());
    assert_eq!(links.peer_restarted(), None, "the restart is reported once");
}

#[test]
fn a_neighbours_message_of_the_session_before_is_dropped() {
    let (mut node, mut links, _, mut now) = greeted_by_host();
    let mut neighbour = peer(40);
    neighbour.send(neighbour_hello(500)).unwrap();
    run(&mut node, &mut links, Port::PosX, &mut neighbour, &mut now);

    // A new host session; the neighbour has not joined it yet, and a reply
    // of the session before (to a ray the node forgot) is still on its way.
    let mut host = peer(501);
    host.send(hello()).unwrap();
    run(&mut node, &mut links, Port::Host, &mut host, &mut now);
    let stale = Message::RayReply(RayReply { tag: 3, accepted: true });
    neighbour.send(stale.clone()).unwrap();
    run(&mut node, &mut links, Port::PosX, &mut neighbour, &mut now);
    assert!(!node.failed(), "a reply of the session before is dropped");

    // Once the neighbour has said the new session, the same reply is taken,
    // and refers to no ray this node sent.
    neighbour.send(neighbour_hello(501)).unwrap();
    neighbour.send(stale).unwrap();
    run(&mut node, &mut links, Port::PosX, &mut neighbour, &mut now);
    let got = run(&mut node, &mut links, Port::Host, &mut host, &mut now);
    let report = error_in(&got).expect("the node reports the reply");
    assert_eq!(
        (report.code, report.b),
        (ErrorCode::Unexpected, Found::from(Site::ReplyToUnsentRay).to_wire())
    );
}
