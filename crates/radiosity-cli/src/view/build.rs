//! From the library's values to the viewer's: a mesh's elements as a [`ViewMesh`] and a state
//! of the solution on them as a [`ViewFrame`].
//!
//! Both come from the library's [`DisplayMesh`] with Gouraud shading, the one per-vertex
//! radiosity the renderer and the exporters use too, so the page interpolates exactly the
//! values `radiosity render` does. The display mesh's triangles, their elements and their
//! vertex order depend only on the elements (and the hanging vertices found on their edges),
//! not on the radiosity, so the mesh is sent once and each frame carries only values in the
//! same order.

use super::{ViewCamera, ViewError, ViewFrame, ViewMesh, ViewState};
use glam::DVec3;
use radiosity::display::{Conformity, DisplayMesh, Shading};
use radiosity::mesh::{Element, Mesh, SurfaceData};
use radiosity::scene::Camera;
use radiosity::units::{luminance_y, lux_from_irradiance};
use std::collections::hash_map::DefaultHasher;
use std::collections::{HashMap, HashSet};
use std::f64::consts::PI;
use std::hash::{Hash, Hasher};
use std::sync::Arc;

/// The elements to show, with what the viewer needs to know about them.
#[derive(Clone, Copy)]
pub struct Geometry<'a> {
    /// Mesh vertices, m.
    pub vertices: &'a [DVec3],
    /// The elements.
    pub elements: &'a [Element],
    /// Material data per surface (the elements' `surface` indexes it).
    pub surfaces: &'a [SurfaceData],
    /// Object names (the surfaces' `object` indexes them).
    pub objects: &'a [String],
}

impl<'a> Geometry<'a> {
    /// The elements of a solver's mesh.
    pub fn of_mesh(mesh: &'a Mesh) -> Self {
        Self {
            vertices: &mesh.vertices,
            elements: &mesh.elements,
            surfaces: &mesh.surfaces,
            objects: &mesh.objects,
        }
    }

    /// A hash of the vertices and elements: equal for the same mesh, different (but for a
    /// hash collision) when refinement changed it.
    fn fingerprint(&self) -> u64 {
        let mut h = DefaultHasher::new();
        self.vertices.len().hash(&mut h);
        self.elements.len().hash(&mut h);
        for v in self.vertices {
            v.to_array().map(f64::to_bits).hash(&mut h);
        }
        for e in self.elements {
            e.surface.hash(&mut h);
            e.corners.hash(&mut h);
        }
        h.finish()
    }
}

