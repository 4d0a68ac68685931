//! Settings, resolved once: the library's defaults, overridden by the scene file's
//! `settings`, overridden by the command line's flags — and validated here, in one place,
//! with errors that name where the bad value came from (the flag, or the scene file and key).
//!
//! The command line parses its flags into plain values ([`Overrides`]) and hands them here
//! with the scene file's [`SceneSettings`]; [`resolve`] returns one validated [`Settings`].

use crate::formfactor::FormFactorMethod;
use crate::io::scene_file::SceneSettings;
use crate::mesh::{MeshOptions, RefineOptions, MAX_ELEMENTS};
use crate::pipeline::SolveSettings;
use crate::render::{MAX_IMAGE_SIZE, MAX_SAMPLES_PER_AXIS};
use crate::scene::Camera;
use crate::solve::{SolveOptions, SolverKind};
use glam::DVec3;
use std::fmt;

/// The most progressive shots a solve may be asked to take.
pub const MAX_SHOTS: u64 = 1 << 32;
/// The deepest adaptive refinement (each level quadruples an element).
pub const MAX_REFINE_DEPTH: u64 = 8;

/// Where a value came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// A command-line flag, e.g. `--width`.
    Flag(&'static str),
    /// A key of a scene file's `settings`, e.g. `cornell.json: settings.width`.
    SceneFile {
        /// The file, as the user named it.
        file: String,
        /// The key inside `settings`.
        key: &'static str,
    },
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Origin::Flag(flag) => f.write_str(flag),
            Origin::SceneFile { file, key } => write!(f, "{file}: settings.{key}"),
        }
    }
}

/// A bad setting: where it came from and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{origin} {problem}")]
pub struct SettingsError {
    /// The flag or the scene file and key.
    pub origin: Origin,
    /// What is wrong, with the value given.
    pub problem: String,
}

/// Values from the command line; `None` leaves the scene file's value or the default.
/// Counts are signed so that a negative count is reported by name rather than as a parse
/// error.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// `--elements`.
    pub elements: Option<i64>,
    /// `--max-element-size` (m).
    pub max_element_size: Option<f64>,
    /// `--patch-subdivision`.
    pub patch_subdivision: Option<i64>,
    /// `--solver`.
    pub solver: Option<SolverKind>,
    /// `--form-factor`.
    pub form_factor: Option<FormFactorMethod>,
    /// `--tolerance`.
    pub tolerance: Option<f64>,
    /// `--max-shots`.
    pub max_shots: Option<i64>,
    /// `--overshoot`.
    pub overshoot: Option<f64>,
    /// `--epsilon` (hierarchical link tolerance).
    pub epsilon: Option<f64>,
    /// `--adaptive`.
    pub adaptive: bool,
    /// `--refine-threshold`.
    pub refine_threshold: Option<f64>,
    /// `--max-depth`.
    pub max_depth: Option<i64>,
    /// `--width` (pixels).
    pub width: Option<i64>,
    /// `--height` (pixels).
    pub height: Option<i64>,
    /// `--samples` (per pixel axis).
    pub samples: Option<i64>,
    /// `--exposure` (stops).
    pub exposure: Option<f64>,
    /// `--ambient`.
    pub ambient: bool,
}

/// How to render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Supersamples per pixel axis.
    pub samples: u32,
    /// PNG exposure in stops: pixel = L · 2^exposure before the sRGB curve.
    pub exposure: f64,
    /// Display the progressive-refinement ambient term.
    pub ambient: bool,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 512,
            height: 512,
            samples: 4,
            exposure: 0.0,
            ambient: false,
        }
    }
}

/// Every setting, resolved and validated.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Settings {
    /// Meshing, form factors and solver.
    pub solve: SolveSettings,
    /// Adaptive refinement, when asked for.
    pub refine: Option<RefineOptions>,
    /// Image output.
    pub render: RenderSettings,
}

/// One value with its origin, from a flag or else the scene file.
struct Pick<'a, T> {
    flag: &'static str,
    key: &'static str,
    file: Option<&'a str>,
    from_flag: Option<T>,
    from_file: Option<T>,
}

impl<'a, T: Copy> Pick<'a, T> {
    fn new(
        file: Option<&'a str>,
        flag: &'static str,
        key: &'static str,
        from_flag: Option<T>,
        from_file: Option<T>,
    ) -> Self {
        Self {
            flag,
            key,
            file,
            from_flag,
            from_file,
        }
    }

