//! Scene input: the built-in Cornell box against the reference data, scene-file round trips,
//! and one test per kind of bad input (error variant, file, line, object in the message).
//!
//! Paths are relative to the crate root, where cargo runs integration tests.

use radiosity::cornell::{cornell_box, cornell_camera};
use radiosity::geometry::{GeometryError, Polygon};
use radiosity::io::error::SceneError;
use radiosity::io::formats::{load_any_with, LoadOptions};
use radiosity::io::obj::{load_obj, parse_obj, DEFAULT_GREY, MAX_REFLECTANCE};
use radiosity::io::scene_file::{
    load_any, load_scene_file, save_scene_file, scene_to_json, SceneSettings,
};
use radiosity::scene::{Origin, Scene};
use std::path::{Path, PathBuf};

/// `cornell_reference.json → per_polygon_area_averaged.polygons[*].{name, area}` (mm²), in
/// the reference's order, which is also the OBJ's.
const REFERENCE_AREAS_MM2: [(&str, f64); 20] = [
    ("floor", 308231.04000000004),
    ("ceiling_front", 126212.0),
    ("ceiling_back", 126323.20000000003),
    ("ceiling_right", 22365.0),
    ("ceiling_left", 22365.0),
    ("light", 13650.0),
    ("back_wall", 303376.64),
    ("right_wall_green", 306888.96),
    ("left_wall_red_tri0", 153457.42589549194),
    ("left_wall_red_tri1", 153447.0884909479),
    ("short_block_top", 27633.0),
    ("short_block_side_facing_red", 27344.23888134391),
    ("short_block_front", 27610.27390302385),
    ("short_block_side_facing_green", 27562.409183523854),
    ("short_block_back", 27198.987573069702),
    ("tall_block_top", 27626.5),
    ("tall_block_side_facing_red", 54905.098123944736),
    ("tall_block_back", 54688.47776268782),
    ("tall_block_side_facing_green", 55220.5478060477),
    ("tall_block_front", 54589.8204796462),
];

fn without_origins(mut scene: Scene) -> Scene {
    for s in &mut scene.surfaces {
        s.origin = Origin::default();
    }
    scene
}

#[test]
fn cornell_box_matches_reference_polygons() {
    let scene = cornell_box();
    assert_eq!(scene.name, "cornell");
    assert_eq!(scene.surfaces.len(), 20);
    let names: Vec<&str> = scene.surfaces.iter().map(|s| s.object.as_str()).collect();
    let expected: Vec<&str> = REFERENCE_AREAS_MM2.iter().map(|(n, _)| *n).collect();
    assert_eq!(names, expected);
    for (surface, (name, area_mm2)) in scene.surfaces.iter().zip(REFERENCE_AREAS_MM2) {
        let area = area_mm2 * 1e-6;
        let rel = (surface.polygon.area() - area).abs() / area;
        assert!(
            rel < 1e-9,
            "{name}: {} vs {area} m²",
            surface.polygon.area()
        );
    }
    let total: f64 = REFERENCE_AREAS_MM2.iter().map(|(_, a)| a * 1e-6).sum();
    assert!((scene.total_area() - total).abs() / total < 1e-9);

    let light = &scene.surfaces[5];
    assert_eq!(light.group, "light");
    assert_eq!(scene.material(light).emission, [17.0, 12.0, 4.0]);
    assert_eq!(scene.material(light).reflectance, [0.78; 3]);
    let emitters: Vec<&str> = scene
        .surfaces
        .iter()
        .filter(|s| scene.material(s).is_emitter())
        .map(|s| s.object.as_str())
        .collect();
    assert_eq!(emitters, ["light"]);
    let red = &scene.surfaces[8];
    assert_eq!(red.group, "left_wall_red");
    assert_eq!(scene.material(red).reflectance, [0.63, 0.065, 0.05]);
    assert_eq!(scene.camera, Some(cornell_camera()));
}

