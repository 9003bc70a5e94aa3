//! Scenes: the JSON schema, the paper's random scenes, validation and quantisation.
//!
//! Schema (every field but `spheres` has a default):
//! ```json
//! {
//!   "grid": [32, 32, 32],
//!   "camera": {"eye": [16, 16, -30], "look_at": [16, 16, 16], "up": [0, 1, 0], "fov_deg": 45},
//!   "ambient": [0.25, 0.25, 0.25],
//!   "background": [0.05, 0.06, 0.1],
//!   "max_depth": 3,
//!   "lights": [{"position": [40, 60, -20], "color": [0.8, 0.8, 0.8]}],
//!   "spheres": [{"center": [16, 16, 16], "radius": 2.5, "color": [0.9, 0.3, 0.2],
//!                "ambient": 0.3, "diffuse": 0.7, "specular": 0.4, "shininess": 24, "reflect": 0.3}],
//!   "keyframes": [{"frame": 0, "camera": {"eye": [16, 16, -30], "look_at": [16, 16, 16]}}],
//!   "sphere_keyframes": [{"sphere": 0, "frame": 0, "center": [16, 16, 16]},
//!                        {"sphere": 0, "frame": 30, "center": [16, 24, 16]}]
//! }
//! ```
//! Lengths are in unit cubes; colours and coefficients in `[0, 2)`.

use link_proto::{LightMsg, MaterialMsg, SceneHeader, SphereMsg};
use node_fw::limits::{MAX_GRID, MAX_OUTSIDE};
use rand::{Rng, SeedableRng, rngs::SmallRng};
use serde::{Deserialize, Serialize};

use crate::error::{HostError, input};

pub mod fit;
pub mod nff;
pub mod occupancy;
pub mod path;

pub use fit::fit;

/// A pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Eye position.
    pub eye: [f64; 3],
    /// Point the camera looks at.
    pub look_at: [f64; 3],
    /// Up direction.
    #[serde(default = "default_up")]
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    #[serde(default = "default_fov")]
    pub fov_deg: f64,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

fn default_fov() -> f64 {
    45.0
}

/// A point light.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Light {
    /// Position.
    pub position: [f64; 3],
    /// Colour and intensity.
    #[serde(default = "white")]
    pub color: [f64; 3],
}

fn white() -> [f64; 3] {
    [1.0; 3]
}

/// A sphere with its surface parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereDesc {
    /// Centre.
    pub center: [f64; 3],
    /// Radius.
    pub radius: f64,
    /// Colour.
    #[serde(default = "white")]
    pub color: [f64; 3],
    /// Ambient coefficient.
    #[serde(default = "default_ambient")]
    pub ambient: f64,
    /// Diffuse coefficient.
    #[serde(default = "default_diffuse")]
    pub diffuse: f64,
    /// Specular coefficient.
    #[serde(default)]
    pub specular: f64,
    /// Phong exponent.
    #[serde(default = "default_shininess")]
    pub shininess: u8,
    /// Mirror reflection coefficient.
    #[serde(default)]
    pub reflect: f64,
}

pub(crate) fn default_ambient() -> f64 {
    0.3
}
fn default_diffuse() -> f64 {
    0.7
}
fn default_shininess() -> u8 {
    16
}

/// A whole scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Grid size in unit cubes per axis.
    #[serde(default = "default_grid")]
    pub grid: [u16; 3],
    /// Camera; by default it looks at the grid's centre from the -z side.
    #[serde(default)]
    pub camera: Option<Camera>,
    /// Ambient light colour.
    #[serde(default = "default_ambient_light")]
    pub ambient: [f64; 3],
    /// Colour of rays that leave the grid.
    #[serde(default = "default_background")]
    pub background: [f64; 3],
    /// Maximum reflections along a path.
    #[serde(default = "default_depth")]
    pub max_depth: u8,
    /// Point lights (at most 8).
    #[serde(default)]
    pub lights: Vec<Light>,
    /// Spheres.
    pub spheres: Vec<SphereDesc>,
    /// Cameras pinned to frames of a sequence ([`path`]); none: `camera` throughout.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub keyframes: Vec<path::Keyframe>,
    /// Spheres' centres pinned to frames of a sequence ([`path`]); a sphere
    /// with none stands at its `center` throughout.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sphere_keyframes: Vec<path::SphereKeyframe>,
}

fn default_grid() -> [u16; 3] {
    [32; 3]
}
pub(crate) fn default_ambient_light() -> [f64; 3] {
    [0.25; 3]
}
fn default_background() -> [f64; 3] {
    [0.05, 0.06, 0.1]
}
pub(crate) fn default_depth() -> u8 {
    3
}

