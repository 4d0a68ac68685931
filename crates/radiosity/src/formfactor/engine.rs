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
                let order = kernel.receiver_order(size, &|| mesh.clearance(i));
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

/// Largest distance between two corners, m.
fn diameter(corners: &[glam::DVec3]) -> f64 {
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