#[test]
fn cornell_box_equals_the_obj_file_with_the_camera() {
    let mut loaded = load_obj(Path::new("scenes/cornell.obj")).unwrap();
    assert_eq!(loaded.camera, None);
    loaded.camera = Some(cornell_camera());
    assert_eq!(loaded, cornell_box());
    assert_eq!(
        loaded.surfaces[0].origin,
        Origin {
            file: Some("scenes/cornell.obj".into()),
            line: Some(11)
        }
    );
}

#[test]
fn cornell_scene_file_equals_the_builtin() {
    let loaded = load_any(Path::new("scenes/cornell.json")).unwrap();
    assert_eq!(loaded.scene, cornell_box());
    assert_eq!(loaded.settings.elements, Some(4000));
    assert_eq!(loaded.settings.width, Some(512));

    let obj = load_any(Path::new("scenes/cornell.obj")).unwrap();
    assert_eq!(obj.settings, SceneSettings::default());
    assert_eq!(obj.scene.surfaces, loaded.scene.surfaces);
}

#[test]
fn round_trip_gives_the_same_scene_and_settings() {
    let dir = tempfile::tempdir().unwrap();
    let first = load_scene_file(Path::new("scenes/cornell.json")).unwrap();
    let saved = dir.path().join("saved.json");
    save_scene_file(&saved, &first.scene, &first.settings).unwrap();
    let second = load_scene_file(&saved).unwrap();
    assert_eq!(second.settings, first.settings);
    // Origins name the file each surface was read from; everything else is identical.
    assert_eq!(
        without_origins(second.scene.clone()),
        without_origins(first.scene)
    );
    // Saving over the same file and loading again is exact, origins included.
    save_scene_file(&saved, &second.scene, &second.settings).unwrap();
    assert_eq!(load_scene_file(&saved).unwrap(), second);
    // Only the saved file is left behind (the temporary was renamed over it).
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    assert_eq!(
        serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(&saved).unwrap())
            .unwrap(),
        scene_to_json(&second.scene, &second.settings)
    );
}

#[test]
fn round_trip_keeps_awkward_numbers_and_split_faces() {
    // Inline surfaces that are split (the L shape is ear-clipped, the twisted quad cut in
    // two) come back as the same pieces, and 17-digit numbers survive.
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.json");
    std::fs::write(
        &a,
        r#"{
          "materials": [{"name": "grey", "reflectance": [0.30000000000000004, 0.1, 0.7],
                         "emission": [1e-300, 0, 3.141592653589793]}],
          "surfaces": [
            {"object": "L", "material": "grey", "vertices": [[0,0,0],[2,0,0],[2,1,0],[1,1,0],[1,2,0],[0,2,0]]},
            {"object": "twist", "group": "g", "material": "grey",
             "vertices": [[0,0,1],[1,0,1],[1,1,1.1],[0,1,1]]},
            {"object": "odd", "material": "grey",
             "vertices": [[0.1,0.2,0.30000000000000004],[1.0000000000000002,0.7,0.30000000000000004],[0.12345678901234568,0.9876543210987654,0.30000000000000004]]}
          ],
          "camera": {"eye": [0.1, 0.2, -3.0000000000000004], "target": [0, 0, 0], "fov_deg": 47.123456789012345},
          "settings": {"tolerance": 1e-3, "solver": "progressive", "ambient": true, "max_element_size": 0.05}
        }"#,
    )
    .unwrap();
    let first = load_scene_file(&a).unwrap();
    assert_eq!(first.scene.surfaces.len(), 4 + 2 + 1);
    let b = dir.path().join("b.json");
    save_scene_file(&b, &first.scene, &first.settings).unwrap();
    let second = load_scene_file(&b).unwrap();
    assert_eq!(second.settings, first.settings);
    assert_eq!(second.scene.name, "a");
    assert_eq!(without_origins(second.scene), without_origins(first.scene));
}

