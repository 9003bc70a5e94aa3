//! Paths: where the camera and the spheres are at each frame of a sequence.
//!
//! A scene's own camera stands still unless the scene file gives keyframes
//! (`"keyframes": [{"frame": 0, "camera": {...}}, ...]`, linear between them,
//! held before the first and after the last) or `render --orbit DEGREES`
//! swings it about its look-at point. A sphere stands at its `center` unless
//! the file gives it keyframes of its own (`"sphere_keyframes": [{"sphere":
//! 0, "frame": 0, "center": [...]}, ...]`), linear and held the same way.

use std::collections::BTreeMap;

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

/// A sphere's centre pinned to a frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereKeyframe {
    /// The sphere, by its index in the scene's `spheres`.
    pub sphere: u32,
    /// Frame number, from 0.
    pub frame: u32,
    /// The sphere's centre at that frame.
    pub center: [f64; 3],
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

    /// The (valid) scene as frame `k` of `frames` sees it: its camera (new,
    /// and checked) and its spheres where their keyframes put them.
    pub fn frame(&self, scene: &Scene, k: u32, frames: u32) -> Result<Scene, HostError> {
        let camera = self.camera(scene, k, frames);
        scene.check_camera(&camera).map_err(|e| e.context(&format!("frame {k}")))?;
        let mut at = Scene { camera: Some(camera), ..scene.clone() };
        for (i, keys) in sphere_paths(scene) {
            let center = match between(&keys, |key| key.frame, k) {
                Some(Between::Held(key)) => key.center,
                Some(Between::Lerp(a, b, t)) => lerp(a.center, b.center, t),
                None => continue,
            };
            if let Some(s) = at.spheres.get_mut(i) {
                s.center = center;
            }
        }
        Ok(at)
    }
}

/// Each sphere that has keyframes, with them in the file's order.
fn sphere_paths(scene: &Scene) -> BTreeMap<usize, Vec<SphereKeyframe>> {
    let mut paths: BTreeMap<usize, Vec<SphereKeyframe>> = BTreeMap::new();
    for key in &scene.sphere_keyframes {
        paths.entry(key.sphere as usize).or_default().push(*key);
    }
    paths
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
    check_sphere_keyframes(scene)
}

/// Checks sphere keyframes: each of a sphere in the scene, a sphere's in
/// increasing frame order, and the sphere valid where each puts it (so
/// everywhere between: the grid is convex).
fn check_sphere_keyframes(scene: &Scene) -> Result<(), HostError> {
    for (i, keys) in sphere_paths(scene) {
        let Some(sphere) = scene.spheres.get(i) else {
            return Err(input(format!(
                "sphere_keyframes name sphere {i}, but the scene has {} spheres",
                scene.spheres.len()
            )));
        };
        for pair in keys.windows(2) {
            if pair[1].frame <= pair[0].frame {
                return Err(input(format!(
                    "sphere {i}'s keyframes must be in increasing frame order: frame {} follows frame {}",
                    pair[1].frame, pair[0].frame
                )));
            }
        }
        for key in &keys {
            let moved = super::SphereDesc { center: key.center, ..*sphere };
            super::validate_sphere(i, &moved, &scene.grid.map(f64::from))
                .map_err(|e| e.context(&format!("sphere keyframe at frame {}", key.frame)))?;
        }
    }
    Ok(())
}

/// Where frame `k` falls among keys in increasing frame order.
enum Between<'a, K> {
    /// On a key, before the first or after the last: that key's value holds.
    Held(&'a K),
    /// Between two keys, this far from the first to the second.
    Lerp(&'a K, &'a K, f64),
}

/// Frame `k` among `keys` (in increasing `frame` order); `None` if there
/// are none.
fn between<K>(keys: &[K], frame: impl Fn(&K) -> u32, k: u32) -> Option<Between<'_, K>> {
    let after = keys.partition_point(|key| frame(key) <= k);
    match (after.checked_sub(1).and_then(|i| keys.get(i)), keys.get(after)) {
        (Some(a), Some(b)) => {
            Some(Between::Lerp(a, b, f64::from(k - frame(a)) / f64::from(frame(b) - frame(a))))
        }
        (Some(a), None) => Some(Between::Held(a)),
        (None, first) => first.map(Between::Held),
    }
}

