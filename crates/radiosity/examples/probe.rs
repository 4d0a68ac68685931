use radiosity::coupling::hierarchical::{Hierarchical, HierarchicalOptions};
use radiosity::Coupling;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let n: usize = a[1].parse().unwrap();
    let eps: f64 = a[2].parse().unwrap();
    let scene = radiosity::generate::furnished_room(n, 1);
    let mut h = Hierarchical::new(
        &scene,
        radiosity::FormFactorMethod::Raycast.kernel(),
        HierarchicalOptions::default(),
    )
    .unwrap();
    let e = h.emitted_power() / h.mesh().elements.iter().map(|e| e.area).sum::<f64>();
    let b = radiosity::solve::exitance(h.mesh());
    let guess = vec![[e; 3]; b.len()];
    h.set_solution(&b, &guess);
    let t = std::time::Instant::now();
    h.refine(eps);
    h.remesh(&scene);
    println!(
        "inputs {} leaves {} links {} kinds {:?} forced {} in {:.2}s",
        scene.surfaces.len(),
        h.mesh().elements.len(),
        h.link_count(),
        h.link_kinds(),
        h.forced,
        t.elapsed().as_secs_f64()
    );
}
