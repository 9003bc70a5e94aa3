//! The frame buffer: integer pixel sums, credit accounting, loads, errors.

use link_proto::{
    Contribution, ErrorReport, LoadReport, Message, PROTOCOL_VERSION, PortHealth, SlideNote, Totals,
};

use crate::error::HostError;
use crate::session::clock::Clock;
use crate::session::transport::Endpoint;

/// The most pixels an image may have: 2^26, such as 8192 x 8192. The host
/// keeps three 64-bit sums per pixel (1.5 GiB at this size) and the image
/// itself; beyond it a run would exhaust a desktop's memory rather than fail
/// with a message, so larger sizes are refused up front.
pub const MAX_PIXELS: u64 = 1 << 26;

/// Checks an image size: at least 1 x 1 and at most [`MAX_PIXELS`] pixels.
pub fn check_size(width: u16, height: u16) -> Result<(), HostError> {
    let pixels = u64::from(width) * u64::from(height);
    if pixels == 0 {
        return Err(HostError::ImageSize(format!("image size {width}x{height} must be at least 1x1")));
    }
    if pixels > MAX_PIXELS {
        return Err(HostError::ImageSize(format!(
            "image size {width}x{height} is {pixels} pixels; the most is {MAX_PIXELS} (such as 8192x8192)"
        )));
    }
    Ok(())
}

/// A committed slide as the host heard of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlideSeen<T> {
    /// Arrival time of the note.
    pub at: T,
    /// The node that received the slab.
    pub node: u16,
    /// What it reported.
    pub note: SlideNote,
}

/// Everything the host collects during a frame.
#[derive(Debug, Clone)]
pub struct FrameBuffer<T> {
    /// Width in samples (the image's width times the samples per axis).
    pub width: u16,
    /// Height in samples.
    pub height: u16,
    /// Samples per pixel along each axis.
    side: u16,
    /// Per sample and channel, sum of Q1.15 contributions.
    pub sums: Vec<[u64; 3]>,
    /// The scene's background colour, Q1.15, added for each ray a record
    /// counts as leaving the scene at full strength.
    background: [u16; 3],
    /// Credit expected back (one initial credit per pixel).
    pub credit_total: u128,
    /// Credit returned so far.
    pub credit_back: u128,
    /// Rays created: one per pixel plus every spawned child.
    pub rays_created: u64,
    /// Rays retired.
    pub rays_terminated: u64,
    /// Retirement messages taken, and the records they carried (a pixel's
    /// rays that ended one after another at a node share a record, and rays
    /// that added nothing to their pixel take none).
    pub retirements: RetireCounts,
    /// Arrival time of the last retirement.
    pub makespan: T,
    /// Final load report per node.
    pub loads: Vec<Option<LoadReport>>,
    /// Errors reported by nodes.
    pub errors: Vec<ErrorReport>,
    /// Nodes that said hello with another protocol version.
    pub version_mismatch: Vec<(u16, u16)>,
    /// Whether the host is collecting final loads (after `Finish`).
    pub finishing: bool,
    /// Hellos received per node: a second one means the node restarted.
    pub hellos: Vec<u32>,
    /// Nodes that said hello again mid-frame (restarted).
    pub restarted: Vec<u16>,
    /// Interval load reports: (arrival time, report).
    pub history: Vec<(T, LoadReport)>,
    /// Committed slides, as their receiving nodes reported them.
    pub slides: Vec<SlideSeen<T>>,
    /// Slides refused for capacity: (arrival time, receiving node, boundary).
    pub refused_slides: Vec<(T, u16, u16)>,
    /// Per node and port, the frames it resent and took damaged since it
    /// last told us, as it tells us before its final load (all clean where
    /// the links lost nothing).
    pub link_health: Vec<[PortHealth; 7]>,
}

/// How the rays that ended came back to the host.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RetireCounts {
    /// Retirement messages.
    pub messages: u64,
    /// Records in them: contributions to pixels.
    pub records: u64,
}