#[test]
fn round_trip_is_exact_for_full_precision_numbers() {
    // Scaling gives every coordinate a full 53-bit mantissa; about one in eight such numbers
    // comes back one ulp off unless serde_json has its `float_roundtrip` feature.
    const K: f64 = 1.2923838504381915;
    let mut scene = cornell_box();
    for s in &mut scene.surfaces {
        let scaled = s.polygon.vertices().iter().map(|v| *v * K).collect();
        s.polygon = Polygon::new(scaled).unwrap();
    }
    for m in &mut scene.materials {
        m.reflectance = m.reflectance.map(|r| r * 0.9353209664463897);
        m.emission = m.emission.map(|e| e * 0.46373174443479204);
    }
    let mut camera = cornell_camera();
    camera.eye *= K;
    camera.fov_deg *= K;
    scene.camera = Some(camera);
    let settings = SceneSettings {
        tolerance: Some(0.46373174443479204 * 1e-3),
        ..Default::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scaled.json");
    save_scene_file(&path, &scene, &settings).unwrap();
    let loaded = load_scene_file(&path).unwrap();
    assert_eq!(loaded.settings, settings);
    assert_eq!(without_origins(loaded.scene), without_origins(scene));
}

#[test]
fn module_doc_example_loads() {
    let example = r#"{
      "name": "cornell",
      "settings": { "elements": 4000, "width": 512, "height": 512 },
      "camera": { "eye": [0.278, 0.273, -0.8], "target": [0.278, 0.273, 0],
                  "up": [0, 1, 0], "fov_deg": 39.30764811610662 },
      "include": ["cornell.obj"],
      "materials": [
        { "name": "white", "reflectance": [0.725, 0.71, 0.68] },
        { "name": "lamp", "reflectance": [0.78, 0.78, 0.78], "emission": [17, 12, 4] }
      ],
      "surfaces": [
        { "object": "panel", "group": "lamps", "material": "lamp",
          "vertices": [[0.3, 0.5, 0.2], [0.3, 0.5, 0.3], [0.2, 0.5, 0.3], [0.2, 0.5, 0.2]] }
      ]
    }"#;
    let obj = std::fs::read_to_string("scenes/cornell.obj").unwrap();
    let mtl = std::fs::read_to_string("scenes/cornell.mtl").unwrap();
    let (_dir, path) = write_files(&[
        ("example.json", example),
        ("cornell.obj", &obj),
        ("cornell.mtl", &mtl),
    ]);
    let loaded = load_scene_file(&path).unwrap();
    let scene = &loaded.scene;
    assert_eq!(scene.surfaces.len(), 21);
    let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["white", "light", "green", "red", "lamp"]);
    let panel = scene.surfaces.last().unwrap();
    assert_eq!(
        (panel.object.as_str(), panel.group.as_str()),
        ("panel", "lamps")
    );
    assert_eq!(scene.material(panel).emission, [17.0, 12.0, 4.0]);
    assert!(panel.polygon.normal().y < -0.999);
    assert_eq!(scene.camera, Some(cornell_camera()));
    assert_eq!(loaded.settings.elements, Some(4000));
}

/// Writes `files` into a fresh temporary directory and returns it with the first file's path.
fn write_files(files: &[(&str, &str)]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    let first = dir.path().join(files[0].0);
    (dir, first)
}

/// Loads the first of `files` and checks the error: its variant and that the message contains
/// every one of `needles`.
fn expect_error(
    files: &[(&str, &str)],
    is_expected: impl Fn(&SceneError) -> bool,
    needles: &[&str],
) -> SceneError {
    expect_error_with(files, &LoadOptions::default(), is_expected, needles)
}

