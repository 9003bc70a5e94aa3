//! What a node holds on a board with 64 KiB of RAM.
//!
//! Sizes (measured from the ELF, `scripts/firmware.sh`): the node with its
//! storage, the seven reliable channels and the transmit rings take the
//! static RAM; the rest of the 64 KiB is stack.

use node_fw::Node;
use node_fw::framed::FramedLinks;

/// Spheres a node holds (those touching its storage box).
pub const SPHERES: usize = 128;
/// Sphere references over all cubes of the box.
pub const REFS: usize = 2048;
/// Cubes of the storage box (e.g. 8 x 8 x 16).
pub const CUBES: usize = 1024;
/// Ray slots (class levels x queue depth).
pub const RAYS: usize = 96;
/// Unacknowledged frames per link.
pub const WINDOW: usize = 4;
/// Received messages waiting per port.
pub const INBOX: usize = 2;

/// The node as boards run it.
pub type BoardNode = Node<SPHERES, REFS, CUBES, RAYS>;
/// Its seven reliable channels.
pub type BoardLinks = FramedLinks<WINDOW, INBOX>;
