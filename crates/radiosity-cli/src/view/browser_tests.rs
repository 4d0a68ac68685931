//! The page in a real browser (headless Chromium with SwiftShader WebGL): it renders the
//! synthetic box at the scene camera with exactly the renderer's colours, updates live, and
//! reports `converged`.
//!
//! Skipped (with a note on stderr) when no Chromium is installed, unless
//! `RADIOSITY_REQUIRE_BROWSER=1`, which turns a missing browser into a failure (set it in
//! CI, which installs Debian's `chromium`). `VIEW_SCREENSHOT_DIR=dir` keeps the screenshots.

#[path = "../../tests/support/headless.rs"]
mod headless;

use super::test_scene::{self, box_mesh, uniform_frame, CAMERA};
use super::*;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

fn chromium() -> Option<PathBuf> {
    headless::chromium_or_skip(module_path!())
}

fn screenshot_path(name: &str) -> (PathBuf, Option<tempfile::TempDir>) {
    match std::env::var_os("VIEW_SCREENSHOT_DIR") {
        Some(dir) => (PathBuf::from(dir).join(name), None),
        None => {
            let dir = tempfile::tempdir().unwrap();
            (dir.path().join(name), Some(dir))
        }
    }
}

/// The renderer's pixel for linear value v: clamp to [0, 1], sRGB transfer curve
/// (IEC 61966-2-1), round (as `radiosity::render::srgb_byte`).
fn srgb_byte(v: f32) -> u8 {
    let v = f64::from(v.clamp(0.0, 1.0));
    let e = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (e * 255.0).round() as u8
}