impl<T: Clock> FrameBuffer<T> {
    /// An empty frame of `width` x `height` for `nodes` nodes, `credit` per
    /// pixel, of a scene whose background colour is `background` (Q1.15).
    pub fn new(width: u16, height: u16, nodes: usize, credit: u64, background: [u16; 3]) -> Self {
        let pixels = usize::from(width) * usize::from(height);
        Self {
            background,
            width,
            height,
            side: 1,
            sums: vec![[0; 3]; pixels],
            credit_total: pixels as u128 * u128::from(credit),
            credit_back: 0,
            rays_created: pixels as u64,
            rays_terminated: 0,
            retirements: RetireCounts::default(),
            makespan: T::default(),
            loads: vec![None; nodes],
            errors: Vec::new(),
            version_mismatch: Vec::new(),
            finishing: false,
            hellos: vec![0; nodes],
            restarted: Vec::new(),
            history: Vec::new(),
            slides: Vec::new(),
            refused_slides: Vec::new(),
            link_health: vec![[PortHealth::default(); 7]; nodes],
        }
    }

    /// Whether every ray has been accounted for.
    pub fn complete(&self) -> bool {
        self.credit_back == self.credit_total
    }

    /// Rays that ended at `at`: their credit and counts.
    fn account(&mut self, at: T, t: Totals) {
        self.credit_back += u128::from(t.credit);
        self.rays_created += u64::from(t.spawned);
        self.rays_terminated += u64::from(t.rays);
        self.makespan = self.makespan.max(at);
    }

    /// What rays that ended add to their pixel.
    fn contribute(&mut self, c: Contribution) {
        if let Some(px) = self.sums.get_mut(c.pixel as usize) {
            for ((s, v), b) in px.iter_mut().zip(c.rgb).zip(self.background) {
                *s += u64::from(v) + u64::from(c.background) * u64::from(b);
            }
        }
    }

    /// The same frame with `side` x `side` samples a pixel.
    pub fn sampled(self, side: u16) -> Self {
        Self { side: side.max(1), ..self }
    }

    /// Samples per pixel along each axis.
    pub fn side(&self) -> u16 {
        self.side
    }

    /// The image's width and height in pixels.
    pub fn image_size(&self) -> [u16; 2] {
        [self.width / self.side, self.height / self.side]
    }

    /// The image as 8-bit sRGB: each pixel the mean of its samples.
    pub fn rgb8(&self) -> Vec<u8> {
        crate::results::image::srgb8(&self.sums, self.width, self.height, self.side)
    }
}

impl<T: Clock> Endpoint<T> for FrameBuffer<T> {
    fn receive(&mut self, node: u16, at: T, msg: Message) {
        match msg {
            Message::Retire(batch) => {
                self.retirements.messages += 1;
                self.retirements.records += batch.len() as u64;
                self.account(at, batch.totals());
                for c in batch.iter() {
                    self.contribute(c);
                }
            }
            Message::Load(l) if l.interval == node_fw::node::FINAL_INTERVAL => {
                if let Some(slot) = self.loads.get_mut(usize::from(l.node)) {
                    *slot = Some(l);
                }
            }
            Message::Load(l) => self.history.push((at, l)),
            Message::SlideNote(note) => self.slides.push(SlideSeen { at, node, note }),
            Message::SlideReply(r) => self.refused_slides.push((at, node, r.boundary)),
            Message::Error(e) => self.errors.push(e),
            Message::LinkHealth(h) => {
                if let Some(ports) = self.link_health.get_mut(usize::from(node)) {
                    for (sum, p) in ports.iter_mut().zip(h.ports) {
                        *sum += p;
                    }
                }
            }
            Message::Hello(h) if h.version != PROTOCOL_VERSION => {
                self.version_mismatch.push((node, h.version))
            }
            Message::Hello(_) => {
                if let Some(n) = self.hellos.get_mut(usize::from(node)) {
                    *n += 1;
                    if *n > 1 {
                        self.restarted.push(node);
                    }
                }
            }
            _ => {}
        }
    }

    fn finished(&self) -> bool {
        !self.errors.is_empty()
            || !self.version_mismatch.is_empty()
            || !self.restarted.is_empty()
            || if self.finishing { self.loads.iter().all(Option::is_some) } else { self.complete() }
    }
}
