//! The default viewpoint of a scene that has no camera: one that sees lit surfaces from their
//! front, so that a scene never renders black just because the camera stands in the wrong
//! place.
//!
//! A fixed framing from outside (the classic "frame the bounds from −z") looks at the backs of
//! the walls of a closed room, which are black. Instead:
//!
//! 1. **Closed or open.** Rays are cast in 128 directions from each point of a lattice inside
//!    the scene's bounds. If from some point at least 95 % of them hit the front of a surface
//!    (a two-sided surface has two fronts), that point is inside a closed space: the scene is
//!    *closed*. Otherwise it is *open* (the Cornell box, an object on a floor).
//! 2. **What is lit.** Rays leave every emitting surface (cosine-distributed, in proportion to
//!    its power) and every point or spot light (weighted by its intensity distribution); the
//!    surfaces whose fronts they hit first are *lit*.
//! 3. **Candidates.** Closed: from each free lattice point (≥ 90 % front hits), eight
//!    horizontal directions tilted slightly down, 70° field of view. Open: the bounds framed
//!    from outside, as [`Camera::framing`] does, from the six axis directions and eight
//!    three-quarter views from above, 40° field of view.
//! 4. **Score.** A 16 × 16 grid of rays through each candidate's image: a ray scores 1 when it
//!    first meets the front of a lit surface, 0.3 for the front of an unlit one, 0 for a back
//!    face or nothing; hits closer than 2 % of the scene's size count a fifth. The best
//!    candidate wins; ties go to the earlier one, and the first open candidate is the classic
//!    −z framing.
//!
//! "Up" is the opposite of the mean facing direction of the emitters (lamps face down) when
//! that is clearly along one axis, else +y (the glTF and most OBJ exporters' convention).
//!
//! Everything is deterministic (fixed sample patterns), so a scene always gets the same camera.
//!
//! See also: [`crate::diagnose`], which warns when no viewpoint can help (nothing emits).

use crate::accel::Visibility;
use crate::scene::{Camera, Scene};
use glam::DVec3;
use std::f64::consts::PI;

/// Field of view of interior views, degrees.
const INTERIOR_FOV_DEG: f64 = 70.0;
/// Field of view of exterior views, degrees (as [`Camera::framing`]).
const EXTERIOR_FOV_DEG: f64 = 40.0;
/// A point whose rays hit fronts at least this often is inside a closed space.
const CLOSED_FRONT_FRACTION: f64 = 0.95;
/// Interior eyes must see fronts at least this often (free space, not inside furniture).
const FREE_FRONT_FRACTION: f64 = 0.9;

/// The camera to use for a scene without one (see the module documentation).
pub fn default_camera(scene: &Scene) -> Camera {
    if scene.surfaces.is_empty() {
        return Camera::default();
    }
    let probe = Probe::new(scene);
    let up = up_axis(scene);
    let mut best: Option<(f64, Camera)> = None;
    let mut consider = |camera: Camera| {
        let score = probe.score(&camera);
        if best.as_ref().is_none_or(|(s, _)| score > *s) {
            best = Some((score, camera));
        }
    };
    let free = probe.free_points(up);
    if free.closed {
        for eye in free.eyes {
            for direction in horizontal_directions(up) {
                let look = (direction - up * 0.15).normalize();
                consider(Camera {
                    eye,
                    target: eye + look,
                    up,
                    fov_deg: INTERIOR_FOV_DEG,
                });
            }
        }
    } else {
        for look in exterior_directions(up) {
            consider(probe.framing(look, up));
        }
    }
    best.map_or_else(
        || {
            let (lo, hi) = scene.bounds();
            Camera::framing(lo, hi)
        },
        |(_, camera)| camera,
    )
}

/// The scene's likely up direction, a unit axis: against the emitters' mean facing when that
/// is clearly along one axis (and the spot lights' aim), else +y.
pub fn up_axis(scene: &Scene) -> DVec3 {
    let mut facing = DVec3::ZERO;
    let mut total = 0.0;
    for s in &scene.surfaces {
        let m = scene.material(s);
        if m.is_emitter() && !(m.two_sided && m.two_sided_emission) {
            let w = crate::units::luminance_y(m.emission) * s.polygon.area();
            facing += s.polygon.normal() * w;
            total += w;
        }
    }
    for light in &scene.lights {
        if matches!(light.distribution, crate::light::Distribution::Spot { .. }) {
            let w = crate::units::luminance_y(light.intensity);
            facing += light.aim.nadir * w;
            total += w;
        }
    }
    if total > 0.0 && facing.length() > 0.5 * total {
        let axis = snap_to_axis(-facing);
        if axis.length() > 0.0 {
            return axis;
        }
    }
    DVec3::Y
}

