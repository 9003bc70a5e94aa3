//! Serial faults that happen on real desks, over pseudo-terminals: a board's
//! device closing mid-render (unplugged, reset, its adapter gone) and garbage
//! bytes on a host link mid-render (a noisy cable, a board printing a boot
//! banner). `host-tool render --backend serial` runs against software boards:
//! the node firmware (`node-fw`, the code the boards run) behind one pty per
//! node, neighbour links in memory. The host must name the node, exit with
//! the documented code and write nothing, or, for garbage its CRC catches,
//! render the same image; and it must never hang.

use std::io::{Read, Write};
use std::os::fd::{AsRawFd, RawFd};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use node_fw::framed::FramedLinks;
use node_fw::{Port, wiring};
use serialport::{SerialPort, TTYPort};
use sim_board::SimNode;

/// One set of software boards at a time: a host process started by one test
/// inherits every pty open in this process at that moment, and would keep
/// another test's closed device from hanging up.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Microseconds without an acknowledgement before a board's channel resends.
const RESEND_AFTER_US: u64 = 50_000;

/// What goes wrong on one node's host link once it has traced `after` rays
/// of the frame (mid-render: the scene is loaded and retirements flow).
#[derive(Debug, Clone, Copy)]
enum Fault {
    None,
    /// The board's end of the device closes.
    Close {
        node: usize,
        after: usize,
    },
    /// Bursts of garbage bytes go both ways on the link, four times.
    Garbage {
        node: usize,
        after: usize,
    },
    /// The node stops working, while its links still acknowledge (and drop)
    /// everything: an array that answers but makes no progress.
    Deaf {
        node: usize,
        after: usize,
    },
}

