//! The firmware's sphere hits against the exact big-integer reference and the
//! ideal (unquantised) f64 geometry.

use fixed::types::I16F16;
use node_fw::{Error, Field, Grid, Material, Point, Sphere};
use proptest::prelude::*;
use rand::{Rng, SeedableRng, rngs::SmallRng};
use tests::exact_sphere::exact_hit;
use tests::{quantise, stiff};

const ULP: f64 = 1.0 / 65536.0;

fn sphere(center: [f64; 3], radius: f64, grid: &Grid) -> Result<Sphere, Error> {
    let c = Point::from_bits(quantise::point_raw(center))?;
    let r = I16F16::from_bits(quantise::pos(radius));
    Sphere::new(0, c, r, Material::default(), grid)
}

/// Compares the firmware with the exact reference on one quantised ray; returns
/// the depth error in cubes, if both hit.
fn agree(name: &str, line: &node_fw::Line, s: &Sphere) -> Option<f64> {
    let got = s.intersect(line);
    let want = exact_hit(line.origin(), line.dir(), s.center(), s.radius().to_bits());
    match (got, want) {
        (None, None) => None,
        (Some(g), Some(w)) => {
            assert_eq!(g.inside, w.inside, "{name}: inside flag");
            let err = (g.t.to_num::<f64>() - w.t).abs();
            assert!(err <= 2.0 * ULP, "{name}: depth error {err:e} > 2 ulp (t = {})", w.t);
            Some(err)
        }
        (g, w) => panic!("{name}: firmware {g:?} but exact reference {w:?}"),
    }
}

/// Closest approach of the case's ideal line to the centre.
fn impact_of(case: &stiff::HitCase) -> f64 {
    let f: [f64; 3] = std::array::from_fn(|a| case.origin[a] - case.center[a]);
    let len = case.dir.iter().map(|d| d * d).sum::<f64>().sqrt();
    let along: f64 = (0..3).map(|a| f[a] * case.dir[a] / len).sum();
    (f.iter().map(|x| x * x).sum::<f64>() - along * along).max(0.0).sqrt()
}

#[test]
fn stiff_hit_cases() {
    let grid = Grid::new([256; 3]).unwrap();
    let mut worst_ideal: f64 = 0.0;
    for case in stiff::hit_cases() {
        let s = sphere(case.center, case.radius, &grid);
        if case.expect == stiff::Expect::RejectRadius {
            assert_eq!(s, Err(Error::OutOfRange(Field::Radius)), "{}", case.name);
            continue;
        }
        let s = s.unwrap_or_else(|e| panic!("{}: {e:?}", case.name));
        let line = quantise::line(case.origin, case.dir);
        let exact_err = agree(&case.name, &line, &s);
        let got = s.intersect(&line);
        match case.expect {
            stiff::Expect::Hit { inside } => {
                let g = got.unwrap_or_else(|| panic!("{}: expected a hit", case.name));
                assert_eq!(g.inside, inside, "{}", case.name);
                // Against the ideal geometry the error also holds the input
                // quantisation (origin and centre 2^-17 per axis, radius 2^-17,
                // direction 2^-31 per component per cube travelled), amplified
                // near grazing by the conditioning dt/dp = p / h of the depth.
                let ideal = case.ideal_t.unwrap();
                let shift =
                    (2.0 * 3f64.sqrt() + 1.0) * ULP / 2.0 + ideal.abs() * 3f64.sqrt() * 2f64.powi(-31);
                let (p, r) = (impact_of(&case), case.radius);
                let h = (r * r - p * p).max(0.0).sqrt();
                let bound = shift * (1.0 + p / h.max(1e-300)).min(1e6) + 2.0 * ULP;
                let err = (g.t.to_num::<f64>() - ideal).abs();
                worst_ideal = worst_ideal.max(err);
                assert!(err <= bound, "{}: ideal depth error {err:e} > bound {bound:e}", case.name);
                assert!(exact_err.is_some());
            }
            stiff::Expect::Miss => assert_eq!(got, None, "{}", case.name),
            stiff::Expect::Exact | stiff::Expect::RejectRadius => {}
        }
    }
    println!("worst depth error against ideal geometry on stiff cases: {worst_ideal:e} cubes");
}

