//! The camera as the nodes see it: eye and per-pixel direction steps, quantised.

use link_proto::CameraMsg;

use crate::scene::{Camera, cross, norm, q16, sub};

/// Basis of the image plane at distance 1: direction of pixel `(x, y)` is
/// `corner + x du + y dv` (f64, before quantisation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelBasis {
    /// Eye.
    pub eye: [f64; 3],
    /// Direction through the centre of pixel (0, 0).
    pub corner: [f64; 3],
    /// Step per pixel to the right.
    pub du: [f64; 3],
    /// Step per pixel down.
    pub dv: [f64; 3],
}

impl PixelBasis {
    /// The basis of `camera` for a `width` x `height` image.
    pub fn new(camera: &Camera, width: u16, height: u16) -> Self {
        let f = unit(sub(camera.look_at, camera.eye));
        let r = unit(cross(f, camera.up));
        let u = cross(r, f);
        let h = (camera.fov_deg.to_radians() / 2.0).tan();
        let w = h * f64::from(width) / f64::from(height);
        let du = r.map(|c| c * 2.0 * w / f64::from(width));
        let dv = u.map(|c| -c * 2.0 * h / f64::from(height));
        let corner = std::array::from_fn(|a| f[a] - w * r[a] + h * u[a] + (du[a] + dv[a]) / 2.0);
        // Directions are normalised by the nodes, so any common scale works:
        // keep every component inside Q2.30's range.
        let s = 1.0 / corner.iter().chain(&f).fold(1.0f64, |m, c| m.max(c.abs() * 1.01));
        Self { eye: camera.eye, corner: corner.map(|c| c * s), du: du.map(|c| c * s), dv: dv.map(|c| c * s) }
    }

    /// The quantised camera message.
    pub fn msg(&self) -> CameraMsg {
        let q30 = |v: [f64; 3]| v.map(|c| (c * (1u64 << 30) as f64).round() as i32);
        CameraMsg { eye: self.eye.map(q16), corner: q30(self.corner), du: q30(self.du), dv: q30(self.dv) }
    }
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = norm(v);
    v.map(|c| c / n)
}
