//! Single form-factor problems, independent of any mesh: from a polygon (or a differential
//! area) to a polygon, optionally with occluding polygons. This is what
//! `radiosity formfactor FILE.json` reads, and what the accuracy table measures.
//!
//! The file format (lengths in any unit; form factors are scale-free):
//!
//! ```json
//! { "from": [[x, y, z], ...]  or  {"point": [x, y, z], "normal": [x, y, z]},
//!   "to": [[x, y, z], ...],
//!   "occluders": [[[x, y, z], ...], ...] }
//! ```
//!
//! Polygons are planar, convex and counter-clockwise seen from their front; `occluders` is
//! optional, and occluders block from both sides (they may also be non-convex: they are split).
//!
//! Every method answers F_{from→to} ([`solve_pair`]); F_{to→from} is the same method applied
//! to the swapped problem (not reciprocity, so that reciprocity can be tested), and is not
//! defined for a differential `from`.

use super::{
    analytic, hemicube, monte_carlo, point_sampled, raycast, Engine, FormFactorMethod, Visibility,
};
use crate::geometry::{split_into_convex, GeometryError, Polygon, COORDINATE_LIMIT};
use crate::mesh::{Mesh, MeshOptions};
use crate::scene::{Material, MaterialId, Origin, Scene, Surface};
use glam::DVec3;
use serde_json::Value;
use std::time::Instant;

/// The emitting side of a form factor.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A differential area at `point` with unit `normal`.
    Point {
        /// Position, m.
        point: DVec3,
        /// Unit normal.
        normal: DVec3,
    },
    /// A planar convex polygon, counter-clockwise seen from its front.
    Polygon(Vec<DVec3>),
}

/// One form-factor problem: F from `from` to the polygon `to`, with occluders.
///
/// Build it with [`PairProblem::new`] or [`PairProblem::from_json`], which validate the
/// geometry; the methods assume valid input.
#[derive(Debug, Clone, PartialEq)]
pub struct PairProblem {
    /// The receiving side (F is from it).
    pub from: Source,
    /// The source polygon, counter-clockwise seen from its front.
    pub to: Vec<DVec3>,
    /// Opaque convex polygons that may block the view (both sides block).
    pub occluders: Vec<Vec<DVec3>>,
}

/// A form-factor value, with its standard error where the method is a random estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The form factor (dimensionless).
    pub value: f64,
    /// Its standard error, for random estimates.
    pub stderr: Option<f64>,
}

impl Estimate {
    /// A deterministic value (no standard error).
    pub fn exact(value: f64) -> Self {
        Self {
            value,
            stderr: None,
        }
    }
}

/// Why a pair problem could not be built.
#[derive(Debug, thiserror::Error)]
pub enum PairError {
    #[error("not valid JSON: {0}")]
    /// The file is not valid JSON.
    Json(#[from] serde_json::Error),
    #[error("{0}")]
    /// The JSON does not describe a problem.
    Format(String),
    #[error("{what}: {source}")]
    /// A polygon of the problem is not usable.
    Geometry {
        /// What the value is.
        what: String,
        /// The underlying error.
        source: GeometryError,
    },
}

impl PairProblem {
    /// Validates and builds a problem: every polygon finite, in range, non-degenerate, planar
    /// and convex (occluders may be non-convex or slightly twisted quads: they are split); a
    /// point source finite with a non-zero normal (normalised here).
    pub fn new(
        from: Source,
        to: Vec<DVec3>,
        occluders: Vec<Vec<DVec3>>,
    ) -> Result<Self, PairError> {
        let polygon = |what: &str, v: Vec<DVec3>| {
            Polygon::new(v).map_err(|source| PairError::Geometry {
                what: what.to_owned(),
                source,
            })
        };
        let from = match from {
            Source::Polygon(v) => Source::Polygon(polygon("from", v)?.vertices().to_vec()),
            Source::Point { point, normal } => {
                if !point.is_finite() || !normal.is_finite() {
                    return Err(PairError::Geometry {
                        what: "from".into(),
                        source: GeometryError::NonFinite,
                    });
                }
                let m = point.abs().max_element();
                if m > COORDINATE_LIMIT {
                    return Err(PairError::Geometry {
                        what: "from: point".into(),
                        source: GeometryError::OutOfRange {
                            value: m,
                            limit: COORDINATE_LIMIT,
                        },
                    });
                }
                let len = normal.length();
                if len <= 1e-300 {
                    return Err(PairError::Format(format!(
                        "from: normal [{}, {}, {}] has zero length",
                        normal.x, normal.y, normal.z
                    )));
                }
                Source::Point {
                    point,
                    normal: normal / len,
                }
            }
        };
        let to = polygon("to", to)?.vertices().to_vec();
        let mut convex = Vec::new();
        for (i, o) in occluders.into_iter().enumerate() {
            let parts = split_into_convex(o).map_err(|source| PairError::Geometry {
                what: format!("occluders[{i}]"),
                source,
            })?;
            convex.extend(parts.into_iter().map(|p| p.vertices().to_vec()));
        }
        Ok(Self {
            from,
            to,
            occluders: convex,
        })
    }

