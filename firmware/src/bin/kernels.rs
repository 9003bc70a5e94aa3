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
use link_proto::{MaterialMsg, SphereMsg};
use node_board::board::mps2_an385::{self as board, Timer, Uart};
use node_fw::{DigitalLine, Direction, Grid, Line, Point, Sphere};

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

fn sphere_list(grid: &Grid, rng: &mut Lcg) -> heapless::Vec<Sphere, SPHERES> {
    let mut spheres = heapless::Vec::new();
    let material =
        MaterialMsg { color: [0; 3], ambient: 0, diffuse: 0, specular: 0, shininess: 1, reflect: 0 };
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

#[entry]
fn main() -> ! {
    let (host, _, mut timer) = board::init();
    let mut out = Out(host);
    let Ok(grid) = Grid::new([256; 3]) else { board::exit(false) };
    let mut rng = Lcg(12345);

    let (ticks, steps) = cube_steps(&mut timer, &grid);
    let _ = writeln!(out, "kernel cube_step {} {steps}", per_unit_x100(ticks, steps));
    let (ticks, steps) = cube_walks(&mut timer, &grid);
    let _ = writeln!(out, "kernel cube_walk {} {steps}", per_unit_x100(ticks, steps));

    let spheres = sphere_list(&grid, &mut rng);
    if let Some(miss) = line([-100 << 16, 128 << 16, 128 << 16], [1_000_000, 1_234, -987]) {
        let (ticks, tests, hits) = sphere_tests(&mut timer, &spheres, &miss, 40);
        let _ = writeln!(out, "kernel sphere_test {} {tests} hits {hits}", per_unit_x100(ticks, tests));
    }
    // Every test a hit: a line from outside through each centre.
    let (mut ticks, mut tests) = (0, 0);
    for s in spheres.iter().take(64) {
        let c = s.center();
        if let Some(l) =
            line([c[0] - (20 << 16), c[1] - (7 << 16), c[2] + (3 << 16)], [20 << 16, 7 << 16, -3 << 16])
        {
            let (t, n, _) = sphere_tests(&mut timer, core::slice::from_ref(s), &l, 50);
            ticks += t;
            tests += n;
        }
    }
    let _ = writeln!(out, "kernel sphere_hit {} {tests}", per_unit_x100(ticks, tests));
    let _ = writeln!(out, "kernels done");
    board::exit(true)
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    board::exit(false)
}
