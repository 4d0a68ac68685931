//! Scenes users bring, end to end: a closed room renders lit from the default camera and
//! named after its file, outputs are not overwritten without --force, scenes that would
//! render black say why, and a glTF scene solves and bakes to GLB.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the binary in `dir` (outputs named after the input land there).
fn run_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run radiosity")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../radiosity/scenes")
}

/// A closed 4 × 2.7 × 3 m room (faces counter-clockwise seen from inside) with a 0.5 m
/// square ceiling lamp; `lamp_down` false winds the lamp to face the ceiling.
fn room_obj(lamp_down: bool, emission: f64) -> String {
    let lamp = if lamp_down {
        "f 9 10 11 12"
    } else {
        "f 12 11 10 9"
    };
    format!(
        "mtllib room.mtl\n\
         v 0 0 0\nv 4 0 0\nv 4 0 3\nv 0 0 3\nv 0 2.7 0\nv 4 2.7 0\nv 4 2.7 3\nv 0 2.7 3\n\
         v 1.75 2.69 1.25\nv 2.25 2.69 1.25\nv 2.25 2.69 1.75\nv 1.75 2.69 1.75\n\
         o floor\nusemtl wall\nf 1 4 3 2\n\
         o ceiling\nusemtl wall\nf 5 6 7 8\n\
         o walls\nusemtl wall\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n\
         o lamp\nusemtl lamp\n{lamp}\n\
         # emission {emission}\n"
    )
}

fn write_room(dir: &Path, lamp_down: bool, emission: f64) {
    std::fs::write(dir.join("room.obj"), room_obj(lamp_down, emission)).unwrap();
    std::fs::write(
        dir.join("room.mtl"),
        format!("newmtl wall\nKd 0.7 0.7 0.7\nnewmtl lamp\nKd 0.5 0.5 0.5\nKe {emission} {emission} {emission}\n"),
    )
    .unwrap();
}

const FAST: &[&str] = &[
    "--elements",
    "200",
    "--quiet",
    "--width",
    "48",
    "--height",
    "36",
];

