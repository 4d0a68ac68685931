//! Quadrature rules over elements: Gauss–Legendre on quads (through the bilinear map) and
//! on triangles (through the collapsed-square Duffy map), weights normalised to sum to 1.

use glam::DVec3;

/// Gauss–Legendre nodes and weights on [0, 1] (Newton iteration on P_n).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let pn = if n == 0 { 1.0 } else { p1 };
            let pn1 = if n <= 1 { 1.0 } else { p0 };
            dp = n as f64 * (x * pn - pn1) / (x * x - 1.0);
            let dx = pn / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push((0.5 * (1.0 - x), 0.5 * w));
    }
    out
}

/// `n × n` points with weights summing to 1 over a convex triangle or quad; `n = 1` gives
/// the centroid. A polygon of more corners (a cell along the outline of a polygon of many
/// vertices, [`crate::mesh::grid`]) is integrated over the fan of at most eight of its
/// corners ([`key_corners`]), `n × n` points per fan triangle weighted by its area.
pub fn element_points(corners: &[DVec3], centroid: DVec3, n: usize, out: &mut Vec<(DVec3, f64)>) {
    out.clear();
    if n <= 1 {
        out.push((centroid, 1.0));
        return;
    }
    let rule = gauss_legendre(n);
    match corners.len() {
        4 => {
            let [a, b, c, d] = [corners[0], corners[1], corners[2], corners[3]];
            let mut total = 0.0;
            for &(u, wu) in &rule {
                for &(v, wv) in &rule {
                    let p = (1.0 - u) * (1.0 - v) * a
                        + u * (1.0 - v) * b
                        + u * v * c
                        + (1.0 - u) * v * d;
                    let du = (1.0 - v) * (b - a) + v * (c - d);
                    let dv = (1.0 - u) * (d - a) + u * (c - b);
                    let w = wu * wv * du.cross(dv).length();
                    total += w;
                    out.push((p, w));
                }
            }
            out.iter_mut().for_each(|(_, w)| *w /= total);
        }
        3 => triangle_points(&rule, [corners[0], corners[1], corners[2]], 1.0, out),
        _ => {
            let key = key_corners(corners);
            let fan = |w: &[DVec3]| 0.5 * (w[0] - key[0]).cross(w[1] - key[0]).length();
            let total: f64 = key[1..].windows(2).map(fan).sum();
            if total.is_nan() || total <= 0.0 {
                out.push((centroid, 1.0));
                return;
            }
            for w in key[1..].windows(2) {
                triangle_points(&rule, [key[0], w[0], w[1]], fan(w) / total, out);
            }
        }
    }
}

/// The Gauss rule over the triangle (a, b, c), weights summing to `share`: the collapsed
/// square p = a + u (b − a) + u v (c − b), Jacobian ∝ u.
fn triangle_points(
    rule: &[(f64, f64)],
    [a, b, c]: [DVec3; 3],
    share: f64,
    out: &mut Vec<(DVec3, f64)>,
) {
    for &(u, wu) in rule {
        for &(v, wv) in rule {
            out.push((a + u * (b - a) + u * v * (c - b), share * 2.0 * wu * wv * u));
        }
    }
}

/// At most eight corners of a convex polygon that outline it: its sharp corners (turning by
/// more than 0.2 rad; the six sharpest), and, where fewer than three are sharp (a cell cut by
/// a smooth outline, or a whole small disc), six corners evenly spaced along the loop too.
/// The fan of these lies inside the polygon and misses only the thin strips between the
/// polygon's smooth arcs and their chords. O(n) for n corners.
pub fn key_corners(corners: &[DVec3]) -> Vec<DVec3> {
    const KEEP: usize = 6;
    let n = corners.len();
    if n <= KEEP {
        return corners.to_vec();
    }
    let turn = |i: usize| {
        let (a, b, c) = (corners[(i + n - 1) % n], corners[i], corners[(i + 1) % n]);
        let (d1, d2) = (b - a, c - b);
        d1.cross(d2).length().atan2(d1.dot(d2))
    };
    let mut sharp: Vec<(f64, usize)> = (0..n)
        .map(|i| (turn(i), i))
        .filter(|&(t, _)| t > 0.2)
        .collect();
    if sharp.len() > KEEP {
        sharp.select_nth_unstable_by(KEEP - 1, |a, b| b.0.total_cmp(&a.0));
        sharp.truncate(KEEP);
    }
    let mut keep: Vec<usize> = sharp.iter().map(|&(_, i)| i).collect();
    if keep.len() < 3 {
        keep.extend((0..KEEP).map(|k| k * n / KEEP));
    }
    keep.sort_unstable();
    keep.dedup();
    keep.iter().map(|&i| corners[i]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        for n in 1..=8 {
            let rule = gauss_legendre(n);
            for k in 0..(2 * n) {
                let s: f64 = rule.iter().map(|(x, w)| w * x.powi(k as i32)).sum();
                assert!((s - 1.0 / (k as f64 + 1.0)).abs() < 1e-13, "n={n} k={k}");
            }
        }
    }

    #[test]
    fn many_cornered_cells_get_points_inside_with_their_centroid() {
        // The unit square cell [0, 1]² clipped by a disc of radius 1.2 about the origin drawn
        // with 400 corners on the arc: a cell on the outline of a disc.
        let r: f64 = 1.2;
        let h = (r * r - 1.0).sqrt();
        let (a0, a1) = (h.atan2(1.0), 1f64.atan2(h));
        let mut cell = vec![DVec3::ZERO, DVec3::X];
        for k in 0..=400 {
            let a = a0 + (a1 - a0) * k as f64 / 400.0;
            cell.push(DVec3::new(r * a.cos(), r * a.sin(), 0.0));
        }
        cell.push(DVec3::Y);
        let key = key_corners(&cell);
        assert_eq!(key.len(), 5, "the cell's five sharp corners");
        let mut pts = Vec::new();
        let centroid = crate::formfactor::kernel::polygon_centroid(&cell);
        element_points(&cell, centroid, 3, &mut pts);
        assert_eq!(pts.len(), 3 * 9);
        let sum_w: f64 = pts.iter().map(|p| p.1).sum();
        assert!((sum_w - 1.0).abs() < 1e-13);
        for (p, _) in &pts {
            assert!(p.x >= 0.0 && p.x <= 1.0 && p.y >= 0.0 && p.y <= 1.0 && p.length() <= r);
        }
        // The fan misses only the circular segment between the arc and its chord,
        // r²/2 (θ − sin θ) = 0.0077 m² of the cell's 0.96 m² (θ = 0.399 rad): the mean point
        // moves by that fraction (0.8 %) of the distance between the two parts' centroids
        // (< 1 m), so by less than 0.01 m.
        let mean: DVec3 = pts.iter().map(|p| p.0 * p.1).sum();
        assert!(
            (mean - centroid).length() < 0.01,
            "{mean} against {centroid}"
        );
    }

    #[test]
    fn triangle_rule_gives_centroid() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let mut pts = Vec::new();
        element_points(&t, DVec3::new(1.0 / 3.0, 1.0 / 3.0, 0.0), 4, &mut pts);
        let sum_w: f64 = pts.iter().map(|p| p.1).sum();
        let mean: DVec3 = pts.iter().map(|p| p.0 * p.1).sum();
        assert!((sum_w - 1.0).abs() < 1e-13);
        assert!((mean - DVec3::new(1.0 / 3.0, 1.0 / 3.0, 0.0)).length() < 1e-13);
    }
}
