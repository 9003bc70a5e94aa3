//! `bench animation`: a camera orbit rendered as one sequence per balancing
//! mode, on the in-memory board: how even the frames are once the
//! boundaries have settled, what the whole sequence costs, and how many
//! frames sliding needs to get there from the even partition.
//!
//! The modes: the paper's rule and the proportional policy, each carrying
//! its boundaries from frame to frame; a static partition fitted to each
//! frame's own preview (the preview rendered on the host every frame, the
//! scene sent again whenever the fit moves a boundary); and static even
//! boxes. Beside them, each steady frame's floor ([`floor`]): the least
//! busiest node any partition the nodes route could have.

pub mod floor;

use std::fmt::Write as _;
use std::path::Path;

use rayon::prelude::*;

use host_tool::error::HostError;
use host_tool::plan::options::{Layout, PROPORTIONAL, RenderOptions};
use host_tool::results::RenderResult;
use host_tool::results::output::write_all_atomic;
use host_tool::results::plot::{Chart, Series, Style, png};
use host_tool::results::sequence::FrameRow;
use host_tool::scene::Scene;
use host_tool::scene::path::CameraPath;
use host_tool::session::sequence::{self, FrameStart, Sequence};
use link_proto::{Balance, SlidePolicy};

use floor::{FrameFloor, frame_floors};

/// How boundaries are set over a sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// The paper's rule (one cube a step), carried from frame to frame.
    Paper,
    /// The proportional policy (render's default), carried.
    Proportional,
    /// Static boxes fitted to each frame's preview.
    PreviewPerFrame,
    /// Static even boxes.
    Static,
}

impl Mode {
    /// Every mode, in table order.
    pub const ALL: [Mode; 4] = [Mode::Paper, Mode::Proportional, Mode::PreviewPerFrame, Mode::Static];

    /// The name tables and plots give it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper, carried",
            Self::Proportional => "proportional, carried",
            Self::PreviewPerFrame => "preview fit per frame",
            Self::Static => "static, even",
        }
    }

    /// `base` set up for this mode, and where each frame starts.
    fn options(self, base: &RenderOptions) -> (RenderOptions, FrameStart) {
        let mut o = *base;
        let slide = |policy| Some(Balance { policy, ..base.balance.unwrap_or(DEFAULT_BALANCE) });
        match self {
            Self::Paper => (RenderOptions { balance: slide(SlidePolicy::Paper), ..o }, FrameStart::Carried),
            Self::Proportional => (RenderOptions { balance: slide(PROPORTIONAL), ..o }, FrameStart::Carried),
            Self::PreviewPerFrame => {
                o.balance = None;
                o.layout = Layout::Preview;
                (o, FrameStart::Planned)
            }
            Self::Static => {
                o.balance = None;
                o.layout = Layout::Even;
                (o, FrameStart::Carried)
            }
        }
    }
}

/// `render`'s sliding: its interval and threshold.
const DEFAULT_BALANCE: Balance = host_tool::plan::options::DEFAULT_BALANCE;

/// What to run.
#[derive(Debug, Clone)]
pub struct AnimationConfig {
    /// Arrays, each with every mode.
    pub arrays: Vec<[u16; 3]>,
    /// Frames of the orbit.
    pub frames: u32,
    /// Degrees the camera turns over the sequence.
    pub degrees: f64,
    /// Frames from this one on are the steady state.
    pub steady_from: u32,
    /// Image, links and the rest (array, balance and layout set per run).
    pub base: RenderOptions,
}

/// One sequence's figures.
#[derive(Debug, Clone)]
pub struct AnimationRun {
    /// The array.
    pub array: [u16; 3],
    /// The mode.
    pub mode: Mode,
    /// One row per frame.
    pub frames: Vec<FrameRow>,
    /// Per frame, the least imbalance boundaries sliding along the driving
    /// axis could reach with the frame's loads ([`row_bound`]).
    pub row_bounds: Vec<f64>,
}

impl AnimationRun {
    fn steady(&self, from: u32) -> impl Iterator<Item = &FrameRow> {
        self.frames.iter().filter(move |r| r.frame >= from)
    }

