//! The progress bar of a long render.

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

use crate::session::clock::Clock;
use crate::session::frame::FrameBuffer;
use crate::session::transport::Endpoint;

/// Forwards to the frame buffer and, on a terminal, shows the share of the
/// frame's ray credit come back once a render passes a second. It gives no
/// time estimate: credit comes back unevenly (a pixel's last reflections
/// are the slowest), so any estimate from it runs low.
pub(super) struct Tracked<'a, T> {
    frame: &'a mut FrameBuffer<T>,
    started: Instant,
    bar: Option<ProgressBar>,
}

impl<'a, T> Tracked<'a, T> {
    /// Tracks `frame` from now.
    pub(super) fn new(frame: &'a mut FrameBuffer<T>) -> Self {
        Self { frame, started: Instant::now(), bar: None }
    }

    /// Takes the bar off the terminal.
    pub(super) fn done(self) {
        if let Some(bar) = self.bar {
            bar.finish_and_clear();
        }
    }
}

impl<T: Clock> Endpoint<T> for Tracked<'_, T> {
    fn receive(&mut self, node: u16, at: T, msg: link_proto::Message) {
        self.frame.receive(node, at, msg);
        if self.bar.is_none() && self.started.elapsed() > Duration::from_secs(1) {
            // Hidden by indicatif when standard error is not a terminal.
            let bar = ProgressBar::new(1000);
            if let Ok(style) = ProgressStyle::with_template(
                "rendering {bar:40} {percent}% of the rays' credit back ({elapsed})",
            ) {
                bar.set_style(style);
            }
            self.bar = Some(bar);
        }
        if let Some(bar) = &self.bar {
            let done = self.frame.credit_back * 1000 / self.frame.credit_total.max(1);
            bar.set_position(done as u64);
        }
    }

    fn finished(&self) -> bool {
        self.frame.finished()
    }
}
