//! `radiosity progressive` and `radiosity compare` end to end: the files they promise, at the
//! requested size, and clean failures (message naming the culprit, exit status 1, no panic,
//! nothing half-written) on bad input.

use std::path::Path;
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

fn files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    names
}

fn assert_fails_cleanly(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "exit status; stderr: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    for n in needles {
        assert!(err.contains(n), "message should mention '{n}': {err}");
    }
}

/// Small, fast settings: a coarse Cornell box, tiny frames.
const FAST: &[&str] = &[
    "--elements",
    "300",
    "--width",
    "40",
    "--height",
    "30",
    "--samples",
    "2",
];

#[test]
fn progressive_writes_every_frame_and_the_sheet() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("seq");
    let o = run(&[
        &[
            "progressive",
            "-o",
            out.to_str().unwrap(),
            "--frames",
            "0,2,5",
            "--hdr",
            "--ambient",
        ],
        FAST,
    ]
    .concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        files(&out),
        [
            "frame_0000.exr",
            "frame_0000.png",
            "frame_0002.exr",
            "frame_0002.png",
            "frame_0005.exr",
            "frame_0005.png",
            "sheet.png"
        ],
        "exactly the promised files, no temporaries"
    );
    for n in ["0000", "0002", "0005"] {
        let png = image::open(out.join(format!("frame_{n}.png"))).unwrap();
        assert_eq!((png.width(), png.height()), (40, 30));
    }
    let exr = radiosity::render::Image::read_exr(&out.join("frame_0005.exr")).unwrap();
    assert_eq!((exr.width, exr.height), (40, 30));
    // Linear radiance, not clipped: the light shows its L_e = 17 W·m⁻²·sr⁻¹ in red.
    assert!(exr.pixels.iter().any(|p| p[0] > 1.0));
    // The sheet: three frames side by side (tiles at least 150 px wide), labels beneath.
    let sheet = image::open(out.join("sheet.png")).unwrap();
    assert_eq!(sheet.width(), 8 + 3 * (150 + 8));
    assert!(sheet.height() > 30 + 2 * 13);
    // The summary names each frame and its shots.
    let err = stderr(&o);
    assert!(err.contains("frame     2: 2 shots"), "{err}");
}

#[test]
fn progressive_says_when_it_converged_before_the_frame() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("seq");
    let o = run(&[
        &[
            "progressive",
            "-o",
            out.to_str().unwrap(),
            "--frames",
            "0,1000000",
            "--tolerance",
            "1e-2",
        ],
        FAST,
    ]
    .concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("converged after"), "{}", stderr(&o));
    assert_eq!(
        files(&out),
        ["frame_0000.png", "frame_1000000.png", "sheet.png"]
    );
}

#[test]
fn progressive_adaptive_with_wireframe_runs() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("seq");
    let o = run(&[
        &[
            "progressive",
            "-o",
            out.to_str().unwrap(),
            "--frames",
            "0,4,16",
            "--adaptive",
            "--wireframe",
        ][..],
        &[
            "--refine-threshold",
            "0.05",
            "--max-depth",
            "2",
            "--overshoot",
            "1.1",
        ],
        FAST,
    ]
    .concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        files(&out),
        [
            "frame_0000.png",
            "frame_0004.png",
            "frame_0016.png",
            "sheet.png"
        ]
    );
}

#[test]
fn progressive_rejects_bad_frame_lists_before_writing_anything() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("seq");
    let o = |frames: &str| {
        run(&[
            &[
                "progressive",
                "-o",
                out.to_str().unwrap(),
                "--frames",
                frames,
            ],
            FAST,
        ]
        .concat())
    };
    assert_fails_cleanly(&o("0,8,x"), &["--frames", "'x'"]);
    assert_fails_cleanly(&o("0,16,8"), &["--frames", "increasing", "16", "8"]);
    assert_fails_cleanly(&o(""), &["--frames"]);
    assert!(!out.exists(), "nothing created for a bad command line");
}

