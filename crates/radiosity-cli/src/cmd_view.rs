//! `radiosity view`: solve a scene while a browser watches, or show a saved solution.
//!
//! The order of things: everything that can be wrong with the input (the scene, the
//! settings, the solution file) is checked first, so bad input ends with status 1 before a
//! server exists; then the server binds 127.0.0.1 and its URL is printed on stdout (the only
//! line there); then the solver runs on a thread of its own, publishing to the viewer's
//! state ([`crate::view::ViewState`]) as it goes:
//!
//! - the stage and its steps (meshing, form-factor rows, shots or iterations with the
//!   unshot fraction or residual, against the tolerance, with an ETA), at most every
//!   [`PROGRESS_INTERVAL`];
//! - the mesh, again whenever refinement changes it;
//! - a frame of the current radiosity at most every [`FRAME_INTERVAL`] (the first at once),
//!   and the final solution's frame when the solver returns;
//! - how it ended: converged, stopped at the step limit, or failed.
//!
//! The server keeps serving after the solve until Ctrl-C (or SIGTERM), which stops it and,
//! if the solve is still running, the solve too; the command then exits with status 0. A
//! solve that fails shows the error on the page and on stderr, and the command exits 1.

use crate::args::SolveArgs;
use crate::commands::{load_scene, Loaded};
use crate::progress::Bars;
use crate::view::build::{Geometry, Irradiance, Publisher};
use crate::view::{self, Outcome, Server, ServerConfig, ShutdownHandle, ViewProgress, ViewState};
use anyhow::{Context, Result};
use clap::Args;
use radiosity::io::solution_file::SolutionFile;
use radiosity::mesh::Mesh;
use radiosity::pipeline::{
    solve_mesh, solve_scene_adaptive_observed, solve_scene_observed, Solved,
};
use radiosity::progress::{ConvergenceEta, Progress};
use radiosity::scene::Camera;
use radiosity::settings::{CameraOverrides, Settings};
use radiosity::solve::{display_radiosity, Flow, Observer, SolverKind, Step, StepKind};
use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

/// Shortest time between two frames sent to the viewer: a few updates a second, so that
/// building frames costs the solver little and the page can keep up.
pub const FRAME_INTERVAL: Duration = Duration::from_millis(250);

/// Shortest time between two progress updates (the event stream coalesces them further).
pub const PROGRESS_INTERVAL: Duration = Duration::from_millis(100);

/// How long a failed solve keeps serving, so that open pages receive the error before the
/// server closes (the event stream sends at most one notice per 250 ms).
const LINGER_AFTER_FAILURE: Duration = Duration::from_millis(600);

