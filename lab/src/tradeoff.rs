//! `lab report tradeoff`: error against run time on any scene, over the
//! settings a user can turn to trade quality for time.
//!
//! Every setting renders the scene with the node kernels (the direct
//! renderer, which makes the array's image bit for bit) and is measured
//! against an f64 reference of the same scene (its own reflection depth: a
//! setting that reflects deeper renders another image) at high sampling:
//! - error: per-pixel error of the 8-bit sRGB image (mean, p99, max over
//!   pixels and channels) and PSNR, and at the sample positions the primary
//!   hits' agreement and depth and normal errors;
//! - run time, in units the machine's load does not move: instructions on the
//!   emulated Cortex-M3, per frame and per ray, from the in-memory board's
//!   cost model (the kernels' counts of `scripts/firmware.sh`) as one node
//!   spends them, and the makespan in virtual cycles on a chosen array. Host
//!   nanoseconds per ray stand beside them, noisy.
//!
//! The settings: samples per pixel, reflection depth, grid resolution (the
//! scene fitted into a grid of that many cubes a side) and the arithmetic
//! variants of the numerics report. The sweep crosses samples with depth at
//! the scene's grid, then moves the grid and the arithmetic one at a time.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use host_tool::compare::{Comparison, compare};
use host_tool::error::{HostError, input};
use host_tool::plan::direct;
use host_tool::plan::options::RenderOptions;
use host_tool::reference::{self, RefImage};
use host_tool::results::image::srgb8;
use host_tool::results::output::write_all_atomic;
use host_tool::results::plot::{Chart, Series, Style, png};
use host_tool::scene::Scene;
use host_tool::session::links::LinkChoice;
use host_tool::session::sim::render_sim;
use sim_board::{CostModel, LinkPreset};

use crate::numerics::variants::{float_as_direct, pareto, positions_rounded};

/// How the numbers are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arithmetic {
    /// The nodes' own: Q16.16 positions, Q2.30 directions.
    Shipped,
    /// Positions, radii, eye and lights stored with 12 fraction bits.
    PositionsQ12,
    /// Primary directions stepped in 16-bit fractions.
    CameraQ16,
    /// The reference algorithm in single precision, walking the grid's
    /// cubes as the nodes do.
    F32,
}

impl Arithmetic {
    /// The name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Self::Shipped => "fixed-q16.16-q2.30",
            Self::PositionsQ12 => "fixed-pos-q.12",
            Self::CameraQ16 => "fixed-camera-q2.16",
            Self::F32 => "f32",
        }
    }
}

/// One point of the sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Setting {
    /// Samples per pixel (a square).
    pub samples: u16,
    /// Reflection depth.
    pub max_depth: u8,
    /// The grid the scene is fitted into; `None`: the scene's own.
    pub grid: Option<[u16; 3]>,
    /// The arithmetic.
    pub arithmetic: Arithmetic,
}

impl Setting {
    /// `render`'s: one sample, the scene's depth and grid, the nodes' arithmetic.
    pub fn default_for(scene: &Scene) -> Self {
        Self { samples: 1, max_depth: scene.max_depth, grid: None, arithmetic: Arithmetic::Shipped }
    }

    fn label(&self, scene: &Scene) -> String {
        let grid = self.grid.unwrap_or(scene.grid);
        format!(
            "{} spp, depth {}, grid {}x{}x{}, {}",
            self.samples,
            self.max_depth,
            grid[0],
            grid[1],
            grid[2],
            self.arithmetic.name()
        )
    }
}

/// What to sweep and how.
#[derive(Debug, Clone)]
pub struct TradeoffConfig {
    /// Image size.
    pub size: [u16; 2],
    /// Samples per pixel tried.
    pub samples: Vec<u16>,
    /// Reflection depths tried.
    pub depths: Vec<u8>,
    /// Grids tried, as factors of the scene's cubes along each axis.
    pub grids: Vec<f64>,
    /// Arithmetic variants tried beside the nodes'.
    pub variants: Vec<Arithmetic>,
    /// Samples per axis of the reference.
    pub reference_side: u16,
    /// The array the makespans are measured on.
    pub array: [u16; 3],
}

impl TradeoffConfig {
    /// The full sweep at `size`.
    pub fn full(size: [u16; 2]) -> Self {
        Self {
            size,
            samples: vec![1, 4, 9, 16],
            depths: vec![1, 2, 3, 4],
            grids: vec![0.5, 0.75, 1.5],
            variants: vec![Arithmetic::PositionsQ12, Arithmetic::CameraQ16, Arithmetic::F32],
            reference_side: 8,
            array: [4, 4, 4],
        }
    }