/// The axis direction (±x, ±y, ±z) nearest to `v`; zero for a zero vector.
fn snap_to_axis(v: DVec3) -> DVec3 {
    let a = v.abs();
    if a.max_element() == 0.0 {
        DVec3::ZERO
    } else if a.x >= a.y && a.x >= a.z {
        DVec3::X * v.x.signum()
    } else if a.y >= a.z {
        DVec3::Y * v.y.signum()
    } else {
        DVec3::Z * v.z.signum()
    }
}

/// Two unit axes perpendicular to the axis `up`, forming a right-handed frame (a, b, up).
fn horizontal_axes(up: DVec3) -> (DVec3, DVec3) {
    let a = if up.x.abs() > 0.5 { DVec3::Z } else { DVec3::X };
    let a = (a - up * a.dot(up)).normalize();
    (a, up.cross(a))
}

/// Eight horizontal unit directions: the four axes and the four diagonals.
fn horizontal_directions(up: DVec3) -> Vec<DVec3> {
    let (a, b) = horizontal_axes(up);
    (0..8)
        .map(|k| {
            let angle = k as f64 * PI / 4.0;
            a * angle.cos() + b * angle.sin()
        })
        .collect()
}

/// View directions for exterior framings: +z first (the classic framing from −z), the other
/// axes, then three-quarter views from above.
fn exterior_directions(up: DVec3) -> Vec<DVec3> {
    let mut out = vec![
        DVec3::Z,
        DVec3::NEG_Z,
        DVec3::X,
        DVec3::NEG_X,
        DVec3::Y,
        DVec3::NEG_Y,
    ];
    let diagonals: Vec<DVec3> = horizontal_directions(up)
        .into_iter()
        .skip(1)
        .step_by(2)
        .collect();
    for tilt in [0.8, 0.3] {
        for direction in &diagonals {
            out.push((*direction - up * tilt).normalize());
        }
    }
    out
}

/// What a ray from a point first meets.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Seen {
    /// Nothing.
    Nothing,
    /// The front of surface `s` (or either side of a two-sided one), at distance `t`.
    Front(usize, f64),
    /// The back of a one-sided surface.
    Back,
}

/// Interior lattice points and whether the scene is closed.
struct FreePoints {
    closed: bool,
    eyes: Vec<DVec3>,
}

/// Ray casting against the scene's surfaces, with which of them are lit.
struct Probe<'s> {
    scene: &'s Scene,
    visibility: Visibility,
    /// Polygon index of each surface's BVH triangles is the surface index.
    lit: Vec<bool>,
    lo: DVec3,
    hi: DVec3,
    diameter: f64,
}

impl<'s> Probe<'s> {
    fn new(scene: &'s Scene) -> Self {
        let (lo, hi) = scene.bounds();
        let diameter = (hi - lo).length().max(1e-9);
        let visibility = Visibility::from_polygons(
            scene.surfaces.iter().map(|s| s.polygon.vertices()),
            diameter,
        );
        let mut probe = Self {
            scene,
            visibility,
            lit: vec![false; scene.surfaces.len()],
            lo,
            hi,
            diameter,
        };
        probe.lit = probe.directly_lit();
        probe
    }

    /// What the ray from `origin` along `dir` (unit) first meets.
    fn cast(&self, origin: DVec3, dir: DVec3) -> Seen {
        let Some(hit) = self.visibility.first_hit(origin.as_vec3(), dir.as_vec3()) else {
            return Seen::Nothing;
        };
        let s = self.visibility.polygon_of(hit.triangle);
        let surface = &self.scene.surfaces[s];
        if surface.polygon.normal().dot(dir) < 0.0 || self.scene.material(surface).two_sided {
            Seen::Front(s, f64::from(hit.t))
        } else {
            Seen::Back
        }
    }

    /// Surfaces whose front receives light directly from an emitter or a light (all of them
    /// when nothing emits, so the score still prefers fronts).
    fn directly_lit(&self) -> Vec<bool> {
        let mut lit = vec![false; self.scene.surfaces.len()];
        let sources = crate::diagnose::emitted_rays(self.scene, 4096, self.diameter);
        if sources.is_empty() {
            return vec![true; self.scene.surfaces.len()];
        }
        for ray in sources {
            if let Seen::Front(s, _) = self.cast(ray.origin, ray.direction) {
                lit[s] = true;
            }
        }
        lit
    }

