//! The map of occupied cubes every node is sent ([`node_fw::occupancy`]):
//! one bit a cube of the whole grid, set where some sphere's surface touches
//! it, by the test the nodes fill their own cube lists with.

use link_proto::{CUBES_PER_OCCUPANCY, OccupancyMsg, SphereMsg};
use node_fw::{CubeBox, Grid, Sphere};

/// The largest grid mapped, in cubes (64 KiB cubes: 256 messages, 8 KiB a
/// node). The map costs every node's host link an eighth of a byte a cube,
/// once a scene; larger grids go without, and their nodes pass every ray
/// that leaves them.
pub const MAX_MAPPED_CUBES: usize = 1 << 16;

/// The messages that carry the map of `spheres` in `grid`; none when the
/// grid is larger than [`MAX_MAPPED_CUBES`] or a sphere does not fit it (the
/// nodes then report that sphere).
pub fn occupancy_msgs(spheres: &[SphereMsg], grid: &Grid) -> Vec<OccupancyMsg> {
    let size = grid.size();
    let whole = CubeBox { lo: [0; 3], hi: size };
    let cubes = size.iter().map(|&s| usize::from(s)).product::<usize>();
    if cubes > MAX_MAPPED_CUBES {
        return Vec::new();
    }
    let per = CUBES_PER_OCCUPANCY as usize;
    let mut bits = vec![0u8; cubes.div_ceil(per) * per / 8];
    for msg in spheres {
        let Ok(sphere) =
            Sphere::from_msg(msg, grid).map_err(|_| ()).and_then(|s| s.within(grid).then_some(s).ok_or(()))
        else {
            return Vec::new();
        };
        whole.for_each_surface_cube(&sphere, |k| bits[k / 8] |= 1 << (k % 8));
    }
    bits.chunks_exact(per / 8)
        .zip((0u32..).step_by(per))
        .map(|(chunk, first)| OccupancyMsg { first, bits: chunk.try_into().unwrap_or([0xFF; 32]) })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use link_proto::MaterialMsg;

    fn sphere(center: [f64; 3], radius: f64) -> SphereMsg {
        let q = |x: f64| (x * 65536.0).round() as i32;
        let material =
            MaterialMsg { color: [0; 3], ambient: 0, diffuse: 0, specular: 0, shininess: 1, reflect: 0 };
        SphereMsg { id: 0, center: center.map(q), radius: q(radius), material }
    }

    fn marked(msgs: &[OccupancyMsg]) -> Vec<u32> {
        msgs.iter()
            .flat_map(|m| {
                (0..CUBES_PER_OCCUPANCY)
                    .filter(|i| m.bits[(i / 8) as usize] & (1 << (i % 8)) != 0)
                    .map(move |i| m.first + i)
            })
            .collect()
    }

    #[test]
    fn a_sphere_marks_the_cubes_its_surface_touches_and_no_others() {
        // Grid 4x4x4, cube index (z * 4 + y) * 4 + x. A sphere of radius 0.3
        // at the centre of cube (1, 2, 3) lies inside it alone.
        let grid = Grid::new([4, 4, 4]).unwrap();
        let msgs = occupancy_msgs(&[sphere([1.5, 2.5, 3.5], 0.3)], &grid);
        assert_eq!(msgs.len(), 1);
        assert_eq!(marked(&msgs), vec![(3 * 4 + 2) * 4 + 1]);
        // Radius 0.6 at the same centre crosses the cube's six faces, not its
        // edges (0.5 * sqrt(2) > 0.6): the cube and its six face neighbours.
        let six = marked(&occupancy_msgs(&[sphere([1.5, 2.5, 2.5], 0.6)], &grid));
        let at = |x: u32, y: u32, z: u32| (z * 4 + y) * 4 + x;
        let mut want =
            vec![at(1, 2, 2), at(0, 2, 2), at(2, 2, 2), at(1, 1, 2), at(1, 3, 2), at(1, 2, 1), at(1, 2, 3)];
        want.sort_unstable();
        assert_eq!(six, want);
    }

    #[test]
    fn a_large_grid_takes_as_many_messages_as_its_cubes_need() {
        let grid = Grid::new([20, 10, 3]).unwrap();
        let msgs = occupancy_msgs(&[], &grid);
        // 600 cubes: three messages of 256, the last partly past the grid.
        assert_eq!(msgs.iter().map(|m| m.first).collect::<Vec<_>>(), vec![0, 256, 512]);
        assert!(msgs.iter().all(|m| m.bits == [0; 32]));
    }

    #[test]
    fn a_grid_too_large_goes_without_a_map() {
        assert_eq!(occupancy_msgs(&[], &Grid::new([64, 32, 32]).unwrap()).len(), MAX_MAPPED_CUBES / 256);
        assert!(occupancy_msgs(&[], &Grid::new([64, 32, 33]).unwrap()).is_empty());
    }

    #[test]
    fn a_sphere_outside_the_grid_leaves_no_map() {
        let grid = Grid::new([4, 4, 4]).unwrap();
        assert!(
            occupancy_msgs(&[sphere([1.5, 2.5, 3.5], 0.3), sphere([3.9, 2.0, 2.0], 0.5)], &grid).is_empty()
        );
    }
}