    /// A reduced sweep for the test command.
    pub fn quick() -> Self {
        Self {
            size: [32, 32],
            samples: vec![1, 4],
            depths: vec![2, 3],
            grids: vec![0.5],
            variants: vec![Arithmetic::PositionsQ12, Arithmetic::CameraQ16],
            reference_side: 4,
            array: [2, 2, 2],
        }
    }

    /// Every setting, the default first.
    pub fn settings(&self, scene: &Scene) -> Vec<Setting> {
        let default = Setting::default_for(scene);
        let mut out = vec![default];
        let mut add = |s: Setting| {
            if !out.contains(&s) {
                out.push(s);
            }
        };
        for &samples in &self.samples {
            for &max_depth in &self.depths {
                add(Setting { samples, max_depth, ..default });
            }
        }
        for &factor in &self.grids {
            let grid = scene.grid.map(|n| (f64::from(n) * factor).round().clamp(1.0, 256.0) as u16);
            add(Setting { grid: Some(grid), ..default });
        }
        for &arithmetic in &self.variants {
            add(Setting { arithmetic, ..default });
        }
        out
    }
}

/// Error of an image against the reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageError {
    /// Mean absolute error per pixel and channel, 8-bit sRGB levels.
    pub mean: f64,
    /// Its 99th percentile.
    pub p99: f64,
    /// Its largest.
    pub max: f64,
    /// Peak signal-to-noise ratio, dB.
    pub psnr_db: f64,
}

impl ImageError {
    fn of(image: &[u8], reference: &[u8]) -> Self {
        let mut d: Vec<f64> = image.iter().zip(reference).map(|(&a, &b)| f64::from(a.abs_diff(b))).collect();
        let n = d.len().max(1) as f64;
        let mean = d.iter().sum::<f64>() / n;
        let mse = d.iter().map(|e| e * e).sum::<f64>() / n;
        d.sort_by(f64::total_cmp);
        Self {
            mean,
            p99: d.get(d.len() * 99 / 100).copied().unwrap_or(0.0),
            max: d.last().copied().unwrap_or(0.0),
            psnr_db: if mse == 0.0 { f64::INFINITY } else { 10.0 * (255.0 * 255.0 / mse).log10() },
        }
    }
}

/// One setting's measurements.
#[derive(Debug, Clone)]
pub struct Point {
    /// The setting.
    pub setting: Setting,
    /// Its description.
    pub label: String,
    /// Error against the reference.
    pub error: ImageError,
    /// Primary hits, depth and normals against the reference's, at the
    /// sample positions.
    pub hits: Comparison,
    /// Rays traced.
    pub rays: u64,
    /// Cortex-M3 instructions one node spends on the frame (the cost model);
    /// `None` for arithmetic the nodes do not run.
    pub instructions: Option<u64>,
    /// Makespan on the config's array, virtual cycles; `None` where the
    /// in-memory board cannot run the setting.
    pub makespan: Option<u64>,
    /// Host nanoseconds per ray (noisy).
    pub host_ns_per_ray: f64,
}

impl Point {
    /// Instructions per ray.
    pub fn instructions_per_ray(&self) -> Option<f64> {
        self.instructions.map(|i| i as f64 / self.rays.max(1) as f64)
    }
}

/// The cost model of the emulated Cortex-M3 board: its kernels' instruction
/// counts and its loop's pass.
fn emulated_costs() -> CostModel {
    CostModel { pass: LinkPreset::Emulated.loop_pass(), ..CostModel::default() }
}

/// The scene a setting renders.
fn scene_for(base: &Scene, s: &Setting) -> Result<Scene, HostError> {
    let mut scene = geometry(base, s.grid)?;
    if s.arithmetic == Arithmetic::PositionsQ12 {
        scene = positions_rounded(&scene, 12);
    }
    scene.max_depth = s.max_depth;
    scene.validate()?;
    Ok(scene)
}

/// The scene as it is, or fitted into `grid`: what the references of the
/// settings on that grid render.
fn geometry(base: &Scene, grid: Option<[u16; 3]>) -> Result<Scene, HostError> {
    let mut scene = base.clone();
    if let Some(g) = grid {
        host_tool::scene::fit(&mut scene, Some(g))?;
    }
    Ok(scene)
}

