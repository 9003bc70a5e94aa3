//! Scenes in the Neutral File Format (Eric Haines, Standard Procedural
//! Databases, 1987): the format the era's ray tracers read, and most since.
//!
//! Read: the viewpoint (`v` with `from`, `at`, `up`, `angle`, `hither`,
//! `resolution`), the background (`b`), point lights (`l`, white unless a
//! colour follows), fill materials (`f`: colour, Kd, Ks, Shine, T, index of
//! refraction) and spheres (`s`). NFF's Ks is both the highlight's and the
//! mirror's coefficient, so it sets a sphere's `specular` and `reflect`;
//! transmission (T) and refraction are not rendered and are ignored, and so
//! are `hither` and `resolution` (`--size` sets the image). Cones and
//! cylinders (`c`), polygons (`p`) and polygonal patches (`pp`) cannot be
//! rendered: they are refused with their line number, or left out with a
//! warning when the caller asks. Coordinates are the file's own: the caller
//! fits the scene into the grid ([`super::fit`](mod@super::fit)).

use std::fmt::Write as _;

use super::{Camera, Light, Scene, SphereDesc, default_ambient_light, default_depth};
use crate::error::HostError;

/// A scene read from NFF, in the file's coordinates, and what was left out.
#[derive(Debug, Clone, PartialEq)]
pub struct NffScene {
    /// The scene; its grid is a placeholder until it is fitted.
    pub scene: Scene,
    /// One line per primitive left out (with `skip_unsupported`).
    pub warnings: Vec<String>,
}

/// The current `f` line.
#[derive(Debug, Clone, Copy)]
struct Fill {
    color: [f64; 3],
    diffuse: f64,
    specular: f64,
    shininess: u8,
}

/// Before any `f` line: white, matte.
const NO_FILL: Fill = Fill { color: [1.0; 3], diffuse: 0.7, specular: 0.0, shininess: 16 };

/// Parses NFF text; `source` names it in errors. A primitive that cannot be
/// rendered is an error unless `skip_unsupported`.
pub fn parse(text: &str, source: &str, skip_unsupported: bool) -> Result<NffScene, HostError> {
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim())).peekable();
    let bad = |n: usize, why: String| HostError::Malformed(format!("{source} line {n}: {why}"));
    let mut scene = Scene {
        grid: [1; 3],
        camera: None,
        ambient: default_ambient_light(),
        background: [0.0; 3],
        max_depth: default_depth(),
        lights: Vec::new(),
        spheres: Vec::new(),
        keyframes: Vec::new(),
        sphere_keyframes: Vec::new(),
    };
    let mut fill = NO_FILL;
    let mut warnings = Vec::new();
    while let Some((n, line)) = lines.next() {
        let mut words = line.split_whitespace();
        let Some(command) = words.next() else { continue };
        let args: Vec<&str> = words.collect();
        match command {
            c if c.starts_with('#') => {}
            "v" => {
                let mut view = View::default();
                for _ in 0..6 {
                    let Some((m, l)) = lines.next() else {
                        return Err(bad(n, "the viewpoint ('v') ends before its six lines".into()));
                    };
                    view.take(l).map_err(|why| bad(m, why))?;
                }
                scene.camera = Some(view.camera().map_err(|why| bad(n, why))?);
            }
            "b" => scene.background = numbers::<3>(&args).map_err(|why| bad(n, why))?,
            "l" => {
                let (position, color) = match args.len() {
                    3 => (numbers::<3>(&args).map_err(|why| bad(n, why))?, [1.0; 3]),
                    6 => {
                        let v = numbers::<6>(&args).map_err(|why| bad(n, why))?;
                        ([v[0], v[1], v[2]], [v[3], v[4], v[5]])
                    }
                    k => return Err(bad(n, format!("a light ('l') takes 3 or 6 numbers, got {k}"))),
                };
                scene.lights.push(Light { position, color });
            }
            "f" => {
                let v = numbers::<8>(&args).map_err(|why| bad(n, why))?;
                let shininess = v[5].round().clamp(0.0, 255.0) as u8;
                fill = Fill { color: [v[0], v[1], v[2]], diffuse: v[3], specular: v[4], shininess };
            }
            "s" => {
                let v = numbers::<4>(&args).map_err(|why| bad(n, why))?;
                scene.spheres.push(SphereDesc {
                    center: [v[0], v[1], v[2]],
                    radius: v[3],
                    color: fill.color,
                    ambient: super::default_ambient(),
                    diffuse: fill.diffuse,
                    specular: fill.specular,
                    shininess: fill.shininess,
                    reflect: fill.specular,
                });
            }
            "c" | "p" | "pp" => {
                let (name, follow) = match command {
                    "c" => ("a cone or cylinder ('c')", 2),
                    "p" => ("a polygon ('p')", count(&args).map_err(|why| bad(n, why))?),
                    _ => ("a polygonal patch ('pp')", count(&args).map_err(|why| bad(n, why))?),
                };
                if !skip_unsupported {
                    return Err(HostError::Input(format!(
                        "{source} line {n}: {name} cannot be rendered (the array traces spheres); \
                         pass --skip-unsupported to leave such primitives out"
                    )));
                }
                for _ in 0..follow {
                    lines.next();
                }
                warnings.push(format!("{source} line {n}: left out {name}"));
            }
            other => return Err(bad(n, format!("unknown NFF command '{other}'"))),
        }
    }
    if scene.spheres.is_empty() {
        return Err(HostError::Malformed(format!("{source}: no spheres ('s' lines)")));
    }
    Ok(NffScene { scene, warnings })
}

