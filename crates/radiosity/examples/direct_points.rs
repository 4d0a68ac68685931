use glam::DVec3;
use radiosity::formfactor::analytic_point::point_to_polygon;
use radiosity::formfactor::{subdivide, Visibility};
use radiosity::mesh::{Mesh, MeshOptions};
fn main() {
    let scene = radiosity::cornell::cornell_box();
    let mesh = Mesh::build(&scene, &MeshOptions::default()).unwrap();
    let vis = Visibility::new(&mesh);
    let light = scene.surfaces.iter().find(|s| s.object == "light").unwrap();
    let lv = light.polygon.vertices().to_vec();
    let ln = light.polygon.normal();
    let r: serde_json::Value = serde_json::from_str(include_str!("../tests/reference/cornell_reference.json")).unwrap();
    {
        let floor = scene.surfaces.iter().find(|s| s.object == "floor").unwrap();
        let fv = floor.polygon.vertices().to_vec();
        let n = floor.polygon.normal();
        let subs = subdivide(&lv, 16);
        let k = 150;
        let (mut tot, mut area) = (0.0, 0.0);
        for cell in subdivide(&fv, k) {
            let a = radiosity::geometry::newell(&cell).1;
            let x = cell.iter().copied().sum::<DVec3>() / 4.0;
            let mut f = 0.0;
            for s in &subs {
                let c = s.iter().copied().sum::<DVec3>() / s.len() as f64;
                if vis.visible(x, n, c, ln) { f += point_to_polygon(x, n, s, ln); }
            }
            tot += a * std::f64::consts::PI * 17.0 * f;
            area += a;
        }
        println!("floor direct irradiance avg {:.5} (ref {:.5}), area {area}", tot / area, r["per_polygon_area_averaged"]["polygons"][0]["direct_only_irradiance_avg"][0]);
    }
    for p in r["points"]["values"].as_array().unwrap() {
        let x = DVec3::new(p["point_mm"][0].as_f64().unwrap(), p["point_mm"][1].as_f64().unwrap(), p["point_mm"][2].as_f64().unwrap()) / 1000.0;
        let n = DVec3::new(p["normal"][0].as_f64().unwrap(), p["normal"][1].as_f64().unwrap(), p["normal"][2].as_f64().unwrap());
        let subs = subdivide(&lv, 64);
        let mut f = 0.0;
        for s in &subs {
            let c = s.iter().copied().sum::<DVec3>() / s.len() as f64;
            if vis.visible(x, n, c, ln) { f += point_to_polygon(x, n, s, ln); }
        }
        let h = std::f64::consts::PI * 17.0 * f;
        let want = p["direct_irradiance"][0].as_f64().unwrap();
        println!("{} {:?}: ours {:.5} ref {:.5} ({:+.2}%)", p["surface"], p["point_mm"], h, want, 100.0 * (h - want) / want);
    }
}
#[allow(dead_code)]
fn unused() {}