/// `radiosity view`.
#[derive(Debug, Args)]
pub struct ViewCmdArgs {
    /// Scene file (.obj or .json); the built-in Cornell box if omitted.
    pub scene: Option<PathBuf>,
    /// Show a saved solution (from `solve --save`) instead of solving a scene.
    #[arg(long, value_name = "FILE", conflicts_with = "scene")]
    pub solution: Option<PathBuf>,
    /// Port on 127.0.0.1 to serve on; 0 picks a free port. The URL is printed on stdout.
    #[arg(long, value_name = "P", default_value_t = 0)]
    pub port: u16,
    /// Open the page in the desktop's web browser.
    #[arg(long)]
    pub open: bool,
    /// Start solving only once a page has connected, so that it shows the whole
    /// progressive sequence from the first shot (e.g. with --open).
    #[arg(long)]
    pub wait: bool,
    /// Show the ambient term of progressive refinement in the displayed radiosity (right
    /// overall brightness from the first shots).
    #[arg(long)]
    pub ambient: bool,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// What to show, checked before the server starts.
enum Job {
    Saved {
        file: Box<SolutionFile>,
        path: PathBuf,
    },
    Solve(Box<(Loaded, Settings)>),
}

/// Runs `radiosity view`.
pub fn run(args: ViewCmdArgs) -> Result<()> {
    let quiet = args.solve.quiet;
    let job = match &args.solution {
        Some(path) => {
            let file = SolutionFile::load(path)
                .with_context(|| format!("loading solution {}", path.display()))?;
            Job::Saved {
                file: Box::new(file),
                path: path.clone(),
            }
        }
        None => {
            let loaded = load_scene(args.scene.as_deref(), &args.solve)?;
            let settings = loaded.settings(&args.solve.overrides())?;
            Job::Solve(Box::new((loaded, settings)))
        }
    };
    let camera = match &job {
        Job::Saved { file, .. } => {
            let base = file.camera.map(Camera::from).unwrap_or_default();
            radiosity::settings::camera(base, None, &CameraOverrides::default())
                .context("the saved solution's camera")?
        }
        Job::Solve(solve) => {
            let loaded = &solve.0;
            let (lo, hi) = loaded.scene.bounds();
            radiosity::settings::camera(
                loaded.scene.camera_or_default(),
                Some((lo + hi) * 0.5),
                &CameraOverrides::default(),
            )?
        }
    };

    let state = Arc::new(ViewState::new());
    let server = Server::bind(
        state.clone(),
        ServerConfig {
            port: args.port,
            ..ServerConfig::default()
        },
    )?;
    let url = server.url();
    crate::write_stdout(&format!("{url}\n"))?;
    let running = server.spawn()?;
    let stop = running.shutdown_handle();
    view::shutdown_on_signal(stop.clone())?;
    if !quiet {
        stderr_line!("viewer at {url} (Ctrl-C stops it)");
    }
    if args.open {
        if let Err(e) = view::open_in_browser(&url) {
            stderr_line!("warning: {e}");
        }
    }

    let failure: Arc<Mutex<Option<anyhow::Error>>> = Arc::default();
    match job {
        Job::Saved { file, path } => {
            if let Err(e) = show_saved(&state, &file, &path, camera, args.ambient) {
                state.finish(Outcome::Failed(format!("{e:#}")));
                stop.shutdown();
                let _ = running.join();
                return Err(e);
            }
            if !quiet {
                stderr_line!(
                    "showing the saved solution {} ({} elements)",
                    path.display(),
                    file.elements.len()
                );
            }
        }
        Job::Solve(solve) => {
            let (loaded, settings) = *solve;
            let live = Live {
                state: state.clone(),
                stop: stop.clone(),
                camera,
                wait: args.wait,
                ambient: args.ambient || settings.render.ambient,
                quiet,
            };
            let failure = failure.clone();
            std::thread::Builder::new()
                .name("view-solver".to_owned())
                .spawn(move || {
                    if let Err(e) = live.solve(&loaded, &settings) {
                        live.state.finish(Outcome::Failed(format!("{e:#}")));
                        *failure.lock().unwrap_or_else(PoisonError::into_inner) = Some(e);
                        std::thread::sleep(LINGER_AFTER_FAILURE);
                        live.stop.shutdown();
                    }
                })
                .context("starting the solver thread")?;
        }
    }
    // Serve until Ctrl-C (or a failed solve). A solve still running then is abandoned:
    // returning from `main` ends its thread.
    running.join()?;
    let failed = failure
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .take();
    match failed {
        Some(e) => Err(e),
        None => {
            if !quiet {
                stderr_line!("viewer stopped");
            }
            Ok(())
        }
    }
}

/// Publishes a saved solution: its mesh, one frame, and the status `loaded`.
fn show_saved(
    state: &Arc<ViewState>,
    file: &SolutionFile,
    path: &std::path::Path,
    camera: Camera,
    ambient: bool,
) -> Result<()> {
    let vertices = file.vertices();
    let geometry = Geometry {
        vertices: &vertices,
        elements: &file.elements,
        surfaces: &file.surfaces,
        objects: &file.objects,
    };
    let mut publisher = Publisher::new(state.clone(), camera);
    publisher
        .publish(
            &geometry,
            &file.display_radiosity(ambient),
            Irradiance::Known(&file.irradiance),
        )
        .with_context(|| format!("showing {}", path.display()))?;
    state.finish(Outcome::Loaded(format!(
        "saved solution {}",
        path.display()
    )));
    Ok(())
}

/// A solve that publishes to the viewer.
struct Live {
    state: Arc<ViewState>,
    stop: ShutdownHandle,
    camera: Camera,
    wait: bool,
    ambient: bool,
    quiet: bool,
}

impl Live {
    /// Meshes and solves the scene as `radiosity solve` does, publishing as it goes, and
    /// ends with the final frame and the outcome. Returns early (Ok) on Ctrl-C.
    fn solve(&self, loaded: &Loaded, settings: &Settings) -> Result<()> {
        let scene = &loaded.scene;
        let bars = Bars::new(self.quiet);
        let started = Instant::now();
        let stages = Stages {
            state: &self.state,
            bars: &bars,
            started,
            current: Mutex::new(None),
        };
        let mut publisher = Publisher::new(self.state.clone(), self.camera);
        let solve = &settings.solve;
        let plain = settings.refine.is_none() && solve.solve.solver != SolverKind::Hierarchical;
        // The plain pipeline is run stage by stage here, so that the page shows the meshed
        // scene (its emitters) before the form factors; refinement and the hierarchical
        // solver mesh inside the library and are shown from their first step.
        let mesh = if plain {
            stages.begin("meshing", None, "");
            let mesh = Mesh::build(scene, &solve.mesh).context("meshing")?;
            let exitance = radiosity::solve::exitance(&mesh);
            publisher.publish(
                &Geometry::of_mesh(&mesh),
                &exitance,
                Irradiance::FromRadiosity(&exitance),
            )?;
            Some(mesh)
        } else {
            None
        };
        if self.wait {
            self.state
                .set_progress(ViewProgress::stage("waiting for a page to connect"));
            if !self.state.wait_for_viewer(&|| self.stop.is_shutdown()) {
                return Ok(());
            }
        }
        let mut watcher = Watcher {
            live: self,
            stages: &stages,
            publisher: &mut publisher,
            eta: ConvergenceEta::new(1.0),
            last_progress: None,
            passes: 0,
            adaptive: settings.refine.is_some(),
            error: None,
        };
        let result = match (mesh, &settings.refine) {
            (Some(mesh), _) => {
                solve_mesh(&mesh, solve, &stages, &mut watcher).map(|solution| Solved {
                    mesh,
                    solution,
                    form_factor: solve.form_factor,
                    hierarchy: None,
                })
            }
            (None, Some(refine)) => {
                solve_scene_adaptive_observed(scene, solve, refine, &stages, &mut watcher)
            }
            (None, None) => solve_scene_observed(scene, solve, &stages, &mut watcher),
        };
        let publish_error = watcher.error.take();
        drop(bars);
        if self.stop.is_shutdown() {
            return Ok(());
        }
        let solved = result?;
        if let Some(e) = publish_error {
            return Err(e.into());
        }
        let st = &solved.solution.stats;
        let displayed = solved
            .solution
            .display_radiosity(&solved.mesh, self.ambient);
        publisher.publish(
            &Geometry::of_mesh(&solved.mesh),
            &displayed,
            Irradiance::Known(&solved.solution.irradiance),
        )?;
        let (word, quantity) = step_names(st.solver == SolverKind::Progressive);
        let steps = format!("{word}s");
        let converged = st.residual <= solve.solve.tolerance;
        let summary = format!(
            "{} {steps}, {quantity} {:.2e} (tolerance {:.0e})",
            st.iterations, st.residual, solve.solve.tolerance
        );
        self.state.set_progress(ViewProgress {
            steps: st.iterations as u64,
            step_word: word.to_owned(),
            quantity: quantity.to_owned(),
            value: Some(st.residual),
            tolerance: Some(solve.solve.tolerance),
            elapsed_s: started.elapsed().as_secs_f64(),
            ..ViewProgress::stage(&format!("{} solve", st.solver))
        });
        self.state.finish(if converged {
            Outcome::Converged
        } else {
            Outcome::Stopped(format!("stopped before converging: {summary}"))
        });
        if !self.quiet {
            stderr_line!(
                "solved '{}': {} elements, {} solver: {summary}, {} in {:.2} s; {} frames shown",
                scene.name,
                solved.mesh.len(),
                st.solver,
                if converged {
                    "converged"
                } else {
                    "not converged"
                },
                started.elapsed().as_secs_f64(),
                publisher.frames()
            );
        }
        Ok(())
    }
}

/// What a solver's step is called and what converges: shots and the unshot fraction of the
/// emitted power (progressive refinement), or iterations and the relative residual.
fn step_names(shooting: bool) -> (&'static str, &'static str) {
    if shooting {
        ("shot", "unshot fraction")
    } else {
        ("iteration", "relative residual")
    }
}

/// The stage being reported through the library's [`Progress`] (meshing, form factors).
struct Stage {
    name: String,
    total: Option<u64>,
    step_word: String,
    done: u64,
    started: Instant,
    last_sent: Option<Instant>,
}

/// Stages, to the terminal's bars and to the viewer.
struct Stages<'a> {
    state: &'a ViewState,
    bars: &'a Bars,
    started: Instant,
    current: Mutex<Option<Stage>>,
}

