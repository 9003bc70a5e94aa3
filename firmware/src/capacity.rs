//! What a node holds, per board profile.
//!
//! The node with its storage, the seven reliable channels and the transmit
//! rings are the static RAM; the rest is stack. `scripts/firmware.sh` prints
//! each image's sizes against its chip and fails one that does not leave
//! its stack.

use node_fw::Node;
use node_fw::framed::FramedLinks;

/// One profile's storage.
struct Profile {
    spheres: usize,
    refs: usize,
    cubes: usize,
    rays: usize,
    occupancy: usize,
}

/// A small microcontroller's 64 KiB (the emulated mps2-an385 keeps to it).
#[cfg(feature = "mps2-an385")]
const PROFILE: Profile = Profile { spheres: 128, refs: 2048, cubes: 1024, rays: 96, occupancy: 128 };

/// The STM32F413's 320 KiB: the paper's 1000-sphere scene on a 32^3 grid fits
/// a 2x2x2 array (its busiest node of a preview layout needs 7 344 cubes,
/// 241 spheres and 2 289 references).
#[cfg(all(feature = "stm32f413", not(feature = "mps2-an385")))]
const PROFILE: Profile = Profile { spheres: 1024, refs: 32_768, cubes: 32_768, rays: 512, occupancy: 2048 };

/// QEMU's netduinoplus2 has 192 KiB.
#[cfg(all(feature = "netduinoplus2", not(feature = "mps2-an385"), not(feature = "stm32f413")))]
const PROFILE: Profile = Profile { spheres: 512, refs: 16_384, cubes: 16_384, rays: 256, occupancy: 2048 };

/// Spheres a node holds (those touching its storage box).
pub const SPHERES: usize = PROFILE.spheres;
/// Sphere references over all cubes of the box.
pub const REFS: usize = PROFILE.refs;
/// Cubes of the storage box.
pub const CUBES: usize = PROFILE.cubes;
/// Ray slots (class levels x queue depth).
pub const RAYS: usize = PROFILE.rays;
/// Words of the grid's occupancy map, a bit a cube ([`node_fw::occupancy`]):
/// the host maps grids of up to 64 Ki cubes, which the STM32 boards keep
/// whole (8 KiB); the small board keeps 4 Ki cubes (16^3) whole and larger
/// grids in blocks.
pub const OCCUPANCY: usize = PROFILE.occupancy;
/// Unacknowledged frames per link: as many as the host's and the in-memory
/// board's channels keep ([`node_fw::reliable::WINDOW`], sixteen). An
/// acknowledgement with no data to ride on goes alone once it answers half
/// a window, so a stream of granted rays costs an ack frame every eighth
/// ray; the channels leave the small board 10.4 KiB of stack.
pub const WINDOW: usize = node_fw::reliable::WINDOW;
/// Received messages waiting per port.
pub const INBOX: usize = 2;

/// The node as boards run it.
pub type BoardNode = Node<SPHERES, REFS, CUBES, RAYS, OCCUPANCY>;
/// Its seven reliable channels.
pub type BoardLinks = FramedLinks<WINDOW, INBOX>;
