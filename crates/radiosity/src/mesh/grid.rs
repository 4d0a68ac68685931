//! Meshing of polygons with many vertices: the polygon is cut by a regular square lattice laid
//! in its plane, so that interior elements are whole lattice cells and only the cells the
//! outline crosses are clipped.
//!
//! The fan triangles of an n-gon are slivers from vertex 0 to every edge: a disc of 200,000
//! vertices became 200,000 patches 2 m long and a fraction of a millimetre wide, one element
//! each whatever the element budget, and every one of them a near-field candidate of every
//! element (issue 8). On the lattice the number of elements and patches follows the element
//! size alone (about A/h² plus one row of boundary cells); a boundary cell keeps the vertices
//! of the outline that lie in it, so the elements tile the polygon exactly.
//!
//! The cuts are made by [`split_convex`] in halves (the middle line of a range of lattice
//! lines first, then each half), O(n log k) for n vertices and k lines, never O(n·k): columns
//! of patches, then patches, then the columns and cells of each patch. The crossing vertices
//! are computed once for both sides of a cut and lattice points come out exactly as
//! (x_i, y_j), so neighbouring cells weld into a mesh without cracks.
//!
//! Polygons of at most [`GRID_MIN_VERTICES`]` − 1` vertices (every triangle and quad, the
//! pentagons and hexagons that surfaces split at contacts become) keep their lattice or fan
//! meshes ([`super::Mesh`]).

use crate::geometry::{split_convex, PlaneFrame, Polygon};
use glam::DVec3;

/// Polygons with at least this many vertices are meshed on the square lattice; smaller ones
/// by their own (fan) lattice. The fan of a regular n-gon has triangles of aspect about n/π
/// near vertex 0: up to 8 vertices they are fair elements, beyond they turn into slivers.
pub const GRID_MIN_VERTICES: usize = 9;

/// Whether `polygon` is meshed on the square lattice.
pub fn uses_grid(polygon: &Polygon) -> bool {
    polygon.vertices().len() >= GRID_MIN_VERTICES
}

/// Cells per axis of the lattice over a bounding box side of `length` m: `(patches,
/// elements per patch)`, as for a quad ([`super::split_count`]).
fn axis_cells(length: f64, size: f64, sub: u32) -> (u32, u32) {
    super::split_count(length, size, sub)
}

/// About how many elements [`mesh_on_grid`] makes of `polygon` at element size `size`: the
/// whole cells its area holds plus one per lattice column and row (the convex outline
/// crosses each column and each row in two cells, which the area counts about half of),
/// at most every cell of the bounding box.
pub fn grid_count(polygon: &Polygon, size: f64, sub: u32) -> f64 {
    let frame = PlaneFrame::new(polygon.vertices(), polygon.normal());
    let (lu, lw) = (frame.hi[0] - frame.lo[0], frame.hi[1] - frame.lo[1]);
    let (pu, ku) = axis_cells(lu, size, sub);
    let (pw, kw) = axis_cells(lw, size, sub);
    let (nu, nw) = (f64::from(pu * ku), f64::from(pw * kw));
    let cell = (lu / nu) * (lw / nw);
    (polygon.area() / cell + nu + nw).min(nu * nw).max(1.0)
}

/// One patch of a gridded polygon: its outline and its elements' corners, counter-clockwise
/// seen from the polygon's front.
pub struct GridPatch {
    /// The patch: the polygon clipped to a block of cells.
    pub outline: Vec<DVec3>,
    /// The elements: the polygon clipped to each cell of the block, in row order.
    pub elements: Vec<Vec<DVec3>>,
}

/// Cuts `polygon` by the square lattice of element size about `size` (cells of the bounding
/// box in its plane, `sub` × `sub` cells a patch, as for a quad). Pieces of less than 10⁻¹²
/// of a cell (a vertex or an edge grazing a lattice line) are dropped.
pub fn mesh_on_grid(polygon: &Polygon, size: f64, sub: u32) -> Vec<GridPatch> {
    let frame = PlaneFrame::new(polygon.vertices(), polygon.normal());
    let (lo, hi) = (frame.lo, frame.hi);
    let (pu, ku) = axis_cells(hi[0] - lo[0], size, sub);
    let (pw, kw) = axis_cells(hi[1] - lo[1], size, sub);
    let (nu, nw) = (pu * ku, pw * kw);
    // Lattice line i of each axis; every cut along line i computes the same value.
    let line_u = |i: u32| lo[0] + (hi[0] - lo[0]) * (f64::from(i) / f64::from(nu));
    let line_w = |j: u32| lo[1] + (hi[1] - lo[1]) * (f64::from(j) / f64::from(nw));
    let tiny = 1e-12 * ((hi[0] - lo[0]) / f64::from(nu)) * ((hi[1] - lo[1]) / f64::from(nw));
    let to_3d = |piece: &[[f64; 2]]| piece.iter().map(|p| frame.point(*p)).collect();

    let mut out = Vec::new();
    let columns = cut(frame.flat.clone(), 0, 0, pu, &|a| line_u(a * ku));
    for (a, column) in columns {
        for (b, block) in cut(column, 1, 0, pw, &|b| line_w(b * kw)) {
            if area(&block) <= tiny {
                continue;
            }
            let mut elements = Vec::new();
            for (_, strip) in cut(block.clone(), 0, a * ku, (a + 1) * ku, &line_u) {
                for (_, cell) in cut(strip, 1, b * kw, (b + 1) * kw, &line_w) {
                    if area(&cell) > tiny {
                        elements.push(to_3d(&cell));
                    }
                }
            }
            if !elements.is_empty() {
                out.push(GridPatch {
                    outline: to_3d(&block),
                    elements,
                });
            }
        }
    }
    out
}

