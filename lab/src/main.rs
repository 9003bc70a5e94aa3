//! `lab`: the experiments behind the docs' numbers, apart from the product:
//! the paper's experiments, the scaling and board benchmarks, and the
//! arithmetic reports. Each writes its tables (and plots) where `--out` says.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use host_tool::args::{AxisChoice, LinkArgs, SceneArgs, load_scene, parse_faults, parse_triple, usage_error};
use host_tool::error::{HostError, input};
use host_tool::plan::direct;
use host_tool::plan::options::RenderOptions;
use host_tool::results::output::write_atomic;
use host_tool::session::sim::render_sim;

#[derive(Parser)]
#[command(
    name = "lab",
    version,
    about = "Experiments of the sliding-boundary ray tracer: benchmarks and reports"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Benchmarks.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Reports on the arithmetic.
    #[command(subcommand)]
    Report(ReportCommand),
    /// The tables of docs/results.md, made anew (about a minute).
    Results(ResultsArgs),
    /// A long orbit on one array under link faults against the same on clean
    /// links: every frame identical, nothing lost, the host's memory flat.
    /// Exits 30 if a frame differs or loses a ray.
    Soak(SoakArgs),
}

#[derive(Args)]
struct SoakArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Frames of the orbit (each run).
    #[arg(long, value_name = "N", default_value_t = 200)]
    frames: u32,
    /// Array of nodes.
    #[arg(long, value_name = "XxYxZ", value_parser = parse_triple, default_value = "4x4x4")]
    array: [u16; 3],
    /// Faults on every link (per-frame probabilities).
    #[arg(long, value_name = "corrupt=P,drop=P,...", value_parser = parse_faults,
          default_value = "corrupt=0.01,drop=0.01,seed=1")]
    faults: sim_board::Faults,
}

#[derive(Args)]
struct AnimationArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    links: LinkArgs,
    /// Arrays, comma-separated.
    #[arg(long, value_name = "XxYxZ,...", default_value = "4x4x4,8x8x8")]
    arrays: String,
    /// Frames of the orbit.
    #[arg(long, value_name = "N", default_value_t = 60)]
    frames: u32,
    /// Degrees the camera turns over the sequence.
    #[arg(long, value_name = "DEGREES", default_value_t = 360.0)]
    orbit: f64,
    /// The first frame of the steady state.
    #[arg(long, value_name = "K", default_value_t = 10)]
    steady_from: u32,
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "animation")]
    out: PathBuf,
    /// Eight 64x64 frames on 2x2x2 (for CI).
    #[arg(long)]
    quick: bool,
}

#[derive(Args)]
struct ResultsArgs {
    /// Where the document goes.
    #[arg(long, value_name = "FILE.md", default_value = "docs/results.md")]
    out: PathBuf,
    /// Compare with the document instead of writing it; exit 5 naming each
    /// table that is no longer what the code makes.
    #[arg(long)]
    check: bool,
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
    /// Error against run time on a scene (the demo without one) over the
    /// settings a user can turn: samples per pixel, reflection depth, grid
    /// resolution, arithmetic. CSV, Markdown table and a Pareto plot.
    Tradeoff(TradeoffArgs),
}

#[derive(Args)]
struct TradeoffArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "tradeoff")]
    out: PathBuf,
    /// A reduced sweep at 32x32 (for the test command).
    #[arg(long)]
    quick: bool,
    /// Array the makespans are measured on (render's defaults otherwise).
    #[arg(long, value_name = "XxYxZ", value_parser = parse_triple, default_value = "4x4x4")]
    array: [u16; 3],
    /// Also render the default setting on one emulated board (QEMU) and set
    /// its instruction count beside the cost model's.
    #[arg(long)]
    spot_check: bool,
    /// Instead of the scene options: the built-in sphereflake of this many
    /// generations (mirrors everywhere; 2 gives 91 spheres).
    #[arg(long, value_name = "LEVELS", conflicts_with_all = ["scene", "spheres"])]
    sphereflake: Option<u32>,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Host rays/s of the in-memory board at several array sizes, and of a plain
    /// single-threaded loop over the same kernels (the node machinery's overhead).
    Board(BoardBenchArgs),
    /// The paper's experiments (Figs. 7-10): CSV tables and PNG plots.
    Paper(PaperArgs),
    /// A camera orbit as one sequence per balancing mode (the paper's rule and
    /// the proportional policy carried, a preview fit per frame, static):
    /// imbalance and makespan per frame, settling, the sequence's cost.
    Animation(AnimationArgs),
    /// Efficiency E = T(1) / (S T(S)) and where the busy cycles go, for
    /// S = 1, 8, 27, 64, 216, 512 on the in-memory board: a table, CSV and PNG.
    Scaling(ScalingArgs),
    /// The same for every shape of one number of nodes (4x4x4, 4x8x2,
    /// 8x8x1, ...), fastest first: how to cable the boards you have.
    Shapes(ShapesArgs),
}

