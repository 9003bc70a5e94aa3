//! `host-tool`: render on the in-memory array, render the f64 reference, compare.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};
use host_tool::args::{
    AxisChoice, LinkArgs, SceneArgs, load_scene, load_scene_for, node_timeout, parse_faults, parse_triple,
    scene_source, usage_error,
};
use host_tool::compare::compare;
use host_tool::error::{HostError, input};
use host_tool::plan::options::{Initial, Layout, RenderOptions};
use host_tool::results::RenderResult;
use host_tool::results::files::{
    Provenance, boundary_history_csv, history_plot, imbalance, link_warning, load_history_csv, loads_csv,
    summary_json,
};
use host_tool::results::output::{
    check_png_name, check_writable, png, refuse_overwrite, write_all_atomic, write_atomic,
};
use host_tool::results::sequence::{SequenceFiles, SequenceWriter};
use host_tool::scene::Scene;
use host_tool::scene::SceneFormat;
use host_tool::scene::path::CameraPath;
use host_tool::session::backend::{Backend, Rendered};
use host_tool::session::clock::Clock;
use host_tool::session::qemu::EmulatedBoard;
use host_tool::session::sequence::{FrameStart, Sequence};
use host_tool::{plan::direct, reference};
use link_proto::{Balance, SlidePolicy};

#[derive(Parser)]
#[command(
    name = "host-tool",
    version,
    about = "Host of the sliding-boundary ray tracer (Nemoto & Omachi, 1986)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render on an array of nodes (in memory, emulated or real); write the image, per-node loads and a summary.
    Render(Box<RenderArgs>),
    /// List the boards on serial devices (or emulated ones) without rendering:
    /// id, firmware and protocol version, capacities, clock, baud rates and cables.
    Boards(BoardsArgs),
    /// Write a scene (the demo, a random one, or a scene file converted) as JSON or NFF, by --out's extension.
    Scene(SceneOutArgs),
    /// Render the same scene with the independent f64 reference renderer.
    Reference(ReferenceArgs),
    /// Render with the fixed-point kernels and the f64 reference; print the comparison as JSON.
    Compare(SceneArgs),
}

#[derive(Clone, Copy, ValueEnum)]
enum InitialMode {
    /// Every node creates the rays of a regular sub-image and passes each to
    /// the node where it enters (the paper's parallel mode).
    Parallel,
    /// The node holding the eye creates all of them.
    Eye,
    /// The nodes on the face toward the eye, and on a side face it sees at an
    /// angle, create the rays entering through their part of it, so rays
    /// start where they are traced (beyond the paper).
    Entry,
}

#[derive(Clone, Copy, ValueEnum)]
enum LayoutMode {
    /// Even boxes (the paper's start).
    Even,
    /// Fitted to the cost of a half-resolution preview the host renders
    /// first (beyond the paper).
    Preview,
}

#[derive(Clone, Copy, ValueEnum)]
enum BalanceMode {
    /// No redistribution: the even partition throughout.
    Static,
    /// The paper's sliding boundary surfaces.
    Slide,
}

#[derive(Clone, Copy, ValueEnum)]
enum FrameStartChoice {
    /// Where the frame before ended: slid boundaries stay where they slid.
    Carried,
    /// Afresh from each frame's camera, as --layout says (preview: a fit per frame).
    Planned,
}

#[derive(Clone, Copy, ValueEnum)]
enum PolicyChoice {
    /// One cube when one load is lower and under the threshold (the paper's).
    Paper,
    /// Proportional to the running-time difference, under-relaxed, capped, with a dead band.
    Proportional,
}

#[derive(Args)]
struct SceneOutArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Where to write it: FILE.json or FILE.nff.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
}