    /// Mean imbalance over the steady frames.
    pub fn steady_imbalance(&self, from: u32) -> f64 {
        let (n, sum) = self.steady(from).fold((0, 0.0), |(n, s), r| (n + 1, s + r.imbalance));
        sum / f64::from(n.max(1))
    }

    /// Mean of [`row_bound`] over the steady frames.
    pub fn steady_row_bound(&self, from: u32) -> f64 {
        let steady = self.frames.iter().zip(&self.row_bounds).filter(|(r, _)| r.frame >= from);
        let (n, sum) = steady.fold((0, 0.0), |(n, s), (_, b)| (n + 1, s + b));
        sum / f64::from(n.max(1))
    }

    /// Mean makespan over the steady frames.
    pub fn steady_makespan(&self, from: u32) -> f64 {
        let (n, sum) = self.steady(from).fold((0, 0.0), |(n, s), r| (n + 1, s + r.makespan as f64));
        sum / f64::from(n.max(1))
    }

    /// All frames' makespans.
    pub fn total_makespan(&self) -> u64 {
        self.frames.iter().map(|r| r.makespan).sum()
    }

    /// Host seconds spent planning (the previews of a per-frame fit).
    pub fn planning_s(&self) -> f64 {
        self.frames.iter().map(|r| r.planning_ms).sum::<f64>() / 1e3
    }

    /// Host seconds the sequence waited for its plans (a frame planned
    /// afresh is planned while the frame before renders).
    pub fn plan_wait_s(&self) -> f64 {
        self.frames.iter().map(|r| r.plan_wait_ms).sum::<f64>() / 1e3
    }

    /// The first frame from which the imbalance stays within 5% of the
    /// steady mean.
    pub fn settled_at(&self, from: u32) -> Option<u32> {
        let bound = 1.05 * self.steady_imbalance(from);
        let last_above = self.frames.iter().rposition(|r| r.imbalance > bound);
        match last_above {
            None => self.frames.first().map(|r| r.frame),
            Some(i) => self.frames.get(i + 1).map(|r| r.frame),
        }
    }
}

/// Runs every array and mode (two at a time); writes `animation.csv`,
/// `animation.md` and `animation.png` to `out` (all or none) and returns
/// the Markdown table.
pub fn bench_animation(scene: &Scene, cfg: &AnimationConfig, out: &Path) -> Result<String, HostError> {
    let files = crate::outputs(out, ["animation.csv", "animation.md", "animation.png"])?;
    let runs = runs(scene, cfg)?;
    let floors = floors(scene, cfg)?;
    let table = markdown(cfg, &runs, &floors);
    let plot = chart(cfg, &runs)?;
    let [csv_path, md_path, png_path] = &files;
    write_all_atomic(&[
        (csv_path, csv(&runs, &floors).as_bytes()),
        (md_path, table.as_bytes()),
        (png_path, &plot),
    ])?;
    Ok(table)
}

/// Renders every array and mode of `cfg`.
pub fn runs(scene: &Scene, cfg: &AnimationConfig) -> Result<Vec<AnimationRun>, HostError> {
    let jobs: Vec<([u16; 3], Mode)> =
        cfg.arrays.iter().flat_map(|&a| Mode::ALL.into_iter().map(move |m| (a, m))).collect();
    jobs.into_par_iter().map(|(array, mode)| run(scene, cfg, array, mode)).collect()
}

/// Each array's floors over the steady frames.
#[derive(Debug, Clone)]
pub struct ArrayFloors {
    /// The array.
    pub array: [u16; 3],
    /// One per steady frame whose grid could be tabled.
    pub frames: Vec<FrameFloor>,
}

impl ArrayFloors {
    /// The floor of frame `k`, if it was found.
    pub fn of(&self, k: u32) -> Option<&FrameFloor> {
        self.frames.iter().find(|f| f.frame == k)
    }

    fn mean(&self, pick: impl Fn(&FrameFloor) -> f64) -> f64 {
        self.frames.iter().map(pick).sum::<f64>() / self.frames.len().max(1) as f64
    }

    /// The floors' mean busiest node, in cycles.
    pub fn mean_cycles(&self) -> f64 {
        self.mean(|f| f.cycles as f64)
    }