/// The viewpoint block's six lines, in any order.
#[derive(Debug, Default)]
struct View {
    from: Option<[f64; 3]>,
    at: Option<[f64; 3]>,
    up: Option<[f64; 3]>,
    angle: Option<f64>,
}

impl View {
    fn take(&mut self, line: &str) -> Result<(), String> {
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or_default();
        let args: Vec<&str> = words.collect();
        match key {
            "from" => self.from = Some(numbers::<3>(&args)?),
            "at" => self.at = Some(numbers::<3>(&args)?),
            "up" => self.up = Some(numbers::<3>(&args)?),
            "angle" => self.angle = Some(numbers::<1>(&args)?[0]),
            "hither" => {
                numbers::<1>(&args)?;
            }
            "resolution" => {
                numbers::<2>(&args)?;
            }
            other => {
                return Err(format!(
                    "expected a viewpoint line (from, at, up, angle, hither, resolution), got '{other}'"
                ));
            }
        }
        Ok(())
    }

    fn camera(&self) -> Result<Camera, String> {
        match (self.from, self.at, self.up, self.angle) {
            (Some(eye), Some(look_at), Some(up), Some(fov_deg)) => Ok(Camera { eye, look_at, up, fov_deg }),
            _ => Err("the viewpoint ('v') needs from, at, up and angle".into()),
        }
    }
}

/// Exactly `N` numbers.
fn numbers<const N: usize>(args: &[&str]) -> Result<[f64; N], String> {
    if args.len() != N {
        return Err(format!("expected {N} numbers, got {}", args.len()));
    }
    let mut out = [0.0; N];
    for (slot, word) in out.iter_mut().zip(args) {
        *slot = word.parse::<f64>().map_err(|_| format!("'{word}' is not a number"))?;
        if !slot.is_finite() {
            return Err(format!("'{word}' is not a finite number"));
        }
    }
    Ok(out)
}

/// The vertex count of a `p` or `pp` line.
fn count(args: &[&str]) -> Result<usize, String> {
    match args {
        [n] => n.parse().map_err(|_| format!("'{n}' is not a vertex count")),
        _ => Err("expected one vertex count".into()),
    }
}

/// The scene as NFF, `size` its resolution. Every number is written so it
/// reads back exactly; a sphere's Ks is its reflect coefficient, or its
/// specular one if it reflects nothing (NFF has one for both), and NFF keeps
/// neither the ambient light nor each sphere's ambient coefficient.
pub fn write(scene: &Scene, size: [u16; 2]) -> String {
    let c = scene.camera();
    let v = |p: [f64; 3]| format!("{} {} {}", p[0], p[1], p[2]);
    let mut out = String::from("# written by host-tool (Nemoto & Omachi sliding-boundary ray tracer)\n");
    let _ = writeln!(out, "v\nfrom {}\nat {}\nup {}", v(c.eye), v(c.look_at), v(c.up));
    let _ = writeln!(out, "angle {}\nhither 0\nresolution {} {}", c.fov_deg, size[0], size[1]);
    let _ = writeln!(out, "b {}", v(scene.background));
    for l in &scene.lights {
        let _ = writeln!(out, "l {} {}", v(l.position), v(l.color));
    }
    let mut last = String::new();
    for s in &scene.spheres {
        let ks = if s.reflect > 0.0 { s.reflect } else { s.specular };
        let f = format!("f {} {} {} {} 0 1", v(s.color), s.diffuse, ks, s.shininess);
        if f != last {
            let _ = writeln!(out, "{f}");
            last = f;
        }
        let _ = writeln!(out, "s {} {}", v(s.center), s.radius);
    }
    out
}
