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

/// A CSV a command wrote: its header and rows, read by column name.
struct Csv {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Csv {
    fn read(path: &Path) -> Self {
        let text = std::fs::read_to_string(path).unwrap();
        let mut lines = text.lines().map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>());
        let header = lines.next().unwrap();
        Self { header, rows: lines.collect() }
    }

    fn text<'a>(&self, row: &'a [String], name: &str) -> &'a str {
        &row[self.header.iter().position(|h| h == name).unwrap()]
    }

    fn num(&self, row: &[String], name: &str) -> f64 {
        self.text(row, name).parse().unwrap()
    }

    /// Every row's E is T(1) / (S T(S)) from the first row's makespan.
    fn assert_efficiency_from_makespans(&self) {
        let t1 = self.num(&self.rows[0], "makespan");
        for r in &self.rows {
            let e = t1 / (self.num(r, "nodes") * self.num(r, "makespan"));
            assert!((self.num(r, "efficiency") - e).abs() < 1e-4, "{r:?}");
        }
    }
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
    let csv = Csv::read(&dir.join("s/scaling.csv"));
    let nodes: Vec<&str> = csv.rows.iter().map(|r| csv.text(r, "nodes")).collect();
    assert_eq!(nodes, ["1", "8", "8", "27", "27"]);
    csv.assert_efficiency_from_makespans();
    for r in &csv.rows {
        let busy = csv.num(r, "compute") + csv.num(r, "setup") + csv.num(r, "messaging");
        assert!((csv.num(r, "messaging_share") - csv.num(r, "messaging") / busy).abs() < 1e-4, "{r:?}");
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
    let csv = Csv::read(&dir.join("s/shapes.csv"));
    assert_eq!(csv.text(&csv.rows[0], "array"), "1x1x1");
    // The ordered shapes of 8 = 2^3, counted by hand: C(5, 2) = 10, each
    // with the even and the preview cut.
    let mut shapes: Vec<&str> = csv.rows[1..].iter().map(|r| csv.text(r, "array")).collect();
    shapes.sort_unstable();
    let expected = [
        "1x1x8", "1x1x8", "1x2x4", "1x2x4", "1x4x2", "1x4x2", "1x8x1", "1x8x1", "2x1x4", "2x1x4", "2x2x2",
        "2x2x2", "2x4x1", "2x4x1", "4x1x2", "4x1x2", "4x2x1", "4x2x1", "8x1x1", "8x1x1",
    ];
    assert_eq!(shapes, expected);
    for pair in csv.rows[1..].windows(2) {
        assert!(csv.num(&pair[0], "makespan") <= csv.num(&pair[1], "makespan"), "fastest first: {pair:?}");
    }
    csv.assert_efficiency_from_makespans();

    let refused = lab(dir, &[&["bench", "shapes", "--nodes", "1", "--out", "t"][..], &scene].concat());
    assert_eq!(refused.status.code(), Some(17), "{}", String::from_utf8_lossy(&refused.stderr));
    assert!(!dir.join("t").exists(), "nothing written");
}
