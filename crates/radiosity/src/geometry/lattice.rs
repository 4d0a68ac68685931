//! The one lattice subdivider: regular lattices over convex triangles and quads, used to mesh
//! surfaces into patches and elements, to split elements in refinement, and to divide sources
//! into sub-areas for the form-factor kernels.
//!
//! - A quad (a, b, c, d) gets the bilinear lattice
//!   p(i, j) = ū v̄·a + u v̄·b + uv·c + ū v·d, u = i/n_u, ū = (n_u − i)/n_u, v = j/n_v,
//!   v̄ = (n_v − j)/n_v (ū computed from integers, not as 1 − u, so that it is exact in the
//!   reverse direction).
//! - A triangle (a, b, c) gets the barycentric lattice
//!   p(i, j) = ((n−i−j)/n)·a + (i/n)·b + (j/n)·c, i + j ≤ n.
//!
//! Both formulas are symmetric in the two endpoints of an edge: a lattice point on an edge
//! is the same weighted sum whichever polygon computes it and in whichever direction it walks
//! the edge (floating-point addition is commutative), so neighbouring polygons that share an
//! edge, and the fan triangles of an n-gon that share a diagonal, get bit-identical vertices.
//!
//! See also: [`sub_areas`], pieces of similar size and shape for any convex polygon.

use super::clip::clip_convex;
use super::newell;
use glam::DVec3;

/// A regular lattice over a convex triangle or quad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lattice {
    /// Bilinear lattice with `nu` × `nv` cells over the quad (a, b, c, d).
    Quad {
        /// Corners, counter-clockwise.
        corners: [DVec3; 4],
        /// Cells along a→b.
        nu: u32,
        /// Cells along a→d.
        nv: u32,
    },
    /// Barycentric lattice with n² cells over the triangle (a, b, c).
    Triangle {
        /// Corners, counter-clockwise.
        corners: [DVec3; 3],
        /// Divisions of each edge.
        n: u32,
    },
}

impl Lattice {
    /// The lattice point (i, j): i along the first edge, j along the last.
    pub fn point(&self, i: u32, j: u32) -> DVec3 {
        match *self {
            Lattice::Quad {
                corners: [a, b, c, d],
                nu,
                nv,
            } => {
                let (u, v) = (i as f64 / nu as f64, j as f64 / nv as f64);
                let ubar = nu.saturating_sub(i) as f64 / nu as f64;
                let vbar = nv.saturating_sub(j) as f64 / nv as f64;
                (ubar * vbar) * a + (u * vbar) * b + (u * v) * c + (ubar * v) * d
            }
            Lattice::Triangle {
                corners: [a, b, c],
                n,
            } => {
                let nf = n as f64;
                let wa = n.saturating_sub(i + j) as f64 / nf;
                (wa * a + (i as f64 / nf) * b) + (j as f64 / nf) * c
            }
        }
    }