impl Stages<'_> {
    fn begin(&self, name: &str, total: Option<u64>, step_word: &str) {
        let stage = Stage {
            name: name.to_owned(),
            total,
            step_word: step_word.to_owned(),
            done: 0,
            started: Instant::now(),
            last_sent: None,
        };
        self.send(&stage);
        *self.current.lock().unwrap_or_else(PoisonError::into_inner) = Some(stage);
    }

    fn send(&self, s: &Stage) {
        // Linear extrapolation of the stage's own rate.
        let elapsed = s.started.elapsed().as_secs_f64();
        let eta_s = match s.total {
            Some(total) if s.done > 0 => {
                Some(elapsed * (total.saturating_sub(s.done)) as f64 / s.done as f64)
            }
            _ => None,
        };
        self.state.set_progress(ViewProgress {
            steps: s.done,
            total_steps: s.total,
            step_word: s.step_word.clone(),
            elapsed_s: self.started.elapsed().as_secs_f64(),
            eta_s,
            ..ViewProgress::stage(&s.name)
        });
    }
}

impl Progress for Stages<'_> {
    fn start(&self, stage: &str, total: u64) {
        self.bars.start(stage, total);
        let word = if stage == "form factors" {
            "row"
        } else {
            "step"
        };
        self.begin(stage, Some(total), word);
    }

    fn inc(&self, n: u64) {
        self.bars.inc(n);
        let mut current = self.current.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(s) = current.as_mut() {
            s.done += n;
            if s.last_sent.is_none_or(|t| t.elapsed() >= PROGRESS_INTERVAL) {
                s.last_sent = Some(Instant::now());
                self.send(s);
            }
        }
    }

    fn message(&self, text: &str) {
        self.bars.message(text);
    }

    fn finish(&self) {
        self.bars.finish();
        let mut current = self.current.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(mut s) = current.take() {
            s.done = s.total.unwrap_or(s.done);
            self.send(&s);
        }
    }
}