    fn value(&self) -> Option<(T, Origin)> {
        if let Some(v) = self.from_flag {
            return Some((v, Origin::Flag(self.flag)));
        }
        let v = self.from_file?;
        Some((
            v,
            Origin::SceneFile {
                file: self.file.unwrap_or("scene").to_owned(),
                key: self.key,
            },
        ))
    }
}

fn bad(origin: Origin, problem: String) -> SettingsError {
    SettingsError { origin, problem }
}

/// A whole number in `lo..=hi`.
fn count<T: Copy + Into<i128>>(
    pick: Pick<'_, T>,
    lo: i128,
    hi: i128,
    what: &str,
) -> Result<Option<u64>, SettingsError> {
    match pick.value() {
        None => Ok(None),
        Some((v, origin)) => {
            let v: i128 = v.into();
            if v < lo || v > hi {
                Err(bad(
                    origin,
                    format!("must be {what} from {lo} to {hi}, got {v}"),
                ))
            } else {
                Ok(Some(v as u64))
            }
        }
    }
}

/// A finite number in the open interval (lo, hi).
fn number(pick: Pick<'_, f64>, lo: f64, hi: f64, what: &str) -> Result<Option<f64>, SettingsError> {
    match pick.value() {
        None => Ok(None),
        Some((v, origin)) => {
            if v.is_finite() && v > lo && v < hi {
                Ok(Some(v))
            } else {
                Err(bad(origin, format!("must be {what}, got {v}")))
            }
        }
    }
}

/// A method or solver name from the scene file, or the flag's value.
fn named<T: Copy + std::str::FromStr<Err = String>>(
    key: &'static str,
    file: Option<&str>,
    from_flag: Option<T>,
    from_file: Option<&str>,
) -> Result<Option<T>, SettingsError> {
    if from_flag.is_some() {
        return Ok(from_flag);
    }
    match from_file {
        None => Ok(None),
        Some(name) => name.parse().map(Some).map_err(|e| {
            bad(
                Origin::SceneFile {
                    file: file.unwrap_or("scene").to_owned(),
                    key,
                },
                e,
            )
        }),
    }
}

