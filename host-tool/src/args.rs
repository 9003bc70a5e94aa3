//! The command-line options the host's commands share (the scene, the
//! in-memory board's links), parsed into the library's values, and how a
//! usage error is shown.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, ValueEnum};

use crate::error::HostError;
use crate::plan::options::RenderOptions;
use crate::scene::{Reading, Scene, SceneFormat};

/// The scene: a file, a random scene like the paper's, or the demo; and the image size.
#[derive(Args, Clone)]
pub struct SceneArgs {
    /// Scene file: JSON (schema in docs/cli.md), or NFF if it ends in .nff. Without it, a random scene is made.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["spheres", "seed", "volume_ratio"])]
    pub scene: Option<PathBuf>,
    /// Random scene: number of spheres.
    #[arg(long, value_name = "N")]
    pub spheres: Option<usize>,
    /// Random scene: seed.
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,
    /// Random scene: volume ratio of the cube the spheres are confined to, (0, 1].
    #[arg(long, value_name = "V")]
    pub volume_ratio: Option<f64>,
    /// Grid size: of a random scene [default: 32x32x32], or the one a scene is fitted into [default: chosen
    /// from the scene].
    #[arg(long, value_name = "XxYxZ", value_parser = parse_triple)]
    pub grid: Option<[u16; 3]>,
    /// Fit a JSON scene into the grid (scale and offset); NFF scenes always are.
    #[arg(long, requires = "scene")]
    pub fit: bool,
    /// Leave out NFF primitives that cannot be rendered (cones, polygons), with a warning, instead of refusing
    /// the file.
    #[arg(long, requires = "scene")]
    pub skip_unsupported: bool,
    /// Image size.
    #[arg(long, value_name = "WxH", value_parser = parse_pair, default_value = "256x256")]
    pub size: [u16; 2],
    /// Samples per pixel on a regular grid, a square (1, 4, 9, ..., 64): each
    /// pixel is the mean of that many rays (antialiasing, at that many times the work).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub samples: u16,
}

/// The links of the in-memory board: a preset, and settings that override it.
#[derive(Args, Clone)]
pub struct LinkArgs {
    /// Links of the in-memory board: f413 (NUCLEO-F413ZH boards: 100 MHz,
    /// neighbour USARTs at 3.125 Mbaud and the host's at 921 600 baud, every
    /// link's bytes moved by DMA),
    /// ideal (25 cycles a byte, no CPU per byte) or emulated (the QEMU
    /// boards: polled UARTs, the loop's pass charged) [default: f413].
    #[arg(long, value_name = "PRESET", value_parser = crate::session::links::preset_named)]
    pub link: Option<sim_board::LinkPreset>,
    /// Core clock of the nodes, MHz (overrides the preset's).
    #[arg(long, value_name = "MHZ")]
    pub clock_mhz: Option<f64>,
    /// Line rate of the neighbour links, baud (10 bits a byte).
    #[arg(long, value_name = "BAUD")]
    pub baud: Option<u64>,
    /// Line rate of the host links, baud.
    #[arg(long, value_name = "BAUD")]
    pub host_baud: Option<u64>,
    /// How the nodes move the bytes of their neighbour links between UARTs
    /// and memory (the host link's is the preset's).
    #[arg(long, value_enum)]
    pub transfer: Option<TransferChoice>,
}

impl LinkArgs {
    /// Whether any link setting was given.
    pub fn given(&self) -> bool {
        self.link.is_some()
            || self.clock_mhz.is_some()
            || self.baud.is_some()
            || self.host_baud.is_some()
            || self.transfer.is_some()
    }