/// The reference of a setting's geometry: the scene itself (its own
/// reflection depth: the image its author asked for), in f64, at `side` x
/// `side` samples a pixel.
fn reference_rgb(
    base: &Scene,
    grid: Option<[u16; 3]>,
    size: [u16; 2],
    side: u16,
) -> Result<Vec<u8>, HostError> {
    Ok(reference::rgb8_of(&reference::render_sampled(&geometry(base, grid)?, size, side)))
}

/// Measures one setting.
fn measure(
    base: &Scene,
    s: &Setting,
    cfg: &TradeoffConfig,
    refs: &mut References,
) -> Result<Point, HostError> {
    let scene = scene_for(base, s)?;
    let side = host_tool::results::image::sample_side(s.samples)?;
    let [tw, th] = host_tool::results::image::traced(cfg.size, s.samples)?;
    let started = Instant::now();
    let (img, instructions) = match s.arithmetic {
        Arithmetic::F32 => (float_as_direct(&reference::render_f32_walked(&scene, tw, th)), None),
        a => {
            let bits = if a == Arithmetic::CameraQ16 { 16 } else { 30 };
            let cost = emulated_costs();
            let (img, map) = direct::render_costed(&scene, tw, th, bits, &cost, direct::ByteCpu::default())?;
            let mut map = map;
            direct::add_initial_rays(&mut map, &scene, [tw, th], &cost, direct::ByteCpu::default(), true)?;
            let total = map.compute.iter().chain(&map.messages).sum::<u64>()
                + direct::fixed_cost(scene.spheres.len(), 0, &scene, &cost);
            (img, Some(total))
        }
    };
    let host_ns_per_ray = started.elapsed().as_secs_f64() * 1e9 / img.rays.max(1) as f64;
    let rgb = srgb8(&img.sums, tw, th, side);
    // Against the unrounded geometry: input rounding is part of a variant's error.
    let hits = {
        let geometry = geometry(base, s.grid)?;
        let at_samples = refs.at_samples(&geometry, s.grid, [tw, th])?;
        let fixed_rgb = srgb8(&img.sums, tw, th, 1);
        compare(&geometry, [tw, th], &img, &fixed_rgb, at_samples, &at_samples.rgb8())
    };
    let error = ImageError::of(&rgb, refs.image(base, s.grid)?);
    let makespan = match s.arithmetic {
        Arithmetic::Shipped | Arithmetic::PositionsQ12 => Some(makespan(&scene, s.samples, cfg)?),
        _ => None,
    };
    Ok(Point {
        setting: *s,
        label: s.label(base),
        error,
        hits,
        rays: img.rays,
        instructions,
        makespan,
        host_ns_per_ray,
    })
}

/// The references a sweep measures against, each rendered once: per grid
/// the finely sampled image, and per grid and traced size the f64 render at
/// the very samples (for primary hits, which do not depend on the depth).
struct References {
    size: [u16; 2],
    side: u16,
    images: Vec<(Option<[u16; 3]>, Vec<u8>)>,
    samples: Vec<(SamplesKey, RefImage)>,
}

/// A grid (`None`: the scene's own) and a traced size.
type SamplesKey = (Option<[u16; 3]>, [u16; 2]);

impl References {
    /// The finely sampled reference image of `base` on `grid`.
    fn image(&mut self, base: &Scene, grid: Option<[u16; 3]>) -> Result<&[u8], HostError> {
        let i = match self.images.iter().position(|(g, _)| *g == grid) {
            Some(i) => i,
            None => {
                self.images.push((grid, reference_rgb(base, grid, self.size, self.side)?));
                self.images.len() - 1
            }
        };
        Ok(&self.images[i].1)
    }

    /// The f64 render of `geometry` (the scene on `grid`) at `traced` samples.
    fn at_samples(
        &mut self,
        geometry: &Scene,
        grid: Option<[u16; 3]>,
        traced: [u16; 2],
    ) -> Result<&RefImage, HostError> {
        let key = (grid, traced);
        let i = match self.samples.iter().position(|(k, _)| *k == key) {
            Some(i) => i,
            None => {
                self.samples.push((key, reference::render(geometry, traced[0], traced[1])));
                self.samples.len() - 1
            }
        };
        Ok(&self.samples[i].1)
    }
}

/// The frame's makespan on the config's array with `render`'s defaults.
fn makespan(scene: &Scene, samples: u16, cfg: &TradeoffConfig) -> Result<u64, HostError> {
    let mut opts = RenderOptions::new(cfg.array);
    LinkChoice::default().apply(&mut opts)?;
    opts.size = cfg.size;
    opts.samples = samples;
    opts.balance = Some(host_tool::plan::options::DEFAULT_BALANCE);
    Ok(render_sim(scene, &opts)?.frame.makespan.0)
}

