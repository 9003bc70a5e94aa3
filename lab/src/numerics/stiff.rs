//! The stiff and extreme cases of `shared/notes/numerics.md`, as named data.

/// A unit vector and one perpendicular to it, both exact in f64 arithmetic.
pub const U: [f64; 3] = [0.6, 0.48, 0.64];
/// Perpendicular to [`U`], unit length.
pub const W: [f64; 3] = [0.8, -0.36, -0.48];

/// A traversal case: the walk must equal the rational reference and pass the
/// geometric checks.
#[derive(Debug, Clone)]
pub struct WalkCase {
    /// Name, as in the numerics table.
    pub name: &'static str,
    /// Grid size.
    pub grid: [u16; 3],
    /// Origin in cubes.
    pub origin: [f64; 3],
    /// Direction (any length).
    pub dir: [f64; 3],
}

/// What a sphere case must do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Expect {
    /// Hit, as the ideal (unquantised) geometry says; `inside` as given.
    Hit {
        /// Origin inside the sphere.
        inside: bool,
    },
    /// Miss, as the ideal geometry says.
    Miss,
    /// Closer to the silhouette than quantisation resolves: must match the exact
    /// decision on the quantised ray, whatever it is.
    Exact,
    /// The sphere is out of the documented range and must be rejected.
    RejectRadius,
}

/// A ray/sphere case.
#[derive(Debug, Clone)]
pub struct HitCase {
    /// Name, as in the numerics table.
    pub name: String,
    /// Origin in cubes.
    pub origin: [f64; 3],
    /// Direction (any length).
    pub dir: [f64; 3],
    /// Sphere centre in cubes.
    pub center: [f64; 3],
    /// Sphere radius in cubes.
    pub radius: f64,
    /// Expected behaviour.
    pub expect: Expect,
    /// Ideal depth of the hit, where there is one.
    pub ideal_t: Option<f64>,
}

fn add(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}