#[test]
fn closed_room_renders_lit_from_inside_named_after_the_file_and_is_not_overwritten() {
    let d = tempfile::tempdir().unwrap();
    write_room(d.path(), true, 20.0);
    let o = run_in(d.path(), &[&["render", "room.obj"], FAST].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    // No warning for a sound scene.
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    let png = d.path().join("room.png");
    let img = image::open(&png)
        .expect("room.png, named after room.obj")
        .to_rgb8();
    // The default camera is inside the room: the lit walls fill the image. (From outside,
    // the camera would see the backs of the walls, which are black.)
    let lit = img.pixels().filter(|p| p.0.iter().any(|&c| c > 30)).count();
    assert!(
        lit > img.pixels().len() / 2,
        "{lit} of {} pixels lit",
        img.pixels().len()
    );

    // Again without --force: refused, the file untouched; with --force: written.
    let before = std::fs::read(&png).unwrap();
    let o = run_in(d.path(), &[&["render", "room.obj"], FAST].concat());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&png).unwrap(), before);
    let o = run_in(
        d.path(),
        &[&["render", "room.obj", "--force"], FAST].concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_room_without_emitter_warns_on_stderr_and_in_the_report() {
    let d = tempfile::tempdir().unwrap();
    write_room(d.path(), true, 0.0);
    let o = run_in(
        d.path(),
        &[
            "solve",
            "room.obj",
            "--elements",
            "100",
            "--report",
            "r.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("nothing emits light"), "{}", stderr(&o));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.path().join("r.json")).unwrap()).unwrap();
    let warnings = report["warnings"]
        .as_array()
        .expect("warnings in the report");
    assert!(warnings
        .iter()
        .any(|w| w.as_str().unwrap().contains("nothing emits light")));
}

#[test]
fn a_room_wound_inside_out_is_named_and_two_sided_lights_it() {
    let d = tempfile::tempdir().unwrap();
    write_room(d.path(), true, 20.0);
    // Every room face wound the other way (as a modeller that made the room solid would):
    // the lamp's light lands on their black backs.
    let text = std::fs::read_to_string(d.path().join("room.obj")).unwrap();
    let flipped: String = text
        .lines()
        .map(|l| match l.strip_prefix("f ") {
            Some(rest) if !l.starts_with("f 9 ") => {
                let mut v: Vec<&str> = rest.split(' ').collect();
                v.reverse();
                format!("f {}\n", v.join(" "))
            }
            _ => format!("{l}\n"),
        })
        .collect();
    std::fs::write(d.path().join("room.obj"), flipped).unwrap();
    let o = run_in(d.path(), &[&["render", "room.obj"], FAST].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("backs of one-sided"), "{err}");
    assert!(err.contains("'floor'"), "{err}");
    assert!(err.contains("--two-sided"), "{err}");
    // As advised: with --two-sided the backs reflect, no warning, and the room is lit, with
    // either kind of solver. (The hierarchical solver refines the two sides of a surface
    // apart, so no element has a twin at its own place, and the room rendered black: each
    // back was drawn over the side facing the camera.)
    for solver in ["progressive", "hierarchical"] {
        let o = run_in(
            d.path(),
            &[
                &["render", "room.obj", "--two-sided", "--force"],
                FAST,
                &["--solver", solver],
            ]
            .concat(),
        );
        assert!(o.status.success(), "{solver}: {}", stderr(&o));
        assert!(!stderr(&o).contains("warning"), "{solver}: {}", stderr(&o));
        let img = image::open(d.path().join("room.png")).unwrap().to_rgb8();
        let lit = img.pixels().filter(|p| p.0.iter().any(|&c| c > 30)).count();
        assert!(lit > img.pixels().len() / 2, "{solver}: {lit} lit pixels");
    }
}

#[test]
fn solution_render_is_named_after_the_solution_and_looks_at_the_centre() {
    let d = tempfile::tempdir().unwrap();
    let o = run_in(
        d.path(),
        &[
            "solve",
            "--elements",
            "200",
            "--quiet",
            "--save",
            "box.solution.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // The README's example: --eye alone keeps looking at the scene's centre, so the box is
    // in view; the output is named after the solution, not cornell.png.
    let o = run_in(
        d.path(),
        &[
            "render",
            "--solution",
            "box.solution.json",
            "--eye",
            "0.1,0.4,-0.5",
            "--width",
            "48",
            "--height",
            "36",
            "--quiet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!d.path().join("cornell.png").exists());
    let img = image::open(d.path().join("box.png")).unwrap().to_rgb8();
    let lit = img.pixels().filter(|p| p.0.iter().any(|&c| c > 30)).count();
    assert!(lit > img.pixels().len() / 4, "{lit} lit pixels");
}

#[test]
fn gltf_scene_solves_and_bakes_to_glb() {
    let d = tempfile::tempdir().unwrap();
    let glb = scenes().join("cornell.glb");
    let o = run_in(
        d.path(),
        &[
            "solve",
            glb.to_str().unwrap(),
            "--elements",
            "200",
            "--quiet",
            "--bake",
            "out.glb",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for name in ["out.glb", "out_lightmap.png", "out_lightmap.exr"] {
        let meta = std::fs::metadata(d.path().join(name)).expect(name);
        assert!(meta.len() > 0, "{name}");
    }
    let bytes = std::fs::read(d.path().join("out.glb")).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    // The baked GLB is itself a scene we can read back.
    let o = run_in(
        d.path(),
        &[
            "render",
            "out.glb",
            "--elements",
            "100",
            "--quiet",
            "--width",
            "16",
            "--height",
            "16",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.path().join("out.png").exists());
    // An existing bake target is refused before solving.
    let o = run_in(
        d.path(),
        &[
            "solve",
            glb.to_str().unwrap(),
            "--elements",
            "100",
            "--bake",
            "out.glb",
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("exists"), "{}", stderr(&o));
}