/// How to read a scene file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Reading {
    /// Fit a JSON scene into the grid (NFF scenes are always fitted).
    pub fit: bool,
    /// The grid to fit into; chosen from the scene when `None`.
    pub grid: Option<[u16; 3]>,
    /// Cubes along each axis a grid chosen from the scene has at least
    /// ([`fit::at_least_for`] the array it is rendered on).
    pub at_least: [u16; 3],
    /// Leave out NFF primitives that cannot be rendered, with a warning,
    /// instead of refusing the file.
    pub skip_unsupported: bool,
}

/// A scene file's format, from its name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneFormat {
    /// JSON (docs/cli.md has the schema).
    Json,
    /// Haines' Neutral File Format.
    Nff,
}

impl SceneFormat {
    /// NFF for a `.nff` name, JSON for anything else.
    pub fn of(path: &std::path::Path) -> SceneFormat {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("nff") => SceneFormat::Nff,
            _ => SceneFormat::Json,
        }
    }

    /// The format a scene is written in: by the extension, `.json` or
    /// `.nff`, anything else refused.
    pub fn for_output(path: &std::path::Path) -> Result<SceneFormat, HostError> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("nff") => Ok(SceneFormat::Nff),
            Some("json") => Ok(SceneFormat::Json),
            _ => Err(input(format!("{}: a scene is written as .json or .nff", path.display()))),
        }
    }
}

/// Largest reflection depth accepted (bounds ray classes and credit splits).
pub const MAX_DEPTH: u8 = link_proto::MAX_DEPTH;
/// Largest number of lights.
pub const MAX_LIGHTS: usize = node_fw::node::MAX_LIGHTS;

impl Scene {
    /// Reads and validates a scene file: NFF if its name ends in `.nff`
    /// (fitted into a grid chosen from it), else JSON.
    pub fn load(path: &std::path::Path) -> Result<Scene, HostError> {
        Ok(Self::read(path, &Reading::default())?.0)
    }

    /// Reads a scene file as `how` says, validated; also returns a warning
    /// for each primitive left out.
    pub fn read(path: &std::path::Path, how: &Reading) -> Result<(Scene, Vec<String>), HostError> {
        let bytes = std::fs::read(path)
            .map_err(|e| HostError::Io(format!("cannot read scene {}: {e}", path.display())))?;
        // Read, but not a scene: exit 10 like any other malformed file, not 20.
        let text = String::from_utf8(bytes).map_err(|e| {
            HostError::Malformed(format!(
                "scene {} is not valid: not UTF-8 text (byte {} is not UTF-8)",
                path.display(),
                e.utf8_error().valid_up_to()
            ))
        })?;
        let source = format!("scene {}", path.display());
        let (mut scene, warnings, fit_it) = match SceneFormat::of(path) {
            SceneFormat::Nff => {
                let read = nff::parse(&text, &source, how.skip_unsupported)?;
                (read.scene, read.warnings, true)
            }
            SceneFormat::Json => {
                let scene: Scene = serde_json::from_str(&text)
                    .map_err(|e| HostError::Malformed(format!("{source} is not valid: {e}")))?;
                (scene, Vec::new(), how.fit)
            }
        };
        if fit_it {
            let grid = match how.grid {
                Some(g) => g,
                None => fit::choose(&scene, how.at_least)?,
            };
            fit(&mut scene, Some(grid))?;
        } else if let Some(grid) = how.grid.filter(|&g| g != scene.grid) {
            return Err(input(format!(
                "{source} has its own grid {:?}; to render it in {grid:?}, add --fit",
                scene.grid
            )));
        }
        scene.validate()?;
        Ok((scene, warnings))
    }

    /// The scene as its file format: JSON or NFF (`size` is NFF's resolution).
    pub fn to_text(&self, format: SceneFormat, size: [u16; 2]) -> Result<String, HostError> {
        match format {
            SceneFormat::Json => serde_json::to_string_pretty(self)
                .map(|t| t + "\n")
                .map_err(|e| HostError::Io(format!("cannot write the scene as JSON: {e}"))),
            SceneFormat::Nff => Ok(nff::write(self, size)),
        }
    }