/// Every setting of `cfg` on `scene`, the default first.
pub fn sweep(scene: &Scene, cfg: &TradeoffConfig) -> Result<Vec<Point>, HostError> {
    let settings = cfg.settings(scene);
    let mut refs =
        References { size: cfg.size, side: cfg.reference_side, images: Vec::new(), samples: Vec::new() };
    let mut points = Vec::new();
    for s in &settings {
        let p = measure(scene, s, cfg, &mut refs).map_err(|e| e.context(&s.label(scene)))?;
        eprintln!(
            "{}: error {:.3} (PSNR {:.1} dB), {} instructions",
            p.label,
            p.error.mean,
            p.error.psnr_db,
            p.instructions.map_or("-".to_string(), |i| format!("{i:.3e}"))
        );
        points.push(p);
    }
    Ok(points)
}

/// Which run time a Pareto front is over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Time {
    /// Instructions one node spends on the frame: the work.
    Work,
    /// The makespan on the chosen array: what the user waits for.
    Array,
}

impl Time {
    fn of(self, p: &Point) -> Option<u64> {
        match self {
            Self::Work => p.instructions,
            Self::Array => p.makespan,
        }
    }
}

/// The points on the Pareto front of (`time`, mean error), by run time;
/// points without that time are off it.
pub fn front(points: &[Point], time: Time) -> Vec<usize> {
    let timed: Vec<usize> = (0..points.len()).filter(|&i| time.of(&points[i]).is_some()).collect();
    let xy: Vec<(f64, f64)> =
        timed.iter().map(|&i| (time.of(&points[i]).unwrap_or(0) as f64, points[i].error.mean)).collect();
    pareto(&xy).into_iter().map(|k| timed[k]).collect()
}

/// The CSV: one row per setting; the host-time column last (noisy: the
/// rest is the same on every run).
pub fn csv(points: &[Point]) -> String {
    let (work, array) = (front(points, Time::Work), front(points, Time::Array));
    let mut s = String::from(
        "samples,max_depth,grid,arithmetic,default,front_work,front_array,rays,instructions_per_frame,instructions_per_ray,\
         makespan_cycles,error_mean,error_p99,error_max,psnr_db,hit_agreement,gross_mismatches,depth_error_p99,\
         normal_error_max_deg,host_ns_per_ray_noisy\n",
    );
    for (i, p) in points.iter().enumerate() {
        let st = &p.setting;
        let opt = |v: Option<String>| v.unwrap_or_default();
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{:.4},{:.1},{:.1},{:.2},{:.6},{},{:.3e},{:.3e},{:.0}",
            st.samples,
            st.max_depth,
            st.grid.map_or("scene".to_string(), |g| format!("{}x{}x{}", g[0], g[1], g[2])),
            st.arithmetic.name(),
            i == 0,
            work.contains(&i),
            array.contains(&i),
            p.rays,
            opt(p.instructions.map(|v| v.to_string())),
            opt(p.instructions_per_ray().map(|v| format!("{v:.1}"))),
            opt(p.makespan.map(|v| v.to_string())),
            p.error.mean,
            p.error.p99,
            p.error.max,
            p.error.psnr_db,
            p.hits.hit_agreement,
            p.hits.gross_mismatches,
            p.hits.depth_error_p99,
            p.hits.normal_error_max_deg,
            p.host_ns_per_ray
        );
    }
    s
}

