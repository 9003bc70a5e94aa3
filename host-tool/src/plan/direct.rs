//! A plain single-threaded loop over the node kernels, with no nodes and no
//! messages: the whole grid as one subregion, each pixel's ray tree walked
//! depth-first. It produces the same image as the array (the same integer
//! contributions), the fixed-point first hit of every pixel for `compare`, and
//! the baseline that measures what the node machinery costs.

use link_proto::ray_wire::{ORIGIN_AT_EYE, PIXEL_CREDIT};
use link_proto::{Message, RayKind, RayMsg, Retire, Retirements};
use node_fw::camera::{primary_line, primary_ray};
use node_fw::shading::{Child, Scene as Shading, Surface};
use node_fw::{CubeBox, DigitalLine, Direction, Grid, Line, Outcome, Point, Query, Sphere, Subregion};
use node_fw::{limits::Scalar, sphere::Hit};

use crate::error::{HostError, input};
use crate::plan::camera::PixelBasis;
use crate::plan::cost_map::CostMap;
use crate::plan::entry;
use crate::scene::Scene;
use crate::scene::occupancy::occupancy_msgs;
use node_fw::occupancy::{Occupancy, near_the_end};

/// The whole grid in one subregion: up to 64^3 cubes and 65535 references.
type Whole = Subregion<8192, 65535, 262_144>;

/// The first hit of a pixel's primary ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrimaryHit {
    /// Sphere id.
    pub sphere: u16,
    /// Ray parameter, cubes.
    pub t: f64,
}

/// Result of a direct render.
#[derive(Debug, Clone)]
pub struct DirectImage {
    /// Per pixel, sum of Q1.15 contributions.
    pub sums: Vec<[u64; 3]>,
    /// Per pixel, the primary hit.
    pub hits: Vec<Option<PrimaryHit>>,
    /// Rays traced.
    pub rays: u64,
}

/// The CPU a board spends on each byte of a frame it sends or receives, on
/// its neighbour and its host links: none where DMA moves them (`f413`) or
/// on the `ideal` links, 51 cycles where an interrupt takes each byte
/// (`--transfer interrupt`). A ray's
/// frame of 40 bytes then costs its ends more than its kernel does, and a
/// fit that left the bytes out cut partitions that pass too many rays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ByteCpu {
    /// Cycles a byte on a neighbour link.
    pub neighbour: u64,
    /// Cycles a byte on the host link.
    pub host: u64,
}

impl ByteCpu {
    /// Bytes priced as the in-memory board's links charge them.
    pub fn of(link: &sim_board::LinkSpec, host: &sim_board::LinkSpec) -> Self {
        Self { neighbour: link.model().byte_cpu, host: host.model().byte_cpu }
    }
}

/// Renders `scene` and measures what every unit cube and face costs, the
/// initial rays' creation aside ([`add_initial_rays`]).
pub fn measure_costs(
    scene: &Scene,
    width: u16,
    height: u16,
    cost: &sim_board::CostModel,
    bytes: ByteCpu,
) -> Result<CostMap, HostError> {
    measure(scene, [width, height], cost, bytes, false)
}

/// [`measure_costs`], the nodes walking rays on through clear cubes
/// (`clear_walks`, [`RenderOptions::clear_walks`](crate::plan::options::RenderOptions::clear_walks)) or not.
fn measure(
    scene: &Scene,
    [width, height]: [u16; 2],
    cost: &sim_board::CostModel,
    bytes: ByteCpu,
    clear_walks: bool,
) -> Result<CostMap, HostError> {
    let mut costs = Costs::new(cost, bytes, scene, clear_walks);
    render_impl(scene, width, height, Some(&mut costs), 30)?;
    Ok(costs.map)
}

/// The cost map of a `width` x `height` render of `scene`, with each initial
/// ray charged to the cube where it enters the grid: its creation with
/// `creation` (the node holding that cube creates it), else its receipt from
/// the node that created it; the nodes walk rays on through clear cubes
/// with `clear_walks`.
pub fn cost_map(
    scene: &Scene,
    [width, height]: [u16; 2],
    cost: &sim_board::CostModel,
    bytes: ByteCpu,
    creation: bool,
    clear_walks: bool,
) -> Result<CostMap, HostError> {
    let mut map = measure(scene, [width, height], cost, bytes, clear_walks)?;
    add_initial_rays(&mut map, scene, [width, height], cost, bytes, creation)?;
    Ok(map)
}