/// Where a frame's irradiance comes from.
#[derive(Clone, Copy)]
pub enum Irradiance<'a> {
    /// The solver's irradiance H per element, W·m⁻².
    Known(&'a [[f64; 3]]),
    /// Recovered from the radiosity per element (W·m⁻²) by B = E + ρH, i.e.
    /// H = (B − E)/ρ: exact for the state a solver reports (progressive refinement keeps
    /// B = E + ρH after every shot; an iteration's B is E + ρH of the previous iterate), and
    /// unknown (NaN) in a channel with ρ = 0.
    FromRadiosity(&'a [[f64; 3]]),
}

/// The camera as the page takes it.
pub fn view_camera(camera: &Camera) -> ViewCamera {
    let f = |v: DVec3| v.as_vec3().to_array();
    ViewCamera {
        eye: f(camera.eye),
        target: f(camera.target),
        up: f(camera.up),
        fov_deg: camera.fov_deg as f32,
    }
}

/// The display mesh of `geometry` as the viewer's mesh, numbered `version`.
///
/// Element edges (the wireframe) join the display vertices at an element's corners; an
/// edge shared by two elements of one surface is listed once.
pub fn view_mesh(
    geometry: &Geometry,
    conformity: &Conformity,
    version: u64,
    camera: &Camera,
) -> ViewMesh {
    let zeros = vec![[0.0; 3]; geometry.elements.len()];
    let display = DisplayMesh::with_conformity(
        geometry.vertices,
        geometry.elements,
        &zeros,
        Shading::Smooth,
        conformity,
    );
    let key = |p: DVec3| p.to_array().map(f64::to_bits);
    // The display triangles of each element are consecutive; a corner's display vertex is
    // the one of the element's triangles at exactly the corner's position (display
    // vertices copy the mesh vertices' positions).
    let mut element_edges = Vec::new();
    let mut seen = HashSet::new();
    let mut start = 0;
    while start < display.triangles.len() {
        let e = display.triangle_element[start];
        let mut end = start;
        let mut at: HashMap<[u64; 3], u32> = HashMap::new();
        while end < display.triangles.len() && display.triangle_element[end] == e {
            for &v in &display.triangles[end] {
                at.insert(key(display.positions[v as usize]), v);
            }
            end += 1;
        }
        let corners = &geometry.elements[e as usize].corners;
        let ids: Vec<Option<u32>> = corners
            .iter()
            .map(|&c| at.get(&key(geometry.vertices[c as usize])).copied())
            .collect();
        for k in 0..ids.len() {
            if let (Some(a), Some(b)) = (ids[k], ids[(k + 1) % ids.len()]) {
                if seen.insert((a.min(b), a.max(b))) {
                    element_edges.push([a, b]);
                }
            }
        }
        start = end;
    }
    let surface = |e: &Element| &geometry.surfaces[e.surface as usize];
    ViewMesh {
        version,
        positions: display
            .positions
            .iter()
            .map(|p| p.as_vec3().to_array())
            .collect(),
        triangles: display.triangles,
        triangle_element: display.triangle_element,
        element_object: geometry
            .elements
            .iter()
            .map(|e| surface(e).object)
            .collect(),
        object_names: geometry.objects.to_vec(),
        element_reflectance: geometry
            .elements
            .iter()
            .map(|e| surface(e).reflectance.map(|r| r as f32))
            .collect(),
        // The renderer draws every surface one-sided (a back face is black); so does the page.
        element_two_sided: vec![false; geometry.elements.len()],
        element_edges,
        camera: view_camera(camera),
        luminance_weights: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            .map(|rgb| luminance_y(rgb) as f32),
    }
}

/// A frame on the mesh `geometry` was shown as: `displayed` is the radiosity per element to
/// draw (W·m⁻², the ambient term included where asked), `irradiance` where H comes from.
pub fn view_frame(
    geometry: &Geometry,
    conformity: &Conformity,
    mesh_version: u64,
    frame: u64,
    displayed: &[[f64; 3]],
    irradiance: Irradiance,
) -> ViewFrame {
    let display = DisplayMesh::with_conformity(
        geometry.vertices,
        geometry.elements,
        displayed,
        Shading::Smooth,
        conformity,
    );
    let h: Vec<[f64; 3]> = match irradiance {
        Irradiance::Known(h) => h.to_vec(),
        Irradiance::FromRadiosity(b) => geometry
            .elements
            .iter()
            .zip(b)
            .map(|(e, b)| {
                let s = &geometry.surfaces[e.surface as usize];
                std::array::from_fn(|c| {
                    if s.reflectance[c] > 0.0 {
                        ((b[c] - s.exitance[c]) / s.reflectance[c]).max(0.0)
                    } else {
                        f64::NAN
                    }
                })
            })
            .collect(),
    };
    let f32s = |v: &[f64; 3]| v.map(|x| x as f32);
    ViewFrame {
        mesh_version,
        frame,
        vertex_radiance: display
            .vertex_radiosity
            .iter()
            .map(|b| b.map(|x| (x / PI) as f32))
            .collect(),
        element_radiosity: displayed.iter().map(f32s).collect(),
        element_illuminance: h.iter().map(|&h| lux_from_irradiance(h) as f32).collect(),
        element_irradiance: h.iter().map(f32s).collect(),
    }
}

/// Sends meshes and frames to a [`ViewState`]: a new mesh version whenever the elements
/// change (adaptive or hierarchical refinement), frames numbered 1, 2, … across meshes.
pub struct Publisher {
    state: Arc<ViewState>,
    camera: Camera,
    shown: Option<Shown>,
    frames: u64,
}

/// The mesh the viewer shows.
struct Shown {
    fingerprint: u64,
    version: u64,
    conformity: Conformity,
}

impl Publisher {
    /// Publishes to `state`; the page starts at `camera`.
    pub fn new(state: Arc<ViewState>, camera: Camera) -> Self {
        Self {
            state,
            camera,
            shown: None,
            frames: 0,
        }
    }

    /// Frames published so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Shows `geometry` (sending it as a new mesh if it differs from the one shown) with
    /// the radiosity `displayed` and the given irradiance.
    pub fn publish(
        &mut self,
        geometry: &Geometry,
        displayed: &[[f64; 3]],
        irradiance: Irradiance,
    ) -> Result<(), ViewError> {
        let fingerprint = geometry.fingerprint();
        if self.shown.as_ref().map(|s| s.fingerprint) != Some(fingerprint) {
            let conformity = Conformity::find(geometry.vertices, geometry.elements);
            let version = self.shown.as_ref().map_or(1, |s| s.version + 1);
            let mesh = view_mesh(geometry, &conformity, version, &self.camera);
            self.state.set_mesh(mesh)?;
            self.shown = Some(Shown {
                fingerprint,
                version,
                conformity,
            });
        }
        let Some(shown) = &self.shown else {
            unreachable!("a mesh was just set");
        };
        self.frames += 1;
        let frame = view_frame(
            geometry,
            &shown.conformity,
            shown.version,
            self.frames,
            displayed,
            irradiance,
        );
        self.state.set_frame(frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cornell_mesh(elements: usize) -> Mesh {
        let scene = radiosity::cornell::cornell_box();
        let options = radiosity::MeshOptions {
            elements,
            ..Default::default()
        };
        Mesh::build(&scene, &options).unwrap()
    }

    #[test]
    fn the_view_mesh_is_the_renderers_display_mesh() {
        let mesh = cornell_mesh(300);
        let g = Geometry::of_mesh(&mesh);
        let conformity = Conformity::find(&mesh.vertices, &mesh.elements);
        // Radiosity varying from element to element, so that vertex values differ.
        let b: Vec<[f64; 3]> = (0..mesh.len())
            .map(|i| [i as f64, 2.0 * i as f64 + 1.0, 0.5])
            .collect();
        let camera = radiosity::cornell::cornell_box().camera.unwrap();
        let vm = view_mesh(&g, &conformity, 1, &camera);
        vm.validate().unwrap();
        let frame = view_frame(&g, &conformity, 1, 1, &b, Irradiance::Known(&b));
        frame.validate_for(&vm).unwrap();
        let display = DisplayMesh::build(&mesh.vertices, &mesh.elements, &b, Shading::Smooth);
        assert_eq!(vm.triangles, display.triangles);
        assert_eq!(vm.triangle_element, display.triangle_element);
        for (got, want) in frame.vertex_radiance.iter().zip(&display.vertex_radiosity) {
            for c in 0..3 {
                let want = (want[c] / PI) as f32;
                assert!((got[c] - want).abs() <= 1e-6 * want.abs().max(1.0));
            }
        }
        // Every element edge of the mesh appears once per surface side: the wireframe has
        // the same segments as the renderer's overlay.
        let edges = radiosity::display::element_edges(&mesh.vertices, &mesh.elements);
        let key = |a: [f32; 3], b: [f32; 3]| {
            let (a, b) = (a.map(f32::to_bits), b.map(f32::to_bits));
            if a < b {
                (a, b)
            } else {
                (b, a)
            }
        };
        let ours: HashSet<_> = vm
            .element_edges
            .iter()
            .map(|&[a, b]| key(vm.positions[a as usize], vm.positions[b as usize]))
            .collect();
        let theirs: HashSet<_> = edges
            .iter()
            .map(|[a, b]| key(a.as_vec3().to_array(), b.as_vec3().to_array()))
            .collect();
        assert_eq!(ours, theirs);
        // Camera and names carry over.
        assert_eq!(vm.object_names, mesh.objects);
        assert_eq!(vm.camera.fov_deg, camera.fov_deg as f32);
    }

    #[test]
    fn irradiance_is_recovered_from_radiosity_where_reflectance_allows() {
        let mut mesh = cornell_mesh(100);
        // Make one surface black in its red channel: H is unknown there.
        mesh.surfaces[0].reflectance[0] = 0.0;
        let g = Geometry::of_mesh(&mesh);
        let conformity = Conformity::find(&mesh.vertices, &mesh.elements);
        // B = E + ρH with H = (1, 2, 3) W·m⁻² everywhere.
        let h = [1.0, 2.0, 3.0];
        let b: Vec<[f64; 3]> = mesh
            .elements
            .iter()
            .map(|e| {
                let (rho, ex) = (mesh.reflectance(e), mesh.exitance(e));
                std::array::from_fn(|c| ex[c] + rho[c] * h[c])
            })
            .collect();
        let frame = view_frame(&g, &conformity, 1, 1, &b, Irradiance::FromRadiosity(&b));
        for (e, got) in mesh.elements.iter().zip(&frame.element_irradiance) {
            for c in 0..3 {
                if mesh.surfaces[e.surface as usize].reflectance[c] == 0.0 {
                    assert!(got[c].is_nan());
                } else {
                    assert!((f64::from(got[c]) - h[c]).abs() < 1e-5, "{got:?}");
                }
            }
        }
        // Illuminance: 683 lm/W · Y(H) where H is known.
        let lit = mesh.elements.iter().position(|e| e.surface != 0).unwrap();
        let want = 683.0 * (0.2126 * 1.0 + 0.7152 * 2.0 + 0.0722 * 3.0);
        assert!((f64::from(frame.element_illuminance[lit]) - want).abs() < 1e-2);
    }

    #[test]
    fn a_changed_mesh_gets_a_new_version_and_frames_keep_counting() {
        let state = Arc::new(ViewState::new());
        let camera = radiosity::cornell::cornell_box().camera.unwrap();
        let mut publisher = Publisher::new(state.clone(), camera);
        let coarse = cornell_mesh(100);
        let b = vec![[1.0; 3]; coarse.len()];
        publisher
            .publish(&Geometry::of_mesh(&coarse), &b, Irradiance::Known(&b))
            .unwrap();
        publisher
            .publish(&Geometry::of_mesh(&coarse), &b, Irradiance::Known(&b))
            .unwrap();
        assert_eq!(state.notice().mesh_version, Some(1));
        assert_eq!(state.notice().frame, Some(2));
        let fine = cornell_mesh(400);
        let b = vec![[1.0; 3]; fine.len()];
        publisher
            .publish(&Geometry::of_mesh(&fine), &b, Irradiance::Known(&b))
            .unwrap();
        assert_eq!(state.notice().mesh_version, Some(2));
        assert_eq!(state.notice().frame, Some(3));
        assert_eq!(state.mesh().unwrap().element_count(), fine.len());
    }
}
