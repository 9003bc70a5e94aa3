//! `host-tool`: render on the in-memory array, render the f64 reference, compare.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};
use host_tool::backend::Backend;
use host_tool::compare::compare;
use host_tool::error::{HostError, input};
use host_tool::output::{
    check_png_name, check_writable, png, refuse_overwrite, write_all_atomic, write_atomic,
};
use host_tool::qemu::EmulatedBoard;
use host_tool::render::{Initial, Layout, RenderOptions, render_sim};
use host_tool::run_files::{
    Provenance, boundary_history_csv, history_plot, imbalance, load_history_csv, loads_csv, summary_json,
};
use host_tool::scene::{Reading, Scene, SceneFormat};
use host_tool::{direct, reference};
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
    /// Benchmarks.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Reports on the arithmetic.
    #[command(subcommand)]
    Report(ReportCommand),
}

#[derive(Subcommand)]
enum ReportCommand {
    /// The stiff and extreme cases of the numerics notes: a Markdown table of
    /// what each must do and what it did (docs/arithmetic.md shows it). Exits 4 if any fails.
    Stiff {
        /// Also write the table here.
        #[arg(long, value_name = "FILE.md")]
        out: Option<PathBuf>,
    },
    /// Error against run time of arithmetic variants (fixed point, f32) against
    /// the f64 reference: CSV, Markdown table and a Pareto plot.
    Numerics {
        /// Output directory.
        #[arg(long, value_name = "DIR", default_value = "numerics")]
        out: PathBuf,
        /// One small scene (for CI).
        #[arg(long)]
        quick: bool,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Host rays/s of the in-memory board at several array sizes, and of a plain
    /// single-threaded loop over the same kernels (the node machinery's overhead).
    Board(BoardBenchArgs),
    /// The paper's experiments (Figs. 7-10): CSV tables and PNG plots.
    Paper(PaperArgs),
    /// Efficiency E = T(1) / (S T(S)) and where the busy cycles go, for
    /// S = 1, 8, 27, 64, 216, 512 on the in-memory board: a table, CSV and PNG.
    Scaling(ScalingArgs),
}

#[derive(Args)]
struct ScalingArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    links: LinkArgs,
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "scaling")]
    out: PathBuf,
    /// S = 1, 8 and 27 only (for CI).
    #[arg(long)]
    quick: bool,
}

#[derive(Args)]
struct PaperArgs {
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "paper")]
    out: PathBuf,
    /// A reduced run (a minute or two) for CI.
    #[arg(long)]
    quick: bool,
    /// Seed of the random scenes (1986 by default, the paper's year): rerun
    /// with others to see how far the results depend on one scene.
    #[arg(long, value_name = "N", default_value_t = 1986)]
    seed: u64,
}

#[derive(Args)]
struct BoardBenchArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Arrays to run, comma-separated.
    #[arg(long, value_name = "XxYxZ,...", default_value = "1x1x1,2x2x2,4x4x4,8x8x8")]
    arrays: String,
    /// Runs per configuration (the best is reported).
    #[arg(long, default_value_t = 1)]
    repeat: u32,
}

#[derive(Args, Clone)]
struct SceneArgs {
    /// Scene file: JSON (schema in docs/cli.md), or NFF if it ends in .nff. Without it, a random scene is made.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["spheres", "seed", "volume_ratio"])]
    scene: Option<PathBuf>,
    /// Random scene: number of spheres.
    #[arg(long, value_name = "N")]
    spheres: Option<usize>,
    /// Random scene: seed.
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// Random scene: volume ratio of the cube the spheres are confined to, (0, 1].
    #[arg(long, value_name = "V")]
    volume_ratio: Option<f64>,
    /// Grid size: of a random scene [default: 32x32x32], or the one a scene is fitted into [default: chosen
    /// from the scene].
    #[arg(long, value_name = "XxYxZ", value_parser = parse_triple)]
    grid: Option<[u16; 3]>,
    /// Fit a JSON scene into the grid (scale and offset); NFF scenes always are.
    #[arg(long, requires = "scene")]
    fit: bool,
    /// Leave out NFF primitives that cannot be rendered (cones, polygons), with a warning, instead of refusing
    /// the file.
    #[arg(long, requires = "scene")]
    skip_unsupported: bool,
    /// Image size.
    #[arg(long, value_name = "WxH", value_parser = parse_pair, default_value = "256x256")]
    size: [u16; 2],
}