/// [`expect_error`] for the repairs that are errors only with `--strict`.
fn expect_strict_error(
    files: &[(&str, &str)],
    is_expected: impl Fn(&SceneError) -> bool,
    needles: &[&str],
) -> SceneError {
    let strict = LoadOptions {
        strict: true,
        ..LoadOptions::default()
    };
    expect_error_with(files, &strict, is_expected, needles)
}

/// Loads the first of `files` leniently and returns its warnings.
fn load_warnings(files: &[(&str, &str)]) -> (Scene, Vec<String>) {
    let (_dir, path) = write_files(files);
    let loaded = load_any_with(&path, &LoadOptions::default()).expect("loads leniently");
    (loaded.scene, loaded.warnings)
}

fn expect_error_with(
    files: &[(&str, &str)],
    options: &LoadOptions,
    is_expected: impl Fn(&SceneError) -> bool,
    needles: &[&str],
) -> SceneError {
    let (_dir, path) = write_files(files);
    let err = match load_any_with(&path, options) {
        Ok(_) => panic!("{} loaded; expected an error", files[0].0),
        Err(e) => e,
    };
    assert!(is_expected(&err), "unexpected variant: {err:?}");
    let message = err.to_string();
    for needle in needles {
        assert!(message.contains(needle), "{message:?} lacks {needle:?}");
    }
    err
}

const MTL: &str = "newmtl white\nKd 0.5 0.5 0.5\n\nnewmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\n";

fn obj_with(body: &str) -> String {
    format!("mtllib bad.mtl\nusemtl white\no quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n{body}")
}

#[test]
fn malformed_number() {
    let obj = obj_with("v 0 zero 0\nf 1 2 3 4\n");
    expect_error(
        &[("bad.obj", &obj), ("bad.mtl", MTL)],
        |e| matches!(e, SceneError::Syntax { .. }),
        &["bad.obj: line 8", "'zero' is not a number"],
    );
}

#[test]
fn face_index_out_of_range() {
    let obj = obj_with("f 1 2 3 5\n");
    let err = expect_error(
        &[("bad.obj", &obj), ("bad.mtl", MTL)],
        |e| {
            matches!(
                e,
                SceneError::IndexOutOfRange {
                    index: 5,
                    count: 4,
                    ..
                }
            )
        },
        &["bad.obj: line 8: face refers to vertex 5, file has 4"],
    );
    assert!(err.to_string().ends_with("file has 4"));
}

#[test]
fn nan_vertex() {
    let obj = obj_with("v nan 0 0\nf 1 2 3 4\n");
    expect_error(
        &[("bad.obj", &obj), ("bad.mtl", MTL)],
        |e| matches!(e, SceneError::NonFiniteCoordinate { .. }),
        &["bad.obj: line 8", "NaN"],
    );
}

#[test]
fn degenerate_face() {
    let obj = obj_with("v 2 0 0\nf 1 2 5\n");
    expect_error(
        &[("bad.obj", &obj), ("bad.mtl", MTL)],
        |e| {
            matches!(
                e,
                SceneError::Geometry {
                    source: GeometryError::Degenerate { .. },
                    ..
                }
            )
        },
        &["bad.obj: line 9", "object 'quad'", "degenerate"],
    );
    let obj = obj_with("f 1 2\n");
    expect_error(
        &[("bad.obj", &obj), ("bad.mtl", MTL)],
        |e| {
            matches!(
                e,
                SceneError::Geometry {
                    source: GeometryError::TooFewVertices(2),
                    ..
                }
            )
        },
        &["bad.obj: line 8", "object 'quad'"],
    );
}

#[test]
fn absurd_coordinates() {
    let obj = obj_with("v 1e7 0 0\nf 1 2 5\n");
    expect_error(
        &[("bad.obj", &obj), ("bad.mtl", MTL)],
        |e| {
            matches!(
                e,
                SceneError::Geometry {
                    source: GeometryError::OutOfRange { .. },
                    ..
                }
            )
        },
        &["bad.obj: line 9", "object 'quad'", "out of range"],
    );
}