/// The pixel (column, row) that world point p falls in, with the renderer's camera
/// convention: right = normalize(look × up), true up = right × look,
/// s = 2(i + ½)/W − 1, u = 1 − 2(j + ½)/H, tan(fov/2) scaling the vertical axis.
fn pixel_of(p: [f32; 3], width: u32, height: u32) -> (u32, u32) {
    let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: [f32; 3], b: [f32; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let unit = |a: [f32; 3]| {
        let l = dot(a, a).sqrt();
        [a[0] / l, a[1] / l, a[2] / l]
    };
    let look = unit(sub(CAMERA.target, CAMERA.eye));
    let right = unit(cross(look, CAMERA.up));
    let up = cross(right, look);
    let d = sub(p, CAMERA.eye);
    let t = (CAMERA.fov_deg.to_radians() / 2.0).tan();
    let aspect = width as f32 / height as f32;
    let s = dot(d, right) / dot(d, look) / (t * aspect);
    let u = dot(d, up) / dot(d, look) / t;
    let i = (s + 1.0) / 2.0 * width as f32 - 0.5;
    let j = (1.0 - u) / 2.0 * height as f32 - 0.5;
    (i.round() as u32, j.round() as u32)
}

/// Object indices in `test_scene`.
const BACK: usize = 0;
const FLOOR: usize = 1;
const LEFT: usize = 3;
const PANEL_ONE_SIDED: usize = 6;
const PANEL_TWO_SIDED: usize = 7;

#[test]
fn page_draws_the_renderers_colours_at_the_scene_camera() {
    let Some(chromium) = chromium() else { return };
    let mut radiance = [[0.0f32; 3]; 8];
    radiance[BACK] = [0.09, 0.25, 0.02];
    // Above 1 after exposure (clamps to 255), inside the linear segment, and mid-range.
    radiance[FLOOR] = [0.6, 0.0005, 0.3];
    radiance[2] = [0.2, 0.2, 0.2];
    radiance[LEFT] = [0.05, 0.2, 0.03];
    radiance[4] = [0.3, 0.03, 0.02];
    radiance[5] = [5.0, 5.0, 5.0];
    radiance[PANEL_ONE_SIDED] = [0.4, 0.4, 0.4];
    radiance[PANEL_TWO_SIDED] = [0.35, 0.2, 0.05];
    let state = Arc::new(ViewState::new());
    let mesh = box_mesh(4, 1);
    let frame = uniform_frame(&mesh, 7, &radiance, &[[1.0, 2.0, 3.0]; 8]);
    state.set_mesh(mesh).unwrap();
    state.set_frame(frame).unwrap();
    state.finish(Outcome::Converged);
    let server = Server::bind(state, ServerConfig::default())
        .unwrap()
        .spawn()
        .unwrap();
    let (width, height) = (320, 240);
    let options = headless::Options {
        width,
        height,
        budget: Duration::from_secs(60),
        chromium: Some(chromium),
    };
    let exposure = 1.0f32;
    // Probe points well inside each surface (the panels span 0.2 m, about 30 pixels).
    let probes = [
        (BACK, test_scene::point_on(BACK, 0.75, 0.5)),
        (FLOOR, test_scene::point_on(FLOOR, 0.7, 0.5)),
        (LEFT, test_scene::point_on(LEFT, 0.8, 0.6)),
        (
            PANEL_ONE_SIDED,
            test_scene::point_on(PANEL_ONE_SIDED, 0.5, 0.5),
        ),
        (
            PANEL_TWO_SIDED,
            test_scene::point_on(PANEL_TWO_SIDED, 0.5, 0.5),
        ),
    ];
    for mode in ["gouraud", "flat"] {
        let (png, _keep) = screenshot_path(&format!("exact-{mode}.png"));
        let url = format!("{}?ui=0&mode={mode}&exposure={exposure}", server.url());
        let capture = headless::capture(&url, &png, &options).unwrap();
        assert_eq!(capture.status, "converged");
        assert_eq!(capture.status_text, "converged");
        assert_eq!(capture.frame, Some(7));
        assert!(capture.errors.is_empty(), "{:?}", capture.errors);
        let image = image::load_from_memory(&capture.png).unwrap().to_rgb8();
        assert_eq!(image.dimensions(), (width, height));
        let mut off_by_one = 0;
        for (object, point) in probes {
            let (i, j) = pixel_of(point, width, height);
            // Seen from behind and one-sided: black. Otherwise the renderer's formula.
            let expected = if object == PANEL_ONE_SIDED {
                [0, 0, 0]
            } else {
                radiance[object].map(|l| srgb_byte(l * exposure.exp2()))
            };
            // A 3 × 3 block around the probe: every pixel must match. One code of
            // tolerance: the GPU evaluates the curve in 32-bit floats with its own pow()
            // and rounds to 8 bits itself, which can land on the other side of a .5.
            for dj in -1i32..=1 {
                for di in -1i32..=1 {
                    let (x, y) = ((i as i32 + di) as u32, (j as i32 + dj) as u32);
                    let got = image.get_pixel(x, y).0;
                    let close = got.iter().zip(expected).all(|(&g, e)| g.abs_diff(e) <= 1);
                    assert!(
                        close,
                        "{mode}: object {object} at ({x}, {y}): got {got:?}, want {expected:?}"
                    );
                    off_by_one += got.iter().zip(expected).filter(|(&g, e)| g != *e).count();
                }
            }
        }
        eprintln!(
            "{mode}: {off_by_one} of {} probed channels one code off",
            probes.len() * 27
        );
    }
    server.stop().unwrap();
}

#[test]
fn page_follows_a_live_solve_and_reports_converged() {
    let Some(chromium) = chromium() else { return };
    let state = Arc::new(ViewState::new());
    let server = Server::bind(state.clone(), ServerConfig::default())
        .unwrap()
        .spawn()
        .unwrap();
    let url = format!("{}?ui=1", server.url());
    // The solver: a coarse mesh, frames, then a refined mesh (version 2) and more frames.
    let solver = {
        let state = state.clone();
        std::thread::spawn(move || {
            state.set_progress(ViewProgress::stage("meshing"));
            let mut mesh = box_mesh(3, 1);
            state.set_mesh(mesh.clone()).unwrap();
            for frame in 1..=30u64 {
                if frame == 15 {
                    mesh = box_mesh(6, 2);
                    state.set_mesh(mesh.clone()).unwrap();
                }
                let t = frame as f32 / 30.0;
                state
                    .set_frame(test_scene::demo_frame(&mesh, frame, t))
                    .unwrap();
                state.set_progress(ViewProgress {
                    steps: frame * 10,
                    step_word: "shot".into(),
                    quantity: "unshot fraction".into(),
                    value: Some(f64::from(1.0 - t) * 0.1),
                    tolerance: Some(1e-3),
                    elapsed_s: frame as f64 * 0.1,
                    eta_s: Some((30 - frame) as f64 * 0.1),
                    ..ViewProgress::stage("solving")
                });
                std::thread::sleep(Duration::from_millis(100));
            }
            state.finish(Outcome::Converged);
        })
    };
    let options = headless::Options {
        width: 640,
        height: 480,
        budget: Duration::from_secs(60),
        chromium: Some(chromium),
    };
    let mut browser = headless::Browser::launch(&options).unwrap();
    browser.navigate(&url).unwrap();
    let (status, text, frame) = browser.wait_settled(options.budget).unwrap();
    solver.join().unwrap();
    assert_eq!(
        (status.as_str(), text.as_str(), frame),
        ("converged", "converged", Some(30))
    );
    assert_eq!(
        browser
            .evaluate("document.body.dataset.meshVersion")
            .unwrap(),
        "2"
    );
    assert_eq!(
        browser
            .evaluate("document.getElementById('steps').textContent")
            .unwrap(),
        "300 shots"
    );
    // Clicking the two-sided panel (seen from behind) names it.
    let (x, y) = pixel_of(test_scene::point_on(PANEL_TWO_SIDED, 0.5, 0.5), 640, 480);
    browser
        .click(f64::from(x) + 0.5, f64::from(y) + 0.5)
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let title = browser
        .evaluate("document.getElementById('pick-title').textContent")
        .unwrap();
    assert_eq!(title, "panel two-sided");
    let picked = browser
        .evaluate("document.getElementById('pick-table').textContent")
        .unwrap();
    assert!(
        picked.as_str().unwrap().contains("seen from behind"),
        "{picked}"
    );
    let (png, _keep) = screenshot_path("live-converged.png");
    std::fs::write(&png, browser.screenshot().unwrap()).unwrap();
    let errors = browser.errors();
    assert!(errors.is_empty(), "{errors:?}");
    browser.close();
    server.stop().unwrap();
}
