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
    // A limit a setting lifts names the setting.
    fails(
        "capacity-hint",
        &render(&["--spheres", "2100", "--grid", "8x8x8", "--array", "1x1x1"]),
        None,
        16,
        "--array",
    );
    fails("missing", &render(&["--scene", "nope.json"]), None, 20, "cannot read scene");
    // Readable, but not a scene: malformed (10), not unreadable (20).
    let garbage = String::from_utf8_lossy(&[0xff, 0xfe, 0x00, 0x9c, 0x80]).into_owned();
    let scratch = scratch("binary");
    std::fs::write(scratch.path().join("scene.json"), [0xff, 0xfe, 0x00, 0x9c, 0x80]).unwrap();
    let out = host_tool(scratch.path(), &render(&["--scene", "scene.json"]));
    assert_eq!(
        out.status.code(),
        Some(10),
        "binary scene ({garbage:?}): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("not UTF-8"));
}

/// An image the host could not hold is refused up front, in one line, with
/// the largest size stated; it used to abort with an allocation failure.
#[test]
fn an_image_too_large_to_hold_is_refused() {
    let too_large = ["render", "--spheres", "10", "--size", "65535x65535", "--array", "2x2x2"];
    fails("huge", &too_large, None, 14, "the most is 67108864");
    fails(
        "huge-reference",
        &["reference", "--spheres", "10", "--size", "8193x8192"],
        None,
        14,
        "the most is",
    );
    fails("huge-compare", &["compare", "--spheres", "10", "--size", "65535x2000"], None, 14, "the most is");
}