    /// The paper's random scene: `count` spheres with uniformly random centres
    /// inside a cube of `volume_ratio` of the grid's volume, centred in the
    /// grid, with random radius, colour and reflecting parameters.
    pub fn random(count: usize, seed: u64, volume_ratio: f64, grid: [u16; 3]) -> Result<Scene, HostError> {
        if !volume_ratio.is_finite() || volume_ratio <= 0.0 || volume_ratio > 1.0 {
            let msg = format!("--volume-ratio must be in (0, 1], got {volume_ratio}");
            return Err(if volume_ratio.is_finite() { input(msg) } else { HostError::NonFinite(msg) });
        }
        if count > usize::from(u16::MAX) {
            return Err(input(format!("--spheres must be at most {}, got {count}", u16::MAX)));
        }
        let mut rng = SmallRng::seed_from_u64(seed);
        let side = volume_ratio.cbrt();
        let g = grid.map(f64::from);
        let spheres = (0..count)
            .map(|_| {
                let radius = rng.gen_range(0.25..1.0);
                // Uniform in the confining cube, kept wholly inside the grid.
                let center = std::array::from_fn(|a| {
                    let lo = g[a] * (1.0 - side) / 2.0;
                    (lo + rng.gen_range(0.0..1.0) * g[a] * side).clamp(radius, g[a] - radius)
                });
                let reflect = if rng.gen_bool(0.3) { rng.gen_range(0.2..0.6) } else { 0.0 };
                SphereDesc {
                    center,
                    radius,
                    color: std::array::from_fn(|_| rng.gen_range(0.2..1.0)),
                    ambient: 0.3,
                    diffuse: rng.gen_range(0.5..0.9),
                    specular: rng.gen_range(0.0..0.6),
                    shininess: rng.gen_range(4..48),
                    reflect,
                }
            })
            .collect();
        let lights = vec![
            Light { position: [g[0] * 1.2, g[1] * 1.5, -g[2] * 0.5], color: [0.7, 0.7, 0.65] },
            Light { position: [-g[0] * 0.3, g[1] * 0.8, -g[2] * 0.3], color: [0.3, 0.3, 0.35] },
        ];
        let scene = Scene {
            grid,
            camera: None,
            ambient: default_ambient_light(),
            background: default_background(),
            max_depth: default_depth(),
            lights,
            spheres,
            keyframes: Vec::new(),
            sphere_keyframes: Vec::new(),
        };
        scene.validate()?;
        Ok(scene)
    }

    /// The camera, or the default one looking at the grid's centre from -z.
    pub fn camera(&self) -> Camera {
        self.camera.unwrap_or_else(|| {
            let g = self.grid.map(f64::from);
            let c = [g[0] / 2.0, g[1] / 2.0, g[2] / 2.0];
            Camera { eye: [c[0], c[1], -1.25 * g[2]], look_at: c, up: default_up(), fov_deg: 40.0 }
        })
    }

    /// Checks `cam` as this scene's camera: finite, its eye near the grid, a
    /// field of view in range, and a view direction apart from `up`.
    pub fn check_camera(&self, cam: &Camera) -> Result<(), HostError> {
        finite("camera eye", &cam.eye)?;
        finite("camera look_at", &cam.look_at)?;
        finite("camera up", &cam.up)?;
        if !self.near_grid(&cam.eye) {
            return Err(input(format!(
                "camera eye {:?} is more than {MAX_OUTSIDE} cubes outside the grid",
                cam.eye
            )));
        }
        if !cam.fov_deg.is_finite() || cam.fov_deg <= 0.0 || cam.fov_deg >= 170.0 {
            return Err(input(format!("camera fov_deg must be in (0, 170), got {}", cam.fov_deg)));
        }
        let forward = sub(cam.look_at, cam.eye);
        if norm(forward) == 0.0 || norm(cross(forward, cam.up)) < 1e-9 * norm(forward) {
            return Err(input("camera look_at must differ from eye and not lie along up"));
        }
        Ok(())
    }

    /// Whether `p` is within [`MAX_OUTSIDE`] cubes of the grid.
    fn near_grid(&self, p: &[f64; 3]) -> bool {
        let out = MAX_OUTSIDE as f64;
        (0..3).all(|a| p[a] >= -out && p[a] <= f64::from(self.grid[a]) + out)
    }

