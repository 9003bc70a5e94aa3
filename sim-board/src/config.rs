//! What a board is made of: its settings, and the node and links it runs.

use node_fw::Node;
use node_fw::framed::FramedLinks;
use node_fw::reliable::WINDOW;

use crate::cost::CostModel;
use crate::faults::Faults;
use crate::link_spec::{LinkPreset, LinkSpec};

/// Messages a simulated node's framed port holds until the node takes them.
pub const SIM_INBOX: usize = 16;

/// A node's links when they are byte streams: reliable channels with a
/// board's window.
pub type SimFramed = FramedLinks<WINDOW, SIM_INBOX>;

/// The node firmware as the board runs it: 2048 spheres, 32768 sphere
/// references, 32768 cubes (a 32^3 grid on one node) and 4096 ray slots
/// (an 8x8x8 array with sliding needs 661 class levels at depth 3 and more).
pub type SimNode = Node<2048, 32768, 32768, 4096, 2048>;

/// Board settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// Nodes per axis.
    pub array: [u16; 3],
    /// Node work costs.
    pub cost: CostModel,
    /// Node-to-node links.
    pub link: LinkSpec,
    /// Node-to-host links.
    pub host_link: LinkSpec,
    /// When set, every link carries bytes (CRC-checked frames through the
    /// node firmware's reliable channels) through this fault injector.
    pub faults: Option<Faults>,
    /// Restart node `.0` (a fresh firmware state, as after a reset) at virtual time `.1`.
    pub restart: Option<(u16, u64)>,
    /// Stop with [`crate::SimError::Stalled`] when no node has sent the host anything
    /// for this many cycles while the host waits.
    pub watchdog: u64,
}

impl SimConfig {
    /// Default costs and links ([`LinkPreset::default`]) for an array.
    pub fn new(array: [u16; 3]) -> Self {
        Self::with_links(array, LinkPreset::default())
    }

    /// Default costs and the links of `preset` for an array.
    pub fn with_links(array: [u16; 3], preset: LinkPreset) -> Self {
        Self {
            array,
            cost: CostModel { pass: preset.loop_pass(), ..CostModel::default() },
            link: preset.neighbour(),
            host_link: preset.host(),
            faults: None,
            restart: None,
            watchdog: 200_000_000,
        }
    }
}