    /// The least, mean and largest of `pick` over the frames.
    pub fn spread(&self, pick: impl Fn(&FrameFloor) -> f64) -> [f64; 3] {
        let least = self.frames.iter().map(&pick).fold(f64::INFINITY, f64::min);
        let most = self.frames.iter().map(&pick).fold(0.0, f64::max);
        [least, self.mean(pick), most]
    }
}

/// Each array's floors over the steady frames of `cfg`'s orbit.
pub fn floors(scene: &Scene, cfg: &AnimationConfig) -> Result<Vec<ArrayFloors>, HostError> {
    let path = CameraPath::Orbit { degrees: cfg.degrees };
    let mut all = Vec::new();
    for &array in &cfg.arrays {
        let started = std::time::Instant::now();
        let found = frame_floors(scene, &cfg.base, (path, cfg.frames), array, cfg.steady_from)?;
        let floors = ArrayFloors { array, frames: found.into_iter().flatten().collect() };
        let [x, y, z] = array;
        eprintln!(
            "{x}x{y}x{z} floors of {} frames: imbalance {:.3}, {:.0} s",
            floors.frames.len(),
            floors.spread(|f| f.imbalance)[1],
            started.elapsed().as_secs_f64()
        );
        all.push(floors);
    }
    Ok(all)
}

fn run(scene: &Scene, cfg: &AnimationConfig, array: [u16; 3], mode: Mode) -> Result<AnimationRun, HostError> {
    let (mut opts, start) = mode.options(&cfg.base);
    opts.array = array;
    opts.sim.array = array;
    let sequence = Sequence { frames: cfg.frames, path: CameraPath::Orbit { degrees: cfg.degrees }, start };
    let mut board = host_tool::session::sim::board(&opts);
    let (mut frames, mut row_bounds) = (Vec::new(), Vec::new());
    let started = std::time::Instant::now();
    sequence::run(&mut board, scene, &opts, &sequence, |f| {
        frames.push(FrameRow::of(&f));
        row_bounds.push(row_bound(&f.result));
        Ok(())
    })
    .map_err(|e| e.context(&format!("{}x{}x{} {}", array[0], array[1], array[2], mode.name())))?;
    let run = AnimationRun { array, mode, frames, row_bounds };
    eprintln!(
        "{}x{}x{} {:24} steady imbalance {:.3}, makespans {:.3e}, {:.0} s",
        array[0],
        array[1],
        array[2],
        mode.name(),
        run.steady_imbalance(cfg.steady_from),
        run.total_makespan() as f64,
        started.elapsed().as_secs_f64()
    );
    Ok(run)
}

/// The least imbalance that sliding boundaries along the driving axis can
/// reach with a frame's loads: sliding moves work only within a row of
/// nodes along that axis, so at best each node of a row does the row's mean,
/// and the busiest row's mean over all nodes' mean bounds the imbalance from
/// below (for work that splits finely and costs the same wherever it runs).
pub fn row_bound<T>(r: &RenderResult<T>) -> f64 {
    let p = &r.partition;
    let d = usize::from(p.driving_axis);
    let per_row = f64::from(p.array[d]);
    let mut rows = vec![0.0; p.len() / usize::from(p.array[d].max(1))];
    let mut total = 0.0;
    for (id, load) in r.frame.loads.iter().enumerate() {
        let running = load.map_or(0.0, |l| l.running as f64);
        if let Some(row) = rows.get_mut(p.row_of(p.coord(id))) {
            *row += running;
        }
        total += running;
    }
    let mean = total / p.len().max(1) as f64;
    rows.iter().map(|row| row / per_row).fold(0.0, f64::max) / mean.max(f64::MIN_POSITIVE)
}

fn csv(runs: &[AnimationRun], floors: &[ArrayFloors]) -> String {
    let mut s = String::from(
        "array,mode,frame,makespan,imbalance,row_bound,floor_cycles,floor_imbalance,slides,messages,loaded,planning_ms,plan_wait_ms\n",
    );
    for run in runs {
        let [x, y, z] = run.array;
        let floors = floors.iter().find(|f| f.array == run.array);
        for (r, bound) in run.frames.iter().zip(&run.row_bounds) {
            let floor = floors.and_then(|f| f.of(r.frame));
            let (floor_cycles, floor_imbalance) = floor.map_or((String::new(), String::new()), |f| {
                (f.cycles.to_string(), format!("{:.4}", f.imbalance))
            });
            let _ = writeln!(
                s,
                "{x}x{y}x{z},\"{}\",{},{},{:.4},{bound:.4},{floor_cycles},{floor_imbalance},{},{},{},{:.1},{:.1}",
                run.mode.name(),
                r.frame,
                r.makespan,
                r.imbalance,
                r.slides,
                r.messages.unwrap_or(0),
                u8::from(r.loaded),
                r.planning_ms,
                r.plan_wait_ms
            );
        }
    }
    s
}

