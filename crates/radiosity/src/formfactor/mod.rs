//! Form factors: the coupling between elements (receivers) and patches (sources).
//!
//! F_{e→p} = (1/A_e) ∫_{A_e} ∫_{A_p} cosθ_x cosθ_y V(x, y) / (π r²) dA_y dA_x is the fraction
//! of the power leaving element `e` diffusely that arrives at patch `p`. The solver gathers
//! B_e = E_e + ρ_e Σ_p F_{e→p} B_p. Every method implements [`FormFactors`]; the methods
//! are selected by name ([`FormFactorMethod`]) from the command line and the scene file.
//! Visibility is one shared component ([`Visibility`], rays through a BVH).

pub mod analytic_point;
pub mod quadrature;
pub mod raycast;

use crate::accel::Bvh;
use crate::mesh::Mesh;
use crate::progress::Progress;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::fmt;
use std::str::FromStr;

/// The form-factor methods, by the names used on the command line and in scene files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FormFactorMethod {
    /// Receiver quadrature × exact point-to-polygon × shadow rays (Wallace, Elmquist &
    /// Haines 1989).
    #[default]
    Raycast,
}

impl FormFactorMethod {
    pub const ALL: &'static [FormFactorMethod] = &[FormFactorMethod::Raycast];

    pub fn name(self) -> &'static str {
        match self {
            FormFactorMethod::Raycast => "raycast",
        }
    }

    /// Builds the method's engine over a mesh.
    pub fn engine<'a>(self, mesh: &'a Mesh, visibility: &'a Visibility) -> Box<dyn FormFactors + 'a> {
        match self {
            FormFactorMethod::Raycast => Box::new(raycast::Raycast::new(mesh, visibility)),
        }
    }
}

impl fmt::Display for FormFactorMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for FormFactorMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Self::ALL.iter().map(|m| m.name()).collect();
                format!("unknown form-factor method '{s}' (expected one of: {})", names.join(", "))
            })
    }
}

/// A way of computing element-to-patch form factors.
pub trait FormFactors: Sync {
    /// The method's name.
    fn name(&self) -> &'static str;

    /// F_{e→p}: element `e` (receiver) to patch `p` (source), with visibility.
    fn pair(&self, element: usize, patch: usize) -> f64;

    /// Column `p`: F_{e→p} for every element `e` (what one progressive shot needs).
    fn column(&self, patch: usize, out: &mut [f32]) {
        out.par_iter_mut()
            .enumerate()
            .for_each(|(e, f)| *f = self.pair(e, patch) as f32);
    }

    /// Row `e`: F_{e→p} for every patch `p` (what one gathering step needs).
    fn row(&self, element: usize, out: &mut [f32]) {
        for (p, f) in out.iter_mut().enumerate() {
            *f = self.pair(element, p) as f32;
        }
    }
}

/// The dense element × patch form-factor matrix, row-major (one row per receiving element).
#[derive(Debug, Clone)]
pub struct CouplingMatrix {
    pub elements: usize,
    pub patches: usize,
    pub data: Vec<f32>,
}

impl CouplingMatrix {
    /// Bytes needed to hold the matrix for a mesh.
    pub fn bytes_for(elements: usize, patches: usize) -> u128 {
        elements as u128 * patches as u128 * 4
    }

    /// Computes every row in parallel.
    pub fn compute(ff: &dyn FormFactors, mesh: &Mesh, progress: &dyn Progress) -> Self {
        let (n, m) = (mesh.elements.len(), mesh.patches.len());
        let mut data = vec![0.0f32; n * m];
        progress.start("form factors", n as u64);
        data.par_chunks_mut(m.max(1)).enumerate().for_each(|(e, row)| {
            ff.row(e, row);
            progress.inc(1);
        });
        progress.finish();
        Self {
            elements: n,
            patches: m,
            data,
        }
    }

    pub fn row(&self, e: usize) -> &[f32] {
        &self.data[e * self.patches..(e + 1) * self.patches]
    }

    pub fn get(&self, e: usize, p: usize) -> f64 {
        self.data[e * self.patches + p] as f64
    }
}

/// Point-to-point visibility by shadow rays through a BVH over the scene's surfaces.
///
/// Every surface blocks light from both sides (a back face is opaque). Ray ends are lifted
/// off their surfaces by a small offset proportional to the scene size so that the surfaces
/// the ray starts and ends on are not hit.
pub struct Visibility {
    bvh: Bvh,
    offset: f64,
}

impl Visibility {
    /// Builds the BVH over the original surface polygons (fan-triangulated).
    pub fn new(mesh: &Mesh) -> Self {
        let mut tris = Vec::new();
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in &mesh.surface_polygons {
            for t in p.triangles() {
                tris.push(t.map(|v| v.as_vec3()));
            }
            let (a, b) = p.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        let diameter = (hi - lo).length().max(1e-9);
        Self {
            bvh: Bvh::build(&tris),
            offset: 1e-5 * diameter,
        }
    }

    /// True when nothing blocks the segment from `x` (on a surface with normal `nx`) to `y`
    /// (on a surface with normal `ny`).
    pub fn visible(&self, x: DVec3, nx: DVec3, y: DVec3, ny: DVec3) -> bool {
        let a = (x + nx * self.offset).as_vec3();
        let b = (y + ny * self.offset).as_vec3();
        !self.bvh.segment_occluded(a, b, 1e-5)
    }

    /// The underlying BVH.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Closest surface hit along a ray (for picking and tests).
    pub fn first_hit(&self, origin: Vec3, dir: Vec3) -> Option<crate::accel::Hit> {
        self.bvh.intersect(origin, dir, 0.0, f32::INFINITY)
    }
}

/// Divides a convex triangle or quad into `k²` sub-polygons (bilinear or barycentric lattice).
pub fn subdivide(vertices: &[DVec3], k: usize) -> Vec<Vec<DVec3>> {
    let mut out = Vec::with_capacity(k * k);
    let kf = k as f64;
    if vertices.len() == 4 {
        let [a, b, c, d] = [vertices[0], vertices[1], vertices[2], vertices[3]];
        let p = |i: usize, j: usize| {
            let (u, v) = (i as f64 / kf, j as f64 / kf);
            (1.0 - u) * (1.0 - v) * a + u * (1.0 - v) * b + u * v * c + (1.0 - u) * v * d
        };
        for i in 0..k {
            for j in 0..k {
                out.push(vec![p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
            }
        }
    } else if vertices.len() == 3 {
        let [a, b, c] = [vertices[0], vertices[1], vertices[2]];
        let p = |i: usize, j: usize| a + (b - a) * (i as f64 / kf) + (c - a) * (j as f64 / kf);
        for i in 0..k {
            for j in 0..k - i {
                out.push(vec![p(i, j), p(i + 1, j), p(i, j + 1)]);
                if j + 1 < k - i {
                    out.push(vec![p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
                }
            }
        }
    } else {
        // General convex polygon: fan triangles, each subdivided.
        let v0 = vertices[0];
        for w in vertices[1..].windows(2) {
            out.extend(subdivide(&[v0, w[0], w[1]], k));
        }
    }
    out
}