    /// Checks every value against the documented ranges; the error names the first
    /// offending value.
    pub fn validate(&self) -> Result<(), HostError> {
        if self.grid.iter().any(|&s| s == 0 || s > MAX_GRID) {
            return Err(input(format!("grid {:?} must be 1..={MAX_GRID} cubes per axis", self.grid)));
        }
        let g = self.grid.map(f64::from);
        self.check_camera(&self.camera())?;
        unit_range("ambient", &self.ambient)?;
        unit_range("background", &self.background)?;
        if self.max_depth > MAX_DEPTH {
            return Err(input(format!("max_depth must be at most {MAX_DEPTH}, got {}", self.max_depth)));
        }
        if self.lights.len() > MAX_LIGHTS {
            return Err(input(format!("at most {MAX_LIGHTS} lights, got {}", self.lights.len())));
        }
        for (i, l) in self.lights.iter().enumerate() {
            finite(&format!("light {i} position"), &l.position)?;
            if !self.near_grid(&l.position) {
                return Err(input(format!("light {i} is more than {MAX_OUTSIDE} cubes outside the grid")));
            }
            unit_range(&format!("light {i} color"), &l.color)?;
        }
        if self.spheres.len() > usize::from(u16::MAX) {
            return Err(input(format!("at most {} spheres, got {}", u16::MAX, self.spheres.len())));
        }
        for (i, s) in self.spheres.iter().enumerate() {
            validate_sphere(i, s, &g)?;
        }
        path::check_keyframes(self)
    }

    /// The scene header message.
    pub fn header(&self) -> SceneHeader {
        SceneHeader {
            grid: self.grid,
            ambient: self.ambient.map(q15),
            background: self.background.map(q15),
            max_depth: self.max_depth,
            map: link_proto::MapLoad::Sent,
        }
    }

    /// The sphere messages, ids in order.
    pub fn sphere_msgs(&self) -> Vec<SphereMsg> {
        self.spheres
            .iter()
            .enumerate()
            .map(|(i, s)| SphereMsg {
                id: i as u16,
                center: s.center.map(q16),
                radius: q16(s.radius),
                material: MaterialMsg {
                    color: s.color.map(q15),
                    ambient: q15(s.ambient),
                    diffuse: q15(s.diffuse),
                    specular: q15(s.specular),
                    shininess: s.shininess,
                    reflect: q15(s.reflect),
                },
            })
            .collect()
    }

    /// The light messages.
    pub fn light_msgs(&self) -> Vec<LightMsg> {
        self.lights
            .iter()
            .enumerate()
            .map(|(i, l)| LightMsg { id: i as u8, position: l.position.map(q16), color: l.color.map(q15) })
            .collect()
    }
}

fn validate_sphere(i: usize, s: &SphereDesc, g: &[f64; 3]) -> Result<(), HostError> {
    finite(&format!("sphere {i} center"), &s.center)?;
    if !s.radius.is_finite() {
        return Err(HostError::NonFinite(format!("sphere {i} radius is not a finite number")));
    }
    if s.radius <= 0.0 {
        return Err(HostError::Radius(format!("sphere {i} radius must be positive, got {}", s.radius)));
    }
    let (lo, hi) = (1.0 / 256.0, 64.0);
    if q16(s.radius) < q16(lo) || s.radius > hi {
        return Err(HostError::Radius(format!("sphere {i} radius {} is outside 1/256..=64 cubes", s.radius)));
    }
    if (0..3).any(|a| s.center[a] < 0.0 || s.center[a] > g[a]) {
        return Err(HostError::OutsideGrid(format!(
            "sphere {i} center {:?} is outside the grid {:?}",
            s.center, g
        )));
    }
    if (0..3).any(|a| s.center[a] - s.radius < 0.0 || s.center[a] + s.radius > g[a]) {
        return Err(HostError::OutsideGrid(format!(
            "sphere {i} (center {:?}, radius {}) extends outside the grid {:?}; the scene is the grid",
            s.center, s.radius, g
        )));
    }
    unit_range(&format!("sphere {i} color"), &s.color)?;
    for (name, v) in
        [("ambient", s.ambient), ("diffuse", s.diffuse), ("specular", s.specular), ("reflect", s.reflect)]
    {
        unit_range(&format!("sphere {i} {name}"), &[v])?;
    }
    Ok(())
}

fn finite(what: &str, v: &[f64]) -> Result<(), HostError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(HostError::NonFinite(format!("{what} holds a NaN or infinite number: {v:?}")))
    }
}

fn unit_range(what: &str, v: &[f64]) -> Result<(), HostError> {
    finite(what, v)?;
    if v.iter().all(|&x| (0.0..2.0).contains(&x)) {
        Ok(())
    } else {
        Err(input(format!("{what} must lie in [0, 2), got {v:?}")))
    }
}

/// Rounds to raw Q16.16.
pub fn q16(x: f64) -> i32 {
    (x * 65536.0).round() as i32
}

/// Rounds to raw Q1.15 (saturating at the top of `[0, 2)`).
pub fn q15(x: f64) -> u16 {
    (x * 32768.0).round().clamp(0.0, 65535.0) as u16
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}
