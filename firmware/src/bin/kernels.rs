//! Instruction counts of the firmware's kernels on the emulated Cortex-M3.
//!
//! Run under `qemu-system-arm -machine mps2-an385 -icount shift=0`, where one
//! instruction is one nanosecond of virtual time, so the 25 MHz timer counts
//! one tick per 40 instructions; each kernel runs thousands of times and the
//! average is printed over UART 0 as `kernel <name> <instructions x 100>
//! <count>` lines (the timed loops' own overhead included), then the program exits through semihosting.
#![no_std]
#![no_main]

use core::fmt::Write as _;

use cortex_m_rt::entry;
use embedded_io::Write;
use link_proto::ray_wire::{ORIGIN_AT_EYE, PIXEL_CREDIT};
use link_proto::{
    CameraMsg, LightMsg, MAX_FRAME_LEN, MaterialMsg, Message, OccupancyMsg, OutgoingRay, RayKind, RayMsg,
    RayReply, Retire, Retirements, SceneHeader, SphereMsg,
};
use node_board::board::mps2_an385::{self as board, Timer, Uart};
use node_board::capacity::WINDOW;
use node_fw::camera::{primary_line, primary_ray};
use node_fw::digital_line::wire_cell;
use node_fw::occupancy::Occupancy;
use node_fw::reliable::Channel;
use node_fw::shading::{Scene, Surface};
use node_fw::{CubeBox, DigitalLine, Direction, Grid, Line, Point, Sphere, Subregion};

/// Nanoseconds (instructions) per timer tick.
const NS_PER_TICK: u64 = 40;
/// Spheres in the sphere-test list.
const SPHERES: usize = 256;

struct Out(Uart);

impl core::fmt::Write for Out {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0.write_all(s.as_bytes()).map_err(|_| core::fmt::Error)
    }
}

/// A small linear congruential generator (no floats on the board).
struct Lcg(u64);

impl Lcg {
    fn below(&mut self, n: u32) -> u32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 32) as u32) % n
    }
}

fn line(origin: [i32; 3], dir: [i64; 3]) -> Option<Line> {
    Some(Line::new(Point::from_bits(origin).ok()?, Direction::normalize(dir).ok()?))
}

/// Average instructions x 100 per unit over `units` units taking `ticks`.
fn per_unit_x100(ticks: u64, units: u64) -> u64 {
    ticks * NS_PER_TICK * 100 / units.max(1)
}

/// Lines through the 256-cube grid: diagonal, from an eye far outside, along an axis.
fn walk_lines() -> [Option<Line>; 3] {
    [
        line([32768, 45875, 19661], [1_000_000, 618_034, 381_966]),
        line([-589_824_000, -262_144_000, -196_608_000], [1_000_000, 470_000, 340_000]),
        line([32768, 32768, 32768], [1, 0, 0]),
    ]
}

/// `DigitalLine::step` alone: each line's known number of steps, no exit test.
#[inline(never)]
fn cube_steps(timer: &mut Timer, grid: &Grid) -> (u64, u64) {
    let lines = walk_lines();
    let mut counts = [0u64; 3];
    for (l, count) in lines.iter().zip(counts.iter_mut()) {
        let Some(mut walk) = l.as_ref().and_then(|l| DigitalLine::enter(l, grid)) else { continue };
        while grid.contains(walk.cell()) {
            walk.step();
            *count += 1;
        }
    }
    let (mut steps, start) = (0u64, timer.ticks());
    for _ in 0..20 {
        for (l, &count) in lines.iter().zip(counts.iter()) {
            let Some(mut walk) = l.as_ref().and_then(|l| DigitalLine::enter(l, grid)) else { continue };
            for _ in 0..count {
                core::hint::black_box(walk.step());
            }
            steps += count;
        }
    }
    (timer.ticks() - start, steps)
}

/// A walk as the node does it: a step, then whether the cube is still inside.
/// Kept out of `main` (as is `cube_steps`): inlined there, its registers were
/// allocated anew whenever other kernels changed, and its count moved by 8%.
#[inline(never)]
fn cube_walks(timer: &mut Timer, grid: &Grid) -> (u64, u64) {
    let lines = walk_lines();
    let (mut steps, start) = (0u64, timer.ticks());
    for _ in 0..20 {
        for l in lines.iter().flatten() {
            let Some(mut walk) = DigitalLine::enter(l, grid) else { continue };
            while grid.contains(walk.cell()) {
                walk.step();
                steps += 1;
            }
        }
    }
    (timer.ticks() - start, steps)
}