/// The pieces of the convex loop `piece` between consecutive lines `line(i)`, i in
/// `first..end` (the piece lies between lines `first` and `end`), with their index i, in
/// increasing order; pieces of fewer than three vertices are dropped. Cuts in halves, so
/// that each vertex is copied O(log(end − first)) times.
fn cut(
    piece: Vec<[f64; 2]>,
    axis: usize,
    first: u32,
    end: u32,
    line: &dyn Fn(u32) -> f64,
) -> Vec<(u32, Vec<[f64; 2]>)> {
    let mut out = Vec::new();
    let mut stack = vec![(first, end, piece)];
    while let Some((first, end, piece)) = stack.pop() {
        if piece.len() < 3 {
            continue;
        }
        if end - first <= 1 {
            out.push((first, piece));
            continue;
        }
        let mid = first + (end - first) / 2;
        let (mut below, mut above) = (Vec::new(), Vec::new());
        split_convex(&piece, axis, line(mid), &mut below, &mut above);
        // Last in, first out: the lower half is cut first.
        stack.push((mid, end, above));
        stack.push((first, mid, below));
    }
    out
}

/// Signed area of a plane loop (shoelace), positive counter-clockwise.
fn area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    let o = p[0];
    let mut twice = 0.0;
    for i in 1..n.saturating_sub(1) {
        let (a, b) = (p[i], p[i + 1]);
        twice += (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    }
    0.5 * twice
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc(n: usize, r: f64) -> Polygon {
        Polygon::new(
            (0..n)
                .map(|k| {
                    let a = std::f64::consts::TAU * k as f64 / n as f64;
                    DVec3::new(r * a.cos(), r * a.sin(), 0.5)
                })
                .collect(),
        )
        .unwrap()
    }

    #[test]
    fn cells_tile_the_polygon_and_interior_cells_are_whole() {
        let p = disc(1000, 1.0);
        let size = 0.1;
        let patches = mesh_on_grid(&p, size, 3);
        let cells: Vec<&Vec<DVec3>> = patches.iter().flat_map(|q| &q.elements).collect();
        let total: f64 = cells
            .iter()
            .map(|c| Polygon::new_unchecked(c.to_vec()).area())
            .sum();
        // 1e-12: rounding of a few hundred cell areas.
        assert!((total - p.area()).abs() < 1e-12 * p.area(), "{total}");
        let patch_total: f64 = patches
            .iter()
            .map(|q| Polygon::new_unchecked(q.outline.clone()).area())
            .sum();
        assert!((patch_total - p.area()).abs() < 1e-12 * p.area());
        // π/h² whole cells and a ring of clipped ones: the count is set by the element size,
        // not by the 1000 vertices (the bound is the whole bounding box, 21 × 21).
        let whole = cells.iter().filter(|c| c.len() == 4).count();
        assert!(cells.len() <= 21 * 21, "{} cells", cells.len());
        assert!(whole >= 200, "{whole} whole cells");
        // Every vertex of the outline is in exactly one cell or on a cell wall.
        let corners: usize = cells.iter().map(|c| c.len()).sum();
        assert!(corners < 1000 + 8 * cells.len());
        for c in &cells {
            let q = Polygon::new_unchecked(c.to_vec());
            assert!(
                q.normal().dot(p.normal()) > 0.999_999,
                "a cell is turned over"
            );
            assert!(q.diameter() <= 0.1 * 2f64.sqrt() * 1.000_001);
        }
    }

    #[test]
    fn cuts_share_their_vertices_bit_for_bit() {
        // Euler characteristic of a conforming mesh of a disc, welding bit-identical
        // vertices: V − E + F = 1. A crack (two copies of one point) would raise it.
        let p = disc(777, 1.3);
        let cells: Vec<Vec<DVec3>> = mesh_on_grid(&p, 0.07, 2)
            .into_iter()
            .flat_map(|q| q.elements)
            .collect();
        let key = |v: DVec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
        let mut vertices = std::collections::HashSet::new();
        let mut edges = std::collections::HashSet::new();
        for c in &cells {
            for k in 0..c.len() {
                let (a, b) = (key(c[k]), key(c[(k + 1) % c.len()]));
                vertices.insert(a);
                edges.insert(if a < b { (a, b) } else { (b, a) });
            }
        }
        let chi = vertices.len() as i64 - edges.len() as i64 + cells.len() as i64;
        assert_eq!(chi, 1);
    }
}