/// Software boards: node-fw nodes on one thread, each node's host port on a pty.
struct SoftBoards {
    /// The device the host opens for each node.
    paths: Vec<String>,
    /// The boards' ends of the ptys: a host process started from this one
    /// must not inherit them (a pty hangs up only when every copy of its
    /// board's end is closed, and no real host holds one).
    board_fds: Vec<RawFd>,
    /// Kept open so a board's writes never fail before the host opens its end.
    _slaves: Vec<TTYPort>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl SoftBoards {
    fn launch(array: [u16; 3], fault: Fault) -> Self {
        let nodes: usize = array.iter().map(|&n| usize::from(n)).product();
        let (masters, slaves): (Vec<TTYPort>, Vec<TTYPort>) =
            (0..nodes).map(|_| TTYPort::pair().expect("a pty pair")).unzip();
        let paths = slaves.iter().map(|s| s.name().expect("pty has a name")).collect();
        let board_fds = masters.iter().map(AsRawFd::as_raw_fd).collect();
        let stop = Arc::new(AtomicBool::new(false));
        let halt = stop.clone();
        // A node is about a megabyte: built on a thread with a large stack.
        let thread = std::thread::Builder::new()
            .stack_size(64 << 20)
            .spawn(move || run_boards(array, masters, fault, &halt))
            .expect("board thread");
        Self { paths, board_fds, _slaves: slaves, stop, thread: Some(thread) }
    }
}

impl Drop for SoftBoards {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The boards' loop: bytes in from each pty, one poll per node, bytes out,
/// neighbour bytes handed across in memory.
fn run_boards(array: [u16; 3], masters: Vec<TTYPort>, fault: Fault, stop: &AtomicBool) {
    let nodes = masters.len();
    let mut masters: Vec<Option<TTYPort>> = masters.into_iter().map(Some).collect();
    let mut node: Vec<Box<SimNode>> = (0..nodes).map(|i| Box::new(SimNode::new(i as u16))).collect();
    // Each software board names itself, as real ones do, so the host checks
    // their cables (in memory, right by construction) before rendering.
    for (i, n) in node.iter_mut().enumerate() {
        n.set_board(sim_board::board::board_info(i));
    }
    let mut links: Vec<Box<FramedLinks<8, 16>>> = (0..nodes)
        .map(|i| {
            let mut l = Box::new(FramedLinks::new(RESEND_AFTER_US));
            l.set_incarnation(i as u32 + 1);
            l
        })
        .collect();
    let mut to_host: Vec<Vec<u8>> = vec![Vec::new(); nodes];
    let mut bursts = 0;
    let started = Instant::now();
    let mut buf = vec![0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        let now = started.elapsed().as_micros() as u64;
        let mut busy = false;
        let mut wire: Vec<(usize, Port, Vec<u8>)> = Vec::new();
        for i in 0..nodes {
            if let Some(m) = masters[i].as_mut()
                && m.bytes_to_read().unwrap_or(0) > 0
                && let Ok(n) = m.read(&mut buf)
            {
                links[i].ingest(Port::Host, &buf[..n]);
                busy |= n > 0;
            }
            if matches!(fault, Fault::Deaf { node: k, after } if k == i && traced(&node[k]) > after) {
                for port in Port::ALL {
                    while node_fw::Links::recv(&mut *links[i], port).is_some() {}
                }
            } else {
                busy |= node[i].poll(now, &mut *links[i]).is_busy();
            }
            links[i].transmit(now, |port, bytes| {
                match port {
                    Port::Host => to_host[i].extend_from_slice(bytes),
                    p => {
                        if let Some(j) = wiring::neighbour_of(i, p, array) {
                            wire.push((usize::from(j), p.opposite(), bytes.to_vec()));
                        }
                    }
                }
                true
            });
            if let Some(m) = masters[i].as_mut()
                && !to_host[i].is_empty()
                && let Ok(n) = m.write(&to_host[i])
            {
                to_host[i].drain(..n);
                busy |= n > 0;
            }
        }
        for (j, port, bytes) in wire {
            links[j].ingest(port, &bytes);
        }
        match fault {
            Fault::Close { node: k, after } if traced(&node[k]) > after && masters[k].is_some() => {
                masters[k] = None;
            }
            Fault::Garbage { node: k, after } if bursts < 4 && traced(&node[k]) > after + bursts * 40 => {
                // Bytes no frame can be made of, then half a frame's
                // delimiter pattern: the CRC and resends must absorb both.
                let garbage: Vec<u8> = (0..97u32).map(|b| (b * 151 + 7) as u8).collect();
                if let Some(m) = masters[k].as_mut() {
                    let _ = m.write_all(&garbage);
                }
                links[k].ingest(Port::Host, &garbage);
                bursts += 1;
            }
            _ => {}
        }
        if !busy {
            std::thread::sleep(Duration::from_micros(100));
        }
    }
}

/// Rays node has traced in this frame.
fn traced(node: &SimNode) -> usize {
    node.totals().rays as usize
}

const SCENE: [&str; 8] = ["--spheres", "30", "--seed", "3", "--grid", "12x12x12", "--size", "32x32"];
const OUTPUTS: [(&str, &str); 6] = [
    ("--out", "render.png"),
    ("--plot", "loads.png"),
    ("--loads", "loads.csv"),
    ("--summary", "summary.json"),
    ("--load-history", "load-history.csv"),
    ("--boundary-history", "boundary-history.csv"),
];

/// Runs `host-tool render` with `extra` arguments and every output in `dir`,
/// with the file descriptors `closed` closed (through bash, which closes them
/// before it becomes host-tool); kills it (and fails) after a minute. Returns
/// the exit code and stderr.
fn render(dir: &Path, extra: &[&str], closed: &[RawFd]) -> (Option<i32>, String) {
    let mut args: Vec<String> = ["render", "--array", "2x2x1"].iter().map(|s| s.to_string()).collect();
    args.extend(SCENE.iter().chain(extra).map(|s| s.to_string()));
    for (flag, file) in OUTPUTS {
        args.push(flag.into());
        args.push(dir.join(file).display().to_string());
    }
    let closing: Vec<String> = closed.iter().map(|fd| format!("{fd}<&-")).collect();
    let mut child = Command::new("bash")
        .arg("-c")
        .arg(format!("exec \"$0\" \"$@\" {}", closing.join(" ")))
        .arg(env!("CARGO_BIN_EXE_host-tool"))
        .args(&args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("host-tool runs");
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("waits") {
            break status;
        }
        if started.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("host-tool hung: still running after a minute ({args:?})");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    child.stderr.take().expect("stderr").read_to_string(&mut err).expect("stderr is text");
    (status.code(), err)
}

fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("host-tool-serial-{name}-")).tempdir().unwrap()
}

fn serial_render(dir: &Path, boards: &SoftBoards) -> (Option<i32>, String) {
    let ports = boards.paths.join(",");
    render(dir, &["--backend", "serial", "--node-timeout", "5", "--ports", &ports], &boards.board_fds)
}

/// The image the in-memory board renders for the same scene and array.
fn in_memory_image() -> Vec<u8> {
    let dir = scratch("memory");
    let (code, err) = render(dir.path(), &[], &[]);
    assert_eq!(code, Some(0), "in-memory render: {err}");
    std::fs::read(dir.path().join("render.png")).expect("image written")
}

#[test]
fn software_boards_over_ptys_render_the_in_memory_image() {
    let _one = one_at_a_time();
    let boards = SoftBoards::launch([2, 2, 1], Fault::None);
    let dir = scratch("clean");
    let (code, err) = serial_render(dir.path(), &boards);
    assert_eq!(code, Some(0), "{err}");
    let image = std::fs::read(dir.path().join("render.png")).expect("image written");
    assert!(image == in_memory_image(), "the serial image differs from the in-memory board's");
}

#[test]
fn a_device_closed_mid_render_names_its_node_and_writes_nothing() {
    let _one = one_at_a_time();
    // Node 2's device closes once it has traced 100 rays. The host must see
    // the hang-up, not wait out its time-out.
    let boards = SoftBoards::launch([2, 2, 1], Fault::Close { node: 2, after: 100 });
    let dir = scratch("closed");
    let started = Instant::now();
    let (code, err) = serial_render(dir.path(), &boards);
    assert_eq!(code, Some(30), "{err}");
    assert!(err.contains("node 2 (0,1,0)"), "the node is named: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "nothing written, found {left:?}");
    assert!(started.elapsed() < Duration::from_secs(5), "took the time-out ({:?}): {err}", started.elapsed());
    eprintln!("after {:?}: {}", started.elapsed(), err.trim_end());
}

#[test]
fn garbage_on_a_host_link_mid_render_costs_resends_not_the_image() {
    let _one = one_at_a_time();
    let boards = SoftBoards::launch([2, 2, 1], Fault::Garbage { node: 1, after: 20 });
    let dir = scratch("garbage");
    let (code, err) = serial_render(dir.path(), &boards);
    assert_eq!(code, Some(0), "{err}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
    assert!(
        summary["corrupted_frames"].as_u64().is_some_and(|n| n > 0),
        "the host saw the garbage: {summary}"
    );
    eprintln!(
        "garbage: {} corrupted frames, {} resent",
        summary["corrupted_frames"], summary["retransmissions"]
    );
    let image = std::fs::read(dir.path().join("render.png")).expect("image written");
    assert!(image == in_memory_image(), "garbage changed the image");
}

#[test]
fn an_array_that_answers_but_makes_no_progress_is_given_up_on() {
    let _one = one_at_a_time();
    // Node 3 goes deaf after 50 rays: every frame is still acknowledged, so
    // no node looks silent, but nothing comes back.
    let boards = SoftBoards::launch([2, 2, 1], Fault::Deaf { node: 3, after: 50 });
    let dir = scratch("deaf");
    let started = Instant::now();
    let ports = boards.paths.join(",");
    let args = ["--backend", "serial", "--node-timeout", "2", "--ports", &ports];
    let (code, err) = render(dir.path(), &args, &boards.board_fds);
    assert_eq!(code, Some(30), "{err}");
    assert!(err.contains("stopped making progress"), "{err}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "nothing written, found {left:?}");
    // Three node time-outs of silence, not a minute.
    assert!(started.elapsed() < Duration::from_secs(20), "gave up after {:?}", started.elapsed());
}
