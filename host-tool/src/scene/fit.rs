//! Fitting a scene into the grid: the array's space is a grid of unit cubes
//! starting at the origin, but scene files use their own units (an NFF
//! sphereflake spans about [-1, 1]). One uniform scale and an offset put the
//! spheres' bounding box in the middle of the grid; the camera and the
//! lights move with them, so the picture is the same.

use node_fw::limits::MAX_GRID;

use super::Scene;
use crate::error::{HostError, input};

/// Free space left on each side of the spheres, as a share of the grid.
const MARGIN: f64 = 0.02;
/// Cubes per sphere when the grid is chosen from the scene: a few cubes per
/// sphere keeps both the cube steps and the sphere tests per ray small (the
/// paper's own scene: 1000 spheres on 32^3, 33 cubes each).
const CUBES_PER_SPHERE: f64 = 8.0;

/// Cubes a node should hold along each axis at least when the grid is chosen
/// for an array: fewer leave the partition fit and the sliding boundaries
/// too coarse a step (`lab report tradeoff` measures it: docs/arithmetic.md).
pub const CUBES_PER_NODE: u16 = 4;

/// Scales and moves `scene` into `grid`, or into a grid chosen from the
/// spheres' extent and number (at most `MAX_GRID` a side) when `grid` is
/// `None`.
pub fn fit(scene: &mut Scene, grid: Option<[u16; 3]>) -> Result<(), HostError> {
    let grid = match grid {
        Some(g) => g,
        None => choose(scene, [1; 3])?,
    };
    let (lo, hi) = bounds(scene).ok_or_else(|| input("the scene has no spheres to fit"))?;
    let extent: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(f64::MIN_POSITIVE));
    if grid.iter().any(|&g| g == 0 || g > MAX_GRID) {
        return Err(input(format!("grid {grid:?} must be 1..={MAX_GRID} cubes per axis")));
    }
    let g = grid.map(f64::from);
    let scale = (0..3).map(|a| g[a] * (1.0 - 2.0 * MARGIN) / extent[a]).fold(f64::INFINITY, f64::min);
    let mid = |a: usize| (lo[a] + hi[a]) / 2.0;
    let place = |p: [f64; 3]| -> [f64; 3] { std::array::from_fn(|a| (p[a] - mid(a)) * scale + g[a] / 2.0) };
    let camera = scene.camera();
    scene.camera = Some(super::Camera { eye: place(camera.eye), look_at: place(camera.look_at), ..camera });
    for key in &mut scene.keyframes {
        let c = key.camera;
        key.camera = super::Camera { eye: place(c.eye), look_at: place(c.look_at), ..c };
    }
    for light in &mut scene.lights {
        light.position = place(light.position);
    }
    for s in &mut scene.spheres {
        s.center = place(s.center);
        s.radius *= scale;
    }
    for key in &mut scene.sphere_keyframes {
        key.center = place(key.center);
    }
    scene.grid = grid;
    Ok(())
}

/// The spheres' bounding box, wherever their keyframes move them.
fn bounds(scene: &Scene) -> Option<([f64; 3], [f64; 3])> {
    let moved = scene.sphere_keyframes.iter().filter_map(|key| {
        let s = scene.spheres.get(key.sphere as usize)?;
        Some((key.center, s.radius))
    });
    let mut boxes =
        scene.spheres.iter().map(|s| (s.center, s.radius)).chain(moved).map(|(center, radius)| {
            (std::array::from_fn(|a| center[a] - radius), std::array::from_fn(|a| center[a] + radius))
        });
    let first: ([f64; 3], [f64; 3]) = boxes.next()?;
    Some(boxes.fold(first, |(lo, hi), (l, h)| {
        (std::array::from_fn(|a| lo[a].min(l[a])), std::array::from_fn(|a| hi[a].max(h[a])))
    }))
}

/// The grid a scene is fitted into when none is given: about
/// `CUBES_PER_SPHERE` cubes per sphere, shaped like the spheres' bounding
/// box, and finer where that leaves fewer than `at_least` cubes along an axis.
pub fn choose(scene: &Scene, at_least: [u16; 3]) -> Result<[u16; 3], HostError> {
    let (lo, hi) = bounds(scene).ok_or_else(|| input("the scene has no spheres to fit"))?;
    let extent: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(f64::MIN_POSITIVE));
    Ok(grid_for(extent, scene.spheres.len(), at_least))
}