#[derive(Args)]
struct BoardsArgs {
    /// Serial devices of the boards, comma- or space-separated, in any order.
    #[arg(long, value_name = "DEV,DEV,...", value_delimiter = ',', num_args = 1.., required_unless_present = "emulate")]
    ports: Vec<String>,
    /// The array the boards should form: check their cables and print the
    /// order to list the devices in for `render --ports`.
    #[arg(long, value_name = "XxYxZ", value_parser = parse_triple)]
    array: Option<[u16; 3]>,
    /// List an emulated array of this board (one per node of --array) instead of --ports.
    #[arg(long, value_enum, conflicts_with = "ports", requires = "array")]
    emulate: Option<BoardChoice>,
    /// Node firmware ELF for --emulate [default: the board's image from scripts/firmware.sh].
    #[arg(long, value_name = "ELF", requires = "emulate")]
    firmware: Option<PathBuf>,
    /// Seconds a board may take to say hello.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0)]
    node_timeout: f64,
}

#[derive(Clone, Copy, ValueEnum)]
enum BoardChoice {
    /// ARM's mps2-an385 (Cortex-M3, four neighbour UARTs): the small-MCU image.
    #[value(name = "mps2-an385")]
    Mps2An385,
    /// An STM32F405 model with the F413's six neighbour U(S)ARTs: the STM32 image.
    Netduinoplus2,
}

