//! Subregion storage and the nearest hit across cubes and across subregions,
//! against a brute-force search with the exact reference.

use fixed::types::I16F16;
use node_fw::{
    CubeBox, DigitalLine, Error, Grid, Line, Material, Outcome, Point, Query, Sphere, Subregion, TraceStats,
};
use rand::{Rng, SeedableRng, rngs::SmallRng};
use tests::exact_sphere::exact_hit;
use tests::quantise;

type Region = Subregion<512, 16384, 4096>;

fn region(grid: Grid, lo: [u16; 3], hi: [u16; 3]) -> Box<Region> {
    let mut r = Box::new(Region::new());
    r.assign(grid, CubeBox { lo, hi }).unwrap();
    r
}

fn sphere(id: u16, c: [f64; 3], r: f64, grid: &Grid) -> Sphere {
    let c = Point::from_bits(quantise::point_raw(c)).unwrap();
    Sphere::new(id, c, I16F16::from_bits(quantise::pos(r)), Material::default(), grid).unwrap()
}

/// Registered cubes of one sphere in a whole-grid subregion.
fn cubes_of(s: Sphere, grid: Grid) -> usize {
    let mut r = region(grid, [0; 3], grid.size());
    r.insert(s).unwrap();
    r.ref_count()
}

#[test]
fn registration_corner_and_tangent_cases() {
    let grid = Grid::new([8; 3]).unwrap();
    // Centre on a lattice corner, r = 0.5: the eight cubes around the corner.
    assert_eq!(cubes_of(sphere(0, [4.0; 3], 0.5, &grid), grid), 8);
    // Tangent to the six faces of its cube: the cube and its six face neighbours.
    assert_eq!(cubes_of(sphere(0, [2.5; 3], 0.5, &grid), grid), 7);
    // Small sphere inside one cube.
    assert_eq!(cubes_of(sphere(0, [2.5; 3], 0.25, &grid), grid), 1);
    // A big sphere registers its shell, not its solid interior.
    let big = cubes_of(sphere(0, [4.0; 3], 3.5, &grid), grid);
    assert!(big < 8 * 8 * 8 && big > 6 * 6 * 6 - 4 * 4 * 4, "shell cubes: {big}");
    // Sphere larger than the grid: only the cubes its surface meets.
    assert_eq!(cubes_of(sphere(0, [4.0; 3], 64.0, &grid), grid), 0);
}

fn trace<const S: usize, const R: usize, const C: usize>(
    r: &mut Subregion<S, R, C>,
    line: &Line,
    grid: &Grid,
    query: &Query,
) -> (Outcome, TraceStats) {
    let mut walk = DigitalLine::enter(line, grid).unwrap();
    let mut best = None;
    let mut stats = TraceStats::default();
    (r.trace(line, &mut walk, &mut best, query, &mut stats), stats)
}

#[test]
fn tangent_face_rays_hit() {
    // A ray lying in the face plane x = 3, tangent to the sphere there.
    let grid = Grid::new([8; 3]).unwrap();
    let mut r = region(grid, [0; 3], [8; 3]);
    r.insert(sphere(5, [2.5; 3], 0.5, &grid)).unwrap();
    for x in [2.0, 3.0] {
        let line = quantise::line([x, -1.0, 2.5], [0.0, 1.0, 0.0]);
        let (out, _) = trace(&mut r, &line, &grid, &Query::default());
        match out {
            Outcome::Hit(h) => {
                assert_eq!(h.sphere, 5);
                assert!((h.t.to_num::<f64>() - 3.5).abs() < 1e-4);
            }
            other => panic!("x = {x}: {other:?}"),
        }
    }
}

