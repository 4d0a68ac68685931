//! `radiosity formfactor` end to end: one JSON line per method with the documented keys and
//! values matching Howell's closed forms, the accuracy table, and clean failures (a message
//! naming the file and the problem, exit status 1, no panic) on bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(args)
        .output()
        .expect("run radiosity")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Howell C-11: unit squares one apart, F = 0.19982489569838746 both ways.
const C11: &str = r#"{"from": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]],
                      "to": [[0,1,1],[1,1,1],[1,0,1],[0,0,1]]}"#;
const C11_F: f64 = 0.199_824_895_698_387_46;

fn lines(o: &Output) -> Vec<Value> {
    assert!(o.status.success(), "{}", stderr(o));
    stdout(o)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON: {l}: {e}")))
        .collect()
}

#[test]
fn prints_one_json_line_per_method_matching_howell() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "c11.json", C11);
    let out = lines(&run(&[
        "formfactor",
        file.to_str().unwrap(),
        "--method",
        "all",
    ]));
    let names: Vec<&str> = out.iter().map(|l| l["method"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "analytic-point",
            "analytic-polygon",
            "point-sampled",
            "hemicube",
            "raycast",
            "monte-carlo"
        ]
    );
    for l in &out {
        let method = l["method"].as_str().unwrap();
        // Every method's default settings reach 2e-3 on this case (see tests/formfactors.rs
        // in the library for the per-method tolerances and their reasons).
        for key in ["F_from_to", "F_to_from"] {
            let f = l[key].as_f64().unwrap();
            assert!((f - C11_F).abs() < 2e-3, "{method} {key} = {f}");
        }
        assert!(l["seconds"].as_f64().unwrap() >= 0.0);
        // A standard error exactly where the method is a random estimate.
        assert_eq!(
            l.get("stderr").is_some(),
            method == "monte-carlo",
            "{method}: {l}"
        );
    }
    // The default method is the default engine's, raycast; one line.
    let out = lines(&run(&["formfactor", file.to_str().unwrap()]));
    assert_eq!(out.len(), 1);
    assert_eq!(out[0]["method"], "raycast");
}

#[test]
fn a_point_source_has_no_reverse_form_factor() {
    // Howell B-3 a = b = c = 1: F = 0.13853160599489298.
    let dir = tempfile::tempdir().unwrap();
    let file = write(
        dir.path(),
        "b3.json",
        r#"{"from": {"point": [0,0,0], "normal": [0,0,1]}, "to": [[0,1,1],[1,1,1],[1,0,1],[0,0,1]]}"#,
    );
    let out = lines(&run(&[
        "formfactor",
        file.to_str().unwrap(),
        "--method",
        "analytic-point",
    ]));
    assert!((out[0]["F_from_to"].as_f64().unwrap() - 0.138_531_605_994_892_98).abs() < 1e-12);
    assert!(out[0]["F_to_from"].is_null());
}

#[test]
fn occluders_and_method_parameters_are_used() {
    let dir = tempfile::tempdir().unwrap();
    // A plate between the squares hiding everything.
    let blocked = write(
        dir.path(),
        "blocked.json",
        r#"{"from": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]], "to": [[0,1,1],[1,1,1],[1,0,1],[0,0,1]],
            "occluders": [[[-2,-2,0.5],[3,-2,0.5],[3,3,0.5],[-2,3,0.5]]]}"#,
    );
    let out = lines(&run(&[
        "formfactor",
        blocked.to_str().unwrap(),
        "--method",
        "monte-carlo",
    ]));
    assert_eq!(out[0]["F_from_to"], 0.0);
    // Fewer rays: a larger standard error, about 0.4/√N; the seed makes it reproducible.
    let file = write(dir.path(), "c11.json", C11);
    let args = [
        "formfactor",
        file.to_str().unwrap(),
        "--method",
        "monte-carlo",
        "--samples",
        "10000",
        "--seed",
        "3",
    ];
    let a = lines(&run(&args));
    let se = a[0]["stderr"].as_f64().unwrap();
    assert!(
        (se - (C11_F * (1.0 - C11_F) / 9999.0).sqrt()).abs() < 4e-4,
        "stderr {se}"
    );
    let b = lines(&run(&args));
    for key in ["F_from_to", "F_to_from", "stderr"] {
        assert_eq!(a[0][key], b[0][key], "same seed, same {key}");
    }
    // A coarse hemi-cube is coarser.
    let coarse = lines(&run(&[
        "formfactor",
        file.to_str().unwrap(),
        "--method",
        "hemicube",
        "--resolution",
        "8",
    ]));
    let fine = lines(&run(&[
        "formfactor",
        file.to_str().unwrap(),
        "--method",
        "hemicube",
    ]));
    let err = |l: &Vec<Value>| (l[0]["F_from_to"].as_f64().unwrap() - C11_F).abs();
    assert!(
        err(&coarse) > err(&fine),
        "resolution 8: {} vs default: {}",
        err(&coarse),
        err(&fine)
    );
}