    /// Sets `opts`'s links.
    pub fn apply(&self, opts: &mut RenderOptions) -> Result<(), HostError> {
        let clock_hz = match self.clock_mhz {
            Some(mhz) if !mhz.is_finite() => {
                return Err(HostError::NonFinite(format!("--clock-mhz must be a number, got {mhz}")));
            }
            Some(mhz) => Some((mhz * 1e6).round().clamp(0.0, u64::MAX as f64) as u64),
            None => None,
        };
        let choice = crate::session::links::LinkChoice {
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
        choice.apply(opts)
    }
}

/// How a node moves a byte between a UART and memory.
#[derive(Clone, Copy, ValueEnum)]
pub enum TransferChoice {
    /// The main loop polls each UART (16 cycles a byte).
    Polled,
    /// An interrupt per byte (51 cycles a byte).
    Interrupt,
    /// DMA (no CPU cycles per byte, 70 a frame).
    Dma,
}

/// `--driving-axis`: which axis the boundaries slide along and the preview
/// fit's rows run along.
#[derive(Clone, Copy, ValueEnum)]
pub enum AxisChoice {
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

impl AxisChoice {
    /// The axis for `scene`, or `None` for the paper's rule (the plan applies it).
    pub fn resolve(self, scene: &Scene) -> Option<u8> {
        match self {
            AxisChoice::Auto => None,
            AxisChoice::View => Some(crate::plan::partition::view_axis(scene)),
            AxisChoice::X => Some(0),
            AxisChoice::Y => Some(1),
            AxisChoice::Z => Some(2),
        }
    }
}

/// Help and version go to stdout as clap writes them. A usage error leads
/// with the one line that says what is wrong, then clap's tip and its pointer
/// to `--help`, without the usage block and blank lines between; exit 2.
pub fn usage_error(e: &clap::Error) -> ExitCode {
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
pub const DEMO_SPHERES: usize = 400;
/// The demo scene's seed.
pub const DEMO_SEED: u64 = 1986;

/// Where the scene came from, for the run summary.
pub fn scene_source(args: &SceneArgs, scene: &Scene) -> serde_json::Value {
    let spheres = scene.spheres.len();
    match &args.scene {
        Some(path) => serde_json::json!({
            "source": "file", "path": path.display().to_string(),
            "format": match SceneFormat::of(path) { SceneFormat::Nff => "nff", SceneFormat::Json => "json" },
            "fitted": args.fit || SceneFormat::of(path) == SceneFormat::Nff, "spheres": spheres,
        }),
        None if is_demo(args) => {
            serde_json::json!({"source": "demo", "spheres": spheres, "seed": DEMO_SEED, "volume_ratio": 1.0})
        }
        None => serde_json::json!({
            "source": "random", "spheres": spheres, "seed": args.seed.unwrap_or(1),
            "volume_ratio": args.volume_ratio.unwrap_or(1.0),
        }),
    }
}

/// The scene the options describe: a file, a random scene, or the built-in demo.
pub fn load_scene(args: &SceneArgs) -> Result<Scene, HostError> {
    load_scene_for(args, [1; 3])
}

/// The scene the options describe, for an array: a grid chosen from the
/// scene gives each node at least [`crate::scene::fit::CUBES_PER_NODE`]
/// cubes along each axis.
pub fn load_scene_for(args: &SceneArgs, array: [u16; 3]) -> Result<Scene, HostError> {
    if let Some(path) = &args.scene {
        let how = Reading {
            fit: args.fit,
            grid: args.grid,
            at_least: crate::scene::fit::at_least_for(array),
            skip_unsupported: args.skip_unsupported,
        };
        let (scene, warnings) = Scene::read(path, &how)?;
        for warning in warnings {
            eprintln!("warning: {warning}");
        }
        return Ok(scene);
    }
    let (count, seed, ratio) = if is_demo(args) {
        (DEMO_SPHERES, DEMO_SEED, 1.0)
    } else {
        (args.spheres.unwrap_or(1000), args.seed.unwrap_or(1), args.volume_ratio.unwrap_or(1.0))
    };
    Scene::random(count, seed, ratio, args.grid.unwrap_or([32; 3]))
}

/// Whether the options leave the scene to the demo.
fn is_demo(args: &SceneArgs) -> bool {
    args.spheres.is_none() && args.seed.is_none() && args.volume_ratio.is_none()
}

/// `--node-timeout`'s seconds as a time-out, or why they are not one.
pub fn node_timeout(seconds: f64) -> Result<std::time::Duration, HostError> {
    if seconds.is_finite() && seconds > 0.0 && seconds < 1e6 {
        Ok(std::time::Duration::from_secs_f64(seconds))
    } else {
        Err(crate::error::input(format!(
            "--node-timeout must be a positive number of seconds, got {seconds}"
        )))
    }
}

/// `XxYxZ`, such as an array or a grid.
pub fn parse_triple(s: &str) -> Result<[u16; 3], String> {
    let parts: Vec<&str> = s.split('x').collect();
    match parts.as_slice() {
        [a, b, c] => Ok([num(a)?, num(b)?, num(c)?]),
        _ => Err(format!("expected XxYxZ such as 4x4x4, got '{s}'")),
    }
}

/// `WxH`, such as an image size.
pub fn parse_pair(s: &str) -> Result<[u16; 2], String> {
    let parts: Vec<&str> = s.split('x').collect();
    match parts.as_slice() {
        [a, b] => Ok([num(a)?, num(b)?]),
        _ => Err(format!("expected WxH such as 256x256, got '{s}'")),
    }
}

fn num(s: &str) -> Result<u16, String> {
    s.trim().parse::<u16>().map_err(|_| format!("'{s}' is not a whole number from 0 to 65535"))
}

/// Parses `--faults`: per-frame probabilities `corrupt=P,drop=P,dup=P,delay=P` and `seed=N`.
pub fn parse_faults(s: &str) -> Result<sim_board::Faults, String> {
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
