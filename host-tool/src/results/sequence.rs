//! A sequence's outputs: each frame as a numbered PNG, the whole as an
//! animated PNG, and one CSV row per frame with a plot of makespan and
//! imbalance over the frames. Frames are written as they come, so a long
//! sequence is never held in memory, and staged beside their targets: the
//! run writes all of them or none.

use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;

use link_proto::PortHealth;

use crate::error::HostError;
use crate::results::files::{imbalance, link_troubles};
use crate::results::output::{Staging, png};
use crate::results::plot::{self, Chart, Series, Style};
use crate::session::clock::Clock;
use crate::session::sequence::{FrameSink, SequenceFrame};

/// Where a sequence's outputs go.
#[derive(Debug, Clone)]
pub struct SequenceFiles {
    /// Directory of the numbered frames (`frame-0000.png`, ...).
    pub dir: PathBuf,
    /// The animated PNG.
    pub animation: PathBuf,
    /// One row per frame.
    pub table: PathBuf,
    /// Makespan and imbalance over the frames.
    pub plot: PathBuf,
}

impl SequenceFiles {
    /// Frame `k`'s image.
    pub fn frame(&self, k: u32) -> PathBuf {
        self.dir.join(format!("frame-{k:04}.png"))
    }

    /// Every file a sequence of `frames` writes.
    pub fn all(&self, frames: u32) -> Vec<PathBuf> {
        let fixed = [&self.animation, &self.table, &self.plot].map(|p| p.to_path_buf());
        (0..frames).map(|k| self.frame(k)).chain(fixed).collect()
    }
}

/// What one frame took, as its CSV row says it.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRow {
    /// Frame number.
    pub frame: u32,
    /// From the frame's start to its last retirement, in the transport's ticks.
    pub makespan: u64,
    /// Busiest node's running time over the mean.
    pub imbalance: f64,
    /// Slides committed during the frame.
    pub slides: usize,
    /// Messages the nodes sent (where the transport counts them).
    pub messages: Option<u64>,
    /// Bytes the nodes sent to neighbours.
    pub neighbour_bytes: u64,
    /// Bytes the nodes sent to the host.
    pub host_bytes: u64,
    /// Rays retired.
    pub rays: u64,
    /// The scene was sent for this frame.
    pub loaded: bool,
    /// Host milliseconds spent planning it.
    pub planning_ms: f64,
    /// Host milliseconds the sequence waited for its plan (planned frames
    /// are planned while the frame before renders).
    pub plan_wait_ms: f64,
    /// Frames the nodes resent, and took damaged, as they told the host.
    pub link_troubles: PortHealth,
}

impl FrameRow {
    /// The row of a finished frame.
    pub fn of<T: Clock>(f: &SequenceFrame<T>) -> Self {
        let r = &f.result;
        let host = node_fw::Port::Host.index();
        Self {
            frame: f.number,
            makespan: r.frame.makespan.ticks().saturating_sub(r.stats.start.ticks()),
            imbalance: imbalance(r),
            slides: r.frame.slides.len(),
            messages: r.busy.iter().map(|b| b.map(|b| b.sent)).sum(),
            neighbour_bytes: r.bytes.iter().map(|b| b.iter().sum::<u64>() - b[host]).sum(),
            host_bytes: r.bytes.iter().map(|b| b[host]).sum(),
            rays: r.frame.rays_terminated,
            loaded: f.loaded,
            planning_ms: f.planning.as_secs_f64() * 1e3,
            plan_wait_ms: f.plan_wait.as_secs_f64() * 1e3,
            link_troubles: link_troubles(r),
        }
    }
}

/// Writes a sequence's outputs as its frames arrive.
pub struct SequenceWriter {
    files: SequenceFiles,
    staging: Staging,
    animation: png::Writer<BufWriter<File>>,
    rows: Vec<FrameRow>,
    /// The unit of the makespans (the transport's clock).
    unit: &'static str,
}

