//! `Node::renew` makes a node what `Node::new` makes, in place: from the
//! zero-filled storage a board keeps its node in, and from a node that has
//! been working. Compared through `Debug`, which shows every field (the
//! slots of the pool, the held spheres, the queues' contents).

use link_proto::{
    Assign, Boundaries, Hello, LightMsg, MaterialMsg, Message, SceneEnd, SceneHeader, SphereMsg,
};
use node_fw::Port;
use node_fw::framed::FramedLinks;
use node_fw::node::Node;
use node_fw::reliable::Channel;

type TestNode = Node<8, 64, 64, 16, 8>;

/// The node as a board's static starts: all bytes zero. `mem::zeroed` in a
/// constant is checked by the compiler, which refuses to build a type that
/// all-zero bytes are not a valid value of (as the firmware's static is).
#[allow(unsafe_code)]
const ZEROED: TestNode = unsafe { core::mem::zeroed() };

fn fresh(id: u16) -> String {
    format!("{:?}", TestNode::new(id))
}

#[test]
fn a_zero_filled_node_renewed_is_a_new_one() {
    let mut node = Box::new(ZEROED);
    assert_ne!(format!("{node:?}"), fresh(3), "zero bytes alone are not a new node");
    node.renew(3);
    assert_eq!(format!("{node:?}"), fresh(3));
}

#[test]
fn a_working_node_renewed_is_a_new_one() {
    let (mut node, mut links) = (Box::new(TestNode::new(0)), FramedLinks::<4, 4>::new(5));
    links.set_incarnation(1);
    let mut host = Channel::<8>::new(5);
    host.set_incarnation(500);
    let header = SceneHeader {
        grid: [4, 4, 4],
        ambient: [0; 3],
        background: [0; 3],
        max_depth: 1,
        map: link_proto::MapLoad::Sent,
    };
    let assign = Assign {
        array: [1; 3],
        coord: [0; 3],
        lo: [0; 3],
        hi: [4; 3],
        driving_axis: 0,
        boundaries: Boundaries::Whole,
    };
    let material = MaterialMsg {
        color: [20000; 3],
        ambient: 3000,
        diffuse: 20000,
        specular: 0,
        shininess: 1,
        reflect: 0,
    };
    let sphere = SphereMsg { id: 0, center: [2 << 16; 3], radius: 1 << 16, material };
    let light = LightMsg { id: 0, position: [3 << 16; 3], color: [20000; 3] };
    for m in [
        Message::Hello(Hello::host()),
        Message::SceneBegin(header),
        Message::Assign(assign),
        Message::Sphere(sphere),
        Message::Light(light),
        Message::SceneEnd(SceneEnd { spheres: 1, lights: 1, occupancy: 0 }),
    ] {
        host.send(m).unwrap();
    }
    for now in 1..60 {
        node.poll(now, &mut links);
        let mut to_host = Vec::new();
        links.transmit(now, |port, bytes| {
            if port == Port::Host {
                to_host.extend_from_slice(bytes);
            }
            true
        });
        host.receive(&to_host, |_| true);
        let mut to_node = Vec::new();
        host.transmit(now, |bytes| {
            to_node.extend_from_slice(bytes);
            true
        });
        links.ingest(Port::Host, &to_node);
    }
    let working = format!("{node:?}");
    assert!(working.contains("phase: Loaded") && working.contains("spheres: [Sphere"), "{working}");
    node.renew(5);
    assert_eq!(format!("{node:?}"), fresh(5));
}
