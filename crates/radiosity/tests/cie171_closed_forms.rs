//! The CIE 171:2006 references proven before the engine is tested against them. For every case
//! under tests/cie171/, the closed forms of tests/common/cie171.rs are checked against
//! (a) the shared reference values (expected.json, copied from ../shared/reference/cie171) to
//! 1e-9 and the published tables within their rounding, and (b) independent estimates made
//! here: stratified Monte Carlo over the emitters with ray–polygon visibility, the aligned-
//! rectangle catalogue formulas, small-patch solid angles for point sources, isotropic
//! direction sampling for flux conservation and photon tracing in the closed cubes.

mod common;

use common::cie171::*;
use glam::DVec3;
use serde_json::Value;
use std::f64::consts::PI;

/// SplitMix64 (Steele, Lea & Flood 2014): a small, seedable generator, so that the Monte Carlo
/// estimates here share no code with the engine's sampling.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

fn cases() -> Vec<Case> {
    all_cases().unwrap_or_else(|e| panic!("loading the CIE 171 cases: {e}"))
}

fn geometry(case: &Case) -> Geometry {
    load_geometry(case).unwrap_or_else(|e| panic!("{e}"))
}

fn expected_json(case: &Case) -> Option<Value> {
    let path = case.dir.join("expected.json");
    let text = std::fs::read_to_string(&path).ok()?;
    Some(serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

fn vec3(v: &Value) -> DVec3 {
    DVec3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

fn rel_diff(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / a.abs().max(b.abs())
    }
}

/// Whether `q` (on the polygon's plane) lies inside the convex polygon, within `eps` m.
fn inside_convex(poly: &[DVec3], q: DVec3, eps: f64) -> bool {
    let m = polygon_normal(poly);
    (0..poly.len()).all(|i| {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        (b - a).cross(q - a).dot(m) >= -eps * (b - a).length()
    })
}

/// Whether the open segment from `a` to `b` crosses any of the polygons.
fn segment_blocked(a: DVec3, b: DVec3, polygons: &[Vec<DVec3>]) -> bool {
    polygons.iter().any(|poly| {
        let m = polygon_normal(poly);
        let (da, db) = ((a - poly[0]).dot(m), (b - poly[0]).dot(m));
        if da * db >= 0.0 {
            return false;
        }
        let q = a + (b - a) * (da / (da - db));
        inside_convex(poly, q, 0.0)
    })
}

/// The nearest front-or-back hit of the ray x + t d (t > 1e-9) with the polygons:
/// (index, t).
fn nearest_hit(x: DVec3, d: DVec3, objects: &[Object]) -> Option<(usize, f64)> {
    let mut best: Option<(usize, f64)> = None;
    for (i, o) in objects.iter().enumerate() {
        let m = o.normal();
        let denom = d.dot(m);
        if denom == 0.0 {
            continue;
        }
        let t = (o.vertices[0] - x).dot(m) / denom;
        if t <= 1e-9 || best.is_some_and(|(_, bt)| t >= bt) {
            continue;
        }
        if inside_convex(&o.vertices, x + d * t, 1e-12) {
            best = Some((i, t));
        }
    }
    best
}

/// A cosine-weighted direction about the unit normal `n` (Malley's method).
fn cosine_direction(n: DVec3, rng: &mut SplitMix64) -> DVec3 {
    let (r, phi) = (rng.uniform().sqrt(), 2.0 * PI * rng.uniform());
    let (u, v) = n.any_orthonormal_pair();
    (u * (r * phi.cos()) + v * (r * phi.sin()) + n * (1.0 - r * r).max(0.0).sqrt()).normalize()
}

/// A uniform direction on the sphere.
fn sphere_direction(rng: &mut SplitMix64) -> DVec3 {
    let z = 1.0 - 2.0 * rng.uniform();
    let (r, phi) = ((1.0 - z * z).max(0.0).sqrt(), 2.0 * PI * rng.uniform());
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Mean and standard error of replicate estimates.
fn mean_stderr(reps: &[f64]) -> (f64, f64) {
    let n = reps.len() as f64;
    let mean = reps.iter().sum::<f64>() / n;
    let var = reps.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Stratified Monte Carlo estimate of the irradiance at `x` (normal `n`) from a Lambertian
/// emitter polygon of radiance `radiance`, with ray–polygon visibility against `occluders`:
/// E = ∫ L cosθ cosθ' / r² V dA over each fan triangle, k × k jittered strata per triangle
/// (uniform triangle sampling by the square-root map), `replicates` independent replicates.
/// Returns (mean, standard error), W·m⁻².
fn emitter_monte_carlo(
    (x, n): (DVec3, DVec3),
    emitter: &[DVec3],
    radiance: f64,
    occluders: &[Vec<DVec3>],
    (k, replicates): (usize, usize),
    rng: &mut SplitMix64,
) -> (f64, f64) {
    let m = polygon_normal(emitter);
    let reps: Vec<f64> = (0..replicates)
        .map(|_| {
            let mut e = 0.0;
            for t in 1..emitter.len() - 1 {
                let (a, b, c) = (emitter[0], emitter[t], emitter[t + 1]);
                let area = 0.5 * (b - a).cross(c - a).length();
                let mut sum = 0.0;
                for i in 0..k {
                    for j in 0..k {
                        let u = (i as f64 + rng.uniform()) / k as f64;
                        let v = (j as f64 + rng.uniform()) / k as f64;
                        let s = u.sqrt();
                        let p = a * (1.0 - s) + b * (s * (1.0 - v)) + c * (s * v);
                        let d = p - x;
                        let r2 = d.length_squared();
                        let (cx, ce) = (n.dot(d), -m.dot(d));
                        if cx <= 0.0 || ce <= 0.0 || segment_blocked(x, p, occluders) {
                            continue;
                        }
                        sum += cx * ce / (r2 * r2);
                    }
                }
                e += radiance * area * sum / (k * k) as f64;
            }
            e
        })
        .collect();
    mean_stderr(&reps)
}

/// The emitters of an area-source case and, for the Monte Carlo visibility, every other
/// polygon of the scene (not only the declared occluder: this also proves that nothing else
/// shadows the points, which the closed form assumes).
fn area_case_parts(case: &Case, g: &Geometry) -> Option<(Vec<Object>, Vec<Vec<DVec3>>)> {
    let ClosedForm::AreaSourceContour { emitters, .. } = &case.closed_form else {
        return None;
    };
    let em = emitters
        .iter()
        .map(|e| g.object(e).unwrap().clone())
        .collect();
    let others = g
        .objects
        .iter()
        .filter(|o| !emitters.contains(&o.name))
        .map(|o| o.vertices.clone())
        .collect();
    Some((em, others))
}

/// The vertices of a case's declared occluder group (empty if none).
fn declared_occluder(case: &Case, g: &Geometry) -> Vec<DVec3> {
    match &case.closed_form {
        ClosedForm::AreaSourceContour {
            occluder: Some(o), ..
        } => g.group(o).iter().flat_map(|o| o.vertices.clone()).collect(),
        _ => Vec::new(),
    }
}

#[test]
fn every_case_loads_with_points_on_their_objects() {
    let cases = cases();
    // 4 shared + cie52, cie54, cie57, 12 point cubes, 11 more panel cubes, 4 extensions.
    assert_eq!(
        cases.len(),
        34,
        "cases: {:?}",
        cases.iter().map(|c| &c.id).collect::<Vec<_>>()
    );
    for case in &cases {
        let g = geometry(case);
        assert!(
            !case.points.is_empty() || !case.groups.is_empty(),
            "{}: nothing to test",
            case.id
        );
        for p in &case.points {
            let o = g.object(&p.object).unwrap();
            let (x, n) = (DVec3::from(p.position), DVec3::from(p.normal));
            let dist = (x - o.vertices[0]).dot(o.normal());
            assert!(
                dist.abs() < 1e-12,
                "{} {}: {dist} m off {}",
                case.id,
                p.id,
                o.name
            );
            assert!(
                inside_convex(&o.vertices, x, 1e-12),
                "{} {}: outside {}",
                case.id,
                p.id,
                o.name
            );
            assert!(
                (n - o.normal()).length() < 1e-12,
                "{} {}: normal differs from {}'s",
                case.id,
                p.id,
                o.name
            );
        }
        // The features a case declares are the ones its closed form uses.
        let req = |f| case.requires.contains(&f);
        assert_eq!(
            req(Feature::PointLights),
            !case.point_lights.is_empty(),
            "{}",
            case.id
        );
        assert_eq!(
            req(Feature::AreaEmitters),
            g.emitted_power() > 0.0,
            "{}",
            case.id
        );
        let occluded = matches!(
            &case.closed_form,
            ClosedForm::AreaSourceContour {
                occluder: Some(_),
                ..
            }
        );
        assert_eq!(req(Feature::Occlusion), occluded, "{}", case.id);
        if matches!(case.closed_form, ClosedForm::ClosedCubeInterreflection) {
            assert!(req(Feature::Interreflection), "{}", case.id);
            assert!(
                (g.total_area() - 96.0).abs() < 1e-12,
                "{}: S_T = {}",
                case.id,
                g.total_area()
            );
        }
        assert!(
            case.tolerance.relative <= 0.01,
            "{}: the lead's criterion is 1 %",
            case.id
        );
    }
}

#[test]
fn closed_forms_reproduce_the_shared_reference_values() {
    let mut compared = 0;
    for case in cases() {
        let Some(reference) = expected_json(&case) else {
            continue;
        };
        let g = geometry(&case);
        let exp = expectations(&case).unwrap();
        for p in reference["points"].as_array().unwrap() {
            if p["exact"] != Value::Bool(true) {
                continue;
            }
            let id = p["id"].as_str().unwrap();
            let ours = exp.points.iter().find(|q| q.id == id).unwrap();
            assert_eq!(ours.position, vec3(&p["position"]), "{} {id}", case.id);
            assert_eq!(ours.normal, vec3(&p["normal"]), "{} {id}", case.id);
            let want = p["irradiance"].as_f64().unwrap();
            // Both are exact closed forms evaluated in double precision: 1e-9.
            assert!(
                rel_diff(ours.irradiance, want) < 1e-9,
                "{} {id}: {} vs {want}",
                case.id,
                ours.irradiance
            );
            compared += 1;
        }
        for s in reference["surfaces"].as_array().unwrap() {
            let name = s["object"].as_str().unwrap();
            if s["exact"] != Value::Bool(true) || g.object(name).unwrap().emitted_radiance > 0.0 {
                continue;
            }
            let want = s["irradiance"].as_f64().unwrap();
            let ours =
                closed_form_group_mean(&case, &g, &[name.to_string()], GROUP_PANELS, GROUP_ORDER)
                    .unwrap();
            // The shared means are exact (rectangle-to-rectangle factors, solid angles); ours are
            // converged quadratures of the exact point value (≲ 1e-11, see
            // group_means_are_converged) or exact: 1e-9, or 1e-12 W/m² for zeros.
            assert!(
                rel_diff(ours, want) < 1e-9 || (ours - want).abs() < 1e-12,
                "{} surface {name}: {ours} vs {want}",
                case.id
            );
            compared += 1;
        }
        for grp in reference["groups"].as_array().into_iter().flatten() {
            let objects: Vec<String> = grp["objects"]
                .as_array()
                .unwrap()
                .iter()
                .map(|o| o.as_str().unwrap().to_string())
                .collect();
            let ours =
                closed_form_group_mean(&case, &g, &objects, GROUP_PANELS, GROUP_ORDER).unwrap();
            let want = grp["irradiance"].as_f64().unwrap();
            assert!(
                rel_diff(ours, want) < 1e-9,
                "{} group {}: {ours} vs {want}",
                case.id,
                grp["group"]
            );
            compared += 1;
        }
    }
    // The shared cube's reflectance variants against the panel cubes of every CIE reflectance.
    let all = cases();
    let shared = all.iter().find(|c| c.id == "cie58_cube_rho050").unwrap();
    for v in expected_json(shared).unwrap()["reflectance_variants"]
        .as_array()
        .unwrap()
    {
        let rho = v["reflectance"].as_f64().unwrap();
        let id = format!("cie58_cube_rho{:03}", (rho * 100.0).round() as u32);
        let case = all
            .iter()
            .find(|c| c.id == id)
            .unwrap_or_else(|| panic!("no case {id}"));
        let g = geometry(case);
        assert_eq!(g.objects[0].reflectance, rho, "{id}");
        for grp in expectations(case).unwrap().groups {
            let want = v["face_group_irradiance"].as_f64().unwrap();
            assert!(
                rel_diff(grp.irradiance, want) < 1e-9,
                "{id} {}: {} vs {want}",
                grp.id,
                grp.irradiance
            );
            compared += 1;
        }
    }
    // 5.3: 14 points + 9 surfaces; 5.6: 13 + 2; cube: 6 groups; 5.2: 10 + 1; 12 ρ × 6 faces.
    assert_eq!(compared, 23 + 15 + 6 + 11 + 72);
}

#[test]
fn closed_forms_agree_with_published_tables() {
    let mut checked = 0;
    for case in cases() {
        let g = geometry(&case);
        let exp = expectations(&case).unwrap();
        for (p, e) in case.points.iter().zip(&exp.points) {
            if let Some(c) = &p.crosscheck {
                assert!(
                    c.agrees(e.irradiance),
                    "{} {}: closed form {} vs {} ({})",
                    case.id,
                    p.id,
                    e.irradiance,
                    c.value,
                    c.source
                );
                checked += 1;
            }
        }
        let direct = (case.point_light_power() + g.emitted_power()) / g.total_area();
        for (spec, e) in case.groups.iter().zip(&exp.groups) {
            if let Some(c) = &spec.crosscheck {
                let ours = match c.quantity.as_deref() {
                    Some("reflected_part") => e.irradiance - direct,
                    None => e.irradiance,
                    Some(q) => panic!("{}: unknown cross-check quantity {q}", case.id),
                };
                assert!(
                    c.agrees(ours),
                    "{} {}: closed form {ours} vs {} ({})",
                    case.id,
                    spec.id,
                    c.value,
                    c.source
                );
                checked += 1;
            }
        }
    }
    // Table 11 (10), Table 12 (14), Table 17 (13), corrected Table 19 (11), Table 20 (66),
    // the 5.4 mean (1).
    assert_eq!(checked, 115);
}

#[test]
fn area_sources_agree_with_stratified_monte_carlo() {
    let mut rng = SplitMix64(171);
    let mut checked = 0;
    for case in cases() {
        let g = geometry(&case);
        let Some((emitters, occluders)) = area_case_parts(&case, &g) else {
            continue;
        };
        let exp = expectations(&case).unwrap();
        for p in &exp.points {
            let (mut mc, mut var) = (0.0, 0.0);
            for em in &emitters {
                if (p.position - em.vertices[0]).dot(em.normal()) <= 0.0 {
                    continue;
                }
                let (m, s) = emitter_monte_carlo(
                    (p.position, p.normal),
                    &em.vertices,
                    em.emitted_radiance,
                    &occluders,
                    (32, 32),
                    &mut rng,
                );
                mc += m;
                var += s * s;
            }
            let stderr = var.sqrt();
            // 32 replicates: |t| > 5 with 31 degrees of freedom has probability ~2e-5 per point;
            // the seed is fixed. 1e-12 W/m² covers the points where both are exactly 0.
            assert!(
                (mc - p.irradiance).abs() <= 5.0 * stderr + 1e-12 * (1.0 + p.irradiance),
                "{} {}: closed form {} vs Monte Carlo {mc} ± {stderr}",
                case.id,
                p.id,
                p.irradiance
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 14 + 13 + 13 + 11 + 13 + 23, "points checked");
}

#[test]
fn contour_formula_matches_aligned_rectangle_catalogue() {
    let mut checked = 0;
    for case in cases() {
        let g = geometry(&case);
        let Some((emitters, _)) = area_case_parts(&case, &g) else {
            continue;
        };
        if !declared_occluder(&case, &g).is_empty() {
            continue;
        }
        for p in &case.points {
            let (x, n) = (DVec3::from(p.position), DVec3::from(p.normal));
            for em in &emitters {
                let Some(cat) = aligned_rectangle_form_factor(x, n, &em.vertices) else {
                    continue;
                };
                let contour = point_to_polygon_form_factor(x, n, &em.vertices);
                // Two exact formulas in double precision (F ≤ 1): 1e-12.
                assert!(
                    (cat - contour).abs() < 1e-12,
                    "{} {} {}: catalogue {cat} vs contour {contour}",
                    case.id,
                    p.id,
                    em.name
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 60, "{checked}");
}

#[test]
fn contour_formula_clips_at_the_horizon() {
    // A wall rectangle straddling the tangent plane of a floor point: the catalogue formula
    // cuts it at the horizon by construction; the contour formula must clip it.
    let x = DVec3::new(0.3, 0.2, 0.0);
    let n = DVec3::Z;
    let rect = [
        DVec3::new(-1.0, 2.0, -1.5),
        DVec3::new(-1.0, 2.0, 2.0),
        DVec3::new(1.5, 2.0, 2.0),
        DVec3::new(1.5, 2.0, -1.5),
    ];
    let cat = aligned_rectangle_form_factor(x, n, &rect).unwrap();
    let contour = point_to_polygon_form_factor(x, n, &rect);
    assert!(
        cat > 0.01 && (cat - contour).abs() < 1e-12,
        "{cat} vs {contour}"
    );
    // And a tilted triangle against Monte Carlo (the catalogue has no formula for it).
    let tri = [
        DVec3::new(-1.0, 1.0, -0.5),
        DVec3::new(1.0, 1.5, 1.5),
        DVec3::new(0.5, 2.5, 0.8),
    ];
    let f = point_to_polygon_form_factor(x, n, &tri);
    let m = polygon_normal(&tri);
    let facing = if (x - tri[0]).dot(m) > 0.0 {
        tri.to_vec()
    } else {
        tri.iter().rev().copied().collect()
    };
    let (mc, se) =
        emitter_monte_carlo((x, n), &facing, 1.0 / PI, &[], (64, 32), &mut SplitMix64(5));
    assert!(f > 0.01 && (mc - f).abs() <= 5.0 * se, "{f} vs {mc} ± {se}");
}

#[test]
fn occlusion_shadow_classes_are_as_declared() {
    let mut checked = 0;
    for case in cases() {
        let g = geometry(&case);
        let Some((emitters, _)) = area_case_parts(&case, &g) else {
            continue;
        };
        let occ = declared_occluder(&case, &g);
        for p in &case.points {
            let Some(shadow) = p.shadow else { continue };
            let (x, n) = (DVec3::from(p.position), DVec3::from(p.normal));
            let (mut full, mut visible) = (0.0, 0.0);
            for em in &emitters {
                full += point_to_polygon_form_factor(x, n, &em.vertices);
                visible += visible_form_factor(x, n, &em.vertices, &occ).unwrap();
            }
            let class = if visible <= 1e-12 * full {
                Shadow::Umbra
            } else if visible >= full * (1.0 - 1e-12) {
                Shadow::Full
            } else {
                Shadow::Penumbra
            };
            assert_eq!(
                class, shadow,
                "{} {}: visible {visible} of {full}",
                case.id, p.id
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 24);
}

/// Sides of a small square patch centred on `x`, perpendicular to `n`, of side `s`.
fn patch(x: DVec3, n: DVec3, s: f64) -> [DVec3; 4] {
    let (u, v) = n.any_orthonormal_pair();
    let h = 0.5 * s;
    [
        x - u * h - v * h,
        x + u * h - v * h,
        x + u * h + v * h,
        x - u * h + v * h,
    ]
}

#[test]
fn point_sources_agree_with_small_patch_solid_angles() {
    let mut checked = 0;
    for case in cases() {
        if !matches!(
            case.closed_form,
            ClosedForm::PointSource | ClosedForm::FluxConservation
        ) {
            continue;
        }
        let g = geometry(&case);
        for p in expectations(&case).unwrap().points {
            // Flux through a patch of side s = 1e-4 d centred on the point, divided by its area:
            // I Ω (Van Oosterom–Strackee) for isotropic lights, I₀ π F(light → patch) for cosine
            // ones. The patch mean differs from the point value by O((s/d)²) = 1e-8.
            let mut est = 0.0;
            for light in &case.point_lights {
                // The closed form assumes nothing shadows the point: check it.
                let others: Vec<Vec<DVec3>> =
                    g.objects.iter().map(|o| o.vertices.clone()).collect();
                assert!(
                    !segment_blocked(light.position(), p.position, &others),
                    "{} {}: shadowed",
                    case.id,
                    p.id
                );
                let d = (light.position() - p.position).length();
                let s = 1e-4 * d;
                let mut q = patch(p.position, p.normal, s);
                if polygon_normal(&q).dot(p.normal) < 0.0 {
                    q.reverse();
                }
                est += point_light_flux_on_polygon(light, &q) / (s * s);
            }
            assert!(
                rel_diff(est, p.irradiance) < 1e-6,
                "{} {}: {} vs patch {est}",
                case.id,
                p.id,
                p.irradiance
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 10 + 10 + 16 + 16);
}

#[test]
fn point_source_group_means_agree_with_quadrature() {
    let mut checked = 0;
    for case in cases() {
        if !matches!(
            case.closed_form,
            ClosedForm::PointSource | ClosedForm::FluxConservation
        ) {
            continue;
        }
        let g = geometry(&case);
        for grp in expectations(&case).unwrap().groups {
            let mut weighted = 0.0;
            for name in &grp.objects {
                let o = g.object(name).unwrap();
                let n = o.normal();
                let mean = polygon_mean(&o.vertices, 64, 10, &mut |x| {
                    case.point_lights
                        .iter()
                        .map(|l| point_light_irradiance(l, x, n))
                        .sum()
                });
                weighted += mean * o.area();
            }
            let quad = weighted / grp.area;
            // The exact mean I Ω / A against a 409 600-point Gauss–Legendre quadrature of the
            // point values (the sharpest peak, 0.25 m from a wall, is resolved by 0.06 m panels).
            assert!(
                rel_diff(quad, grp.irradiance) < 1e-9,
                "{} {}: exact {} vs quadrature {quad}",
                case.id,
                grp.id,
                grp.irradiance
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 1 + 1 + 6 + 7);
}

#[test]
fn flux_is_conserved_and_matches_direction_sampling() {
    for case in cases() {
        if !matches!(case.closed_form, ClosedForm::FluxConservation) {
            continue;
        }
        let g = geometry(&case);
        let phi = case.point_light_power();
        // Σ I Ω_i = 4π I: the six solid angles of a closed room from an inside point.
        let flux: f64 = g
            .objects
            .iter()
            .flat_map(|o| {
                case.point_lights
                    .iter()
                    .map(|l| point_light_flux_on_polygon(l, &o.vertices))
            })
            .sum();
        assert!(
            rel_diff(flux, phi) < 1e-12,
            "{}: received {flux} of {phi}",
            case.id
        );
        // Each face's share against isotropic direction sampling (binomial standard error).
        let light = &case.point_lights[0];
        let mut rng = SplitMix64(54);
        let samples = 1 << 20;
        let mut hits = vec![0u64; g.objects.len()];
        for _ in 0..samples {
            let (i, _) = nearest_hit(light.position(), sphere_direction(&mut rng), &g.objects)
                .expect("closed room");
            hits[i] += 1;
        }
        let exp = expectations(&case).unwrap();
        for grp in exp.groups.iter().filter(|gr| gr.objects.len() == 1) {
            let i = g
                .objects
                .iter()
                .position(|o| o.name == grp.objects[0])
                .unwrap();
            let p = hits[i] as f64 / samples as f64;
            let (mc, se) = (
                phi * p / grp.area,
                phi / grp.area * (p * (1.0 - p) / samples as f64).sqrt(),
            );
            assert!(
                (mc - grp.irradiance).abs() <= 5.0 * se,
                "{} {}: {} vs {mc} ± {se}",
                case.id,
                grp.id,
                grp.irradiance
            );
        }
        let all = exp
            .groups
            .iter()
            .find(|gr| gr.id == "all_surfaces")
            .unwrap();
        assert!(
            rel_diff(all.irradiance, phi / g.total_area()) < 1e-12,
            "{}",
            case.id
        );
    }
}

/// Photon tracing in a closed scene: `photons` photons from the point lights and area
/// emitters (chosen by power), diffuse reflection with Russian roulette (survival ρ), every
/// incidence tallied per group of object indices. Returns per group the mean incident flux,
/// W, and its standard error (from the per-photon Σ count and Σ count²).
fn photon_trace(
    case: &Case,
    g: &Geometry,
    groups: &[Vec<usize>],
    photons: usize,
    rng: &mut SplitMix64,
) -> Vec<(f64, f64)> {
    let phi_lights = case.point_light_power();
    let phi = phi_lights + g.emitted_power();
    let emitters: Vec<&Object> = g
        .objects
        .iter()
        .filter(|o| o.emitted_radiance > 0.0)
        .collect();
    let mut group_of = vec![usize::MAX; g.objects.len()];
    for (k, members) in groups.iter().enumerate() {
        for &i in members {
            group_of[i] = k;
        }
    }
    let mut sums = vec![(0.0, 0.0); groups.len()];
    let mut counts = vec![0u32; groups.len()];
    for _ in 0..photons {
        // Start at the (isotropic) point light, or at a uniform point of an emitter with a
        // cosine-distributed direction, chosen by power.
        let pick = rng.uniform() * phi;
        let (mut x, mut d) = if pick < phi_lights {
            (case.point_lights[0].position(), sphere_direction(rng))
        } else {
            let mut acc = phi_lights;
            let mut chosen = emitters[emitters.len() - 1];
            for e in &emitters {
                acc += e.exitance() * e.area();
                if pick < acc {
                    chosen = e;
                    break;
                }
            }
            let v = &chosen.vertices;
            let (s, t) = (rng.uniform(), rng.uniform());
            // The cube's emitters are squares: the bilinear map is uniform on them.
            let p = v[0] * ((1.0 - s) * (1.0 - t))
                + v[1] * (s * (1.0 - t))
                + v[2] * (s * t)
                + v[3] * ((1.0 - s) * t);
            (p, cosine_direction(chosen.normal(), rng))
        };
        counts.iter_mut().for_each(|c| *c = 0);
        loop {
            let (i, t) = nearest_hit(x, d, &g.objects).expect("the cube is closed");
            if group_of[i] != usize::MAX {
                counts[group_of[i]] += 1;
            }
            let o = &g.objects[i];
            if rng.uniform() >= o.reflectance {
                break;
            }
            x += d * t;
            d = cosine_direction(o.normal(), rng);
        }
        for (sum, &c) in sums.iter_mut().zip(&counts) {
            sum.0 += c as f64;
            sum.1 += (c as f64).powi(2);
        }
    }
    let (w, nf) = (phi / photons as f64, photons as f64);
    sums.iter()
        .map(|&(s1, s2)| {
            let mean = s1 / nf;
            let var = (s2 / nf - mean * mean).max(0.0) * nf / (nf - 1.0);
            (w * s1, w * nf * (var / nf).sqrt())
        })
        .collect()
}

#[test]
fn closed_cubes_agree_with_photon_tracing() {
    let mut rng = SplitMix64(58);
    let mut checked = 0;
    for case in cases() {
        if !matches!(case.closed_form, ClosedForm::ClosedCubeInterreflection) {
            continue;
        }
        let g = geometry(&case);
        let exp = expectations(&case).unwrap();
        let groups: Vec<Vec<usize>> = exp
            .groups
            .iter()
            .map(|grp| {
                grp.objects
                    .iter()
                    .map(|n| g.objects.iter().position(|o| &o.name == n).unwrap())
                    .collect()
            })
            .collect();
        let flux = photon_trace(&case, &g, &groups, 40_000, &mut rng);
        for (grp, (f, se)) in exp.groups.iter().zip(flux) {
            let (mc, se) = (f / grp.area, se / grp.area);
            // 40 000 photons: 5 standard errors (a normal tail of 6e-7 per face; fixed seed).
            assert!(
                (mc - grp.irradiance).abs() <= 5.0 * se,
                "{} {}: closed form {} vs photons {mc} ± {se}",
                case.id,
                grp.id,
                grp.irradiance
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 24 * 6);
}

#[test]
fn group_means_are_converged() {
    for case in cases() {
        if !matches!(case.closed_form, ClosedForm::AreaSourceContour { .. }) {
            continue;
        }
        let g = geometry(&case);
        for spec in &case.groups {
            let coarse =
                closed_form_group_mean(&case, &g, &spec.objects, GROUP_PANELS, GROUP_ORDER)
                    .unwrap();
            let fine =
                closed_form_group_mean(&case, &g, &spec.objects, 2 * GROUP_PANELS, GROUP_ORDER)
                    .unwrap();
            // The Gauss–Legendre rule on smooth integrands: doubling the panels changes the mean
            // by less than 1e-11 relative, so the default is converged far below 1e-9.
            assert!(
                rel_diff(coarse, fine) < 1e-11,
                "{} {}: {coarse} vs {fine}",
                case.id,
                spec.id
            );
        }
    }
}

#[test]
fn gauss_legendre_integrates_polynomials_exactly() {
    for n in [1, 2, 5, 10, 16] {
        let rule = gauss_legendre_01(n);
        assert_eq!(rule.len(), n);
        for k in 0..2 * n {
            let q: f64 = rule.iter().map(|(x, w)| w * x.powi(k as i32)).sum();
            // ∫₀¹ x^k dx = 1/(k+1), exact for k < 2n.
            assert!(
                (q - 1.0 / (k as f64 + 1.0)).abs() < 1e-14,
                "n = {n}, k = {k}: {q}"
            );
        }
    }
}

#[test]
fn hull_and_intersection_of_convex_polygons() {
    // Hull of a square's corners plus an interior point and a collinear edge point.
    let hull = convex_hull_2d(&[
        [0.0, 0.0],
        [1.0, 0.0],
        [1.0, 1.0],
        [0.0, 1.0],
        [0.5, 0.5],
        [0.5, 0.0],
    ]);
    assert_eq!(hull.len(), 4);
    // Two unit squares offset by (0.5, 0.25): intersection 0.5 × 0.75.
    let a = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let b = [[0.5, 0.25], [1.5, 0.25], [1.5, 1.25], [0.5, 1.25]];
    let i = convex_intersection_2d(&a, &b);
    let area: f64 = (0..i.len())
        .map(|k| {
            let (p, q) = (i[k], i[(k + 1) % i.len()]);
            0.5 * (p[0] * q[1] - p[1] * q[0])
        })
        .sum();
    assert!((area - 0.375).abs() < 1e-15, "{area}");
}

#[test]
fn loader_errors_name_the_file_and_line() {
    let dir = std::env::temp_dir().join(format!("cie171_bad_{}", std::process::id()));
    let case_dir = dir.join("bad_case");
    std::fs::create_dir_all(&case_dir).unwrap();
    let good = cases()
        .into_iter()
        .find(|c| c.id == "cie53_area_source")
        .unwrap();
    let json = std::fs::read_to_string(good.dir.join("case.json"))
        .unwrap()
        .replace("cie53_area_source", "bad_case");
    std::fs::write(case_dir.join("case.json"), &json).unwrap();
    std::fs::copy(good.mtl_path(), case_dir.join("scene.mtl")).unwrap();
    let obj = std::fs::read_to_string(good.obj_path()).unwrap();
    let line = obj.lines().position(|l| l == "f 5 6 7 8").unwrap() + 1;
    std::fs::write(
        case_dir.join("scene.obj"),
        obj.replace("f 5 6 7 8", "f 5 6 7 80"),
    )
    .unwrap();
    let case = load_case(&case_dir).unwrap();
    let e = load_geometry(&case).unwrap_err().to_string();
    assert!(
        e.contains("scene.obj") && e.contains(&format!("line {line}:")) && e.contains("vertex 80"),
        "{e}"
    );
    std::fs::write(
        case_dir.join("case.json"),
        json.replace("\"relative\": 0.01", "\"relative\": \"x\""),
    )
    .unwrap();
    let e = load_case(&case_dir).unwrap_err().to_string();
    assert!(e.contains("case.json") && e.contains("line"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn expectations_are_finite_and_summarised() {
    for case in cases() {
        let exp = expectations(&case).unwrap();
        let mut line = format!("{:28}", case.id);
        for p in &exp.points {
            assert!(
                p.irradiance.is_finite() && p.irradiance >= 0.0,
                "{} {}",
                case.id,
                p.id
            );
            line += &format!(" {}={:.4}", p.id, p.irradiance);
        }
        for g in &exp.groups {
            assert!(
                g.irradiance.is_finite() && g.irradiance >= 0.0 && g.area > 0.0,
                "{} {}",
                case.id,
                g.id
            );
            line += &format!(" [{}]={:.6}", g.id, g.irradiance);
        }
        println!("{line}");
    }
}

#[test]
fn an_occluder_straddling_the_point_plane_is_refused() {
    // The ext57 panel and a box reaching from below to above a wall point's height: part of
    // it is behind the point, where the central projection does not describe the shadow.
    let panel = [
        DVec3::new(1.5, 2.5, 3.0),
        DVec3::new(2.5, 2.5, 3.0),
        DVec3::new(2.5, 1.5, 3.0),
        DVec3::new(1.5, 1.5, 3.0),
    ];
    let corners: Vec<DVec3> = (0..8)
        .map(|i| {
            DVec3::new(
                [1.6, 2.4][i & 1],
                [1.5, 2.3][(i >> 1) & 1],
                [1.0, 2.0][i >> 2],
            )
        })
        .collect();
    let x = DVec3::new(2.0, 0.0, 1.5);
    let e = visible_form_factor(x, DVec3::Y, &panel, &corners).unwrap_err();
    assert!(
        matches!(e, Cie171Error::Occluder { .. }) && e.to_string().contains("straddles"),
        "{e}"
    );
    // Raised wholly between the point's height and the panel, the same box is accepted.
    let low: Vec<DVec3> = corners
        .iter()
        .map(|c| *c + DVec3::new(0.0, 0.0, 0.6))
        .collect();
    assert!(visible_form_factor(x, DVec3::Y, &panel, &low).is_ok());
}