/// The links of the in-memory board: a preset, and settings that override it.
#[derive(Args, Clone)]
struct LinkArgs {
    /// Links of the in-memory board: f413 (NUCLEO-F413ZH boards: 100 MHz,
    /// neighbour USARTs at 3.125 Mbaud, host at 921 600 baud, a byte interrupt),
    /// ideal (25 cycles a byte, no CPU per byte) or emulated (the QEMU
    /// boards: polled UARTs, the loop's pass charged) [default: f413].
    #[arg(long, value_name = "PRESET", value_parser = host_tool::links::preset_named)]
    link: Option<sim_board::LinkPreset>,
    /// Core clock of the nodes, MHz (overrides the preset's).
    #[arg(long, value_name = "MHZ")]
    clock_mhz: Option<f64>,
    /// Line rate of the neighbour links, baud (10 bits a byte).
    #[arg(long, value_name = "BAUD")]
    baud: Option<u64>,
    /// Line rate of the host links, baud.
    #[arg(long, value_name = "BAUD")]
    host_baud: Option<u64>,
    /// How the nodes move bytes between UARTs and memory (CPU cycles a byte).
    #[arg(long, value_enum)]
    transfer: Option<TransferChoice>,
}

impl LinkArgs {
    /// Whether any link setting was given.
    fn given(&self) -> bool {
        self.link.is_some()
            || self.clock_mhz.is_some()
            || self.baud.is_some()
            || self.host_baud.is_some()
            || self.transfer.is_some()
    }

