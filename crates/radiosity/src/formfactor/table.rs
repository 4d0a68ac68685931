//! Accuracy versus cost: every method on the reference cases of
//! `tests/reference/formfactors.json` (Howell's catalog C-11, C-14, C-41, B-3, B-8 at 90°,
//! exact values cross-checked by pyviewfactor and Monte Carlo; see its README).
//!
//! For each method: the maximum and mean absolute error over every reference value (F12, and
//! F21 where the source is a polygon), and the wall-clock time per form factor. This is what
//! `radiosity formfactor --table` prints.
//!
//! The C-41 references are for true disks and the cases use 256-gons of equal area: the
//! polygons' own values differ from the disks' by less than 1e-9, below every method's error.

use super::pair::{solve_pair, PairProblem, PairSettings, Source};
use super::FormFactorMethod;
use glam::DVec3;
use serde_json::Value;

const REFERENCE: &str = include_str!("../../tests/reference/formfactors.json");

/// One reference case: the problem and its exact answers.
#[derive(Debug, Clone)]
pub struct ReferenceCase {
    /// Catalog number and parameters, e.g. "C-11 a=1 b=1 c=1".
    pub name: String,
    /// The configuration.
    pub problem: PairProblem,
    /// F_{1→2}.
    pub f12: f64,
    /// F_{2→1} (`None` for a differential A1).
    pub f21: Option<f64>,
}

/// The reference cases embedded from `tests/reference/formfactors.json`.
pub fn reference_cases() -> Vec<ReferenceCase> {
    let doc: Value =
        serde_json::from_str(REFERENCE).expect("embedded formfactors.json is valid JSON");
    let vertices = |v: &Value| -> Vec<DVec3> {
        v.as_array()
            .expect("polygon")
            .iter()
            .map(|p| {
                let c: Vec<f64> = p
                    .as_array()
                    .expect("vertex")
                    .iter()
                    .map(|x| x.as_f64().expect("number"))
                    .collect();
                DVec3::new(c[0], c[1], c[2])
            })
            .collect()
    };
    doc["cases"]
        .as_array()
        .expect("cases")
        .iter()
        .map(|c| {
            let from = match c.get("A1") {
                Some(a1) => Source::Polygon(vertices(a1)),
                None => {
                    let d = &c["dA1"];
                    let v = |k: &str| {
                        let p: Vec<f64> = d[k]
                            .as_array()
                            .expect(k)
                            .iter()
                            .map(|x| x.as_f64().expect("number"))
                            .collect();
                        DVec3::new(p[0], p[1], p[2])
                    };
                    Source::Point {
                        point: v("point"),
                        normal: v("normal"),
                    }
                }
            };
            let params = c["params"]
                .as_object()
                .map(|m| {
                    m.iter()
                        .filter(|(k, _)| *k != "polygon_sides")
                        .map(|(k, v)| format!("{k}={v}"))
                        .collect::<Vec<_>>()
                        .join(" ")
                })
                .unwrap_or_default();
            let name = c["case"]
                .as_str()
                .expect("case")
                .replace(" (Phi=90deg)", "");
            ReferenceCase {
                name: format!("{name} {params}"),
                problem: PairProblem::new(from, vertices(&c["A2"]), Vec::new())
                    .expect("reference geometry is valid"),
                f12: c["F12"].as_f64().expect("F12"),
                f21: c["F21"].as_f64(),
            }
        })
        .collect()
}

/// One method's line of the table.
#[derive(Debug, Clone)]
pub struct TableRow {
    /// The method.
    pub method: FormFactorMethod,
    /// Largest |computed − exact| over every reference value.
    pub max_error: f64,
    /// The case where it occurred.
    pub worst_case: String,
    /// Mean |computed − exact|.
    pub mean_error: f64,
    /// Form factors computed (F12 of every case and F21 where defined).
    pub form_factors: usize,
    /// Mean wall-clock seconds per form factor (dominated by the 256-gons of C-41).
    pub seconds_per_form_factor: f64,
    /// Median over the cases of the seconds per form factor.
    pub median_seconds: f64,
}

/// Runs `methods` on every reference case.
pub fn accuracy_table(methods: &[FormFactorMethod], settings: &PairSettings) -> Vec<TableRow> {
    let cases = reference_cases();
    methods
        .iter()
        .map(|&method| {
            let (mut max, mut sum, mut count, mut seconds) = (0.0f64, 0.0, 0usize, 0.0);
            let mut worst = String::new();
            let mut per_case = Vec::with_capacity(cases.len());
            for case in &cases {
                let r = solve_pair(&case.problem, method, settings);
                seconds += r.seconds;
                per_case.push(r.seconds / if r.to_from.is_some() { 2.0 } else { 1.0 });
                let mut errors = vec![(r.from_to.value - case.f12).abs()];
                if let (Some(want), Some(got)) = (case.f21, r.to_from) {
                    errors.push((got.value - want).abs());
                }
                for e in errors {
                    // NaN counts as the worst possible error.
                    let e = if e.is_nan() { f64::INFINITY } else { e };
                    if e > max || count == 0 {
                        max = max.max(e);
                        worst = case.name.clone();
                    }
                    sum += e;
                    count += 1;
                }
            }
            TableRow {
                method,
                max_error: max,
                worst_case: worst,
                mean_error: sum / count.max(1) as f64,
                form_factors: count,
                seconds_per_form_factor: seconds / count.max(1) as f64,
                median_seconds: median(&mut per_case),
            }
        })
        .collect()
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The table in Markdown.
pub fn to_markdown(rows: &[TableRow]) -> String {
    let mut s = String::from(
        "| method | max abs error | mean abs error | worst case | time per form factor (median) | (mean) |\n\
         | --- | --- | --- | --- | --- | --- |\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {:.1e} | {:.1e} | {} | {} | {} |\n",
            r.method.name(),
            r.max_error,
            r.mean_error,
            r.worst_case,
            human_seconds(r.median_seconds),
            human_seconds(r.seconds_per_form_factor)
        ));
    }
    s
}

fn human_seconds(s: f64) -> String {
    if s >= 1.0 {
        format!("{s:.2} s")
    } else if s >= 1e-3 {
        format!("{:.2} ms", s * 1e3)
    } else {
        format!("{:.1} µs", s * 1e6)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embeds_the_twenty_cases_with_their_areas() {
        let cases = reference_cases();
        assert_eq!(cases.len(), 20);
        let doc: Value = serde_json::from_str(REFERENCE).unwrap();
        for (case, raw) in cases.iter().zip(doc["cases"].as_array().unwrap()) {
            if let Some(a1) = raw["area_A1"].as_f64() {
                assert!(
                    (case.problem.from_area().unwrap() - a1).abs() < 1e-9 * a1,
                    "{}",
                    case.name
                );
                // Reciprocity of the reference values themselves: A1 F12 = A2 F21.
                let a2 = raw["area_A2"].as_f64().unwrap();
                assert!(
                    (a1 * case.f12 - a2 * case.f21.unwrap()).abs() < 1e-12,
                    "{}",
                    case.name
                );
            } else {
                assert!(case.f21.is_none());
            }
        }
    }
}
