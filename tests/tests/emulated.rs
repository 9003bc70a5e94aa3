//! The node firmware on emulated boards: 2x2x2 arrays of QEMU mps2-an385 and
//! netduinoplus2 (STM32) instances render the same image as the in-memory
//! board, and a node that stops answering is named.
//!
//! Needs `qemu-system-arm` and the firmware (`scripts/firmware.sh`); the
//! test command (`scripts/test.sh`) installs and builds both first.

use std::path::PathBuf;
use std::process::Command;
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

use host_tool::error::HostError;
use host_tool::plan::Plan;
use host_tool::plan::options::RenderOptions;
use host_tool::results::RenderResult;
use host_tool::results::files::link_troubles;
use host_tool::scene::Scene;
use host_tool::session::backend::{Backend, Rendered};
use host_tool::session::clock::HostMicros;
use host_tool::session::qemu::{EmulatedBoard, Launch, QEMU, QemuArray};
use host_tool::session::serial::SerialArray;
use host_tool::session::sim::render_sim;
use host_tool::session::transport::Transport;
use link_proto::{Balance, SlidePolicy};
use node_fw::Port;

/// Renders on the emulated boards of `backend`: their times are the host's.
fn render(
    s: &Scene,
    opts: &RenderOptions,
    backend: &Backend,
    node_timeout: Duration,
) -> Result<RenderResult<HostMicros>, HostError> {
    match host_tool::session::backend::render(s, opts, backend, node_timeout)? {
        Rendered::Boards(r) => Ok(r),
        Rendered::Sim(_) => panic!("{backend:?} rendered on the in-memory board"),
    }
}

/// One QEMU array at a time: eight emulators already fill both cores, and a
/// test's node time-out must not fire because another test's array is busy.
static ONE_ARRAY: Mutex<()> = Mutex::new(());

fn one_array() -> MutexGuard<'static, ()> {
    ONE_ARRAY.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn firmware(board: EmulatedBoard) -> PathBuf {
    let elf = board.default_firmware();
    assert!(elf.is_file(), "{} is missing: run scripts/firmware.sh (scripts/test.sh does)", elf.display());
    let qemu = Command::new(QEMU).arg("--version").output();
    assert!(
        qemu.is_ok_and(|o| o.status.success()),
        "{QEMU} is missing: apt-get install qemu-system-arm (scripts/test.sh does)"
    );
    elf
}

fn scene() -> Scene {
    Scene::random(24, 7, 1.0, [12, 12, 12]).expect("valid scene")
}

fn options(balance: Option<Balance>) -> RenderOptions {
    let mut opts = RenderOptions::new([2, 2, 2]);
    opts.size = [24, 24];
    opts.level_depth = 1;
    opts.balance = balance;
    opts
}

/// Sliding on emulated boards. Emulated nodes idle in real time (virtual
/// time follows the host's clock while they sleep), so their loads are
/// small: a fortieth of a second and a load difference of 1% let
/// boundaries slide there. A busy emulated node's clock falls behind the
/// host's, so the two sides' interval indices drift apart by tens of
/// intervals within a frame; while the nodes compared only loads of the
/// same index, CI saw three tries without a slide (now 12-19 slides a try).
const SLIDING: Balance =
    Balance { interval: 25_000_000, threshold: 655, step: 1, policy: SlidePolicy::Paper };

/// Renders the test frame on an `array` of `board` with each of `balances`
/// and compares each with the in-memory board.
///
/// Whether a boundary slides on emulated boards depends on wall-clock time
/// (an idle node's virtual time follows the host's clock), and on a loaded
/// machine a frame sometimes ends before any node is idle enough: a render
/// with sliding is tried up to [`SLIDING_TRIES`] times until one slides,
/// and every try must match the in-memory board.
fn matches_the_in_memory_board(board: EmulatedBoard, array: [u16; 3], balances: &[Option<Balance>]) {
    let _one = one_array();
    let backend = Backend::Qemu { board, firmware: firmware(board) };
    let s = scene();
    for &balance in balances {
        let mut opts = options(balance);
        opts.array = array;
        let memory = render_sim(&s, &opts).expect("in-memory render");
        let tries = if balance.is_some() { SLIDING_TRIES } else { 1 };
        let mut slides = Vec::new();
        for _ in 0..tries {
            let started = std::time::Instant::now();
            let qemu = render(&s, &opts, &backend, Duration::from_secs(30))
                .unwrap_or_else(|e| panic!("{} render ({balance:?}): {e}", board.name()));
            let [x, y, z] = array;
            eprintln!("{} {x}x{y}x{z} ({balance:?}): {:.1} s", board.name(), started.elapsed().as_secs_f64());
            assert_eq!(qemu.frame.rays_created, qemu.frame.rays_terminated, "every ray accounted for");
            assert_eq!(qemu.frame.rays_created, memory.frame.rays_created);
            assert!(
                qemu.frame.sums == memory.frame.sums,
                "pixel sums differ from the in-memory board ({balance:?})"
            );
            assert!(qemu.frame.loads.iter().all(Option::is_some), "every node reported its load");
            slides.push(qemu.frame.slides.len());
            if balance.is_none() || !qemu.frame.slides.is_empty() {
                break;
            }
        }
        if balance.is_some() {
            eprintln!("{} with sliding: slides committed per try {slides:?}", board.name());
            assert!(slides.iter().any(|&n| n > 0), "{}: no boundary slid in {tries} tries", board.name());
        }
    }
}

