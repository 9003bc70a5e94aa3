//! Helpers shared by the node's integration tests.

use link_proto::{Balance, CameraMsg, InitialRays, RenderStart};

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