#[test]
fn mailbox_tests_each_sphere_once_per_walk() {
    let grid = Grid::new([8; 3]).unwrap();
    let mut r = region(grid, [0; 3], [8; 3]);
    r.insert(sphere(0, [4.0; 3], 0.5, &grid)).unwrap();
    // Along the diagonal through the corner the sphere sits on: 4+ of its cubes.
    let line = quantise::line([0.1, 0.2, 0.3], [1.0, 1.0, 1.0]);
    let (out, stats) = trace(&mut r, &line, &grid, &Query::default());
    assert!(matches!(out, Outcome::Hit(h) if h.sphere == 0));
    assert_eq!((stats.sphere_tests, stats.sphere_hits), (1, 1));
    // A miss (0.636 from the centre) that walks through two of its cubes,
    // (3,3,3) and (4,3,3), and then through none.
    let line = quantise::line([0.0, 3.55, 3.55], [1.0, 0.0, 0.0]);
    let (out, stats) = trace(&mut r, &line, &grid, &Query::default());
    assert_eq!(out, Outcome::LeftGrid);
    assert_eq!((stats.sphere_tests, stats.sphere_hits), (1, 0));
    // A diagonal miss (0.6 from the centre) through three of its cubes.
    let line = quantise::line([3.0, 3.0, 4.6], [1.0, 1.0, 0.0]);
    let (out, stats) = trace(&mut r, &line, &grid, &Query::default());
    assert_eq!(out, Outcome::LeftGrid);
    assert_eq!((stats.sphere_tests, stats.sphere_hits), (1, 0));
    // Away from the sphere, the line through its centre meets it behind the
    // origin: a test, no hit (the depth is not computed).
    let line = quantise::line([5.5, 5.5, 5.5], [1.0, 1.0, 1.0]);
    let mut behind = region(grid, [0; 3], [8; 3]);
    behind.insert(sphere(0, [4.0; 3], 2.5, &grid)).unwrap();
    let (out, stats) = trace(&mut behind, &line, &grid, &Query::default());
    assert_eq!(out, Outcome::LeftGrid);
    assert_eq!((stats.sphere_tests, stats.sphere_hits), (1, 0));
}

#[test]
fn equal_depths_resolve_to_the_lowest_id() {
    let grid = Grid::new([8; 3]).unwrap();
    for order in [[7u16, 3, 9], [9, 7, 3], [3, 9, 7]] {
        let mut r = region(grid, [0; 3], [8; 3]);
        for id in order {
            r.insert(sphere(id, [4.5; 3], 1.0, &grid)).unwrap();
        }
        let line = quantise::line([0.5, 4.5, 4.5], [1.0, 0.0, 0.0]);
        let (out, _) = trace(&mut r, &line, &grid, &Query::default());
        assert!(matches!(out, Outcome::Hit(h) if h.sphere == 3), "{order:?}: {out:?}");
    }
}

#[test]
fn capacity_overflow_hands_the_sphere_back() {
    let grid = Grid::new([8; 3]).unwrap();
    let mut r: Box<Subregion<2, 64, 512>> = Box::new(Subregion::new());
    r.assign(grid, CubeBox { lo: [0; 3], hi: [8; 3] }).unwrap();
    assert_eq!(r.insert(sphere(1, [1.5; 3], 0.2, &grid)), Ok(true));
    assert_eq!(r.insert(sphere(2, [2.5; 3], 0.2, &grid)), Ok(true));
    let third = sphere(3, [3.5; 3], 0.2, &grid);
    let rejected = r.insert(third).unwrap_err();
    assert_eq!(rejected.sphere, third);
    assert_eq!(rejected.error, Error::SphereCapacity { capacity: 2 });
    // References: a radius-2 sphere meets far more than 64 cubes.
    let mut r: Box<Subregion<8, 64, 512>> = Box::new(Subregion::new());
    r.assign(grid, CubeBox { lo: [0; 3], hi: [8; 3] }).unwrap();
    let big = sphere(4, [4.0; 3], 2.0, &grid);
    let rejected = r.insert(big).unwrap_err();
    assert!(matches!(rejected.error, Error::RefCapacity { capacity: 64, needed } if needed > 64));
    assert_eq!(r.spheres().len(), 0, "nothing half-stored");
    // Cubes: a box larger than the node holds.
    let err = r.assign(grid, CubeBox { lo: [0; 3], hi: [8, 8, 9] }).unwrap_err();
    assert_eq!(err, Error::OutOfRange(node_fw::Field::Subregion));
    let err = Subregion::<8, 64, 100>::new().assign(grid, CubeBox { lo: [0; 3], hi: [8; 3] }).unwrap_err();
    assert_eq!(err, Error::CubeCapacity { capacity: 100, needed: 512 });
    // A sphere that does not touch the box is not ours, and not an error.
    let mut r = region(grid, [0; 3], [4, 8, 8]);
    assert_eq!(r.insert(sphere(5, [6.5; 3], 0.5, &grid)), Ok(false));
}