/// Charges each initial ray of a `size` image: with `creation` (entry
/// tiles), its creation where the tiles have it created, and its way from
/// there to the cube where it enters: on the side face that creates its own
/// rays the entry cube itself, elsewhere the cube on the grid's
/// face toward the eye in its entry cube's row, whence it goes along the
/// view axis ([`crate::plan::entry`]). Without, its receipt where it enters.
/// Rays that miss the grid are not charged.
pub fn add_initial_rays(
    map: &mut CostMap,
    scene: &Scene,
    size: [u16; 2],
    cost: &sim_board::CostModel,
    bytes: ByteCpu,
    creation: bool,
) -> Result<(), HostError> {
    let [width, height] = size;
    let grid = Grid::new(scene.grid).map_err(|e| input(format!("grid: {e:?}")))?;
    let basis = PixelBasis::new(&scene.camera(), width, height);
    let camera = basis.msg();
    let hop = HopPrice::new(cost, bytes);
    let cells = entry::entry_cells(&camera, &grid, [width, height]);
    let creators = creation.then(|| Creators::of(scene, &basis, &cells)).flatten();
    for (i, cell) in cells.into_iter().enumerate() {
        let Some(cell) = cell else { continue };
        if let Some(creators) = &creators {
            let mut at = creators.creator(cell);
            map.add_compute(at, cost.create + cost.pass);
            if at != cell {
                // Passed along the view axis to the cube where it enters.
                let (x, y) = (i % usize::from(width), i / usize::from(width));
                let line =
                    primary_line(&camera, x as u16, y as u16).map_err(|e| input(format!("camera: {e:?}")))?;
                let price = hop.of(&primary_ray(&line, i as u32, PIXEL_CREDIT));
                let axis = creators.view_axis;
                let step = (cell[axis] - at[axis]).signum();
                while at != cell {
                    let mut next = at;
                    next[axis] += step;
                    map.add_crossing(at, next, price.cycles, price.bytes);
                    at = next;
                }
            }
        } else if creation {
            map.add_compute(cell, cost.create + cost.pass);
        } else {
            let (x, y) = (i % usize::from(width), i / usize::from(width));
            let line =
                primary_line(&camera, x as u16, y as u16).map_err(|e| input(format!("camera: {e:?}")))?;
            let ray = primary_ray(&line, i as u32, PIXEL_CREDIT);
            map.add_message(cell, hop.of(&ray).cycles);
        }
    }
    Ok(())
}

/// Where entry tiles create the initial rays, by cube: `None` with the eye
/// inside the grid, where the tiles are the regular ones.
struct Creators {
    view_axis: usize,
    /// The layer of cubes on the grid's face toward the eye along the view axis.
    front: i32,
    /// The side face that creates its own rays ([`entry::side_face`]), if
    /// any: its axis and its layer of cubes.
    side: Option<(usize, i32)>,
}

impl Creators {
    /// For the camera `basis` and each pixel's entry cube `cells`.
    fn of(scene: &Scene, basis: &PixelBasis, cells: &[Option<[i32; 3]>]) -> Option<Self> {
        let view_axis = usize::from(crate::plan::partition::view_axis(scene));
        let low = entry::eye_on_low_side(basis.eye, scene.grid, view_axis)?;
        let across = entry::across_axis(basis, view_axis);
        let side = entry::side_face(cells, basis.eye, scene.grid, view_axis, across)
            .map(|(axis, low)| (axis, entry::layer_of_face(scene.grid, axis, low)));
        Some(Self { view_axis, front: entry::layer_of_face(scene.grid, view_axis, low), side })
    }

    /// The cube where the ray entering at `cell` is created: `cell` itself
    /// on the side face that creates its own, else the front face's cube in its row.
    fn creator(&self, cell: [i32; 3]) -> [i32; 3] {
        if self.side.is_some_and(|(axis, layer)| cell[axis] == layer) {
            return cell;
        }
        let mut at = cell;
        at[self.view_axis] = self.front;
        at
    }
}