/// Arrays whose rays take more class levels than a node's pool has are
/// refused before anything is sent, naming the limit and what to change;
/// they used to start and end with a node's PoolCapacity report.
#[test]
fn a_pool_too_small_for_the_classes_is_refused_up_front() {
    let many = ["render", "--array", "10x10x10", "--size", "16x16"];
    fails("levels", &many, None, 16, "a node's pool has at most 1024: use a smaller array");
    let preview = ["render", "--array", "16x16x16", "--size", "16x16", "--layout", "preview"];
    fails("levels-preview", &preview, None, 16, "class levels");
    fails(
        "depth-0",
        &["render", "--queue-depth", "0", "--size", "8x8"],
        None,
        17,
        "--queue-depth must be at least 1",
    );
    // The same array without sliding fits: the refusal names a setting that works.
    let scratch = scratch("levels-static");
    let out = host_tool(
        scratch.path(),
        &["render", "--array", "10x10x10", "--size", "16x16", "--balance", "static"],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// One output that cannot be written means none is: checked before the run.
#[test]
fn an_unwritable_output_writes_nothing() {
    let args = ["render", "--spheres", "10", "--size", "8x8", "--summary", "/nonexistent/s.json"];
    fails("unwritable", &args, None, 20, "cannot write /nonexistent/s.json");
    let twice = ["render", "--spheres", "10", "--size", "8x8", "--loads", "render.png"];
    fails("twice", &twice, None, 17, "both be written to render.png");
}

/// A usage error leads with the one line that says what is wrong, then
/// clap's pointer to --help; exit 2.
#[test]
fn a_usage_error_leads_with_what_is_wrong() {
    let scratch = scratch("usage");
    for args in [&["render", "--frobnicate"][..], &["render", "--array", "4x4"], &["render", "--size"]] {
        let out = host_tool(scratch.path(), args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        let lines: Vec<&str> = err.lines().collect();
        assert!(lines[0].starts_with("error: ") && lines[0].len() > 20, "{args:?}: {err}");
        assert!(lines.len() <= 3 && !lines.iter().any(|l| l.trim().is_empty()), "{args:?}: {err}");
        assert!(lines.last().is_some_and(|l| l.contains("--help")), "{args:?}: {err}");
    }
    assert!(std::fs::read_dir(scratch.path()).unwrap().next().is_none(), "nothing written");
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
    // The links it ran on, and where the busy cycles went.
    assert_eq!(summary["link"]["preset"], "f413");
    assert_eq!(summary["link"]["neighbour"]["wire_cycles_per_byte"], 320);
    let busy = &summary["busy"];
    let kinds = ["compute", "setup", "messaging"].map(|k| busy[k].as_u64().unwrap());
    let share = busy["messaging_share"].as_f64().unwrap();
    assert!((share - kinds[2] as f64 / kinds.iter().sum::<u64>() as f64).abs() < 1e-9);
    for n in summary["nodes"].as_array().unwrap() {
        let node_busy: u64 =
            ["compute", "setup", "messaging"].iter().map(|k| n["busy"][k].as_u64().unwrap()).sum();
        assert!(node_busy > 0);
        let host = &n["ports"]["host"];
        assert!(host["bytes"].as_u64().unwrap() > 0 && host["utilisation"].as_f64().unwrap() > 0.0);
        let sent: u64 = n["ports"].as_object().unwrap().values().map(|p| p["bytes"].as_u64().unwrap()).sum();
        assert_eq!(Some(sent), n["bytes_sent"].as_u64());
    }
    let csv = std::fs::read_to_string(dir.join("loads.csv")).unwrap();
    assert_eq!(csv.lines().count(), 9);
    let png = image::open(dir.join("render.png")).unwrap();
    assert_eq!((png.width(), png.height()), (32, 24));
    // Where it came from, and the unit of every time.
    assert_eq!(summary["backend"], "sim");
    assert_eq!(summary["versions"]["protocol"], link_proto::PROTOCOL_VERSION);
    assert_eq!(summary["scene"]["source"], "random");
    assert_eq!(
        (summary["scene"]["spheres"].as_u64(), summary["scene"]["seed"].as_u64()),
        (Some(50), Some(1))
    );
    assert_eq!(summary["units"]["makespan"], "cycles (virtual)");
    // The best measured policy is the default; the paper's is --policy paper.
    assert_eq!(summary["sliding"]["policy"], "proportional");
}

/// A second run does not replace the first run's files unless told to;
/// --out-dir puts every file elsewhere; an image is a .png.
#[test]
fn a_run_keeps_an_earlier_runs_files_unless_told() {
    let scratch = scratch("again");
    let dir = scratch.path();
    let run = ["render", "--size", "16x16", "--array", "1x1x1", "--spheres", "10", "--balance", "static"];
    assert!(host_tool(dir, &run).status.success());
    let first = std::fs::read(dir.join("summary.json")).unwrap();
    let again = host_tool(dir, &run);
    assert_eq!(again.status.code(), Some(17));
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(err.contains("exists, from an earlier run; add --overwrite"), "{err}");
    assert_eq!(
        std::fs::read(dir.join("summary.json")).unwrap(),
        first,
        "the first run's summary was touched"
    );
    assert!(host_tool(dir, &[&run[..], &["--overwrite"]].concat()).status.success());
    let elsewhere = host_tool(dir, &[&run[..], &["--out-dir", "runs/two"]].concat());
    assert!(elsewhere.status.success(), "{}", String::from_utf8_lossy(&elsewhere.stderr));
    for f in
        ["render.png", "loads.csv", "summary.json", "load-history.csv", "boundary-history.csv", "loads.png"]
    {
        assert!(dir.join("runs/two").join(f).is_file(), "{f}");
    }
    fails("jpg", &[&run[..], &["--out", "x.jpg"]].concat(), None, 17, "images are written as PNG");
}

/// The boundary history starts from the even cut and, under the paper's
/// rule, records every committed slide as a move of one cube.
#[test]
fn a_sliding_render_writes_its_boundary_history() {
    let scratch = scratch("slides");
    let dir = scratch.path();
    let args = [
        "render",
        "--size",
        "32x24",
        "--array",
        "2x2x2",
        "--spheres",
        "50",
        "--interval",
        "50000",
        "--policy",
        "paper",
    ];
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

#[test]
fn link_settings_are_checked() {
    fails("baud", &["render", "--size", "8x8", "--baud", "10"], None, 17, "--baud must be from 300");
    fails(
        "clock",
        &["render", "--size", "8x8", "--clock-mhz", "5000"],
        None,
        17,
        "--clock-mhz must be from 1 to 1000",
    );
    let out = host_tool(scratch("preset").path(), &["render", "--size", "8x8", "--link", "fast"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).starts_with(
        "error: invalid value 'fast' for '--link <PRESET>': unknown link preset 'fast' (one of f413, ideal, emulated)"
    ));
    let qemu = ["render", "--size", "8x8", "--backend", "qemu", "--link", "ideal"];
    fails("qemu-link", &qemu, None, 17, "model the in-memory board's links");
}

/// Outputs written atomically must not rename a file over what is not one:
/// `--plot /dev/null` once replaced the device with a regular file. A FIFO
/// stays a FIFO and its reader gets the plot; a symbolic link stays a link
/// and its target gets the table.
#[test]
fn outputs_keep_fifos_and_symbolic_links() {
    use std::os::unix::fs::FileTypeExt;
    let scratch = scratch("special");
    let dir = scratch.path();
    let fifo = dir.join("plot.fifo");
    assert!(Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()), "mkfifo");
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).expect("the FIFO reads"))
    };
    std::fs::write(dir.join("real.csv"), "old").unwrap();
    std::os::unix::fs::symlink(dir.join("real.csv"), dir.join("loads.csv")).unwrap();
    // The link's target holds a file already: replacing it takes --overwrite.
    let args = [
        "render",
        "--spheres",
        "20",
        "--size",
        "16x16",
        "--array",
        "2x1x1",
        "--plot",
        "plot.fifo",
        "--overwrite",
    ];
    let out = host_tool(dir, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let plot = reader.join().expect("reader");
    assert!(plot.starts_with(b"\x89PNG"), "the FIFO's reader got the plot ({} bytes)", plot.len());
    assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo(), "still a FIFO");
    assert!(
        std::fs::symlink_metadata(dir.join("loads.csv")).unwrap().file_type().is_symlink(),
        "still a link"
    );
    let table = std::fs::read_to_string(dir.join("real.csv")).unwrap();
    assert!(table.lines().count() == 3, "the link's target holds the loads: {table}");
    let stray: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp-"))
        .collect();
    assert!(stray.is_empty(), "temporary files left: {stray:?}");
}

