//! How to render: the choices a user makes, before anything is computed
//! from the scene.

use link_proto::{Balance, InitialRays};
use sim_board::{LinkPreset, SimConfig};

use crate::error::HostError;

/// Who creates the initial rays: a sub-image per node, chosen by the host.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Initial {
    /// Every node creates the rays of a regular sub-image (the paper's
    /// parallel mode, Fig. 7 C).
    Parallel,
    /// The node holding the eye creates all of them (Fig. 7 B).
    EyeNode,
    /// The nodes on the face toward the eye, and on a side face it sees at an
    /// angle, create the rays that enter through their part of it
    /// ([`crate::plan::entry`]; beyond the paper).
    Entry,
}

impl Initial {
    /// What the nodes are told: they create their tile's rays either way.
    pub fn wire(self) -> InitialRays {
        match self {
            Self::Parallel | Self::Entry => InitialRays::Parallel,
            Self::EyeNode => InitialRays::EyeNode,
        }
    }

    /// The name on the command line and in summaries.
    pub fn name(self) -> &'static str {
        match self {
            Self::Parallel => "parallel",
            Self::EyeNode => "eye",
            Self::Entry => "entry",
        }
    }
}

/// How the grid is first cut into subregions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Even boxes (the paper's start).
    Even,
    /// Cut to a preview: the host renders the frame at half the resolution
    /// per axis with the node kernels, measures each cube's cost and fits the
    /// partition to it ([`Partition::fitted`](crate::plan::partition::Partition::fitted); beyond the paper).
    Preview,
}

impl Layout {
    /// The name on the command line and in summaries.
    pub fn name(self) -> &'static str {
        match self {
            Self::Even => "even",
            Self::Preview => "preview",
        }
    }
}

/// Pixels per preview pixel along each image axis. A quarter per axis (a
/// sixteenth of the rays) left the map noisy enough that fits with columns
/// per slab followed the noise: at 2 the busiest node the full map predicts
/// was lower in 8 of 10 bench configurations (2.5% on average), and the
/// preview still takes milliseconds.
pub const PREVIEW_STRIDE: u16 = 2;

/// The proportional policy's settings: gamma 4 (ALL's stable choice), a 15% dead band
/// (at 10% two of the 16 `bench paper` configurations moved over 1% of their
/// boundaries per interval in steady state; see docs/partition-and-sliding.md).
pub const PROPORTIONAL: link_proto::SlidePolicy =
    link_proto::SlidePolicy::Proportional { gamma: 4 << 16, deadband: 9830 };

/// `render`'s sliding interval, virtual cycles between load comparisons.
pub const DEFAULT_INTERVAL: u64 = 5_000_000;

/// `render`'s threshold: a node whose load (running / waiting) is under it
/// may take a slab. 16.16 fixed point.
pub const DEFAULT_THRESHOLD: u32 = 1 << 16;

/// Sliding as `render` does by default: the proportional policy, every
/// [`DEFAULT_INTERVAL`] cycles (docs/partition-and-sliding.md says why).
pub const DEFAULT_BALANCE: Balance =
    Balance { interval: DEFAULT_INTERVAL, threshold: DEFAULT_THRESHOLD, step: 1, policy: PROPORTIONAL };

/// How to render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Nodes per axis.
    pub array: [u16; 3],
    /// Image width and height.
    pub size: [u16; 2],
    /// Samples per pixel, on a regular grid: a square from 1 to 64
    /// ([`crate::results::image::sample_side`]).
    pub samples: u16,
    /// Who creates the initial rays.
    pub initial: Initial,
    /// Ray pool slots kept for each class level.
    pub level_depth: u16,
    /// Ray pool slots beyond those, open to every class; `None`: all a node
    /// has left over.
    pub shared_slots: Option<u16>,
    /// Board costs and links.
    pub sim: SimConfig,
    /// The preset `sim`'s links started from (for summaries; the settings
    /// themselves are `sim.link` and `sim.host_link`).
    pub link_preset: LinkPreset,
    /// Sliding boundaries, or `None` for the static partition.
    pub balance: Option<Balance>,
    /// Driving axis; `None` picks the paper's (most varied sphere counts).
    pub driving_axis: Option<u8>,
    /// How the grid is first cut.
    pub layout: Layout,
    /// Send every node the map of occupied cubes, so that a node walks a
    /// leaving ray on through clear cubes near the grid's end and retires
    /// it instead of passing it ([`node_fw::occupancy`]).
    pub clear_walks: bool,
}

impl RenderOptions {
    /// Defaults for an array: 256 x 256 pixels, initial rays created where they
    /// enter, one slot kept per class level and every slot left over shared,
    /// the map of occupied cubes sent.
    pub fn new(array: [u16; 3]) -> Self {
        Self {
            array,
            size: [256, 256],
            samples: 1,
            initial: Initial::Entry,
            level_depth: 1,
            shared_slots: None,
            sim: SimConfig::new(array),
            link_preset: LinkPreset::default(),
            balance: None,
            driving_axis: None,
            layout: Layout::Even,
            clear_walks: true,
        }
    }

    /// The image the nodes trace: `size` times the samples per axis, each
    /// pixel of the image the mean of a block of it; both sizes checked.
    pub fn trace_size(&self) -> Result<[u16; 2], HostError> {
        crate::results::image::traced(self.size, self.samples)
    }
}
