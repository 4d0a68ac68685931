//! The whole method in one call: scene → mesh → form factors → coupling → solution, and
//! solution → image. The command-line tool, the studies and the integration tests all go
//! through here.

use crate::accel::Visibility;
use crate::coupling::closure::Enclosure;
use crate::coupling::hierarchical::{HierarchicalError, HierarchicalOptions};
use crate::coupling::{Columns, Coupling, Dense, NearField};
use crate::display::{DisplayMesh, Shading};
use crate::formfactor::{engine, FormFactorMethod};
use crate::mesh::{Element, Mesh, MeshError, MeshOptions, RefineOptions};
use crate::progress::Progress;
use crate::render::{render, Image, RenderError, RenderOptions};
use crate::scene::{Camera, Scene};
use crate::solve::{solve, NoObserver, Observer, Solution, SolveError, SolveOptions, SolverKind};
use glam::DVec3;

/// Everything that decides how a scene is meshed and solved.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SolveSettings {
    /// How finely to mesh.
    pub mesh: MeshOptions,
    /// The form-factor method.
    pub form_factor: FormFactorMethod,
    /// The solver and its stopping rule.
    pub solve: SolveOptions,
    /// The hierarchical solver's link tolerance and minimum element area.
    pub hierarchical: HierarchicalOptions,
}

/// A solved scene.
pub struct Solved {
    /// The mesh the solution lives on.
    pub mesh: Mesh,
    /// Radiosity and irradiance per element.
    pub solution: Solution,
    /// The form-factor method used.
    pub form_factor: FormFactorMethod,
    /// What the hierarchical solver built (`None` for the classic solvers).
    pub hierarchy: Option<HierarchyStats>,
}

/// The size of a hierarchical solution.
#[derive(Debug, Clone, PartialEq)]
pub struct HierarchyStats {
    /// The link tolerance ε it was refined to.
    pub epsilon: f64,
    /// Links at the end.
    pub links: usize,
    /// Nodes of the hierarchy (clusters, polygons and their sub-elements).
    pub nodes: usize,
    /// Whether refinement stopped at the memory limit (the links are then coarser than ε).
    pub capped: bool,
    /// The hierarchy's estimated memory, bytes: nodes, links and prepared sources, what the
    /// memory limit is checked against.
    pub bytes: u64,
    /// Objects with elements whose links gathered more than their hemisphere (coincident or
    /// crossing copies of a surface), their irradiance scaled down, and how many elements.
    pub overfull: Vec<(String, usize)>,
}

impl HierarchyStats {
    /// What the user should know about the result: refinement stopped at the memory limit,
    /// or elements that gathered more than their hemisphere.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.capped {
            out.push(format!(
                "link refinement stopped at the memory limit, so some links are coarser than \
                 ε {}: the result is less accurate than asked",
                self.epsilon
            ));
        }
        if !self.overfull.is_empty() {
            let elements: usize = self.overfull.iter().map(|o| o.1).sum();
            let named: Vec<String> = self
                .overfull
                .iter()
                .take(5)
                .map(|(object, n)| format!("'{object}' ({n})"))
                .collect();
            let more = if self.overfull.len() > 5 { ", …" } else { "" };
            out.push(format!(
                "{elements} elements gathered more than their hemisphere, so their light was \
                 scaled down: coincident or crossing copies of a surface? In {}{more}",
                named.join(", ")
            ));
        }
        out
    }
}