/// A random scene written as NFF renders from its file, fitted back into
/// the grid asked for; a scene file of another kind is refused.
#[test]
fn a_scene_written_as_nff_renders_from_its_file() {
    let scratch = scratch("nff");
    let dir = scratch.path();
    let scene = ["--spheres", "40", "--seed", "5", "--grid", "12x12x12", "--size", "24x24"];
    let out = host_tool(dir, &[&["scene", "--out", "s.nff"][..], &scene].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(dir.join("s.nff")).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("s ")).count(), 40);
    let render = host_tool(
        dir,
        &[
            "render", "--scene", "s.nff", "--grid", "12x12x12", "--size", "24x24", "--array", "2x1x1",
            "--out", "a.png",
        ],
    );
    assert!(render.status.success(), "{}", String::from_utf8_lossy(&render.stderr));
    assert!(dir.join("a.png").is_file());
    let wrong = host_tool(dir, &["scene", "--out", "s.txt"]);
    assert_eq!(wrong.status.code(), Some(17));
    assert!(String::from_utf8_lossy(&wrong.stderr).contains("written as .json or .nff"));
    assert!(!dir.join("s.txt").exists());
}

/// The frames of an animated PNG (its acTL chunk), or `None` for a still one.
fn animation_frames(png: &[u8]) -> Option<u32> {
    let mut i = 8;
    while i + 12 <= png.len() {
        let n = u32::from_be_bytes(png[i..i + 4].try_into().unwrap()) as usize;
        if &png[i + 4..i + 8] == b"acTL" {
            return Some(u32::from_be_bytes(png[i + 8..i + 12].try_into().unwrap()));
        }
        i += 12 + n;
    }
    None
}

#[test]
fn a_sequence_writes_every_frame_the_animation_and_the_table() {
    let scratch = scratch("sequence");
    let dir = scratch.path();
    let scene =
        ["--spheres", "40", "--seed", "3", "--grid", "12x12x12", "--size", "24x16", "--array", "2x2x2"];
    let out = host_tool(
        dir,
        &[&["render", "--frames", "3", "--orbit", "90", "--out-dir", "seq"][..], &scene].concat(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let seq = dir.join("seq");
    for k in 0..3 {
        let frame = image::open(seq.join(format!("frame-{k:04}.png"))).expect("frame").to_rgb8();
        assert_eq!(frame.dimensions(), (24, 16));
    }
    let animation = std::fs::read(seq.join("animation.png")).unwrap();
    assert_eq!(animation_frames(&animation), Some(3));
    let table = std::fs::read_to_string(seq.join("frames.csv")).unwrap();
    let rows: Vec<&str> = table.lines().filter(|l| !l.starts_with('#')).collect();
    assert!(rows[0].starts_with("frame,makespan,imbalance,slides,messages"), "{table}");
    assert_eq!(rows.len(), 4, "{table}");
    // The scene goes with frame 0 only (`loaded` is the ninth column).
    let loaded: Vec<&str> = rows[1..].iter().map(|r| r.split(',').nth(8).unwrap()).collect();
    assert_eq!(loaded, ["1", "0", "0"]);
    assert!(seq.join("frames.png").is_file());
    // Frame 0 is the scene's own camera: the single-frame render's image, byte for byte.
    let single = host_tool(dir, &[&["render", "--out-dir", "one"][..], &scene].concat());
    assert!(single.status.success(), "{}", String::from_utf8_lossy(&single.stderr));
    assert_eq!(
        std::fs::read(seq.join("frame-0000.png")).unwrap(),
        std::fs::read(dir.join("one/render.png")).unwrap()
    );
    // A second run refuses to replace the first's files, naming one.
    let again = host_tool(dir, &[&["render", "--frames", "3", "--out-dir", "seq"][..], &scene].concat());
    assert_eq!(again.status.code(), Some(17));
    assert!(String::from_utf8_lossy(&again.stderr).contains("exists"));
}

#[test]
fn a_sequence_refuses_single_frame_outputs_and_zero_frames() {
    fails("zero-frames", &["render", "--frames", "0"], None, 17, "--frames");
    fails("seq-out", &["render", "--frames", "2", "--out", "x.png"], None, 17, "--out-dir");
    fails("seq-orbit", &["render", "--frames", "2", "--orbit", "inf"], None, 17, "--orbit");
    let keys = r#"{"grid": [8, 8, 8], "spheres": [{"center": [4, 4, 4], "radius": 1}],
        "keyframes": [{"frame": 4, "camera": {"eye": [4, 4, -9], "look_at": [4, 4, 4]}},
                      {"frame": 2, "camera": {"eye": [4, 5, -9], "look_at": [4, 4, 4]}}]}"#;
    fails(
        "keys-order",
        &["render", "--scene", "scene.json", "--frames", "2"],
        Some(keys),
        17,
        "increasing frame order",
    );
}
