//! `lab results`: the tables of docs/results.md, made from scratch on the
//! in-memory board (virtual cycles, so every run makes the same bytes), and
//! the check that the checked-in copy is still what the code makes.
//!
//! Each table sits between `<!-- table:NAME -->` and `<!-- end:NAME -->`, so
//! the check can name the one that went stale. The commit line is left out
//! of the comparison: it says where the tables were made.

use std::fmt::Write as _;

use host_tool::error::HostError;
use host_tool::plan::options::{DEFAULT_BALANCE, Initial, Layout, RenderOptions};
use host_tool::scene::Scene;
use host_tool::session::links::LinkChoice;
use host_tool::session::sim::render_sim;
use link_proto::SlidePolicy;
use sim_board::LinkPreset;

use crate::scaling::{ScalingConfig, markdown, rows};

/// One generated table.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Table {
    /// Its marker name.
    pub name: &'static str,
    /// Its heading.
    pub title: &'static str,
    /// What it shows and how it was made (before the table).
    pub about: &'static str,
    /// The table itself.
    pub body: String,
}

/// Every table of docs/results.md, rendered now (about a minute in release).
pub fn tables() -> Result<Vec<Table>, HostError> {
    Ok(vec![
        defaults()?,
        initial_rays()?,
        scaling(LinkPreset::Ideal)?,
        scaling(LinkPreset::F413)?,
        tradeoff()?,
    ])
}

/// The document: a stamp, then each table under its heading.
pub fn document(commit: &str, tables: &[Table]) -> String {
    let mut s = String::from("# Results\n\n");
    let _ = writeln!(
        s,
        "Made by `cargo run --release -p lab -- results` at commit {commit}, in units the machine does \
         not move (virtual cycles of the in-memory board, Cortex-M3 instructions of its cost model, \
         image errors): the same code makes the same tables on any machine. The test \
         `docs_results_md_is_current` (lab/tests/results.rs) fails when a table below is no \
         longer what the code makes; run the command again and commit the file.\n"
    );
    for t in tables {
        let _ = write!(
            s,
            "## {}\n\n{}\n\n<!-- table:{} -->\n{}<!-- end:{} -->\n\n",
            t.title, t.about, t.name, t.body, t.name
        );
    }
    s.truncate(s.trim_end().len());
    s.push('\n');
    s
}

/// The names of the tables whose copy in `doc` differs from `tables` (or is missing).
pub fn stale<'a>(doc: &str, tables: &'a [Table]) -> Vec<&'a str> {
    tables.iter().filter(|t| section(doc, t.name) != Some(t.body.as_str())).map(|t| t.name).collect()
}

/// The text between a table's markers.
fn section<'d>(doc: &'d str, name: &str) -> Option<&'d str> {
    let start = format!("<!-- table:{name} -->\n");
    let end = format!("<!-- end:{name} -->");
    let from = doc.find(&start)? + start.len();
    let len = doc.get(from..)?.find(&end)?;
    doc.get(from..from + len)
}

/// The paper's scene: 1000 random spheres (volume ratio 1) in a 32^3 grid.
fn paper_scene(seed: u64) -> Result<Scene, HostError> {
    Scene::random(1000, seed, 1.0, [32; 3])
}

/// Options on a 4x4x4 array at 256x256 with the links of `preset`.
fn options(array: [u16; 3], preset: LinkPreset) -> Result<RenderOptions, HostError> {
    let mut opts = RenderOptions::new(array);
    LinkChoice { preset, ..LinkChoice::default() }.apply(&mut opts)?;
    Ok(opts)
}

/// `render`'s defaults against the paper's method and the preview fit.
fn defaults() -> Result<Table, HostError> {
    let scenes: [(&str, Scene, [u16; 3]); 4] = [
        ("demo (400 spheres, seed 1986)", Scene::random(400, 1986, 1.0, [32; 3])?, [4; 3]),
        ("1000 spheres, seed 7", paper_scene(7)?, [4; 3]),
        ("1000 spheres, seed 1986, volume 1/4", Scene::random(1000, 1986, 0.25, [32; 3])?, [4; 3]),
        ("400 spheres, seed 3, 2x2x2", Scene::random(400, 3, 1.0, [32; 3])?, [2; 3]),
    ];
    let mut body = String::from(
        "| scene | link | even, static | even, paper | even, proportional (default) | preview, proportional |\n\
         |---|---|---|---|---|---|\n",
    );
    for (name, scene, array) in &scenes {
        for preset in [LinkPreset::F413, LinkPreset::Ideal] {
            let base = options(*array, preset)?;
            let paper = RenderOptions { balance: Some(paper_balance()), ..base };
            let slide = RenderOptions { balance: Some(DEFAULT_BALANCE), ..base };
            let view = host_tool::plan::partition::view_axis(scene);
            let preview = RenderOptions { layout: Layout::Preview, driving_axis: Some(view), ..slide };
            let _ = write!(body, "| {name} | {} |", preset.name());
            for opts in [base, paper, slide, preview] {
                let r = render_sim(scene, &opts).map_err(|e| e.context(name))?;
                let _ = write!(body, " {:.3e} |", r.frame.makespan.0 as f64);
            }
            body.push('\n');
        }
    }
    Ok(Table {
        name: "defaults",
        title: "The defaults against the paper's method",
        about: "Makespan in virtual cycles of `render` on the in-memory board, 256x256, initial rays \
                where they enter. `even, proportional` is `render` with no options; `even, paper` is \
                `--policy paper` (the paper's rule, one cube a step); `even, static` is `--balance \
                static`; `preview, proportional` is `--layout preview --driving-axis view`. Links: \
                `f413` (the default: the real boards' USARTs) and `ideal`.",
        body,
    })
}

