//! Hierarchical radiosity against scene size: time, links, leaves and peak memory for the
//! tessellated Cornell box (38 k² input triangles, [`radiosity::generate::tessellated`]),
//! the Cornell box with two spheres of 8 k(k − 1) triangles
//! ([`radiosity::generate::cornell_with_spheres`]: curved surfaces, whose triangles do not
//! merge), furnished rooms of N boxes and shelves ([`radiosity::generate::furnished_room`],
//! seed 1) and meeting rooms of N chairs ([`radiosity::generate::meeting_room`]: tessellated
//! furniture whose legs pierce what they hold, as real interior models are made), with the
//! growth exponent of time in input size fitted by least squares on
//! log–log axes.
//!
//! Each size runs in its own process, so that its peak resident memory (`VmHWM`) is its own.
//!
//! Run: `cargo bench -p radiosity --bench scale` (sizes that run in a few minutes on two
//! cores), or with `-- --full` up to the 1 M-triangle Cornell box and 10⁵ furnished
//! objects; `-- cornell`, `-- spheres`, `-- room` or `-- meeting` runs one family.

use radiosity::coupling::hierarchical::HierarchicalOptions;
use radiosity::generate::{cornell_with_spheres, furnished_room, meeting_room, tessellated};
use radiosity::scene::Scene;
use radiosity::solve::{NoObserver, SolveOptions, SolverKind};
use radiosity::FormFactorMethod;
use std::process::Command;
use std::time::Instant;

/// One measured size.
#[derive(Debug, Clone)]
struct Row {
    family: String,
    size: usize,
    triangles: usize,
    seconds: f64,
    links: usize,
    leaves: usize,
    nodes: usize,
    peak_mib: f64,
    escaped: f64,
    /// The hierarchy's own estimate of its memory, MiB (what its memory limit checks).
    estimate_mib: f64,
}

/// Divisions of the meeting room's curved parts ([`meeting_room`]): about 12 k triangles
/// per chair.
const MEETING_SEGMENTS: usize = 36;

fn scene(family: &str, size: usize) -> Scene {
    match family {
        "cornell" => tessellated(&radiosity::cornell::cornell_box(), size),
        "spheres" => cornell_with_spheres(size),
        "meeting" => meeting_room(size, MEETING_SEGMENTS),
        _ => furnished_room(size, 1),
    }
}

/// Triangles the scene's polygons make (a convex n-gon is n − 2).
fn triangles(scene: &Scene) -> usize {
    scene
        .surfaces
        .iter()
        .map(|s| s.polygon.vertices().len() - 2)
        .sum()
}

fn peak_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn child(family: &str, size: usize) {
    let scene = scene(family, size);
    let triangles = triangles(&scene);
    let started = Instant::now();
    let solved = radiosity::solve::hierarchical::solve(
        &scene,
        FormFactorMethod::Raycast,
        // ε = 0.02, the README's scaling table's (the default was 0.02 when it was
        // measured; 0.01 since hierarchical became the default solver).
        HierarchicalOptions {
            epsilon: 0.02,
            ..HierarchicalOptions::default()
        },
        &SolveOptions {
            solver: SolverKind::Hierarchical,
            ..Default::default()
        },
        &mut NoObserver,
        &radiosity::progress::NoProgress,
    )
    .expect("solve");
    let seconds = started.elapsed().as_secs_f64();
    // Power that leaves the surfaces but lands on none, as a fraction of the emitted: zero
    // for a closed room when the links close.
    let emitted = radiosity::solve::Solution::emitted_power(&solved.mesh);
    let escaped = solved.solution.escaped_power[1] / emitted[1];
    println!(
        "ROW {family} {size} {triangles} {seconds} {} {} {} {} {} {}",
        solved.links,
        solved.mesh.elements.len(),
        solved.nodes,
        peak_mib(),
        escaped,
        solved.bytes as f64 / f64::from(1 << 20),
    );
}

fn run(family: &str, size: usize) -> Option<Row> {
    let out = Command::new(std::env::current_exe().ok()?)
        .args(["--child", family, &size.to_string()])
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().find(|l| l.starts_with("ROW "))?;
    let f: Vec<&str> = line.split_whitespace().collect();
    Some(Row {
        family: f[1].to_owned(),
        size: f[2].parse().ok()?,
        triangles: f[3].parse().ok()?,
        seconds: f[4].parse().ok()?,
        links: f[5].parse().ok()?,
        leaves: f[6].parse().ok()?,
        nodes: f[7].parse().ok()?,
        peak_mib: f[8].parse().ok()?,
        escaped: f[9].parse().ok()?,
        estimate_mib: f[10].parse().ok()?,
    })
}

/// Least-squares slope of ln y against ln x.
fn exponent(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0);
    for &(x, y) in points {
        let (lx, ly) = (x.ln(), y.ln());
        sx += lx;
        sy += ly;
        sxx += lx * lx;
        sxy += lx * ly;
    }
    (n * sxy - sx * sy) / (n * sxx - sx * sx)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--child") {
        child(&args[1], args[2].parse().expect("size"));
        return;
    }
    let full = args.iter().any(|a| a == "--full");
    let only = args
        .iter()
        .find(|a| *a == "cornell" || *a == "spheres" || *a == "room" || *a == "meeting")
        .cloned();
    let families: Vec<(&str, Vec<usize>)> = vec![
        (
            "cornell",
            if full {
                vec![16, 36, 81, 162]
            } else {
                vec![16, 23, 32, 45]
            },
        ),
        (
            "spheres",
            if full {
                vec![16, 50, 112, 158]
            } else {
                vec![16, 35, 50]
            },
        ),
        (
            "room",
            if full {
                vec![1000, 3162, 10000, 31623, 100000]
            } else {
                vec![300, 1000, 3000]
            },
        ),
        (
            "meeting",
            if full {
                vec![2, 6, 12, 24, 48]
            } else {
                vec![2, 6, 12]
            },
        ),
    ];
    println!(
        "{:8} {:>7} {:>10} {:>9} {:>10} {:>9} {:>10} {:>9} {:>12} {:>10}",
        "scene",
        "size",
        "triangles",
        "seconds",
        "links",
        "leaves",
        "nodes",
        "peak MiB",
        "estimate MiB",
        "escaped"
    );
    for (family, sizes) in families {
        if only.as_deref().is_some_and(|o| o != family) {
            continue;
        }
        let mut rows = Vec::new();
        for size in sizes {
            match run(family, size) {
                Some(r) => {
                    println!(
                        "{:8} {:>7} {:>10} {:>9.2} {:>10} {:>9} {:>10} {:>9.0} {:>12.0} {:>10.2e}",
                        r.family,
                        r.size,
                        r.triangles,
                        r.seconds,
                        r.links,
                        r.leaves,
                        r.nodes,
                        r.peak_mib,
                        r.estimate_mib,
                        r.escaped
                    );
                    rows.push(r);
                }
                None => println!("{family} {size}: the run failed"),
            }
        }
        if rows.len() >= 2 {
            let fit = |y: &dyn Fn(&Row) -> f64| {
                exponent(
                    &rows
                        .iter()
                        .map(|r| (r.triangles as f64, y(r)))
                        .collect::<Vec<_>>(),
                )
            };
            println!(
                "{family}: growth exponent in input triangles: time {:.2}, links {:.2}, leaves {:.2}, memory {:.2}",
                fit(&|r| r.seconds),
                fit(&|r| r.links as f64),
                fit(&|r| r.leaves as f64),
                fit(&|r| r.peak_mib),
            );
        }
    }
}
