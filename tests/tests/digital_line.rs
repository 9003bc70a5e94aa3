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

/// Rays along cube diagonals pass exactly through edges and corners, where
/// the cube is entered at the very parameter it is left: such a cube meets
/// the ray in one point and is taken, its neighbours past the point are not.
#[test]
fn resume_takes_cubes_the_ray_only_touches() {
    let half = 1 << 15;
    let diagonal2 = (f64::from(1u32 << 30) / 2f64.sqrt()).round() as i32;
    let diagonal3 = (f64::from(1u32 << 30) / 3f64.sqrt()).round() as i32;
    let mut touching = 0;
    for (origin, dir) in [
        ([0, 0, half], [diagonal2, diagonal2, 0]),
        ([4 << 16, 0, half], [-diagonal2, diagonal2, 0]),
        ([0, half, 0], [diagonal2, 0, diagonal2]),
        ([0, 0, 0], [diagonal3, diagonal3, diagonal3]),
        ([4 << 16, 4 << 16, 4 << 16], [-diagonal3, -diagonal3, -diagonal3]),
    ] {
        let line = Line::from_bits(origin, dir).unwrap();
        for x in -1..6 {
            for y in -1..6 {
                for z in -1..6 {
                    let cell = [x, y, z];
                    let want = cube_meets_ray(origin, dir, cell);
                    assert_eq!(DigitalLine::resume(&line, cell).is_ok(), want, "{origin:?} {dir:?} {cell:?}");
                    touching += usize::from(want);
                }
            }
        }
    }
    assert!(touching > 40, "the cases reach few cubes ({touching})");
}

/// A cube farther than 2^14 cubes from the grid's corner is never part of a
/// walk, and is refused even where the ray passes through it.
#[test]
fn resume_refuses_cubes_no_walk_reaches() {
    let origin = [-10_000 << 16, 0, 0];
    let line = Line::from_bits(origin, [-(1 << 30), 0, 0]).unwrap();
    assert!(cube_meets_ray(origin, line.dir(), [-16_385, 0, 0]));
    assert!(DigitalLine::resume(&line, [-16_384, 0, 0]).is_ok());
    assert!(DigitalLine::resume(&line, [-16_385, 0, 0]).is_err());
    assert!(DigitalLine::resume(&line, [i32::MIN, 0, 0]).is_err());
}

/// Whether the closed unit cube `cell` meets the ray `origin + t dir`,
/// `t >= 0`, decided independently of the firmware: per axis the interval of
/// `t` (as num / den with den > 0) over which the ray is in the cube's slab,
/// intersected exactly by cross-multiplying in i128.
fn cube_meets_ray(origin: [i32; 3], dir: [i32; 3], cell: [i32; 3]) -> bool {
    const ONE: i128 = 1 << 16;
    // Bounds as (num, den) fractions of t in raw Q16.16 / Q2.30 units; None = unbounded.
    let (mut lo, mut hi): ((i128, i128), Option<(i128, i128)>) = ((0, 1), None);
    for axis in 0..3 {
        let (o, d, c) = (i128::from(origin[axis]), i128::from(dir[axis]), i128::from(cell[axis]));
        let (lower, upper) = (c * ONE, c * ONE + ONE);
        if d == 0 {
            if o < lower || o > upper {
                return false;
            }
            continue;
        }
        // t at which the coordinate reaches `lower` and `upper`, as (num, |d|).
        let (a, b) = ((lower - o) * d.signum(), (upper - o) * d.signum());
        let (enter, leave) = if d > 0 { (a, b) } else { (b, a) };
        let den = d.abs();
        if enter * lo.1 > lo.0 * den {
            lo = (enter, den);
        }
        if hi.is_none_or(|h| leave * h.1 < h.0 * den) {
            hi = Some((leave, den));
        }
    }
    hi.is_none_or(|h| lo.0 * h.1 <= h.0 * lo.1)
}

proptest::proptest! {
    /// A received ray is taken exactly when its cube lies on its line ahead
    /// of its origin: every such cube is resumed, no other is.
    #[test]
    fn resume_accepts_exactly_the_cubes_on_the_ray(
        origin in proptest::array::uniform3(-4.0f64..20.0),
        dir in proptest::array::uniform3(-1.0f64..1.0),
        zero_axis in 0usize..4,
        offset in proptest::array::uniform3(-2i32..3),
        along in 0.0f64..24.0,
    ) {
        let mut dir = dir;
        if let Some(d) = dir.get_mut(zero_axis) {
            *d = 0.0;
        }
        proptest::prop_assume!(dir.iter().map(|d| d * d).sum::<f64>() > 1e-6);
        let line = quantise::line(origin, dir);
        // A cube near the point `along` cubes down the ray, off it by `offset`.
        let cell = std::array::from_fn(|a| {
            let p = f64::from(line.origin()[a]) / 65536.0 + along * f64::from(line.dir()[a]) / f64::from(1 << 30);
            p.floor() as i32 + offset[a]
        });
        let want = cube_meets_ray(line.origin(), line.dir(), cell);
        proptest::prop_assert_eq!(DigitalLine::resume(&line, cell).is_ok(), want, "cell {:?}", cell);
    }
}
