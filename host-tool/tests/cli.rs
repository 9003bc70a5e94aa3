//! The command line: bad input gets one clear line and a non-zero exit, and
//! nothing is written.

use std::path::Path;
use std::process::{Command, Output};

use tempfile::TempDir;

fn host_tool(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-tool")).current_dir(dir).args(args).output().expect("runs")
}

/// A fresh directory for one case, removed when dropped.
fn scratch(name: &str) -> TempDir {
    tempfile::Builder::new().prefix(&format!("host-tool-cli-{name}-")).tempdir().unwrap()
}

/// Runs a failing command: exactly one line on stderr naming `needle`, exit
/// `code`, and no output files.
fn fails(name: &str, args: &[&str], scene: Option<&str>, code: i32, needle: &str) {
    let scratch = scratch(name);
    let dir = scratch.path();
    if let Some(text) = scene {
        std::fs::write(dir.join("scene.json"), text).unwrap();
    }
    let out = host_tool(dir, args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{name}: {err}");
    assert!(err.contains(needle), "{name}: '{err}' lacks '{needle}'");
    assert_eq!(err.trim_end().lines().count(), 1, "{name}: one line, got '{err}'");
    for f in ["render.png", "loads.csv", "summary.json", "load-history.csv", "boundary-history.csv"] {
        assert!(!dir.join(f).exists(), "{name}: {f} written despite the error");
    }
}

const ONE_SPHERE: &str = r#"{"grid": [8, 8, 8], "spheres": [{"center": [4, 4, 4], "radius": RADIUS}]}"#;

#[test]
fn bad_input_is_one_line_with_its_documented_exit_code() {
    let render = |extra: &[&'static str]| [&["render"][..], extra].concat();
    fails("nan", &render(&["--spheres", "10", "--volume-ratio", "NaN"]), None, 11, "volume-ratio");
    fails(
        "neg-radius",
        &render(&["--scene", "scene.json"]),
        Some(&ONE_SPHERE.replace("RADIUS", "-1")),
        12,
        "must be positive",
    );
    fails(
        "zero-radius",
        &render(&["--scene", "scene.json"]),
        Some(&ONE_SPHERE.replace("RADIUS", "0")),
        12,
        "must be positive",
    );
    fails(
        "big-radius",
        &render(&["--scene", "scene.json"]),
        Some(&ONE_SPHERE.replace("RADIUS", "65")),
        12,
        "outside 1/256",
    );
    let outside = r#"{"grid": [8, 8, 8], "spheres": [{"center": [9, 4, 4], "radius": 0.5}]}"#;
    fails("outside", &render(&["--scene", "scene.json"]), Some(outside), 13, "outside the grid");
    // Found while comparing with the reference: a sphere sticking out of the grid was
    // seen by the array but clipped by the reference. The scene is the grid.
    let protruding = r#"{"grid": [8, 8, 8], "spheres": [{"center": [7.5, 4, 4], "radius": 1}]}"#;
    fails(
        "protruding",
        &render(&["--scene", "scene.json"]),
        Some(protruding),
        13,
        "extends outside the grid",
    );
    fails("malformed", &render(&["--scene", "scene.json"]), Some("{\"grid\": [8, 8"), 10, "is not valid");
    let inf = r#"{"grid": [8, 8, 8], "spheres": [{"center": [4, 4, 4], "radius": 1e999}]}"#;
    fails("inf", &render(&["--scene", "scene.json"]), Some(inf), 10, "is not valid");
    fails("zero-size", &render(&["--spheres", "10", "--size", "0x10"]), None, 14, "at least 1x1");
    fails(
        "big-array",
        &render(&["--spheres", "10", "--grid", "8x8x8", "--array", "16x2x2"]),
        None,
        15,
        "larger than the grid",
    );
    fails(
        "capacity",
        &render(&["--spheres", "2100", "--grid", "8x8x8", "--array", "1x1x1"]),
        None,
        16,
        "node 0 (0,0,0) would hold",
    );
    fails("missing", &render(&["--scene", "nope.json"]), None, 20, "cannot read scene");
}

#[test]
fn default_render_writes_image_loads_and_summary() {
    let scratch = scratch("ok");
    let dir = scratch.path();
    let out = host_tool(dir, &["render", "--size", "32x24", "--array", "2x2x2", "--spheres", "50"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["rays_created"], summary["rays_terminated"]);
    assert_eq!(summary["nodes"].as_array().unwrap().len(), 8);
    for key in ["makespan", "imbalance"] {
        assert!(summary[key].as_f64().unwrap() > 0.0, "{key}");
    }
    for n in summary["nodes"].as_array().unwrap() {
        for key in ["running", "waiting", "rays", "sphere_tests"] {
            assert!(n[key].is_u64(), "{key}");
        }
    }
    let refused: u64 =
        summary["nodes"].as_array().unwrap().iter().map(|n| n["refused"].as_u64().unwrap()).sum();
    assert_eq!(summary["rays_refused"].as_u64(), Some(refused));
    let csv = std::fs::read_to_string(dir.join("loads.csv")).unwrap();
    assert_eq!(csv.lines().count(), 9);
    let png = image::open(dir.join("render.png")).unwrap();
    assert_eq!((png.width(), png.height()), (32, 24));
}

/// The boundary history starts from the even cut and, under the paper's
/// rule, records every committed slide as a move of one cube.
#[test]
fn a_sliding_render_writes_its_boundary_history() {
    let scratch = scratch("slides");
    let dir = scratch.path();
    let args = ["render", "--size", "32x24", "--array", "2x2x2", "--spheres", "50", "--interval", "50000"];
    let out = host_tool(dir, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let csv = std::fs::read_to_string(dir.join("boundary-history.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("time,row,boundary,position"));
    let rows: Vec<[u64; 4]> = lines
        .map(|l| {
            let v: Vec<u64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    // A 2x2x2 array has four lines of two nodes along the driving axis, each
    // cut once, at first in the middle of the 32-cube grid.
    let (start, slides): (Vec<&[u64; 4]>, Vec<&[u64; 4]>) = rows.iter().partition(|r| r[0] == 0);
    assert_eq!(
        start.iter().map(|r| (r[1], r[2], r[3])).collect::<Vec<_>>(),
        [0, 1, 2, 3].map(|row| (row, 0, 16))
    );
    assert_eq!(Some(slides.len() as u64), summary["slides"].as_u64());
    assert!(!slides.is_empty(), "no slide at this interval: the test checks nothing");
    let mut at = [16u64; 4];
    let mut time = 0;
    for [t, row, _, position] in slides {
        assert!(*t >= time, "time runs forward");
        time = *t;
        let was = &mut at[*row as usize];
        assert_eq!(was.abs_diff(*position), 1, "row {row}: {was} to {position}");
        assert!((1..32).contains(position));
        *was = *position;
    }
}

#[test]
fn a_node_restarting_mid_render_is_named_and_no_image_is_written() {
    let args =
        ["render", "--spheres", "200", "--array", "2x2x2", "--size", "64x64", "--restart-node", "5@500000"];
    fails("restart", &args, None, 30, "node 5 (1,0,1) restarted mid-render");
    // Over framed links a restart is a new incarnation on the node's links,
    // noticed by the host's channel and the neighbours' alike.
    let framed = [&args[..], &["--faults", "corrupt=0.01,drop=0.01"]].concat();
    fails("restart-framed", &framed, None, 30, "node 5 (1,0,1) restarted mid-render");
}