#[test]
fn non_planar_pentagon() {
    let obj = obj_with("v 0.5 0.5 1\nf 1 2 3 5 4\n");
    expect_error(
        &[("bad.obj", &obj), ("bad.mtl", MTL)],
        |e| {
            matches!(
                e,
                SceneError::Geometry {
                    source: GeometryError::NonPlanar { .. },
                    ..
                }
            )
        },
        &["bad.obj: line 9", "object 'quad'", "not planar"],
    );
}

#[test]
fn missing_mtllib() {
    let obj = obj_with("f 1 2 3 4\n");
    expect_error(
        &[("bad.obj", &obj)],
        |e| matches!(e, SceneError::MissingMaterialLibrary { .. }),
        &["bad.obj: line 1", "bad.mtl"],
    );
}

#[test]
fn unknown_usemtl() {
    let obj = obj_with("usemtl whit\nf 1 2 3 4\n");
    expect_error(
        &[("bad.obj", &obj), ("bad.mtl", MTL)],
        |e| matches!(e, SceneError::UnknownMaterial { .. }),
        &["bad.obj: line 8", "object 'quad'", "'whit'"],
    );
}

#[test]
fn face_without_material() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\ng walls\nf 1 2 3\n";
    expect_strict_error(
        &[("bad.obj", obj)],
        |e| matches!(e, SceneError::NoMaterial { .. }),
        &["bad.obj: line 5", "object 'walls'", "no material"],
    );
    // Leniently: the documented default grey, with a warning naming the line and object.
    let (scene, warnings) = load_warnings(&[("bad.obj", obj)]);
    assert_eq!(scene.material(&scene.surfaces[0]).reflectance, DEFAULT_GREY);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("line 5 'walls'"), "{warnings:?}");
}

#[test]
fn reflectance_of_one_or_more() {
    let obj = obj_with("f 1 2 3 4\n");
    let mtl = "newmtl white\nKd 0.5 0.5 0.5\n\nnewmtl mirror\nKd 0.5 1.2 0.5\n";
    let err = expect_strict_error(
        &[("bad.obj", &obj), ("bad.mtl", mtl)],
        |e| matches!(e, SceneError::Material { .. }),
        &[
            "bad.mtl: line 4",
            "material 'mirror'",
            "reflectance 1.2 (green) must be < 1",
        ],
    );
    assert!(err.to_string().contains(std::path::MAIN_SEPARATOR));
    let mtl = "newmtl white\nKd 1 1 1\n";
    expect_strict_error(
        &[("bad.obj", &obj), ("bad.mtl", mtl)],
        |e| matches!(e, SceneError::Material { .. }),
        &["bad.mtl: line 1", "material 'white'", "must be < 1"],
    );
    // Leniently: clamped to the documented maximum, with one warning naming the material.
    let (scene, warnings) = load_warnings(&[("bad.obj", &obj), ("bad.mtl", mtl)]);
    assert_eq!(scene.materials[0].reflectance, [MAX_REFLECTANCE; 3]);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("'white'"), "{warnings:?}");
}

#[test]
fn negative_emission() {
    let obj = obj_with("f 1 2 3 4\n");
    let mtl = "newmtl white\nKd 0.5 0.5 0.5\nKe 1 -2 1\n";
    expect_error(
        &[("bad.obj", &obj), ("bad.mtl", mtl)],
        |e| matches!(e, SceneError::Material { .. }),
        &[
            "bad.mtl: line 1",
            "material 'white'",
            "emission -2 (green) must be ≥ 0",
        ],
    );
}

#[test]
fn malformed_mtl_line() {
    let obj = obj_with("f 1 2 3 4\n");
    let mtl = "newmtl white\nKd 0.5 0.5\n";
    expect_error(
        &[("bad.obj", &obj), ("bad.mtl", mtl)],
        |e| matches!(e, SceneError::Syntax { .. }),
        &["bad.mtl: line 2", "'Kd' needs three numbers"],
    );
}