#[test]
fn random_hits_match_exact_reference() {
    let grid = Grid::new([256; 3]).unwrap();
    let mut rng = SmallRng::seed_from_u64(0x5eed_0002);
    let (mut hits, mut max_err) = (0, 0.0f64);
    for i in 0..20_000 {
        let center: [f64; 3] = std::array::from_fn(|_| rng.gen_range(0.0..256.0));
        let radius = 2f64.powf(rng.gen_range(-8.0..6.0));
        let dist = 2f64.powf(rng.gen_range(-1.0..13.0)).min(9000.0);
        let dir: [f64; 3] = std::array::from_fn(|_| rng.gen_range(-1.0..1.0));
        let len = dir.iter().map(|d| d * d).sum::<f64>().sqrt();
        let u = dir.map(|d| d / len);
        // Aim near the sphere: impact parameter within 1.5 r.
        let off: [f64; 3] = std::array::from_fn(|_| rng.gen_range(-1.0..1.0) * radius);
        let origin: [f64; 3] = std::array::from_fn(|a| center[a] - dist * u[a] + off[a]);
        let s = sphere(center, radius, &grid).unwrap();
        let line = quantise::line(origin, u);
        if let Some(e) = agree(&format!("random {i}"), &line, &s) {
            hits += 1;
            max_err = max_err.max(e);
        }
    }
    assert!(hits > 5000, "too few hits to mean anything: {hits}");
    println!("{hits} hits, max depth error {:.2} ulp", max_err / ULP);
}

/// Against the ideal geometry, decisions may differ only where the ideal ray's
/// closest approach is within the quantisation bound of the silhouette.
#[test]
fn random_hits_match_ideal_geometry_outside_quantisation_bound() {
    let grid = Grid::new([256; 3]).unwrap();
    let mut rng = SmallRng::seed_from_u64(0x5eed_0003);
    let (mut ambiguous, mut checked) = (0, 0);
    for _ in 0..20_000 {
        let center: [f64; 3] = std::array::from_fn(|_| rng.gen_range(0.0..256.0));
        let radius = 2f64.powf(rng.gen_range(-8.0..6.0));
        let dist = 2f64.powf(rng.gen_range(0.0..13.0)).min(9000.0) + radius;
        let u = quantise::direction([
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        ]);
        let u = u.bits().map(|d| d as f64 / (1u64 << 30) as f64);
        let len = u.iter().map(|d| d * d).sum::<f64>().sqrt();
        let u = u.map(|d| d / len);
        let impact = radius * rng.gen_range(0.0..1.5);
        // A perpendicular of length `impact`.
        let p = [u[1], -u[0], 0.0];
        let pl = (p[0] * p[0] + p[1] * p[1]).sqrt().max(1e-12);
        let origin: [f64; 3] = std::array::from_fn(|a| center[a] - dist * u[a] + impact * p[a] / pl);
        let ideal_hit = impact <= radius;
        // Quantisation moves the line by at most the rounding of origin, centre and
        // radius (2^-17 each, per axis) plus the direction's rounding over the distance.
        let bound = 4.0 * 3f64.sqrt() * ULP / 2.0 + dist * 4.0 * 2f64.powi(-30);
        if (impact - radius).abs() <= bound {
            ambiguous += 1;
            continue;
        }
        let s = sphere(center, radius, &grid).unwrap();
        let got = s.intersect(&quantise::line(origin, u)).is_some();
        assert_eq!(got, ideal_hit, "impact {impact} radius {radius} dist {dist}");
        checked += 1;
    }
    assert!(checked > 19_000, "checked {checked}, ambiguous {ambiguous}");
}