/// What a node pays beside its cells' work: [`fixed_messages`] short messages.
pub fn fixed_cost(spheres: usize, neighbours: usize, scene: &Scene, cost: &sim_board::CostModel) -> u64 {
    fixed_messages(spheres, neighbours, scene) as u64 * cost.short_message
}

/// The short messages a node handles beside its cells' work: one per sphere
/// it is sent (one node is sent all; on an array each node only those that
/// meet its box, [`Partition::spheres_sent`](crate::plan::partition::Partition::spheres_sent))
/// and per light, six to begin and end the scene and the frame with the
/// host, and seven per neighbour (hellos both ways and the host's note of
/// who answered, the first grants both ways, the frame's end both ways).
pub fn fixed_messages(spheres: usize, neighbours: usize, scene: &Scene) -> usize {
    spheres + scene.lights.len() + 6 + 7 * neighbours
}

/// What each side of a hop pays: the ray on a grant, a share of the `Grant`
/// messages (one per half the grant target of rays, both ends), each with
/// its frame's bytes, and half the receiver's walk set-up and of the loop's
/// pass around it (a ray entering a node is set up again, in a poll of its
/// own). Rays go on grants unless a node's pool has no slot to set aside.
#[derive(Debug, Clone, Copy)]
struct HopPrice {
    /// Everything but the ray's own frame bytes.
    fixed: u64,
    /// Cycles a byte of the ray's frame.
    byte: u64,
}

/// What one side of a hop costs, and the bytes it puts on the wire.
#[derive(Debug, Clone, Copy, Default)]
struct Hop {
    cycles: u64,
    /// The ray's share of a full batch ([`sim_board::sim_links::batched_len`]):
    /// a link is busy where its wire bounds a frame, and a busy link's rays
    /// go in batches (entry tiles pass the initial rays along the view axis
    /// in full ones). Priced as frames of their own, the 3x3x3 array's
    /// busiest links came out 1.45 times the bytes they carried.
    bytes: u64,
}

impl HopPrice {
    fn new(cost: &sim_board::CostModel, bytes: ByteCpu) -> Self {
        let grant =
            cost.short_message + bytes.neighbour * frame_len(&Message::Grant(node_fw::node::GRANT_TARGET));
        let grants = grant / u64::from(node_fw::node::GRANT_TARGET / 2);
        Self { fixed: cost.granted_ray + grants + (cost.trace + cost.pass) / 2, byte: bytes.neighbour }
    }

    /// One side of a hop of `ray`.
    fn of(&self, ray: &RayMsg) -> Hop {
        let alone = frame_len(&Message::GrantedRay(on_the_wire(ray)));
        let bytes = sim_board::sim_links::batched_len(alone as usize).round() as u64;
        Hop { cycles: self.fixed + self.byte * alone, bytes }
    }
}

/// What a node pays to retire `ray` to the host, its frame's bytes included.
/// (The frame is encoded only where bytes cost.)
fn retire_cost(cost: &sim_board::CostModel, bytes: ByteCpu, ray: &RayMsg) -> u64 {
    if bytes.host == 0 {
        return cost.retire_message;
    }
    // Its contribution is its weight at most: that many bytes, about.
    let record =
        Retire { pixel: ray.pixel, rgb: ray.weight, credit: ray.credit, spawned: 0, rays: 1, background: 0 };
    cost.retire_message + bytes.host * frame_len(&Message::Retire(Retirements::new(record)))
}

/// Records a full message holds, about ([`Retirements`]): the nodes whose
/// host links bound a frame are busy, and send their records so.
const RECORDS_A_MESSAGE: u64 = 10;

/// Bytes the retirement of `ray`, adding `rgb` to its pixel (or its
/// `background`), puts on the host's wire: what its record adds to a
/// message after another pixel's, and its share of the message's frame
/// ([`RECORDS_A_MESSAGE`]). A ray that adds nothing (a blocked shadow ray)
/// has no record.
fn retire_bytes(ray: &RayMsg, rgb: [u32; 3], background: bool) -> u64 {
    let retire = |pixel, rgb, background| Retire { pixel, rgb, credit: 1, spawned: 0, rays: 1, background };
    let before = Retirements::new(retire(ray.pixel.wrapping_add(1), [1; 3], 0));
    let mut with = before;
    let record = if background { retire(ray.pixel, [0; 3], 1) } else { retire(ray.pixel, rgb, 0) };
    let one = frame_len(&Message::Retire(before));
    if with.push(record).is_err() {
        return one;
    }
    let added = frame_len(&Message::Retire(with)).saturating_sub(one);
    if added == 0 { 0 } else { added + one.div_ceil(RECORDS_A_MESSAGE) }
}

