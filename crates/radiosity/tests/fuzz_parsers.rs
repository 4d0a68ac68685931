//! A mutation fuzzer for every parser, on stable Rust (proptest over byte strings).
//!
//! Each parser gets (a) valid seed files mutated by random byte replacements, insertions,
//! deletions and copied chunks, and (b) arbitrary bytes. The property: no panic, and what is
//! accepted is sound (finite geometry of positive area, reflectances in [0, 1), emission
//! finite and ≥ 0). Inputs reach the parsers as text, as they do after the UTF-8 check of
//! `radiosity::io::open` (invalid bytes become U+FFFD).
//!
//! CI runs 1000 cases per parser (seconds). A longer run:
//! `PROPTEST_CASES=100000 cargo test --release -p radiosity --test fuzz_parsers`. A failing
//! input is shrunk and saved by proptest under `tests/fuzz_parsers.proptest-regressions`;
//! commit that file so the input is replayed first on every later run.

use proptest::prelude::*;
use radiosity::formfactor::pair::PairProblem;
use radiosity::io::obj::parse_obj;
use radiosity::io::scene_file::parse_scene_file;
use radiosity::io::solution_file::SolutionFile;
use radiosity::photometry::{from_eulumdat, from_ies};
use radiosity::Scene;
use std::path::Path;

const OBJ: &str = "mtllib m.mtl\no floor\nusemtl white\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
f 1 2 3 4\nvn 0 0 1\nvn 0 0 -1\nvt 0 0\ng lamps\no lamp\nusemtl lamp\nv 0 0 1\nv 0 1 1\nv 1 1 1\nv 1 0 1\nv 0.5 0.5 1\n\
f -5 -4 -3 -2\nf 5/1/1 6//2 9\n# comment\ns off\n";

const MTL: &str =
    "newmtl white\nKd 0.5 0.5 0.5\nKs 0 0 0\nNs 10\nnewmtl lamp\nKd 0.5 0.5 0.5\nKe 10 10 10\nillum 1\n";

const SCENE: &str = r#"{
  "name": "box",
  "settings": { "elements": 50, "width": 8, "height": 8, "solver": "progressive" },
  "camera": { "eye": [0.5, 0.5, 3], "target": [0.5, 0.5, 0], "up": [0, 1, 0], "fov_deg": 40 },
  "materials": [
    { "name": "grey", "reflectance": [0.3, 0.3, 0.3] },
    { "name": "lamp", "reflectance": [0.5, 0.5, 0.5], "emission": [10, 10, 10] }
  ],
  "surfaces": [
    { "object": "wall", "group": "g", "material": "grey",
      "vertices": [[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]] },
    { "object": "lamp", "material": "lamp",
      "vertices": [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1], [0.5, -0.2, 1]] }
  ]
}"#;

/// Saved by `radiosity solve one.obj --elements 1 --patch-subdivision 1 --save` (a 1 m²
/// lamp quad).
const SOLUTION: &str = r#"{"format":"radiosity-solution","version":1,"scene":"one","camera":{"eye":[0.5,0.5,3.0],"target":[0.5,0.5,0.0],"up":[0.0,1.0,0.0],"fov_deg":40.0},"objects":["lamp"],"surfaces":[{"object":0,"scene_surface":0,"reflectance":[0.5,0.5,0.5],"exitance":[31.41592653589793,31.41592653589793,31.41592653589793]}],"vertices":[[0.0,0.0,1.0],[0.0,1.0,1.0],[1.0,1.0,1.0],[1.0,0.0,1.0]],"elements":[{"surface":0,"patch":0,"corners":[0,1,2,3],"centre":[0.5,0.5,1.0],"normal":[0.0,0.0,-1.0],"area":1.0,"parent":null,"depth":0}],"radiosity":[[31.41592653589793,31.41592653589793,31.41592653589793]],"irradiance":[[0.0,0.0,0.0]],"ambient":[0.0,0.0,0.0]}"#;

const PAIR: &str = r#"{"from": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]], "to": [[0,1,1],[1,1,1],[1,0,1],[0,0,1]], "occluders": [[[0.2,0.2,0.5],[0.8,0.2,0.5],[0.8,0.8,0.5]]]}"#;

const IES: &str = "IESNA:LM-63-2002\n[TEST] fuzz seed\n[MANUFAC] none\nTILT=NONE\n\
1 1000 1 3 1 1 2 0.6 0.6 0.1\n1 1 30\n0 45 90\n0\n100 80 0\n";

const LDT: &str = "Fuzz seed\r\n1\r\n1\r\n1\r\n0\r\n3\r\n45\r\nREPORT-1\r\nLuminaire\r\n\
CAT-1\r\nseed.ldt\r\n2024-01-01\r\n620\r\n620\r\n80\r\n600\r\n600\r\n0\r\n0\r\n0\r\n0\r\n\
100\r\n80\r\n1\r\n0\r\n1\r\n1\r\nLED\r\n1000\r\n4000\r\n80\r\n30\r\n0.5\r\n0.54\r\n0.58\r\n\
0.62\r\n0.66\r\n0.7\r\n0.74\r\n0.78\r\n0.82\r\n0.86\r\n0\r\n0\r\n45\r\n90\r\n100\r\n80\r\n0\r\n";

