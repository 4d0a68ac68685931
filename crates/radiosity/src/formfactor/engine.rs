//! Mesh-level form-factor engines: F_{e→p} from element `e` (receiver) to patch `p`
//! (source), and F_{e→e'} to single source elements for near-field links, built on the
//! kernels of [`super::kernel`].
//!
//! [`KernelEngine`] prepares every element as a [`Receiver`] and every patch (and, on first
//! use, every element) as a [`SourcePolygon`] and calls the kernel per pair; rows and columns
//! are pairs in parallel. The hemi-cube ([`super::hemicube::Hemicube`]) and Monte Carlo
//! ([`super::monte_carlo::MonteCarlo`]) engines compute whole rows or columns at once from
//! one hemi-cube or one batch of rays, the way those methods are meant to be used.

use super::kernel::{Kernel, Receiver, SourcePolygon};
use super::FormFactorMethod;
use crate::accel::Visibility;
use crate::mesh::Mesh;
use rayon::prelude::*;
use std::sync::OnceLock;

/// Form factors over one mesh, by element and patch index.
pub trait Engine: Sync {
    /// The method.
    fn method(&self) -> FormFactorMethod;

    /// F_{e→p}: element `element` (receiver) to patch `patch` (source), with visibility.
    fn pair(&self, element: usize, patch: usize) -> f64;

    /// F_{e→e'}: element `element` to the single source element `source` (near-field links).
    fn element_pair(&self, element: usize, source: usize) -> f64;

    /// Column `patch`: F_{e→p} for every element `e` (what one progressive shot needs).
    fn column(&self, patch: usize, out: &mut [f32]) {
        out.par_iter_mut()
            .enumerate()
            .for_each(|(e, f)| *f = self.pair(e, patch) as f32);
    }

    /// Row `element`: F_{e→p} for every patch `p` (what one gathering step needs).
    fn row(&self, element: usize, out: &mut [f32]) {
        for (p, f) in out.iter_mut().enumerate() {
            *f = self.pair(element, p) as f32;
        }
    }
}

/// A mesh engine that calls a [`Kernel`] for every pair.
pub struct KernelEngine<'a> {
    mesh: &'a Mesh,
    visibility: &'a Visibility,
    kernel: Box<dyn Kernel>,
    receivers: Vec<Receiver>,
    patches: Vec<SourcePolygon>,
    element_sources: Vec<OnceLock<SourcePolygon>>,
}

impl<'a> KernelEngine<'a> {
    /// Prepares every element as a receiver (at the kernel's quadrature order) and every patch
    /// as a source.
    pub fn new(mesh: &'a Mesh, visibility: &'a Visibility, kernel: Box<dyn Kernel>) -> Self {
        let receivers = mesh
            .elements
            .par_iter()
            .enumerate()
            .map(|(i, e)| {
                let corners = mesh.element_corners(e);
                let size = diameter(&corners);
                let order =
                    kernel.receiver_order(size, &|limit| clearance(mesh, visibility, i, limit));
                let mut r = Receiver::polygon(corners, order);
                // The mesh's own centre and normal are the reference (identical up to
                // rounding; kept so that engines agree bit for bit on them).
                r.centre = e.centre;
                r.normal = e.normal;
                if order <= 1 {
                    r.points = vec![(e.centre, 1.0)];
                    r.visibility_points = r.points.clone();
                }
                r
            })
            .collect();
        let patches = mesh
            .patches
            .par_iter()
            .map(|p| kernel.source(p.polygon.vertices()))
            .collect();
        Self {
            mesh,
            visibility,
            receivers,
            patches,
            element_sources: (0..mesh.elements.len()).map(|_| OnceLock::new()).collect(),
            kernel,
        }
    }
}