/// A map of a 32^3 grid with every cube clear, in use.
fn clear_map(grid: &Grid) -> Occupancy<1024> {
    let mut map = Occupancy::new();
    map.begin(grid);
    let _ = map.take(&OccupancyMsg { first: 0, bits: [0; 32] }, grid);
    let _ = map.finish(1);
    map
}

/// Walks past a node's box through clear cubes to the grid's end
/// (`Occupancy::walk_clear`), from ten cubes before each line's exit: per
/// cube walked, the call and its look at how far the end is included.
#[inline(never)]
fn clear_walks(timer: &mut Timer) -> (u64, u64) {
    let Ok(grid) = Grid::new([32; 3]) else { return (0, 0) };
    let map = clear_map(&grid);
    let lines = [
        line([32768, 45875, 19661], [1_000_000, 618_034, 381_966]),
        line([-(40 << 16), -(10 << 16), -(30 << 16)], [1_000_000, 470_000, 340_000]),
        line([(16 << 16) + 4321, (20 << 16) + 999, -(8 << 16)], [-120_000, 310_000, 1_000_000]),
        line([32768, 32768, 32768], [1, 0, 0]),
    ];
    let (mut steps, mut ticks) = (0u64, 0u64);
    for l in lines.iter().flatten() {
        let Some(mut walk) = DigitalLine::enter(l, &grid) else { continue };
        let mut n = 0u32;
        while grid.contains(walk.cell()) {
            walk.step();
            n += 1;
        }
        let Some(mut start) = DigitalLine::enter(l, &grid) else { continue };
        for _ in 0..n.saturating_sub(10) {
            start.step();
        }
        let t0 = timer.ticks();
        for _ in 0..50 {
            let mut walk = start.clone();
            let mut taken = 0;
            core::hint::black_box(map.walk_clear(l, &mut walk, &grid, None, &mut taken));
            steps += u64::from(taken);
        }
        ticks += timer.ticks() - t0;
    }
    (ticks, steps)
}

/// A ray far from the grid's end: the map is not walked, only the end's
/// distance looked at (`Occupancy::walk_clear` returns at once).
#[inline(never)]
fn clear_looks(timer: &mut Timer) -> (u64, u64) {
    let Ok(grid) = Grid::new([32; 3]) else { return (0, 0) };
    let map = clear_map(&grid);
    // Turned away, the walk is left as it was: no copy needed.
    let mut walks = walk_lines().map(|l| l.and_then(|l| Some((l, DigitalLine::enter(&l, &grid)?))));
    let (mut looks, start) = (0u64, timer.ticks());
    for _ in 0..100 {
        for (l, walk) in walks.iter_mut().flatten() {
            let mut taken = 0;
            core::hint::black_box(map.walk_clear(l, walk, &grid, None, &mut taken));
            looks += 1;
        }
    }
    (timer.ticks() - start, looks)
}

/// Looking whether a leaving ray still needs the sphere it ignores
/// (`Subregion::left_behind`): a node's box of 8^3 cubes holding 32
/// spheres (about what a node of the paper's 4x4x4 array holds), a ray
/// leaving from beside each, half of them with the sphere behind it. Per look.
#[inline(never)]
fn ignore_looks(timer: &mut Timer, rng: &mut Lcg) -> (u64, u64) {
    let Ok(grid) = Grid::new([32; 3]) else { return (0, 0) };
    let mut region = Subregion::<32, 1024, 512>::new();
    if region.assign(grid, CubeBox { lo: [0; 3], hi: [8; 3] }).is_err() {
        return (0, 0);
    }
    let material = material(0);
    let mut leaving = heapless::Vec::<(u16, [i32; 3], [i32; 3]), 32>::new();
    for id in 0..32u16 {
        let radius = 16_384 + rng.below(1 << 16) as i32;
        let center = [0; 3].map(|_| (1 << 16) + rng.below(6 << 16) as i32);
        let Ok(s) = Sphere::from_msg(&SphereMsg { id: id * 31, center, radius, material }, &grid) else {
            continue;
        };
        let _ = region.insert(s);
        // Two cubes beyond the sphere's, going on away from it or coming back.
        let cell = [(center[0] >> 16) + 3, center[1] >> 16, center[2] >> 16];
        let dir = if id % 2 == 0 { [1 << 29, 1 << 28, -(1 << 28)] } else { [-(1 << 29), 1 << 28, 1 << 28] };
        let _ = leaving.push((id * 31, cell, dir));
    }
    let (mut looks, start) = (0u64, timer.ticks());
    for _ in 0..50 {
        for &(id, cell, dir) in &leaving {
            core::hint::black_box(region.left_behind(core::hint::black_box(id), cell, dir));
            looks += 1;
        }
    }
    (timer.ticks() - start, looks)
}