/// The summary per array and mode, headed by what ran.
pub fn markdown(cfg: &AnimationConfig, runs: &[AnimationRun], floors: &[ArrayFloors]) -> String {
    let o = &cfg.base;
    let from = cfg.steady_from;
    let mut s = format!(
        "An orbit of {} degrees in {} frames, {}x{}, `{}` links, on the in-memory board. Steady state: \
         frames {from} to {}. Imbalance: the busiest node's running time over the mean, per frame. \
         Row bound: the least imbalance sliding along the driving axis could reach with the \
         frame's loads (each row of nodes along it at its own mean). Over floor: the steady \
         makespan over the steady frames' mean floor (below). Settled: the first frame \
         from which the imbalance stays within 5% of its steady mean. Planning: host seconds \
         (the preview fit renders a preview and fits it per frame); waited: the part of them the \
         sequence waited for (a frame planned afresh is planned while the frame before renders; \
         two sequences run at a time, so they share the cores).\n\n",
        cfg.degrees,
        cfg.frames,
        o.size[0],
        o.size[1],
        o.link_preset.name(),
        cfg.frames.saturating_sub(1),
    );
    s.push_str(
        "| array | mode | steady imbalance | worst steady | row bound | steady makespan (cycles) | over floor | all frames (cycles) | settled at frame | slides | planning (s) | waited (s) |\n",
    );
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for run in runs {
        let [x, y, z] = run.array;
        let worst = run.steady(from).map(|r| r.imbalance).fold(0.0, f64::max);
        let settled = match run.mode {
            Mode::Paper | Mode::Proportional => run.settled_at(from).map_or("-".into(), |k| k.to_string()),
            _ => "-".into(),
        };
        let over_floor = floors
            .iter()
            .find(|f| f.array == run.array && !f.frames.is_empty())
            .map_or("-".into(), |f| format!("{:.3}", run.steady_makespan(from) / f.mean_cycles()));
        let _ = writeln!(
            s,
            "| {x}x{y}x{z} | {} | {:.3} | {worst:.3} | {:.3} | {:.3e} | {over_floor} | {:.3e} | {settled} | {} | {:.1} | {:.1} |",
            run.mode.name(),
            run.steady_imbalance(from),
            run.steady_row_bound(from),
            run.steady_makespan(from),
            run.total_makespan() as f64,
            run.frames.iter().map(|r| r.slides).sum::<usize>(),
            run.planning_s(),
            run.plan_wait_s()
        );
    }
    s.push_str(&floors_markdown(floors));
    s
}