    /// Lattice points inside the bounds (3 × 3 across, two heights up), whether any of them is
    /// enclosed, and those in free space.
    fn free_points(&self, up: DVec3) -> FreePoints {
        let (a, b) = horizontal_axes(up);
        let size = self.hi - self.lo;
        let directions = sphere_directions(128);
        let mut closed = false;
        let mut eyes = Vec::new();
        for fa in [0.25, 0.5, 0.75] {
            for fb in [0.25, 0.5, 0.75] {
                for fu in [0.45, 0.65] {
                    // The point at fraction f of the bounds along a unit axis (from the low
                    // end for a positive axis, from the high end for a negative one).
                    let along = |axis: DVec3, f: f64| {
                        let unsigned = axis.abs();
                        let (l, h) = (self.lo.dot(unsigned), self.hi.dot(unsigned));
                        let f = if axis.max_element() > 0.0 { f } else { 1.0 - f };
                        unsigned * (l + f * (h - l))
                    };
                    let mut p = along(a, fa) + along(b, fb) + along(up, fu);
                    // Degenerate (flat) bounds: stay on the plane's centre.
                    if size.min_element() <= 0.0 {
                        p = (self.lo + self.hi) * 0.5;
                    }
                    let fronts = directions
                        .iter()
                        .filter(|d| matches!(self.cast(p, **d), Seen::Front(..)))
                        .count() as f64
                        / directions.len() as f64;
                    closed |= fronts >= CLOSED_FRONT_FRACTION;
                    if fronts >= FREE_FRONT_FRACTION {
                        eyes.push(p);
                    }
                }
            }
        }
        FreePoints { closed, eyes }
    }

    /// The camera framing the bounds from outside, looking along `look`.
    fn framing(&self, look: DVec3, up: DVec3) -> Camera {
        let centre = (self.lo + self.hi) * 0.5;
        let radius = (self.diameter * 0.5).max(1e-6);
        let distance = radius / (EXTERIOR_FOV_DEG.to_radians() * 0.5).sin();
        let camera_up = if look.cross(up).length() < 1e-6 {
            horizontal_axes(up).1
        } else {
            up
        };
        Camera {
            eye: centre - look * distance,
            target: centre,
            up: camera_up,
            fov_deg: EXTERIOR_FOV_DEG,
        }
    }

    /// How much of the camera's image would show lit fronts (see the module documentation).
    fn score(&self, camera: &Camera) -> f64 {
        const N: usize = 16;
        let forward = (camera.target - camera.eye).normalize();
        let right = forward.cross(camera.up).normalize();
        let up = right.cross(forward);
        let half = (camera.fov_deg.to_radians() * 0.5).tan();
        let near = 0.02 * self.diameter;
        let mut total = 0.0;
        for i in 0..N {
            for j in 0..N {
                let x = (2.0 * (i as f64 + 0.5) / N as f64 - 1.0) * half;
                let y = (2.0 * (j as f64 + 0.5) / N as f64 - 1.0) * half;
                let dir = (forward + right * x + up * y).normalize();
                total += match self.cast(camera.eye, dir) {
                    Seen::Front(s, t) => {
                        let value = if self.lit[s] { 1.0 } else { 0.3 };
                        if t < near {
                            value * 0.2
                        } else {
                            value
                        }
                    }
                    Seen::Back | Seen::Nothing => 0.0,
                };
            }
        }
        total / (N * N) as f64
    }
}