#[derive(Args)]
struct ShapesArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    links: LinkArgs,
    /// Nodes in the array: every X x Y x Z of this many is run.
    #[arg(long, value_name = "S", default_value_t = 64)]
    nodes: u32,
    /// Driving axis of each partition (the preview fit's rows run along it).
    #[arg(long, value_enum, default_value = "auto")]
    driving_axis: AxisChoice,
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "shapes")]
    out: PathBuf,
}

#[derive(Args)]
struct ScalingArgs {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    links: LinkArgs,
    /// Driving axis of each partition (the preview fit's rows run along it).
    #[arg(long, value_enum, default_value = "auto")]
    driving_axis: AxisChoice,
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

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return usage_error(&e),
    };
    let result = match cli.command {
        Command::Bench(BenchCommand::Board(args)) => bench_board(args),
        Command::Report(ReportCommand::Tradeoff(args)) => tradeoff_report(&args),
        Command::Report(ReportCommand::Stiff { out }) => {
            let (table, pass) = lab::numerics::stiff_table::markdown();
            print!("{table}");
            match out {
                Some(path) => write_atomic(&path, table.as_bytes()),
                None => Ok(()),
            }
            .and_then(|()| if pass { Ok(()) } else { Err(HostError::Node("a stiff case failed".into())) })
        }
        Command::Bench(BenchCommand::Scaling(args)) => bench_scaling(args),
        Command::Bench(BenchCommand::Shapes(args)) => bench_shapes(args),
        Command::Bench(BenchCommand::Animation(args)) => bench_animation(args),
        Command::Soak(args) => soak(args),
        Command::Results(args) => return results(&args),
        Command::Bench(BenchCommand::Paper(args)) => {
            let cfg =
                if args.quick { lab::paper::PaperConfig::quick() } else { lab::paper::PaperConfig::full() };
            let cfg = lab::paper::PaperConfig { seed: args.seed, ..cfg };
            lab::paper::bench_paper(&cfg, &args.out).map(|report| print!("{report}"))
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

/// Writes docs/results.md, or checks it with `--check` (exit 5 when stale).
fn results(args: &ResultsArgs) -> ExitCode {
    let fail = |e: HostError| {
        eprintln!("error: {e}");
        ExitCode::from(e.exit_code() as u8)
    };
    let tables = match lab::results::tables() {
        Ok(t) => t,
        Err(e) => return fail(e),
    };
    if args.check {
        let doc = match std::fs::read_to_string(&args.out) {
            Ok(d) => d,
            Err(e) => return fail(HostError::Io(format!("cannot read {}: {e}", args.out.display()))),
        };
        let stale = lab::results::stale(&doc, &tables);
        if stale.is_empty() {
            return ExitCode::SUCCESS;
        }
        eprintln!(
            "error: {}: {} no longer what the code makes; run `cargo run --release -p lab -- results`",
            args.out.display(),
            stale.join(", ")
        );
        return ExitCode::from(5);
    }
    let commit = std::process::Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map_or_else(|| "unknown".to_string(), |o| String::from_utf8_lossy(&o.stdout).trim().to_string());
    match write_atomic(&args.out, lab::results::document(&commit, &tables).as_bytes()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => fail(e),
    }
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

/// The scene unless one is given: the paper's 1000 random spheres, seed 1986.
fn paper_scene(args: &SceneArgs) -> SceneArgs {
    let mut scene_args = args.clone();
    if scene_args.scene.is_none() && scene_args.spheres.is_none() {
        scene_args.spheres = Some(1000);
        scene_args.seed = scene_args.seed.or(Some(1986));
    }
    scene_args
}

fn bench_animation(args: AnimationArgs) -> Result<(), HostError> {
    let mut scene_args = paper_scene(&args.scene);
    let mut arrays = args
        .arrays
        .split(',')
        .map(|a| parse_triple(a.trim()).map_err(|e| input(format!("--arrays: {e}"))))
        .collect::<Result<Vec<_>, _>>()?;
    let (mut frames, mut steady_from) = (args.frames, args.steady_from);
    if args.quick {
        (arrays, frames, steady_from, scene_args.size) = (vec![[2, 2, 2]], 8, 4, [64, 64]);
    }
    if frames <= steady_from || !args.orbit.is_finite() {
        return Err(input("--frames must exceed --steady-from, and --orbit be a number of degrees"));
    }
    let scene = load_scene(&scene_args)?;
    let mut base = RenderOptions::new([1, 1, 1]);
    base.size = scene_args.size;
    args.links.apply(&mut base)?;
    let cfg = lab::animation::AnimationConfig { arrays, frames, degrees: args.orbit, steady_from, base };
    let table = lab::animation::bench_animation(&scene, &cfg, &args.out)?;
    print!("{table}");
    Ok(())
}

fn soak(args: SoakArgs) -> Result<(), HostError> {
    if args.frames < 20 {
        return Err(input("--frames must be at least 20 (memory is read at frame 20 and the last)"));
    }
    let scene_args = paper_scene(&args.scene);
    let scene = load_scene(&scene_args)?;
    let mut opts = RenderOptions::new(args.array);
    opts.size = scene_args.size;
    let report = lab::soak::soak(&scene, &opts, args.frames, args.faults, &[20, args.frames])?;
    print!("{}", report.text());
    if report.passed() {
        Ok(())
    } else {
        Err(HostError::Node("the soak found a frame that differs or lost a ray".into()))
    }
}

/// The scene (the paper's unless given) and the options every run of a
/// scaling benchmark shares; each run sets its own array.
fn scaling_base(
    scene: &SceneArgs,
    links: &LinkArgs,
    axis: AxisChoice,
) -> Result<(host_tool::scene::Scene, RenderOptions), HostError> {
    let scene_args = paper_scene(scene);
    let scene = load_scene(&scene_args)?;
    let mut base = RenderOptions::new([1, 1, 1]);
    base.size = scene_args.size;
    links.apply(&mut base)?;
    base.driving_axis = axis.resolve(&scene);
    Ok((scene, base))
}

fn bench_scaling(args: ScalingArgs) -> Result<(), HostError> {
    let (scene, base) = scaling_base(&args.scene, &args.links, args.driving_axis)?;
    let cfg = if args.quick {
        lab::scaling::ScalingConfig::quick(base)
    } else {
        lab::scaling::ScalingConfig::full(base)
    };
    let table = lab::scaling::bench_scaling(&scene, &cfg, &args.out)?;
    print!("{table}");
    Ok(())
}

fn bench_shapes(args: ShapesArgs) -> Result<(), HostError> {
    let (scene, base) = scaling_base(&args.scene, &args.links, args.driving_axis)?;
    let layouts = [host_tool::plan::options::Layout::Even, host_tool::plan::options::Layout::Preview];
    let table = lab::scaling::bench_shapes(&scene, &base, args.nodes, &layouts, &args.out)?;
    print!("{table}");
    Ok(())
}

fn tradeoff_report(args: &TradeoffArgs) -> Result<(), HostError> {
    let scene = match args.sphereflake {
        Some(levels) if levels > 3 => return Err(input("--sphereflake takes 0 to 3 generations")),
        Some(levels) => lab::scenes::sphereflake(levels, args.array)?,
        None => host_tool::args::load_scene_for(&args.scene, args.array)?,
    };
    let cfg = if args.quick {
        lab::tradeoff::TradeoffConfig { array: args.array, ..lab::tradeoff::TradeoffConfig::quick() }
    } else {
        lab::tradeoff::TradeoffConfig {
            array: args.array,
            ..lab::tradeoff::TradeoffConfig::full(args.scene.size)
        }
    };
    let md = lab::tradeoff::report(&scene, &cfg, &args.out, args.spot_check)?;
    print!("{md}");
    Ok(())
}
