//! The lab's commands, run as a user runs them.

use std::path::Path;
use std::process::{Command, Output};

use tempfile::TempDir;

fn lab(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lab")).current_dir(dir).args(args).output().expect("runs")
}

fn scratch(name: &str) -> TempDir {
    tempfile::Builder::new().prefix(&format!("lab-cli-{name}-")).tempdir().unwrap()
}

/// `bench scaling --quick`: E and the messaging share as the CSV's own
/// columns say they should be (E = T(1) / (S T(S)), messaging over busy).
#[test]
fn bench_scaling_reports_efficiency_from_its_makespans() {
    let scratch = scratch("scaling");
    let dir = scratch.path();
    let args = [
        "bench",
        "scaling",
        "--quick",
        "--spheres",
        "60",
        "--size",
        "32x32",
        "--link",
        "ideal",
        "--out",
        "s",
    ];
    let out = lab(dir, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("s/scaling.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.iter().map(|r| r[col("nodes")]).collect::<Vec<_>>(), ["1", "8", "8", "27", "27"]);
    let num = |r: &Vec<&str>, name: &str| r[col(name)].parse::<f64>().unwrap();
    let t1 = num(&rows[0], "makespan");
    for r in &rows {
        let e = t1 / (num(r, "nodes") * num(r, "makespan"));
        assert!((num(r, "efficiency") - e).abs() < 1e-4, "{r:?}");
        let busy = num(r, "compute") + num(r, "setup") + num(r, "messaging");
        assert!((num(r, "messaging_share") - num(r, "messaging") / busy).abs() < 1e-4, "{r:?}");
    }
    assert!(dir.join("s/scaling.png").is_file() && dir.join("s/scaling.md").is_file());
}

/// `bench shapes`: every shape of eight nodes once per cut, fastest first
/// after the one-node run that E is measured against; a count of nodes
/// with no shape is refused with exit 17 and nothing written.
#[test]
fn bench_shapes_runs_every_shape_fastest_first() {
    let scratch = scratch("shapes");
    let dir = scratch.path();
    let scene = ["--spheres", "60", "--size", "32x32", "--link", "ideal"];
    let out = lab(dir, &[&["bench", "shapes", "--nodes", "8", "--out", "s"][..], &scene].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("s/shapes.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows[0][col("array")], "1x1x1");
    // The ordered shapes of 8 = 2^3, counted by hand: C(5, 2) = 10, each
    // with the even and the preview cut.
    let mut shapes: Vec<&str> = rows[1..].iter().map(|r| r[col("array")]).collect();
    shapes.sort_unstable();
    let expected = [
        "1x1x8", "1x1x8", "1x2x4", "1x2x4", "1x4x2", "1x4x2", "1x8x1", "1x8x1", "2x1x4", "2x1x4", "2x2x2",
        "2x2x2", "2x4x1", "2x4x1", "4x1x2", "4x1x2", "4x2x1", "4x2x1", "8x1x1", "8x1x1",
    ];
    assert_eq!(shapes, expected);
    let num = |r: &Vec<&str>, name: &str| r[col(name)].parse::<f64>().unwrap();
    let t1 = num(&rows[0], "makespan");
    for pair in rows[1..].windows(2) {
        assert!(num(&pair[0], "makespan") <= num(&pair[1], "makespan"), "fastest first: {pair:?}");
    }
    for r in &rows {
        let e = t1 / (num(r, "nodes") * num(r, "makespan"));
        assert!((num(r, "efficiency") - e).abs() < 1e-4, "{r:?}");
    }

    let refused = lab(dir, &[&["bench", "shapes", "--nodes", "1", "--out", "t"][..], &scene].concat());
    assert_eq!(refused.status.code(), Some(17), "{}", String::from_utf8_lossy(&refused.stderr));
    assert!(!dir.join("t").exists(), "nothing written");
}
