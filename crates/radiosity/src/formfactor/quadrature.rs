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
/// the centroid.
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
        _ => {
            // Triangle (a, b, c): p = a + u (b − a) + u v (c − b), Jacobian ∝ u.
            let [a, b, c] = [corners[0], corners[1], corners[2]];
            for &(u, wu) in &rule {
                for &(v, wv) in &rule {
                    out.push((a + u * (b - a) + u * v * (c - b), 2.0 * wu * wv * u));
                }
            }
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