/// Initial rays created where they enter against the paper's parallel mode.
fn initial_rays() -> Result<Table, HostError> {
    let scene = paper_scene(1986)?;
    let mut one = options([1; 3], LinkPreset::F413)?;
    one.size = [128, 128];
    let t1 = render_sim(&scene, &one)?.frame.makespan.0 as f64;
    let mut body = String::from(
        "| array | `parallel` (cycles) | `entry` (cycles) | E `parallel` | E `entry` |\n|---|---|---|---|---|\n",
    );
    for side in [2u16, 4, 8] {
        let nodes = f64::from(side).powi(3);
        let _ = write!(body, "| {side}x{side}x{side} |");
        let mut e = Vec::new();
        for initial in [Initial::Parallel, Initial::Entry] {
            let opts = RenderOptions { array: [side; 3], initial, ..one };
            let t = render_sim(&scene, &opts)?.frame.makespan.0 as f64;
            let _ = write!(body, " {t:.3e} |");
            e.push(t1 / (nodes * t));
        }
        for e in e {
            let _ = write!(body, " {e:.3} |");
        }
        body.push('\n');
    }
    let _ = write!(body, "\nT(1) = {t1:.3e} cycles.\n");
    Ok(Table {
        name: "initial-rays",
        title: "Initial rays where they enter, against the paper's parallel mode",
        about: "Makespan in virtual cycles on the in-memory board, 1000 random spheres (seed 1986) in \
                a 32^3 grid at 128x128, even static partitions, `f413` links; E = T(1) / (S T(S)) \
                with T(1) the one-node run of the same frame.",
        body,
    })
}

/// Error against run time on the sphereflake (`lab report tradeoff`).
fn tradeoff() -> Result<Table, HostError> {
    let cfg = crate::tradeoff::TradeoffConfig::full([48, 48]);
    let scene = crate::scenes::sphereflake(2, cfg.array)?;
    let points = crate::tradeoff::sweep(&scene, &cfg)?;
    Ok(Table {
        name: "tradeoff",
        title: "Error against run time on the sphereflake",
        about: "`lab report tradeoff --sphereflake 2 --size 48x48`: the built-in sphereflake (91 \
                spheres, every surface a 45% mirror) fitted into the grid `render` chooses for 4x4x4. \
                docs/arithmetic.md says what is measured and why the defaults sit where they do.",
        body: crate::tradeoff::markdown(&points, &cfg),
    })
}

/// The paper's sliding rule at `render`'s interval and threshold.
fn paper_balance() -> link_proto::Balance {
    link_proto::Balance { policy: SlidePolicy::Paper, ..DEFAULT_BALANCE }
}

/// Efficiency and the messaging share against array size on `preset`'s links.
fn scaling(preset: LinkPreset) -> Result<Table, HostError> {
    let mut base = options([1; 3], preset)?;
    base.size = [128, 128];
    let cfg = ScalingConfig { sides: vec![1, 2, 3, 4], ..ScalingConfig::full(base) };
    let rows = rows(&paper_scene(1986)?, &cfg)?;
    let (name, title) = match preset {
        LinkPreset::F413 => ("scaling-f413", "Does the array pay for itself? Real-board links"),
        _ => ("scaling-ideal", "Does the array pay for itself? Ideal links"),
    };
    Ok(Table {
        name,
        title,
        about: "E = T(1) / (S x T(S)) in virtual cycles, static partitions (`even` boxes or fitted to \
                a `preview`), 1000 spheres (seed 1986) in a 32^3 grid at 128x128. `lab bench scaling` \
                makes the same table up to S = 512 at any size and link.",
        body: markdown(&cfg, &rows),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(name: &'static str, body: &str) -> Table {
        Table { name, title: "T", about: "A.", body: body.to_string() }
    }

    #[test]
    fn a_changed_or_missing_table_is_named_and_the_stamp_is_not() {
        let made = [table("a", "| 1 |\n"), table("b", "| 2 |\n")];
        let doc = document("abc123", &made);
        assert!(stale(&doc, &made).is_empty());
        // Another commit in the stamp is not staleness.
        assert!(stale(&document("def456", &made), &made).is_empty());
        let now = [table("a", "| 1 |\n"), table("b", "| 3 |\n"), table("c", "| 4 |\n")];
        assert_eq!(stale(&doc, &now), ["b", "c"]);
    }
}