/// A map message taken (`Occupancy::take`): the whole map of a 32^3 grid,
/// 128 messages, about a quarter of the cubes marked (the paper's scene
/// marks a quarter), taken ten times over. Per message.
#[inline(never)]
fn map_takes(timer: &mut Timer, rng: &mut Lcg) -> (u64, u64) {
    let Ok(grid) = Grid::new([32; 3]) else { return (0, 0) };
    let mut msgs = [OccupancyMsg { first: 0, bits: [0; 32] }; 8];
    for (i, m) in msgs.iter_mut().enumerate() {
        m.first = 256 * i as u32;
        for b in m.bits.iter_mut() {
            for bit in 0..8 {
                if rng.below(4) == 0 {
                    *b |= 1 << bit;
                }
            }
        }
    }
    let mut map = Occupancy::<1024>::new();
    let (mut taken, mut ticks) = (0u64, 0u64);
    for _ in 0..10 {
        map.begin(&grid);
        let t0 = timer.ticks();
        for k in 0..128u32 {
            let Some(m) = msgs.get((k % 8) as usize) else { continue };
            let m = OccupancyMsg { first: 256 * k, bits: m.bits };
            if core::hint::black_box(map.take(&m, &grid)).is_ok() {
                taken += 1;
            }
        }
        ticks += timer.ticks() - t0;
    }
    (ticks, taken)
}

/// The kernels' spheres' material: grey, lit, a mirror as far as `reflect` says.
fn material(reflect: u16) -> MaterialMsg {
    MaterialMsg {
        color: [20_000; 3],
        ambient: 8_000,
        diffuse: 20_000,
        specular: 10_000,
        shininess: 8,
        reflect,
    }
}

fn sphere_list(grid: &Grid, rng: &mut Lcg) -> heapless::Vec<Sphere, SPHERES> {
    let mut spheres = heapless::Vec::new();
    let material = material(16_000);
    for id in 0..SPHERES as u16 {
        let radius = 3277 + rng.below(2 << 16) as i32;
        let center = [0; 3].map(|_| (8 << 16) + rng.below(240 << 16) as i32);
        let m = SphereMsg { id, center, radius, material };
        if let Ok(s) = Sphere::from_msg(&m, grid) {
            let _ = spheres.push(s);
        }
    }
    spheres
}

fn sphere_tests(timer: &mut Timer, spheres: &[Sphere], l: &Line, rounds: u32) -> (u64, u64, u64) {
    let (mut tests, mut hits, start) = (0u64, 0u64, timer.ticks());
    for _ in 0..rounds {
        for s in spheres {
            tests += 1;
            hits += u64::from(core::hint::black_box(s).intersect(l).is_some());
        }
    }
    (timer.ticks() - start, tests, hits)
}

/// Tests that all hit: a line from outside through each sphere's centre.
/// Out of line only in the profile build, so that a trace can tell where it
/// begins.
#[cfg_attr(feature = "profile", inline(never))]
fn sphere_hits(timer: &mut Timer, spheres: &[Sphere]) -> (u64, u64) {
    let (mut ticks, mut tests) = (0, 0);
    for s in spheres.iter().take(64) {
        let c = s.center();
        if let Some(l) =
            line([c[0] - (20 << 16), c[1] - (7 << 16), c[2] + (3 << 16)], [20 << 16, 7 << 16, -3 << 16])
        {
            let (t, n, _) = sphere_tests(timer, core::slice::from_ref(s), &l, 50);
            ticks += t;
            tests += n;
        }
    }
    (ticks, tests)
}

/// A camera 200 cubes in front of a 256-cube grid, looking at its middle.
fn camera() -> CameraMsg {
    let one = 1 << 30;
    CameraMsg {
        eye: [128 << 16, 128 << 16, -(200 << 16)],
        corner: [-one / 4, -one / 4, one],
        du: [one / 64, 0, 0],
        dv: [0, one / 64, 0],
    }
}

