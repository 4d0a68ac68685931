//! A synthetic scene for the viewer's tests and demo: an open box (1 m cube, open towards the
//! camera at z = 0) with a ceiling light and two small panels turned away from the camera,
//! one one-sided (must show black) and one two-sided (must show its radiance).
//!
//! Each surface is an n × n grid of square elements, two display triangles each, wound
//! counter-clockwise seen from the front. The frames are not a radiosity solution: they are
//! chosen so that a test knows every pixel's value (uniform surfaces) or, for the demo, so
//! that they look plausible (a cosine-weighted falloff from the light plus a growing
//! ambient term).

use super::{ViewCamera, ViewFrame, ViewMesh};

/// A surface of the box: name, origin, the two edge vectors (normal = u × v), reflectance,
/// two-sidedness.
struct Surface {
    name: &'static str,
    origin: [f32; 3],
    u: [f32; 3],
    v: [f32; 3],
    reflectance: [f32; 3],
    two_sided: bool,
}

const SURFACES: [Surface; 8] = [
    Surface {
        name: "back",
        origin: [0.0, 0.0, 1.0],
        u: [0.0, 1.0, 0.0],
        v: [1.0, 0.0, 0.0],
        reflectance: [0.7, 0.7, 0.7],
        two_sided: false,
    },
    Surface {
        name: "floor",
        origin: [0.0, 0.0, 0.0],
        u: [0.0, 0.0, 1.0],
        v: [1.0, 0.0, 0.0],
        reflectance: [0.7, 0.7, 0.7],
        two_sided: false,
    },
    Surface {
        name: "ceiling",
        origin: [0.0, 1.0, 0.0],
        u: [1.0, 0.0, 0.0],
        v: [0.0, 0.0, 1.0],
        reflectance: [0.7, 0.7, 0.7],
        two_sided: false,
    },
    Surface {
        name: "left x=0",
        origin: [0.0, 0.0, 0.0],
        u: [0.0, 1.0, 0.0],
        v: [0.0, 0.0, 1.0],
        reflectance: [0.15, 0.45, 0.1],
        two_sided: false,
    },
    Surface {
        name: "right x=1",
        origin: [1.0, 0.0, 0.0],
        u: [0.0, 0.0, 1.0],
        v: [0.0, 1.0, 0.0],
        reflectance: [0.6, 0.07, 0.05],
        two_sided: false,
    },
    Surface {
        name: "light",
        origin: [0.4, 0.99, 0.4],
        u: [0.2, 0.0, 0.0],
        v: [0.0, 0.0, 0.2],
        reflectance: [0.78, 0.78, 0.78],
        two_sided: false,
    },
    Surface {
        name: "panel one-sided",
        origin: [0.6, 0.3, 0.5],
        u: [0.2, 0.0, 0.0],
        v: [0.0, 0.2, 0.0],
        reflectance: [0.5, 0.5, 0.8],
        two_sided: false,
    },
    Surface {
        name: "panel two-sided",
        origin: [0.2, 0.3, 0.5],
        u: [0.2, 0.0, 0.0],
        v: [0.0, 0.2, 0.0],
        reflectance: [0.8, 0.6, 0.2],
        two_sided: true,
    },
];

/// Index of the light among the objects.
pub const LIGHT: usize = 5;

/// The camera: in front of the open side, looking at the box's centre.
pub const CAMERA: ViewCamera = ViewCamera {
    eye: [0.5, 0.5, -1.2],
    target: [0.5, 0.5, 0.5],
    up: [0.0, 1.0, 0.0],
    fov_deg: 50.0,
};

fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(a: [f32; 3], s: f32) -> [f32; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Y = 0.2126 R + 0.7152 G + 0.0722 B (ITU-R BT.709), as `radiosity::units`.
const LUMINANCE_WEIGHTS: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// Illuminance, lx, of an irradiance: 683 lm/W · Y(E), as `radiosity::units`.
fn lux(e: [f32; 3]) -> f32 {
    683.0 * (0..3).map(|c| LUMINANCE_WEIGHTS[c] * e[c]).sum::<f32>()
}

/// The box with `n` × `n` elements per surface.
pub fn box_mesh(n: u32, version: u64) -> ViewMesh {
    let n = n.max(1);
    let mut mesh = ViewMesh {
        version,
        positions: Vec::new(),
        triangles: Vec::new(),
        triangle_element: Vec::new(),
        element_object: Vec::new(),
        object_names: SURFACES.iter().map(|s| s.name.to_owned()).collect(),
        element_reflectance: Vec::new(),
        element_two_sided: Vec::new(),
        element_edges: Vec::new(),
        camera: CAMERA,
        luminance_weights: LUMINANCE_WEIGHTS,
    };
    for (object, s) in SURFACES.iter().enumerate() {
        let base = mesh.positions.len() as u32;
        let at = |i: u32, j: u32| base + j * (n + 1) + i;
        for j in 0..=n {
            for i in 0..=n {
                let p = add(
                    add(s.origin, scale(s.u, i as f32 / n as f32)),
                    scale(s.v, j as f32 / n as f32),
                );
                mesh.positions.push(p);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let element = mesh.element_object.len() as u32;
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                // u runs along i and v along j: (b − a) × (d − a) ∥ u × v, the normal.
                mesh.triangles.push([a, b, c]);
                mesh.triangles.push([a, c, d]);
                mesh.triangle_element.extend([element, element]);
                mesh.element_object.push(object as u32);
                mesh.element_reflectance.push(s.reflectance);
                mesh.element_two_sided.push(s.two_sided);
            }
        }
        for j in 0..=n {
            for i in 0..n {
                mesh.element_edges.push([at(i, j), at(i + 1, j)]);
            }
        }
        for i in 0..=n {
            for j in 0..n {
                mesh.element_edges.push([at(i, j), at(i, j + 1)]);
            }
        }
    }
    mesh
}

/// The front normal of an object (unit).
pub fn normal(object: usize) -> [f32; 3] {
    let s = &SURFACES[object];
    let c = cross(s.u, s.v);
    let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    scale(c, 1.0 / l)
}

/// The world position of point (a, b) ∈ [0, 1]² of an object.
pub fn point_on(object: usize, a: f32, b: f32) -> [f32; 3] {
    let s = &SURFACES[object];
    add(add(s.origin, scale(s.u, a)), scale(s.v, b))
}

/// A frame in which every element of object k has radiance `radiance[k]` (W·m⁻²·sr⁻¹) at
/// all its vertices, radiosity π·L and irradiance `irradiance[k]`.
pub fn uniform_frame(
    mesh: &ViewMesh,
    frame: u64,
    radiance: &[[f32; 3]; 8],
    irradiance: &[[f32; 3]; 8],
) -> ViewFrame {
    let mut vertex_radiance = vec![[0.0; 3]; mesh.positions.len()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let object = mesh.element_object[mesh.triangle_element[t] as usize] as usize;
        for &v in tri {
            vertex_radiance[v as usize] = radiance[object];
        }
    }
    let objects = mesh.element_object.iter().map(|&o| o as usize);
    ViewFrame {
        mesh_version: mesh.version,
        frame,
        vertex_radiance,
        element_radiosity: objects
            .clone()
            .map(|o| scale(radiance[o], std::f32::consts::PI))
            .collect(),
        element_irradiance: objects.clone().map(|o| irradiance[o]).collect(),
        element_illuminance: objects.map(|o| lux(irradiance[o])).collect(),
    }
}

/// A plausible-looking frame for the demo at solve progress `t` ∈ [0, 1]: light from the
/// ceiling light falling off as cos θ / r², plus an ambient term growing with `t`.
pub fn demo_frame(mesh: &ViewMesh, frame: u64, t: f32) -> ViewFrame {
    let light_centre = point_on(LIGHT, 0.5, 0.5);
    let light_normal = normal(LIGHT);
    // Emitted radiosity of the light, W·m⁻², and its power-like scale for the falloff.
    let emitted = [53.4, 37.7, 12.6];
    let light_area = 0.04;
    let elements = mesh.element_count();
    let mut centre = vec![[0.0f32; 3]; elements];
    let mut corners = vec![0u32; elements];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let e = mesh.triangle_element[t] as usize;
        // Each element is two triangles sharing a diagonal: its centre is the mean of the
        // first triangle's a and c.
        if corners[e] == 0 {
            centre[e] = scale(
                add(
                    mesh.positions[tri[0] as usize],
                    mesh.positions[tri[2] as usize],
                ),
                0.5,
            );
        }
        corners[e] += 1;
    }
    let mut radiosity = Vec::with_capacity(elements);
    let mut irradiance = Vec::with_capacity(elements);
    for e in 0..elements {
        let object = mesh.element_object[e] as usize;
        let rho = mesh.element_reflectance[e];
        if object == LIGHT {
            radiosity.push(emitted);
            irradiance.push([0.0; 3]);
            continue;
        }
        let n = normal(object);
        let d = [
            light_centre[0] - centre[e][0],
            light_centre[1] - centre[e][1],
            light_centre[2] - centre[e][2],
        ];
        let r2 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).max(1e-4);
        let r = r2.sqrt();
        let cos_receiver = ((n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / r).max(0.0);
        let cos_light =
            (-(light_normal[0] * d[0] + light_normal[1] * d[1] + light_normal[2] * d[2]) / r)
                .max(0.0);
        let factor = cos_receiver * cos_light * light_area / (std::f32::consts::PI * r2);
        let ambient = 1.5 * t;
        let e_in = [0, 1, 2].map(|c| emitted[c] * factor + ambient * emitted[c] / emitted[0]);
        irradiance.push(e_in);
        radiosity.push([0, 1, 2].map(|c| rho[c] * e_in[c]));
    }
    // Vertex radiance: area-weighted mean of the adjacent elements' B/π (equal areas within
    // a surface, so a plain mean over the triangles' elements, each counted once).
    let mut sum = vec![[0.0f32; 3]; mesh.positions.len()];
    let mut count = vec![0.0f32; mesh.positions.len()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let e = mesh.triangle_element[t] as usize;
        // Count each element once per vertex: only its first triangle's corners plus the
        // second triangle's new corner.
        let corners: &[u32] = if t % 2 == 0 { &tri[..] } else { &tri[2..] };
        for &v in corners {
            for c in 0..3 {
                sum[v as usize][c] += radiosity[e][c] / std::f32::consts::PI;
            }
            count[v as usize] += 1.0;
        }
    }
    let vertex_radiance = sum
        .iter()
        .zip(&count)
        .map(|(s, &k)| {
            if k > 0.0 {
                scale(*s, 1.0 / k)
            } else {
                [0.0; 3]
            }
        })
        .collect();
    ViewFrame {
        mesh_version: mesh.version,
        frame,
        vertex_radiance,
        element_radiosity: radiosity,
        element_illuminance: irradiance.iter().map(|&e| lux(e)).collect(),
        element_irradiance: irradiance,
    }
}