/// Walk cases: boundary origins, axis and near-axis directions, lattice-corner
/// diagonals, the longest walks, far eyes, range tops and tiny grids.
pub fn walk_cases() -> Vec<WalkCase> {
    let g8 = [8; 3];
    let g256 = [256; 3];
    let c = |name, grid, origin, dir| WalkCase { name, grid, origin, dir };
    let far = add([128.0; 3], [1.0, 0.618, 0.382], -10_000.0 / 1.236_067_977_5);
    vec![
        c("origin on plane, d_x > 0", g8, [3.0, 2.5, 2.5], [1.0, 0.3, 0.2]),
        c("origin on plane, d_x < 0", g8, [3.0, 2.5, 2.5], [-1.0, 0.3, 0.2]),
        c("origin on plane, d_x = 0", g8, [3.0, 2.5, 2.5], [0.0, 1.0, 0.3]),
        c("origin on edge, into both", g8, [3.0, 3.0, 2.5], [1.0, 1.0, 0.1]),
        c("origin on edge, mixed signs", g8, [3.0, 3.0, 2.5], [-1.0, 1.0, 0.2]),
        c("origin on edge, along it", g8, [3.0, 3.0, 2.5], [0.0, 0.0, 1.0]),
        c("origin on edge, against it", g8, [3.0, 3.0, 2.5], [0.0, 0.0, -1.0]),
        c("origin on corner, (1,1,1)", g8, [3.0, 3.0, 3.0], [1.0, 1.0, 1.0]),
        c("origin on corner, (-1,-1,-1)", g8, [3.0, 3.0, 3.0], [-1.0, -1.0, -1.0]),
        c("origin on corner, (1,-1,0)", g8, [3.0, 3.0, 3.0], [1.0, -1.0, 0.0]),
        c("origin on corner, (0,0,-1)", g8, [3.0, 3.0, 3.0], [0.0, 0.0, -1.0]),
        c("direction (1,0,0)", g256, [0.5, 0.5, 0.5], [1.0, 0.0, 0.0]),
        c("direction (1,1e-6,0)", g256, [0.5, 0.5, 0.5], [1.0, 1e-6, 0.0]),
        c("direction (1,2^-16,0)", g256, [0.5, 0.5, 0.5], [1.0, 1.0 / 65536.0, 0.0]),
        c("direction (1,2^-16,0) from a boundary", g256, [0.0, 3.0, 0.0], [1.0, 1.0 / 65536.0, 0.0]),
        c("(1,1,1) through lattice corners", g256, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
        c("(1,1,1) from outside through corners", g256, [-10.0, -10.0, -10.0], [1.0, 1.0, 1.0]),
        c("(-1,1,-1) through corners", g256, [200.0, 3.0, 100.0], [-1.0, 1.0, -1.0]),
        c("longest walk along (1,0.618,0.382)", g256, [0.5, 0.5, 0.5], [1.0, 0.618, 0.382]),
        c("eye 10^4 outside along (1,0.618,0.382)", g256, far, [1.0, 0.618, 0.382]),
        c("eye 10^4 outside on every axis", g256, [-10_000.0; 3], [1.0, 1.0, 1.0]),
        c("eye 10^4 outside, near-axis", g256, [10_256.0, 128.5, 128.25], [-1.0, 1e-5, -2e-6]),
        c("coordinates at the top of the range", g256, [10_256.0; 3], [-1.0, -0.999, -0.998]),
        c("top of the range, exact diagonal", g256, [10_256.0; 3], [-1.0, -1.0, -1.0]),
        c("coordinates at the bottom of the range", g256, [-10_000.0, 100.0, 100.0], [1.0, 0.0, 0.0]),
        c("grid of one cube, inside", [1; 3], [0.5, 0.5, 0.5], [1.0, 2.0, 3.0]),
        c("grid of one cube, from outside", [1; 3], [-3.0, 0.5, 0.5], [1.0, 0.0, 0.0]),
        c("ray in the grid's lower face plane", g8, [0.0, 4.5, -3.0], [0.0, 0.0, 1.0]),
        c("ray in the grid's upper face plane", g8, [8.0, 4.5, -3.0], [0.0, 0.1, 1.0]),
        c("ray touching only a grid edge", g8, [-1.0, 1.0, 4.5], [1.0, -1.0, 0.0]),
        c("ray missing the grid", g8, [-1.0, -1.0, -1.0], [-1.0, 0.5, 0.5]),
        c("ray leaving from the grid face", g8, [0.0, 4.5, 4.5], [-1.0, 0.2, 0.1]),
        c("flat grid 256x1x1", [256, 1, 1], [-5.0, 0.5, 0.5], [1.0, 0.001, -0.001]),
    ]
}

/// Sphere cases: tiny and huge radii at near and far distances, grazing rays,
/// origins inside and on the surface, and out-of-range inputs.
pub fn hit_cases() -> Vec<HitCase> {
    let center = [128.3, 128.7, 128.1];
    let mut cases = Vec::new();
    let mut push = |name: String, dist: f64, impact: f64, radius: f64, expect: Expect| {
        let origin = add(add(center, U, -dist), W, impact);
        let ideal_t = matches!(expect, Expect::Hit { .. }).then(|| {
            let h = (radius * radius - impact * impact).sqrt();
            if dist.abs() < radius && impact.abs() < radius { dist + h } else { dist - h }
        });
        cases.push(HitCase { name, origin, dir: U, center, radius, expect, ideal_t });
    };
    for r in [1e-3, 100.0, 200.0, 0.0] {
        push(format!("r = {r} rejected"), 20.0, 0.0, r, Expect::RejectRadius);
    }
    let tiny = 1.0 / 256.0;
    for dist in [20.0, 150.0, 1000.0] {
        push(format!("r = 1/256 at {dist}, centre"), dist, 0.0, tiny, Expect::Hit { inside: false });
        push(
            format!("r = 1/256 at {dist}, impact r/2"),
            dist,
            tiny / 2.0,
            tiny,
            Expect::Hit { inside: false },
        );
        push(format!("r = 1/256 at {dist}, impact 2r"), dist, 2.0 * tiny, tiny, Expect::Miss);
    }
    for dist in [150.0, 1000.0] {
        push(format!("r = 64, eye {dist} away, centre"), dist, 0.0, 64.0, Expect::Hit { inside: false });
        push(
            format!("r = 64, eye {dist} away, impact 0.999r"),
            dist,
            63.936,
            64.0,
            Expect::Hit { inside: false },
        );
        push(format!("r = 64, eye {dist} away, impact 1.001r"), dist, 64.064, 64.0, Expect::Miss);
    }
    for r in [1.0, 64.0] {
        for dist in [20.0, 150.0] {
            let d = dist + r;
            push(
                format!("grazing r = {r} at {d}, impact r(1 - 1e-3)"),
                d,
                r * (1.0 - 1e-3),
                r,
                Expect::Hit { inside: false },
            );
            push(format!("grazing r = {r} at {d}, impact r(1 + 1e-3)"), d, r * (1.0 + 1e-3), r, Expect::Miss);
            push(
                format!("grazing r = {r} at {d}, impact r(1 - 1e-6)"),
                d,
                r * (1.0 - 1e-6),
                r,
                Expect::Exact,
            );
            push(
                format!("grazing r = {r} at {d}, impact r(1 + 1e-6)"),
                d,
                r * (1.0 + 1e-6),
                r,
                Expect::Exact,
            );
        }
    }
    push("origin inside, at the centre".into(), 0.0, 0.0, 2.0, Expect::Hit { inside: true });
    push("origin inside, off centre".into(), 0.5, 0.7, 2.0, Expect::Hit { inside: true });
    push("origin inside a radius-64 sphere".into(), 30.0, 20.0, 64.0, Expect::Hit { inside: true });
    push("sphere behind the origin".into(), -10.0, 0.0, 2.0, Expect::Miss);
    push("origin just outside, heading in".into(), 2.001, 0.0, 2.0, Expect::Hit { inside: false });
    cases
}