#[test]
fn progressive_rejects_bad_options() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("seq");
    let base = [
        "progressive",
        "-o",
        out.to_str().unwrap(),
        "--frames",
        "0,1",
    ];
    assert_fails_cleanly(
        &run(&[&base[..], &["--overshoot", "2.5"], FAST].concat()),
        &["--overshoot", "2.5"],
    );
    assert_fails_cleanly(
        &run(&[&base[..], &["--adaptive", "--refine-threshold", "0"], FAST].concat()),
        &["--refine-threshold"],
    );
    assert_fails_cleanly(
        &run(&[&base[..], &["--tolerance", "0"], FAST].concat()),
        &["--tolerance"],
    );
    // The output "directory" is a file.
    let file = d.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let o = run(&[
        &["progressive", "-o", file.to_str().unwrap(), "--frames", "0"],
        FAST,
    ]
    .concat());
    assert_fails_cleanly(&o, &["a-file"]);
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
}

#[test]
fn compare_writes_plot_and_table() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("cmp");
    let o = run(&[
        "compare",
        "-o",
        out.to_str().unwrap(),
        "--elements",
        "200",
        // The hierarchical series at 0.32, 0.16, 0.08, 0.04: coarse, to stay fast.
        "--epsilon",
        "0.04",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        files(&out),
        [
            "comparison.json",
            "convergence.png",
            "convergence.svg",
            "table.md"
        ]
    );
    let table = std::fs::read_to_string(out.join("table.md")).unwrap();
    for name in [
        "direct (LU)",
        "Jacobi",
        "Gauss–Seidel",
        "progressive + ambient",
        "overshoot",
        "hierarchical (per-object ε, whole solve)",
        "| 0.04 |",
    ] {
        assert!(table.contains(name), "{table}");
    }
    assert_eq!(
        String::from_utf8_lossy(&o.stdout),
        table,
        "the table is also printed"
    );
    let png = image::open(out.join("convergence.png")).unwrap();
    assert!(png.width() >= 800 && png.height() >= 400);
}

#[test]
fn compare_rejects_bad_options() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("cmp");
    let o = |extra: &[&str]| {
        run(&[
            &[
                "compare",
                "-o",
                out.to_str().unwrap(),
                "--elements",
                "100",
                "-q",
            ],
            extra,
        ]
        .concat())
    };
    assert_fails_cleanly(&o(&["--overshoot", "1"]), &["--overshoot"]);
    assert_fails_cleanly(&o(&["--target-error", "2"]), &["--target-error"]);
    assert_fails_cleanly(&o(&["--tolerance", "1e-3"]), &["--target-error"]);
    assert_fails_cleanly(&o(&["--epsilon", "1"]), &["--epsilon"]);
    // A per-polygon reference that is missing, not JSON, malformed, or names an object the
    // scene lacks: refused before any work, naming the file (and the object).
    let missing = d.path().join("missing.json");
    assert_fails_cleanly(
        &o(&["--reference", missing.to_str().unwrap()]),
        &["missing.json"],
    );
    let bad = d.path().join("bad.json");
    for (text, says) in [
        ("not json", "not JSON"),
        (r#"{"polygons": [{"name": "floor"}]}"#, "radiosity_avg"),
        (
            r#"{"polygons": [{"name": "no_such_wall", "radiosity_avg": [1, 1, 1]}]}"#,
            "no_such_wall",
        ),
    ] {
        std::fs::write(&bad, text).unwrap();
        assert_fails_cleanly(
            &o(&["--reference", bad.to_str().unwrap()]),
            &["bad.json", says],
        );
    }
    assert!(!out.exists());
}

/// `--reference`: every solve measured per polygon against the path tracer's values of the
/// Cornell box, in the table.
#[test]
fn compare_measures_against_a_per_polygon_reference() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("cmp");
    let reference = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../radiosity/tests/reference/cornell_path_traced.json"
    );
    let o = run(&[
        "compare",
        "-o",
        out.to_str().unwrap(),
        "--elements",
        "200",
        "--epsilon",
        "0.04",
        "--reference",
        reference,
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = std::fs::read_to_string(out.join("table.md")).unwrap();
    for needle in [
        "cornell_path_traced.json, per polygon",
        "| study mesh, ",
        "| hierarchical, ε = 0.04, ",
    ] {
        assert!(table.contains(needle), "{needle}: {table}");
    }
}