/// `n` unit directions spread evenly over the sphere (Fibonacci lattice).
pub(crate) fn sphere_directions(n: usize) -> Vec<DVec3> {
    let golden = PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|k| {
            let z = 1.0 - (2.0 * k as f64 + 1.0) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * k as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Polygon;
    use crate::scene::{Material, MaterialId, Origin, Surface};

    /// An axis-aligned box from `lo` to `hi`, faces pointing inwards (a room) or outwards.
    pub(crate) fn box_faces(lo: DVec3, hi: DVec3, inwards: bool) -> Vec<Vec<DVec3>> {
        let p = |x: bool, y: bool, z: bool| {
            DVec3::new(
                if x { hi.x } else { lo.x },
                if y { hi.y } else { lo.y },
                if z { hi.z } else { lo.z },
            )
        };
        // Outward-facing, counter-clockwise seen from outside.
        let mut faces = vec![
            vec![
                p(false, false, false),
                p(false, true, false),
                p(true, true, false),
                p(true, false, false),
            ], // −z
            vec![
                p(false, false, true),
                p(true, false, true),
                p(true, true, true),
                p(false, true, true),
            ], // +z
            vec![
                p(false, false, false),
                p(true, false, false),
                p(true, false, true),
                p(false, false, true),
            ], // −y
            vec![
                p(false, true, false),
                p(false, true, true),
                p(true, true, true),
                p(true, true, false),
            ], // +y
            vec![
                p(false, false, false),
                p(false, false, true),
                p(false, true, true),
                p(false, true, false),
            ], // −x
            vec![
                p(true, false, false),
                p(true, true, false),
                p(true, true, true),
                p(true, false, true),
            ], // +x
        ];
        if inwards {
            for f in &mut faces {
                f.reverse();
            }
        }
        faces
    }

    fn scene_of(faces: Vec<(Vec<DVec3>, u32)>) -> Scene {
        Scene {
            name: "t".into(),
            materials: vec![
                Material::new("wall", [0.5; 3], [0.0; 3]),
                Material::new("lamp", [0.5; 3], [5.0; 3]),
            ],
            surfaces: faces
                .into_iter()
                .enumerate()
                .map(|(i, (v, m))| Surface {
                    object: format!("s{i}"),
                    group: String::new(),
                    material: MaterialId(m),
                    polygon: Polygon::new(v).unwrap(),
                    origin: Origin::default(),
                })
                .collect(),
            lights: Vec::new(),
            camera: None,
        }
    }

    /// A closed room 4 × 2.7 × 3 m (y up) with a lamp under the ceiling facing down.
    fn room() -> Scene {
        let mut faces: Vec<(Vec<DVec3>, u32)> =
            box_faces(DVec3::ZERO, DVec3::new(4.0, 2.7, 3.0), true)
                .into_iter()
                .map(|f| (f, 0))
                .collect();
        let y = 2.69;
        faces.push((
            vec![
                DVec3::new(1.5, y, 1.0),
                DVec3::new(2.5, y, 1.0),
                DVec3::new(2.5, y, 2.0),
                DVec3::new(1.5, y, 2.0),
            ],
            1,
        ));
        scene_of(faces)
    }

    fn inside(camera: &Camera, lo: DVec3, hi: DVec3) -> bool {
        camera.eye.cmpgt(lo).all() && camera.eye.cmplt(hi).all()
    }

    #[test]
    fn closed_room_is_seen_from_inside() {
        let scene = room();
        // The lamp faces −y: up is +y.
        assert_eq!(up_axis(&scene), DVec3::Y);
        let camera = default_camera(&scene);
        let (lo, hi) = (DVec3::ZERO, DVec3::new(4.0, 2.7, 3.0));
        assert!(inside(&camera, lo, hi), "{camera:?}");
        // The old framing stood outside and saw only backs: score 0. The chosen one sees
        // lit fronts almost everywhere.
        let probe = Probe::new(&scene);
        assert_eq!(probe.score(&Camera::framing(lo, hi)), 0.0);
        assert!(probe.score(&camera) > 0.8, "{}", probe.score(&camera));
    }

    #[test]
    fn z_up_room_gets_z_up() {
        // The same room with z up: the lamp faces −z.
        let mut scene = room();
        for s in &mut scene.surfaces {
            let v: Vec<DVec3> = s
                .polygon
                .vertices()
                .iter()
                .map(|p| DVec3::new(p.x, -p.z, p.y))
                .collect();
            s.polygon = Polygon::new(v).unwrap();
        }
        assert_eq!(up_axis(&scene), DVec3::Z);
        let camera = default_camera(&scene);
        assert_eq!(camera.up, DVec3::Z);
        assert!(inside(
            &camera,
            DVec3::new(0.0, -3.0, 0.0),
            DVec3::new(4.0, 0.0, 2.7)
        ));
    }

    #[test]
    fn open_box_is_seen_from_its_open_lit_side() {
        // A box open at +x with a lamp on its inner back wall (x = 0) facing +x: the camera
        // stands outside on the +x side, looking in (−x).
        let lo = DVec3::ZERO;
        let hi = DVec3::splat(1.0);
        let mut faces: Vec<(Vec<DVec3>, u32)> = box_faces(lo, hi, true)
            .into_iter()
            .enumerate()
            .filter(|(i, _)| *i != 5)
            .map(|(_, f)| (f, 0))
            .collect();
        faces.push((
            vec![
                DVec3::new(0.01, 0.4, 0.4),
                DVec3::new(0.01, 0.4, 0.6),
                DVec3::new(0.01, 0.6, 0.6),
                DVec3::new(0.01, 0.6, 0.4),
            ],
            1,
        ));
        let scene = scene_of(faces);
        let camera = default_camera(&scene);
        assert!(camera.eye.x > 1.0, "{camera:?}");
        let look = (camera.target - camera.eye).normalize();
        assert!(look.x < -0.5, "{look}");
    }

    #[test]
    fn a_single_floor_is_seen_from_above() {
        let scene = scene_of(vec![(
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 0.0),
            ],
            0,
        )]);
        let camera = default_camera(&scene);
        assert!(camera.eye.y > 0.0, "{camera:?}");
    }

    #[test]
    fn sphere_directions_are_unit_and_balanced() {
        let d = sphere_directions(128);
        let mean: DVec3 = d.iter().copied().sum::<DVec3>() / 128.0;
        assert!(mean.length() < 1e-2);
        assert!(d.iter().all(|v| (v.length() - 1.0).abs() < 1e-12));
    }
}
