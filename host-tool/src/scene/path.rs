//! Camera paths: where the camera is at each frame of a sequence.
//!
//! A scene's own camera stands still unless the scene file gives keyframes
//! (`"keyframes": [{"frame": 0, "camera": {...}}, ...]`, linear between them,
//! held before the first and after the last) or `render --orbit DEGREES`
//! swings it about its look-at point.

use serde::{Deserialize, Serialize};

use super::{Camera, Scene, cross, norm, sub};
use crate::error::{HostError, input};

/// A camera the scene file pins to a frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Frame number, from 0.
    pub frame: u32,
    /// The camera at that frame.
    pub camera: Camera,
}

/// How the camera moves over a sequence of frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CameraPath {
    /// The scene's keyframes, or its one camera if it has none.
    Keyframes,
    /// The scene's camera swung about its look-at point, around its up
    /// direction, by this many degrees over the sequence (frame `k` of `n`
    /// at `k / n` of it, so a full turn does not show its first frame twice).
    Orbit {
        /// Degrees over the whole sequence.
        degrees: f64,
    },
}

impl CameraPath {
    /// The camera of frame `k` of `frames`.
    pub fn camera(&self, scene: &Scene, k: u32, frames: u32) -> Camera {
        match *self {
            Self::Keyframes => keyframed(scene, k),
            Self::Orbit { degrees } => {
                let base = scene.camera();
                let angle = (degrees * f64::from(k) / f64::from(frames.max(1))).to_radians();
                let arm = rotate(sub(base.eye, base.look_at), base.up, angle);
                Camera { eye: std::array::from_fn(|a| base.look_at[a] + arm[a]), ..base }
            }
        }
    }

    /// The (valid) scene as frame `k` of `frames` sees it: only its camera
    /// is new, and checked.
    pub fn frame(&self, scene: &Scene, k: u32, frames: u32) -> Result<Scene, HostError> {
        let camera = self.camera(scene, k, frames);
        scene.check_camera(&camera).map_err(|e| e.context(&format!("frame {k}")))?;
        Ok(Scene { camera: Some(camera), ..scene.clone() })
    }
}

/// Checks keyframes: in increasing frame order, each camera valid.
pub fn check_keyframes(scene: &Scene) -> Result<(), HostError> {
    for pair in scene.keyframes.windows(2) {
        if pair[1].frame <= pair[0].frame {
            return Err(input(format!(
                "keyframes must be in increasing frame order: frame {} follows frame {}",
                pair[1].frame, pair[0].frame
            )));
        }
    }
    for key in &scene.keyframes {
        scene
            .check_camera(&key.camera)
            .map_err(|e| e.context(&format!("keyframe at frame {}", key.frame)))?;
    }
    Ok(())
}

/// The camera at frame `k` between the scene's keyframes.
fn keyframed(scene: &Scene, k: u32) -> Camera {
    let keys = &scene.keyframes;
    let Some(first) = keys.first() else { return scene.camera() };
    let after = keys.partition_point(|key| key.frame <= k);
    let (Some(a), Some(b)) = (keys.get(after.wrapping_sub(1)), keys.get(after)) else {
        return if k < first.frame { first.camera } else { keys.last().map_or(first.camera, |l| l.camera) };
    };
    let t = f64::from(k - a.frame) / f64::from(b.frame - a.frame);
    let lerp = |x: [f64; 3], y: [f64; 3]| std::array::from_fn(|i| x[i] + (y[i] - x[i]) * t);
    Camera {
        eye: lerp(a.camera.eye, b.camera.eye),
        look_at: lerp(a.camera.look_at, b.camera.look_at),
        up: lerp(a.camera.up, b.camera.up),
        fov_deg: a.camera.fov_deg + (b.camera.fov_deg - a.camera.fov_deg) * t,
    }
}

/// `v` turned by `angle` radians about the axis `axis` (Rodrigues' formula).
fn rotate(v: [f64; 3], axis: [f64; 3], angle: f64) -> [f64; 3] {
    let n = norm(axis).max(f64::MIN_POSITIVE);
    let k = axis.map(|c| c / n);
    let (s, c) = angle.sin_cos();
    let kxv = cross(k, v);
    let kdv: f64 = (0..3).map(|i| k[i] * v[i]).sum();
    std::array::from_fn(|i| v[i] * c + kxv[i] * s + k[i] * kdv * (1.0 - c))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> Scene {
        Scene::random(4, 1, 1.0, [16; 3]).expect("scene")
    }

    #[test]
    fn a_full_orbit_keeps_the_distance_and_comes_back_round() {
        let s = scene();
        let base = s.camera();
        let path = CameraPath::Orbit { degrees: 360.0 };
        let r = norm(sub(base.eye, base.look_at));
        for k in 0..8 {
            let cam = path.camera(&s, k, 8);
            assert!((norm(sub(cam.eye, cam.look_at)) - r).abs() < 1e-9);
            assert_eq!(cam.look_at, base.look_at);
        }
        // A quarter turn about +y takes an eye on -z to -x of the look-at point.
        let quarter = path.camera(&s, 2, 8);
        assert!((quarter.eye[0] - (base.look_at[0] - r)).abs() < 1e-9, "{:?}", quarter.eye);
        assert!((quarter.eye[2] - base.look_at[2]).abs() < 1e-9);
        assert_eq!(path.camera(&s, 0, 8), base);
    }

    #[test]
    fn keyframes_are_held_outside_and_linear_between() {
        let mut s = scene();
        let cam = |x: f64, fov: f64| Camera {
            eye: [x, 8.0, -20.0],
            look_at: [8.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_deg: fov,
        };
        s.keyframes = vec![
            Keyframe { frame: 2, camera: cam(0.0, 40.0) },
            Keyframe { frame: 6, camera: cam(16.0, 60.0) },
        ];
        check_keyframes(&s).expect("valid");
        let path = CameraPath::Keyframes;
        assert_eq!(path.camera(&s, 0, 10), cam(0.0, 40.0));
        assert_eq!(path.camera(&s, 3, 10), cam(4.0, 45.0));
        assert_eq!(path.camera(&s, 6, 10), cam(16.0, 60.0));
        assert_eq!(path.camera(&s, 9, 10), cam(16.0, 60.0));
        s.keyframes.swap(0, 1);
        let e = check_keyframes(&s).expect_err("out of order");
        assert!(e.to_string().contains("increasing frame order"), "{e}");
    }
}
