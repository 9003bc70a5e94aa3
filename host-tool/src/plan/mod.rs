//! The plan: everything the host computes from the scene and the options
//! before it talks to a node, computed once and kept as a value.
//!
//! A [`Plan`] fixes the driving axis, the starting partition (even, or fitted
//! to a preview), each node's assignment and sub-image tile, and the camera
//! as the nodes see it, and checks them against what a node can hold. The
//! session then only sends what the plan says.

pub mod camera;
pub mod cost_map;
pub mod direct;
pub mod entry;
pub mod fit;
pub mod options;
pub mod partition;

use link_proto::{Assign, Boundaries, CameraMsg, Capacity};
use node_fw::pool::class_bound;

use crate::error::{HostError, input};
use crate::scene::Scene;
use camera::PixelBasis;
use options::{Initial, Layout, PREVIEW_STRIDE, RenderOptions};
use partition::{Partition, tiles, view_axis};

/// A frame's plan on an array whose nodes hold `capacity`.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The options it was made from.
    pub options: RenderOptions,
    /// The starting subregions (and with them the driving axis).
    pub partition: Partition,
    /// The axis the camera looks most along.
    pub view_axis: u8,
    /// The camera's pixel directions.
    pub basis: PixelBasis,
    /// Each node's sub-image of initial rays (empty for none), in samples.
    pub tiles: Vec<[u16; 4]>,
    /// The image the nodes trace, in samples ([`RenderOptions::trace_size`]).
    pub trace_size: [u16; 2],
    /// The background colour the nodes hold (Q1.15): the host adds it for
    /// each ray a node reports as leaving the scene at full strength.
    pub background: [u16; 3],
}

impl Plan {
    /// Plans `scene` as `options` say for nodes of `capacity`: the starting
    /// partition, cut as `options.layout` says, then [`Plan::with_partition`].
    pub fn new(scene: &Scene, options: &RenderOptions, capacity: Capacity) -> Result<Self, HostError> {
        let partition = initial_partition(scene, options, capacity)?;
        Self::with_partition(scene, options, partition, capacity)
    }

    /// Plans `scene` on a given partition, checked against `capacity`.
    pub fn with_partition(
        scene: &Scene,
        options: &RenderOptions,
        partition: Partition,
        capacity: Capacity,
    ) -> Result<Self, HostError> {
        check_frame(scene, options, &partition, capacity)?;
        let trace_size = options.trace_size()?;
        let [w, h] = trace_size;
        let basis = PixelBasis::new(&scene.camera(), w, h);
        let view_axis = view_axis(scene);
        let tiles = match options.initial {
            Initial::Parallel => tiles(w, h, partition.len()),
            Initial::Entry => {
                entry::entry_tiles(&basis, scene.grid, &partition, usize::from(view_axis), trace_size)
            }
            Initial::EyeNode => {
                let eye = partition.owner_of(scene.camera().eye, scene.grid);
                (0..partition.len()).map(|i| if i == eye { [0, 0, w, h] } else { [0; 4] }).collect()
            }
        };
        let background = scene.header().background;
        Ok(Self { options: *options, partition, view_axis, basis, tiles, trace_size, background })
    }

    /// Samples per pixel along each axis.
    pub fn sample_side(&self) -> u16 {
        self.trace_size[0] / self.options.size[0].max(1)
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.partition.len()
    }

    /// Node `id`'s subregion and place, as it is told.
    pub fn assign(&self, id: usize) -> Assign {
        self.partition.assign(id)
    }

    /// The camera as the nodes are told it.
    pub fn camera(&self) -> CameraMsg {
        self.basis.msg()
    }
}

