//! Built-in scenes for the reports beside the random ones: a sphereflake
//! after the Standard Procedural Databases' "balls", mirrors everywhere, so
//! that reflection depth shows.

use std::f64::consts::PI;
use std::fmt::Write as _;

use host_tool::error::HostError;
use host_tool::scene::{Scene, fit, nff};

/// A unit vector at azimuth `az` and elevation `el` about `axis`.
fn around(axis: [f64; 3], az: f64, el: f64) -> [f64; 3] {
    // Any vector not along the axis gives the frame's first axis.
    let helper = if axis[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    };
    let unit = |a: [f64; 3]| {
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|x| x / n)
    };
    let u = unit(cross(axis, helper));
    let v = cross(axis, u);
    std::array::from_fn(|i| el.cos() * (az.cos() * u[i] + az.sin() * v[i]) + el.sin() * axis[i])
}

/// A sphereflake of `levels` generations as NFF: each sphere carries nine of
/// a third its radius, six around its equator and three above, facing away
/// from its parent; every surface reflects 45%.
pub fn sphereflake_nff(levels: u32) -> String {
    let mut text = String::from(
        "# sphereflake\nv\nfrom 2.1 1.3 1.7\nat 0 0 0\nup 0 0 1\nangle 45\nhither 0.01\nresolution 64 64\n\
         b 0.078 0.361 0.753\nl 4 3 2\nl 1 -4 4\nl -3 1 5\n",
    );
    let _ = writeln!(text, "f 0.5 0.45 0.35 0.5 0.45 100 0 1\ns 0 0 0 0.5");
    let _ = writeln!(text, "f 1 0.9 0.7 0.5 0.5 100000 0 1");
    let mut generation = vec![([0.0; 3], 0.5, [0.0, 0.0, 1.0])];
    for _ in 0..levels {
        let mut next = Vec::new();
        for (centre, radius, axis) in generation {
            let child = radius / 3.0;
            let mut dirs: Vec<[f64; 3]> =
                (0..6).map(|k| around(axis, f64::from(k) * PI / 3.0, 0.0)).collect();
            dirs.extend((0..3).map(|k| around(axis, PI / 6.0 + f64::from(k) * 2.0 * PI / 3.0, PI / 3.0)));
            for d in dirs {
                let c: [f64; 3] = std::array::from_fn(|i| centre[i] + d[i] * (radius + child));
                let _ = writeln!(text, "s {} {} {} {}", c[0], c[1], c[2], child);
                next.push((c, child, d));
            }
        }
        generation = next;
    }
    text
}

/// The sphereflake of `levels` generations, fitted into the grid `render`
/// would choose for `array`.
pub fn sphereflake(levels: u32, array: [u16; 3]) -> Result<Scene, HostError> {
    let mut scene = nff::parse(&sphereflake_nff(levels), "sphereflake", false)?.scene;
    let grid = fit::choose(&scene, fit::at_least_for(array))?;
    fit::fit(&mut scene, Some(grid))?;
    scene.validate()?;
    Ok(scene)
}
