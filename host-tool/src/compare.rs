//! The fixed-point image against the f64 reference.
//!
//! A pixel's first hit may legitimately differ where quantisation decides: the
//! primary ray passes within the quantisation bound of a silhouette, or two
//! spheres lie within it along the ray. Any other difference is gross.

use serde::Serialize;

use glam::DVec3;

use crate::plan::camera::PixelBasis;
use crate::plan::direct::DirectImage;
use crate::reference::{RefImage, silhouette_margin};
use crate::scene::Scene;

/// Comparison metrics, as `host-tool compare` prints them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Comparison {
    /// Share of pixels whose first-hit sphere (or miss) agrees.
    pub hit_agreement: f64,
    /// Disagreeing pixels within the quantisation bound.
    pub ambiguous_mismatches: u64,
    /// Disagreeing pixels outside it.
    pub gross_mismatches: u64,
    /// PSNR of the 8-bit sRGB images, dB (infinite if identical).
    pub psnr_db: f64,
    /// Largest |t - t_ref| over pixels whose first hit agrees, cubes.
    pub depth_error_max: f64,
    /// Mean of the same.
    pub depth_error_mean: f64,
    /// 99th percentile of the same (the maximum sits at grazing pixels, where
    /// depth is ill-conditioned: dt/dp = p / sqrt(r^2 - p^2)).
    pub depth_error_p99: f64,
    /// Largest angle between the surface normals at the two hit points of a
    /// pixel whose first hit agrees, degrees.
    pub normal_error_max_deg: f64,
    /// Pixels compared.
    pub pixels: u64,
}

/// How far the quantised primary ray may be from the ideal one at distance
/// `t`: origin, centre and radius rounding (2^-17 per component) plus the
/// direction's rounding (about 2^-30 per component per cube), doubled.
pub fn quantisation_bound(t: f64) -> f64 {
    2.0 * (3.0 * 3f64.sqrt() * 2f64.powi(-17) + t * 4.0 * 2f64.powi(-30))
}

/// Compares the fixed-point primary hits and image with the reference.
pub fn compare(
    scene: &Scene,
    size: [u16; 2],
    fixed: &DirectImage,
    fixed_rgb: &[u8],
    reference: &RefImage,
    ref_rgb: &[u8],
) -> Comparison {
    let (mut agree, mut ambiguous, mut gross) = (0u64, 0u64, 0u64);
    let mut errors: Vec<f64> = Vec::new();
    let mut normal_max = 0.0f64;
    let basis = PixelBasis::new(&scene.camera(), size[0], size[1]);
    let eye = DVec3::from_array(basis.eye);
    let grid = DVec3::from_array(scene.grid.map(f64::from));
    for (pixel, (f, r)) in fixed.hits.iter().zip(&reference.hits).enumerate() {
        let (x, y) = ((pixel % usize::from(size[0])) as f64, (pixel / usize::from(size[0])) as f64);
        let d = (DVec3::from_array(basis.corner)
            + x * DVec3::from_array(basis.du)
            + y * DVec3::from_array(basis.dv))
        .normalize();
        match (f, r) {
            (None, None) => agree += 1,
            (Some(f), Some(r)) if f.sphere == r.sphere => {
                agree += 1;
                errors.push((f.t - r.t).abs());
                if let Some(s) = scene.spheres.get(usize::from(f.sphere)) {
                    let c = DVec3::from_array(s.center);
                    let (nf, nr) = ((eye + d * f.t - c).normalize(), (eye + d * r.t - c).normalize());
                    normal_max = normal_max.max(nf.dot(nr).clamp(-1.0, 1.0).acos().to_degrees());
                }
            }
            (f, r) => {
                let bound = quantisation_bound(f.map_or(0.0, |h| h.t).max(r.map_or(0.0, |h| h.t)));
                // Either candidate grazed by the ideal ray, the two nearly tied
                // in depth, or a hit point at the grid's boundary (clipping).
                let grazes = |id: u16| {
                    scene
                        .spheres
                        .get(usize::from(id))
                        .is_some_and(|s| silhouette_margin(eye, d, s).abs() <= bound)
                };
                let at_boundary = |t: f64| {
                    let p = eye + d * t;
                    (p.min_element().abs() <= bound) || ((grid - p).min_element().abs() <= bound)
                };
                let tie = matches!((f, r), (Some(f), Some(r)) if (f.t - r.t).abs() <= bound);
                let explained = tie
                    || f.is_some_and(|f| grazes(f.sphere) || at_boundary(f.t))
                    || r.is_some_and(|r| grazes(r.sphere) || r.gap <= bound || at_boundary(r.t));
                if explained {
                    ambiguous += 1;
                } else {
                    gross += 1;
                }
            }
        }
    }
    let pixels = fixed.hits.len() as u64;
    let mse =
        fixed_rgb.iter().zip(ref_rgb).map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2)).sum::<f64>()
            / fixed_rgb.len().max(1) as f64;
    Comparison {
        hit_agreement: agree as f64 / pixels.max(1) as f64,
        ambiguous_mismatches: ambiguous,
        gross_mismatches: gross,
        psnr_db: if mse == 0.0 { f64::INFINITY } else { 10.0 * (255.0f64 * 255.0 / mse).log10() },
        depth_error_max: errors.iter().cloned().fold(0.0, f64::max),
        depth_error_mean: errors.iter().sum::<f64>() / errors.len().max(1) as f64,
        depth_error_p99: {
            errors.sort_by(f64::total_cmp);
            errors.get(errors.len() * 99 / 100).copied().unwrap_or(0.0)
        },
        normal_error_max_deg: normal_max,
        pixels,
    }
}
