//! The whole method in one call: scene → mesh → form factors → solution, and solution →
//! image. The command-line tool and the integration tests both go through here.

use crate::display::{shaded_triangles, Conformity, Shading};
use crate::formfactor::{FormFactorMethod, Visibility};
use crate::mesh::{Element, Mesh, MeshError, MeshOptions};
use crate::progress::Progress;
use crate::refine::RefineOptions;
use crate::render::{render, Image, RenderError, RenderOptions};
use crate::scene::{Camera, Scene};
use crate::solve::{solve, Solution, SolveError, SolveOptions};
use glam::DVec3;

/// Everything that decides how a scene is solved.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SolveSettings {
    pub mesh: MeshOptions,
    pub form_factor: FormFactorMethod,
    pub solve: SolveOptions,
}

/// A solved scene.
pub struct Solved {
    pub mesh: Mesh,
    pub solution: Solution,
    pub form_factor: FormFactorMethod,
}

/// Why solving failed.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error("meshing")]
    Mesh(#[from] MeshError),
    #[error("solving")]
    Solve(#[from] SolveError),
    #[error("rendering")]
    Render(#[from] RenderError),
}

/// Meshes and solves a scene.
pub fn solve_scene(
    scene: &Scene,
    settings: &SolveSettings,
    progress: &dyn Progress,
) -> Result<Solved, PipelineError> {
    let mesh = Mesh::build(scene, &settings.mesh)?;
    let solution = {
        let visibility = Visibility::new(&mesh);
        let ff = settings.form_factor.engine(&mesh, &visibility);
        solve(&mesh, ff.as_ref(), &settings.solve, progress)?
    };
    Ok(Solved {
        mesh,
        solution,
        form_factor: settings.form_factor,
    })
}

/// Meshes coarsely, solves, and refines where the radiosity gradient is high (see
/// [`crate::refine`]), re-solving after each pass, until nothing needs splitting, the depth
/// limit is reached or the element budget `refine.max_elements` is used.
///
/// The coarse mesh is [`coarse_mesh_options`] of `settings.mesh`.
pub fn solve_scene_adaptive(
    scene: &Scene,
    settings: &SolveSettings,
    refine: &RefineOptions,
    progress: &dyn Progress,
) -> Result<Solved, PipelineError> {
    let coarse = coarse_mesh_options(&settings.mesh);
    let mut mesh = Mesh::build(scene, &coarse)?;
    loop {
        let solution = {
            let visibility = Visibility::new(&mesh);
            let ff = settings.form_factor.engine(&mesh, &visibility);
            solve(&mesh, ff.as_ref(), &settings.solve, progress)?
        };
        let marked = crate::refine::mark(&mesh, &solution.radiosity, refine);
        if !marked.iter().any(|m| *m) {
            return Ok(Solved {
                mesh,
                solution,
                form_factor: settings.form_factor,
            });
        }
        mesh = crate::refine::refine(&mesh, &marked);
    }
}

/// The mesh adaptive refinement starts from: half the elements of `uniform` (edges √2
/// longer) and its patch subdivision divided by √2 (rounded), so the patches keep about the
/// uniform mesh's size while refinement has half the element budget to spend where the
/// radiosity changes fast.
pub fn coarse_mesh_options(uniform: &MeshOptions) -> MeshOptions {
    let r = std::f64::consts::SQRT_2;
    MeshOptions {
        elements: (uniform.elements / 2).max(1),
        max_element_size: uniform.max_element_size.map(|h| r * h),
        patch_subdivision: ((uniform.patch_subdivision as f64 / r).round() as u32).max(1),
    }
}

/// What to draw: elements with their radiosity (W·m⁻²).
pub struct Shaded<'a> {
    pub vertices: &'a [DVec3],
    pub elements: &'a [Element],
    pub radiosity: &'a [[f64; 3]],
}

/// Renders shaded elements from a camera; `wireframe` overlays the element edges.
pub fn render_elements(
    shaded: &Shaded,
    camera: &Camera,
    shading: Shading,
    wireframe: bool,
    options: &RenderOptions,
) -> Result<Image, PipelineError> {
    let conformity = Conformity::find(shaded.vertices, shaded.elements);
    let triangles = shaded_triangles(
        shaded.vertices,
        shaded.elements,
        shaded.radiosity,
        shading,
        &conformity,
        camera.eye,
    );
    let edges = if wireframe {
        crate::display::element_edges(shaded.vertices, shaded.elements)
    } else {
        Vec::new()
    };
    Ok(render(&triangles, &edges, camera, options)?)
}