/// The Markdown table.
pub fn markdown(points: &[Point], cfg: &TradeoffConfig) -> String {
    let (work, array) = (front(points, Time::Work), front(points, Time::Array));
    let [x, y, z] = cfg.array;
    let mut s = format!(
        "Error against a {}-sample f64 reference of the scene (its own depth), {}x{} pixels; instructions on the \
         emulated Cortex-M3 for one node (cost model); makespan on {x}x{y}x{z} with `render`'s defaults. \
         **bold**: the default. Front: not beaten on both run time and mean error, with the run time the \
         work (instructions) or the array's makespan.\n\n",
        cfg.reference_side * cfg.reference_side,
        cfg.size[0],
        cfg.size[1]
    );
    s.push_str(
        "| setting | instructions / frame | / ray | makespan (cycles) | mean error | p99 | max | PSNR (dB) | hits agree | front |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    for (i, p) in points.iter().enumerate() {
        let label = if i == 0 { format!("**{}**", p.label) } else { p.label.clone() };
        let _ = writeln!(
            s,
            "| {label} | {} | {} | {} | {:.2} | {:.0} | {:.0} | {:.1} | {:.4} | {} |",
            p.instructions.map_or("-".to_string(), |v| format!("{v:.3e}")),
            p.instructions_per_ray().map_or("-".to_string(), |v| format!("{v:.0}")),
            p.makespan.map_or("-".to_string(), |v| format!("{v:.3e}")),
            p.error.mean,
            p.error.p99,
            p.error.max,
            p.error.psnr_db,
            p.hits.hit_agreement,
            match (work.contains(&i), array.contains(&i)) {
                (true, true) => "work, array",
                (true, false) => "work",
                (false, true) => "array",
                (false, false) => "",
            }
        );
    }
    s
}

/// Error against each run time, the fronts drawn and the default marked.
fn chart(points: &[Point]) -> Result<Vec<u8>, HostError> {
    let panel = |time: Time| {
        let xy = |p: &Point| time.of(p).map(|t| (t as f64, p.error.mean.max(1e-3)));
        let series = vec![
            Series {
                name: "settings".into(),
                points: points.iter().skip(1).filter_map(xy).collect(),
                style: Style::Markers,
            },
            Series {
                name: "default".into(),
                points: points.iter().take(1).filter_map(xy).collect(),
                style: Style::Highlight,
            },
            Series {
                name: "Pareto front".into(),
                points: front(points, time).iter().filter_map(|&i| xy(&points[i])).collect(),
                style: Style::Line,
            },
        ];
        let (title, x_label) = match time {
            Time::Work => {
                ("Mean image error against the work", "instructions per frame (one node, emulated Cortex-M3)")
            }
            Time::Array => ("Mean image error against the array's makespan", "makespan (virtual cycles)"),
        };
        let chart = Chart {
            title: title.into(),
            x_label: x_label.into(),
            y_label: "mean error (8-bit sRGB levels)".into(),
            log_x: true,
            log_y: true,
        };
        (chart, series)
    };
    png(&[panel(Time::Work), panel(Time::Array)], 900, 420)
}

/// The default setting's instructions on the emulated board itself: one
/// mps2-an385 under QEMU renders the frame, and its node's running count
/// (instructions, the emulator counting them) stands beside the cost model's.
pub fn spot_check(scene: &Scene, cfg: &TradeoffConfig, estimate: u64) -> Result<String, HostError> {
    use host_tool::session::backend::{Backend, Rendered, render};
    use host_tool::session::qemu::EmulatedBoard;
    let board = EmulatedBoard::Mps2An385;
    let backend = Backend::Qemu { board, firmware: board.default_firmware() };
    let mut opts = RenderOptions::new([1, 1, 1]);
    opts.size = cfg.size;
    let Rendered::Boards(r) = render(scene, &opts, &backend, std::time::Duration::from_secs(60))? else {
        return Err(input("the spot check runs on an emulated board"));
    };
    let running = r.frame.loads.first().copied().flatten().map_or(0, |l| l.running);
    Ok(format!(
        "Spot check of the default on one emulated mps2-an385 (QEMU, instructions counted): {running} \
         instructions ran, the cost model charges {estimate} ({:+.1}%).\n",
        100.0 * (estimate as f64 / running.max(1) as f64 - 1.0)
    ))
}

/// Runs the sweep and writes `tradeoff.csv`, `tradeoff.md` and
/// `tradeoff.png` into `out` (all or none); returns the Markdown table.
pub fn report(scene: &Scene, cfg: &TradeoffConfig, out: &Path, spot: bool) -> Result<String, HostError> {
    if cfg.samples.is_empty() || cfg.depths.is_empty() {
        return Err(input("the sweep needs at least one sample count and one depth"));
    }
    let files = crate::outputs(out, ["tradeoff.csv", "tradeoff.md", "tradeoff.png"])?;
    let points = sweep(scene, cfg)?;
    let mut table = markdown(&points, cfg);
    if spot && let Some(estimate) = points.first().and_then(|p| p.instructions) {
        table.push('\n');
        table.push_str(&spot_check(scene, cfg, estimate)?);
    }
    let [c, m, p] = &files;
    write_all_atomic(&[(c, csv(&points).as_bytes()), (m, table.as_bytes()), (p, &chart(&points)?)])?;
    Ok(table)
}