/// `ray` as a node sends it: a primary ray's origin is the eye, which the
/// wire leaves out.
fn on_the_wire(ray: &RayMsg) -> RayMsg {
    let origin = if ray.kind == RayKind::Primary { ORIGIN_AT_EYE } else { ray.origin };
    RayMsg { origin, ..*ray }
}

/// Bytes of `msg`'s frame on the wire.
fn frame_len(msg: &Message) -> u64 {
    sim_board::sim_links::frame_len(msg) as u64
}

/// Renders `scene` with the camera's direction basis rounded to `bits` fraction
/// bits (instead of 30), for the numerics report.
pub fn render_with_camera_bits(
    scene: &Scene,
    width: u16,
    height: u16,
    bits: u32,
) -> Result<DirectImage, HostError> {
    render_impl(scene, width, height, None, bits)
}

/// Renders `scene` with the camera's direction basis at `camera_bits`
/// fraction bits (30 is the nodes' own) and measures what every cube costs
/// (the initial rays' creation aside, as [`measure_costs`]).
pub fn render_costed(
    scene: &Scene,
    width: u16,
    height: u16,
    camera_bits: u32,
    cost: &sim_board::CostModel,
    bytes: ByteCpu,
) -> Result<(DirectImage, CostMap), HostError> {
    let mut costs = Costs::new(cost, bytes, scene, false);
    let img = render_impl(scene, width, height, Some(&mut costs), camera_bits)?;
    Ok((img, costs.map))
}

/// Renders `scene` at `width` x `height` with the node kernels in one loop.
pub fn render(scene: &Scene, width: u16, height: u16) -> Result<DirectImage, HostError> {
    render_impl(scene, width, height, None, 30)
}

fn render_impl(
    scene: &Scene,
    width: u16,
    height: u16,
    mut costs: Option<&mut Costs>,
    camera_bits: u32,
) -> Result<DirectImage, HostError> {
    let grid = Grid::new(scene.grid).map_err(|e| input(format!("grid: {e:?}")))?;
    let mut region: Box<Whole> = Box::new(Whole::new());
    region
        .assign(grid, CubeBox { lo: [0; 3], hi: scene.grid })
        .map_err(|e| input(format!("the direct renderer holds grids up to 262144 cubes: {e:?}")))?;
    for m in scene.sphere_msgs() {
        let sphere = Sphere::from_msg(&m, &grid).map_err(|e| input(format!("sphere {}: {e:?}", m.id)))?;
        region
            .insert(sphere)
            .map_err(|r| input(format!("direct renderer: sphere {}: {:?}", m.id, r.error)))?;
    }
    let header = scene.header();
    let lights = scene.light_msgs();
    let shading = Shading { header: &header, grid: &grid, lights: &lights };
    let mut camera = PixelBasis::new(&scene.camera(), width, height).msg();
    if camera_bits < 30 {
        let drop = 30 - camera_bits;
        let round = |v: [i32; 3]| v.map(|c| ((i64::from(c) + (1 << (drop - 1))) >> drop << drop) as i32);
        camera.corner = round(camera.corner);
        camera.du = round(camera.du);
        camera.dv = round(camera.dv);
    }
    let pixels = usize::from(width) * usize::from(height);
    let mut out = DirectImage { sums: vec![[0; 3]; pixels], hits: vec![None; pixels], rays: 0 };
    let mut stack: Vec<RayMsg> = Vec::new();
    for y in 0..height {
        for x in 0..width {
            let pixel = usize::from(y) * usize::from(width) + usize::from(x);
            let line = primary_line(&camera, x, y).map_err(|e| input(format!("camera: {e:?}")))?;
            stack.push(primary_ray(&line, pixel as u32, 0));
            while let Some(ray) = stack.pop() {
                out.rays += 1;
                let (rgb, hit) = trace(&mut region, &shading, &grid, &ray, &mut stack, costs.as_deref_mut());
                let sum = &mut out.sums[pixel];
                for c in 0..3 {
                    sum[c] += u64::from(rgb[c]);
                }
                if ray.kind == RayKind::Primary {
                    out.hits[pixel] = hit.map(|h| PrimaryHit { sphere: h.sphere, t: h.t.to_num() });
                }
            }
        }
    }
    Ok(out)
}

