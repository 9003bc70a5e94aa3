//! The tradeoff report is deterministic: two runs make the same CSV, the
//! host-time column aside.

use lab::tradeoff::{TradeoffConfig, csv, sweep};

/// The CSV without its last column (host nanoseconds, noisy).
fn without_host_time(csv: &str) -> Vec<String> {
    csv.lines().map(|l| l.rsplit_once(',').map_or(l, |(rest, _)| rest).to_string()).collect()
}

#[test]
fn two_runs_make_the_same_csv() {
    let scene = lab::scenes::sphereflake(1, [2, 2, 2]).expect("the flake fits");
    let cfg = TradeoffConfig::quick();
    let first = csv(&sweep(&scene, &cfg).expect("the sweep runs"));
    let second = csv(&sweep(&scene, &cfg).expect("the sweep runs"));
    assert!(first.lines().next().is_some_and(|h| h.ends_with(",host_ns_per_ray_noisy")), "{first}");
    // One row per setting and the header: the default, 2 x 2 samples and depths, a grid, two variants.
    assert_eq!(first.lines().count(), 1 + 1 + 3 + 1 + 2, "{first}");
    assert_eq!(without_host_time(&first), without_host_time(&second));
}
