//! The firmware's digital line against the exact rational reference.

use node_fw::{DigitalLine, Grid, Line};
use rand::{Rng, SeedableRng, rngs::SmallRng};
use tests::{quantise, rational_walk, stiff};

/// The firmware's walk: every cube from entry until the ray leaves the grid.
fn firmware_walk(line: &Line, grid: [u16; 3]) -> Vec<[i32; 3]> {
    let grid = Grid::new(grid).unwrap();
    let Some(mut walk) = DigitalLine::enter(line, &grid) else {
        return Vec::new();
    };
    let mut cells = vec![walk.cell()];
    loop {
        walk.step();
        if !grid.contains(walk.cell()) {
            return cells;
        }
        cells.push(walk.cell());
        assert!(cells.len() <= 3 * 256 + 3, "walk does not terminate");
    }
}

fn check(name: &str, line: &Line, grid: [u16; 3]) -> usize {
    let got = firmware_walk(line, grid);
    let want = rational_walk::walk(line.origin(), line.dir(), grid);
    assert_eq!(got, want, "{name}: walk differs from the rational reference");
    if let Err(e) = rational_walk::check_walk(line.origin(), line.dir(), grid, &got) {
        panic!("{name}: {e}");
    }
    got.len()
}

#[test]
fn stiff_walk_cases_match_reference() {
    for case in stiff::walk_cases() {
        let line = quantise::line(case.origin, case.dir);
        let n = check(case.name, &line, case.grid);
        match case.name {
            "ray touching only a grid edge" | "ray missing the grid" | "ray leaving from the grid face" => {
                assert_eq!(n, 0, "{}", case.name)
            }
            _ => assert!(n > 0, "{}: empty walk", case.name),
        }
    }
}

#[test]
fn known_walks() {
    // Along x from the middle of cube 0: 256 cubes, y and z fixed.
    let line = quantise::line([0.5, 0.5, 0.5], [1.0, 0.0, 0.0]);
    let cells = firmware_walk(&line, [256; 3]);
    assert_eq!(cells.len(), 256);
    assert!(cells.iter().enumerate().all(|(i, c)| *c == [i as i32, 0, 0]));
    // Through lattice corners along (1,1,1): each corner costs two extra
    // single-point cubes under the one-axis-per-step rule: x first, then y, then z.
    let line = quantise::line([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    let cells = firmware_walk(&line, [4; 3]);
    assert_eq!(&cells[..4], &[[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1]]);
    assert_eq!(cells.len(), 10);
}

#[test]
fn random_rays_match_reference() {
    let mut rng = SmallRng::seed_from_u64(0x5eed_0001);
    let mut cubes = 0;
    for i in 0..6000 {
        let grid = [rng.gen_range(1..=24u16), rng.gen_range(1..=24u16), rng.gen_range(1..=24u16)];
        // Origins inside, on lattice planes, and outside the grid.
        let origin: [f64; 3] = std::array::from_fn(|a| {
            let s = grid[a] as f64;
            match rng.gen_range(0..4) {
                0 => rng.gen_range(0.0..s),
                1 => rng.gen_range(0..=grid[a]) as f64,
                2 => rng.gen_range(-3.0 * s..4.0 * s),
                _ => (rng.gen_range(0.0..s) * 4.0).round() / 4.0,
            }
        });
        let dir: [f64; 3] = std::array::from_fn(|_| match rng.gen_range(0..6) {
            0 => 0.0,
            1 => rng.gen_range(-1.0..1.0) * 1e-6,
            2 => [1.0, -1.0, 0.5, -0.5][rng.gen_range(0..4)],
            _ => rng.gen_range(-1.0..1.0),
        });
        if dir.iter().all(|&d| d == 0.0) {
            continue;
        }
        let line = quantise::line(origin, dir);
        cubes += check(&format!("random ray {i}"), &line, grid);
    }
    assert!(cubes > 20_000, "too few cubes walked to mean anything: {cubes}");
}

#[test]
fn resume_continues_bit_identically() {
    // A walk resumed from any of its cubes continues exactly as the original.
    let grid = Grid::new([32; 3]).unwrap();
    let mut rng = SmallRng::seed_from_u64(7);
    for _ in 0..300 {
        let origin: [f64; 3] = std::array::from_fn(|_| rng.gen_range(-40.0..70.0));
        let dir: [f64; 3] = std::array::from_fn(|_| rng.gen_range(-1.0..1.0));
        let line = quantise::line(origin, dir);
        let Some(mut walk) = DigitalLine::enter(&line, &grid) else {
            continue;
        };
        let mut k = 0;
        while grid.contains(walk.cell()) {
            let resumed = DigitalLine::resume(&line, walk.cell()).unwrap();
            assert_eq!(resumed, walk, "resume at step {k}");
            walk.step();
            k += 1;
        }
    }
}

#[test]
fn resume_rejects_cells_off_the_line() {
    let grid = Grid::new([16; 3]).unwrap();
    let line = quantise::line([0.5, 0.5, 0.5], [1.0, 0.25, 0.0]);
    assert!(DigitalLine::enter(&line, &grid).is_some());
    assert!(DigitalLine::resume(&line, [0, 0, 0]).is_ok());
    assert!(DigitalLine::resume(&line, [0, 5, 0]).is_err(), "cube the line never reaches");
    assert!(DigitalLine::resume(&line, [0, 0, 3]).is_err(), "z off the line with d_z = 0");
    assert!(DigitalLine::resume(&line, [-3, 0, 0]).is_err(), "cube behind the origin");
}
