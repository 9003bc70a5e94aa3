//! Helpers shared by the node's integration tests (each test binary uses
//! some of them).
#![allow(dead_code)]

use std::collections::VecDeque;

use link_proto::{
    Assign, Balance, Boundaries, CameraMsg, InitialRays, LoadReport, Message, RenderStart, SceneEnd,
    SceneHeader, SlidePolicy,
};
use node_fw::{Links, Port};

/// An 8x8 frame over an 8^3 grid, the eye in front of the z = 0 face, one
/// tile for the whole image, pool depth 2.
pub fn render_start(balance: Balance) -> RenderStart {
    RenderStart {
        frame: 0,
        size: [8, 8],
        camera: CameraMsg {
            eye: [4 << 16, 4 << 16, -(12 << 16)],
            corner: [-(1 << 28), 1 << 28, 1 << 30],
            du: [1 << 26, 0, 0],
            dv: [0, -(1 << 26), 0],
        },
        initial: InitialRays::Parallel,
        tile: [0, 0, 8, 8],
        credit: 1 << 32,
        level_depth: 2,
        // No shared slots: the node tests want back-pressure with few rays.
        shared_slots: Some(0),
        balance: Some(balance),
    }
}

/// Per-port inboxes, ports that refuse sends, and what went out on each port.
#[derive(Default)]
pub struct Wires {
    pub inbox: [VecDeque<Message>; 7],
    pub full: [bool; 7],
    pub sent: [Vec<Message>; 7],
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

/// What the host sends node 0 of a 2x1x1 array over an 8^3 grid: it owns x
/// in [0, 4) and slides along x every 1000 cycles by the paper's rule, any
/// lighter load under the threshold.
pub fn two_nodes_sliding() -> Vec<Message> {
    let balance = Balance { interval: 1000, threshold: u32::MAX, step: 1, policy: SlidePolicy::Paper };
    vec![
        Message::SceneBegin(SceneHeader {
            grid: [8; 3],
            ambient: [8000; 3],
            background: [500; 3],
            max_depth: 1,
            map: link_proto::MapLoad::Sent,
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
        Message::RenderStart(render_start(balance)),
    ]
}

/// Node 1's load report of `interval`.
pub fn neighbour_load(interval: u32, running: u64, waiting: u64, extent: u16) -> Message {
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