/// A cost map being filled.
struct Costs {
    model: sim_board::CostModel,
    bytes: ByteCpu,
    hop: HopPrice,
    map: CostMap,
    /// The map of occupied cubes the nodes are sent, if any: a ray's faces
    /// in its clear tail near the grid's end are never crossed, since the
    /// node it would leave walks it on and retires it.
    occupancy: Box<Occupancy<2048>>,
    /// The cubes of the ray being walked.
    path: Vec<([i32; 3], u64)>,
}

impl Costs {
    fn new(model: &sim_board::CostModel, bytes: ByteCpu, scene: &Scene, clear_walks: bool) -> Self {
        let mut occupancy = Box::new(Occupancy::new());
        if let Some(grid) = Grid::new(scene.grid).ok().filter(|_| clear_walks) {
            let msgs = occupancy_msgs(&scene.sphere_msgs(), &grid);
            occupancy.begin(&grid);
            let taken = msgs.iter().all(|m| occupancy.take(m, &grid).is_ok());
            if !taken || occupancy.finish(msgs.len() as u16).is_err() {
                occupancy.clear();
            }
        }
        Self {
            model: *model,
            bytes,
            hop: HopPrice::new(model, bytes),
            map: CostMap::new(scene.grid),
            occupancy,
            path: Vec::new(),
        }
    }

    /// Charges the walk in `path`: each cube its cycles, and each face the
    /// ray crossed the hop. A ray that ended unhit (`clear_end`) is retired
    /// by the node it would leave where its clear tail comes within reach of
    /// the grid's end: from there on no face is crossed, and the cubes
    /// beyond (walked at the clear walk's price) and the retirement
    /// (`retire`) fall to the cube before, which that node holds were a
    /// boundary there. A face crossed costs its sides, beside the hop, the
    /// leaving node's look and, near the end, its walk on through the clear
    /// cubes to the first marked one, half to each side. Returns the cube
    /// whose holder retires the ray.
    fn add_walk(
        &mut self,
        dir: [i32; 3],
        clear_end: bool,
        grid: &Grid,
        hop: Hop,
        retire: u64,
    ) -> Option<[i32; 3]> {
        let n = self.path.len();
        let walking = self.occupancy.is_ready();
        let mut tail = n;
        if clear_end {
            while tail > 0 && self.path.get(tail - 1).is_some_and(|&(c, _)| self.occupancy.is_clear(c)) {
                tail -= 1;
            }
        }
        let within = |k: usize, cell: [i32; 3]| k >= tail && near_the_end(dir, cell, grid);
        // The first cube past a face that is not crossed.
        let cut = (tail.max(1)..n).find(|&k| within(k, self.path[k].0));
        let holder = |k: usize| match cut {
            Some(j) if k >= j => j - 1,
            _ => k,
        };
        // Clear cubes in a row from each cube on (none known without the map).
        let mut run = vec![0u64; if walking { n + 1 } else { 0 }];
        for k in (0..run.len().saturating_sub(1)).rev() {
            run[k] = if self.occupancy.is_clear(self.path[k].0) { run[k + 1] + 1 } else { 0 };
        }
        let (step, clear_step) = (self.model.cube_step, self.model.clear_step);
        for (k, &(cell, cycles)) in self.path.iter().enumerate() {
            let walked = if cut.is_some_and(|j| k >= j) { cycles - step + clear_step } else { cycles };
            self.map.add_compute(self.path[holder(k)].0, walked);
            if k > 0 && !within(k, cell) {
                let mut extra = 0;
                if walking {
                    extra = self.model.clear_look;
                    if near_the_end(dir, cell, grid) {
                        extra += run[k] * clear_step;
                    }
                }
                self.map.add_crossing(self.path[k - 1].0, cell, hop.cycles + extra / 2, hop.bytes);
            }
        }
        let (cell, _) = *self.path.get(holder(n.saturating_sub(1)))?;
        self.map.add_message(cell, retire);
        Some(cell)
    }
}