#[test]
fn ten_thousand_spheres_in_one_cube() {
    let grid = Grid::new([2; 3]).unwrap();
    let mut r: Box<Subregion<10_000, 10_000, 8>> = Box::new(Subregion::new());
    r.assign(grid, CubeBox { lo: [0; 3], hi: [1; 3] }).unwrap();
    let mut rng = SmallRng::seed_from_u64(3);
    let mut spheres = Vec::new();
    for id in 0..10_000u16 {
        // Pairs share a centre and radius: equal depths.
        let k = id / 2;
        let mut local = SmallRng::seed_from_u64(k as u64);
        let c = [local.gen_range(0.3..0.7), local.gen_range(0.3..0.7), local.gen_range(0.3..0.7)];
        let s = sphere(id, c, 0.01 + local.gen_range(0.0..0.2), &grid);
        spheres.push(s);
    }
    // Insert in a shuffled order: the answer must not depend on it.
    for i in (1..spheres.len()).rev() {
        spheres.swap(i, rng.gen_range(0..=i));
    }
    for s in &spheres {
        assert_eq!(r.insert(*s), Ok(true));
    }
    let line = quantise::line([-1.0, 0.5, 0.5], [1.0, 0.01, 0.02]);
    let (out, stats) = trace(&mut r, &line, &grid, &Query::default());
    assert_eq!(stats.sphere_tests, 10_000);
    let want = brute_force(&spheres, &line);
    let Outcome::Hit(h) = out else { panic!("{out:?}") };
    assert_eq!(h.sphere, want.unwrap().1);
    assert_eq!(h.sphere % 2, 0, "the lower id of an equal pair");
}