    /// Parses and validates the JSON format described in the module docs.
    pub fn from_json(text: &str) -> Result<Self, PairError> {
        let value: Value = serde_json::from_str(text)?;
        let Value::Object(map) = &value else {
            return Err(PairError::Format(format!(
                "expected an object {{\"from\": ..., \"to\": ..., \"occluders\": ...}}, got {}",
                excerpt(&value)
            )));
        };
        if let Some(key) = map
            .keys()
            .find(|k| !["from", "to", "occluders"].contains(&k.as_str()))
        {
            return Err(PairError::Format(format!(
                "unknown key '{key}' (expected \"from\", \"to\" and optionally \"occluders\")"
            )));
        }
        let from = match map.get("from") {
            None => return Err(PairError::Format("missing \"from\"".into())),
            Some(Value::Object(point)) => {
                if let Some(key) = point
                    .keys()
                    .find(|k| !["point", "normal"].contains(&k.as_str()))
                {
                    return Err(PairError::Format(format!(
                        "from: unknown key '{key}' (a differential area is {{\"point\": [x, y, z], \"normal\": [x, y, z]}})"
                    )));
                }
                let get = |key: &str| {
                    point
                        .get(key)
                        .ok_or_else(|| PairError::Format(format!("from: missing \"{key}\"")))
                        .and_then(|v| vertex(&format!("from: {key}"), v))
                };
                Source::Point {
                    point: get("point")?,
                    normal: get("normal")?,
                }
            }
            Some(v) => Source::Polygon(vertices("from", v)?),
        };
        let to = vertices(
            "to",
            map.get("to")
                .ok_or_else(|| PairError::Format("missing \"to\"".into()))?,
        )?;
        let occluders = match map.get("occluders") {
            None | Some(Value::Null) => Vec::new(),
            Some(Value::Array(list)) => list
                .iter()
                .enumerate()
                .map(|(i, p)| vertices(&format!("occluders[{i}]"), p))
                .collect::<Result<_, _>>()?,
            Some(v) => {
                return Err(PairError::Format(format!(
                    "occluders: expected a list of polygons, got {}",
                    excerpt(v)
                )))
            }
        };
        Self::new(from, to, occluders)
    }

    /// The problem seen from the other side (`to` emitting towards `from`); `None` for a
    /// differential `from`, whose reverse form factor is not defined.
    pub fn swapped(&self) -> Option<PairProblem> {
        match &self.from {
            Source::Polygon(from) => Some(PairProblem {
                from: Source::Polygon(self.to.clone()),
                to: from.clone(),
                occluders: self.occluders.clone(),
            }),
            Source::Point { .. } => None,
        }
    }

    /// Area of `from` (`None` for a differential area), in the input's length unit squared.
    pub fn from_area(&self) -> Option<f64> {
        match &self.from {
            Source::Polygon(v) => Some(crate::geometry::newell(v).1),
            Source::Point { .. } => None,
        }
    }

    /// Area of `to`.
    pub fn to_area(&self) -> f64 {
        crate::geometry::newell(&self.to).1
    }

