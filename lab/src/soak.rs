//! `soak`: a long sequence under link faults against the same sequence on
//! clean links. Every frame must be identical to the clean one with every
//! ray accounted for, and the host's memory must stay flat: its resident
//! and peak sizes are read at two frames far apart.

use std::fmt::Write as _;

use host_tool::error::HostError;
use host_tool::plan::options::RenderOptions;
use host_tool::scene::Scene;
use host_tool::scene::path::CameraPath;
use host_tool::session::clock::Cycles;
use host_tool::session::sequence::{self, FrameStart, Sequence, SequenceFrame};
use host_tool::session::sim::board;
use node_fw::reliable::ChannelStats;
use sim_board::{Faults, SimConfig};

/// The process's resident set and its peak, in KiB (Linux's /proc).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Memory {
    /// VmRSS.
    pub resident_kib: u64,
    /// VmHWM: the most resident so far.
    pub peak_kib: u64,
}

impl Memory {
    /// Reads this process's sizes; zeros where /proc cannot tell.
    pub fn now() -> Self {
        let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
        let field = |name: &str| {
            status
                .lines()
                .find_map(|l| l.strip_prefix(name))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
                .unwrap_or(0)
        };
        Self { resident_kib: field("VmRSS:"), peak_kib: field("VmHWM:") }
    }
}

/// What the soak found.
#[derive(Debug, Clone, Default)]
pub struct SoakReport {
    /// Frames run (each way).
    pub frames: u32,
    /// Frames whose image differed from the clean run's.
    pub differing: Vec<u32>,
    /// Frames that lost a ray or credit.
    pub lossy: Vec<u32>,
    /// The faulty links' resends and damaged frames over the whole run.
    pub links: ChannelStats,
    /// (frame, memory after it) at the frames read.
    pub memory: Vec<(u32, Memory)>,
}

impl SoakReport {
    /// Whether every frame matched the clean run and lost nothing.
    pub fn passed(&self) -> bool {
        self.differing.is_empty() && self.lossy.is_empty()
    }

    /// The report as text.
    pub fn text(&self) -> String {
        let mut s = format!(
            "{} frames: {} differ from the clean run, {} lost a ray; faulty links resent {} frames and found {} damaged\n",
            self.frames,
            self.differing.len(),
            self.lossy.len(),
            self.links.retransmitted,
            self.links.corrupted
        );
        for (k, m) in &self.memory {
            let _ = writeln!(s, "after frame {k}: resident {} KiB, peak {} KiB", m.resident_kib, m.peak_kib);
        }
        s
    }
}

/// A digest of a frame's sums (FNV-1a): enough to tell two frames apart.
fn digest(f: &SequenceFrame<Cycles>) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for px in &f.result.frame.sums {
        for c in px {
            for b in c.to_le_bytes() {
                h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    h
}

/// Runs `frames` of an orbit on `opts.array` under `faults`, then the same
/// on clean links, and compares frame by frame. The faulty run goes first,
/// so the memory read at its frames is the host's own, not the clean run's
/// leftovers. `memory_at` names the frames (counted from 1) whose memory is read.
pub fn soak(
    scene: &Scene,
    opts: &RenderOptions,
    frames: u32,
    faults: Faults,
    memory_at: &[u32],
) -> Result<SoakReport, HostError> {
    let sequence =
        Sequence { frames, path: CameraPath::Orbit { degrees: 360.0 }, start: FrameStart::Carried };
    let mut report = SoakReport { frames, ..SoakReport::default() };
    let mut digests = Vec::with_capacity(frames as usize);
    let faulty_opts = RenderOptions { sim: SimConfig { faults: Some(faults), ..opts.sim }, ..*opts };
    let mut faulty = board(&faulty_opts);
    sequence::run(&mut faulty, scene, &faulty_opts, &sequence, |f| {
        let r = &f.result.frame;
        if !r.complete() || r.rays_created != r.rays_terminated {
            report.lossy.push(f.number);
        }
        report.links = report.links + f.result.links;
        digests.push(digest(&f));
        if memory_at.contains(&(f.number + 1)) {
            report.memory.push((f.number + 1, Memory::now()));
        }
        if (f.number + 1) % 20 == 0 {
            eprintln!("faulty links: frame {} of {frames}", f.number + 1);
        }
        Ok(())
    })
    .map_err(|e| e.context("the faulty run"))?;
    drop(faulty);
    let clean_opts = RenderOptions { sim: SimConfig { faults: None, ..opts.sim }, ..*opts };
    let mut clean = board(&clean_opts);
    sequence::run(&mut clean, scene, &clean_opts, &sequence, |f| {
        if digests.get(f.number as usize) != Some(&digest(&f)) {
            report.differing.push(f.number);
        }
        Ok(())
    })
    .map_err(|e| e.context("the clean run"))?;
    Ok(report)
}
