use radiosity::cornell::cornell_box;
use radiosity::formfactor::FormFactorMethod;
use radiosity::mesh::MeshOptions;
use radiosity::pipeline::{solve_scene, SolveSettings};
use radiosity::progress::NoProgress;
use radiosity::report::Report;
use radiosity::solve::{SolveOptions, SolverKind};
use serde_json::Value;

#[test]
fn scratch() {
    let reference: Value = serde_json::from_str(include_str!("reference/cornell_reference.json")).unwrap();
    let n: usize = std::env::var("ELEMS").ok().and_then(|s| s.parse().ok()).unwrap_or(4000);
    let methods: Vec<FormFactorMethod> = std::env::var("METHODS").map(|s| s.split(',').map(|m| m.parse().unwrap()).collect()).unwrap_or(FormFactorMethod::ALL.to_vec());
    for method in methods {
        let settings = SolveSettings {
            form_factor: method,
            mesh: MeshOptions { elements: n, ..Default::default() },
            solve: SolveOptions { tolerance: 1e-4, solver: if std::env::var("DIRECT").is_ok() { SolverKind::Direct } else { SolverKind::Progressive }, ..Default::default() },
        };
        let t = std::time::Instant::now();
        let solved = solve_scene(&cornell_box(), &settings, &NoProgress).unwrap();
        let secs = t.elapsed().as_secs_f64();
        let report = Report::new("cornell", &solved.mesh, &solved.solution, method.name());
        let mut line = format!("{method:>16} {} el {} p {secs:.2}s ff {:.2}s:", solved.mesh.len(), solved.mesh.patches.len(), solved.solution.stats.form_factor_seconds);
        let mut worst: f64 = 0.0;
        for poly in reference["per_polygon_area_averaged"]["polygons"].as_array().unwrap() {
            let name = poly["name"].as_str().unwrap();
            let ours = report.object(name).unwrap();
            let mut e = [0.0; 3];
            for c in 0..3 {
                let want = poly["radiosity_avg"][c].as_f64().unwrap();
                e[c] = 100.0 * (ours.radiosity[c] - want) / want;
                worst = worst.max(e[c].abs());
            }
            line += &format!("\n   {name:>30} {:+6.2} {:+6.2} {:+6.2}", e[0], e[1], e[2]);
        }
        eprintln!("{line}\n   worst {worst:.2} %");
    }
}

#[test]
fn scratch_rays() {
    use radiosity::formfactor::{Visibility, FormFactors};
    use radiosity::mesh::Mesh;
    let mesh = Mesh::build(&cornell_box(), &MeshOptions::default()).unwrap();
    let vis = Visibility::new(&mesh);
    let mut dirs = Vec::new();
    let mut s = 12345u64;
    let mut rnd = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; (s >> 11) as f32 / (1u64 << 53) as f32 };
    for _ in 0..1_000_000 {
        let o = glam::Vec3::new(0.05 + 0.45 * rnd(), 0.001, 0.05 + 0.45 * rnd());
        let d = glam::Vec3::new(rnd() - 0.5, rnd(), rnd() - 0.5).normalize();
        dirs.push((o, d));
    }
    let t = std::time::Instant::now();
    let mut hits = 0;
    for (o, d) in &dirs { if vis.first_hit(*o, *d).is_some() { hits += 1; } }
    let secs = t.elapsed().as_secs_f64();
    eprintln!("first_hit: {:.1} ns/ray single thread, {hits} hits, {} tris", secs * 1e9 / 1e6, vis.bvh().len());
    let mc = radiosity::formfactor::monte_carlo::MonteCarlo::new(&mesh, &vis);
    let t = std::time::Instant::now();
    let mut row = vec![0f32; mesh.patches.len()];
    for e in 0..200 { mc.row(e, &mut row); }
    let secs = t.elapsed().as_secs_f64();
    eprintln!("mc rows: {:.1} ns/ray single thread", secs * 1e9 / (200.0 * 4096.0));
    let ap = radiosity::formfactor::analytic::AnalyticPolygon::new(&mesh, &vis);
    let t = std::time::Instant::now();
    let mut n = 0;
    for e in (0..mesh.elements.len()).step_by(50) { ap.row(e, &mut row); n += row.len(); }
    let secs = t.elapsed().as_secs_f64();
    eprintln!("analytic-polygon: {:.2} us/pair single thread", secs * 1e6 / n as f64);
}

#[test]
fn scratch_cases() {
    use radiosity::formfactor::pair::*;
    let methods: Vec<FormFactorMethod> = std::env::var("METHODS").map(|s| s.split(',').map(|m| m.parse().unwrap()).collect()).unwrap_or(FormFactorMethod::ALL.to_vec());
    let samples = std::env::var("SAMPLES").ok().and_then(|s| s.parse().ok());
    for m in methods {
        for c in radiosity::formfactor::table::reference_cases() {
            let r = solve_pair(&c.problem, m, &PairSettings { samples, ..Default::default() });
            eprintln!("{m:>16} {:>28} {:+.2e} {:+.2e} {:.3}s", c.name, r.from_to.value - c.f12, r.to_from.map_or(0.0, |t| t.value - c.f21.unwrap()), r.seconds);
        }
    }
}