/// Defaults < scene file < flags, validated. `file` is the scene file's settings and the
/// name to report it by.
pub fn resolve(
    file: Option<(&SceneSettings, &str)>,
    flags: &Overrides,
) -> Result<Settings, SettingsError> {
    let empty = SceneSettings::default();
    let (fs, name) = match file {
        Some((s, n)) => (s, Some(n)),
        None => (&empty, None),
    };
    let mut settings = Settings::default();
    let mesh_defaults = MeshOptions::default();

    let elements = count(
        Pick::new(
            name,
            "--elements",
            "elements",
            flags.elements,
            fs.elements.map(|v| v as i64),
        ),
        1,
        MAX_ELEMENTS as i128,
        "a whole number of elements",
    )?;
    let size = number(
        Pick::new(
            name,
            "--max-element-size",
            "max_element_size",
            flags.max_element_size,
            // A count on the command line overrides a size from the file.
            if flags.elements.is_some() {
                None
            } else {
                fs.max_element_size
            },
        ),
        0.0,
        f64::INFINITY,
        "a positive element size in metres",
    )?;
    let patch_subdivision = count(
        Pick::new(
            name,
            "--patch-subdivision",
            "patch_subdivision",
            flags.patch_subdivision,
            fs.patch_subdivision.map(i64::from),
        ),
        1,
        64,
        "a whole number of elements per patch edge",
    )?;
    settings.solve.mesh = MeshOptions {
        max_element_size: size,
        elements: elements.map_or(mesh_defaults.elements, |v| v as usize),
        patch_subdivision: patch_subdivision.map_or(mesh_defaults.patch_subdivision, |v| v as u32),
    };

    let solver = named("solver", name, flags.solver, fs.solver.as_deref())?;
    let form_factor = named(
        "form_factor",
        name,
        flags.form_factor,
        fs.form_factor.as_deref(),
    )?;
    // The default solver is hierarchical. A flag that only the classic mesh or progressive
    // refinement uses asks for them: with no solver named (flag or scene file) it selects
    // progressive refinement; with the hierarchical solver named it is an error naming the
    // flag, rather than silently ignored.
    let classic = classic_only(flags, fs, name);
    let solver = match (solver, classic) {
        (None, Some(_)) => SolverKind::Progressive,
        (Some(SolverKind::Hierarchical), Some((origin, flag))) => {
            return Err(bad(
                origin,
                format!(
                    "{} and does not apply to the hierarchical solver, which refines where \
                     its links ask (--epsilon) down to 1/N of the total area (--elements N)",
                    classic_use(flag)
                ),
            ));
        }
        (solver, _) => solver.unwrap_or_default(),
    };
    let mut solve = SolveOptions {
        solver,
        ..SolveOptions::default()
    };
    if let Some(t) = number(
        Pick::new(
            name,
            "--tolerance",
            "tolerance",
            flags.tolerance,
            fs.tolerance,
        ),
        0.0,
        1.0,
        "a number between 0 and 1 (exclusive)",
    )? {
        solve.tolerance = t;
    }
    solve.max_shots = count(
        Pick::new(
            name,
            "--max-shots",
            "max_shots",
            flags.max_shots,
            fs.max_shots.map(|v| v as i64),
        ),
        1,
        MAX_SHOTS as i128,
        "a whole number of shots",
    )?
    .map(|v| v as usize);
    if let Some(w) = number(
        Pick::new(name, "--overshoot", "overshoot", flags.overshoot, None),
        0.0,
        2.0,
        "a relaxation factor ω between 0 and 2 (exclusive)",
    )? {
        solve.overshoot = w;
    }
    settings.solve.solve = solve;
    if let Some(e) = number(
        Pick::new(name, "--epsilon", "epsilon", flags.epsilon, fs.epsilon),
        0.0,
        1.0,
        "a fraction of each receiver's irradiance between 0 and 1 (exclusive)",
    )? {
        settings.solve.hierarchical.epsilon = e;
    }
    // `--elements N` with the hierarchical solver bounds its leaves: no element is
    // subdivided below 1/N of the scene's total area, so subdivision makes at most N leaves
    // (input polygons smaller than that stay whole). Only the flag: a scene file's
    // `elements` sizes the classic mesh and would silently coarsen a hierarchical solve.
    // N = 1 stops all subdivision (the fraction must stay below 1).
    if let (Some(n), Some(_)) = (elements, flags.elements) {
        if settings.solve.solve.solver == SolverKind::Hierarchical {
            settings.solve.hierarchical.min_area_fraction =
                (1.0 / n as f64).min(1.0 - f64::EPSILON);
        }
    }
    settings.solve.form_factor = form_factor.unwrap_or_default();

    if flags.adaptive {
        let mut refine = RefineOptions {
            max_elements: Some(settings.solve.mesh.elements),
            ..RefineOptions::default()
        };
        if let Some(x) = number(
            Pick::new(
                name,
                "--refine-threshold",
                "refine_threshold",
                flags.refine_threshold,
                None,
            ),
            0.0,
            f64::INFINITY,
            "a positive fraction of the mean radiosity",
        )? {
            refine.threshold = x;
        }
        if let Some(d) = count(
            Pick::new(name, "--max-depth", "max_depth", flags.max_depth, None),
            0,
            MAX_REFINE_DEPTH as i128,
            "a whole number of splits (each quadruples the elements)",
        )? {
            refine.max_depth = d as u8;
        }
        settings.refine = Some(refine);
    }

    let max = MAX_IMAGE_SIZE as i128;
    let render_defaults = RenderSettings::default();
    settings.render = RenderSettings {
        width: count(
            Pick::new(
                name,
                "--width",
                "width",
                flags.width,
                fs.width.map(i64::from),
            ),
            1,
            max,
            "a whole number of pixels",
        )?
        .map_or(render_defaults.width, |v| v as u32),
        height: count(
            Pick::new(
                name,
                "--height",
                "height",
                flags.height,
                fs.height.map(i64::from),
            ),
            1,
            max,
            "a whole number of pixels",
        )?
        .map_or(render_defaults.height, |v| v as u32),
        samples: count(
            Pick::new(name, "--samples", "samples", flags.samples, None),
            1,
            MAX_SAMPLES_PER_AXIS as i128,
            "a whole number of samples per pixel axis",
        )?
        .map_or(render_defaults.samples, |v| v as u32),
        exposure: number(
            Pick::new(name, "--exposure", "exposure", flags.exposure, fs.exposure),
            -64.0 - 1e-9,
            64.0 + 1e-9,
            "a finite number of stops between -64 and 64",
        )?
        .unwrap_or(render_defaults.exposure),
        ambient: flags.ambient || fs.ambient.unwrap_or(false),
    };
    Ok(settings)
}

