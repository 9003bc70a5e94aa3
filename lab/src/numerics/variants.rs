//! `lab report numerics`: what precision costs, against the f64 reference.
//!
//! Variants (all render the same scenes, all measured against the f64 renderer
//! on the unrounded scene):
//! - `fixed-q16.16-q2.30`: the shipped pipeline (the node kernels in one loop).
//! - `fixed-pos-q.12`: the same kernels fed positions, radii, eye and lights
//!   rounded to 2^-12 (positions stored with 12 fraction bits).
//! - `fixed-camera-q2.16`: the same kernels with the camera's direction basis
//!   rounded to 2^-16 (primary directions from 16-bit steps).
//! - `f32`: the reference algorithm in single precision (the float baseline).
//! - `f64`: the reference itself (zero error; its run time for scale).
//!
//! Both fixed-point variants change only what the kernels are fed: the
//! kernels' own arithmetic is exact, so input rounding is where precision goes.
//! The float paths test every sphere for every ray (no grid), so their time per
//! ray compares whole algorithms, not only number formats.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use host_tool::compare::{Comparison, compare};
use host_tool::error::HostError;
use host_tool::plan::direct::{DirectImage, PrimaryHit};
use host_tool::reference::{self, RefImage};
use host_tool::results::output::write_atomic;
use host_tool::results::plot::{Chart, Series, png};
use host_tool::scene::Scene;
use host_tool::session::frame::to_srgb8;

/// One variant's measurements on one scene.
#[derive(Debug, Clone)]
pub struct Measured {
    /// Variant name.
    pub variant: &'static str,
    /// Scene name.
    pub scene: String,
    /// Host time per ray, ns.
    pub ns_per_ray: f64,
    /// Error against the f64 reference.
    pub error: Comparison,
}

fn round_to(x: f64, frac: i32) -> f64 {
    let q = 2f64.powi(frac);
    (x * q).round() / q
}