impl From<BoardChoice> for EmulatedBoard {
    fn from(choice: BoardChoice) -> Self {
        match choice {
            BoardChoice::Mps2An385 => EmulatedBoard::Mps2An385,
            BoardChoice::Netduinoplus2 => EmulatedBoard::Netduinoplus2,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum BackendChoice {
    /// The in-memory board (deterministic virtual time).
    Sim,
    /// One emulated board per node (--board) running the node firmware.
    Qemu,
    /// Real boards on the serial devices given by --ports.
    Serial,
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    links: LinkArgs,
    /// What runs the nodes.
    #[arg(long, value_enum, default_value = "sim")]
    backend: BackendChoice,
    /// Serial devices of the nodes in node order (x fastest), comma- or space-separated (--backend serial).
    #[arg(long, value_name = "DEV,DEV,...", value_delimiter = ',', num_args = 1..)]
    ports: Vec<String>,
    /// Take --ports in any order and put them in array order by the boards' cabling.
    #[arg(long)]
    order_ports: bool,
    /// The board QEMU emulates for --backend qemu.
    #[arg(long, value_enum, default_value = "mps2-an385")]
    board: BoardChoice,
    /// Node firmware ELF for --backend qemu [default: the board's image from scripts/firmware.sh,
    /// target/firmware/node-BOARD.elf].
    #[arg(long, value_name = "ELF")]
    firmware: Option<PathBuf>,
    /// Seconds a node may leave the host unanswered before the run fails (qemu, serial).
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0)]
    node_timeout: f64,
    /// How the grid is first cut into subregions.
    #[arg(long, value_enum, default_value = "even")]
    layout: LayoutMode,
    /// Do not send the nodes the map of the cubes spheres touch (a bit a
    /// cube, grids up to 65536 cubes; with it, a ray leaving a node with
    /// nothing left to meet near the grid's end is retired there instead of
    /// passed on).
    #[arg(long)]
    no_clear_walks: bool,
    /// Load balancing.
    #[arg(long, value_enum, default_value = "slide")]
    balance: BalanceMode,
    /// Virtual cycles between load comparisons (sliding).
    #[arg(long, value_name = "CYCLES", default_value_t = host_tool::plan::options::DEFAULT_INTERVAL)]
    interval: u64,
    /// A node whose load (running/waiting) is under this may take a slab (sliding).
    #[arg(long, value_name = "LOAD", default_value_t = 1.0)]
    threshold: f64,
    /// Driving axis of the sliding boundaries.
    #[arg(long, value_enum, default_value = "auto")]
    driving_axis: AxisChoice,
    /// How far a boundary moves per slide: proportional (the best measured on the boards' links,
    /// docs/partition-and-sliding.md) or paper (the paper's rule).
    #[arg(long, value_enum, default_value = "proportional")]
    policy: PolicyChoice,
    /// Load history over virtual time (per node and interval) [default: DIR/load-history.csv].
    #[arg(long, value_name = "FILE.csv")]
    load_history: Option<PathBuf>,
    /// Boundary positions over virtual time (at the start, then per committed slide)
    /// [default: DIR/boundary-history.csv].
    #[arg(long, value_name = "FILE.csv")]
    boundary_history: Option<PathBuf>,
    /// Plot of per-node load and boundary positions over virtual time [default: DIR/loads.png].
    #[arg(long, value_name = "FILE.png")]
    plot: Option<PathBuf>,
    /// Carry every link as bytes through the nodes' reliable channels and this
    /// fault injector: per-frame probabilities, e.g. corrupt=0.01,drop=0.01,dup=0,delay=0,seed=1.
    /// On emulated boards it acts on the links between boards and to the host; on real
    /// boards on the host links.
    #[arg(long, value_name = "corrupt=P,drop=P,dup=P,delay=P", value_parser = parse_faults)]
    faults: Option<sim_board::Faults>,
    /// Fault injection: reset node N at virtual cycle C mid-render (it must be detected).
    #[arg(long, value_name = "N@C", value_parser = parse_restart)]
    restart_node: Option<(u16, u64)>,
    /// Give up when no node has answered the host for this many virtual cycles.
    #[arg(long, value_name = "CYCLES", default_value_t = 200_000_000)]
    watchdog: u64,
    /// Array of nodes.
    #[arg(long, value_name = "XxYxZ", value_parser = parse_triple, default_value = "4x4x4")]
    array: [u16; 3],
    /// Who creates the initial rays.
    #[arg(long, value_enum, default_value = "entry")]
    initial_rays: InitialMode,
    /// Ray pool slots kept for each class level in each node; the rest are
    /// shared. One is enough for deadlock freedom, and a deeper reserve
    /// starves the shared slots on large arrays.
    #[arg(long, value_name = "N", default_value_t = 1)]
    queue_depth: u16,
    /// Ray pool slots open to every class, beyond the queue depth per level
    /// [default: all a node has left over].
    #[arg(long, value_name = "N")]
    shared_slots: Option<u16>,
    /// Output image [default: DIR/render.png].
    #[arg(long, value_name = "FILE.png")]
    out: Option<PathBuf>,
    /// Per-node load table [default: DIR/loads.csv].
    #[arg(long, value_name = "FILE.csv")]
    loads: Option<PathBuf>,
    /// Run summary [default: DIR/summary.json].
    #[arg(long, value_name = "FILE.json")]
    summary: Option<PathBuf>,
    /// Directory of every file the run writes but those named by their own option (created if missing).
    #[arg(long, value_name = "DIR", default_value = ".")]
    out_dir: PathBuf,
    /// Replace files an earlier run left (a run refuses to by default).
    #[arg(long)]
    overwrite: bool,
    /// Frames to render one after another on the same array, the scene sent once; a sequence
    /// writes DIR/frame-NNNN.png, DIR/animation.png, DIR/frames.csv and DIR/frames.png.
    #[arg(long, value_name = "N", default_value_t = 1)]
    frames: u32,
    /// Swing the camera about its look-at point by DEGREES over the sequence, around its up
    /// direction [default: the scene's keyframes, or its camera standing still].
    #[arg(long, value_name = "DEGREES")]
    orbit: Option<f64>,
    /// Where each frame after the first starts.
    #[arg(long, value_enum, default_value = "carried")]
    frame_start: FrameStartChoice,
    /// Frames per second of DIR/animation.png.
    #[arg(long, value_name = "FPS", default_value_t = 12)]
    fps: u16,
}

#[derive(Args)]
struct ReferenceArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output image.
    #[arg(long, value_name = "FILE.png", default_value = "reference.png")]
    out: PathBuf,
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return usage_error(&e),
    };
    let result = match cli.command {
        Command::Render(args) => render(*args),
        Command::Boards(args) => boards(args),
        Command::Scene(args) => scene_cmd(args),
        Command::Reference(args) => reference_cmd(args),
        Command::Compare(args) => compare_cmd(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}

fn scene_cmd(args: SceneOutArgs) -> Result<(), HostError> {
    let format = SceneFormat::for_output(&args.out)?;
    let scene = load_scene(&args.scene)?;
    let text = scene.to_text(format, args.scene.size)?;
    write_atomic(&args.out, text.as_bytes())
}

fn boards(args: BoardsArgs) -> Result<(), HostError> {
    let timeout = node_timeout(args.node_timeout)?;
    let listing = match (args.emulate, args.array) {
        (Some(board), Some(array)) => {
            let board = EmulatedBoard::from(board);
            let firmware = args.firmware.unwrap_or_else(|| board.default_firmware());
            let qemu = host_tool::session::qemu::QemuArray::launch(board, array, &firmware)?;
            host_tool::session::boards::list(&qemu.ptys, Some(array), timeout)?
        }
        _ => host_tool::session::boards::list(&args.ports, args.array, timeout)?,
    };
    print!("{listing}");
    Ok(())
}

fn render(args: RenderArgs) -> Result<(), HostError> {
    let scene = load_scene_for(&args.scene, args.array)?;
    let mut opts = RenderOptions::new(args.array);
    opts.size = args.scene.size;
    opts.samples = args.scene.samples;
    opts.level_depth = args.queue_depth;
    opts.shared_slots = args.shared_slots;
    opts.initial = match args.initial_rays {
        InitialMode::Parallel => Initial::Parallel,
        InitialMode::Eye => Initial::EyeNode,
        InitialMode::Entry => Initial::Entry,
    };
    opts.clear_walks = !args.no_clear_walks;
    opts.layout = match args.layout {
        LayoutMode::Even => Layout::Even,
        LayoutMode::Preview => Layout::Preview,
    };
    args.links.apply(&mut opts)?;
    opts.sim.faults = args.faults;
    opts.sim.restart = args.restart_node;
    opts.sim.watchdog = args.watchdog;
    opts.driving_axis = args.driving_axis.resolve(&scene);
    if let BalanceMode::Slide = args.balance {
        if args.interval == 0 {
            return Err(input("--interval must be at least 1 cycle"));
        }
        if !args.threshold.is_finite() || args.threshold <= 0.0 || args.threshold > 65535.0 {
            return Err(input(format!("--threshold must be a load in (0, 65535], got {}", args.threshold)));
        }
        let policy = match args.policy {
            PolicyChoice::Paper => SlidePolicy::Paper,
            PolicyChoice::Proportional => host_tool::plan::options::PROPORTIONAL,
        };
        let threshold = (args.threshold * 65536.0).round() as u32;
        opts.balance = Some(Balance { interval: args.interval, threshold, step: 1, policy });
    }
    let backend = match args.backend {
        BackendChoice::Sim => Backend::Sim,
        BackendChoice::Qemu => {
            let board = EmulatedBoard::from(args.board);
            let firmware = args.firmware.clone().unwrap_or_else(|| board.default_firmware());
            Backend::Qemu { board, firmware }
        }
        BackendChoice::Serial => Backend::Serial { ports: args.ports.clone(), order_ports: args.order_ports },
    };
    if backend != Backend::Sim && args.restart_node.is_some() {
        return Err(input("--restart-node restarts a node of the in-memory board (--backend sim)"));
    }
    if backend != Backend::Sim && args.links.given() {
        return Err(input(
            "--link, --clock-mhz, --baud, --host-baud and --transfer model the in-memory board's links \
             (--backend sim)",
        ));
    }
    if !matches!(backend, Backend::Serial { .. }) && (!args.ports.is_empty() || args.order_ports) {
        return Err(input("--ports and --order-ports are for --backend serial"));
    }
    let timeout = node_timeout(args.node_timeout)?;
    let path = match args.orbit {
        Some(d) if !d.is_finite() => {
            return Err(input(format!("--orbit must be a number of degrees, got {d}")));
        }
        Some(degrees) => CameraPath::Orbit { degrees },
        None => CameraPath::Keyframes,
    };
    if args.frames == 0 || args.fps == 0 {
        return Err(input("--frames and --fps must be at least 1"));
    }
    if args.frames > 1 {
        let start = match args.frame_start {
            FrameStartChoice::Carried => FrameStart::Carried,
            FrameStartChoice::Planned => FrameStart::Planned,
        };
        let sequence = Sequence { frames: args.frames, path, start };
        return render_sequence(&args, &scene, &opts, &backend, timeout, &sequence);
    }
    let scene = path.frame(&scene, 0, 1)?;
    let in_dir = |name: &str| match args.out_dir.as_path() {
        dir if dir == std::path::Path::new(".") => PathBuf::from(name),
        dir => dir.join(name),
    };
    let path = |given: &Option<PathBuf>, name: &str| given.clone().unwrap_or_else(|| in_dir(name));
    let out = path(&args.out, "render.png");
    let plot_path = path(&args.plot, "loads.png");
    let loads_path = path(&args.loads, "loads.csv");
    let summary_path = path(&args.summary, "summary.json");
    let history_path = path(&args.load_history, "load-history.csv");
    let boundaries_path = path(&args.boundary_history, "boundary-history.csv");
    let outputs =
        [&out, &plot_path, &loads_path, &summary_path, &history_path, &boundaries_path].map(PathBuf::as_path);
    check_png_name(&out)?;
    check_png_name(&plot_path)?;
    if !args.overwrite {
        refuse_overwrite(&outputs)?;
    }
    std::fs::create_dir_all(&args.out_dir)
        .map_err(|e| HostError::Io(format!("cannot create --out-dir {}: {e}", args.out_dir.display())))?;
    // A run writes all of its outputs or none: a path that cannot take its
    // file is refused before the render, not after it.
    check_writable(&outputs)?;
    let from = Provenance { backend: backend.name(), scene: scene_source(&args.scene, &scene) };
    let files = RunFiles {
        image: out,
        plot: plot_path,
        loads: loads_path,
        summary: summary_path,
        load_history: history_path,
        boundary_history: boundaries_path,
    };
    match host_tool::session::backend::render(&scene, &opts, &backend, timeout)? {
        Rendered::Sim(result) => write_run(&scene, &opts, &result, &from, &files),
        Rendered::Boards(result) => write_run(&scene, &opts, &result, &from, &files),
    }
}

/// Renders a sequence of frames into --out-dir, all files or none.
fn render_sequence(
    args: &RenderArgs,
    scene: &Scene,
    opts: &RenderOptions,
    backend: &Backend,
    timeout: std::time::Duration,
    sequence: &Sequence,
) -> Result<(), HostError> {
    let single =
        [&args.out, &args.plot, &args.loads, &args.summary, &args.load_history, &args.boundary_history];
    if single.iter().any(|p| p.is_some()) {
        return Err(input(
            "--out, --plot, --loads, --summary, --load-history and --boundary-history name one frame's \
             files; a sequence (--frames above 1) writes into --out-dir",
        ));
    }
    let dir = args.out_dir.clone();
    let files = SequenceFiles {
        animation: dir.join("animation.png"),
        table: dir.join("frames.csv"),
        plot: dir.join("frames.png"),
        dir: dir.clone(),
    };
    let all = files.all(sequence.frames);
    let paths: Vec<&std::path::Path> = all.iter().map(PathBuf::as_path).collect();
    if !args.overwrite {
        refuse_overwrite(&paths)?;
    }
    std::fs::create_dir_all(&dir)
        .map_err(|e| HostError::Io(format!("cannot create --out-dir {}: {e}", dir.display())))?;
    check_writable(&paths)?;
    let started = std::time::Instant::now();
    let mut writer = SequenceWriter::new(files.clone(), sequence.frames, opts.size, args.fps)?;
    host_tool::session::backend::render_sequence(scene, opts, backend, timeout, sequence, &mut writer)?;
    let unit = writer.unit();
    let rows = writer.finish()?;
    let total: u64 = rows.iter().map(|r| r.makespan).sum();
    let worst = rows.iter().map(|r| r.imbalance).fold(0.0, f64::max);
    eprintln!(
        "rendered {} frames of {}x{} on {}x{}x{} nodes: makespans sum to {total} {unit}, imbalance at most {worst:.3}, \
         {:.2} s -> {}",
        rows.len(),
        opts.size[0],
        opts.size[1],
        opts.array[0],
        opts.array[1],
        opts.array[2],
        started.elapsed().as_secs_f64(),
        files.animation.display()
    );
    Ok(())
}

/// Where `render` writes each of its outputs.
struct RunFiles {
    image: PathBuf,
    plot: PathBuf,
    loads: PathBuf,
    summary: PathBuf,
    load_history: PathBuf,
    boundary_history: PathBuf,
}

/// Writes a run's outputs, all or none, and says what was rendered.
fn write_run<T: Clock>(
    scene: &Scene,
    opts: &RenderOptions,
    result: &RenderResult<T>,
    from: &Provenance,
    files: &RunFiles,
) -> Result<(), HostError> {
    let f = &result.frame;
    let [w, h] = f.image_size();
    let image = png(w, h, &f.rgb8())?;
    let summary = summary_json(scene, opts, result, from);
    let loads = loads_csv(result);
    let history = load_history_csv(result);
    let boundaries = boundary_history_csv(result);
    let plot = history_plot(result)?;
    write_all_atomic(&[
        (&files.image, &image),
        (&files.plot, &plot),
        (&files.loads, loads.as_bytes()),
        (&files.summary, summary.as_bytes()),
        (&files.load_history, history.as_bytes()),
        (&files.boundary_history, boundaries.as_bytes()),
    ])?;
    eprintln!(
        "rendered {}x{} on {}x{}x{} nodes: makespan {}, imbalance {:.3}, {} rays, {:.2} s -> {}",
        w,
        h,
        opts.array[0],
        opts.array[1],
        opts.array[2],
        f.makespan,
        imbalance(result),
        f.rays_terminated,
        result.wall.as_secs_f64(),
        files.image.display()
    );
    if let Some(warning) = link_warning(result, &files.summary) {
        eprintln!("{warning}");
    }
    Ok(())
}

fn reference_cmd(args: ReferenceArgs) -> Result<(), HostError> {
    let scene = load_scene(&args.scene)?;
    let [w, h] = args.scene.size;
    let [tw, _] = host_tool::results::image::traced(args.scene.size, args.scene.samples)?;
    check_png_name(&args.out)?;
    let side = tw / w;
    let colors = reference::render_sampled(&scene, args.scene.size, side);
    write_atomic(&args.out, &png(w, h, &reference::rgb8_of(&colors))?)?;
    eprintln!("reference {w}x{h} -> {}", args.out.display());
    Ok(())
}

/// Compares at every sample: with `--samples`, at the positions the nodes trace.
fn compare_cmd(args: SceneArgs) -> Result<(), HostError> {
    let scene = load_scene(&args)?;
    let size = host_tool::results::image::traced(args.size, args.samples)?;
    let [w, h] = size;
    let fixed = direct::render(&scene, w, h)?;
    let fixed_rgb: Vec<u8> =
        fixed.sums.iter().flat_map(|px| px.map(host_tool::results::image::to_srgb8)).collect();
    let refimg = reference::render(&scene, w, h);
    let c = compare(&scene, size, &fixed, &fixed_rgb, &refimg, &refimg.rgb8());
    let text = serde_json::to_string_pretty(&c).map_err(|e| HostError::Io(e.to_string()))?;
    println!("{text}");
    Ok(())
}

fn parse_restart(s: &str) -> Result<(u16, u64), String> {
    let (node, at) =
        s.split_once('@').ok_or_else(|| format!("expected NODE@CYCLES such as 5@1000000, got '{s}'"))?;
    let node = node.parse().map_err(|_| format!("node '{node}' is not a whole number"))?;
    let at = at.parse().map_err(|_| format!("cycle '{at}' is not a whole number"))?;
    Ok((node, at))
}