/// Camera flags; `None` keeps the base camera's value.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CameraOverrides {
    /// `--eye` (m).
    pub eye: Option<DVec3>,
    /// `--target` (m).
    pub target: Option<DVec3>,
    /// `--up`.
    pub up: Option<DVec3>,
    /// `--fov` (degrees).
    pub fov_deg: Option<f64>,
}

/// `base` with the camera flags applied and checked: a field of view in (0°, 180°),
/// distinct eye and target, and an up direction not parallel to the view. `--eye` without
/// `--target` looks at `centre` (the scene's centre) when it is given, so moving the eye
/// does not leave the camera staring at where the old one looked.
pub fn camera(
    base: Camera,
    centre: Option<DVec3>,
    flags: &CameraOverrides,
) -> Result<Camera, SettingsError> {
    let target = match (flags.target, flags.eye) {
        (Some(t), _) => t,
        (None, Some(_)) => centre.unwrap_or(base.target),
        (None, None) => base.target,
    };
    let camera = Camera {
        eye: flags.eye.unwrap_or(base.eye),
        target,
        up: flags.up.unwrap_or(base.up),
        fov_deg: flags.fov_deg.unwrap_or(base.fov_deg),
    };
    if !(camera.fov_deg > 0.0 && camera.fov_deg < 180.0) {
        return Err(bad(
            Origin::Flag("--fov"),
            format!("must be between 0 and 180 degrees, got {}", camera.fov_deg),
        ));
    }
    let look = camera.target - camera.eye;
    if look.length() < 1e-12 {
        let flag = if flags.target.is_some() {
            "--target"
        } else {
            "--eye"
        };
        return Err(bad(
            Origin::Flag(flag),
            format!(
                "puts the eye and the target at the same point ({:?})",
                camera.eye.to_array()
            ),
        ));
    }
    if camera.up.length() == 0.0 || look.normalize().cross(camera.up.normalize()).length() < 1e-9 {
        return Err(bad(
            Origin::Flag("--up"),
            format!(
                "must not be zero or parallel to the viewing direction, got {:?}",
                camera.up.to_array()
            ),
        ));
    }
    Ok(camera)
}

/// The first setting given that only the classic mesh or progressive refinement uses, if
/// any: where it came from (a flag, else a key of the scene file `name`) and its flag.
fn classic_only(
    flags: &Overrides,
    fs: &SceneSettings,
    name: Option<&str>,
) -> Option<(Origin, &'static str)> {
    let flag = [
        ("--max-element-size", flags.max_element_size.is_some()),
        ("--patch-subdivision", flags.patch_subdivision.is_some()),
        ("--adaptive", flags.adaptive),
        ("--max-shots", flags.max_shots.is_some()),
        ("--overshoot", flags.overshoot.is_some()),
        ("--ambient", flags.ambient),
    ]
    .into_iter()
    .find_map(|(flag, given)| given.then_some((Origin::Flag(flag), flag)));
    let file = name.and_then(|file| {
        [
            (
                "max_element_size",
                "--max-element-size",
                // A count on the command line overrides a size from the file.
                fs.max_element_size.is_some() && flags.elements.is_none(),
            ),
            (
                "patch_subdivision",
                "--patch-subdivision",
                fs.patch_subdivision.is_some(),
            ),
            ("max_shots", "--max-shots", fs.max_shots.is_some()),
            ("ambient", "--ambient", fs.ambient == Some(true)),
        ]
        .into_iter()
        .find_map(|(key, flag, given)| {
            given.then(|| {
                (
                    Origin::SceneFile {
                        file: file.to_owned(),
                        key,
                    },
                    flag,
                )
            })
        })
    });
    flag.or(file)
}