/// One edit of a byte string.
#[derive(Debug, Clone)]
enum Edit {
    Replace(usize, u8),
    Insert(usize, u8),
    Delete(usize),
    /// Copies `len` bytes from one place to another (repeats lines, numbers, brackets).
    Splice(usize, usize, usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    // Bytes that matter to these formats come up more often than arbitrary ones.
    let byte = prop_oneof![
        any::<u8>(),
        prop::sample::select(b"0123456789.-+eE \n\t/,[]{}\":#nanif".to_vec()),
    ];
    prop_oneof![
        (any::<usize>(), byte.clone()).prop_map(|(i, b)| Edit::Replace(i, b)),
        (any::<usize>(), byte).prop_map(|(i, b)| Edit::Insert(i, b)),
        any::<usize>().prop_map(Edit::Delete),
        (any::<usize>(), any::<usize>(), 1usize..40).prop_map(|(a, b, n)| Edit::Splice(a, b, n)),
    ]
}

fn mutate(seed: &str, edits: &[Edit]) -> String {
    let mut bytes = seed.as_bytes().to_vec();
    for e in edits {
        let n = bytes.len().max(1);
        match *e {
            Edit::Replace(i, b) if !bytes.is_empty() => bytes[i % n] = b,
            Edit::Insert(i, b) => bytes.insert(i % (bytes.len() + 1), b),
            Edit::Delete(i) if !bytes.is_empty() => {
                bytes.remove(i % n);
            }
            Edit::Splice(from, to, len) if !bytes.is_empty() => {
                let from = from % n;
                let chunk: Vec<u8> = bytes[from..(from + len).min(bytes.len())].to_vec();
                let to = to % (bytes.len() + 1);
                bytes.splice(to..to, chunk);
            }
            _ => {}
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

/// A seed mutated by up to 8 edits, or arbitrary bytes.
fn input(seed: &'static str) -> impl Strategy<Value = String> {
    prop_oneof![
        4 => prop::collection::vec(edit(), 1..8).prop_map(move |e| mutate(seed, &e)),
        1 => prop::collection::vec(any::<u8>(), 0..512)
            .prop_map(|b| String::from_utf8_lossy(&b).into_owned()),
    ]
}

/// What the readers promise about an accepted scene.
fn assert_sound(scene: &Scene) {
    for m in &scene.materials {
        for r in m.reflectance {
            assert!((0.0..1.0).contains(&r), "{}: reflectance {r}", m.name);
        }
        for e in m.emission {
            assert!(e.is_finite() && e >= 0.0, "{}: emission {e}", m.name);
        }
    }
    for s in &scene.surfaces {
        let area = s.polygon.area();
        assert!(area.is_finite() && area > 0.0, "{}: area {area}", s.object);
        assert!(s.polygon.vertices().iter().all(|v| v.is_finite()));
        assert!((s.material.0 as usize) < scene.materials.len());
    }
}

/// Cases per parser: `PROPTEST_CASES` if set, else 1000 (about a second each).
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1000)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    #[test]
    fn obj_and_mtl(obj in input(OBJ), mtl in input(MTL)) {
        if let Ok(scene) = parse_obj(&obj, "f.obj", |_| Ok(mtl.clone())) {
            assert_sound(&scene);
        }
    }

    #[test]
    fn scene_file(json in input(SCENE)) {
        // No include in the seed; an inserted one names a file that does not exist.
        let dir = std::env::temp_dir().join("radiosity-fuzz-no-such-dir");
        if let Ok(loaded) = parse_scene_file(&json, &dir.join("s.json")) {
            assert_sound(&loaded.scene);
        }
    }

    #[test]
    fn solution_file(json in input(SOLUTION)) {
        if let Ok(file) = SolutionFile::parse(&json, Path::new("s.json")) {
            for b in file.radiosity.iter().flatten() {
                assert!(b.is_finite() && *b >= 0.0, "radiosity {b}");
            }
        }
    }

    #[test]
    fn pair_problem(json in input(PAIR)) {
        let _ = PairProblem::from_json(&json);
    }

    #[test]
    fn ies(text in input(IES)) {
        let _ = from_ies(&text, "f.ies");
    }

    #[test]
    fn eulumdat(text in input(LDT)) {
        let _ = from_eulumdat(&text, "f.ldt");
    }
}

/// The seeds themselves are accepted, so the mutations start from valid files and reach
/// the parsers' deeper checks.
#[test]
fn seeds_are_valid() {
    let scene = parse_obj(OBJ, "f.obj", |_| Ok(MTL.to_owned())).unwrap();
    assert_sound(&scene);
    let loaded = parse_scene_file(SCENE, Path::new("s.json")).unwrap();
    assert_sound(&loaded.scene);
    SolutionFile::parse(SOLUTION, Path::new("s.json")).unwrap();
    PairProblem::from_json(PAIR).unwrap();
    from_ies(IES, "f.ies").unwrap();
    from_eulumdat(LDT, "f.ldt").unwrap();
}