impl Engine for KernelEngine<'_> {
    fn method(&self) -> FormFactorMethod {
        self.kernel.method()
    }

    fn pair(&self, element: usize, patch: usize) -> f64 {
        let (receiver, source) = (
            self.mesh.elements[element].surface,
            self.mesh.patches[patch].surface,
        );
        if self.mesh.same_sheet(receiver, source) {
            return 0.0;
        }
        self.kernel.form_factor(
            &self.receivers[element],
            &self.patches[patch],
            self.visibility,
        )
    }

    fn element_pair(&self, element: usize, source: usize) -> f64 {
        let (e, s) = (&self.mesh.elements[element], &self.mesh.elements[source]);
        if self.mesh.same_sheet(e.surface, s.surface) {
            return 0.0;
        }
        let src = self.element_sources[source]
            .get_or_init(|| self.kernel.source(&self.mesh.element_corners(s)));
        self.kernel
            .form_factor(&self.receivers[element], src, self.visibility)
    }
}

/// Distance (m) from element `element`'s centre to the nearest other surface that can
/// exchange light with it (some of that surface lies in front of the element and some of
/// the element in front of it, by more than 10⁻⁹ of the element's size, so that coplanar
/// neighbours do not count), if that is below `limit`; infinite otherwise.
///
/// Only surfaces with a triangle in the box of half-side `limit` about the centre are
/// examined (found through the visibility BVH), so the cost per element follows the
/// surfaces near it, not the scene's surface count (it was every surface: 300k separate
/// faces took hours in this search).
fn clearance(mesh: &Mesh, visibility: &Visibility, element: usize, limit: f64) -> f64 {
    let e = &mesh.elements[element];
    if limit.is_nan() || limit <= 0.0 {
        return f64::INFINITY;
    }
    let corners = mesh.element_corners(e);
    let size = corners
        .iter()
        .map(|c| c.distance(e.centre))
        .fold(0.0, f64::max);
    let tol = 1e-9 * size;
    let reach = glam::DVec3::splat(limit.min(f32::MAX as f64 / 4.0));
    let mut triangles = Vec::new();
    visibility.bvh().triangles_in_box(
        (e.centre - reach).as_vec3(),
        (e.centre + reach).as_vec3(),
        &mut triangles,
    );
    let mut surfaces: Vec<usize> = triangles
        .iter()
        .map(|&(t, _)| visibility.polygon_of(t))
        .collect();
    surfaces.sort_unstable();
    surfaces.dedup();
    let nearest = surfaces
        .into_iter()
        .filter(|&s| s != e.surface as usize)
        .map(|s| &mesh.surface_polygons[s])
        .filter(|poly| {
            poly.vertices()
                .iter()
                .any(|v| (*v - e.centre).dot(e.normal) > tol)
                && corners.iter().any(|&k| poly.plane_distance(k) > tol)
        })
        .map(|poly| poly.distance_to(e.centre))
        .fold(f64::INFINITY, f64::min);
    if nearest < limit {
        nearest
    } else {
        f64::INFINITY
    }
}

/// Largest distance between two corners, m: all pairs for the triangles and quads, rotating
/// calipers ([`crate::geometry::Polygon::diameter`]) for a cell of many corners.
fn diameter(corners: &[glam::DVec3]) -> f64 {
    if corners.len() > 8 {
        return crate::geometry::Polygon::new_unchecked(corners.to_vec()).diameter();
    }
    let mut size: f64 = 0.0;
    for i in 0..corners.len() {
        for j in i + 1..corners.len() {
            size = size.max(corners[i].distance(corners[j]));
        }
    }
    size
}

/// The engine of `method` over `mesh`: near patches of each element (`near_patches[e]`,
/// sorted, from the coupling's link oracle) matter to the hemi-cube, which draws them as
/// their elements.
pub fn engine<'a>(
    method: FormFactorMethod,
    mesh: &'a Mesh,
    visibility: &'a Visibility,
    near_patches: &'a [Vec<u32>],
) -> Box<dyn Engine + 'a> {
    match method {
        FormFactorMethod::Hemicube => Box::new(super::hemicube::Hemicube::new(
            mesh,
            super::hemicube::HemicubeParams::default(),
            near_patches,
        )),
        FormFactorMethod::MonteCarlo => {
            Box::new(super::monte_carlo::MonteCarlo::new(mesh, visibility))
        }
        _ => Box::new(KernelEngine::new(mesh, visibility, method.kernel())),
    }
}
