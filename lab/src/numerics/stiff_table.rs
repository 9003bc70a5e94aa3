//! The stiff-case results table (`lab report stiff`), shown in docs/arithmetic.md.

use fixed::types::I16F16;
use node_fw::{DigitalLine, Error, Field, Grid, Line, Material, Point, Sphere};

use super::exact_sphere::exact_hit;
use super::{quantise, rational_walk, stiff};

const ULP: f64 = 1.0 / 65536.0;

/// One row of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Case name.
    pub name: String,
    /// What must happen.
    pub expected: String,
    /// What happened.
    pub got: String,
    /// Whether it is what must happen.
    pub pass: bool,
}

fn walk(line: &Line, grid: [u16; 3]) -> Vec<[i32; 3]> {
    let Ok(g) = Grid::new(grid) else { return Vec::new() };
    let Some(mut w) = DigitalLine::enter(line, &g) else { return Vec::new() };
    let mut cells = vec![w.cell()];
    while cells.len() <= 3 * 256 + 3 {
        w.step();
        if !g.contains(w.cell()) {
            break;
        }
        cells.push(w.cell());
    }
    cells
}

/// Rows for the traversal cases: the walk against the rational reference.
pub fn walk_rows() -> Vec<Row> {
    stiff::walk_cases()
        .into_iter()
        .map(|c| {
            let line = quantise::line(c.origin, c.dir);
            let got = walk(&line, c.grid);
            let want = rational_walk::walk(line.origin(), line.dir(), c.grid);
            let geometry = rational_walk::check_walk(line.origin(), line.dir(), c.grid, &got);
            let pass = got == want && geometry.is_ok();
            let got_text = match (&geometry, got == want) {
                (Ok(()), true) => format!("{} cubes, equal to the reference", got.len()),
                (Ok(()), false) => format!("{} cubes, differs from the reference", got.len()),
                (Err(e), _) => e.clone(),
            };
            Row {
                name: c.name.to_string(),
                expected: "rational reference, gap-free".into(),
                got: got_text,
                pass,
            }
        })
        .collect()
}

/// Rows for the sphere cases: the decision against the exact and ideal geometry.
pub fn hit_rows() -> Vec<Row> {
    let grid = Grid::UNIT;
    let big = Grid::new([256; 3]).unwrap_or(grid);
    stiff::hit_cases()
        .into_iter()
        .map(|c| {
            let center = Point::from_bits(quantise::point_raw(c.center));
            let sphere = center.and_then(|p| {
                Sphere::new(0, p, I16F16::from_bits(quantise::pos(c.radius)), Material::default(), &big)
            });
            let expected = match c.expect {
                stiff::Expect::Hit { inside: false } => "hit".to_string(),
                stiff::Expect::Hit { inside: true } => "hit from inside".to_string(),
                stiff::Expect::Miss => "miss".to_string(),
                stiff::Expect::Exact => "the exact decision".to_string(),
                stiff::Expect::RejectRadius => "rejected (radius)".to_string(),
            };
            let (got, pass) = match (c.expect, sphere) {
                (stiff::Expect::RejectRadius, Err(Error::OutOfRange(Field::Radius))) => {
                    ("rejected".into(), true)
                }
                (_, Err(e)) => (format!("error {e:?}"), false),
                (_, Ok(s)) => judge(&c, &s),
            };
            Row { name: c.name, expected, got, pass }
        })
        .collect()
}

fn judge(c: &stiff::HitCase, s: &Sphere) -> (String, bool) {
    let line = quantise::line(c.origin, c.dir);
    let got = s.intersect(&line);
    let exact = exact_hit(line.origin(), line.dir(), s.center(), s.radius().to_bits());
    let agrees = got.is_some() == exact.is_some();
    let depth = |t: f64| exact.map(|e| (t - e.t).abs() / ULP);
    match (c.expect, got) {
        (stiff::Expect::Miss, None) => ("miss".into(), agrees),
        (stiff::Expect::Hit { inside }, Some(r)) => {
            let t = r.t.to_num::<f64>();
            let ideal = c.ideal_t.map_or(String::new(), |i| format!(", {:.1e} from ideal", (t - i).abs()));
            let ulps = depth(t).unwrap_or(f64::INFINITY);
            let text = format!("hit at t = {t:.5} ({ulps:.2} ulp from exact{ideal})");
            (text, agrees && r.inside == inside && ulps <= 2.0)
        }
        (stiff::Expect::Exact, g) => {
            let text = match g {
                Some(r) => format!("hit at t = {:.5}, as the exact decision", r.t.to_num::<f64>()),
                None => "miss, as the exact decision".into(),
            };
            (text, agrees)
        }
        (_, Some(r)) => (format!("hit at t = {:.5}", r.t.to_num::<f64>()), false),
        (_, None) => ("miss".into(), false),
    }
}

/// The whole table as Markdown, and whether every case passed.
pub fn markdown() -> (String, bool) {
    let rows: Vec<Row> = walk_rows().into_iter().chain(hit_rows()).collect();
    let all = rows.iter().all(|r| r.pass);
    let mut s = String::from("| case | expected | got | |\n|---|---|---|---|\n");
    for r in &rows {
        s += &format!(
            "| {} | {} | {} | {} |\n",
            r.name,
            r.expected,
            r.got,
            if r.pass { "ok" } else { "FAIL" }
        );
    }
    (s, all)
}
