//! The link-level oracle of the two-level couplings: which patches are too close to an
//! element to be treated as one uniform source.
//!
//! The substructured system lets an element gather from a whole patch at the patch's mean
//! radiosity. Where the patch is close (within κ of its own diameter of the element), the
//! part the element actually sees can be much brighter or darker than the mean (a shadow
//! cast next to a block, a dark floor strip at a wall), so the element links to the patch's
//! elements one by one instead: a two-level hierarchy in the spirit of Hanrahan, Salzman &
//! Aupperle (1991), with the link level chosen by this distance oracle. Every two-level
//! coupling and the hemi-cube engine take their link levels from here.

use crate::mesh::Mesh;
use glam::DVec3;
use rayon::prelude::*;

/// How close (in patch diameters) a patch must be to an element to be linked element by
/// element: κ = 1.
pub const KAPPA: f64 = 1.0;

/// Near patches of each element and near receivers of each patch.
#[derive(Debug, Clone, Default)]
pub struct NearField {
    /// Near patches of each element (sorted).
    pub per_element: Vec<Vec<u32>>,
    /// Elements for which each patch is near (sorted).
    pub per_patch: Vec<Vec<u32>>,
}

impl NearField {
    /// The oracle: patches of other surfaces closer to the element's centre than κ × their
    /// diameter ([`KAPPA`]).
    pub fn decide(mesh: &Mesh) -> Self {
        Self::new(mesh, KAPPA)
    }

    /// Patches of other surfaces closer to the element's centre than `kappa` × their
    /// diameter. Candidates come from a uniform grid over the patches' spheres of influence
    /// (centre, κ·diameter + radius), so the cost is about linear in elements + patches.
    pub fn new(mesh: &Mesh, kappa: f64) -> Self {
        let info: Vec<(DVec3, f64, f64)> = mesh
            .patches
            .par_iter()
            .map(|p| extent(&p.polygon))
            .collect();
        let grid = SphereGrid::new(
            info.iter()
                .map(|(c, r, d)| (*c, kappa * d + r))
                .collect::<Vec<_>>(),
        );
        let per_element: Vec<Vec<u32>> = mesh
            .elements
            .par_iter()
            .map(|e| {
                let mut near: Vec<u32> = grid
                    .candidates(e.centre)
                    .iter()
                    .copied()
                    .filter(|&i| {
                        let ((c, r, d), p) = (&info[i as usize], &mesh.patches[i as usize]);
                        p.surface != e.surface
                            && e.centre.distance(*c) - r < kappa * d
                            && p.polygon.distance_to(e.centre) < kappa * d
                    })
                    .collect();
                near.sort_unstable();
                near
            })
            .collect();
        let mut per_patch = vec![Vec::new(); mesh.patches.len()];
        for (e, near) in per_element.iter().enumerate() {
            for &p in near {
                per_patch[p as usize].push(e as u32);
            }
        }
        Self {
            per_element,
            per_patch,
        }
    }

    /// No near field: every element gathers from whole patches.
    pub fn none(mesh: &Mesh) -> Self {
        Self {
            per_element: vec![Vec::new(); mesh.elements.len()],
            per_patch: vec![Vec::new(); mesh.patches.len()],
        }
    }

    /// Whether `patch` is linked element by element to `element`.
    pub fn is_near(&self, element: usize, patch: usize) -> bool {
        self.per_element[element]
            .binary_search(&(patch as u32))
            .is_ok()
    }
}

/// A patch's (centroid, radius about it, diameter), m.
fn extent(polygon: &crate::geometry::Polygon) -> (DVec3, f64, f64) {
    let c = polygon.centroid();
    let r = polygon
        .vertices()
        .iter()
        .map(|v| v.distance(c))
        .fold(0.0, f64::max);
    (c, r, polygon.diameter())
}

/// Spheres binned into the cells of a uniform grid they overlap: the spheres containing a
/// point are among the candidates of the point's cell.
struct SphereGrid {
    lo: DVec3,
    cell: f64,
    dims: [usize; 3],
    cells: Vec<Vec<u32>>,
}

impl SphereGrid {
    /// At most this many cells per axis.
    const MAX_DIM: usize = 32;

    fn new(spheres: Vec<(DVec3, f64)>) -> Self {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for (c, r) in &spheres {
            lo = lo.min(*c - DVec3::splat(*r));
            hi = hi.max(*c + DVec3::splat(*r));
        }
        if spheres.is_empty() {
            (lo, hi) = (DVec3::ZERO, DVec3::ONE);
        }
        let extent = (hi - lo).max(DVec3::splat(1e-12));
        // About as many cells as spheres, but no cell smaller than the median radius.
        let mut radii: Vec<f64> = spheres.iter().map(|(_, r)| *r).collect();
        radii.sort_by(f64::total_cmp);
        let median = radii.get(radii.len() / 2).copied().unwrap_or(1.0);
        let by_count = (extent.x * extent.y * extent.z / spheres.len().max(1) as f64).cbrt();
        let cell = by_count
            .max(median)
            .max(extent.max_element() / Self::MAX_DIM as f64)
            .max(1e-12);
        let dims = [0, 1, 2].map(|a| ((extent[a] / cell).ceil() as usize).clamp(1, Self::MAX_DIM));
        let mut cells = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let index =
            |v: f64, a: usize| (((v - lo[a]) / cell).floor().max(0.0) as usize).min(dims[a] - 1);
        for (i, (c, r)) in spheres.iter().enumerate() {
            let (a, b) = (*c - DVec3::splat(*r), *c + DVec3::splat(*r));
            for x in index(a.x, 0)..=index(b.x, 0) {
                for y in index(a.y, 1)..=index(b.y, 1) {
                    for z in index(a.z, 2)..=index(b.z, 2) {
                        cells[(x * dims[1] + y) * dims[2] + z].push(i as u32);
                    }
                }
            }
        }
        Self {
            lo,
            cell,
            dims,
            cells,
        }
    }

    fn candidates(&self, p: DVec3) -> &[u32] {
        let mut k = [0usize; 3];
        for a in 0..3 {
            let v = ((p[a] - self.lo[a]) / self.cell).floor();
            if !(v >= 0.0 && (v as usize) < self.dims[a]) {
                return &[];
            }
            k[a] = v as usize;
        }
        &self.cells[(k[0] * self.dims[1] + k[1]) * self.dims[2] + k[2]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshOptions;

    #[test]
    fn the_grid_finds_exactly_the_near_patches_of_a_brute_force_search() {
        let mesh = crate::mesh::Mesh::build(
            &crate::cornell::cornell_box(),
            &MeshOptions {
                elements: 1000,
                ..MeshOptions::default()
            },
        )
        .unwrap();
        let near = NearField::decide(&mesh);
        let mut links = 0;
        for (i, e) in mesh.elements.iter().enumerate() {
            let brute: Vec<u32> = mesh
                .patches
                .iter()
                .enumerate()
                .filter(|(_, p)| {
                    let (c, r, d) = extent(&p.polygon);
                    p.surface != e.surface
                        && e.centre.distance(c) - r < KAPPA * d
                        && p.polygon.distance_to(e.centre) < KAPPA * d
                })
                .map(|(k, _)| k as u32)
                .collect();
            assert_eq!(near.per_element[i], brute, "element {i}");
            links += brute.len();
        }
        assert!(links > 100, "the Cornell box has near pairs ({links})");
    }
}