#[test]
fn out_of_range_inputs_are_rejected() {
    let grid = Grid::new([16; 3]).unwrap();
    assert_eq!(sphere([8.0; 3], 0.0, &grid), Err(Error::OutOfRange(Field::Radius)));
    assert_eq!(sphere([8.0; 3], -1.0, &grid), Err(Error::OutOfRange(Field::Radius)));
    assert_eq!(sphere([8.0; 3], 64.5, &grid), Err(Error::OutOfRange(Field::Radius)));
    assert_eq!(sphere([16.5, 8.0, 8.0], 1.0, &grid), Err(Error::OutOfRange(Field::Center)));
    assert_eq!(sphere([-0.01, 8.0, 8.0], 1.0, &grid), Err(Error::OutOfRange(Field::Center)));
    assert!(sphere([16.0, 0.0, 8.0], 1.0 / 256.0, &grid).is_ok(), "closed grid box, smallest radius");
    assert!(Grid::new([0, 4, 4]).is_err());
    assert!(Grid::new([257, 4, 4]).is_err());
    assert!(node_fw::Direction::from_bits([0; 3]).is_err(), "zero direction");
    assert!(node_fw::Direction::from_bits([1 << 29, 0, 0]).is_err(), "not unit length");
    assert!(node_fw::Direction::normalize([0; 3]).is_err());
    assert!(Point::from_bits([i32::MAX, 0, 0]).is_err(), "beyond 10^4 cubes outside");
    assert!(Point::from_bits([quantise::pos(-10_000.0), 0, quantise::pos(10_256.0)]).is_ok());
    assert!(Point::from_bits([quantise::pos(-10_000.01), 0, 0]).is_err());
}

fn arb_coord() -> impl Strategy<Value = i32> {
    let lo = quantise::pos(-10_000.0);
    let hi = quantise::pos(10_256.0);
    prop_oneof![Just(lo), Just(hi), lo..=hi, 0..=quantise::pos(256.0)]
}

fn arb_dir() -> impl Strategy<Value = [i64; 3]> {
    prop_oneof![
        Just([1, 0, 0]),
        Just([0, 0, -1]),
        Just([1, 1, 1]),
        Just([-1 << 40, 1, 0]),
        proptest::array::uniform3(-(1i64 << 40)..(1i64 << 40)),
        proptest::array::uniform3(-3i64..=3),
    ]
    .prop_filter("nonzero", |d| d.iter().any(|&c| c != 0))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// Anywhere in the documented ranges: no overflow (tests run with overflow
    /// checks), and the decision equals the exact reference.
    #[test]
    fn extremes_never_overflow(
        origin in proptest::array::uniform3(arb_coord()),
        dir in arb_dir(),
        center in proptest::array::uniform3(0..=quantise::pos(256.0)),
        radius in prop_oneof![Just(256), Just(64 << 16), 256..=(64 << 16)],
    ) {
        let grid = Grid::new([256; 3]).unwrap();
        let dir = node_fw::Direction::normalize(dir).unwrap();
        let line = node_fw::Line::new(Point::from_bits(origin).unwrap(), dir);
        let s = Sphere::new(1, Point::from_bits(center).unwrap(), I16F16::from_bits(radius), Material::default(), &grid).unwrap();
        agree("extreme", &line, &s);
        // The digital line from the same origin is fine too.
        if let Some(mut walk) = node_fw::DigitalLine::enter(&line, &grid) {
            let mut n = 0;
            while grid.contains(walk.cell()) {
                walk.exits_at_or_after(&line, I16F16::MAX);
                walk.step();
                n += 1;
                prop_assert!(n <= 3 * 256 + 3);
            }
        }
    }
}

#[test]
fn every_stiff_case_passes_and_the_readme_shows_the_current_table() {
    let (table, all_pass) = lab::numerics::stiff_table::markdown();
    assert!(all_pass, "a stiff case failed:\n{table}");
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/arithmetic.md")).unwrap();
    let start =
        readme.find("<!-- stiff-table:start -->\n").expect("docs/arithmetic.md has the stiff table") + 27;
    let end = readme.find("<!-- stiff-table:end -->").unwrap();
    assert_eq!(
        &readme[start..end],
        table,
        "docs/arithmetic.md table is stale: run `lab report stiff` and paste it"
    );
}