    /// The size of the whole configuration (diagonal of the bounding box of every point).
    pub fn diameter(&self) -> f64 {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let from: &[DVec3] = match &self.from {
            Source::Polygon(v) => v,
            Source::Point { point, .. } => std::slice::from_ref(point),
        };
        for p in from
            .iter()
            .chain(&self.to)
            .chain(self.occluders.iter().flatten())
        {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        (hi - lo).length()
    }

    /// Shadow rays through a BVH over the occluders; `None` when there are none (everything
    /// is visible).
    pub fn occluder_visibility(&self) -> Option<Visibility> {
        (!self.occluders.is_empty()).then(|| {
            Visibility::from_polygons(self.occluders.iter().map(Vec::as_slice), self.diameter())
        })
    }
}

fn excerpt(v: &Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 60 {
        format!("{}…", s.chars().take(60).collect::<String>())
    } else {
        s
    }
}

fn vertex(what: &str, v: &Value) -> Result<DVec3, PairError> {
    let bad = || {
        PairError::Format(format!(
            "{what}: expected [x, y, z] (three numbers), got {}",
            excerpt(v)
        ))
    };
    let Value::Array(xyz) = v else {
        return Err(bad());
    };
    if xyz.len() != 3 {
        return Err(bad());
    }
    let mut out = [0.0; 3];
    for (slot, c) in out.iter_mut().zip(xyz) {
        *slot = c.as_f64().ok_or_else(bad)?;
    }
    Ok(DVec3::from_array(out))
}

fn vertices(what: &str, v: &Value) -> Result<Vec<DVec3>, PairError> {
    let Value::Array(list) = v else {
        return Err(PairError::Format(format!(
            "{what}: expected a polygon [[x, y, z], ...], got {}",
            excerpt(v)
        )));
    };
    list.iter()
        .enumerate()
        .map(|(i, p)| vertex(&format!("{what}: vertex {i}"), p))
        .collect()
}

/// Method parameters for pair problems; `None` means the method's default.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PairSettings {
    /// `point-sampled`: sub-areas per polygon; `monte-carlo`: rays per direction.
    pub samples: Option<usize>,
    /// `hemicube`: pixels along the hemi-cube's top face.
    pub resolution: Option<usize>,
    /// Seed of the random methods (`monte-carlo`, and the jittered `hemicube`); the same
    /// seed gives the same answer.
    pub seed: u64,
    /// `hemicube`: rotate each hemi-cube randomly about its normal (against aliasing).
    pub jitter: bool,
}

/// A method's answer to a pair problem.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairResult {
    /// The method.
    pub method: FormFactorMethod,
    /// F_{from→to}.
    pub from_to: Estimate,
    /// F_{to→from}, computed by the same method on the swapped problem; `None` for a
    /// differential `from`.
    pub to_from: Option<Estimate>,
    /// Wall-clock seconds for both.
    pub seconds: f64,
}

impl PairResult {
    /// One JSON line: `{"method", "F_from_to", "F_to_from", "seconds"}`, plus `"stderr"` (of
    /// F_from_to) and `"stderr_to_from"` for the random methods.
    pub fn to_json_line(&self) -> String {
        #[derive(serde::Serialize)]
        struct Line {
            method: &'static str,
            #[serde(rename = "F_from_to")]
            from_to: f64,
            #[serde(rename = "F_to_from")]
            to_from: Option<f64>,
            seconds: f64,
            #[serde(skip_serializing_if = "Option::is_none")]
            stderr: Option<f64>,
            #[serde(skip_serializing_if = "Option::is_none")]
            stderr_to_from: Option<f64>,
        }
        let line = Line {
            method: self.method.name(),
            from_to: self.from_to.value,
            to_from: self.to_from.map(|e| e.value),
            seconds: self.seconds,
            stderr: self.from_to.stderr,
            stderr_to_from: self.to_from.and_then(|e| e.stderr),
        };
        serde_json::to_string(&line).unwrap_or_default()
    }
}