/// Creating initial rays: the pixel's line, the ray, and its entry cube.
fn creations(timer: &mut Timer, grid: &Grid, rays: &mut heapless::Vec<RayMsg, 64>) -> (u64, u64) {
    let cam = camera();
    let (mut created, start) = (0u64, timer.ticks());
    for y in 0..32u16 {
        for x in 0..32u16 {
            let Ok(line) = primary_line(&cam, x, y) else { continue };
            let mut ray = primary_ray(&line, u32::from(y) * 32 + u32::from(x), 1 << 20);
            if let Some(walk) = DigitalLine::enter(&line, grid) {
                ray.cell = walk.cell().map(|c| c as u16);
            }
            if (x ^ y) % 16 == 0 {
                let _ = rays.push(ray);
            }
            core::hint::black_box(&ray);
            created += 1;
        }
    }
    (timer.ticks() - start, created)
}

/// Setting up a walk for a received ray: its line, checked, and the resumed
/// walk. Out of line only in the profile build, so that a trace can tell
/// where it begins: out of line, the compiler lays the loop out differently
/// and the kernel measures a few instructions fewer than the product's
/// inlined set-up, which is what the cost model must charge.
#[cfg_attr(feature = "profile", inline(never))]
fn walk_setups(timer: &mut Timer, rays: &[RayMsg]) -> (u64, u64) {
    let (mut setups, start) = (0u64, timer.ticks());
    for _ in 0..20 {
        for ray in rays {
            let line = Line::from_bits(ray.origin, ray.dir);
            if let Ok(line) = line {
                core::hint::black_box(DigitalLine::resume(&line, wire_cell(ray.cell)).is_ok());
            }
            setups += 1;
        }
    }
    (timer.ticks() - start, setups)
}

/// Shading hits on a mirror sphere lit by one light, as the node does it: the
/// surface and both children (a shadow ray and a reflection), evaluated once
/// (the node spawns what it evaluated; only a hit the pool cannot take all
/// children of evaluates the rest again later).
#[cfg_attr(feature = "profile", inline(never))]
fn shadings(timer: &mut Timer, grid: &Grid, spheres: &[Sphere]) -> (u64, u64) {
    let header = SceneHeader {
        grid: [256; 3],
        ambient: [3000; 3],
        background: [0; 3],
        max_depth: 3,
        map: link_proto::MapLoad::Sent,
    };
    let lights = [LightMsg { id: 0, position: [10 << 16, 250 << 16, 10 << 16], color: [32768; 3] }];
    let scene = Scene { header: &header, grid, lights: &lights };
    let (mut shaded, mut ticks) = (0u64, 0u64);
    for s in spheres.iter().take(64) {
        let c = s.center();
        let Some(l) =
            line([c[0] - (20 << 16), c[1] - (7 << 16), c[2] + (3 << 16)], [20 << 16, 7 << 16, -3 << 16])
        else {
            continue;
        };
        let Some(root) = s.intersect(&l) else { continue };
        let ray = primary_ray(&l, 0, 1 << 20);
        let start = timer.ticks();
        for _ in 0..10 {
            if let Some(surface) = Surface::at(&l, root.t, s) {
                for k in 0..scene.candidates() {
                    core::hint::black_box(scene.child(&ray, &l, &surface, s, k));
                }
            }
            shaded += 1;
        }
        ticks += timer.ticks() - start;
    }
    (ticks, shaded)
}

/// Rays as nodes of the paper's 32^3 grid pass them: every other one a
/// primary ray from the eye (which the wire leaves out, as a node does) on
/// its third hop, the rest reflections from a point in the primary's cube
/// (as a real reflection starts on a sphere in the grid) with part of its
/// weight and half its credit (as a hit splits it), half of them still
/// naming the sphere they leave (as on their first hop). Their cubes are taken
/// modulo 32 (the kernels' grid is 256 cubes a side), so that each ray
/// takes the wire form it would have in the paper's grid.
fn wire_rays(primaries: &[RayMsg]) -> heapless::Vec<RayMsg, 64> {
    let mut out = heapless::Vec::new();
    for (k, ray) in primaries.iter().enumerate() {
        let ray = RayMsg { cell: ray.cell.map(|c| c % 32), ..*ray };
        let ray = if k % 2 == 0 {
            RayMsg { origin: ORIGIN_AT_EYE, credit: PIXEL_CREDIT, class: 3, ..ray }
        } else {
            RayMsg {
                origin: ray.cell.map(|c| (i32::from(c) << 16) + 12_345),
                kind: RayKind::Reflected,
                weight: [20_000, 15_000, 9_000],
                credit: PIXEL_CREDIT / 2,
                depth: 1,
                ignore: (k % 4 == 1).then_some(417),
                ..ray
            }
        };
        let _ = out.push(ray);
    }
    out
}

