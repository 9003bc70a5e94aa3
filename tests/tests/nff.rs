//! Scenes in Haines' Neutral File Format: a sphereflake built here (after
//! the Standard Procedural Databases' "balls") is read, fitted into the grid,
//! rendered bit-identically on several arrays and held to the f64 reference;
//! NFF written by the host reads back; what cannot be rendered is refused by
//! line, or left out on request.

use std::f64::consts::PI;
use std::fmt::Write as _;

use host_tool::compare::compare;
use host_tool::plan::options::RenderOptions;
use host_tool::scene::{Reading, Scene, fit, nff};
use host_tool::session::frame::to_srgb8;
use host_tool::session::sim::render_sim;
use host_tool::{plan::direct, reference};

/// Unit vector at azimuth `az` and elevation `el` in the frame whose third
/// axis is `axis`.
fn around(axis: [f64; 3], az: f64, el: f64) -> [f64; 3] {
    // Any vector not along the axis gives the frame's first axis.
    let helper = if axis[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    };
    let unit = |a: [f64; 3]| {
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|x| x / n)
    };
    let u = unit(cross(axis, helper));
    let v = cross(axis, u);
    std::array::from_fn(|i| el.cos() * (az.cos() * u[i] + az.sin() * v[i]) + el.sin() * axis[i])
}

/// A sphereflake of `levels` generations: each sphere carries nine of a
/// third its radius, six around its equator and three above, facing away
/// from its parent.
fn sphereflake(levels: u32) -> String {
    let mut text = String::from(
        "# sphereflake\nv\nfrom 2.1 1.3 1.7\nat 0 0 0\nup 0 0 1\nangle 45\nhither 0.01\nresolution 64 64\n\
         b 0.078 0.361 0.753\nl 4 3 2\nl 1 -4 4\nl -3 1 5\n",
    );
    let _ = writeln!(text, "f 0.5 0.45 0.35 0.5 0.45 100 0 1\ns 0 0 0 0.5");
    let _ = writeln!(text, "f 1 0.9 0.7 0.5 0.5 100000 0 1");
    let mut generation = vec![([0.0; 3], 0.5, [0.0, 0.0, 1.0])];
    for _ in 0..levels {
        let mut next = Vec::new();
        for (centre, radius, axis) in generation {
            let child = radius / 3.0;
            let mut dirs: Vec<[f64; 3]> =
                (0..6).map(|k| around(axis, f64::from(k) * PI / 3.0, 0.0)).collect();
            dirs.extend((0..3).map(|k| around(axis, PI / 6.0 + f64::from(k) * 2.0 * PI / 3.0, PI / 3.0)));
            for d in dirs {
                let c: [f64; 3] = std::array::from_fn(|i| centre[i] + d[i] * (radius + child));
                let _ = writeln!(text, "s {} {} {} {}", c[0], c[1], c[2], child);
                next.push((c, child, d));
            }
        }
        generation = next;
    }
    text
}

fn read(text: &str) -> Scene {
    let mut scene = nff::parse(text, "sphereflake", false).expect("valid NFF").scene;
    fit(&mut scene, None).expect("fits");
    scene.validate().expect("valid once fitted");
    scene
}

#[test]
fn a_sphereflake_renders_alike_on_every_array_and_agrees_with_the_reference() {
    let scene = read(&sphereflake(2));
    assert_eq!(scene.spheres.len(), 91);
    assert_eq!(scene.lights.len(), 3);
    let size = [64, 64];
    let fixed = direct::render(&scene, size[0], size[1]).expect("renders");
    for array in [[1, 1, 1], [2, 2, 2], [3, 1, 2]] {
        let mut opts = RenderOptions::new(array);
        opts.size = size;
        let r = render_sim(&scene, &opts).unwrap_or_else(|e| panic!("{array:?}: {e}"));
        assert!(r.frame.sums == fixed.sums, "{array:?}: not the single-loop image");
    }
    let fixed_rgb: Vec<u8> = fixed.sums.iter().flat_map(|p| p.map(to_srgb8)).collect();
    let refimg = reference::render(&scene, size[0], size[1]);
    let c = compare(&scene, size, &fixed, &fixed_rgb, &refimg, &refimg.rgb8());
    assert!(c.hit_agreement >= 0.999, "{c:?}");
    assert_eq!(c.gross_mismatches, 0, "{c:?}");
    assert!(c.psnr_db > 40.0, "{c:?}");
    // The flake is in the picture, in the middle: a fifth of the pixels or
    // more see it, and the centre one does.
    let corner = &fixed_rgb[..3];
    let background = fixed_rgb.chunks(3).filter(|p| *p == corner).count();
    assert!(background < 64 * 64 * 4 / 5, "{background} pixels of background");
    let centre = (32 * 64 + 32) * 3;
    assert_ne!(&fixed_rgb[centre..centre + 3], corner, "the centre pixel sees the background");
}