/// Solves a pair problem with one method: F_{from→to}, and F_{to→from} from the swapped
/// problem where `from` is a polygon.
pub fn solve_pair(
    problem: &PairProblem,
    method: FormFactorMethod,
    settings: &PairSettings,
) -> PairResult {
    let start = Instant::now();
    let from_to = estimate(problem, method, settings);
    let to_from = problem.swapped().map(|p| {
        // A different stream for the reverse direction: the two estimates are independent.
        let reverse = PairSettings {
            seed: settings.seed ^ 0x9e37_79b9_7f4a_7c15,
            ..*settings
        };
        estimate(&p, method, &reverse)
    });
    PairResult {
        method,
        from_to,
        to_from,
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// F_{from→to} by one method.
pub fn estimate(
    problem: &PairProblem,
    method: FormFactorMethod,
    settings: &PairSettings,
) -> Estimate {
    match method {
        FormFactorMethod::AnalyticPoint => analytic::analytic_point_pair(problem),
        FormFactorMethod::AnalyticPolygon => analytic::analytic_polygon_pair(problem),
        FormFactorMethod::PointSampled => point_sampled::point_sampled_pair(
            problem,
            settings
                .samples
                .unwrap_or(point_sampled::DEFAULT_PAIR_SAMPLES),
        ),
        FormFactorMethod::Hemicube => hemicube::hemicube_pair(
            problem,
            &hemicube::HemicubeParams {
                resolution: settings
                    .resolution
                    .unwrap_or(hemicube::HemicubeParams::default().resolution),
                jitter: settings.jitter,
                seed: settings.seed,
            },
        ),
        FormFactorMethod::Raycast => raycast_pair(problem),
        FormFactorMethod::MonteCarlo => monte_carlo::monte_carlo_pair(
            problem,
            settings.samples.unwrap_or(monte_carlo::DEFAULT_PAIR_RAYS),
            settings.seed,
        ),
    }
}

/// `raycast` on a pair problem: the mesh engine itself (the [`raycast::RaycastKernel`] in a
/// [`super::KernelEngine`]), run on a mesh of the problem with one element and one patch per polygon
/// (the mesh turns a polygon of more than four vertices into a fan of triangles), so that
/// the answer is the engine's own: F_{from→to} = Σ_{e∈from} (A_e / A_from) Σ_{p∈to} F_{e→p}.
///
/// A differential `from` has no element: there the engine's per-point kernel is applied to
/// the point, the exact point-to-polygon value times the visible fraction estimated from the
/// point by probe rays, refined over penumbra sub-areas when the probes disagree.
pub fn raycast_pair(problem: &PairProblem) -> Estimate {
    // One pair costs microseconds, so the receiver rule is raised from the mesh default
    // (quality 1, chosen for whole-scene speed) to quality 4.
    let params = raycast::RaycastParams {
        quality: 4.0,
        ..Default::default()
    };
    let (point, normal) = match &problem.from {
        Source::Point { point, normal } => (*point, *normal),
        Source::Polygon(from) => {
            return Estimate::exact(raycast_polygon_pair(from, problem, params))
        }
    };
    let to_normal = crate::geometry::newell(&problem.to).0;
    let f = super::analytic_point::point_to_polygon(point, normal, &problem.to, to_normal);
    if f <= 0.0 {
        return Estimate::exact(0.0);
    }
    let fraction = match problem.occluder_visibility() {
        None => 1.0,
        Some(vis) => {
            let source = super::kernel::SourcePolygon::new(
                &problem.to,
                params.probe,
                params.penumbra,
                super::kernel::Division::SubAreas,
            );
            super::kernel::visible_fraction(&vis, &[(point, 1.0)], normal, &source, true)
        }
    };
    Estimate::exact(f * fraction)
}

fn raycast_polygon_pair(
    from: &[DVec3],
    problem: &PairProblem,
    params: raycast::RaycastParams,
) -> f64 {
    let material = Material::new("grey", [0.5; 3], [0.0; 3]);
    let surface = |name: String, vertices: &[DVec3]| Surface {
        object: name,
        group: String::new(),
        material: MaterialId(0),
        polygon: Polygon::new_unchecked(vertices.to_vec()),
        origin: Origin::default(),
    };
    let mut surfaces = vec![
        surface("from".into(), from),
        surface("to".into(), &problem.to),
    ];
    for (i, o) in problem.occluders.iter().enumerate() {
        surfaces.push(surface(format!("occluder {i}"), o));
    }
    let scene = Scene {
        name: "pair".into(),
        materials: vec![material],
        surfaces,
        lights: Vec::new(),
        camera: None,
    };
    // Elements larger than anything in the scene: one element (and patch) per quad or
    // triangle.
    let options = MeshOptions {
        max_element_size: Some(4.0 * problem.diameter().max(1e-300)),
        elements: 1,
        patch_subdivision: 1,
    };
    let Ok(mesh) = Mesh::build(&scene, &options) else {
        return f64::NAN;
    };
    // Scene surface of each mesh surface (the mesh splits surfaces where others touch them).
    let scene_surface = |s: u32| mesh.surfaces[s as usize].scene_surface as usize;
    let is_from = |s: u32| scene_surface(s) == 0;
    let is_to = |s: u32| scene_surface(s) == 1;
    let visibility = Visibility::new(&mesh);
    let engine = super::engine::KernelEngine::new(
        &mesh,
        &visibility,
        Box::new(raycast::RaycastKernel { params }),
    );
    let area: f64 = crate::geometry::newell(from).1;
    let patches: Vec<usize> = (0..mesh.patches.len())
        .filter(|&p| is_to(mesh.patches[p].surface))
        .collect();
    mesh.elements
        .iter()
        .enumerate()
        .filter(|(_, e)| is_from(e.surface))
        .map(|(i, e)| e.area / area * patches.iter().map(|&p| engine.pair(i, p)).sum::<f64>())
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f64, up: bool) -> Vec<DVec3> {
        let mut v = vec![
            DVec3::new(0.0, 0.0, z),
            DVec3::new(1.0, 0.0, z),
            DVec3::new(1.0, 1.0, z),
            DVec3::new(0.0, 1.0, z),
        ];
        if !up {
            v.reverse();
        }
        v
    }

    #[test]
    fn parses_polygons_points_and_occluders() {
        let p = PairProblem::from_json(
            r#"{"from": {"point": [0, 0, 0], "normal": [0, 0, 2]},
                "to": [[0,0,1],[0,1,1],[1,1,1],[1,0,1]],
                "occluders": [[[0,0,0.5],[1,0,0.5],[1,1,0.5],[0,1,0.5]]]}"#,
        )
        .unwrap();
        assert_eq!(
            p.from,
            Source::Point {
                point: DVec3::ZERO,
                normal: DVec3::Z
            }
        );
        assert_eq!(p.occluders.len(), 1);
        assert!(p.swapped().is_none());
        let q = PairProblem::new(
            Source::Polygon(square(0.0, true)),
            square(1.0, false),
            vec![],
        )
        .unwrap();
        let s = q.swapped().unwrap();
        assert_eq!(s.to, square(0.0, true));
        assert_eq!(q.from_area(), Some(1.0));
    }

    #[test]
    fn rejects_bad_input_with_a_message_naming_the_culprit() {
        let cases = [
            ("[1, 2]", "expected an object"),
            (r#"{"from": [[0,0,0],[1,0,0],[1,1,0]]}"#, "missing \"to\""),
            (
                r#"{"from": [[0,0,0],[1,0,0],[2,0,0]], "to": [[0,0,1],[0,1,1],[1,1,1]]}"#,
                "from: polygon is degenerate",
            ),
            (
                r#"{"from": [[0,0,0],[1,0,0],[1,1,0]], "to": [[0,0,1],[0,1,1],[1,"x",1]]}"#,
                "to: vertex 2",
            ),
            (
                r#"{"from": {"point": [0,0,0], "normal": [0,0,0]}, "to": [[0,0,1],[0,1,1],[1,1,1]]}"#,
                "zero length",
            ),
            (
                r#"{"from": [[0,0,0],[1,0,0],[1,1,0]], "to": [[0,0,1],[0,1,1],[1,1,1]], "occluder": []}"#,
                "unknown key 'occluder'",
            ),
            (
                r#"{"from": [[0,0,0],[1,0,0],[1,1,0]], "to": [[0,0,1],[0,1,1],[1,1,1]], "occluders": [[[0,0,0]]]}"#,
                "occluders[0]",
            ),
            (
                "{\"from\": [[0,0,0],[1,0,0],[1,1,0]], \"to\": [[0,0,1],[0,1,1],[1,1,NaN]]}",
                "not valid JSON",
            ),
        ];
        for (text, needle) in cases {
            let err = PairProblem::from_json(text).unwrap_err().to_string();
            assert!(
                err.contains(needle),
                "{text}: '{err}' should mention '{needle}'"
            );
        }
    }

    #[test]
    fn json_line_has_the_documented_keys() {
        let r = PairResult {
            method: FormFactorMethod::MonteCarlo,
            from_to: Estimate {
                value: 0.25,
                stderr: Some(0.01),
            },
            to_from: None,
            seconds: 1.5,
        };
        let v: Value = serde_json::from_str(&r.to_json_line()).unwrap();
        assert_eq!(v["method"], "monte-carlo");
        assert_eq!(v["F_from_to"], 0.25);
        assert!(v["F_to_from"].is_null());
        assert_eq!(v["stderr"], 0.01);
    }
}