#[test]
fn unknown_json_field() {
    let json = "{\n  \"name\": \"x\",\n  \"camra\": {}\n}\n";
    expect_error(
        &[("bad.json", json)],
        |e| matches!(e, SceneError::Json { line: 3, .. }),
        &["bad.json: line 3, column", "unknown field `camra`"],
    );
    let json = "{\n  \"settings\": {\"elemnts\": 10}\n}\n";
    expect_error(
        &[("bad.json", json)],
        |e| matches!(e, SceneError::Json { line: 2, .. }),
        &["bad.json: line 2", "unknown field `elemnts`"],
    );
}

#[test]
fn json_syntax_error() {
    let json = "{\n  \"name\": \"x\",\n  \"materials\": [\n    {\"name\": \"w\" \"reflectance\": [0.5, 0.5, 0.5]}\n  ]\n}\n";
    let err = expect_error(
        &[("bad.json", json)],
        |e| matches!(e, SceneError::Json { line: 4, .. }),
        &["bad.json: line 4, column"],
    );
    assert!(!err.to_string().contains(" at line "), "{err}");
}

#[test]
fn json_semantic_errors() {
    let surface =
        r#"{"object": "floor", "material": "wite", "vertices": [[0,0,0],[1,0,0],[1,1,0]]}"#;
    let json = format!(
        r#"{{"materials": [{{"name": "white", "reflectance": [0.5, 0.5, 0.5]}}], "surfaces": [{surface}]}}"#
    );
    expect_error(
        &[("bad.json", &json)],
        |e| matches!(e, SceneError::UnknownMaterial { .. }),
        &["bad.json", "object 'floor'", "'wite'"],
    );
    let json = r#"{"materials": [{"name": "white", "reflectance": [0.5, 1.5, 0.5]}]}"#;
    expect_error(
        &[("bad.json", json)],
        |e| matches!(e, SceneError::Material { .. }),
        &["bad.json", "material 'white'", "must be < 1"],
    );
    let json = r#"{"include": ["missing.obj"]}"#;
    expect_error(
        &[("bad.json", json)],
        // The error in the included file, wrapped so that the message names both files.
        |e| matches!(e, SceneError::Included { source, .. } if matches!(**source, SceneError::Read { .. })),
        &["bad.json", "missing.obj"],
    );
    let json = r#"{"include": ["box.obj"], "materials": [{"name": "white", "reflectance": [0.1, 0.1, 0.1]}]}"#;
    let obj = "mtllib bad.mtl\nusemtl white\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n";
    expect_error(
        &[("bad.json", json), ("box.obj", obj), ("bad.mtl", MTL)],
        |e| matches!(e, SceneError::Material { .. }),
        &[
            "bad.json",
            "material 'white'",
            "defined differently in",
            "box.obj",
        ],
    );
}

#[test]
fn unknown_extension() {
    expect_error(
        &[("scene.ply", "ply\n")],
        |e| matches!(e, SceneError::UnknownFormat { .. }),
        &["scene.ply", "unknown scene format"],
    );
}

#[test]
fn unreadable_file() {
    let err = load_any(Path::new("scenes/does_not_exist.obj")).unwrap_err();
    assert!(matches!(err, SceneError::Read { .. }), "{err:?}");
    assert!(err.to_string().contains("scenes/does_not_exist.obj"));
}

#[test]
fn empty_scene() {
    expect_error(
        &[("empty.obj", "# nothing\nv 0 0 0\n")],
        |e| matches!(e, SceneError::Empty { .. }),
        &["empty.obj", "no surfaces"],
    );
    expect_error(
        &[("empty.json", "{}")],
        |e| matches!(e, SceneError::Empty { .. }),
        &["empty.json", "no surfaces"],
    );
}