#[test]
fn nff_the_host_writes_reads_back() {
    let text = sphereflake(1);
    let first = nff::parse(&text, "flake", false).expect("valid").scene;
    let again = nff::parse(&nff::write(&first, [64, 64]), "written", false).expect("valid").scene;
    assert_eq!(again, first);
    // A random JSON scene keeps its geometry, colours and camera through NFF.
    let random = Scene::random(50, 3, 0.8, [16; 3]).expect("scene");
    let back = nff::parse(&nff::write(&random, [32, 32]), "written", false).expect("valid").scene;
    assert_eq!(back.camera(), random.camera());
    for (a, b) in back.spheres.iter().zip(&random.spheres) {
        assert_eq!(
            (a.center, a.radius, a.color, a.diffuse, a.shininess),
            (b.center, b.radius, b.color, b.diffuse, b.shininess)
        );
    }
}

#[test]
fn what_cannot_be_rendered_is_refused_by_line_or_left_out_on_request() {
    let text = "v\nfrom 0 0 -5\nat 0 0 0\nup 0 1 0\nangle 40\nhither 1\nresolution 8 8\n\
                s 0 0 0 1\np 3\n0 0 0\n1 0 0\n0 1 0\ns 2 0 0 0.5\n";
    let err = nff::parse(text, "poly.nff", false).expect_err("a polygon is refused");
    assert_eq!(err.exit_code(), 17);
    assert!(err.to_string().starts_with("poly.nff line 9: a polygon ('p') cannot be rendered"), "{err}");
    assert!(err.to_string().contains("--skip-unsupported"), "{err}");
    let read = nff::parse(text, "poly.nff", true).expect("left out");
    assert_eq!(read.warnings, ["poly.nff line 9: left out a polygon ('p')"]);
    // The vertex lines went with it; the sphere after them did not.
    assert_eq!(read.scene.spheres.len(), 2);
    let err = nff::parse("s 1 2 x 4\n", "bad.nff", false).expect_err("not a number");
    assert_eq!((err.exit_code(), err.to_string()), (10, "bad.nff line 1: 'x' is not a number".to_string()));
    let err = nff::parse("q 1\n", "bad.nff", false).expect_err("unknown");
    assert!(err.to_string().contains("unknown NFF command 'q'"), "{err}");
}

#[test]
fn a_scene_file_is_fitted_into_the_grid_asked_for() {
    let dir = tempfile::tempdir().expect("scratch");
    let path = dir.path().join("flake.nff");
    std::fs::write(&path, sphereflake(1)).expect("written");
    let how = Reading { grid: Some([24, 20, 16]), ..Reading::default() };
    let (scene, warnings) = Scene::read(&path, &how).expect("read");
    assert!(warnings.is_empty());
    assert_eq!(scene.grid, [24, 20, 16]);
    // JSON keeps its own grid unless it is fitted.
    let json = dir.path().join("flake.json");
    std::fs::write(&json, scene.to_text(host_tool::scene::SceneFormat::Json, [8, 8]).expect("json"))
        .expect("written");
    let err =
        Scene::read(&json, &Reading { grid: Some([8; 3]), ..Reading::default() }).expect_err("no --fit");
    assert!(err.to_string().contains("add --fit"), "{err}");
    let (refit, _) =
        Scene::read(&json, &Reading { fit: true, grid: Some([8; 3]), ..Reading::default() }).expect("fitted");
    assert_eq!(refit.grid, [8; 3]);
}
