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

/// Orders up to which [`cached_rule`] keeps the rule.
const CACHED_ORDERS: usize = 16;

/// [`gauss_legendre`]`(n)` for `n` ≤ [`CACHED_ORDERS`], computed once per order: element
/// points are taken for every candidate link of the hierarchical solver, where the Newton
/// iterations of the rule took 3.7 % of the samples profiling the Cornell box's solve.
fn cached_rule(n: usize) -> Option<&'static [(f64, f64)]> {
    static RULES: [std::sync::OnceLock<Vec<(f64, f64)>>; CACHED_ORDERS + 1] =
        [const { std::sync::OnceLock::new() }; CACHED_ORDERS + 1];
    RULES
        .get(n)
        .map(|cell| cell.get_or_init(|| gauss_legendre(n)).as_slice())
}

/// `n × n` points with weights summing to 1 over a convex triangle or quad; `n = 1` gives
/// the centroid. A polygon of more corners (a cell along the outline of a polygon of many
/// vertices, [`crate::mesh::grid`]) by the rule on each triangle of its fan, weighted by the
/// triangle's area: exact tiling, (corners − 2)·n² points (only elements near another
/// surface get n > 1, and a polygon's vertices fall in one or two of its cells each, so
/// the points of a whole mesh stay linear in its vertex count).
pub fn element_points(corners: &[DVec3], centroid: DVec3, n: usize, out: &mut Vec<(DVec3, f64)>) {
    out.clear();
    if n <= 1 {
        out.push((centroid, 1.0));
        return;
    }
    let computed;
    let rule: &[(f64, f64)] = match cached_rule(n) {
        Some(rule) => rule,
        None => {
            computed = gauss_legendre(n);
            &computed
        }
    };
    match corners.len() {
        4 => {
            let [a, b, c, d] = [corners[0], corners[1], corners[2], corners[3]];
            let mut total = 0.0;
            for &(u, wu) in rule {
                for &(v, wv) in rule {
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
        3 => triangle_points(rule, [corners[0], corners[1], corners[2]], 1.0, out),
        _ => {
            let fan = |w: &[DVec3]| 0.5 * (w[0] - corners[0]).cross(w[1] - corners[0]).length();
            let total: f64 = corners[1..].windows(2).map(fan).sum();
            if total.is_nan() || total <= 0.0 {
                out.push((centroid, 1.0));
                return;
            }
            for w in corners[1..].windows(2) {
                triangle_points(rule, [corners[0], w[0], w[1]], fan(w) / total, out);
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
        let mut pts = Vec::new();
        let centroid = crate::formfactor::kernel::polygon_centroid(&cell);
        element_points(&cell, centroid, 3, &mut pts);
        assert_eq!(pts.len(), (cell.len() - 2) * 9);
        let sum_w: f64 = pts.iter().map(|p| p.1).sum();
        assert!((sum_w - 1.0).abs() < 1e-13);
        for (p, _) in &pts {
            assert!(p.x >= 0.0 && p.x <= 1.0 && p.y >= 0.0 && p.y <= 1.0 && p.length() <= r);
        }
        // The rule integrates linear functions exactly on each fan triangle, so the mean
        // point is the centroid to rounding.
        let mean: DVec3 = pts.iter().map(|p| p.0 * p.1).sum();
        assert!(
            (mean - centroid).length() < 1e-12,
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
