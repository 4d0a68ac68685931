//! Exact form factor between two planar convex polygons, by contour integration.
//!
//! Stokes' theorem turns the double area integral into a double contour integral
//! (Sparrow 1963; Schröder & Hanrahan 1993, "On the form factor between two polygons"):
//!
//! ```text
//! A_a F_ab = ∫_a ∫_b cosθ_a cosθ_b / (π r²) dA_b dA_a
//!          = 1/(2π) Σ_i Σ_j (â_i · b̂_j) ∫_{edge i of a} ∫_{edge j of b} ln r dt ds
//! ```
//!
//! with both contours counter-clockwise about their own normals, `â_i`, `b̂_j` the unit edge
//! directions and `s`, `t` arc length (the sign is pinned by Howell C-11 in the tests). Each
//! edge-pair integral `I_ij = ∫∫ ln r` is evaluated to rounding error by one of three methods,
//! picked by the geometry of the pair:
//!
//! * well separated edges: tensor Gauss–Legendre, `ln r` being analytic there, with the number
//!   of points set by the Bernstein-ellipse bound for the pair's separation;
//! * parallel (also collinear and overlapping) edges: closed form, as `r` depends on `s ∓ t` only;
//! * other nearby edges (shared vertices, T-junctions, crossings, skew near misses): the inner
//!   integral in closed form, the outer by Gauss–Legendre on a mesh graded towards the real parts
//!   of the complex singularities of the inner result.
//!
//! The `ln` of the length unit cancels because each contour closes (`Σ_j L_j b̂_j = 0`); the
//! polygons are first rescaled by an exact power of two so that `|ln r| = O(1)` and no term is
//! dominated by that constant, and the edge-pair terms are summed with compensation.

use glam::DVec3;
use std::f64::consts::PI;
use std::sync::OnceLock;