/// What a classic-only flag does, for the error that refuses it with the hierarchical solver.
fn classic_use(flag: &str) -> &'static str {
    match flag {
        "--max-element-size" | "--patch-subdivision" => "sizes the classic mesh",
        "--adaptive" => "refines the classic mesh",
        "--max-shots" | "--overshoot" => "steers progressive refinement",
        _ => "shows progressive refinement's ambient term",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_override_the_file_which_overrides_defaults() {
        let file = SceneSettings {
            elements: Some(1234),
            width: Some(100),
            solver: Some("jacobi".into()),
            ..Default::default()
        };
        let flags = Overrides {
            width: Some(64),
            ..Default::default()
        };
        let s = resolve(Some((&file, "room.json")), &flags).unwrap();
        assert_eq!(s.solve.mesh.elements, 1234);
        assert_eq!(s.render.width, 64);
        assert_eq!(s.render.height, 512);
        assert_eq!(s.solve.solve.solver, SolverKind::Jacobi);
    }

    #[test]
    fn errors_name_the_flag_or_the_file_and_key() {
        let file = SceneSettings {
            width: Some(100_000),
            ..Default::default()
        };
        let e = resolve(Some((&file, "room.json")), &Overrides::default()).unwrap_err();
        assert_eq!(e.origin.to_string(), "room.json: settings.width");
        assert!(e.to_string().contains("100000"), "{e}");
        let flags = Overrides {
            elements: Some(-5),
            ..Default::default()
        };
        let e = resolve(None, &flags).unwrap_err();
        assert_eq!(e.origin, Origin::Flag("--elements"));
        assert!(e.to_string().contains("-5"), "{e}");
        let file = SceneSettings {
            solver: Some("magic".into()),
            ..Default::default()
        };
        let e = resolve(Some((&file, "a.json")), &Overrides::default()).unwrap_err();
        assert!(e.to_string().starts_with("a.json: settings.solver"), "{e}");
        for t in [0.0, 1.0, f64::NAN, -1.0] {
            let flags = Overrides {
                tolerance: Some(t),
                ..Default::default()
            };
            assert!(resolve(None, &flags).is_err(), "tolerance {t}");
        }
    }
    #[test]
    fn elements_flag_bounds_the_hierarchical_leaves() {
        let default_fraction = SolveSettings::default().hierarchical.min_area_fraction;
        let hierarchical = |elements: Option<i64>, file: Option<usize>| {
            let file = SceneSettings {
                elements: file,
                ..Default::default()
            };
            let flags = Overrides {
                elements,
                solver: Some(SolverKind::Hierarchical),
                ..Default::default()
            };
            resolve(Some((&file, "room.json")), &flags)
                .unwrap()
                .solve
                .hierarchical
                .min_area_fraction
        };
        // The flag sets the smallest element to 1/N of the total area.
        assert_eq!(hierarchical(Some(2000), None), 1.0 / 2000.0);
        assert_eq!(hierarchical(Some(2000), Some(500)), 1.0 / 2000.0);
        // N = 1: no subdivision, and still a fraction the hierarchy accepts (below 1).
        let one = hierarchical(Some(1), None);
        assert!(one < 1.0 && one > 0.5, "{one}");
        // Without the flag, or a scene file's count (meant for the classic mesh): the
        // hierarchy's own default.
        assert_eq!(hierarchical(None, None), default_fraction);
        assert_eq!(hierarchical(None, Some(500)), default_fraction);
        // Other solvers keep the default too (their meshes use the count).
        let flags = Overrides {
            elements: Some(2000),
            solver: Some(SolverKind::Progressive),
            ..Default::default()
        };
        let s = resolve(None, &flags).unwrap();
        assert_eq!(s.solve.hierarchical.min_area_fraction, default_fraction);
        assert_eq!(s.solve.mesh.elements, 2000);
    }

    #[test]
    fn classic_only_flags_select_progressive_refinement_or_are_refused_for_hierarchical() {
        let cases: [(&str, Overrides); 6] = [
            (
                "--max-element-size",
                Overrides {
                    max_element_size: Some(0.1),
                    ..Default::default()
                },
            ),
            (
                "--patch-subdivision",
                Overrides {
                    patch_subdivision: Some(2),
                    ..Default::default()
                },
            ),
            (
                "--adaptive",
                Overrides {
                    adaptive: true,
                    ..Default::default()
                },
            ),
            (
                "--max-shots",
                Overrides {
                    max_shots: Some(50),
                    ..Default::default()
                },
            ),
            (
                "--overshoot",
                Overrides {
                    overshoot: Some(1.1),
                    ..Default::default()
                },
            ),
            (
                "--ambient",
                Overrides {
                    ambient: true,
                    ..Default::default()
                },
            ),
        ];
        // Nothing asked: the hierarchical solver.
        let plain = resolve(None, &Overrides::default()).unwrap();
        assert_eq!(plain.solve.solve.solver, SolverKind::Hierarchical);
        for (flag, flags) in cases {
            // No solver named: progressive refinement, which uses the flag.
            let s = resolve(None, &flags).unwrap();
            assert_eq!(s.solve.solve.solver, SolverKind::Progressive, "{flag}");
            // A scene file's solver counts as named.
            let file = SceneSettings {
                solver: Some("jacobi".into()),
                ..Default::default()
            };
            let s = resolve(Some((&file, "a.json")), &flags).unwrap();
            assert_eq!(s.solve.solve.solver, SolverKind::Jacobi, "{flag}");
            // The hierarchical solver named: an error naming the flag.
            let e = resolve(
                None,
                &Overrides {
                    solver: Some(SolverKind::Hierarchical),
                    ..flags
                },
            )
            .unwrap_err();
            assert_eq!(e.origin, Origin::Flag(flag));
            assert!(e.to_string().contains("hierarchical"), "{e}");
        }
    }

    #[test]
    fn classic_only_scene_file_keys_select_progressive_refinement_or_are_refused() {
        let files = [
            (
                "max_element_size",
                SceneSettings {
                    max_element_size: Some(0.1),
                    ..Default::default()
                },
            ),
            (
                "patch_subdivision",
                SceneSettings {
                    patch_subdivision: Some(2),
                    ..Default::default()
                },
            ),
            (
                "max_shots",
                SceneSettings {
                    max_shots: Some(50),
                    ..Default::default()
                },
            ),
            (
                "ambient",
                SceneSettings {
                    ambient: Some(true),
                    ..Default::default()
                },
            ),
        ];
        for (key, file) in files {
            let s = resolve(Some((&file, "a.json")), &Overrides::default()).unwrap();
            assert_eq!(s.solve.solve.solver, SolverKind::Progressive, "{key}");
            // The hierarchical solver named, on the command line or in the file: an error
            // naming the file's key.
            let flagged = Overrides {
                solver: Some(SolverKind::Hierarchical),
                ..Default::default()
            };
            let in_file = SceneSettings {
                solver: Some("hierarchical".into()),
                ..file.clone()
            };
            for e in [
                resolve(Some((&file, "a.json")), &flagged).unwrap_err(),
                resolve(Some((&in_file, "a.json")), &Overrides::default()).unwrap_err(),
            ] {
                assert_eq!(
                    e.origin,
                    Origin::SceneFile {
                        file: "a.json".into(),
                        key
                    },
                    "{e}"
                );
            }
        }
        // `ambient: false` asks for nothing, and a count on the command line overrides the
        // file's element size: both stay hierarchical.
        let off = SceneSettings {
            ambient: Some(false),
            ..Default::default()
        };
        let s = resolve(Some((&off, "a.json")), &Overrides::default()).unwrap();
        assert_eq!(s.solve.solve.solver, SolverKind::Hierarchical);
        let sized = SceneSettings {
            max_element_size: Some(0.1),
            ..Default::default()
        };
        let count = Overrides {
            elements: Some(500),
            ..Default::default()
        };
        let s = resolve(Some((&sized, "a.json")), &count).unwrap();
        assert_eq!(s.solve.solve.solver, SolverKind::Hierarchical);
    }

    #[test]
    fn max_element_size_is_refused_for_the_hierarchical_solver() {
        // It sizes the classic mesh only; the hierarchical solver ignored it silently.
        let flags = |solver| Overrides {
            max_element_size: Some(0.1),
            solver: Some(solver),
            ..Default::default()
        };
        let e = resolve(None, &flags(SolverKind::Hierarchical)).unwrap_err();
        assert_eq!(e.origin, Origin::Flag("--max-element-size"));
        assert!(e.to_string().contains("hierarchical"), "{e}");
        let s = resolve(None, &flags(SolverKind::Progressive)).unwrap();
        assert_eq!(s.solve.mesh.max_element_size, Some(0.1));
    }
}