/// The two ends of a link, with the incarnations they announce.
fn channel_pair() -> (Channel<WINDOW>, Channel<WINDOW>) {
    let (mut a, mut b) = (Channel::<WINDOW>::new(1 << 40), Channel::<WINDOW>::new(1 << 40));
    a.set_incarnation(1);
    b.set_incarnation(2);
    (a, b)
}

/// Bytes on the way, and the scratch buffer frames are encoded in, kept
/// between calls as `FramedLinks` keeps it.
type Wire = (heapless::Vec<u8, 1024>, [u8; MAX_FRAME_LEN]);

/// Moves what `from` has due at `round` over `wire` into `to`.
fn pass(
    from: &mut Channel<WINDOW>,
    to: &mut Channel<WINDOW>,
    round: u64,
    wire: &mut Wire,
    deliver: impl FnMut(Message) -> bool,
) {
    from.transmit_via(round, &mut wire.1, |f| wire.0.extend_from_slice(f).is_ok());
    to.receive(&wire.0, deliver);
    wire.0.clear();
}

/// Passing each of `rays` over a hop as nodes do: the ray through a reliable
/// channel pair, the receiver's reply carrying its ack, and the sender's ack
/// of the replies in a frame of its own as the channel sends it when it has
/// nothing else for that neighbour, once per half window (per hop and end,
/// bytes on the UART not included).
fn hops(timer: &mut Timer, rays: &[RayMsg]) -> (u64, u64) {
    let (mut a, mut b) = channel_pair();
    let mut wire = (heapless::Vec::new(), [0; MAX_FRAME_LEN]);
    let (mut passed, start) = (0u64, timer.ticks());
    for round in 0..40u64 {
        for ray in rays {
            let _ = a.send_ray(&OutgoingRay::of(ray, false));
            let mut tag = None;
            pass(&mut a, &mut b, round, &mut wire, |m| {
                if let Message::Ray(r) = m {
                    tag = Some(r.tag);
                }
                true
            });
            if let Some(tag) = tag {
                let _ = b.send(Message::RayReply(RayReply { tag, accepted: true }));
            }
            pass(&mut b, &mut a, round, &mut wire, |m| {
                core::hint::black_box(matches!(m, Message::RayReply(_)))
            });
            pass(&mut a, &mut b, round, &mut wire, |_| true);
            passed += 1;
        }
    }
    // Two ends handle each hop.
    (timer.ticks() - start, 2 * passed)
}

/// Passing each of `rays` over a hop on a grant: the ray, packed from where
/// it lies as a node sends it, through a reliable channel pair and the receiver's acks in frames of their own as the
/// channel sends them when nothing goes back to carry them, once per half
/// window; no reply (per hop and end, bytes on the UART not included).
/// Out of line, so that a trace can tell where it begins.
#[inline(never)]
fn granted_hops(timer: &mut Timer, rays: &[RayMsg]) -> (u64, u64) {
    let (mut a, mut b) = channel_pair();
    let mut wire = (heapless::Vec::new(), [0; MAX_FRAME_LEN]);
    let (mut passed, start) = (0u64, timer.ticks());
    for round in 0..40u64 {
        for ray in rays {
            let _ = a.send_ray(&OutgoingRay::of(ray, true));
            pass(&mut a, &mut b, round, &mut wire, |m| core::hint::black_box(m.is_ray()));
            pass(&mut b, &mut a, round, &mut wire, |_| true);
            passed += 1;
        }
    }
    (timer.ticks() - start, 2 * passed)
}

/// Rays queued together on a busy link: [`BATCH`] rays on a grant at a
/// time through a reliable channel pair, leaving in one frame, and the
/// receiver's acks as in `granted_hops` (per ray and end, bytes on the UART
/// not included).
fn batched_hops(timer: &mut Timer, rays: &[RayMsg]) -> (u64, u64) {
    let (mut a, mut b) = channel_pair();
    let mut wire = (heapless::Vec::new(), [0; MAX_FRAME_LEN]);
    let (mut passed, start) = (0u64, timer.ticks());
    for round in 0..40u64 {
        for batch in rays.chunks(BATCH) {
            for ray in batch {
                let _ = a.send_ray(&OutgoingRay::of(ray, true));
            }
            pass(&mut a, &mut b, round, &mut wire, |m| core::hint::black_box(m.is_ray()));
            pass(&mut b, &mut a, round, &mut wire, |_| true);
            passed += batch.len() as u64;
        }
    }
    (timer.ticks() - start, 2 * passed)
}

