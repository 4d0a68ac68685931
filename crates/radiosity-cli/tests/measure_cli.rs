//! `radiosity measure` and `render --false-colour` end to end: the outputs the issue asks
//! for (per point irradiance and lx; grid JSON, CSV and PNG with Emin, Ē, Emax, U0), the
//! inverse-square law through the whole command, and clean failures on bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(args)
        .output()
        .expect("run radiosity")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A 10 m black square with a 500 cd point light 2 m above its centre: the illuminance
/// anywhere on it is I cos θ / r² (no surface lights another).
const LAMP_OVER_PLANE: &str = r#"{
  "materials": [{ "name": "black", "reflectance": [0, 0, 0] }],
  "surfaces": [{ "object": "floor", "material": "black",
                 "vertices": [[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]] }],
  "lights": [{ "name": "lamp", "type": "point", "position": [5, 5, 2], "intensity_cd": 500 }]
}"#;

fn assert_fails_cleanly(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "exit code; stderr: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    for n in needles {
        assert!(err.contains(n), "message lacks {n:?}: {err}");
    }
}

#[test]
fn points_and_grids_give_lux_statistics_csv_and_png() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "lamp.json", LAMP_OVER_PLANE);
    let points = write(
        dir.path(),
        "points.json",
        r#"{"points": [{"name": "A", "position": [5, 5, 0], "normal": [0, 0, 1]},
                       {"name": "B", "position": [7, 5, 0], "normal": [0, 0, 2]}]}"#,
    );
    let out = dir.path().join("out.json");
    let o = run(&[
        "measure",
        scene.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
        "--grid",
        "height=0,spacing=1",
        "-o",
        out.to_str().unwrap(),
        "--elements",
        "100",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    // E = I cos θ / r²: A straight below (500 / 4 lx), B at 2 m to the side (r² = 8).
    let expected = [500.0 / 4.0, 500.0 * (2.0 / 8f64.sqrt()) / 8.0];
    for (p, want) in json["points"].as_array().unwrap().iter().zip(expected) {
        let lx = p["illuminance"].as_f64().unwrap();
        assert!((lx - want).abs() < 1e-3 * want, "{p}: {lx} vs {want}");
        let w = p["irradiance"][1].as_f64().unwrap();
        assert!((683.0 * w - want).abs() < 1e-3 * want, "{p}");
    }
    let grid = &json["grids"][0];
    assert_eq!(grid["counts"], serde_json::json!([10, 10]));
    let s = &grid["stats"];
    let (min, mean, max) = (
        s["e_min"].as_f64().unwrap(),
        s["e_mean"].as_f64().unwrap(),
        s["e_max"].as_f64().unwrap(),
    );
    assert!(min > 0.0 && min < mean && mean < max, "{s}");
    assert!((s["u0"].as_f64().unwrap() - min / mean).abs() < 1e-9);
    assert!((s["min_over_max"].as_f64().unwrap() - min / max).abs() < 1e-9);
    // The corner cells' centres, (0.5, 0.5): r² = 4.5² + 4.5² + 4.
    let r2: f64 = 2.0 * 4.5 * 4.5 + 4.0;
    let corner = 500.0 * (2.0 / r2.sqrt()) / r2;
    assert!(
        (min - corner).abs() < 1e-3 * corner,
        "Emin {min} vs {corner}"
    );
    let csv = std::fs::read_to_string(dir.path().join("out_grid1.csv")).unwrap();
    assert_eq!(csv.lines().count(), 101, "header + 100 points:\n{csv}");
    let png = image::open(dir.path().join("out_grid1.png")).unwrap();
    assert!(png.width() > 300 && png.height() > 300);
}

#[test]
fn bad_measure_input_fails_cleanly_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "lamp.json", LAMP_OVER_PLANE);
    let out = dir.path().join("out.json");
    let s = scene.to_str().unwrap();
    let o_path = out.to_str().unwrap();

    let o = run(&["measure", s, "-o", o_path]);
    assert_fails_cleanly(&o, &["--points", "--grid"]);

    let o = run(&["measure", s, "--grid", "height=abc", "-o", o_path]);
    assert_fails_cleanly(&o, &["height", "abc"]);

    let o = run(&[
        "measure",
        s,
        "--grid",
        "height=1,surface=nope",
        "-o",
        o_path,
    ]);
    assert_fails_cleanly(&o, &["nope"]);

    let points = write(
        dir.path(),
        "points.json",
        r#"{"points": [{"name": "A", "position": [5, 5, 0]}]}"#,
    );
    let o = run(&[
        "measure",
        s,
        "--points",
        points.to_str().unwrap(),
        "-o",
        o_path,
    ]);
    assert_fails_cleanly(&o, &["points.json", "normal"]);

    assert!(!out.exists(), "no output after a failure");
}

#[test]
fn false_colour_render_writes_png_only() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "lamp.json", LAMP_OVER_PLANE);
    let exr = dir.path().join("lux.exr");
    let o = run(&[
        "render",
        scene.to_str().unwrap(),
        "--false-colour",
        "lux",
        "-o",
        exr.to_str().unwrap(),
    ]);
    assert_fails_cleanly(&o, &["--false-colour", "png"]);
    assert!(!exr.exists());

    let png = dir.path().join("lux.png");
    let o = run(&[
        "render",
        scene.to_str().unwrap(),
        "--false-colour",
        "lux",
        "-o",
        png.to_str().unwrap(),
        "--eye",
        "5,-6,8",
        "--target",
        "5,5,0",
        "--up",
        "0,0,1",
        "--width",
        "96",
        "--height",
        "64",
        "--elements",
        "200",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&png).unwrap().to_rgb8();
    // The picture is wider than the render by the legend; it holds more than two colours.
    assert!(img.width() > 96);
    let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    colours.sort();
    colours.dedup();
    assert!(colours.len() > 20, "{} colours", colours.len());
}