/// Why solving failed.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// Meshing failed.
    #[error("meshing")]
    Mesh(#[from] MeshError),
    /// Solving failed.
    #[error("solving")]
    Solve(#[from] SolveError),
    /// Rendering failed.
    #[error("rendering")]
    Render(#[from] RenderError),
    /// The hierarchy could not be built.
    #[error("hierarchical radiosity")]
    Hierarchical(#[from] HierarchicalError),
}

/// Meshes and solves a scene.
pub fn solve_scene(
    scene: &Scene,
    settings: &SolveSettings,
    progress: &dyn Progress,
) -> Result<Solved, PipelineError> {
    solve_scene_observed(scene, settings, progress, &mut NoObserver)
}

/// Meshes and solves a scene, reporting the solver's steps to `observer`.
pub fn solve_scene_observed(
    scene: &Scene,
    settings: &SolveSettings,
    progress: &dyn Progress,
    observer: &mut dyn Observer,
) -> Result<Solved, PipelineError> {
    if settings.solve.solver == SolverKind::Hierarchical {
        // The hierarchy is built from the scene, so two-sided surfaces become explicit
        // back-to-back pairs first (meshing does the same for the other solvers).
        let explicit = crate::mesh::two_sided::with_back_sides(scene);
        let solved = crate::solve::hierarchical::solve(
            explicit.as_ref().unwrap_or(scene),
            settings.form_factor,
            settings.hierarchical,
            &settings.solve,
            observer,
            progress,
        )?;
        return Ok(Solved {
            mesh: solved.mesh,
            solution: solved.solution,
            form_factor: settings.form_factor,
            hierarchy: Some(HierarchyStats {
                epsilon: settings.hierarchical.epsilon,
                links: solved.links,
                nodes: solved.nodes,
                capped: solved.capped,
                bytes: solved.bytes,
                overfull: solved.overfull,
            }),
        });
    }
    let mut mesh = Mesh::build(scene, &settings.mesh)?;
    crate::direct::illuminate(&mut mesh, &scene.lights);
    let solution = solve_mesh(&mesh, settings, progress, observer)?;
    Ok(Solved {
        mesh,
        solution,
        form_factor: settings.form_factor,
        hierarchy: None,
    })
}

/// Bytes a solver needs beyond the mesh: the dense coupling (and the direct solver's patch
/// matrix and LU factors, 5 m² values) for the matrix solvers; nothing up front for
/// progressive refinement (its column cache takes what the limit leaves).
pub fn solver_memory(solver: SolverKind, elements: usize, patches: usize) -> u128 {
    let m = patches as u128;
    match solver {
        SolverKind::Progressive | SolverKind::Hierarchical => 0,
        SolverKind::Direct => Dense::bytes_for(elements, patches) + 5 * 8 * m * m,
        _ => Dense::bytes_for(elements, patches),
    }
}

/// Refuses a solve that would not fit in `settings.solve.memory_limit`.
pub fn check_memory(
    settings: &SolveOptions,
    elements: usize,
    patches: usize,
) -> Result<(), SolveError> {
    let needed = solver_memory(settings.solver, elements, patches);
    if needed > settings.memory_limit as u128 {
        return Err(SolveError::OutOfMemory {
            solver: settings.solver,
            needed_mib: (needed >> 20).min(u64::MAX as u128) as u64,
            limit_mib: settings.memory_limit >> 20,
            elements,
            patches,
        });
    }
    Ok(())
}

/// Solves a meshed scene: visibility, the link-level oracle, the form-factor engine, the
/// coupling the solver needs (dense for the matrix solvers, columns on the fly for
/// progressive refinement), then the solver. Light sources reach it through the mesh's
/// first shot ([`Mesh::direct`], filled by [`crate::direct::illuminate`]).
pub fn solve_mesh(
    mesh: &Mesh,
    settings: &SolveSettings,
    progress: &dyn Progress,
    observer: &mut dyn Observer,
) -> Result<Solution, PipelineError> {
    check_memory(&settings.solve, mesh.elements.len(), mesh.patches.len())?;
    let visibility = Visibility::new(mesh);
    let near = NearField::decide(mesh);
    let enclosure = Enclosure::probe(mesh, &visibility);
    let engine = engine(settings.form_factor, mesh, &visibility, &near.per_element);
    let solution = match settings.solve.solver {
        SolverKind::Progressive => {
            let coupling = Columns::new(
                mesh,
                engine.as_ref(),
                &near,
                enclosure,
                settings.solve.memory_limit / 2,
            );
            solve(&coupling, &settings.solve, observer)?
        }
        _ => {
            let coupling = Dense::compute(mesh, engine.as_ref(), &near, enclosure, progress);
            solve(&coupling as &dyn Coupling, &settings.solve, observer)?
        }
    };
    Ok(solution)
}

/// Meshes coarsely, solves, and refines where the radiosity gradient is high (see
/// [`crate::mesh::refine`]), re-solving after each pass, until nothing needs splitting, the
/// depth limit is reached or the element budget `refine.max_elements` is used.
///
/// The coarse mesh is [`coarse_mesh_options`] of `settings.mesh`.
pub fn solve_scene_adaptive(
    scene: &Scene,
    settings: &SolveSettings,
    refine: &RefineOptions,
    progress: &dyn Progress,
) -> Result<Solved, PipelineError> {
    solve_scene_adaptive_observed(scene, settings, refine, progress, &mut NoObserver)
}

/// [`solve_scene_adaptive`], reporting every solve's steps to `observer`.
pub fn solve_scene_adaptive_observed(
    scene: &Scene,
    settings: &SolveSettings,
    refine: &RefineOptions,
    progress: &dyn Progress,
    observer: &mut dyn Observer,
) -> Result<Solved, PipelineError> {
    let coarse = coarse_mesh_options(&settings.mesh);
    let mut mesh = Mesh::build(scene, &coarse)?;
    crate::direct::illuminate(&mut mesh, &scene.lights);
    loop {
        let solution = solve_mesh(&mesh, settings, progress, observer)?;
        let marked = crate::mesh::refine::mark(&mesh, &solution.radiosity, refine);
        if !marked.iter().any(|m| *m) {
            return Ok(Solved {
                mesh,
                solution,
                form_factor: settings.form_factor,
                hierarchy: None,
            });
        }
        mesh = crate::mesh::refine::refine(&mesh, &marked);
        crate::direct::illuminate(&mut mesh, &scene.lights);
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
    /// Mesh vertices, m.
    pub vertices: &'a [DVec3],
    /// The elements.
    pub elements: &'a [Element],
    /// Radiosity per element, W·m⁻².
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
    let display = DisplayMesh::build(shaded.vertices, shaded.elements, shaded.radiosity, shading);
    let twinned = crate::display::back_to_back(shaded.vertices, shaded.elements);
    let triangles = display.shaded_triangles(shaded.elements, &|e| twinned[e], camera.eye);
    let edges = if wireframe {
        crate::display::element_edges(shaded.vertices, shaded.elements)
    } else {
        Vec::new()
    };
    Ok(render(&triangles, &edges, camera, options)?)
}
