//! Link faults with sliding boundaries, as a property: over link presets x
//! fault rates x balancing x short load intervals x driving axes x array
//! shapes, every
//! render finishes, loses no ray, and gives the image of the single-loop
//! renderer. The tests of faults and of sliding apart ran at the default
//! interval, which hid a node failing on a neighbour's load report that came
//! before its own assignment.
//!
//! The generator's seed is fixed ([`SEED`]), so every CI run tries the same
//! cases; `FAULT_MATRIX_SEED` and `FAULT_MATRIX_CASES` try others.

use host_tool::plan::direct;
use host_tool::plan::options::RenderOptions;
use host_tool::scene::Scene;
use host_tool::session::sim::render_sim;
use link_proto::{Balance, SlidePolicy};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed, TestCaseError, TestRunner};
use sim_board::{LinkPreset, SimConfig};

/// The generator's seed unless `FAULT_MATRIX_SEED` says otherwise.
const SEED: u64 = 25;
/// Cases per run unless `FAULT_MATRIX_CASES` says otherwise (tens of milliseconds each).
const CASES: u32 = 96;
const SIZE: [u16; 2] = [32, 32];

#[derive(Debug, Clone, Copy)]
enum Balancing {
    Static,
    Paper,
    Proportional,
}

#[derive(Debug, Clone)]
struct Case {
    links: LinkPreset,
    array: [u16; 3],
    axis: u8,
    balancing: Balancing,
    interval: u64,
    corrupt: f64,
    drop: f64,
    dup: f64,
    delay: f64,
    fault_seed: u64,
}

fn case() -> impl Strategy<Value = Case> {
    let array =
        [1u16..=4, 1u16..=4, 1u16..=4].prop_filter("at most 32 nodes", |a| a.iter().product::<u16>() <= 32);
    let balancing =
        prop_oneof![Just(Balancing::Static), Just(Balancing::Paper), Just(Balancing::Proportional)];
    let rate = prop_oneof![Just(0.0), 0.0..0.1];
    let links = prop_oneof![Just(LinkPreset::Ideal), Just(LinkPreset::F413)];
    let fault_rates = (rate.clone(), rate.clone(), rate.clone(), rate);
    (links, array, 0u8..3, balancing, 20_000u64..600_000, fault_rates, any::<u64>()).prop_map(
        |(links, array, axis, balancing, interval, (corrupt, drop, dup, delay), fault_seed)| Case {
            links,
            array,
            axis,
            balancing,
            interval,
            corrupt,
            drop,
            dup,
            delay,
            fault_seed,
        },
    )
}

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

#[test]
fn faults_with_sliding_keep_the_image_over_arrays_axes_and_intervals() {
    let scene = Scene::random(20, 1, 1.0, [16; 3]).expect("valid scene");
    let want = direct::render(&scene, SIZE[0], SIZE[1]).expect("single-loop render");
    let seed = env_or("FAULT_MATRIX_SEED", SEED);
    let cases = env_or("FAULT_MATRIX_CASES", CASES);
    let config =
        Config { cases, rng_seed: RngSeed::Fixed(seed), failure_persistence: None, ..Config::default() };
    let mut runner = TestRunner::new(config);
    let slides = std::cell::Cell::new(0);
    let resends = std::cell::Cell::new(0);
    let result = runner.run(&case(), |c| {
        let mut opts = RenderOptions::new(c.array);
        opts.sim = SimConfig::with_links(c.array, c.links);
        opts.size = SIZE;
        opts.driving_axis = Some(c.axis);
        let policy = match c.balancing {
            Balancing::Static => None,
            Balancing::Paper => Some(SlidePolicy::Paper),
            Balancing::Proportional => Some(host_tool::plan::options::PROPORTIONAL),
        };
        opts.balance =
            policy.map(|policy| Balance { interval: c.interval, threshold: 1 << 16, step: 1, policy });
        opts.sim.faults = Some(sim_board::Faults {
            corrupt: c.corrupt,
            drop: c.drop,
            dup: c.dup,
            delay: c.delay,
            seed: c.fault_seed,
        });
        let r = render_sim(&scene, &opts).map_err(|e| TestCaseError::fail(format!("{c:?}: {e}")))?;
        prop_assert_eq!(r.frame.rays_created, r.frame.rays_terminated, "rays lost: {:?}", c);
        prop_assert!(r.frame.sums == want.sums, "the image changed: {:?}", c);
        slides.set(slides.get() + r.frame.slides.len());
        resends.set(resends.get() + r.links.retransmitted);
        Ok(())
    });
    if let Err(e) = result {
        panic!("seed {seed}: {e}");
    }
    let (slides, resends) = (slides.get(), resends.get());
    eprintln!(
        "fault matrix: {cases} cases passed (seed {seed}), {slides} slides committed, {resends} frames resent"
    );
    assert!(slides > 0 && resends > 0, "the cases slid no boundary or resent no frame: they test nothing");
}
