//! PLACEHOLDER brute-force (replaced by the BVH helper).
use glam::Vec3;
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit { pub t: f32, pub triangle: u32, pub u: f32, pub v: f32 }
pub struct Bvh { tris: Vec<[Vec3; 3]> }
impl Bvh {
    pub fn build(triangles: &[[Vec3; 3]]) -> Bvh { Bvh { tris: triangles.to_vec() } }
    pub fn len(&self) -> usize { self.tris.len() }
    pub fn is_empty(&self) -> bool { self.tris.is_empty() }
    pub fn intersect(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for (i, t) in self.tris.iter().enumerate() {
            let e1 = t[1] - t[0]; let e2 = t[2] - t[0];
            let p = d.cross(e2); let det = e1.dot(p);
            if det.abs() < 1e-20 { continue; }
            let inv = 1.0 / det; let s = o - t[0]; let u = s.dot(p) * inv;
            if !(0.0..=1.0).contains(&u) { continue; }
            let q = s.cross(e1); let v = d.dot(q) * inv;
            if v < 0.0 || u + v > 1.0 { continue; }
            let tt = e2.dot(q) * inv;
            if tt > t_min && tt < t_max && best.is_none_or(|b| tt < b.t) { best = Some(Hit { t: tt, triangle: i as u32, u, v }); }
        }
        best
    }
    pub fn occluded(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool { self.intersect(o, d, t_min, t_max).is_some() }
    pub fn segment_occluded(&self, a: Vec3, b: Vec3, eps: f32) -> bool { self.occluded(a, b - a, eps, 1.0 - eps) }
}