/// Renders with sliding tried before a test says the emulated boards never
/// slide (see [`matches_the_in_memory_board`]).
const SLIDING_TRIES: usize = 3;

#[test]
fn an_mps2_array_matches_the_in_memory_board() {
    matches_the_in_memory_board(EmulatedBoard::Mps2An385, [2, 2, 2], &[None, Some(SLIDING)]);
}

#[test]
fn an_stm32_array_matches_the_in_memory_board() {
    matches_the_in_memory_board(EmulatedBoard::Netduinoplus2, [2, 2, 2], &[None, Some(SLIDING)]);
}

/// The centre node of a 3x3x3 array uses all six neighbour links, which
/// only the STM32 board has. 27 emulators on two cores: about ten
/// seconds each, static and sliding (docs/boards.md).
#[test]
fn a_3x3x3_stm32_array_matches_the_in_memory_board() {
    matches_the_in_memory_board(EmulatedBoard::Netduinoplus2, [3, 3, 3], &[None, Some(SLIDING)]);
}

/// The in-memory board with the emulated boards' links charges each node
/// about what the emulated board spends (instructions on the emulated
/// Cortex-M3, cycles on the in-memory board: the same unit under `-icount
/// shift=0`). An emulated node's passes depend on when bytes arrive, so one
/// run's busiest node varies by a few percent: measured 2.25e6-2.32e6
/// instructions over 5 runs, charged 2.43e6 (+6.4% on their median; the
/// loop's pass is chosen between two frames' fits, see
/// `LinkPreset::loop_pass`). The median of five runs is what is compared;
/// without the loop's pass the board charges 56% too little.
#[test]
fn the_in_memory_board_predicts_the_busiest_emulated_node() {
    let _one = one_array();
    let board = EmulatedBoard::Mps2An385;
    let s = scene();
    let mut opts = options(None);
    opts.sim = sim_board::SimConfig::with_links([2, 2, 2], sim_board::LinkPreset::Emulated);
    let busiest = |loads: &[Option<link_proto::LoadReport>]| {
        loads.iter().map(|l| l.expect("every node reported its load").running).max().unwrap_or(0)
    };
    let memory = busiest(&render_sim(&s, &opts).expect("in-memory render").frame.loads);
    let backend = Backend::Qemu { board, firmware: firmware(board) };
    let mut runs: Vec<u64> = (0..5)
        .map(|_| {
            busiest(&render(&s, &opts, &backend, Duration::from_secs(30)).expect("qemu render").frame.loads)
        })
        .collect();
    runs.sort_unstable();
    let emulated = runs[2];
    let gap = memory.abs_diff(emulated) as f64 / emulated as f64;
    eprintln!(
        "busiest node: emulated {runs:?} (median {emulated}), in-memory {memory} ({:+.1}%)",
        100.0 * (memory as f64 / emulated as f64 - 1.0)
    );
    assert!(
        gap < 0.15,
        "busiest node: emulated {emulated} instructions (median of {runs:?}), the in-memory board charges {memory}"
    );
}

/// One host session on running boards: connect, check, render.
fn session(ptys: &[String], s: &Scene, opts: &RenderOptions) -> RenderResult<HostMicros> {
    let names = (0..ptys.len()).map(|i| format!("node {i}")).collect();
    let mut array = SerialArray::open(ptys, names, Duration::from_secs(30)).expect("ptys open");
    array.connect().expect("every node says hello");
    let plan = Plan::new(s, opts, array.capacity()).expect("the frame fits the boards");
    host_tool::session::run(&mut array, s, &plan).unwrap_or_else(|e| panic!("render: {e}"))
}

