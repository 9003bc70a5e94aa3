//! The results of a run: the frame the session collected, and everything
//! written from it (the image, each pixel the mean of its samples; the summary, the per-node loads, the load and
//! boundary histories and their plot), each file complete or absent.

pub mod files;
pub mod history;
pub mod image;
pub mod output;
pub mod plot;
pub mod sequence;

use std::time::Duration;

use node_fw::reliable::ChannelStats;
use sim_board::Busy;

use crate::plan::partition::Partition;
use crate::session::frame::FrameBuffer;
use crate::session::transport::RunEnd;

/// A rendered frame and how it went, its times on the clock `T` of the
/// transport that carried it.
#[derive(Debug, Clone)]
pub struct RenderResult<T> {
    /// Pixels, accounting and loads.
    pub frame: FrameBuffer<T>,
    /// The partition the frame started from.
    pub partition: Partition,
    /// When the run ended.
    pub stats: RunEnd<T>,
    /// Bytes each node sent, per port.
    pub bytes: Vec<[u64; 7]>,
    /// Bytes each node took in, per port (the in-memory board; zeros where
    /// the transport cannot see them).
    pub bytes_in: Vec<[u64; 7]>,
    /// Each node's busy cycles by what they were spent on (the in-memory
    /// board; `None` where the transport cannot see inside the nodes).
    pub busy: Vec<Option<Busy>>,
    /// Host wall time of the run.
    pub wall: Duration,
    /// Retransmissions and damaged frames on the links (framed mode).
    pub links: ChannelStats,
}