/// The starting partition of `scene` over `opts.array` along the chosen
/// driving axis, cut as `opts.layout` says, for nodes of `capacity`.
pub fn initial_partition(
    scene: &Scene,
    opts: &RenderOptions,
    capacity: Capacity,
) -> Result<Partition, HostError> {
    let traced = opts.trace_size()?;
    let axis = match opts.driving_axis {
        Some(a) if a > 2 => return Err(input(format!("driving axis {a} must be 0, 1 or 2"))),
        Some(a) => a,
        None => partition::driving_axis(scene, opts.array)?,
    };
    match opts.layout {
        Layout::Even => Partition::even(scene.grid, opts.array, axis),
        Layout::Preview => {
            // Checked first so a bad array gets the even partition's error.
            Partition::even(scene.grid, opts.array, axis)?;
            // And the pool, before the preview takes its time.
            check_pool(scene, opts, axis, Boundaries::Whole, capacity)?;
            let [w, h] = traced.map(|n| n.div_ceil(PREVIEW_STRIDE).max(1));
            // Entry tiles create each ray on its entry cube's node: that is
            // work of the cube. Other modes spread creation by tiles.
            let creation = opts.initial == Initial::Entry;
            let bytes = direct::ByteCpu::of(&opts.sim.link, &opts.sim.host_link);
            let mut costs =
                direct::cost_map(scene, [w, h], &opts.sim.cost, bytes, creation, opts.clear_walks)
                    .map_err(|e| e.context("the preview for --layout preview"))?;
            costs.wire.cycles = cost_map::WireCycles::of(&opts.sim.link, &opts.sim.host_link);
            // Staggered no further than the nodes' pools can route at this depth.
            let most = [Boundaries::StaggeredColumns, Boundaries::StaggeredRows]
                .into_iter()
                .find(|&b| check_pool(scene, opts, axis, b, capacity).is_ok())
                .unwrap_or(Boundaries::Whole);
            Partition::fitted(scene.grid, opts.array, axis, &costs, most)
        }
    }
}

/// Checks the image size, each node's share of the scene and the pool
/// depth against `capacity` before anything is sent.
pub fn check_frame(
    scene: &Scene,
    opts: &RenderOptions,
    partition: &Partition,
    capacity: Capacity,
) -> Result<(), HostError> {
    opts.trace_size()?;
    partition.check_capacity(scene, capacity)?;
    check_pool(scene, opts, partition.driving_axis, partition.boundaries(), capacity)
}

/// Checks that a node's ray pool can take the class levels and slots a frame
/// needs ([`node_fw::pool`]): the node would refuse the start otherwise, after
/// the whole scene had been sent.
fn check_pool(
    scene: &Scene,
    opts: &RenderOptions,
    axis: u8,
    boundaries: Boundaries,
    capacity: Capacity,
) -> Result<(), HostError> {
    if opts.level_depth == 0 {
        return Err(input("--queue-depth must be at least 1 (one ray slot per class level)"));
    }
    let lined_up = boundaries.when_sliding(opts.balance.is_some());
    let levels = class_bound(opts.array, scene.max_depth, usize::from(axis), lined_up) + 1;
    let sliding = if opts.balance.is_some() { " with sliding boundaries" } else { "" };
    let [x, y, z] = opts.array;
    if levels as usize > node_fw::pool::MAX_LEVELS {
        return Err(HostError::Capacity(format!(
            "rays on the {x}x{y}x{z} array{sliding} at max_depth {} take {levels} class levels; a node's pool \
             has at most {}: use a smaller array, a lower max_depth, or --balance static",
            scene.max_depth,
            node_fw::pool::MAX_LEVELS
        )));
    }
    let needed = slots_needed(scene, opts, axis, boundaries);
    if needed > u32::from(capacity.rays) {
        let shared = opts.shared_slots.map_or(0, u32::from);
        return Err(HostError::Capacity(format!(
            "{levels} class levels ({x}x{y}x{z} array{sliding}, max_depth {}) at --queue-depth {} and \
             {shared} --shared-slots need {needed} ray slots per node; a node has {}: lower --queue-depth \
             or --shared-slots, or use a smaller array or --balance static",
            scene.max_depth, opts.level_depth, capacity.rays
        )));
    }
    Ok(())
}

/// Ray slots per node a frame of `scene` needs from a start whose boundaries
/// line up as `boundaries` across driving axis `axis`.
fn slots_needed(scene: &Scene, opts: &RenderOptions, axis: u8, boundaries: Boundaries) -> u32 {
    let lined_up = boundaries.when_sliding(opts.balance.is_some());
    let top = class_bound(opts.array, scene.max_depth, usize::from(axis), lined_up);
    (top + 1) * u32::from(opts.level_depth) + opts.shared_slots.map_or(0, u32::from)
}