#[test]
fn a_new_host_session_starts_the_running_boards_over() {
    let _one = one_array();
    let board = EmulatedBoard::Mps2An385;
    let s = scene();
    let opts = options(None);
    let memory = render_sim(&s, &opts).expect("in-memory render");
    let qemu = QemuArray::launch(board, opts.array, &firmware(board)).expect("emulators start");
    // Two host runs against the same boards: the second comes with a new
    // incarnation on every link, and each node drops the first run's state.
    for run in 0..2 {
        let result = session(&qemu.ptys, &s, &opts);
        assert!(
            result.frame.sums == memory.frame.sums,
            "run {run}: pixel sums differ from the in-memory board"
        );
        assert_eq!(result.frame.rays_created, memory.frame.rays_created, "run {run}");
    }
}

#[test]
fn a_frozen_node_is_named_after_the_time_out() {
    let _one = one_array();
    let board = EmulatedBoard::Mps2An385;
    let s = scene();
    let opts = options(None);
    let qemu = QemuArray::launch(board, opts.array, &firmware(board)).expect("emulators start");
    let names = (0..8).map(|i| format!("node {i}")).collect();
    // Long enough that eight emulators starving on two cores are not taken
    // for dead; far below the test's bound.
    let mut array = SerialArray::open(&qemu.ptys, names, Duration::from_secs(8)).expect("ptys open");
    array.connect().expect("every node says hello");
    let plan = Plan::new(&s, &opts, array.capacity()).expect("the frame fits the boards");
    // Freeze node 5: its pty stays open, but it never answers again.
    let pid = qemu.pid(5).expect("node 5 runs").to_string();
    assert!(Command::new("kill").args(["-STOP", &pid]).status().is_ok_and(|s| s.success()));
    let started = std::time::Instant::now();
    let err = match host_tool::session::run(&mut array, &s, &plan) {
        Ok(_) => panic!("a render with a frozen node cannot finish"),
        Err(e) => e,
    };
    let _ = Command::new("kill").args(["-CONT", &pid]).status();
    assert_eq!(err.exit_code(), 30, "{err}");
    assert!(err.to_string().contains("node 5") && err.to_string().contains("stopped answering"), "{err}");
    assert!(started.elapsed() < Duration::from_secs(60), "gave up in {:?}", started.elapsed());
}

/// Opens the boards behind `ptys` and waits for their hellos.
fn connect(ptys: &[String]) -> SerialArray {
    let mut array = SerialArray::open(ptys, ptys.to_vec(), Duration::from_secs(30)).expect("ptys open");
    array.connect().expect("every node says hello");
    array
}

#[test]
fn a_crossed_cable_is_named_before_anything_renders() {
    let _one = one_array();
    let board = EmulatedBoard::Netduinoplus2;
    let array = [2, 2, 2];
    // Node 0's +X and +Y cables plugged into each other's sockets: its +X
    // port reaches node 2 (whose -Y cable it holds), its +Y port node 1.
    let crossed = [((0, Port::PosX), (0, Port::PosY))];
    let how = Launch { crossed: &crossed, ..Launch::default() };
    let qemu = QemuArray::launch_with(board, array, &firmware(board), how).expect("emulators start");
    let err = connect(&qemu.ptys).check_cabling(array).expect_err("a crossed cable is found");
    assert_eq!(err.exit_code(), 32, "{err}");
    let want = format!("node 0 (0,0,0) on {}: its +X and +Y cables are swapped", qemu.ptys[0]);
    assert_eq!(err.to_string(), want);
    // The same boards listed: every other cable is right.
    let listing =
        host_tool::session::boards::list(&qemu.ptys, Some(array), Duration::from_secs(10)).expect("listed");
    assert!(listing.contains("not cabled as a 2x2x2 array"), "{listing}");
    assert_eq!(listing.matches(": its ").count(), 1, "one fault: {listing}");
}

