//! Clear walks (on unless `--no-clear-walks`): nodes that hold the map of occupied cubes
//! retire a ray that has nothing left to meet near the grid's end instead of
//! passing it on. The image must stay the single loop's, on every array,
//! sliding or not, and the rays passed must be fewer.

use host_tool::plan::direct;
use host_tool::plan::options::{Layout, RenderOptions};
use host_tool::scene::Scene;
use host_tool::scene::occupancy::occupancy_msgs;
use host_tool::session::sim::render_sim;

fn hops(r: &host_tool::results::RenderResult<host_tool::session::clock::Cycles>) -> u64 {
    r.busy.iter().flatten().map(|b| b.rays_sent).sum()
}

#[test]
fn clear_walks_keep_the_image_and_pass_fewer_rays() {
    let mut s = Scene::random(300, 11, 1.0, [16; 3]).unwrap();
    s.max_depth = 3;
    let size = [40, 40];
    let want = direct::render(&s, size[0], size[1]).unwrap();
    for (array, layout, sliding) in [
        ([2, 2, 2], Layout::Even, false),
        ([4, 4, 4], Layout::Even, true),
        ([4, 2, 1], Layout::Preview, false),
        ([3, 2, 5], Layout::Even, true),
    ] {
        let mut opts = RenderOptions::new(array);
        opts.size = size;
        opts.layout = layout;
        if sliding {
            opts.balance = Some(host_tool::plan::options::DEFAULT_BALANCE);
        }
        let clear = render_sim(&s, &opts).unwrap();
        let plain = render_sim(&s, &RenderOptions { clear_walks: false, ..opts }).unwrap();
        for r in [&plain, &clear] {
            assert!(r.frame.sums == want.sums, "{array:?}: image differs from the single loop");
            assert_eq!(r.frame.rays_created, r.frame.rays_terminated, "{array:?}: rays lost");
            assert!(r.frame.complete());
        }
        assert!(
            hops(&clear) < hops(&plain),
            "{array:?}: {} rays passed with clear walks, {} without",
            hops(&clear),
            hops(&plain)
        );
    }
}

/// The map of occupied cubes follows the frame's start, and a node uses it
/// once complete: on the real boards' links a frame shorter than the map's
/// time on a node's wire from the host ends before the map has come, and
/// its image is still the single loop's. Sent with the scene, the map had
/// held back every frame's first ray (on 4x4x4 at 128x128, a third of the frame).
#[test]
fn the_first_rays_do_not_wait_for_the_map() {
    let s = Scene::random(20, 5, 1.0, [32; 3]).unwrap();
    let mut opts = RenderOptions::new([2, 2, 2]);
    opts.size = [8, 8];
    assert_eq!(opts.sim.host_link, sim_board::LinkPreset::F413.host(), "the real boards' host links");
    let grid = node_fw::Grid::new(s.grid).unwrap();
    let map_bytes = 32 * occupancy_msgs(&s.sphere_msgs(), &grid).len() as u64;
    let map_time = map_bytes * opts.sim.host_link.byte_cycles();
    let r = render_sim(&s, &opts).unwrap();
    assert!(
        r.frame.makespan.0 < map_time,
        "the frame took {:?}, the map {map_time} cycles",
        r.frame.makespan
    );
    assert!(r.frame.sums == direct::render(&s, 8, 8).unwrap().sums, "image differs from the single loop");
}