/// Exact unoccluded form factor `F_{a→b}` (dimensionless) from polygon `a` to polygon `b`.
///
/// The fraction of the power leaving `a` diffusely that arrives at `b`:
/// `F = (1/A_a) ∫_a ∫_b cosθ_a cosθ_b / (π r²) dA_b dA_a`, computed by the double contour
/// integral of Sparrow (1963) / Schröder & Hanrahan (1993) described in the module docs;
/// accurate to about 1e-14 absolute (the tests demand 1e-12 on exact cases).
///
/// Polygons are planar, convex and counter-clockwise seen from their front. Surfaces are
/// one-sided: only the part of `b` in front of `a`'s plane and the part of `a` in front of `b`'s
/// plane exchange energy, so each polygon is clipped against the other's plane first.
///
/// Edge cases: fewer than three vertices, zero area, coplanar polygons (within 1e-12 of the
/// pair's extent) and polygons facing away from each other give 0; a non-finite coordinate gives
/// NaN. Edges may share vertices or overlap (adjacent walls, T-junctions): those singular
/// integrals are handled exactly. Tiny negative round-off is clamped to 0. Nothing is occluded:
/// this is the form factor of the pair alone.
///
/// Cost: a few µs for two quadrilaterals whose edges are parallel, perpendicular or apart, up to
/// about 30 µs when oblique edges touch; O(n_a n_b) in the vertex counts (about 20 ms for two
/// 256-gons).
///
/// See also: Howell's catalog of configuration factors (C-11, C-14, C-41) for the cases the
/// tests compare against.
pub fn polygon_to_polygon(a: &[DVec3], b: &[DVec3]) -> f64 {
    if a.iter().chain(b).any(|p| !p.is_finite()) {
        return f64::NAN;
    }
    if a.len() < 3 || b.len() < 3 {
        return 0.0;
    }
    // Rescale by an exact power of two (form factors are scale-free) so that ln r = O(1).
    let (mut lo, mut hi) = (a[0], a[0]);
    for &p in a.iter().chain(b) {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let extent = (hi - lo).max_element();
    if extent <= 0.0 {
        return 0.0;
    }
    let scale = 2f64.powi(-(extent.log2().ceil() as i32));
    let origin = a[0];
    let a: Vec<DVec3> = a.iter().map(|&p| (p - origin) * scale).collect();
    let b: Vec<DVec3> = b.iter().map(|&p| (p - origin) * scale).collect();

    let area_vec_a = area_vector(&a);
    let area_vec_b = area_vector(&b);
    let (twice_area_a, twice_area_b) = (area_vec_a.length(), area_vec_b.length());
    if twice_area_a <= 0.0 || twice_area_b <= 0.0 {
        return 0.0;
    }
    let normal_a = area_vec_a / twice_area_a;
    let normal_b = area_vec_b / twice_area_b;

    let Some(b_front) = clip_to_front(&b, centroid(&a), normal_a) else {
        return 0.0;
    };
    let Some(a_front) = clip_to_front(&a, centroid(&b), normal_b) else {
        return 0.0;
    };

    let edges_a = edges(&a_front);
    let edges_b = edges(&b_front);
    // Many terms of alternating sign (65536 for two 256-gons): sum them with compensation.
    let mut sum = CompensatedSum::default();
    for ea in &edges_a {
        for eb in &edges_b {
            let cos = ea.dir.dot(eb.dir);
            // Perpendicular edges contribute exactly nothing.
            if cos.abs() > PERPENDICULAR_COS {
                sum.add(cos * edge_pair_log_integral(ea, eb));
            }
        }
    }
    let form_factor = sum.value() / (2.0 * PI) / (0.5 * twice_area_a);
    form_factor.max(0.0)
}

/// Vertices closer than this to the other polygon's plane count as on it (normalised units,
/// where the pair's extent is between 1/2 and 1).
const PLANE_TOL: f64 = 1e-12;
/// Edges shorter than this (normalised units) are dropped; their contribution is below round-off.
const MIN_EDGE: f64 = 1e-14;
/// `|â·b̂|` below this: the edges are perpendicular and the pair contributes nothing.
const PERPENDICULAR_COS: f64 = 1e-15;
/// `|â×b̂|` below this: the edges are treated as parallel (closed form).
const PARALLEL_SIN: f64 = 1e-12;
/// Separation / half-length above which plain tensor Gauss–Legendre is used.
const FAR_Q: f64 = 3.0;
/// In the graded outer quadrature, pieces closer than this (distance / half-length) to a
/// singularity are split.
const SPLIT_Q: f64 = 2.0;
/// Pieces shorter than this fraction of the edge are not split further (the integrand is at worst
/// `x ln x` there, so the error is of the order of the square of this).
const MIN_PIECE: f64 = 1e-7;
/// `ln(1/ε)/2` for the target relative quadrature error ε ≈ 2e-15 (per edge pair).
const HALF_LOG_INV_EPS: f64 = 17.0;
/// Largest Gauss–Legendre rule used.
const MAX_POINTS: usize = 24;

/// Neumaier's compensated summation.
#[derive(Default)]
struct CompensatedSum {
    sum: f64,
    compensation: f64,
}

impl CompensatedSum {
    fn add(&mut self, x: f64) {
        let t = self.sum + x;
        self.compensation += if self.sum.abs() >= x.abs() {
            (self.sum - t) + x
        } else {
            (x - t) + self.sum
        };
        self.sum = t;
    }

    fn value(&self) -> f64 {
        self.sum + self.compensation
    }
}

/// One directed edge: `start + s dir`, `s ∈ [0, len]`, `dir` a unit vector.
#[derive(Clone, Copy, Debug)]
struct Edge {
    start: DVec3,
    dir: DVec3,
    len: f64,
}

impl Edge {
    fn end(&self) -> DVec3 {
        self.start + self.len * self.dir
    }
}

fn edges(poly: &[DVec3]) -> Vec<Edge> {
    let n = poly.len();
    (0..n)
        .filter_map(|i| {
            let (p, q) = (poly[i], poly[(i + 1) % n]);
            let d = q - p;
            let len = d.length();
            (len > MIN_EDGE).then(|| Edge {
                start: p,
                dir: d / len,
                len,
            })
        })
        .collect()
}

/// Newell's area vector: normal times twice the area.
fn area_vector(poly: &[DVec3]) -> DVec3 {
    let n = poly.len();
    let c = poly[0];
    (1..n.saturating_sub(1))
        .map(|i| (poly[i] - c).cross(poly[i + 1] - c))
        .sum()
}

fn centroid(poly: &[DVec3]) -> DVec3 {
    poly.iter().copied().sum::<DVec3>() / poly.len() as f64
}

/// The part of the convex polygon on the front side of the plane through `origin` with unit
/// `normal` ([`crate::geometry::clip_convex`], distances within `PLANE_TOL` of the plane
/// counted as on it); `None` if nothing lies strictly in front.
fn clip_to_front(poly: &[DVec3], origin: DVec3, normal: DVec3) -> Option<Vec<DVec3>> {
    let dist = |p: &DVec3| {
        let d = normal.dot(*p - origin);
        if d.abs() <= PLANE_TOL {
            0.0
        } else {
            d
        }
    };
    if poly.iter().all(|p| dist(p) <= 0.0) {
        return None;
    }
    let mut out = Vec::with_capacity(poly.len() + 1);
    crate::geometry::clip_convex(poly, dist, &mut out);
    Some(out)
}

/// `∫_0^{e.len} ∫_0^{f.len} ln |e(s) − f(t)| dt ds`.
fn edge_pair_log_integral(e: &Edge, f: &Edge) -> f64 {
    let dist = segment_distance(e, f);
    let (q_e, q_f) = (2.0 * dist / e.len, 2.0 * dist / f.len);
    if q_e.min(q_f) >= FAR_Q {
        return tensor_gauss(e, f, points_for(q_e), points_for(q_f));
    }
    if e.dir.cross(f.dir).length() <= PARALLEL_SIN {
        return parallel_closed_form(e, f);
    }
    // The outer variable runs along the shorter edge: its singularities are then relatively
    // farther away and the graded mesh coarser.
    if e.len <= f.len {
        graded_outer(e, f)
    } else {
        graded_outer(f, e)
    }
}

/// Shortest distance between two segments (Ericson, Real-Time Collision Detection, 5.1.9).
fn segment_distance(e: &Edge, f: &Edge) -> f64 {
    let r = e.start - f.start;
    let (d1, d2) = (e.dir * e.len, f.dir * f.len);
    let (aa, ee) = (d1.length_squared(), d2.length_squared());
    let (b, c, ff) = (d1.dot(d2), d1.dot(r), d2.dot(r));
    let denom = aa * ee - b * b;
    let mut s = if denom > 0.0 {
        ((b * ff - c * ee) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (b * s + ff) / ee;
    if t < 0.0 {
        t = 0.0;
        s = (-c / aa).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / aa).clamp(0.0, 1.0);
    }
    (r + d1 * s - d2 * t).length()
}

/// Gauss–Legendre points needed on an interval whose nearest singularity lies `q` half-lengths
/// away: the error decays like `ρ^{-2n}`, `ρ = q + √(1+q²)` (Bernstein ellipse through it).
fn points_for(q: f64) -> usize {
    points_for_share(q, 1.0)
}

/// As [`points_for`], for a piece of relative size `share` of its edge (at most 1) in the graded
/// quadrature: the non-smooth part of the integrand there is at worst of order `x ln x` or `|x|`,
/// so the piece's error scales with `share²` and its target may be loosened by that.
fn points_for_share(q: f64, share: f64) -> usize {
    let rho = q + (1.0 + q * q).sqrt();
    let n = ((HALF_LOG_INV_EPS + share.ln()) / rho.ln()).ceil();
    if n.is_finite() {
        (n as usize).clamp(2, MAX_POINTS)
    } else {
        MAX_POINTS
    }
}

fn tensor_gauss(e: &Edge, f: &Edge, n_e: usize, n_f: usize) -> f64 {
    let (rule_e, rule_f) = (gauss_legendre(n_e), gauss_legendre(n_f));
    let (he, hf) = (0.5 * e.len, 0.5 * f.len);
    let mut q_pts = [DVec3::ZERO; MAX_POINTS];
    for (q, &(x, _)) in q_pts.iter_mut().zip(rule_f) {
        *q = f.start + (hf * (1.0 + x)) * f.dir;
    }
    let mut sum = 0.0;
    for &(xs, ws) in rule_e {
        let p = e.start + (he * (1.0 + xs)) * e.dir;
        let inner: f64 = q_pts
            .iter()
            .zip(rule_f)
            .map(|(&q, &(_, wt))| wt * (p - q).length_squared().ln())
            .sum();
        sum += ws * inner;
    }
    0.5 * sum * he * hf
}

/// Antiderivative in `u` of `ln √(u² + η²)`: `u ln √(u²+η²) − u + η atan(u/η)` (η ≥ 0).
fn log_antiderivative(u: f64, eta: f64) -> f64 {
    let log_term = if u == 0.0 {
        0.0
    } else {
        0.5 * u * (u * u + eta * eta).ln()
    };
    log_term - u + eta * u.atan2(eta)
}

/// Second antiderivative in `u` of `ln √(u² + h²)`:
/// `½(u² − h²) ln √(u²+h²) − ¾u² + h u atan(u/h)` (h ≥ 0).
fn log_second_antiderivative(u: f64, h: f64) -> f64 {
    let rho2 = u * u + h * h;
    let log_term = if rho2 == 0.0 {
        0.0
    } else {
        0.25 * (u * u - h * h) * rho2.ln()
    };
    log_term - 0.75 * u * u + h * u * u.atan2(h)
}

/// Parallel edges, `f.dir = σ e.dir`: with `c` the offset of `f.start` along `e` and `h` the
/// distance between the lines, `r² = (s − σt − c)² + h²`, so
/// `I = σ [G(L_e − c) − G(−c) − G(L_e − σL_f − c) + G(−σL_f − c)]`, `G'' = ln √(u² + h²)`.
fn parallel_closed_form(e: &Edge, f: &Edge) -> f64 {
    let sigma = if e.dir.dot(f.dir) >= 0.0 { 1.0 } else { -1.0 };
    let d = f.start - e.start;
    let c = d.dot(e.dir);
    let h = d.cross(e.dir).length();
    let g = |u: f64| log_second_antiderivative(u, h);
    sigma * (g(e.len - c) - g(-c) - g(e.len - sigma * f.len - c) + g(-sigma * f.len - c))
}

/// Outer integral along `e` of the closed-form inner integral along `f`.
///
/// The inner result `g(s)` is analytic except where `e(s)` meets `f` in the complex extension
/// of `s`: near the projections of `f`'s endpoints onto `e` (at a distance equal to the
/// endpoint's distance from `e`'s line) and near the point of `e`'s line closest to `f`'s line
/// (at `h / sin φ`). The outer interval is cut at their real parts and graded towards them.
fn graded_outer(e: &Edge, f: &Edge) -> f64 {
    let mut sing = [(0.0, 0.0); 3];
    for (slot, q) in sing.iter_mut().zip([f.start, f.end()]) {
        let w = q - e.start;
        *slot = (w.dot(e.dir), w.cross(e.dir).length());
    }
    let normal = e.dir.cross(f.dir);
    let sin2 = normal.length_squared();
    let w = f.start - e.start;
    let sin = sin2.sqrt();
    sing[2] = (
        w.cross(f.dir).dot(normal) / sin2,
        w.dot(normal).abs() / sin / sin,
    );
    let sing = if sing[2].0.is_finite() && sing[2].1.is_finite() {
        &sing[..]
    } else {
        &sing[..2]
    };

    let inner = |s: f64| {
        let w = e.start + s * e.dir - f.start;
        let tau = w.dot(f.dir);
        let eta = w.cross(f.dir).length();
        log_antiderivative(f.len - tau, eta) - log_antiderivative(-tau, eta)
    };

    let len = e.len;
    let snap = 1e-14 * len;
    let mut cuts = [0.0; 5];
    let mut n_cuts = 1;
    for &(c, _) in sing {
        if c > snap && c < len - snap {
            cuts[n_cuts] = c;
            n_cuts += 1;
        }
    }
    cuts[n_cuts] = len;
    n_cuts += 1;
    let cuts = &mut cuts[..n_cuts];
    cuts.sort_by(f64::total_cmp);
    let edge_half = 0.5 * len;
    cuts.windows(2)
        .map(|w| graded_piece(&inner, w[0], w[1], sing, edge_half))
        .sum()
}

/// `∫_l^r g`, splitting until each piece is at least `SPLIT_Q` half-lengths from every
/// singularity `(real part, imaginary distance)` in `sing`, or is below `MIN_PIECE` of the edge.
/// Every split shrinks the piece by at least a quarter, so the recursion ends.
fn graded_piece(
    g: &impl Fn(f64) -> f64,
    l: f64,
    r: f64,
    sing: &[(f64, f64)],
    edge_half: f64,
) -> f64 {
    let half = 0.5 * (r - l);
    if half.is_nan() || half <= 0.0 {
        return 0.0;
    }
    let mut nearest = f64::INFINITY;
    let mut nearest_re = l;
    for &(c, beta) in sing {
        let dx = if c < l {
            l - c
        } else if c > r {
            c - r
        } else {
            0.0
        };
        let d = dx.hypot(beta);
        if d < nearest {
            nearest = d;
            nearest_re = c;
        }
    }
    let q = nearest / half;
    if q >= SPLIT_Q || half <= MIN_PIECE * edge_half {
        let mid = l + half;
        return half
            * gauss_legendre(points_for_share(q, half / edge_half))
                .iter()
                .map(|&(x, w)| w * g(mid + half * x))
                .sum::<f64>();
    }
    // Split at the singularity's real part when it is well inside, else halve towards it.
    let m = if nearest_re > l + 0.25 * (r - l) && nearest_re < r - 0.25 * (r - l) {
        nearest_re
    } else {
        l + half
    };
    graded_piece(g, l, m, sing, edge_half) + graded_piece(g, m, r, sing, edge_half)
}

/// Gauss–Legendre nodes and weights on [-1, 1], `n ∈ 1..=MAX_POINTS`.
fn gauss_legendre(n: usize) -> &'static [(f64, f64)] {
    static RULES: OnceLock<Vec<Vec<(f64, f64)>>> = OnceLock::new();
    &RULES.get_or_init(|| (0..=MAX_POINTS).map(legendre_rule).collect())[n]
}

/// Legendre `P_n(x)` and `P_n'(x)` by the three-term recurrence.
fn legendre(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    for k in 2..=n {
        let k = k as f64;
        let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    let n = n as f64;
    (p1, n * (x * p1 - p0) / (x * x - 1.0))
}

fn legendre_rule(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            // Newton's method from the classical estimate of the i-th root.
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            for _ in 0..100 {
                let (p, dp) = legendre(n, x);
                let dx = p / dp;
                x -= dx;
                if dx.abs() <= 1e-16 {
                    break;
                }
            }
            let (_, dp) = legendre(n, x);
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    const REFERENCE: &str = include_str!("../../tests/reference/formfactors.json");

    fn polygon(v: &Value) -> Vec<DVec3> {
        v.as_array()
            .expect("vertex list")
            .iter()
            .map(|p| {
                let c: Vec<f64> = p
                    .as_array()
                    .expect("vertex")
                    .iter()
                    .map(|x| x.as_f64().expect("coordinate"))
                    .collect();
                DVec3::new(c[0], c[1], c[2])
            })
            .collect()
    }

    fn poly(v: &[[f64; 3]]) -> Vec<DVec3> {
        v.iter().map(|&p| DVec3::from_array(p)).collect()
    }

    fn area(p: &[DVec3]) -> f64 {
        0.5 * area_vector(p).length()
    }

    /// SplitMix64: a small seeded generator, enough for reproducible random geometry.
    struct Rng(u64);

    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }

        /// Uniform in [lo, hi).
        fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }

        fn unit_vector(&mut self) -> DVec3 {
            loop {
                let v = DVec3::new(
                    self.uniform(-1.0, 1.0),
                    self.uniform(-1.0, 1.0),
                    self.uniform(-1.0, 1.0),
                );
                let l = v.length();
                if l > 0.1 && l <= 1.0 {
                    return v / l;
                }
            }
        }

        /// A random convex triangle or quadrilateral (vertices on an ellipse), CCW about a random
        /// normal.
        fn convex_polygon(&mut self) -> Vec<DVec3> {
            let centre = DVec3::new(
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
            );
            let normal = self.unit_vector();
            let u = normal.any_orthonormal_vector();
            let v = normal.cross(u);
            let (ru, rv) = (self.uniform(0.2, 1.0), self.uniform(0.2, 1.0));
            let k = if self.next_u64() >> 63 == 0 { 3 } else { 4 };
            let mut angles: Vec<f64>;
            loop {
                angles = (0..k).map(|_| self.uniform(0.0, 2.0 * PI)).collect();
                angles.sort_by(f64::total_cmp);
                let min_gap = (0..k)
                    .map(|i| {
                        let next = if i + 1 < k {
                            angles[i + 1]
                        } else {
                            angles[0] + 2.0 * PI
                        };
                        next - angles[i]
                    })
                    .fold(f64::INFINITY, f64::min);
                if min_gap > 0.4 {
                    break;
                }
            }
            angles
                .iter()
                .map(|&t| centre + ru * t.cos() * u + rv * t.sin() * v)
                .collect()
        }
    }

    #[test]
    fn howell_catalog_polygon_pairs() {
        let reference: Value = serde_json::from_str(REFERENCE).expect("formfactors.json");
        let mut checked = 0;
        for case in reference["cases"].as_array().expect("cases") {
            // B-3 and B-8 start from a differential element (key "dA1"): not polygon pairs.
            let (Some(a1), Some(a2)) = (case.get("A1"), case.get("A2")) else {
                continue;
            };
            let (a1, a2) = (polygon(a1), polygon(a2));
            let name = format!("{} {}", case["case"], case["params"]);
            let f12 = polygon_to_polygon(&a1, &a2);
            let f21 = polygon_to_polygon(&a2, &a1);
            let e12 = (f12 - case["F12"].as_f64().expect("F12")).abs();
            let e21 = (f21 - case["F21"].as_f64().expect("F21")).abs();
            println!("{name}: F12 {f12:.15} (err {e12:.1e}), F21 {f21:.15} (err {e21:.1e})");
            // C-11 and C-14 are exact for these polygons; C-41's values are for the disks that
            // the 256-gons approximate (equal area), up to 5e-10 away; the disk-limit test below
            // shows that the polygons' own values are exact.
            let tol = if case["case"] == "C-41" { 2e-9 } else { 1e-12 };
            assert!(e12 < tol && e21 < tol, "{name}: errors {e12:e}, {e21:e}");
            checked += 1;
        }
        assert_eq!(checked, 12, "expected 4 cases each of C-11, C-14, C-41");
    }

    /// Equal-area regular n-gons converge to the disks like n⁻⁴: Richardson extrapolation from
    /// 256 and 512 sides must land on Howell C-41 (r1 = r2 = h = 1) far below the 256-gons'
    /// own 3.6e-10 offset from it.
    #[test]
    fn regular_polygons_extrapolate_to_coaxial_disks() {
        let ngon = |n: usize, z: f64, up: bool| {
            let step = 2.0 * PI / n as f64;
            let radius = (step / step.sin()).sqrt();
            let mut v: Vec<DVec3> = (0..n)
                .map(|k| {
                    let t = step * k as f64;
                    DVec3::new(radius * t.cos(), radius * t.sin(), z)
                })
                .collect();
            if !up {
                v.reverse();
            }
            v
        };
        let f = |n| polygon_to_polygon(&ngon(n, 0.0, true), &ngon(n, 1.0, false));
        let (f256, f512) = (f(256), f(512));
        let disk = (3.0 - 5f64.sqrt()) / 2.0;
        assert!((f256 - disk).abs() > 1e-10, "the 256-gons are not disks");
        let extrapolated = (16.0 * f512 - f256) / 15.0;
        assert!(
            (extrapolated - disk).abs() < 1e-13,
            "{extrapolated} vs {disk}"
        );
    }

    /// ∫∫ ln r over singular and near-singular edge pairs, against mpmath (40 digits: inner
    /// integral in closed form, outer by tanh-sinh split at the singularities; the first also by
    /// 2-D tanh-sinh).
    #[test]
    fn singular_edge_pairs_match_high_precision() {
        let edge = |start: [f64; 3], dir: [f64; 3], len: f64| Edge {
            start: DVec3::from_array(start),
            dir: DVec3::from_array(dir).normalize(),
            len,
        };
        let x_axis = edge([0.0; 3], [1.0, 0.0, 0.0], 1.0);
        let (c60, s60) = ((PI / 3.0).cos(), (PI / 3.0).sin());
        let cases = [
            // Shared vertex, 60°.
            (
                edge([0.0; 3], [c60, s60, 0.0], 0.7),
                -0.522_160_373_708_549_4,
            ),
            // T-junction: a vertex in the middle of the other edge.
            (
                edge([0.4, 0.0, 0.0], [0.6, 0.8, 0.0], 0.5),
                -0.575_585_878_473_037_1,
            ),
            // Crossing edges.
            (
                edge([0.3, -0.2, 0.0], [0.6, 0.8, 0.0], 0.6),
                -0.795_658_451_490_156_2,
            ),
            // Skew, missing by 1e-3 and by 1e-7.
            (
                edge([0.3, -0.2, 1e-3], [0.6, 0.8, 0.0], 0.6),
                -0.795_633_514_181_703_7,
            ),
            (
                edge([0.3, -0.2, 1e-7], [0.6, 0.8, 0.0], 0.6),
                -0.795_658_451_489_545_2,
            ),
            // Nearly parallel (1e-3 rad) at distance 1e-3; nearly collinear (1e-6 rad).
            (
                edge([0.1, 1e-3, 0.0], [1e-3f64.cos(), 1e-3f64.sin(), 0.0], 0.8),
                -1.258_802_140_092_634,
            ),
            (
                edge([0.2, 0.0, 0.0], [1e-6f64.cos(), 1e-6f64.sin(), 0.0], 0.5),
                -0.822_423_370_543_203_1,
            ),
            // Collinear, overlapping; and the shared edge of two adjacent polygons (exactly -3/2).
            (
                edge([0.3, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0),
                -1.257_330_005_400_625,
            ),
            (edge([1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], 1.0), -1.5),
            // Shared vertex at an obtuse angle, longer edge.
            (
                edge([0.0; 3], [2.6f64.cos(), 2.6f64.sin(), 0.0], 2.0),
                0.504_324_074_633_716_3,
            ),
            // A vertex 1e-8 from the other edge, out of plane.
            (
                edge([0.5, 1e-8, 0.0], [0.0, 0.6, 0.8], 0.3),
                -0.383_982_655_119_142_9,
            ),
            // A vertex 1e-9 from the other's endpoint.
            (
                edge([1e-9, 0.0, 0.0], [0.0, 0.6, 0.8], 1.0),
                -0.368_028_247_454_550_7,
            ),
            // Skew, 1e-3 apart near the other's end.
            (
                edge([0.999, 1e-3, 1e-3], [0.3, 0.5, 0.81], 1.0),
                -0.274_838_691_661_587_1,
            ),
        ];
        for (i, (f, expected)) in cases.iter().enumerate() {
            for value in [
                edge_pair_log_integral(&x_axis, f),
                edge_pair_log_integral(f, &x_axis),
            ] {
                assert!(
                    (value - expected).abs() < 2e-15,
                    "case {i}: {value:e} vs {expected:e}"
                );
            }
        }
    }

    #[test]
    fn reciprocity_random_polygons() {
        let mut rng = Rng(0x5EED_F0F0);
        let mut nonzero = 0;
        for _ in 0..300 {
            let (a, b) = (rng.convex_polygon(), rng.convex_polygon());
            let ab = area(&a) * polygon_to_polygon(&a, &b);
            let ba = area(&b) * polygon_to_polygon(&b, &a);
            assert!(
                (ab - ba).abs() <= 1e-9 * ab.max(ba) + 1e-15,
                "{ab:e} vs {ba:e} for {a:?} {b:?}"
            );
            nonzero += usize::from(ab > 0.0);
        }
        assert!(nonzero > 50, "only {nonzero} pairs saw each other");
    }

    #[test]
    fn reciprocity_random_touching_triangles() {
        let mut rng = Rng(7);
        let mut nonzero = 0;
        for k in 0..200 {
            let p0 = DVec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), 0.0);
            let p1 = p0 + rng.uniform(0.2, 1.0) * rng.unit_vector();
            let x = DVec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), 0.5);
            let y = DVec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), -0.5);
            let (a, b) = if k % 2 == 0 {
                // Sharing the edge p0-p1 (traversed in opposite directions).
                (vec![p0, p1, x], vec![p1, p0, y])
            } else {
                // Sharing the vertex p0 only.
                (vec![p0, p1, x], vec![p0, y, p1 + 0.3 * rng.unit_vector()])
            };
            let ab = area(&a) * polygon_to_polygon(&a, &b);
            let ba = area(&b) * polygon_to_polygon(&b, &a);
            assert!(
                (ab - ba).abs() <= 1e-9 * ab.max(ba) + 1e-15,
                "{ab:e} vs {ba:e} for {a:?} {b:?}"
            );
            nonzero += usize::from(ab > 0.0);
        }
        assert!(nonzero > 40, "only {nonzero} pairs saw each other");
    }

    #[test]
    fn additivity_when_the_receiver_is_split() {
        let mut rng = Rng(42);
        let mut nonzero = 0;
        for _ in 0..200 {
            let a = rng.convex_polygon();
            let b = rng.convex_polygon();
            // Cut b along a chord from edge 0 to edge 2 (b has 3 or 4 vertices).
            let (s, t) = (rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9));
            let m0 = b[0].lerp(b[1], s);
            let m2 = b[2].lerp(b[3 % b.len()], t);
            let b1 = vec![m0, b[1], b[2], m2];
            let mut b2 = vec![m2];
            b2.extend_from_slice(&b[3..]);
            b2.extend_from_slice(&[b[0], m0]);
            let whole = polygon_to_polygon(&a, &b);
            let parts = polygon_to_polygon(&a, &b1) + polygon_to_polygon(&a, &b2);
            assert!((whole - parts).abs() < 1e-12, "{whole:e} vs {parts:e}");
            // And the other way round: F_{b→a} A_b = F_{b1→a} A_b1 + F_{b2→a} A_b2.
            let whole = area(&b) * polygon_to_polygon(&b, &a);
            let parts =
                area(&b1) * polygon_to_polygon(&b1, &a) + area(&b2) * polygon_to_polygon(&b2, &a);
            assert!((whole - parts).abs() < 1e-12, "{whole:e} vs {parts:e}");
            nonzero += usize::from(whole > 0.0);
        }
        assert!(nonzero > 30, "only {nonzero} pairs saw each other");
    }

    #[test]
    fn independent_of_the_length_unit() {
        let mut rng = Rng(3);
        for _ in 0..100 {
            let (a, b) = (rng.convex_polygon(), rng.convex_polygon());
            let f = polygon_to_polygon(&a, &b);
            for scale in [1000.0, 1e-3, 3.7e5] {
                let sa: Vec<DVec3> = a.iter().map(|&p| p * scale).collect();
                let sb: Vec<DVec3> = b.iter().map(|&p| p * scale).collect();
                let g = polygon_to_polygon(&sa, &sb);
                assert!((f - g).abs() < 1e-13, "scale {scale}: {f:e} vs {g:e}");
            }
        }
        // Adjacent walls (singular shared edge) in millimetres.
        let a = poly(&[[0., 0., 0.], [0., 0., 1.], [1., 0., 1.], [1., 0., 0.]]);
        let b = poly(&[[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]]);
        let mm = |p: &[DVec3]| p.iter().map(|&v| v * 1000.0).collect::<Vec<_>>();
        let (f, g) = (
            polygon_to_polygon(&a, &b),
            polygon_to_polygon(&mm(&a), &mm(&b)),
        );
        assert!((f - 0.200_043_776_075_403_16).abs() < 1e-14);
        assert!((f - g).abs() < 1e-14, "{f:e} vs {g:e}");
    }

    /// The faces of the unit cube with inward normals, as in `furnace.json`, each split into
    /// `n × n` squares.
    fn cube_patches(n: usize) -> Vec<Vec<DVec3>> {
        let faces = [
            [[0., 0., 1.], [1., 0., 1.], [1., 0., 0.], [0., 0., 0.]],
            [[0., 1., 0.], [1., 1., 0.], [1., 1., 1.], [0., 1., 1.]],
            [[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]],
            [[1., 0., 1.], [1., 1., 1.], [1., 1., 0.], [1., 0., 0.]],
            [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
            [[0., 1., 1.], [1., 1., 1.], [1., 0., 1.], [0., 0., 1.]],
        ];
        let mut patches = Vec::new();
        for face in faces {
            let [p0, p1, _, p3] = face.map(DVec3::from_array);
            let (du, dv) = ((p1 - p0) / n as f64, (p3 - p0) / n as f64);
            for i in 0..n {
                for j in 0..n {
                    let o = p0 + i as f64 * du + j as f64 * dv;
                    patches.push(vec![o, o + du, o + du + dv, o + dv]);
                }
            }
        }
        patches
    }

    fn assert_closed(patches: &[Vec<DVec3>], what: &str) {
        for (i, a) in patches.iter().enumerate() {
            let row: f64 = patches.iter().map(|b| polygon_to_polygon(a, b)).sum();
            assert!((row - 1.0).abs() < 1e-12, "{what}: row {i} sums to {row}");
        }
    }

    #[test]
    fn closed_cube_rows_sum_to_one() {
        let faces = cube_patches(1);
        assert_closed(&faces, "cube");
        // Opposite and adjacent faces: Howell C-11 and C-14, as in furnace.json.
        let opposite = polygon_to_polygon(&faces[0], &faces[1]);
        let adjacent = polygon_to_polygon(&faces[0], &faces[2]);
        assert!((opposite - 0.199_824_895_698_387_46).abs() < 1e-14);
        assert!((adjacent - 0.200_043_776_075_403_16).abs() < 1e-14);
        assert_eq!(polygon_to_polygon(&faces[0], &faces[0]), 0.0);
    }

    #[test]
    fn subdivided_cube_rows_sum_to_one() {
        assert_closed(&cube_patches(2), "cube 2x2");
        // One face split, the rest whole: T-junctions along four cube edges.
        let mut mixed = cube_patches(1);
        mixed.remove(0);
        mixed.extend(cube_patches(2).into_iter().take(4));
        assert_closed(&mixed, "cube with one 2x2 face");
    }

    #[test]
    fn closed_polyhedra_with_oblique_edges_rows_sum_to_one() {
        // Octahedron, and the cube with every face cut into two triangles: edges meeting at
        // 45°, 60° and 90° at shared vertices. Faces turned to face the centre.
        let inward = |mut t: Vec<DVec3>, centre: DVec3| {
            if area_vector(&t).dot(centre - t[0]) < 0.0 {
                t.reverse();
            }
            t
        };
        let mut octahedron = Vec::new();
        for sx in [-1.0, 1.0] {
            for sy in [-1.0, 1.0] {
                for sz in [-1.0, 1.0] {
                    let t = vec![DVec3::X * sx, DVec3::Y * sy, DVec3::Z * sz];
                    octahedron.push(inward(t, DVec3::ZERO));
                }
            }
        }
        assert_closed(&octahedron, "octahedron");
        let mut triangles = Vec::new();
        for (k, q) in cube_patches(1).into_iter().enumerate() {
            let (d0, d1) = if k % 2 == 0 { (0, 2) } else { (1, 3) };
            triangles.push(vec![q[d0], q[d0 + 1], q[d1]]);
            triangles.push(vec![q[d1], q[(d1 + 1) % 4], q[d0]]);
        }
        let triangles: Vec<_> = triangles
            .into_iter()
            .map(|t| inward(t, DVec3::splat(0.5)))
            .collect();
        assert_closed(&triangles, "triangulated cube");
    }

    #[test]
    fn facing_away_or_coplanar_gives_zero() {
        let floor = poly(&[[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]]);
        // Above the floor but facing up, away from it.
        let up = poly(&[[0., 0., 1.], [1., 0., 1.], [1., 1., 1.], [0., 1., 1.]]);
        assert_eq!(polygon_to_polygon(&floor, &up), 0.0);
        assert_eq!(polygon_to_polygon(&up, &floor), 0.0);
        // Below the floor, facing it: the floor only emits upwards.
        let below = poly(&[[0., 1., -1.], [1., 1., -1.], [1., 0., -1.], [0., 0., -1.]]);
        assert_eq!(polygon_to_polygon(&floor, &below), 0.0);
        assert_eq!(polygon_to_polygon(&below, &floor), 0.0);
        // Coplanar: beside it, and overlapping it, either way up.
        let beside = poly(&[[2., 0., 0.], [3., 0., 0.], [3., 1., 0.], [2., 1., 0.]]);
        let overlap = poly(&[
            [0.5, 0.5, 0.],
            [1.5, 0.5, 0.],
            [1.5, 1.5, 0.],
            [0.5, 1.5, 0.],
        ]);
        let flipped: Vec<DVec3> = overlap.iter().rev().copied().collect();
        for b in [&beside, &overlap, &flipped] {
            assert_eq!(polygon_to_polygon(&floor, b), 0.0);
            assert_eq!(polygon_to_polygon(b, &floor), 0.0);
        }
        // Degenerate input.
        assert_eq!(polygon_to_polygon(&floor[..2], &up), 0.0);
        let mut broken = below.clone();
        broken[1].x = f64::NAN;
        assert!(polygon_to_polygon(&floor, &broken).is_nan());
        let sliver = poly(&[[0., 0., 1.], [1., 0., 1.], [2., 0., 1.]]);
        assert_eq!(polygon_to_polygon(&floor, &sliver), 0.0);
    }

    #[test]
    fn partly_behind_equals_the_clipped_part() {
        let floor = poly(&[[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]]);
        // A wall at x = 2 facing -x, reaching below the floor's plane.
        let wall = poly(&[[2., 0., -1.], [2., 0., 1.], [2., 1., 1.], [2., 1., -1.]]);
        let upper = poly(&[[2., 0., 0.], [2., 0., 1.], [2., 1., 1.], [2., 1., 0.]]);
        let f = polygon_to_polygon(&floor, &wall);
        let g = polygon_to_polygon(&floor, &upper);
        assert!(f > 0.0 && (f - g).abs() < 1e-14, "{f:e} vs {g:e}");
        // The wall's lower half sees only the floor's back: F_wall→floor is half that of the
        // upper half alone.
        let f = polygon_to_polygon(&wall, &floor);
        let g = polygon_to_polygon(&upper, &floor);
        assert!((2.0 * f - g).abs() < 1e-14, "{f:e} vs {g:e}");
        // A tilted receiver crossing the floor's plane, and both clipped at once.
        // (Listed clockwise, then reversed so that it faces -y, towards the floor.)
        let mut tilted = poly(&[
            [0.2, 1.5, -0.5],
            [0.2, 1.2, 0.7],
            [0.9, 1.1, 0.8],
            [0.9, 1.4, -0.4],
        ]);
        let mut clipped = vec![
            tilted[0].lerp(tilted[1], 0.5 / 1.2),
            tilted[1],
            tilted[2],
            tilted[3].lerp(tilted[2], 0.4 / 1.2),
        ];
        tilted.reverse();
        clipped.reverse();
        let f = polygon_to_polygon(&floor, &tilted);
        let g = polygon_to_polygon(&floor, &clipped);
        assert!(f > 0.0 && (f - g).abs() < 1e-14, "{f:e} vs {g:e}");
        let f = area(&tilted) * polygon_to_polygon(&tilted, &floor);
        let g = area(&clipped) * polygon_to_polygon(&clipped, &floor);
        assert!((f - g).abs() < 1e-14, "{f:e} vs {g:e}");
    }

    #[test]
    fn gauss_legendre_rules_integrate_polynomials_exactly() {
        for n in 1..=MAX_POINTS {
            let rule = gauss_legendre(n);
            for k in 0..2 * n {
                let approx: f64 = rule.iter().map(|&(x, w)| w * x.powi(k as i32)).sum();
                let exact = if k % 2 == 0 {
                    2.0 / (k as f64 + 1.0)
                } else {
                    0.0
                };
                assert!((approx - exact).abs() < 1e-14, "n {n}, x^{k}: {approx}");
            }
        }
    }
}