#[test]
fn save_into_missing_directory_is_a_write_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no/such/dir/scene.json");
    let err = save_scene_file(&path, &cornell_box(), &SceneSettings::default()).unwrap_err();
    assert!(matches!(err, SceneError::Write { .. }), "{err:?}");
    assert!(err.to_string().contains("scene.json"));
}

/// Mangles every line of the Cornell OBJ and MTL in several ways; each result must load or
/// fail with an error, never panic.
#[test]
fn mangled_cornell_files_never_panic() {
    let obj = std::fs::read_to_string("scenes/cornell.obj").unwrap();
    let mtl = std::fs::read_to_string("scenes/cornell.mtl").unwrap();
    let mangles: [fn(&str) -> String; 10] = [
        |_| String::new(),
        |l| l.replace(' ', "/"),
        |l| l.replace('1', "-1"),
        |l| l.replace('0', "0/0/0/0"),
        |l| l.replace('.', ""),
        |l| format!("{l} 7"),
        |l| l.split(' ').next().unwrap_or_default().to_owned(),
        |l| l.replace('5', "nan"),
        |l| l.replace('2', "99999999999999999999"),
        |l| l.replace(' ', "\u{a0}"),
    ];
    let lines = |text: &str| text.lines().map(str::to_owned).collect::<Vec<_>>();
    let (obj_lines, mtl_lines) = (lines(&obj), lines(&mtl));
    let mut outcomes = [0usize; 2];
    for (which, original) in [&obj_lines, &mtl_lines].into_iter().enumerate() {
        for i in 0..original.len() {
            for mangle in mangles {
                let mut changed = original.clone();
                changed[i] = mangle(&changed[i]);
                let changed = changed.join("\n");
                let (obj_text, mtl_text) = if which == 0 {
                    (changed.as_str(), mtl.as_str())
                } else {
                    (obj.as_str(), changed.as_str())
                };
                let result = parse_obj(obj_text, "m.obj", |_| Ok(mtl_text.to_owned()));
                outcomes[usize::from(result.is_err())] += 1;
            }
        }
    }
    assert!(outcomes[0] > 0 && outcomes[1] > 0, "{outcomes:?}");
}

/// Random OBJ-like text: mostly plausible vertices and faces, with junk statements mixed in.
/// Every result must load or fail with an error, never panic; in debug builds this also checks
/// that the validating scan and tobj agree on every face.
#[test]
fn random_obj_text_never_panics() {
    const KEYWORDS: [&str; 10] = ["v", "f", "l", "vt", "vn", "o", "g", "usemtl", "#", "s"];
    const TOKENS: [&str; 20] = [
        "1", "2", "3", "-1", "-2", "0", "0.5", "1/1", "1//1", "2/1/1", "-1/-1/-1", "/", "1/2/3/4",
        "nan", "1e400", "x", "white", "lamp", "", "99",
    ];
    const COORDINATES: [&str; 6] = ["0", "1", "0.5", "2", "-1", "1e-9"];
    const INDICES: [&str; 8] = ["1", "2", "3", "4", "-1", "-2", "-3", "-4"];
    let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    let mut loaded = 0;
    for _ in 0..3000 {
        let mut text = String::from("mtllib m.mtl\nusemtl white\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
        for _ in 0..next(12) {
            let (keyword, count, pool): (&str, usize, &[&str]) = match next(20) {
                0..=8 => ("v", 3, &COORDINATES),
                9..=17 => ("f", 3 + next(3), &INDICES),
                _ => (KEYWORDS[next(KEYWORDS.len())], next(6), &TOKENS),
            };
            text.push_str(keyword);
            for _ in 0..count {
                text.push(' ');
                text.push_str(pool[next(pool.len())]);
            }
            text.push('\n');
        }
        if parse_obj(&text, "r.obj", |_| Ok(MTL.to_owned())).is_ok() {
            loaded += 1;
        }
    }
    assert!(loaded > 150, "only {loaded} of 3000 loaded");
}