    /// Sets `opts`'s links.
    fn apply(&self, opts: &mut RenderOptions) -> Result<(), HostError> {
        let clock_hz = match self.clock_mhz {
            Some(mhz) if !mhz.is_finite() => {
                return Err(HostError::NonFinite(format!("--clock-mhz must be a number, got {mhz}")));
            }
            Some(mhz) => Some((mhz * 1e6).round().clamp(0.0, u64::MAX as f64) as u64),
            None => None,
        };
        let choice = host_tool::links::LinkChoice {
            preset: self.link.unwrap_or_default(),
            clock_hz,
            baud: self.baud,
            host_baud: self.host_baud,
            transfer: self.transfer.map(|t| match t {
                TransferChoice::Polled => sim_board::Transfer::Polled,
                TransferChoice::Interrupt => sim_board::Transfer::Interrupt,
                TransferChoice::Dma => sim_board::Transfer::Dma,
            }),
        };
        let (link, host) = choice.specs()?;
        opts.sim.link = link;
        opts.sim.host_link = host;
        opts.sim.cost.pass = choice.preset.loop_pass();
        opts.link_preset = choice.preset;
        Ok(())
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum TransferChoice {
    /// The main loop polls each UART (16 cycles a byte).
    Polled,
    /// An interrupt per byte (50 cycles a byte).
    Interrupt,
    /// DMA (no CPU cycles per byte).
    Dma,
}

#[derive(Clone, Copy, ValueEnum)]
enum InitialMode {
    /// Every node creates the rays of a regular sub-image and passes each to
    /// the node where it enters (the paper's parallel mode).
    Parallel,
    /// The node holding the eye creates all of them.
    Eye,
    /// The nodes on the face toward the eye create the rays entering through
    /// their part of it, so rays start where they are traced (beyond the paper).
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
enum PolicyChoice {
    /// One cube when one load is lower and under the threshold (the paper's).
    Paper,
    /// Proportional to the running-time difference, under-relaxed, capped, with a dead band.
    Proportional,
}

#[derive(Clone, Copy, ValueEnum)]
enum AxisChoice {
    /// The axis along which the sphere counts of the node layers vary most (the paper's rule).
    Auto,
    /// The axis most aligned with the camera's view direction.
    View,
    /// x.
    X,
    /// y.
    Y,
    /// z.
    Z,
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
    /// Load balancing.
    #[arg(long, value_enum, default_value = "slide")]
    balance: BalanceMode,
    /// Virtual cycles between load comparisons (sliding).
    #[arg(long, value_name = "CYCLES", default_value_t = 5_000_000)]
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
        Command::Bench(BenchCommand::Board(args)) => bench_board(args),
        Command::Report(ReportCommand::Numerics { out, quick }) => numerics_report(&out, quick),
        Command::Report(ReportCommand::Stiff { out }) => {
            let (table, pass) = host_tool::numerics::stiff_table::markdown();
            print!("{table}");
            match out {
                Some(path) => write_atomic(&path, table.as_bytes()),
                None => Ok(()),
            }
            .and_then(|()| if pass { Ok(()) } else { Err(HostError::Node("a stiff case failed".into())) })
        }
        Command::Bench(BenchCommand::Scaling(args)) => bench_scaling(args),
        Command::Bench(BenchCommand::Paper(args)) => {
            let cfg = if args.quick {
                host_tool::paper::PaperConfig::quick()
            } else {
                host_tool::paper::PaperConfig::full()
            };
            let cfg = host_tool::paper::PaperConfig { seed: args.seed, ..cfg };
            host_tool::paper::bench_paper(&cfg, &args.out).map(|report| print!("{report}"))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}

/// Help and version go to stdout as clap writes them. A usage error leads
/// with the one line that says what is wrong, then clap's tip and its pointer
/// to `--help`, without the usage block and blank lines between; exit 2.
fn usage_error(e: &clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion)
        || e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    {
        let _ = e.print();
        let code = if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand { 2 } else { 0 };
        return ExitCode::from(code);
    }
    let text = e.render().to_string();
    let mut lines = text.lines().map(str::trim_end).filter(|l| !l.trim().is_empty());
    let what = lines.next().unwrap_or("error: bad command line");
    eprintln!("{what}");
    for line in lines.filter(|l| l.trim_start().starts_with("tip:") || l.starts_with("For more information"))
    {
        eprintln!("{line}");
    }
    ExitCode::from(2)
}

/// The demo scene: this many random spheres from this seed, in the whole grid.
const DEMO_SPHERES: usize = 400;
const DEMO_SEED: u64 = 1986;

/// Where the scene came from, for the run summary.
fn scene_source(args: &SceneArgs, scene: &Scene) -> serde_json::Value {
    let spheres = scene.spheres.len();
    match &args.scene {
        Some(path) => serde_json::json!({
            "source": "file", "path": path.display().to_string(),
            "format": match SceneFormat::of(path) { SceneFormat::Nff => "nff", SceneFormat::Json => "json" },
            "fitted": args.fit || SceneFormat::of(path) == SceneFormat::Nff, "spheres": spheres,
        }),
        None if args.spheres.is_none() && args.seed.is_none() && args.volume_ratio.is_none() => {
            serde_json::json!({"source": "demo", "spheres": spheres, "seed": DEMO_SEED, "volume_ratio": 1.0})
        }
        None => serde_json::json!({
            "source": "random", "spheres": spheres, "seed": args.seed.unwrap_or(1),
            "volume_ratio": args.volume_ratio.unwrap_or(1.0),
        }),
    }
}

/// The scene the options describe: a file, a random scene, or the built-in demo.
fn load_scene(args: &SceneArgs) -> Result<Scene, HostError> {
    if let Some(path) = &args.scene {
        let how = Reading { fit: args.fit, grid: args.grid, skip_unsupported: args.skip_unsupported };
        let (scene, warnings) = Scene::read(path, &how)?;
        for warning in warnings {
            eprintln!("warning: {warning}");
        }
        return Ok(scene);
    }
    let default_demo = args.spheres.is_none() && args.seed.is_none() && args.volume_ratio.is_none();
    let (count, seed, ratio) = if default_demo {
        (DEMO_SPHERES, DEMO_SEED, 1.0)
    } else {
        (args.spheres.unwrap_or(1000), args.seed.unwrap_or(1), args.volume_ratio.unwrap_or(1.0))
    };
    Scene::random(count, seed, ratio, args.grid.unwrap_or([32; 3]))
}

fn scene_cmd(args: SceneOutArgs) -> Result<(), HostError> {
    let format = SceneFormat::for_output(&args.out)?;
    let scene = load_scene(&args.scene)?;
    let text = scene.to_text(format, args.scene.size)?;
    write_atomic(&args.out, text.as_bytes())
}

fn boards(args: BoardsArgs) -> Result<(), HostError> {
    if !(args.node_timeout.is_finite() && args.node_timeout > 0.0 && args.node_timeout < 1e6) {
        return Err(input(format!(
            "--node-timeout must be a positive number of seconds, got {}",
            args.node_timeout
        )));
    }
    let timeout = std::time::Duration::from_secs_f64(args.node_timeout);
    let listing = match (args.emulate, args.array) {
        (Some(board), Some(array)) => {
            let board = EmulatedBoard::from(board);
            let firmware = args.firmware.unwrap_or_else(|| board.default_firmware());
            let qemu = host_tool::qemu::QemuArray::launch(board, array, &firmware)?;
            host_tool::boards::list(&qemu.ptys, Some(array), timeout)?
        }
        _ => host_tool::boards::list(&args.ports, args.array, timeout)?,
    };
    print!("{listing}");
    Ok(())
}

fn render(args: RenderArgs) -> Result<(), HostError> {
    let scene = load_scene(&args.scene)?;
    let mut opts = RenderOptions::new(args.array);
    opts.size = args.scene.size;
    opts.level_depth = args.queue_depth;
    opts.shared_slots = args.shared_slots;
    opts.initial = match args.initial_rays {
        InitialMode::Parallel => Initial::Parallel,
        InitialMode::Eye => Initial::EyeNode,
        InitialMode::Entry => Initial::Entry,
    };
    opts.layout = match args.layout {
        LayoutMode::Even => Layout::Even,
        LayoutMode::Preview => Layout::Preview,
    };
    args.links.apply(&mut opts)?;
    opts.sim.faults = args.faults;
    opts.sim.restart = args.restart_node;
    opts.sim.watchdog = args.watchdog;
    opts.driving_axis = match args.driving_axis {
        AxisChoice::Auto => None,
        AxisChoice::View => Some(host_tool::partition::view_axis(&scene)),
        AxisChoice::X => Some(0),
        AxisChoice::Y => Some(1),
        AxisChoice::Z => Some(2),
    };
    if let BalanceMode::Slide = args.balance {
        if args.interval == 0 {
            return Err(input("--interval must be at least 1 cycle"));
        }
        if !args.threshold.is_finite() || args.threshold <= 0.0 || args.threshold > 65535.0 {
            return Err(input(format!("--threshold must be a load in (0, 65535], got {}", args.threshold)));
        }
        let policy = match args.policy {
            PolicyChoice::Paper => SlidePolicy::Paper,
            PolicyChoice::Proportional => host_tool::paper::PROPORTIONAL,
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
    if !(args.node_timeout.is_finite() && args.node_timeout > 0.0 && args.node_timeout < 1e6) {
        return Err(input(format!(
            "--node-timeout must be a positive number of seconds, got {}",
            args.node_timeout
        )));
    }
    let timeout = std::time::Duration::from_secs_f64(args.node_timeout);
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
    let result = host_tool::backend::render(&scene, &opts, &backend, timeout)?;
    let f = &result.frame;
    let image = png(f.width, f.height, &f.rgb8())?;
    let from = Provenance {
        backend: match &backend {
            Backend::Sim => "sim".to_string(),
            Backend::Qemu { board, .. } => format!("qemu ({})", board.name()),
            Backend::Serial { .. } => "serial".to_string(),
        },
        scene: scene_source(&args.scene, &scene),
    };
    let summary = summary_json(&scene, &opts, &result, &from);
    let loads = loads_csv(&result);
    let history = load_history_csv(&result);
    let boundaries = boundary_history_csv(&result);
    let plot = history_plot(&result)?;
    write_all_atomic(&[
        (&out, &image),
        (&plot_path, &plot),
        (&loads_path, loads.as_bytes()),
        (&summary_path, summary.as_bytes()),
        (&history_path, history.as_bytes()),
        (&boundaries_path, boundaries.as_bytes()),
    ])?;
    eprintln!(
        "rendered {}x{} on {}x{}x{} nodes: makespan {} {}, imbalance {:.3}, {} rays, {:.2} s -> {}",
        f.width,
        f.height,
        opts.array[0],
        opts.array[1],
        opts.array[2],
        f.makespan,
        if backend == Backend::Sim { "cycles" } else { "us of host time" },
        imbalance(&result),
        f.rays_terminated,
        result.wall.as_secs_f64(),
        out.display()
    );
    Ok(())
}

fn reference_cmd(args: ReferenceArgs) -> Result<(), HostError> {
    let scene = load_scene(&args.scene)?;
    let [w, h] = args.scene.size;
    host_tool::frame::check_size(w, h)?;
    check_png_name(&args.out)?;
    let img = reference::render(&scene, w, h);
    write_atomic(&args.out, &png(w, h, &img.rgb8())?)?;
    eprintln!("reference {w}x{h} -> {}", args.out.display());
    Ok(())
}

fn compare_cmd(args: SceneArgs) -> Result<(), HostError> {
    let scene = load_scene(&args)?;
    let [w, h] = args.size;
    host_tool::frame::check_size(w, h)?;
    let fixed = direct::render(&scene, w, h)?;
    let fixed_rgb: Vec<u8> = fixed.sums.iter().flat_map(|px| px.map(host_tool::frame::to_srgb8)).collect();
    let refimg = reference::render(&scene, w, h);
    let c = compare(&scene, args.size, &fixed, &fixed_rgb, &refimg, &refimg.rgb8());
    let text = serde_json::to_string_pretty(&c).map_err(|e| HostError::Io(e.to_string()))?;
    println!("{text}");
    Ok(())
}

fn bench_board(args: BoardBenchArgs) -> Result<(), HostError> {
    let mut scene_args = args.scene.clone();
    if scene_args.scene.is_none() && scene_args.spheres.is_none() {
        scene_args.spheres = Some(1000);
    }
    let scene = load_scene(&scene_args)?;
    let [w, h] = scene_args.size;
    let arrays: Vec<[u16; 3]> =
        args.arrays.split(',').map(parse_triple).collect::<Result<_, _>>().map_err(input)?;
    println!("{{\"size\": [{w}, {h}], \"spheres\": {}, \"runs\": [", scene.spheres.len());
    let best = |f: &mut dyn FnMut() -> Result<(f64, u64), HostError>| -> Result<(f64, u64), HostError> {
        let mut out = (f64::INFINITY, 0);
        for _ in 0..args.repeat.max(1) {
            let (t, rays) = f()?;
            out = (out.0.min(t), rays);
        }
        Ok(out)
    };
    let (t_direct, rays) = best(&mut || {
        let start = std::time::Instant::now();
        let img = direct::render(&scene, w, h)?;
        Ok((start.elapsed().as_secs_f64(), img.rays))
    })?;
    let direct_rate = rays as f64 / t_direct;
    println!(
        "  {{\"config\": \"single loop\", \"nodes\": 1, \"rays\": {rays}, \"seconds\": {t_direct:.3}, \"rays_per_s\": {direct_rate:.0}}},"
    );
    for (i, array) in arrays.iter().enumerate() {
        let mut opts = RenderOptions::new(*array);
        opts.size = scene_args.size;
        let (t, rays) = best(&mut || {
            let r = render_sim(&scene, &opts)?;
            Ok((r.wall.as_secs_f64(), r.frame.rays_terminated))
        })?;
        let rate = rays as f64 / t;
        let nodes: u32 = array.iter().map(|&n| u32::from(n)).product();
        let sep = if i + 1 < arrays.len() { "," } else { "" };
        println!(
            "  {{\"config\": \"board {}x{}x{}\", \"nodes\": {nodes}, \"rays\": {rays}, \"seconds\": {t:.3}, \"rays_per_s\": {rate:.0}, \"single_loop_over_board\": {:.2}}}{sep}",
            array[0],
            array[1],
            array[2],
            direct_rate / rate
        );
    }
    println!("]}}");
    Ok(())
}

fn bench_scaling(args: ScalingArgs) -> Result<(), HostError> {
    let mut scene_args = args.scene.clone();
    if scene_args.scene.is_none() && scene_args.spheres.is_none() {
        // The scene: the paper's 1000 random spheres, seed 1986.
        scene_args.spheres = Some(1000);
        scene_args.seed = scene_args.seed.or(Some(1986));
    }
    let scene = load_scene(&scene_args)?;
    let mut base = RenderOptions::new([1, 1, 1]);
    base.size = scene_args.size;
    args.links.apply(&mut base)?;
    let cfg = if args.quick {
        host_tool::scaling::ScalingConfig::quick(base)
    } else {
        host_tool::scaling::ScalingConfig::full(base)
    };
    let table = host_tool::scaling::bench_scaling(&scene, &cfg, &args.out)?;
    print!("{table}");
    Ok(())
}

fn numerics_report(out: &std::path::Path, quick: bool) -> Result<(), HostError> {
    let grid = [32; 3];
    let mut scenes = vec![("demo".to_string(), Scene::random(400, 1986, 1.0, grid)?)];
    let size = if quick {
        [48, 48]
    } else {
        for seed in [1, 2] {
            scenes.push((format!("1000 spheres, seed {seed}"), Scene::random(1000, seed, 1.0, grid)?));
        }
        [128, 128]
    };
    let md = host_tool::numerics::variants::report(&scenes, size, out)?;
    print!("{md}");
    Ok(())
}

fn parse_faults(s: &str) -> Result<sim_board::Faults, String> {
    let mut f = sim_board::Faults { seed: 1, ..Default::default() };
    for part in s.split(',').filter(|p| !p.is_empty()) {
        let (key, value) = part.split_once('=').ok_or_else(|| format!("expected key=value in '{part}'"))?;
        if key == "seed" {
            f.seed = value.parse().map_err(|_| format!("seed '{value}' is not a whole number"))?;
            continue;
        }
        let p: f64 = value.parse().map_err(|_| format!("'{value}' is not a number"))?;
        if !(0.0..1.0).contains(&p) {
            return Err(format!("{key}={value}: a probability in [0, 1)"));
        }
        match key {
            "corrupt" => f.corrupt = p,
            "drop" => f.drop = p,
            "dup" => f.dup = p,
            "delay" => f.delay = p,
            _ => return Err(format!("unknown fault '{key}' (corrupt, drop, dup, delay, seed)")),
        }
    }
    Ok(f)
}

fn parse_restart(s: &str) -> Result<(u16, u64), String> {
    let (node, at) =
        s.split_once('@').ok_or_else(|| format!("expected NODE@CYCLES such as 5@1000000, got '{s}'"))?;
    let node = node.parse().map_err(|_| format!("node '{node}' is not a whole number"))?;
    let at = at.parse().map_err(|_| format!("cycle '{at}' is not a whole number"))?;
    Ok((node, at))
}

fn parse_triple(s: &str) -> Result<[u16; 3], String> {
    let parts: Vec<&str> = s.split('x').collect();
    match parts.as_slice() {
        [a, b, c] => Ok([num(a)?, num(b)?, num(c)?]),
        _ => Err(format!("expected XxYxZ such as 4x4x4, got '{s}'")),
    }
}

fn parse_pair(s: &str) -> Result<[u16; 2], String> {
    let parts: Vec<&str> = s.split('x').collect();
    match parts.as_slice() {
        [a, b] => Ok([num(a)?, num(b)?]),
        _ => Err(format!("expected WxH such as 256x256, got '{s}'")),
    }
}

fn num(s: &str) -> Result<u16, String> {
    s.trim().parse::<u16>().map_err(|_| format!("'{s}' is not a whole number from 0 to 65535"))
}
