//! The `radiosity` binary end to end: outputs are valid and bad input fails cleanly (a clear
//! message naming the culprit, a non-zero exit status, no panic, no output file left behind).

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run radiosity")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Small, fast settings for tests that only check plumbing.
const FAST: &[&str] = &["--elements", "300", "--quiet"];

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A reader that goes away before the report is printed (`radiosity solve | head -1`) does
/// not make the command fail or panic: the solve finishes and exits 0. (It panicked with
/// exit status 101: `println!` on a closed pipe.) The read end is closed before the solve
/// can have written anything, so the write meets the closed pipe every time.
#[test]
fn a_reader_that_goes_away_is_not_a_panic() {
    let mut child = bin()
        .args(["solve", "--elements", "300", "--quiet"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run radiosity");
    drop(child.stdout.take());
    let o = child.wait_with_output().expect("wait for radiosity");
    let err = stderr(&o);
    assert!(o.status.success(), "exit {:?}; stderr: {err}", o.status);
    assert!(!err.contains("panicked"), "panic: {err}");
}

/// The same with standard error gone (`radiosity solve --report r.json 2>&1 | head -1`): the
/// summary and warnings are dropped, the report is written and the command exits 0. (The
/// summary's `eprintln!` panicked, exit status 101, before the report was written.)
#[test]
fn a_closed_standard_error_still_writes_the_report() {
    let dir = tmp();
    let report = dir.path().join("r.json");
    let mut child = bin()
        .args(["solve", "--elements", "300", "--report"])
        .arg(&report)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run radiosity");
    drop(child.stderr.take());
    let status = child.wait().expect("wait for radiosity");
    assert!(status.success(), "exit {status:?}");
    let text = std::fs::read_to_string(&report).expect("the report is written");
    assert!(text.contains("\"objects\""), "{text}");
}

/// Asserts a clean failure: non-zero exit, no panic, the message mentions every `needles`.
fn assert_fails_cleanly(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert!(
        !o.status.success(),
        "expected failure, got success; stderr: {err}"
    );
    assert_eq!(o.status.code(), Some(1), "exit code; stderr: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    for n in needles {
        assert!(err.contains(n), "message should mention '{n}': {err}");
    }
}

#[test]
fn render_writes_png_of_requested_size() {
    let d = tmp();
    let out = d.path().join("box.png");
    let o = run(&[
        &[
            "render",
            "-o",
            out.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
        ],
        FAST,
    ]
    .concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (64, 48));
    // Something is lit: the image is not black.
    assert!(img.to_rgb8().pixels().any(|p| p.0.iter().any(|&c| c > 30)));
    // No temporary files left beside it.
    assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
}

#[test]
fn render_writes_exr_with_reference_camera() {
    let d = tmp();
    let out = d.path().join("box.exr");
    let o = run(&[
        &[
            "render",
            "-o",
            out.to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "32",
            "--eye",
            "0.278,0.273,-0.8",
            "--target",
            "0.278,0.273,0",
            "--up",
            "0,1,0",
            "--fov",
            "39.3076",
        ],
        FAST,
    ]
    .concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let img = radiosity::render::Image::read_exr(&out).unwrap();
    assert_eq!((img.width, img.height), (32, 32));
    // The light (L_e = 17, 12, 4 W·m⁻²·sr⁻¹) is visible at the top centre and is not clipped
    // in EXR; everything is finite and non-negative.
    let max_r = img.pixels.iter().map(|p| p[0]).fold(0.0f32, f32::max);
    assert!(max_r > 10.0, "light radiance in EXR: {max_r}");
    assert!(img
        .pixels
        .iter()
        .flatten()
        .all(|v| v.is_finite() && *v >= 0.0));
}

#[test]
fn solve_writes_report_with_documented_keys() {
    let d = tmp();
    let report = d.path().join("report.json");
    let o = run(&[&["solve", "--report", report.to_str().unwrap()], FAST].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let objects = v["objects"].as_array().unwrap();
    assert_eq!(objects.len(), 20);
    for key in [
        "name",
        "area",
        "reflectance",
        "emitted_exitance",
        "radiosity",
        "irradiance",
        "absorbed_power",
    ] {
        assert!(objects[0].get(key).is_some(), "object key {key}");
    }
    for key in [
        "emitted_power",
        "absorbed_power",
        "escaped_power",
        "elements",
        "solver",
        "iterations",
        "residual",
        "seconds",
    ] {
        assert!(v["totals"].get(key).is_some(), "totals key {key}");
    }
    // Emitted power of the light: E·A = π·L_e·A with A = 0.13 × 0.105 m².
    let emitted = v["totals"]["emitted_power"][0].as_f64().unwrap();
    let expected = std::f64::consts::PI * 17.0 * 0.130 * 0.105;
    assert!(
        (emitted - expected).abs() < 1e-9 * expected,
        "{emitted} vs {expected}"
    );
}

#[test]
fn saved_solution_renders_from_another_viewpoint() {
    let d = tmp();
    let sol = d.path().join("box.solution.json");
    let o = run(&[&["solve", "--save", sol.to_str().unwrap()], FAST].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let out = d.path().join("side.png");
    let o = run(&[
        "render",
        "--solution",
        sol.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--width",
        "40",
        "--height",
        "30",
        "--eye",
        "0.1,0.4,0.2",
        "--target",
        "0.4,0.1,0.5",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (40, 30));
}

#[test]
fn bad_inputs_fail_cleanly() {
    let d = tmp();
    let dir = d.path();
    write(dir, "m.mtl", "newmtl white\nKd 0.5 0.5 0.5\nKe 0 0 0\n");
    write(dir, "hot.mtl", "newmtl hot\nKd 1.2 0.5 0.5\n");
    let good_face =
        "mtllib m.mtl\no quad\nusemtl white\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        ("missing.obj", String::new(), vec!["missing.obj"]),
        (
            "malformed.obj",
            good_face.replace("v 1 1 0", "v 1 x 0"),
            vec!["malformed.obj"],
        ),
        (
            "index.obj",
            good_face.replace("f 1 2 3 4", "f 1 2 3 40"),
            vec!["index.obj"],
        ),
        (
            "nan.obj",
            good_face.replace("v 1 1 0", "v 1 nan 0"),
            vec!["nan.obj"],
        ),
        (
            "degenerate.obj",
            good_face
                .replace("v 1 1 0", "v 2 0 0")
                .replace("v 0 1 0", "v 3 0 0"),
            vec!["degenerate.obj", "quad"],
        ),
        (
            "nomat.obj",
            good_face.replace("usemtl white", "usemtl plaid"),
            vec!["nomat.obj", "plaid"],
        ),
        (
            "rho.obj",
            good_face
                .replace("m.mtl", "hot.mtl")
                .replace("usemtl white", "usemtl hot"),
            vec!["hot.mtl", "hot", "1.2"],
        ),
        (
            "huge.obj",
            good_face.replace("v 1 1 0", "v 1e300 1 0"),
            vec!["huge.obj"],
        ),
        ("scene.txt", "hello".into(), vec!["scene.txt"]),
        (
            "bad.json",
            "{\n  \"name\": \"x\",\n  \"surfaces\": [\n}".into(),
            vec!["bad.json", "line"],
        ),
    ];
    for (name, text, needles) in cases {
        let path = if name == "missing.obj" {
            dir.join(name)
        } else {
            write(dir, name, &text)
        };
        let out = dir.join(format!("{name}.png"));
        let mut args = vec![
            "render",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--quiet",
        ];
        // ρ ≥ 1 is clamped with a warning by default (real files are messy); an error with
        // --strict.
        if name == "rho.obj" {
            args.push("--strict");
        }
        let o = run(&args);
        assert_fails_cleanly(&o, &needles);
        assert!(!out.exists(), "{name}: output left behind");
    }
}

#[test]
fn bad_options_fail_cleanly() {
    let d = tmp();
    let out = d.path().join("x.png");
    let o_str = out.to_str().unwrap();
    let bmp = format!("{o_str}.bmp");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["render", "-o", o_str, "--width", "0"], "width"),
        (vec!["render", "-o", o_str, "--width", "100000"], "width"),
        (
            vec!["render", "-o", o_str, "--max-element-size", "1e-7"],
            "elements",
        ),
        (
            vec!["render", "-o", o_str, "--max-element-size", "-1"],
            "element size",
        ),
        (vec!["render", "-o", o_str, "--solver", "magic"], "magic"),
        (
            vec!["render", "-o", o_str, "--form-factor", "guess"],
            "guess",
        ),
        (vec!["render", "-o", o_str, "--eye", "1,2"], "x,y,z"),
        (vec!["render", "-o", o_str, "--fov", "0"], "fov"),
        (
            vec![
                "solve",
                "--solver",
                "direct",
                "--elements",
                "200000",
                "--patch-subdivision",
                "1",
            ],
            "MiB",
        ),
        (vec!["render", "-o", &bmp], "bmp"),
        (
            vec!["render", "--solution", "/nonexistent/sol.json", "-o", o_str],
            "sol.json",
        ),
    ];
    for (args, needle) in cases {
        let o = run(&[&args[..], &["--quiet"]].concat());
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} should fail");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            err.contains(needle),
            "{args:?}: message should mention '{needle}': {err}"
        );
        assert!(!out.exists(), "{args:?}: output left behind");
    }
}

#[test]
fn elements_bound_the_hierarchical_leaves() {
    // `--elements N` with the hierarchical solver: no element is subdivided below 1/N of the
    // total area, so subdivision makes at most N leaves, plus input polygons left whole. A
    // fine ε (0.005) asks for far more: 12k leaves without the bound.
    let d = tmp();
    let leaves = |extra: &[&str]| {
        let report = d.path().join("r.json");
        let o = run(&[
            &[
                "solve",
                "--solver",
                "hierarchical",
                "--epsilon",
                "0.005",
                "--report",
                report.to_str().unwrap(),
                "--force",
                "--quiet",
            ],
            extra,
        ]
        .concat());
        assert!(o.status.success(), "{}", stderr(&o));
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        r["totals"]["elements"].as_u64().unwrap()
    };
    let scene = radiosity::cornell::cornell_box();
    let inputs = radiosity::mesh::two_sided::with_back_sides(&scene)
        .map_or(scene.surfaces.len(), |s| s.surfaces.len()) as u64;
    let bounded = leaves(&["--elements", "2000"]);
    let free = leaves(&[]);
    assert!(
        bounded <= 2000 + inputs,
        "{bounded} leaves, {inputs} inputs"
    );
    assert!(bounded < free, "{bounded} with the bound, {free} without");
}

#[test]
fn hierarchical_summary_shows_the_links_and_the_tolerance() {
    // The summary of a hierarchical solve says how big the hierarchy got and to which ε it
    // was refined (the classic solvers' summary has no such line).
    let d = tmp();
    let report = d.path().join("r.json");
    let o = run(&[
        "solve",
        "--solver",
        "hierarchical",
        "--epsilon",
        "0.05",
        "--report",
        report.to_str().unwrap(),
        "--force",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let line = err
        .lines()
        .find(|l| l.starts_with("hierarchy: "))
        .unwrap_or_else(|| panic!("no hierarchy line: {err}"));
    let links: usize = line
        .trim_start_matches("hierarchy: ")
        .split(' ')
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    // Light reaches the box's surfaces over links, a few per leaf (about 9 on this box).
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let leaves = r["totals"]["elements"].as_u64().unwrap() as usize;
    assert!(
        links > leaves && links < 100 * leaves,
        "{links} links, {leaves} leaves"
    );
    assert!(line.ends_with("link tolerance ε 0.05"), "{line}");
    assert!(!err.contains("memory limit"), "{err}");
}
