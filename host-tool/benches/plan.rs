//! Host time to plan a frame with `--layout preview`: render the preview,
//! then fit the partition to its cost map. A sequence planned per frame
//! (`--frame-start planned`) pays this every frame.
//!
//! `cargo bench -p host-tool --bench plan`: the paper's scene (1000
//! spheres, seed 1986, 32^3 grid) at 256x256 on the `f413` links.

// criterion_group! generates an undocumented public function.
#![allow(missing_docs)]

use criterion::{BenchmarkId, Criterion, black_box, criterion_group, criterion_main};
use host_tool::plan::initial_partition;
use host_tool::plan::options::{Layout, RenderOptions};
use host_tool::scene::Scene;
use sim_board::{LinkPreset, SimConfig, SimNode};

fn preview_fit(c: &mut Criterion) {
    let scene = Scene::random(1000, 1986, 1.0, [32; 3]).expect("the paper's scene");
    let mut group = c.benchmark_group("preview_fit");
    group.sample_size(10);
    for array in [[4u16, 4, 4], [8, 8, 8]] {
        let mut opts = RenderOptions::new(array);
        opts.sim = SimConfig::with_links(array, LinkPreset::F413);
        opts.layout = Layout::Preview;
        opts.balance = None;
        let [x, y, z] = array;
        group.bench_with_input(BenchmarkId::from_parameter(format!("{x}x{y}x{z}")), &opts, |b, opts| {
            b.iter(|| initial_partition(black_box(&scene), opts, SimNode::capacity()).expect("a plan"))
        });
    }
    group.finish();
}

criterion_group!(benches, preview_fit);
criterion_main!(benches);