/// The scene with every position and radius rounded to `frac` fraction bits.
fn positions_rounded(scene: &Scene, frac: i32) -> Scene {
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

fn float_as_direct(img: &RefImage) -> DirectImage {
    DirectImage {
        sums: img.color.iter().map(|c| c.to_array().map(|v| (v * 32768.0).max(0.0).round() as u64)).collect(),
        hits: img.hits.iter().map(|h| h.map(|h| PrimaryHit { sphere: h.sphere, t: h.t })).collect(),
        rays: img.rays,
    }
}

/// Runs `f` three times; the result and the fastest time (host noise only adds).
fn timed<T>(mut f: impl FnMut() -> Result<T, HostError>) -> Result<(T, f64), HostError> {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..3 {
        let start = Instant::now();
        let value = f()?;
        best = best.min(start.elapsed().as_secs_f64());
        out = Some(value);
    }
    out.map(|v| (v, best)).ok_or_else(|| HostError::Io("no run".into()))
}

/// Measures every variant on `scene` at `size`.
pub fn measure(name: &str, scene: &Scene, size: [u16; 2]) -> Result<Vec<Measured>, HostError> {
    let [w, h] = size;
    let (refimg, t_ref) = timed(|| Ok(reference::render(scene, w, h)))?;
    let ref_rgb = refimg.rgb8();
    let mut out = Vec::new();
    let mut push = |variant: &'static str, img: &DirectImage, seconds: f64| {
        let rgb: Vec<u8> = img.sums.iter().flat_map(|p| p.map(to_srgb8)).collect();
        let error = compare(scene, size, img, &rgb, &refimg, &ref_rgb);
        let ns_per_ray = seconds * 1e9 / img.rays.max(1) as f64;
        out.push(Measured { variant, scene: name.to_string(), ns_per_ray, error });
    };
    let (shipped, t) = timed(|| host_tool::plan::direct::render(scene, w, h))?;
    push("fixed-q16.16-q2.30", &shipped, t);
    let coarse = positions_rounded(scene, 12);
    let (img, t) = timed(|| host_tool::plan::direct::render(&coarse, w, h))?;
    push("fixed-pos-q.12", &img, t);
    let (img, t) = timed(|| host_tool::plan::direct::render_with_camera_bits(scene, w, h, 16))?;
    push("fixed-camera-q2.16", &img, t);
    let (img, t) = timed(|| Ok(reference::render_f32(scene, w, h)))?;
    push("f32", &float_as_direct(&img), t);
    push("f64", &float_as_direct(&refimg), t_ref);
    Ok(out)
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

/// Runs the report on the given scenes and writes `numerics.csv`,
/// `numerics.png` and `numerics.md` into `out`; returns the Markdown table.
pub fn report(scenes: &[(String, Scene)], size: [u16; 2], out: &Path) -> Result<String, HostError> {
    std::fs::create_dir_all(out)
        .map_err(|e| HostError::Io(format!("cannot create {}: {e}", out.display())))?;
    let mut all = Vec::new();
    for (name, scene) in scenes {
        all.extend(measure(name, scene, size)?);
    }
    let mut csv = String::from(
        "variant,scene,ns_per_ray,hit_agreement,ambiguous,gross,psnr_db,depth_mean,depth_p99,depth_max,normal_max_deg\n",
    );
    for m in &all {
        let e = &m.error;
        let _ = writeln!(
            csv,
            "{},{},{:.1},{:.6},{},{},{:.2},{:.3e},{:.3e},{:.3e},{:.3e}",
            m.variant,
            m.scene,
            m.ns_per_ray,
            e.hit_agreement,
            e.ambiguous_mismatches,
            e.gross_mismatches,
            e.psnr_db,
            e.depth_error_mean,
            e.depth_error_p99,
            e.depth_error_max,
            e.normal_error_max_deg
        );
    }
    // Per variant: mean time and worst error over the scenes (the reference is
    // the zero point and stays off the log plot).
    let mut variants: Vec<&'static str> = Vec::new();
    for m in &all {
        if m.variant != "f64" && !variants.contains(&m.variant) {
            variants.push(m.variant);
        }
    }
    let summary: Vec<(&'static str, f64, f64, f64, u64)> = variants
        .iter()
        .map(|v| {
            let ms: Vec<&Measured> = all.iter().filter(|m| m.variant == *v).collect();
            let time = ms.iter().map(|m| m.ns_per_ray).sum::<f64>() / ms.len() as f64;
            let p99 = ms.iter().map(|m| m.error.depth_error_p99).fold(0.0, f64::max);
            let miss = ms.iter().map(|m| 1.0 - m.error.hit_agreement).fold(0.0, f64::max);
            let gross = ms.iter().map(|m| m.error.gross_mismatches).sum();
            (*v, time, p99, miss, gross)
        })
        .collect();
    let pts: Vec<(f64, f64)> = summary.iter().map(|s| (s.1, s.2.max(1e-12))).collect();
    let front = pareto(&pts);
    let mut md = String::from(
        "| variant | ns per ray | depth error p99 (cube) | worst 1 - hit agreement | gross mismatches | Pareto |\n|---|---|---|---|---|---|\n",
    );
    for (i, s) in summary.iter().enumerate() {
        let on = if front.contains(&i) { "yes" } else { "" };
        let _ = writeln!(md, "| {} | {:.0} | {:.2e} | {:.2e} | {} | {on} |", s.0, s.1, s.2, s.3, s.4);
    }
    let series: Vec<Series> = summary
        .iter()
        .map(|s| Series { name: s.0.to_string(), points: vec![(s.1, s.2.max(1e-12))], markers: true })
        .chain(std::iter::once(Series {
            name: "Pareto front".into(),
            points: front.iter().map(|&i| pts[i]).collect(),
            markers: false,
        }))
        .collect();
    let chart = Chart {
        title: "Depth error (p99, worst scene) against host time per ray".into(),
        x_label: "ns per ray (host)".into(),
        y_label: "depth error p99 (cubes)".into(),
        log_x: true,
        log_y: true,
    };
    write_atomic(&out.join("numerics.csv"), csv.as_bytes())?;
    write_atomic(&out.join("numerics.md"), md.as_bytes())?;
    write_atomic(&out.join("numerics.png"), &png(&[(chart, series)], 900, 520)?)?;
    Ok(md)
}