/// [`choose`] for a bounding box of `extent` holding `spheres` spheres.
fn grid_for(extent: [f64; 3], spheres: usize, at_least: [u16; 3]) -> [u16; 3] {
    let volume: f64 = extent.iter().product();
    let per_sphere = (CUBES_PER_SPHERE * spheres as f64 / volume).cbrt();
    // The fit keeps the box's shape: its longest side relative to the grid's decides.
    let per_node = (0..3).map(|a| f64::from(at_least[a]) / extent[a]).fold(0.0, f64::max);
    let per_length = per_sphere.max(per_node);
    std::array::from_fn(|a| {
        let cubes = (extent[a] * per_length).round().max(f64::from(at_least[a]));
        cubes.clamp(1.0, f64::from(MAX_GRID)) as u16
    })
}

/// The least grid for an array: [`CUBES_PER_NODE`] cubes per node along each axis.
pub fn at_least_for(array: [u16; 3]) -> [u16; 3] {
    array.map(|n| n.saturating_mul(CUBES_PER_NODE))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SphereDesc;

    fn sphere(center: [f64; 3], radius: f64) -> SphereDesc {
        SphereDesc {
            center,
            radius,
            color: [0.5; 3],
            ambient: 0.3,
            diffuse: 0.7,
            specular: 0.0,
            shininess: 16,
            reflect: 0.0,
        }
    }

    #[test]
    fn a_scene_in_its_own_units_lands_in_the_middle_of_the_grid() {
        let mut s = Scene::random(2, 1, 1.0, [8; 3]).expect("scene");
        s.spheres = vec![sphere([-1.0, 0.0, 0.0], 0.5), sphere([1.0, 0.0, 0.0], 0.5)];
        s.camera = Some(super::super::Camera {
            eye: [0.0, 0.0, -5.0],
            look_at: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_deg: 30.0,
        });
        fit(&mut s, Some([30, 30, 30])).expect("fits");
        // Extent 3 along x fills 96% of 30 cubes: scale 9.6.
        assert_eq!(s.spheres[0].center, [15.0 - 9.6, 15.0, 15.0]);
        assert_eq!(s.spheres[1].radius, 4.8);
        let cam = s.camera.expect("camera");
        assert_eq!((cam.eye, cam.look_at), ([15.0, 15.0, 15.0 - 48.0], [15.0; 3]));
        s.validate().expect("valid once fitted");
    }

    #[test]
    fn a_moving_sphere_is_fitted_wherever_its_keyframes_take_it() {
        use crate::scene::path::SphereKeyframe;
        let mut s = Scene::random(2, 1, 1.0, [8; 3]).expect("scene");
        s.spheres = vec![sphere([-1.0, 0.0, 0.0], 0.5), sphere([1.0, 0.0, 0.0], 0.5)];
        // Sphere 0 travels to x = 5: the box to fit runs from -1.5 to 5.5.
        s.sphere_keyframes = vec![
            SphereKeyframe { sphere: 0, frame: 0, center: [-1.0, 0.0, 0.0] },
            SphereKeyframe { sphere: 0, frame: 10, center: [5.0, 0.0, 0.0] },
        ];
        fit(&mut s, Some([35, 35, 35])).expect("fits");
        // Extent 7 along x fills 96% of 35 cubes: scale 4.8, centre x 2 at 17.5.
        assert_eq!(s.spheres[0].center[0], 17.5 - 3.0 * 4.8);
        assert_eq!(s.sphere_keyframes[1].center[0], 17.5 + 3.0 * 4.8);
        assert_eq!(s.sphere_keyframes[0].center, s.spheres[0].center);
        s.validate().expect("valid once fitted, at every keyframe");
    }

    #[test]
    fn the_grid_chosen_follows_the_spheres_number_and_shape() {
        // 1000 spheres in a cube: 8 000 cubes, 20 a side.
        assert_eq!(grid_for([2.0; 3], 1000, [1; 3]), [20, 20, 20]);
        // A slab twice as wide as deep.
        assert_eq!(grid_for([4.0, 4.0, 2.0], 1000, [1; 3]), [25, 25, 13]);
        assert_eq!(grid_for([1.0; 3], 10_000_000, [1; 3]), [256, 256, 256]);
        // For a 4x4x4 array every axis gets at least 16 cubes, the box's shape kept.
        assert_eq!(grid_for([4.0, 4.0, 2.0], 10, at_least_for([4; 3])), [32, 32, 16]);
        assert_eq!(grid_for([2.0; 3], 1000, at_least_for([8; 3])), [32, 32, 32]);
    }
}