/// Watches the solver: progress, frames, and Ctrl-C.
struct Watcher<'a> {
    live: &'a Live,
    stages: &'a Stages<'a>,
    publisher: &'a mut Publisher,
    eta: ConvergenceEta,
    last_progress: Option<Instant>,
    /// Solves started (adaptive refinement solves once per pass).
    passes: usize,
    adaptive: bool,
    /// The first frame that could not be published (e.g. a non-finite value); the solve
    /// is stopped and the error reported.
    error: Option<view::ViewError>,
}

impl Observer for Watcher<'_> {
    fn step(&mut self, step: &Step<'_>) -> Flow {
        let mut bars = self.stages.bars;
        bars.step(step);
        if step.kind == StepKind::Start {
            self.passes += 1;
            self.eta = ConvergenceEta::new(step.tolerance);
        }
        self.eta.retarget(step.tolerance);
        self.eta.update(step.elapsed, step.residual);
        let start = step.kind == StepKind::Start;
        if start
            || self
                .last_progress
                .is_none_or(|t| t.elapsed() >= PROGRESS_INTERVAL)
        {
            self.last_progress = Some(Instant::now());
            let (word, quantity) =
                step_names(step.kind == StepKind::Shot || step.solver == SolverKind::Progressive);
            let mut stage = format!("{} solve", step.solver);
            if self.adaptive {
                stage = format!("{stage}, refinement pass {}", self.passes);
            }
            self.live.state.set_progress(ViewProgress {
                steps: step.index as u64,
                step_word: word.to_owned(),
                quantity: quantity.to_owned(),
                value: Some(step.residual),
                tolerance: Some(step.tolerance),
                elapsed_s: self.stages.started.elapsed().as_secs_f64(),
                eta_s: self.eta.eta(),
                ..ViewProgress::stage(&stage)
            });
        }
        if start || self.live.state.frame_due(FRAME_INTERVAL) {
            let displayed = match step.unshot {
                Some(unshot) if self.live.ambient => {
                    display_radiosity(step.mesh, step.radiosity, unshot, true)
                }
                _ => step.radiosity.to_vec(),
            };
            let published = self.publisher.publish(
                &Geometry::of_mesh(step.mesh),
                &displayed,
                Irradiance::FromRadiosity(step.radiosity),
            );
            if let Err(e) = published {
                self.error.get_or_insert(e);
                return Flow::Stop;
            }
        }
        if self.live.stop.is_shutdown() {
            Flow::Stop
        } else {
            Flow::Continue
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The solve flags as parsed from an empty command line.
    fn default_solve_args() -> crate::args::SolveArgs {
        #[derive(clap::Parser)]
        struct Flags {
            #[command(flatten)]
            solve: crate::args::SolveArgs,
        }
        <Flags as clap::Parser>::parse_from(["radiosity"]).solve
    }

    /// A live solve of a small Cornell box publishes the meshed scene, frames that brighten
    /// as light is shot, and ends converged with the solver's own irradiance.
    #[test]
    fn a_live_solve_publishes_frames_and_converges() {
        let state = Arc::new(ViewState::new());
        let server = Server::bind(state.clone(), ServerConfig::default()).unwrap();
        let loaded = load_scene(None, &default_solve_args()).unwrap();
        let flags = radiosity::settings::Overrides {
            elements: Some(300),
            ..Default::default()
        };
        let settings = loaded.settings(&flags).unwrap();
        let camera = loaded.scene.camera_or_default();
        let live = Live {
            state: state.clone(),
            stop: server.shutdown_handle(),
            camera,
            wait: false,
            ambient: false,
            quiet: true,
        };
        live.solve(&loaded, &settings).unwrap();
        let notice = state.notice();
        assert_eq!(
            notice.progress.status,
            view::protocol::ViewStatus::Converged
        );
        assert_eq!(notice.progress.message, "converged");
        assert!(notice.progress.value.unwrap() <= 1e-3);
        // The emitters-only frame, at least one frame during the solve, the final frame.
        assert!(notice.frame.unwrap() >= 2, "{notice:?}");
        // The final frame is the solver's answer: B and H as `solve` computes them.
        let solved = radiosity::pipeline::solve_scene(
            &loaded.scene,
            &settings.solve,
            &radiosity::progress::NoProgress,
        )
        .unwrap();
        let frame = state.frame().unwrap();
        for (got, want) in frame
            .element_radiosity
            .iter()
            .zip(&solved.solution.radiosity)
        {
            for c in 0..3 {
                assert!((f64::from(got[c]) - want[c]).abs() <= 1e-5 * want[c].max(1.0));
            }
        }
        for (got, want) in frame
            .element_irradiance
            .iter()
            .zip(&solved.solution.irradiance)
        {
            for c in 0..3 {
                assert!((f64::from(got[c]) - want[c]).abs() <= 1e-5 * want[c].max(1.0));
            }
        }
    }

    /// Ctrl-C stops a solve at its next step (and one waiting for a page at once), with no
    /// final status.
    #[test]
    fn a_stopped_viewer_stops_the_solve() {
        let server = Server::bind(Arc::new(ViewState::new()), ServerConfig::default()).unwrap();
        let stop = server.shutdown_handle();
        stop.shutdown();
        let loaded = load_scene(None, &default_solve_args()).unwrap();
        let settings = loaded
            .settings(&radiosity::settings::Overrides {
                elements: Some(300),
                solver: Some(radiosity::solve::SolverKind::Progressive),
                ..Default::default()
            })
            .unwrap();
        for wait in [true, false] {
            let state = Arc::new(ViewState::new());
            let live = Live {
                state: state.clone(),
                stop: stop.clone(),
                camera: loaded.scene.camera_or_default(),
                wait,
                ambient: false,
                quiet: true,
            };
            live.solve(&loaded, &settings).unwrap();
            let notice = state.notice();
            assert!(!notice.progress.done, "{notice:?}");
            if !wait {
                // Stopped at the solver's first report: no shot was taken.
                assert_eq!(notice.progress.stage, "progressive solve");
                assert_eq!(notice.progress.steps, 0);
            }
        }
    }
}