impl SequenceWriter {
    /// Opens the animation of `frames` frames of `size` pixels, shown at `fps`.
    pub fn new(files: SequenceFiles, frames: u32, size: [u16; 2], fps: u16) -> Result<Self, HostError> {
        let mut staging = Staging::default();
        let file = staging.open(&files.animation)?;
        let apng =
            |e: png::EncodingError| HostError::Io(format!("cannot write {}: {e}", files.animation.display()));
        let mut encoder = png::Encoder::new(BufWriter::new(file), u32::from(size[0]), u32::from(size[1]));
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_animated(frames.max(1), 0).map_err(apng)?;
        encoder.set_frame_delay(1, fps.max(1)).map_err(apng)?;
        let animation = encoder.write_header().map_err(apng)?;
        Ok(Self { files, staging, animation, rows: Vec::new(), unit: "" })
    }

    /// The unit of the rows' makespans (empty before the first frame).
    pub fn unit(&self) -> &'static str {
        self.unit
    }

    /// Writes the table and the plot, ends the animation, and puts every
    /// file in place.
    pub fn finish(mut self) -> Result<Vec<FrameRow>, HostError> {
        let animation = &self.files.animation;
        self.animation
            .finish()
            .map_err(|e| HostError::Io(format!("cannot write {}: {e}", animation.display())))?;
        self.staging.add(&self.files.table, frames_csv(&self.rows, self.unit).as_bytes())?;
        self.staging.add(&self.files.plot, &frames_plot(&self.rows, self.unit)?)?;
        self.staging.commit()?;
        Ok(self.rows)
    }
}

impl FrameSink for SequenceWriter {
    fn take<T: Clock>(&mut self, f: SequenceFrame<T>) -> Result<(), HostError> {
        let frame = &f.result.frame;
        let [w, h] = frame.image_size();
        let rgb = frame.rgb8();
        self.staging.add(&self.files.frame(f.number), &png(w, h, &rgb)?)?;
        self.animation
            .write_image_data(&rgb)
            .map_err(|e| HostError::Io(format!("cannot write {}: {e}", self.files.animation.display())))?;
        self.unit = T::UNIT;
        self.rows.push(FrameRow::of(&f));
        Ok(())
    }
}

/// One row per frame; makespans in `unit`.
pub fn frames_csv(rows: &[FrameRow], unit: &str) -> String {
    let mut s = format!(
        "# makespan in {unit}: from the frame's start to its last retirement (frame 0's includes sending the scene)\n\
         frame,makespan,imbalance,slides,messages,neighbour_bytes,host_bytes,rays,loaded,planning_ms,plan_wait_ms,resent,damaged,lost\n"
    );
    for r in rows {
        let messages = r.messages.map_or(String::new(), |m| m.to_string());
        s += &format!(
            "{},{},{:.4},{},{messages},{},{},{},{},{:.1},{:.1},{},{},{}\n",
            r.frame,
            r.makespan,
            r.imbalance,
            r.slides,
            r.neighbour_bytes,
            r.host_bytes,
            r.rays,
            u8::from(r.loaded),
            r.planning_ms,
            r.plan_wait_ms,
            r.link_troubles.resent,
            r.link_troubles.damaged,
            r.link_troubles.lost
        );
    }
    s
}

/// Makespan and imbalance over the frames, one panel each.
pub fn frames_plot(rows: &[FrameRow], unit: &str) -> Result<Vec<u8>, HostError> {
    let series = |name: &str, pick: fn(&FrameRow) -> f64| {
        vec![Series {
            name: name.to_string(),
            points: rows.iter().map(|r| (f64::from(r.frame), pick(r))).collect(),
            style: Style::LineWithMarkers,
        }]
    };
    let chart = |title: &str, y: &str| Chart {
        title: title.to_string(),
        x_label: "frame".to_string(),
        y_label: y.to_string(),
        log_x: false,
        log_y: false,
    };
    plot::png(
        &[
            (
                chart("Makespan per frame", &format!("makespan ({unit})")),
                series("makespan", |r| r.makespan as f64),
            ),
            (
                chart("Imbalance per frame", "busiest / mean running time"),
                series("imbalance", |r| r.imbalance),
            ),
        ],
        900,
        320,
    )
}