/// Exact-reference nearest hit over all spheres: (t, id), ties to the lowest id.
fn brute_force(spheres: &[Sphere], line: &Line) -> Option<(f64, u16)> {
    spheres
        .iter()
        .filter_map(|s| {
            exact_hit(line.origin(), line.dir(), s.center(), s.radius().to_bits()).map(|h| (h.t, s.id()))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
}

/// Second-nearest depth, to tell ambiguous near-ties.
fn runner_up(spheres: &[Sphere], line: &Line, best: u16) -> Option<f64> {
    spheres
        .iter()
        .filter(|s| s.id() != best)
        .filter_map(|s| exact_hit(line.origin(), line.dir(), s.center(), s.radius().to_bits()).map(|h| h.t))
        .min_by(f64::total_cmp)
}

/// Walks a ray through a set of subregions, passing it on at each `Leave`,
/// carrying the best hit: what the array of nodes does.
fn trace_partitioned(regions: &mut [Box<Region>], line: &Line, grid: &Grid, query: &Query) -> (Outcome, u32) {
    let Some(mut walk) = DigitalLine::enter(line, grid) else {
        return (Outcome::LeftGrid, 0);
    };
    let mut best = None;
    let mut stats = TraceStats::default();
    let mut hops = 0;
    loop {
        let owner =
            regions.iter_mut().find(|r| r.contains(walk.cell())).expect("a subregion owns every cube");
        // Resume from (origin, dir, cell) as a receiving node would.
        let mut resumed = DigitalLine::resume(line, walk.cell()).unwrap();
        match owner.trace(line, &mut resumed, &mut best, query, &mut stats) {
            Outcome::Leave => {
                walk = resumed;
                hops += 1;
            }
            done => return (done, hops),
        }
    }
}

#[test]
fn nearest_hit_matches_brute_force_on_one_and_many_subregions() {
    let grid = Grid::new([16; 3]).unwrap();
    let mut rng = SmallRng::seed_from_u64(0x5eed_0004);
    let (mut hits, mut ambiguous, mut hops) = (0, 0, 0);
    for scene in 0..20 {
        let spheres: Vec<Sphere> = (0..60u16)
            .map(|id| {
                let r = 2f64.powf(rng.gen_range(-7.0..1.5));
                let c = [(); 3].map(|_| rng.gen_range(r..16.0 - r));
                sphere(id, c, r, &grid)
            })
            .collect();
        let mut whole = region(grid, [0; 3], [16; 3]);
        // 3 x 2 x 2 boxes with uneven cuts.
        let (xs, ys, zs) = ([0u16, 5, 11, 16], [0u16, 7, 16], [0u16, 3, 16]);
        let mut parts = Vec::new();
        for z in 0..2 {
            for y in 0..2 {
                for x in 0..3 {
                    parts.push(region(grid, [xs[x], ys[y], zs[z]], [xs[x + 1], ys[y + 1], zs[z + 1]]));
                }
            }
        }
        for s in &spheres {
            assert_eq!(whole.insert(*s), Ok(true));
            let kept = parts.iter_mut().map(|p| p.insert(*s).unwrap()).filter(|&k| k).count();
            assert!(kept >= 1, "scene {scene}: sphere {} kept by no subregion", s.id());
        }
        for _ in 0..300 {
            let origin = [(); 3].map(|_| rng.gen_range(-20.0..36.0));
            let target = [(); 3].map(|_| rng.gen_range(0.0..16.0));
            let dir: [f64; 3] = std::array::from_fn(|a| target[a] - origin[a]);
            let line = quantise::line(origin, dir);
            let Some(mut walk) = DigitalLine::enter(&line, &grid) else {
                continue;
            };
            let (mut best, mut stats) = (None, TraceStats::default());
            let one = whole.trace(&line, &mut walk, &mut best, &Query::default(), &mut stats);
            let (many, h) = trace_partitioned(&mut parts, &line, &grid, &Query::default());
            hops += h;
            assert_eq!(one, many, "partition changed the answer");
            let want = brute_force(&spheres, &line);
            match (one, want) {
                (Outcome::LeftGrid, None) => {}
                (Outcome::Hit(got), Some((t, id))) => {
                    hits += 1;
                    if got.sphere != id {
                        // Only a near-tie may resolve otherwise.
                        let second = runner_up(&spheres, &line, id).unwrap();
                        assert!(
                            (second - t).abs() <= 2.0 / 65536.0,
                            "wrong sphere: got {got:?}, want {id} at {t}"
                        );
                        ambiguous += 1;
                    }
                    assert!((got.t.to_num::<f64>() - t).abs() <= 3.0 / 65536.0 || got.sphere != id);
                }
                (o, w) => panic!("got {o:?}, want {w:?}"),
            }
        }
    }
    assert!(hits > 1500, "hits {hits}");
    assert!(hops > 1000, "rays crossed subregions {hops} times");
    println!("{hits} hits, {ambiguous} near-ties, {hops} subregion crossings");
}

#[test]
fn secondary_rays_ignore_their_own_sphere() {
    let grid = Grid::new([8; 3]).unwrap();
    let mut r = region(grid, [0; 3], [8; 3]);
    let s = sphere(2, [4.0; 3], 1.5, &grid);
    r.insert(s).unwrap();
    r.insert(sphere(3, [4.0, 4.0, 7.0], 0.5, &grid)).unwrap();
    // Leave the top of sphere 2 (rounded surface point) straight up: without
    // `ignore`, the rounded origin may lie inside and hit sphere 2 again.
    let origin = [4.0, 4.0, 5.5 - 1.0 / 65536.0];
    let line = quantise::line(origin, [0.0, 0.0, 1.0]);
    let (out, _) = trace(&mut r, &line, &grid, &Query { ignore: Some(2), ..Query::default() });
    assert!(matches!(out, Outcome::Hit(h) if h.sphere == 3), "{out:?}");
    let (out, _) = trace(&mut r, &line, &grid, &Query::default());
    assert!(matches!(out, Outcome::Hit(h) if h.sphere == 2), "self-hit shows without ignore: {out:?}");
    // Shadow ray toward a light below sphere 3: clear; beyond it: blocked.
    let q = |t: f64| Query { ignore: Some(2), t_max: Some(I16F16::from_num(t)), any_hit: true };
    assert_eq!(trace(&mut r, &line, &grid, &q(0.5)).0, Outcome::Clear);
    assert_eq!(trace(&mut r, &line, &grid, &q(2.0)).0, Outcome::Blocked);
}

#[test]
fn a_sphere_sticking_out_of_the_grid_is_not_within_it() {
    let grid = Grid::new([8; 3]).unwrap();
    assert!(sphere(0, [4.0; 3], 4.0, &grid).within(&grid), "touching the faces from inside");
    assert!(!sphere(0, [7.5, 4.0, 4.0], 1.0, &grid).within(&grid));
    assert!(!sphere(0, [0.2, 4.0, 4.0], 0.25, &grid).within(&grid));
}

/// A shadow ray toward a light a cube or more outside the grid's box goes
/// without the light's distance (`Scene::shadow_ray`): it must end as it
/// would with it, blocked or not, for every light on that edge (one cube
/// out, on every face and past corners) and beyond, from points on spheres
/// that touch the grid's faces.
#[test]
fn a_light_a_cube_outside_the_grid_needs_no_distance() {
    let grid = Grid::new([8; 3]).unwrap();
    let mut rng = SmallRng::seed_from_u64(26);
    let mut r = region(grid, [0; 3], [8; 3]);
    let mut spheres = Vec::new();
    for id in 0..60 {
        let rad = rng.gen_range(0.2..1.5);
        let c = [0; 3].map(|_: i32| rng.gen_range(rad..8.0 - rad));
        let s = sphere(id, c, rad, &grid);
        if r.insert(s).is_ok() {
            spheres.push((id, c, rad));
        }
    }
    let lights = [
        [-1.0, 4.0, 4.0],
        [9.0, 4.0, 4.0],
        [4.0, -1.0, 4.0],
        [4.0, 9.0, 4.0],
        [4.0, 4.0, -1.0],
        [4.0, 4.0, 9.0],
        [-1.0, -1.0, -1.0],
        [9.0, 9.0, 9.0],
        [-1.0, 8.5, 3.0],
        [9.6, 12.0, -4.0],
        [-2.4, 8.0, 8.0],
    ];
    let (mut blocked, mut clear) = (0, 0);
    for &(id, c, rad) in &spheres {
        for light in lights {
            // A point on the sphere facing the light.
            let toward = [0, 1, 2].map(|a| light[a] - c[a]);
            let len = toward.iter().map(|x| x * x).sum::<f64>().sqrt();
            let o = [0, 1, 2].map(|a| c[a] + toward[a] / len * rad);
            let d = [0, 1, 2].map(|a| light[a] - o[a]);
            let dist = d.iter().map(|x| x * x).sum::<f64>().sqrt();
            let line = quantise::line(o, d);
            let Some(_) = DigitalLine::enter(&line, &grid) else { continue };
            let with = Query {
                ignore: Some(id),
                t_max: Some(I16F16::from_bits((dist * 65536.0).floor() as i32)),
                any_hit: true,
            };
            let without = Query { t_max: None, ..with };
            let (a, _) = trace(&mut r, &line, &grid, &with);
            let (b, _) = trace(&mut r, &line, &grid, &without);
            match (a, b) {
                (Outcome::Blocked, Outcome::Blocked) => blocked += 1,
                (Outcome::LeftGrid | Outcome::Clear, Outcome::LeftGrid) => clear += 1,
                other => panic!("sphere {id}, light {light:?}: {other:?}"),
            }
        }
    }
    assert!(blocked > 50 && clear > 50, "both endings tried: {blocked} blocked, {clear} clear");
}
