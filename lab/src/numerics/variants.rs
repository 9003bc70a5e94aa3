//! The arithmetic variants of the tradeoff report ([`crate::tradeoff`]):
//! the same exact kernels fed coarser inputs, and a float render in the
//! fixed-point renderer's form; and the Pareto front of a set of points.
//!
//! - `fixed-pos-q.12`: positions, radii, eye and lights rounded to 2^-12
//!   (positions stored with 12 fraction bits).
//! - `fixed-camera-q2.16`: the camera's direction basis rounded to 2^-16
//!   (primary directions from 16-bit steps; `direct::render_costed`).
//!
//! The kernels' own arithmetic is exact, so input rounding is where
//! precision goes.

use host_tool::plan::direct::{DirectImage, PrimaryHit};
use host_tool::reference::RefImage;
use host_tool::scene::Scene;

fn round_to(x: f64, frac: i32) -> f64 {
    let q = 2f64.powi(frac);
    (x * q).round() / q
}

/// The scene with every position and radius rounded to `frac` fraction bits.
pub fn positions_rounded(scene: &Scene, frac: i32) -> Scene {
    let mut s = scene.clone();
    let r3 = |p: [f64; 3]| p.map(|x| round_to(x, frac));
    let mut cam = s.camera();
    cam.eye = r3(cam.eye);
    s.camera = Some(cam);
    for l in &mut s.lights {
        l.position = r3(l.position);
    }
    for sp in &mut s.spheres {
        sp.center = r3(sp.center);
        sp.radius = round_to(sp.radius, frac).max(2f64.powi(-frac));
    }
    s
}

/// A float render in the direct renderer's form (Q1.15 sums, primary hits).
pub fn float_as_direct(img: &RefImage) -> DirectImage {
    DirectImage {
        sums: img.color.iter().map(|c| c.to_array().map(|v| (v * 32768.0).max(0.0).round() as u64)).collect(),
        hits: img.hits.iter().map(|h| h.map(|h| PrimaryHit { sphere: h.sphere, t: h.t })).collect(),
        rays: img.rays,
    }
}

/// Points not dominated in (run time, error): the Pareto front, by run time.
pub fn pareto(points: &[(f64, f64)]) -> Vec<usize> {
    let mut front: Vec<usize> = (0..points.len())
        .filter(|&i| {
            !points.iter().enumerate().any(|(j, q)| {
                j != i && q.0 <= points[i].0 && q.1 <= points[i].1 && (q.0 < points[i].0 || q.1 < points[i].1)
            })
        })
        .collect();
    front.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0));
    front
}
