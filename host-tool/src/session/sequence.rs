//! A sequence of frames on one array: the scene sent once, a start per
//! frame, and the subregions carried from frame to frame.
//!
//! Each node keeps its subregion and the spheres in it when a frame ends,
//! with its boundaries where sliding left them. The next frame starts there
//! ([`FrameStart::Carried`]), so boundaries follow the work as it moves and
//! no frame pays for a preview; or each frame is planned afresh
//! ([`FrameStart::Planned`]: `--layout preview` fits each frame's own
//! preview), and the scene is sent again whenever the planned subregions
//! differ from those the nodes hold. Spheres that move by keyframes are sent
//! again, all of them, in each frame where they stand elsewhere than in the
//! last frame sent, as the nodes hold them (quantised: a move smaller than
//! the wire's resolution sends nothing); the subregions stay carried or
//! planned as above.

use std::time::{Duration, Instant};

use crate::error::HostError;
use crate::plan::options::RenderOptions;
use crate::plan::partition::Partition;
use crate::plan::{Plan, initial_partition};
use crate::results::RenderResult;
use crate::results::history::after_slides;
use crate::scene::Scene;
use crate::scene::path::CameraPath;
use crate::session::transport::Transport;
use crate::threads::join;
use link_proto::{Capacity, MapLoad, SphereMsg};

/// Where each frame after the first starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameStart {
    /// Where the frame before ended: slid boundaries stay where they slid
    /// (static ones never move).
    Carried,
    /// Planned afresh from the frame's own camera, as the options' layout
    /// says.
    Planned,
}

/// The frames to render and how.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sequence {
    /// Number of frames.
    pub frames: u32,
    /// Where the camera is at each.
    pub path: CameraPath,
    /// Where each frame after the first starts.
    pub start: FrameStart,
}

/// One frame of a sequence, as it ended.
#[derive(Debug, Clone)]
pub struct SequenceFrame<T> {
    /// Frame number, from 0.
    pub number: u32,
    /// The frame's image and accounting (its partition: where it started).
    pub result: RenderResult<T>,
    /// Whether the scene was sent for this frame (the first, planned frames
    /// whose subregions changed, and frames where spheres moved).
    pub loaded: bool,
    /// Host time spent planning the frame (the preview and the fit, with
    /// `--layout preview`).
    pub planning: Duration,
    /// Host time the sequence waited for the frame's plan: all of
    /// [`Self::planning`] for the first frame and for carried ones, and only
    /// what the frame before did not cover for frames planned afresh, which
    /// are planned while the frame before renders.
    pub plan_wait: Duration,
}

/// What takes each frame of a sequence as it is done: generic over the
/// transport's clock, so one sink serves every backend.
pub trait FrameSink {
    /// Takes frame `f`; an error stops the sequence.
    fn take<T: crate::session::clock::Clock>(&mut self, f: SequenceFrame<T>) -> Result<(), HostError>;
}

/// A frame's plan, its scene as the frame sees it, and the host time they took.
struct Planned {
    at: Scene,
    plan: Plan,
    spent: Duration,
}

/// Plans frame `k`: on `carried` if given, else as the options' layout says.
fn plan_frame(
    scene: &Scene,
    opts: &RenderOptions,
    sequence: &Sequence,
    k: u32,
    carried: Option<Partition>,
    capacity: Capacity,
) -> Result<Planned, HostError> {
    let started = Instant::now();
    let at = sequence.path.frame(scene, k, sequence.frames)?;
    let partition = match carried {
        Some(p) => p,
        None => initial_partition(&at, opts, capacity)?,
    };
    let plan = Plan::with_partition(&at, opts, partition, capacity)?;
    Ok(Planned { at, plan, spent: started.elapsed() })
}

/// Renders `sequence` of `scene` on `transport`, handing each frame to
/// `each` as soon as it is done (so a long sequence is never held in
/// memory); stops at the first error, of a frame or of `each`.
///
/// A frame planned afresh does not depend on the frame before, so it is
/// planned on another thread while that frame renders: a preview fit costs
/// the sequence only what it takes beyond the frame before. Its error, if
/// any, comes after the frame before is handed on, as if planned then.
pub fn run<T: Transport>(
    transport: &mut T,
    scene: &Scene,
    opts: &RenderOptions,
    sequence: &Sequence,
    mut each: impl FnMut(SequenceFrame<T::Time>) -> Result<(), HostError>,
) -> Result<(), HostError> {
    let capacity = transport.capacity();
    // The subregions the nodes hold, once a scene is loaded, and the
    // spheres they were sent.
    let mut held: Option<Partition> = None;
    let mut sent: Option<Vec<SphereMsg>> = None;
    // Whether the nodes hold a map of the occupied cubes of `sent`.
    let mut mapped = false;
    std::thread::scope(|scope| {
        let mut ahead = None;
        for k in 0..sequence.frames {
            let waiting = Instant::now();
            let planned = match ahead.take() {
                Some(planning) => join(planning)?,
                None => {
                    let carried = held.clone().filter(|_| sequence.start == FrameStart::Carried);
                    plan_frame(scene, opts, sequence, k, carried, capacity)?
                }
            };
            let plan_wait = waiting.elapsed();
            if sequence.start == FrameStart::Planned && k + 1 < sequence.frames {
                ahead = Some(scope.spawn(move || plan_frame(scene, opts, sequence, k + 1, None, capacity)));
            }
            let Planned { at, plan, spent } = planned;
            let spheres = at.sphere_msgs();
            let same_spheres = sent.as_ref() == Some(&spheres);
            let loaded = held.as_ref() != Some(&plan.partition) || !same_spheres;
            let mut map = Vec::new();
            if loaded {
                // Boxes that moved over the same spheres keep the map.
                let keep = if same_spheres && mapped { MapLoad::Kept } else { MapLoad::Sent };
                let load = super::load(transport, &at, &plan, keep);
                (map, mapped) = (load.after_start, load.mapped);
                sent = Some(spheres);
            }
            let result = super::frame(transport, &plan, k, &map)
                .map_err(|e| if sequence.frames > 1 { e.context(&format!("frame {k}")) } else { e })?;
            held = Some(after_slides(&plan.partition, &result.frame.slides));
            each(SequenceFrame { number: k, result, loaded, planning: spent, plan_wait })?;
        }
        Ok(())
    })
}