/// Traces one ray to its end; pushes its children; returns its own contribution.
fn trace(
    region: &mut Whole,
    shading: &Shading<'_>,
    grid: &Grid,
    ray: &RayMsg,
    stack: &mut Vec<RayMsg>,
    mut costs: Option<&mut Costs>,
) -> ([u32; 3], Option<Hit>) {
    let line = Line::new(
        Point::from_bits(ray.origin).expect("quantised origin"),
        Direction::from_bits(ray.dir).expect("unit direction"),
    );
    let Some(mut walk) = DigitalLine::enter(&line, grid) else {
        let rgb = if ray.kind == RayKind::Shadow { ray.weight } else { shading.background(ray) };
        return (rgb, None);
    };
    let query = Query {
        ignore: ray.ignore,
        t_max: ray.t_max.map(Scalar::from_bits),
        any_hit: ray.kind == RayKind::Shadow,
    };
    let (mut best, mut stats) = (None, node_fw::TraceStats::default());
    // A hop's cost depends on the ray's frame; priced once for its walk.
    let mut hop = Hop::default();
    if let Some(c) = costs.as_deref_mut() {
        c.map.add_compute(walk.cell(), c.model.trace + c.model.pass);
        hop = c.hop.of(ray);
    }
    let mut last = walk.cell();
    if let Some(c) = costs.as_deref_mut() {
        c.path.clear();
    }
    let outcome = region.trace_observed(&line, &mut walk, &mut best, &query, &mut stats, |cell, cube| {
        if let Some(c) = costs.as_deref_mut() {
            let cycles = c.model.cube_step
                + u64::from(cube.sphere_tests) * c.model.sphere_test
                + u64::from(cube.sphere_hits) * c.model.sphere_hit;
            c.path.push((cell, cycles));
        }
        last = cell;
    });
    let mut retired_at = None;
    if let Some(c) = costs.as_deref_mut() {
        let clear_end = matches!(outcome, Outcome::LeftGrid | Outcome::Clear);
        // The node where the ray ends retires it to the host.
        let retire = retire_cost(&c.model, c.bytes, ray);
        retired_at = c.add_walk(ray.dir, clear_end, grid, hop, retire);
        if let Outcome::Hit(_) = outcome {
            c.map.add_compute(last, c.model.shade);
        }
    }
    let (rgb, hit, background) = match outcome {
        Outcome::Hit(hit) => (shade(region, shading, ray, &line, hit, stack), Some(hit), false),
        Outcome::LeftGrid | Outcome::Clear if ray.kind == RayKind::Shadow => (ray.weight, None, false),
        Outcome::LeftGrid | Outcome::Clear => {
            let rgb = shading.background(ray);
            (rgb, None, rgb == shading.background_colour())
        }
        Outcome::Blocked | Outcome::Leave => ([0; 3], None, false),
    };
    if let (Some(c), Some(cell)) = (costs, retired_at) {
        c.map.add_host_bytes(cell, retire_bytes(ray, rgb, background));
    }
    (rgb, hit)
}

/// What `ray` hitting `hit` adds to its pixel itself; pushes its children.
fn shade(
    region: &Whole,
    shading: &Shading<'_>,
    ray: &RayMsg,
    line: &Line,
    hit: Hit,
    stack: &mut Vec<RayMsg>,
) -> [u32; 3] {
    let sphere = *region.sphere(hit.sphere).expect("hit sphere is stored");
    let Some(surface) = Surface::at(line, hit.t, &sphere) else { return [0; 3] };
    let mut rgb = shading.ambient(ray, &sphere);
    for k in 0..shading.candidates() {
        match shading.child(ray, line, &surface, &sphere, k) {
            Some(Child::Ray(child)) => stack.push(child),
            Some(Child::Done(c)) => {
                for i in 0..3 {
                    rgb[i] = rgb[i].saturating_add(c[i]);
                }
            }
            None => {}
        }
    }
    rgb
}