    /// Every cell as its corner lattice indices, counter-clockwise like the polygon: quads
    /// (i, j), (i+1, j), (i+1, j+1), (i, j+1) in row order of i then j; triangles
    /// (i, j), (i+1, j), (i, j+1) and, where it fits, (i+1, j), (i+1, j+1), (i, j+1).
    pub fn cells(&self) -> Vec<Vec<(u32, u32)>> {
        let mut out = Vec::new();
        match *self {
            Lattice::Quad { nu, nv, .. } => {
                for i in 0..nu {
                    for j in 0..nv {
                        out.push(vec![(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]);
                    }
                }
            }
            Lattice::Triangle { n, .. } => {
                for i in 0..n {
                    for j in 0..n - i {
                        out.push(vec![(i, j), (i + 1, j), (i, j + 1)]);
                        if j + 1 < n - i {
                            out.push(vec![(i + 1, j), (i + 1, j + 1), (i, j + 1)]);
                        }
                    }
                }
            }
        }
        out
    }

    /// Every cell as a polygon.
    pub fn cell_polygons(&self) -> Vec<Vec<DVec3>> {
        let mut out = Vec::new();
        self.for_each_cell(&mut |cell| out.push(cell.to_vec()));
        out
    }

    /// Calls `visit` with every cell's corners, in the order and orientation of
    /// [`Lattice::cells`], without allocating.
    pub fn for_each_cell(&self, visit: &mut dyn FnMut(&[DVec3])) {
        let p = |i, j| self.point(i, j);
        match *self {
            Lattice::Quad { nu, nv, .. } => {
                for i in 0..nu {
                    for j in 0..nv {
                        visit(&[p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
                    }
                }
            }
            Lattice::Triangle { n, .. } => {
                for i in 0..n {
                    for j in 0..n - i {
                        visit(&[p(i, j), p(i + 1, j), p(i, j + 1)]);
                        if j + 1 < n - i {
                            visit(&[p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
                        }
                    }
                }
            }
        }
    }
}

/// Divides a convex polygon into `k²` pieces per triangle: a triangle into k² similar
/// triangles, a quad into k × k quads, a larger polygon's fan triangles (from vertex 0) each
/// into k² triangles.
pub fn subdivide(vertices: &[DVec3], k: usize) -> Vec<Vec<DVec3>> {
    let mut out = Vec::new();
    for_each_piece(vertices, k, &mut |piece| out.push(piece.to_vec()));
    out
}

/// Calls `visit` with every piece of [`subdivide`], in its order, without allocating.
pub fn for_each_piece(vertices: &[DVec3], k: usize, visit: &mut dyn FnMut(&[DVec3])) {
    let k = k.max(1) as u32;
    match vertices.len() {
        4 => Lattice::Quad {
            corners: [vertices[0], vertices[1], vertices[2], vertices[3]],
            nu: k,
            nv: k,
        }
        .for_each_cell(visit),
        3 => Lattice::Triangle {
            corners: [vertices[0], vertices[1], vertices[2]],
            n: k,
        }
        .for_each_cell(visit),
        _ => {
            for w in vertices[1..].windows(2) {
                Lattice::Triangle {
                    corners: [vertices[0], w[0], w[1]],
                    n: k,
                }
                .for_each_cell(visit);
            }
        }
    }
}

/// Divides a convex polygon into about `k²` convex pieces of similar size and shape:
/// triangles by [`subdivide`] (`k²` similar triangles), quads on a `ku × kv` bilinear lattice
/// with `ku / kv` following the quad's aspect ratio (so that the pieces of a long strip are
/// not long strips themselves), larger polygons by clipping a square grid of side √A / k laid
/// along their first edge (so that a 256-gon is not cut into slivers).
///
/// The pieces tile the polygon exactly (their areas sum to its area, to rounding).
pub fn sub_areas(vertices: &[DVec3], k: usize) -> Vec<Vec<DVec3>> {
    let k = k.max(1);
    if vertices.len() == 4 {
        let [a, b, c, d] = [vertices[0], vertices[1], vertices[2], vertices[3]];
        let lu = a.distance(b).max(d.distance(c));
        let lv = a.distance(d).max(b.distance(c));
        let ku = ((k as f64 * (lu / lv).sqrt()).round() as usize).clamp(1, k * k);
        let kv = ((k * k) as f64 / ku as f64).round().max(1.0) as usize;
        return Lattice::Quad {
            corners: [a, b, c, d],
            nu: ku as u32,
            nv: kv as u32,
        }
        .cell_polygons();
    }
    if vertices.len() <= 4 {
        return subdivide(vertices, k);
    }
    let (normal, area) = newell(vertices);
    let PlaneFrame {
        origin,
        u,
        w,
        flat,
        lo,
        hi,
    } = PlaneFrame::new(vertices, normal);
    let side = area.sqrt() / k as f64;
    let cells = |a: usize| (((hi[a] - lo[a]) / side).ceil() as usize).max(1);
    let (nu, nw) = (cells(0), cells(1));
    let (hu, hw) = ((hi[0] - lo[0]) / nu as f64, (hi[1] - lo[1]) / nw as f64);
    let mut out = Vec::new();
    let (mut piece, mut next) = (Vec::new(), Vec::new());
    for i in 0..nu {
        for j in 0..nw {
            let (u0, w0) = (lo[0] + i as f64 * hu, lo[1] + j as f64 * hw);
            piece.clone_from(&flat);
            // The outer cells reach the bounding box: only inner cell walls cut.
            let walls: [(bool, usize, f64, f64); 4] = [
                (i > 0, 0, u0, 1.0),
                (i + 1 < nu, 0, u0 + hu, -1.0),
                (j > 0, 1, w0, 1.0),
                (j + 1 < nw, 1, w0 + hw, -1.0),
            ];
            for (cut, axis, bound, sign) in walls {
                if cut {
                    clip_convex(&piece, |p: &[f64; 2]| sign * (p[axis] - bound), &mut next);
                    std::mem::swap(&mut piece, &mut next);
                }
            }
            if piece.len() < 3 {
                continue;
            }
            let loop3: Vec<DVec3> = piece.iter().map(|p| origin + u * p[0] + w * p[1]).collect();
            if newell(&loop3).1 > 1e-12 * area {
                out.push(loop3);
            }
        }
    }
    out
}

/// A convex polygon's plane frame: vertex 0 as origin, its first edge as the first axis u,
/// normal × u as the second w (so the loop stays counter-clockwise), the loop in those
/// coordinates and its bounding box there.
pub(crate) struct PlaneFrame {
    pub origin: DVec3,
    pub u: DVec3,
    pub w: DVec3,
    pub flat: Vec<[f64; 2]>,
    pub lo: [f64; 2],
    pub hi: [f64; 2],
}

impl PlaneFrame {
    /// The frame of `vertices` (at least two) with unit normal `normal`.
    pub fn new(vertices: &[DVec3], normal: DVec3) -> Self {
        let origin = vertices[0];
        let u = (vertices[1] - origin).normalize();
        let w = normal.cross(u);
        let flat: Vec<[f64; 2]> = vertices
            .iter()
            .map(|v| [(*v - origin).dot(u), (*v - origin).dot(w)])
            .collect();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &flat {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        Self {
            origin,
            u,
            w,
            flat,
            lo,
            hi,
        }
    }

    /// The point at plane coordinates `p`.
    pub fn point(&self, p: [f64; 2]) -> DVec3 {
        self.origin + self.u * p[0] + self.w * p[1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_tiles(poly: &[DVec3], pieces: &[Vec<DVec3>], what: &str) {
        let (normal, area) = newell(poly);
        let sum: f64 = pieces.iter().map(|p| newell(p).1).sum();
        assert!(
            (sum - area).abs() < 1e-12 * area,
            "{what}: pieces cover {sum}, polygon {area}"
        );
        for p in pieces {
            // Same orientation, inside the polygon.
            assert!(
                newell(p).0.dot(normal) > 0.999_999,
                "{what}: a piece is turned over"
            );
            for v in p {
                let n = poly.len();
                let inside = (0..n).all(|i| {
                    (poly[(i + 1) % n] - poly[i])
                        .cross(*v - poly[i])
                        .dot(normal)
                        >= -1e-12
                });
                assert!(inside, "{what}: piece vertex {v} outside");
            }
        }
    }

    #[test]
    fn sub_areas_tile_polygons_with_pieces_of_similar_size() {
        // A 4 × 0.5 strip: near-square pieces (11 of 0.36 × 0.5), not 4 × 4 long strips.
        let strip = vec![
            DVec3::ZERO,
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(4.0, 0.5, 0.0),
            DVec3::new(0.0, 0.5, 0.0),
        ];
        let pieces = sub_areas(&strip, 4);
        assert!((8..=32).contains(&pieces.len()), "{} pieces", pieces.len());
        assert_tiles(&strip, &pieces, "strip");
        for p in &pieces {
            let (a, b) = (p[0].distance(p[1]), p[1].distance(p[2]));
            assert!(a.max(b) / a.min(b) <= 2.0, "a {a} × {b} piece");
        }
        // A square: exactly k × k squares.
        let square = vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        assert_eq!(sub_areas(&square, 5).len(), 25);
        let triangle = vec![DVec3::ZERO, DVec3::X, DVec3::new(0.2, 0.9, 0.3)];
        let pieces = sub_areas(&triangle, 3);
        assert_eq!(pieces.len(), 9);
        assert_tiles(&triangle, &pieces, "triangle");
        // A 64-gon: about k² pieces, none a sliver reaching across the disk.
        let disk: Vec<DVec3> = (0..64)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 64.0;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let pieces = sub_areas(&disk, 4);
        assert!((8..=32).contains(&pieces.len()), "{} pieces", pieces.len());
        assert_tiles(&disk, &pieces, "64-gon");
        let side = newell(&disk).1.sqrt() / 4.0;
        for p in &pieces {
            let diameter = p
                .iter()
                .flat_map(|a| p.iter().map(move |b| a.distance(*b)))
                .fold(0.0, f64::max);
            assert!(
                diameter <= side * 2f64.sqrt() + 1e-12,
                "piece of diameter {diameter}"
            );
        }
    }

    #[test]
    fn subdivision_tiles_and_shares_edge_points_bit_exactly() {
        let tri = [
            DVec3::ZERO,
            DVec3::new(1.0, 0.1, 0.0),
            DVec3::new(0.3, 0.9, 0.2),
        ];
        for k in 1..6 {
            let pieces = subdivide(&tri, k);
            assert_eq!(pieces.len(), k * k);
            assert_tiles(&tri, &pieces, "triangle");
        }
        // Two triangles sharing the edge b–c, which each walks in its own direction.
        let (a, b, c, d) = (
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.3, 0.1, 0.0),
            DVec3::new(0.2, 1.7, 0.0),
            DVec3::new(1.9, 1.1, 0.0),
        );
        let first = Lattice::Triangle {
            corners: [a, b, c],
            n: 7,
        };
        let second = Lattice::Triangle {
            corners: [d, c, b],
            n: 7,
        };
        for t in 0..=7 {
            // On b–c: first (i, j) = (7 − t, t); second (i, j) = (t, 7 − t).
            assert_eq!(first.point(7 - t, t), second.point(t, 7 - t));
        }
        // Quads sharing an edge the same way.
        let q1 = Lattice::Quad {
            corners: [a, b, d, c],
            nu: 5,
            nv: 3,
        };
        let q2 = Lattice::Quad {
            corners: [b, a, a - DVec3::Y, b - DVec3::Y],
            nu: 5,
            nv: 2,
        };
        for i in 0..=5 {
            assert_eq!(q1.point(i, 0), q2.point(5 - i, 0));
        }
    }

    /// The cells visited one by one are the cells of [`Lattice::cells`], corner for corner
    /// and in the same order (the meshing walks `cells`, the sources `for_each_cell`).
    #[test]
    fn visited_cells_are_the_listed_cells() {
        let lattices = [
            Lattice::Quad {
                corners: [
                    DVec3::ZERO,
                    DVec3::new(2.0, 0.1, 0.0),
                    DVec3::new(2.2, 1.3, 0.2),
                    DVec3::new(-0.1, 1.0, 0.0),
                ],
                nu: 3,
                nv: 2,
            },
            Lattice::Triangle {
                corners: [DVec3::ZERO, DVec3::X, DVec3::new(0.3, 0.8, 0.1)],
                n: 4,
            },
        ];
        for lattice in lattices {
            let listed: Vec<Vec<DVec3>> = lattice
                .cells()
                .iter()
                .map(|cell| cell.iter().map(|&(i, j)| lattice.point(i, j)).collect())
                .collect();
            let mut visited = Vec::new();
            lattice.for_each_cell(&mut |cell| visited.push(cell.to_vec()));
            assert_eq!(visited, listed);
            assert_eq!(lattice.cell_polygons(), listed);
        }
    }
}