/// Rays in a batch in the `hop_batched` kernel: what a link backed up
/// behind its wire holds at once, about.
const BATCH: usize = 4;

/// Passing a reply to each of `rays` through a reliable channel pair, both
/// ends and the acks, in frames of their own once per half window (per
/// message and end, bytes on the UART not included).
#[cfg_attr(feature = "profile", inline(never))]
fn replies(timer: &mut Timer, rays: &[RayMsg]) -> (u64, u64) {
    let (mut a, mut b) = channel_pair();
    let mut wire = (heapless::Vec::new(), [0; MAX_FRAME_LEN]);
    let (mut passed, start) = (0u64, timer.ticks());
    for round in 0..40u64 {
        for ray in rays {
            let _ = a.send(Message::RayReply(RayReply { tag: ray.tag, accepted: true }));
            pass(&mut a, &mut b, round, &mut wire, |m| {
                core::hint::black_box(!matches!(m, Message::Hello(_)))
            });
            pass(&mut b, &mut a, round, &mut wire, |_| true);
            passed += 1;
        }
    }
    // Two ends handle each message.
    (timer.ticks() - start, 2 * passed)
}

/// Records in the `retire_batch` kernel's messages: what a busy node's
/// messages hold, about (`scripts/firmware.sh` prices it so).
const RETIRE_BATCH: usize = 6;

/// A node sending retirements to the host, `per` records to a message (of
/// different pixels): the node's end alone, as the in-memory board charges
/// it (the message built, framed and written; the host's acks, which go
/// alone every half window, taken). Per message.
#[cfg_attr(feature = "profile", inline(never))]
fn retirements(timer: &mut Timer, rays: &[RayMsg], per: usize) -> (u64, u64) {
    let (mut node, mut host) = channel_pair();
    let mut wire: Wire = (heapless::Vec::new(), [0; MAX_FRAME_LEN]);
    let (mut sent, mut ticks) = (0u64, 0u64);
    for round in 0..20u64 {
        for chunk in rays.chunks(per) {
            let start = timer.ticks();
            let mut records = chunk.iter().map(|ray| Retire {
                pixel: ray.pixel,
                rgb: [ray.pixel * 7 % 9000, 1200, ray.pixel % 300],
                // Shares as hits split them: powers of two.
                credit: PIXEL_CREDIT >> (1 + ray.pixel % 4),
                spawned: (ray.pixel % 3) as u8,
                rays: 1,
                background: 0,
            });
            let Some(first) = records.next() else { continue };
            let mut batch = Retirements::new(first);
            for r in records {
                if batch.push(r).is_err() {
                    // The kernel would measure fewer records than it says.
                    board::exit(false)
                }
            }
            let _ = node.send(Message::Retire(batch));
            node.transmit_via(round, &mut wire.1, |f| wire.0.extend_from_slice(f).is_ok());
            ticks += timer.ticks() - start;
            host.receive(&wire.0, |m| core::hint::black_box(matches!(m, Message::Retire(_))));
            wire.0.clear();
            host.transmit_via(round, &mut wire.1, |f| wire.0.extend_from_slice(f).is_ok());
            let start = timer.ticks();
            node.receive(&wire.0, |_| true);
            ticks += timer.ticks() - start;
            wire.0.clear();
            sent += 1;
        }
    }
    (ticks, sent)
}

