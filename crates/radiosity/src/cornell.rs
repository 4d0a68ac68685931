//! The built-in Cornell box: the canonical Cornell University measurements in metres, as in
//! `scenes/cornell.obj` + `scenes/cornell.mtl` (verbatim copies of the reference OBJ+MTL), with
//! the reference pinhole camera.
//!
//! 20 polygons: the ceiling is split into four rectangles around the light, and the slightly
//! twisted left (red) wall is given as two triangles, so every polygon is planar and convex.
//! Reflectances are the Bitterli/Tungsten RGB values; the light emits L_e = (17, 12, 4)
//! W·m⁻²·sr⁻¹ (exitance π·L_e). The box is open towards the camera (z = 0).
//!
//! See also: `scenes/cornell.json`, the same scene as a scene file.

use crate::io::obj::parse_obj;
use crate::scene::{Camera, Scene};
use glam::DVec3;
use std::path::Path;

const OBJ: &str = include_str!("../scenes/cornell.obj");
const MTL: &str = include_str!("../scenes/cornell.mtl");

/// The label the embedded OBJ carries in surface origins: the file it was embedded from,
/// relative to the crate root (so it equals `load_obj("scenes/cornell.obj")` run from there).
pub const CORNELL_OBJ_LABEL: &str = "scenes/cornell.obj";

/// The reference camera: pinhole at (0.278, 0.273, −0.8) m looking along +z, up +y, 35 mm
/// focal length on a 25 mm film, so fov = 2·atan(12.5/35) = 39.3076°. The image's right is
/// −x: the red wall (x ≈ 0.556) is on the left.
pub fn cornell_camera() -> Camera {
    Camera {
        eye: DVec3::new(0.278, 0.273, -0.8),
        target: DVec3::new(0.278, 0.273, 0.0),
        up: DVec3::Y,
        fov_deg: 39.30764811610662,
    }
}

/// The Cornell box scene, named "cornell", with [`cornell_camera`].
pub fn cornell_box() -> Scene {
    let load_mtl = |path: &Path| {
        if path == Path::new("cornell.mtl") {
            Ok(MTL.to_owned())
        } else {
            Err(std::io::ErrorKind::NotFound.into())
        }
    };
    // The embedded files are fixed and loaded by the tests, so this cannot fail at run time.
    let mut scene = parse_obj(OBJ, CORNELL_OBJ_LABEL, load_mtl).expect("built-in Cornell box");
    scene.name = "cornell".to_owned();
    scene.camera = Some(cornell_camera());
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cornell_box_loads_every_face_as_one_polygon() {
        let scene = cornell_box();
        assert_eq!(scene.surfaces.len(), 20);
        assert_eq!(scene.object_names().len(), 20);
        assert_eq!(scene.materials.len(), 4);
        let light = scene.surfaces.iter().find(|s| s.object == "light").unwrap();
        assert_eq!(scene.material(light).emission, [17.0, 12.0, 4.0]);
        assert!(light.polygon.normal().y < -0.999, "light faces down");
    }
}