#[test]
fn table_lists_each_method_with_its_errors() {
    let o = run(&["formfactor", "--table", "--method", "analytic-polygon"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(
        text.starts_with("| method | max abs error | mean abs error |"),
        "{text}"
    );
    let row = text
        .lines()
        .find(|l| l.starts_with("| analytic-polygon |"))
        .expect("a row");
    let max: f64 = row.split('|').nth(2).unwrap().trim().parse().unwrap();
    assert!(max < 1e-6, "{row}");
}

/// Asserts a clean failure: exit status 1, no panic, the message mentions every needle.
fn assert_fails_cleanly(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "exit status; stderr: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    for n in needles {
        assert!(err.contains(n), "message should mention '{n}': {err}");
    }
}

#[test]
fn bad_input_fails_cleanly_naming_the_file_and_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "syntax.json",
            r#"{"from": [[0,0,0],"#,
            vec!["not valid JSON"],
        ),
        (
            "nan.json",
            r#"{"from": [[0,0,0],[1,0,0],[1,1,NaN]], "to": [[0,0,1],[0,1,1],[1,1,1]]}"#,
            vec!["not valid JSON"],
        ),
        (
            "huge.json",
            r#"{"from": [[0,0,0],[1,0,0],[1,1,1e999]], "to": [[0,0,1],[0,1,1],[1,1,1]]}"#,
            vec!["not valid JSON"],
        ),
        (
            "degenerate.json",
            r#"{"from": [[0,0,0],[1,0,0],[2,0,0]], "to": [[0,0,1],[0,1,1],[1,1,1]]}"#,
            vec!["from", "degenerate"],
        ),
        (
            "concave.json",
            r#"{"from": [[0,0,0],[2,0,0],[2,2,0],[1,0.5,0],[0,2,0]], "to": [[0,0,1],[0,1,1],[1,1,1]]}"#,
            vec!["from", "not convex"],
        ),
        (
            "vertex.json",
            r#"{"from": [[0,0,0],[1,0,0],[1,1,0]], "to": [[0,0,1],[0,1],[1,1,1]]}"#,
            vec!["to: vertex 1"],
        ),
        (
            "missing.json",
            r#"{"from": [[0,0,0],[1,0,0],[1,1,0]]}"#,
            vec!["missing \"to\""],
        ),
        (
            "normal.json",
            r#"{"from": {"point": [0,0,0], "normal": [0,0,0]}, "to": [[0,0,1],[0,1,1],[1,1,1]]}"#,
            vec!["normal", "zero length"],
        ),
    ];
    for (name, text, needles) in cases {
        let file = write(dir.path(), name, text);
        let o = run(&["formfactor", file.to_str().unwrap(), "--method", "all"]);
        let mut all = needles.clone();
        all.push(name);
        assert_fails_cleanly(&o, &all);
        assert!(stdout(&o).is_empty(), "{name}: no output on failure");
    }
    let file = write(dir.path(), "c11.json", C11);
    assert_fails_cleanly(
        &run(&[
            "formfactor",
            file.to_str().unwrap(),
            "--method",
            "radiosity",
        ]),
        &["unknown form-factor method 'radiosity'", "analytic-polygon"],
    );
    assert_fails_cleanly(
        &run(&["formfactor", "no/such/file.json"]),
        &["reading no/such/file.json"],
    );
    assert_fails_cleanly(
        &run(&["formfactor", file.to_str().unwrap(), "--samples", "0"]),
        &["--samples"],
    );
}

#[test]
fn jittered_hemicube_is_reachable_and_accurate() {
    let dir = tempfile::tempdir().unwrap();
    // Howell C-11, unit squares one apart: F = 0.19982489569838746.
    let file = write(
        dir.path(),
        "c11.json",
        r#"{"from": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]], "to": [[0,1,1],[1,1,1],[1,0,1],[0,0,1]]}"#,
    );
    let f = file.to_str().unwrap();
    let plain = lines(&run(&["formfactor", f, "--method", "hemicube"]));
    let a = lines(&run(&[
        "formfactor",
        f,
        "--method",
        "hemicube",
        "--jitter",
        "--seed",
        "3",
    ]));
    let b = lines(&run(&[
        "formfactor",
        f,
        "--method",
        "hemicube",
        "--jitter",
        "--seed",
        "4",
    ]));
    let value = |v: &[Value]| v[0]["F_from_to"].as_f64().unwrap();
    // Jitter rotates each hemi-cube: the seed changes the answer, and each stays within the
    // hemicube's 1e-3 bound at resolution 128 (see tests/formfactors.rs).
    assert_ne!(value(&a), value(&b));
    assert_ne!(value(&a), value(&plain));
    for v in [value(&plain), value(&a), value(&b)] {
        assert!((v - 0.19982489569838746).abs() < 1e-3, "{v}");
    }
}