#[test]
fn the_host_puts_shuffled_ports_in_array_order_by_the_cables() {
    let _one = one_array();
    let board = EmulatedBoard::Netduinoplus2;
    let array = [2, 2, 2];
    let qemu = QemuArray::launch(board, array, &firmware(board)).expect("emulators start");
    let mut shuffled = qemu.ptys.clone();
    shuffled.reverse();
    shuffled.swap(2, 5);
    let err = connect(&shuffled).check_cabling(array).expect_err("the order given is not the array's");
    let want = format!("in array order: --ports {} (or add --order-ports)", qemu.ptys.join(","));
    assert!(err.to_string().ends_with(&want), "{err}");
    let mut boards = connect(&shuffled);
    assert_eq!(boards.order_by_cabling(array).expect("an order fits"), qemu.ptys);
    boards.check_cabling(array).expect("in order now");
    // Each board names itself with the id the host gave it.
    let ids: Vec<_> = boards.hellos().iter().map(|h| h.expect("said hello").board.id).collect();
    assert_eq!(ids, qemu.ids);
}

/// The writes to a board's user LEDs in its emulator's log, as (light, lit)
/// pairs in order: 0 is the working light, 1 the fault light.
fn light_writes(board: EmulatedBoard, log: &str) -> Vec<(usize, bool)> {
    let field = |line: &str, key: &str| {
        let value = line.split(key).nth(1)?.split([' ', ')', ',']).next()?;
        u32::from_str_radix(value.trim_start_matches("0x"), 16).ok()
    };
    let mut writes = Vec::new();
    for line in log.lines() {
        match board {
            // FPGAIO LED0: bit 0 working, bit 1 fault; each write sets both.
            EmulatedBoard::Mps2An385 if line.starts_with("mps2_fpgaio_write") => {
                if let (Some(0), Some(data)) = (field(line, "offset "), field(line, "data ")) {
                    writes.extend([(0, data & 1 != 0), (1, data & 2 != 0)]);
                }
            }
            // GPIOB BSRR: bit n sets pin n, bit n + 16 resets it; PB0 green, PB14 red.
            EmulatedBoard::Netduinoplus2 if line.starts_with("GPIOB: unimplemented device write") => {
                if let (Some(0x18), Some(v)) = (field(line, "offset "), field(line, "value ")) {
                    for (light, pin) in [(0, 0), (1, 14)] {
                        if v & (1 << pin) != 0 {
                            writes.push((light, true));
                        }
                        if v & (1 << (pin + 16)) != 0 {
                            writes.push((light, false));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    writes
}

#[test]
fn the_lights_show_work_and_waiting_and_no_fault() {
    let _one = one_array();
    let s = scene();
    let mut opts = options(None);
    opts.array = [2, 1, 1];
    for board in EmulatedBoard::ALL {
        let how = Launch { log_lights: true, ..Launch::default() };
        let qemu = QemuArray::launch_with(board, opts.array, &firmware(board), how).expect("emulators start");
        session(&qemu.ptys, &s, &opts);
        for node in 0..2 {
            let writes = light_writes(board, &qemu.log(node));
            let working: Vec<bool> = writes.iter().filter(|w| w.0 == 0).map(|w| w.1).collect();
            // Dark at start, then lit for each stretch of work and dark
            // again while waiting: many times over a frame.
            assert_eq!(working.first(), Some(&false), "{} node {node}", board.name());
            let lit = working.windows(2).filter(|w| !w[0] && w[1]).count();
            assert!(lit >= 10, "{} node {node}: the working light came on {lit} times", board.name());
            assert!(
                writes.iter().all(|&(light, on)| light == 0 || !on),
                "{} node {node}: the fault light came on",
                board.name()
            );
        }
    }
}

#[test]
fn a_panicking_board_says_where_and_the_host_passes_it_on() {
    let _one = one_array();
    let board = EmulatedBoard::Mps2An385;
    let elf = firmware(board).with_file_name("fault-check-mps2-an385.elf");
    let mut opts = options(None);
    opts.array = [1, 1, 1];
    let backend = Backend::Qemu { board, firmware: elf };
    let err = match render(&scene(), &opts, &backend, Duration::from_secs(5)) {
        Ok(_) => panic!("a firmware that panics cannot render"),
        Err(e) => e,
    };
    let text = err.to_string();
    assert!(text.contains("node firmware panicked at src/bin/fault_check.rs:"), "{text}");
}

/// The fault injector that the in-memory board uses, on the emulated
/// boards' links: every frame between the boards and to the host may be
/// corrupted, dropped, duplicated or delayed, and the image is the clean one.
#[test]
fn emulated_boards_under_link_faults_render_the_clean_image() {
    let _one = one_array();
    let board = EmulatedBoard::Mps2An385;
    let s = scene();
    let clean = render_sim(&s, &options(None)).expect("in-memory render");
    let mut opts = options(None);
    opts.sim.faults = Some(sim_board::Faults { corrupt: 0.02, drop: 0.02, dup: 0.01, delay: 0.01, seed: 11 });
    let backend = Backend::Qemu { board, firmware: firmware(board) };
    let started = std::time::Instant::now();
    let faulty =
        render(&s, &opts, &backend, Duration::from_secs(30)).unwrap_or_else(|e| panic!("render: {e}"));
    eprintln!(
        "mps2-an385 2x2x2 under faults: {:.1} s, host links {:?}",
        started.elapsed().as_secs_f64(),
        faulty.links
    );
    assert!(faulty.frame.sums == clean.frame.sums, "the faults changed the image");
    assert_eq!(faulty.frame.rays_created, faulty.frame.rays_terminated, "every ray accounted for");
    // The faults happened: the host's channels saw damaged frames. (Whether
    // the host itself resends is chance: its few frames, many messages to a
    // batch, may all get through; one run in test.sh's debug build resent
    // none. The boards' resends, over thousands of frames, are checked next.)
    assert!(faulty.links.corrupted > 0, "{:?}", faulty.links);
    // And the boards told the host of the damage they took, which the host
    // sees no other way.
    let told = link_troubles(&faulty);
    assert!(told.damaged > 0 && told.resent > 0, "{told:?}");
    // QEMU holds bytes back until a board reads them: its UARTs never
    // overrun, so a board telling of lost bytes would misread its UART.
    assert_eq!(told.lost, 0, "{told:?}");
}

/// A sequence on emulated boards: three orbiting frames with the boundaries
/// carried (sliding), a sphere that moves before the third so the boards are
/// sent the scene again mid-session, each frame's image the in-memory
/// board's single-frame render of its camera with the sphere put in place.
#[test]
fn an_emulated_sequence_matches_single_frames() {
    use host_tool::scene::path::{CameraPath, SphereKeyframe};
    use host_tool::session::clock::Clock;
    use host_tool::session::sequence::{FrameSink, FrameStart, Sequence, SequenceFrame};

    /// Keeps each frame's sums and whether the scene was sent for it.
    #[derive(Default)]
    struct Kept(Vec<(Vec<[u64; 3]>, bool, usize)>);
    impl FrameSink for Kept {
        fn take<T: Clock>(&mut self, f: SequenceFrame<T>) -> Result<(), HostError> {
            let r = &f.result.frame;
            assert_eq!(r.rays_created, r.rays_terminated, "frame {}: every ray accounted for", f.number);
            self.0.push((r.sums.clone(), f.loaded, r.slides.len()));
            Ok(())
        }
    }

    let _one = one_array();
    let board = EmulatedBoard::Mps2An385;
    let backend = Backend::Qemu { board, firmware: firmware(board) };
    let mut s = scene();
    let (from, to) = ([2.0, 3.0, 4.0], [9.0, 8.0, 6.0]);
    s.spheres[3].center = from;
    s.sphere_keyframes = vec![
        SphereKeyframe { sphere: 3, frame: 1, center: from },
        SphereKeyframe { sphere: 3, frame: 2, center: to },
    ];
    s.validate().expect("valid scene");
    let opts = options(Some(SLIDING));
    let path = CameraPath::Orbit { degrees: 60.0 };
    let sequence = Sequence { frames: 3, path, start: FrameStart::Carried };
    let mut kept = Kept::default();
    host_tool::session::backend::render_sequence(
        &s,
        &opts,
        &backend,
        Duration::from_secs(30),
        &sequence,
        &mut kept,
    )
    .unwrap_or_else(|e| panic!("sequence: {e}"));
    assert_eq!(kept.0.len(), 3);
    for (k, (sums, loaded, slides)) in kept.0.iter().enumerate() {
        let mut at = s.clone();
        at.camera = Some(path.camera(&s, k as u32, 3));
        at.sphere_keyframes.clear();
        at.spheres[3].center = if k < 2 { from } else { to };
        let single = render_sim(&at, &options(None)).expect("in-memory render");
        assert!(*sums == single.frame.sums, "frame {k} differs from its single-frame render");
        assert_eq!(*loaded, k != 1, "frame {k}: the scene is sent first and where the sphere moved");
        eprintln!("emulated sequence frame {k}: {slides} slides");
    }
}