/// Where one end of a hop goes, each part of a ray's frame apart: encoding
/// it whole (postcard, CRC and COBS), decoding it whole, the CRC alone, COBS
/// alone both ways, and the frame's length. The parts are the plain CRC and
/// COBS's general pass over the masked payload: a frame is masked in the
/// CRC's pass, and only one left with a zero pays the general pass. Per ray; not charged by the cost
/// model (its `ray_message` is the hop's end as a whole), printed to show
/// what a cheaper transport must cut.
fn frame_parts(timer: &mut Timer, rays: &[RayMsg]) -> [(&'static str, u64, u64); 6] {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut work = [0u8; MAX_FRAME_LEN];
    let (mut decoder, mut into) =
        (link_proto::FrameDecoder::new(), link_proto::Frame::new(0, Message::Space));
    let (mut encode, mut decode, mut crc, mut cobs_enc, mut cobs_dec, mut bytes) = (0, 0, 0, 0, 0, 0);
    let mut n = 0u64;
    for round in 0..20u8 {
        for ray in rays {
            let frame = link_proto::Frame::new(round, Message::Ray(*ray));
            let start = timer.ticks();
            let Ok(len) = core::hint::black_box(link_proto::encode_frame(&frame, &mut buf)) else { continue };
            encode += timer.ticks() - start;
            bytes += len as u64;
            // Into a frame kept, as a channel decodes.
            let start = timer.ticks();
            let decoded = decoder.decode_into(&mut buf.get(..len).unwrap_or_default(), &mut into);
            core::hint::black_box((&decoded, &into));
            decode += timer.ticks() - start;
            // The payload between the delimiters, COBS-decoded, for the parts.
            let Some(stuffed) = buf.get(1..len - 1) else { continue };
            let Some(w) = work.get_mut(..stuffed.len()) else { continue };
            w.copy_from_slice(stuffed);
            let start = timer.ticks();
            let payload_len = core::hint::black_box(link_proto::cobs::decode_slice(w)).map_or(0, <[u8]>::len);
            cobs_dec += timer.ticks() - start;
            // Plain chains (every frame's) decode to the bytes after the first code.
            let Some(payload) = work.get(1..=payload_len) else { continue };
            let start = timer.ticks();
            core::hint::black_box(link_proto::frame::checksum(payload));
            crc += timer.ticks() - start;
            // Encoding in place wants the slot for its first code at w[0]: there already.
            let Some(w) = work.get_mut(..payload_len + 1) else { continue };
            let start = timer.ticks();
            core::hint::black_box(link_proto::cobs::encode_in_place(w));
            cobs_enc += timer.ticks() - start;
            n += 1;
        }
    }
    let per = |t: u64| per_unit_x100(t, n);
    [
        ("ray_frame_encode", per(encode), n),
        ("ray_frame_decode", per(decode), n),
        ("ray_frame_crc", per(crc), n),
        ("ray_frame_cobs_encode", per(cobs_enc), n),
        ("ray_frame_cobs_decode", per(cobs_dec), n),
        // Bytes on the wire per frame (x 100, as the other lines).
        ("ray_frame_bytes", 100 * bytes / n.max(1), n),
    ]
}

/// Checks the firmware's `__aeabi_memcpy` (`node_board::memcpy`) against a
/// byte loop for every source and destination alignment and every length
/// up to 80, and that it writes nothing outside the destination.
#[inline(never)]
fn memcpy_is_exact() -> bool {
    let mut src = [0u8; 96];
    for (i, b) in src.iter_mut().enumerate() {
        *b = (i as u8).wrapping_mul(37).wrapping_add(11);
    }
    for from in 0..4 {
        for to in 0..4 {
            for len in 0..=80 {
                let mut dst = [0xA5u8; 96];
                let n = core::hint::black_box(len);
                // SAFETY: both ranges lie inside their arrays and do not overlap.
                #[allow(unsafe_code)]
                unsafe {
                    core::ptr::copy_nonoverlapping(src.as_ptr().add(from), dst.as_mut_ptr().add(to), n)
                };
                let copied = (0..len).all(|i| dst.get(to + i) == src.get(from + i));
                let untouched =
                    dst.iter().enumerate().all(|(i, &b)| (to..to + len).contains(&i) || b == 0xA5);
                if !copied || !untouched {
                    return false;
                }
            }
        }
    }
    true
}

/// With the `profile` feature, only the kernel that `PROFILE_KERNEL` names at
/// build time (`hop_granted` unless it names `trace`, `sphere_hit`,
/// `reply`, `shade` or `retire_batch`), for
/// scripts/profile-kernel.sh, which traces it from its entry on: what comes
/// before is set-up.
fn profile(timer: &mut Timer, out: &mut Out, grid: &Grid) -> ! {
    let mut rays = heapless::Vec::new();
    creations(timer, grid, &mut rays);
    let (name, (ticks, n)) = match option_env!("PROFILE_KERNEL") {
        Some("trace") => ("trace", walk_setups(timer, &rays)),
        Some("sphere_hit") => {
            let mut rng = Lcg(12345);
            ("sphere_hit", sphere_hits(timer, &sphere_list(grid, &mut rng)))
        }
        Some("reply") => ("reply", replies(timer, &wire_rays(&rays))),
        Some("shade") => {
            let mut rng = Lcg(12345);
            ("shade", shadings(timer, grid, &sphere_list(grid, &mut rng)))
        }
        Some("retire_batch") => ("retire_batch", retirements(timer, &wire_rays(&rays), RETIRE_BATCH)),
        _ => ("hop_granted", granted_hops(timer, &wire_rays(&rays))),
    };
    let _ = writeln!(out, "kernel {name} {} {n}", per_unit_x100(ticks, n));
    board::exit(true)
}

#[entry]
fn main() -> ! {
    let board::Parts { host, clock: mut timer, .. } = board::init();
    let mut out = Out(host);
    let Ok(grid) = Grid::new([256; 3]) else { board::exit(false) };
    let mut rng = Lcg(12345);
    if !memcpy_is_exact() {
        let _ = writeln!(out, "error: __aeabi_memcpy copied wrongly");
        board::exit(false)
    }

    if cfg!(feature = "profile") {
        profile(&mut timer, &mut out, &grid)
    }
    let (ticks, steps) = cube_steps(&mut timer, &grid);
    let _ = writeln!(out, "kernel cube_step {} {steps}", per_unit_x100(ticks, steps));
    let (ticks, steps) = cube_walks(&mut timer, &grid);
    let _ = writeln!(out, "kernel cube_walk {} {steps}", per_unit_x100(ticks, steps));
    let (ticks, steps) = clear_walks(&mut timer);
    let _ = writeln!(out, "kernel clear_walk {} {steps}", per_unit_x100(ticks, steps));
    let (ticks, looks) = clear_looks(&mut timer);
    let _ = writeln!(out, "kernel clear_look {} {looks}", per_unit_x100(ticks, looks));
    let (ticks, looks) = ignore_looks(&mut timer, &mut Lcg(4242));
    let _ = writeln!(out, "kernel ignore_look {} {looks}", per_unit_x100(ticks, looks));
    let (ticks, taken) = map_takes(&mut timer, &mut Lcg(777));
    let _ = writeln!(out, "kernel map_take {} {taken}", per_unit_x100(ticks, taken));

    let spheres = sphere_list(&grid, &mut rng);
    if let Some(miss) = line([-100 << 16, 128 << 16, 128 << 16], [1_000_000, 1_234, -987]) {
        let (ticks, tests, hits) = sphere_tests(&mut timer, &spheres, &miss, 40);
        let _ = writeln!(out, "kernel sphere_test {} {tests} hits {hits}", per_unit_x100(ticks, tests));
    }
    let (ticks, tests) = sphere_hits(&mut timer, &spheres);
    let _ = writeln!(out, "kernel sphere_hit {} {tests}", per_unit_x100(ticks, tests));

    let mut rays = heapless::Vec::new();
    let (ticks, n) = creations(&mut timer, &grid, &mut rays);
    let _ = writeln!(out, "kernel create {} {n}", per_unit_x100(ticks, n));
    let (ticks, n) = walk_setups(&mut timer, &rays);
    let _ = writeln!(out, "kernel trace {} {n}", per_unit_x100(ticks, n));
    let (ticks, n) = shadings(&mut timer, &grid, &spheres);
    let _ = writeln!(out, "kernel shade {} {n}", per_unit_x100(ticks, n));
    let rays = wire_rays(&rays);
    let (ticks, n) = hops(&mut timer, &rays);
    let _ = writeln!(out, "kernel hop {} {n}", per_unit_x100(ticks, n));
    let (ticks, n) = replies(&mut timer, &rays);
    let _ = writeln!(out, "kernel reply {} {n}", per_unit_x100(ticks, n));
    let (ticks, n) = granted_hops(&mut timer, &rays);
    let _ = writeln!(out, "kernel hop_granted {} {n}", per_unit_x100(ticks, n));
    let (ticks, n) = batched_hops(&mut timer, &rays);
    let _ = writeln!(out, "kernel hop_batched {} {n}", per_unit_x100(ticks, n));
    let (ticks, n) = retirements(&mut timer, &rays, 1);
    let _ = writeln!(out, "kernel retire {} {n}", per_unit_x100(ticks, n));
    let (ticks, n) = retirements(&mut timer, &rays, RETIRE_BATCH);
    let _ = writeln!(out, "kernel retire_batch {} {n}", per_unit_x100(ticks, n));
    for (name, x100, n) in frame_parts(&mut timer, &rays) {
        let _ = writeln!(out, "kernel {name} {x100} {n}");
    }
    let _ = writeln!(out, "kernels done");
    board::exit(true)
}