/// The floors' table: per array, what no partition the nodes route can beat,
/// and what the partition reaching it gives on the board.
fn floors_markdown(floors: &[ArrayFloors]) -> String {
    let mut s = String::from(
        "\nFloor: per steady frame, the least busiest node of any partition the nodes can route \
         (planes across one axis, each slab its own columns, each row its own cuts, along any of the \
         three driving axes), priced by the frame's own full cost map, with what every node pays beside \
         its cubes. Its imbalance: that busiest node over its partition's mean node, as the map prices \
         them; a partition more even must do more work in all (for 1.05, the extra work shown). Run \
         alone: the frame rendered by itself (the whole scene sent first) on the floor's partition, \
         static, on the in-memory board. Least / mean / most over the steady frames.\n\n\
         | array | frames | floor, mean (cycles) | floor's imbalance | at most 1.05 | extra work for 1.05 | run alone: imbalance | at most 1.05 | run alone: makespan, mean (cycles) |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    let three = |[a, b, c]: [f64; 3]| format!("{a:.3} / {b:.3} / {c:.3}");
    for f in floors.iter().filter(|f| !f.frames.is_empty()) {
        let [x, y, z] = f.array;
        let under = |pick: fn(&FrameFloor) -> f64| f.frames.iter().filter(|&f| pick(f) <= GOAL).count();
        let [least_extra, mean_extra, most_extra] = f.spread(|f| 100.0 * f.extra_work_for(GOAL));
        let _ = writeln!(
            s,
            "| {x}x{y}x{z} | {} | {:.3e} | {} | {} | {least_extra:.1}% / {mean_extra:.1}% / {most_extra:.1}% | {} | {} | {:.3e} |",
            f.frames.len(),
            f.mean_cycles(),
            three(f.spread(|f| f.imbalance)),
            under(|f| f.imbalance),
            three(f.spread(|f| f.ran.imbalance)),
            under(|f| f.ran.imbalance),
            f.mean(|f| f.ran.makespan as f64),
        );
    }
    s
}

/// The steady imbalance the floors are held to: between what LAMMPS reaches
/// on measured time (1.08-1.14) and what GROMACS aims at (1.02).
const GOAL: f64 = 1.05;

fn chart(cfg: &AnimationConfig, runs: &[AnimationRun]) -> Result<Vec<u8>, HostError> {
    let panel = |array: [u16; 3], title: &str, y: &str, pick: fn(&FrameRow) -> f64| {
        let series = runs
            .iter()
            .filter(|r| r.array == array)
            .map(|r| Series {
                name: r.mode.name().into(),
                points: r.frames.iter().map(|f| (f64::from(f.frame), pick(f))).collect(),
                style: Style::Line,
            })
            .collect();
        let [x, y_, z] = array;
        let chart = Chart {
            title: format!("{title}, {x}x{y_}x{z}"),
            x_label: "frame".into(),
            y_label: y.into(),
            log_x: false,
            log_y: false,
        };
        (chart, series)
    };
    let panels: Vec<_> = cfg
        .arrays
        .iter()
        .flat_map(|&a| {
            [
                panel(a, "Imbalance per frame", "busiest / mean running time", |r| r.imbalance),
                panel(a, "Makespan per frame", "makespan (cycles)", |r| r.makespan as f64),
            ]
        })
        .collect();
    png(&panels, 900, 320)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Splits a CSV line into its fields, a quoted field taken whole.
    fn fields(line: &str) -> Vec<String> {
        let (mut out, mut field, mut quoted) = (Vec::new(), String::new(), false);
        for c in line.chars() {
            match c {
                '"' => quoted = !quoted,
                ',' if !quoted => out.push(std::mem::take(&mut field)),
                _ => field.push(c),
            }
        }
        out.push(field);
        out
    }

    #[test]
    fn every_csv_row_has_the_header_s_fields_whatever_the_mode_is_called() {
        let row = FrameRow {
            frame: 3,
            makespan: 1000,
            imbalance: 1.5,
            slides: 2,
            messages: Some(9),
            neighbour_bytes: 0,
            host_bytes: 0,
            rays: 10,
            loaded: false,
            planning_ms: 0.0,
            plan_wait_ms: 0.0,
            link_troubles: Default::default(),
        };
        let runs: Vec<AnimationRun> = Mode::ALL
            .into_iter()
            .map(|mode| AnimationRun {
                array: [2; 3],
                mode,
                frames: vec![row.clone()],
                row_bounds: vec![1.2],
            })
            .collect();
        let ran = floor::Ran { makespan: 900, imbalance: 1.1 };
        let floors = [ArrayFloors {
            array: [2; 3],
            frames: vec![FrameFloor { frame: 3, cycles: 800, imbalance: 1.05, ran }],
        }];
        let text = csv(&runs, &floors);
        let mut lines = text.lines().map(fields);
        let header = lines.next().expect("a header");
        let slides = header.iter().position(|h| h == "slides").expect("a slides column");
        let floor = header.iter().position(|h| h == "floor_cycles").expect("a floor column");
        let rows: Vec<Vec<String>> = lines.collect();
        assert_eq!(rows.len(), Mode::ALL.len());
        for (r, mode) in rows.iter().zip(Mode::ALL) {
            assert_eq!(r.len(), header.len(), "{r:?}");
            assert_eq!(r[1], mode.name());
            assert_eq!((r[slides].as_str(), r[floor].as_str()), ("2", "800"));
        }
    }
}