/// `t` of the way from `x` to `y`.
fn lerp(x: [f64; 3], y: [f64; 3], t: f64) -> [f64; 3] {
    std::array::from_fn(|i| x[i] + (y[i] - x[i]) * t)
}

/// The camera at frame `k` between the scene's keyframes.
fn keyframed(scene: &Scene, k: u32) -> Camera {
    match between(&scene.keyframes, |key| key.frame, k) {
        None => scene.camera(),
        Some(Between::Held(key)) => key.camera,
        Some(Between::Lerp(a, b, t)) => Camera {
            eye: lerp(a.camera.eye, b.camera.eye, t),
            look_at: lerp(a.camera.look_at, b.camera.look_at, t),
            up: lerp(a.camera.up, b.camera.up, t),
            fov_deg: a.camera.fov_deg + (b.camera.fov_deg - a.camera.fov_deg) * t,
        },
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

    #[test]
    fn spheres_move_along_their_own_keyframes_and_the_rest_stand_still() {
        let mut s = scene();
        let key = |sphere, frame, x: f64| SphereKeyframe { sphere, frame, center: [x, 8.0, 8.0] };
        // Sphere 1 from x 2 at frame 4 to x 10 at frame 8; sphere 3's keys
        // interleaved with them in the file.
        s.sphere_keyframes = vec![key(1, 4, 2.0), key(3, 0, 12.0), key(1, 8, 10.0), key(3, 2, 6.0)];
        s.validate().expect("valid");
        let still = s.spheres.clone();
        let path = CameraPath::Orbit { degrees: 90.0 };
        let centre = |k: u32, i: usize| path.frame(&s, k, 10).expect("frame").spheres[i].center;
        assert_eq!(centre(0, 1), [2.0, 8.0, 8.0]);
        assert_eq!(centre(5, 1), [4.0, 8.0, 8.0]);
        assert_eq!(centre(7, 1), [8.0, 8.0, 8.0]);
        assert_eq!(centre(9, 1), [10.0, 8.0, 8.0]);
        assert_eq!(centre(1, 3), [9.0, 8.0, 8.0]);
        assert_eq!(centre(9, 3), [6.0, 8.0, 8.0]);
        for k in [0, 5, 9] {
            let at = path.frame(&s, k, 10).expect("frame");
            assert_eq!((at.spheres[0], at.spheres[2]), (still[0], still[2]), "frame {k}");
            assert_eq!((at.spheres[1].radius, at.spheres[1].color), (still[1].radius, still[1].color));
            // The camera follows its own path.
            assert_eq!(at.camera, Some(path.camera(&s, k, 10)));
        }
    }

    #[test]
    fn sphere_keyframes_are_checked() {
        let mut s = scene();
        let key = |sphere, frame, x: f64| SphereKeyframe { sphere, frame, center: [x, 8.0, 8.0] };
        let refused = |s: &Scene| s.validate().expect_err("refused").to_string();
        s.sphere_keyframes = vec![key(4, 0, 2.0)];
        let e = refused(&s);
        assert!(e.contains("sphere 4") && e.contains("has 4 spheres"), "{e}");
        s.sphere_keyframes = vec![key(0, 3, 2.0), key(1, 0, 2.0), key(0, 3, 4.0)];
        let e = refused(&s);
        assert!(e.contains("sphere 0's keyframes must be in increasing frame order"), "{e}");
        s.sphere_keyframes = vec![key(2, 0, 2.0), key(2, 5, 17.0)];
        let e = refused(&s);
        assert!(e.contains("frame 5") && e.contains("outside the grid"), "{e}");
        s.sphere_keyframes = vec![key(2, 0, f64::NAN)];
        assert!(matches!(s.validate(), Err(HostError::NonFinite(_))), "{:?}", s.validate());
    }
}
