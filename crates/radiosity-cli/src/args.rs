//! Command-line arguments: plain values, handed to the library's settings resolution
//! ([`radiosity::settings::resolve`]), which validates them and names the flag when one is
//! wrong. Numbers are parsed leniently (negative counts are accepted here) so that the
//! library, not the parser, says what a good value is.

use clap::{Args, Parser, Subcommand};
use glam::DVec3;
use radiosity::formfactor::FormFactorMethod;
use radiosity::settings::Overrides;
use radiosity::solve::SolverKind;
use std::path::PathBuf;

/// Physically based diffuse global illumination by the radiosity method.
///
/// Scenes: OBJ+MTL (Kd = reflectance, Ke = emitted radiance in W·m⁻²·sr⁻¹), glTF 2.0
/// (.gltf, .glb), MGF or our JSON scene file; with no scene, the built-in Cornell box. Lengths in metres; radiosity and irradiance
/// in W·m⁻²; power in W; image pixels are radiance L = B/π.
#[derive(Debug, Parser)]
#[command(name = "radiosity", version, about = "Physically based diffuse global illumination by the radiosity method", long_about = None)]
pub struct Cli {
    /// Worker threads [default: one per core].
    #[arg(long, global = true, value_name = "N", allow_hyphen_values = true)]
    pub threads: Option<usize>,
    /// The command.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Solve a scene and render it to a PNG (sRGB) or EXR (linear radiance) image.
    Render(RenderArgs),
    /// Solve a scene and write a report (JSON, physical units) and/or the solution.
    Solve(SolveCmdArgs),
    /// Compute one form factor with one or every method, or print the accuracy table.
    Formfactor(crate::cmd_formfactor::FormfactorArgs),
    /// Solve by progressive refinement and write a frame at each listed shot count, plus a
    /// labelled contact sheet (the lecture's image sequences).
    Progressive(crate::cmd_progressive::ProgressiveArgs),
    /// Run every solver on the same mesh and plot their error against time and iterations.
    Compare(crate::cmd_compare::CompareArgs),
    /// Solve a scene (or load a saved solution) and show it live in a web browser: a local
    /// server on 127.0.0.1 whose address is printed; Ctrl-C stops it.
    View(crate::cmd_view::ViewCmdArgs),
    /// Print the shell completion script for bash, zsh, fish, elvish or powershell.
    Completions(crate::cmd_shell::CompletionsArgs),
    /// Print the manual page (roff), or write one page per command with -o DIR.
    Man(crate::cmd_shell::ManArgs),
    /// Illuminance (lx) at point sensors and on work-plane grids: JSON, CSV and false-colour
    /// PNG with Emin, Ē, Emax and the uniformity U0.
    Measure(crate::cmd_measure::MeasureArgs),
}

/// Options that decide how a scene is meshed and solved.
#[derive(Debug, Clone, Args)]
pub struct SolveArgs {
    /// Maximum element edge length in metres (overrides --elements; the classic solvers'
    /// mesh only: selects progressive refinement when no solver is named, refused with
    /// --solver hierarchical).
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub max_element_size: Option<f64>,
    /// Approximate total number of elements of the classic mesh [default: 4000]. With the
    /// hierarchical solver (the default): no element is subdivided below 1/N of the total
    /// surface area, so subdivision makes at most N leaves (input polygons smaller than that
    /// stay whole) [default there: 33333].
    #[arg(long, value_name = "N", allow_hyphen_values = true)]
    pub elements: Option<i64>,
    /// Elements per patch edge: patches shoot, elements receive (1 = every element shoots)
    /// [default: 3]. Classic mesh only, as --max-element-size.
    #[arg(long, value_name = "K", allow_hyphen_values = true)]
    pub patch_subdivision: Option<i64>,
    /// Solver [default: hierarchical; progressive when a classic-only option is given:
    /// --max-element-size, --patch-subdivision, --adaptive, --max-shots, --overshoot,
    /// --ambient].
    #[arg(long, value_enum)]
    pub solver: Option<SolverKind>,
    /// Form-factor method [default: raycast].
    #[arg(long, value_enum)]
    pub form_factor: Option<FormFactorMethod>,
    /// Stop at this relative change (Jacobi, Gauss–Seidel) or unshot power fraction
    /// (progressive) [default: 1e-3].
    #[arg(long, value_name = "X", allow_hyphen_values = true)]
    pub tolerance: Option<f64>,
    /// Stop progressive refinement after this many shots [default: 100 per patch].
    #[arg(long, value_name = "N", allow_hyphen_values = true)]
    pub max_shots: Option<i64>,
    /// Progressive refinement shoots ω × the unshot radiosity (over-relaxation), 0 < ω < 2
    /// [default: 1].
    #[arg(long, value_name = "W", allow_hyphen_values = true)]
    pub overshoot: Option<f64>,
    /// Hierarchical solver: the largest irradiance error one link may carry, as a fraction of
    /// its receiver's irradiance (smaller: more links, more accurate) [default: 0.01].
    #[arg(long, value_name = "X", allow_hyphen_values = true)]
    pub epsilon: Option<f64>,
    /// Adaptive meshing: start from half of --elements (edges √2 longer) and split elements
    /// where the radiosity changes fast, up to --elements in total.
    #[arg(long)]
    pub adaptive: bool,
    /// Adaptive: split where neighbouring elements differ by more than this fraction of the
    /// mean radiosity [default: 0.1].
    #[arg(
        long,
        value_name = "X",
        requires = "adaptive",
        allow_hyphen_values = true
    )]
    pub refine_threshold: Option<f64>,
    /// Adaptive: how many times an element may be split [default: 3].
    #[arg(
        long,
        value_name = "D",
        requires = "adaptive",
        allow_hyphen_values = true
    )]
    pub max_depth: Option<i64>,
    /// Show no progress and no summary.
    #[arg(long, short)]
    pub quiet: bool,
    #[command(flatten)]
    pub load: LoadArgs,
}

/// How scene files are read.
#[derive(Debug, Clone, Default, Args)]
pub struct LoadArgs {
    /// Make repairs errors: zero-area faces (skipped), reflectance ≥ 1 (clamped to 0.99),
    /// faces without a material (default grey), ignored texture, specular and transparency
    /// statements.
    #[arg(long)]
    pub strict: bool,
    /// Make every surface two-sided: both sides reflect (emission stays on the front).
    #[arg(long)]
    pub two_sided: bool,
    /// glTF: emitted radiance in W·m⁻²·sr⁻¹ per unit of emissive colour
    /// (emissiveFactor × emissiveStrength) [default: 1].
    #[arg(long, value_name = "X", allow_hyphen_values = true)]
    pub emission_scale: Option<f64>,
}

impl SolveArgs {
    /// The flags as overrides for the library's settings resolution.
    pub fn overrides(&self) -> Overrides {
        Overrides {
            elements: self.elements,
            max_element_size: self.max_element_size,
            patch_subdivision: self.patch_subdivision,
            solver: self.solver,
            form_factor: self.form_factor,
            tolerance: self.tolerance,
            max_shots: self.max_shots,
            overshoot: self.overshoot,
            epsilon: self.epsilon,
            adaptive: self.adaptive,
            refine_threshold: self.refine_threshold,
            max_depth: self.max_depth,
            ..Overrides::default()
        }
    }
}

/// Camera, image and display options.
#[derive(Debug, Clone, Args)]
pub struct ViewArgs {
    /// Image width in pixels [default: 512].
    #[arg(long, allow_hyphen_values = true)]
    pub width: Option<i64>,
    /// Image height in pixels [default: 512].
    #[arg(long, allow_hyphen_values = true)]
    pub height: Option<i64>,
    /// Camera position x,y,z in metres [default: the scene's camera]; alone, the camera
    /// looks at the centre of the scene.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<DVec3>,
    /// Point the camera looks at, x,y,z in metres.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<DVec3>,
    /// Camera up direction x,y,z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<DVec3>,
    /// Vertical field of view in degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub fov: Option<f64>,
    /// Flat shading (one value per element) instead of smooth (Gouraud) shading.
    #[arg(long)]
    pub flat: bool,
    /// Overlay the element edges.
    #[arg(long)]
    pub wireframe: bool,
    /// PNG exposure in stops (pixel = L · 2^exposure before the sRGB curve) [default: 0].
    #[arg(long, allow_hyphen_values = true)]
    pub exposure: Option<f64>,
    /// Anti-aliasing: supersamples per pixel axis (box filter) [default: 4].
    #[arg(long, allow_hyphen_values = true)]
    pub samples: Option<i64>,
    /// Add the ambient term of progressive refinement (for unconverged solutions).
    #[arg(long)]
    pub ambient: bool,
}

impl ViewArgs {
    /// Adds the view flags to `overrides`.
    pub fn add_to(&self, overrides: &mut Overrides) {
        overrides.width = self.width;
        overrides.height = self.height;
        overrides.samples = self.samples;
        overrides.exposure = self.exposure;
        overrides.ambient = self.ambient;
    }

    /// The camera flags.
    pub fn camera(&self) -> radiosity::settings::CameraOverrides {
        radiosity::settings::CameraOverrides {
            eye: self.eye,
            target: self.target,
            up: self.up,
            fov_deg: self.fov,
        }
    }
}

/// `radiosity solve`.
#[derive(Debug, Args)]
pub struct SolveCmdArgs {
    /// Scene file (.obj, .gltf, .glb, .mgf or .json); the built-in Cornell box if omitted.
    pub scene: Option<PathBuf>,
    /// Write the report (per-object radiosity, irradiance, absorbed power; totals) as JSON.
    #[arg(long, value_name = "OUT.json")]
    pub report: Option<PathBuf>,
    /// Save the solution, to render later with `render --solution`.
    #[arg(long, value_name = "FILE")]
    pub save: Option<PathBuf>,
    /// Write the solved scene as a GLB: per-vertex radiance (COLOR_0, _RADIANCE) and a
    /// lightmap (TEXCOORD_1, embedded PNG; also OUT_lightmap.png and OUT_lightmap.exr).
    #[arg(long, value_name = "OUT.glb")]
    pub bake: Option<PathBuf>,
    /// --bake: COLOR_0 as display-ready sRGB bytes (after --bake-exposure) instead of linear
    /// floats.
    #[arg(long, requires = "bake")]
    pub srgb_vertex_colors: bool,
    /// --bake: exposure in stops for COLOR_0 and the PNG lightmap (L · 2^stops) [default: 0].
    #[arg(
        long,
        value_name = "STOPS",
        requires = "bake",
        allow_hyphen_values = true
    )]
    pub bake_exposure: Option<f64>,
    /// --bake: the lightmap's longest side in texels [default: 2048].
    #[arg(long, value_name = "N", requires = "bake", allow_hyphen_values = true)]
    pub lightmap_size: Option<i64>,
    /// Overwrite output files that exist (without it, an existing output is an error).
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// `radiosity render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene file (.obj, .gltf, .glb, .mgf or .json); the built-in Cornell box if omitted.
    pub scene: Option<PathBuf>,
    /// Output image: .png (sRGB, 8-bit) or .exr (linear float RGB radiance)
    /// [default: named after the input: room.obj → room.png, box.solution.json → box.png,
    /// no scene → cornell.png].
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Overwrite the output if it exists (without it, an existing output is an error).
    #[arg(long)]
    pub force: bool,
    /// Render a saved solution (from `solve --save`) instead of solving a scene.
    #[arg(long, value_name = "FILE", conflicts_with = "scene")]
    pub solution: Option<PathBuf>,
    /// Show surfaces in false colour with a legend and iso-lines: illuminance in lx
    /// (`lux`) or luminance in cd/m² (`luminance`). PNG only.
    #[arg(long, value_enum, value_name = "QUANTITY")]
    pub false_colour: Option<crate::cmd_falsecolour::FalseColour>,
    #[command(flatten)]
    pub view: ViewArgs,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// Parses "x,y,z" into a finite vector.
pub fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!(
            "expected x,y,z (three comma-separated numbers), got '{s}'"
        ));
    }
    let mut v = [0.0; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        let x: f64 = p.parse().map_err(|_| format!("'{p}' is not a number"))?;
        if !x.is_finite() {
            return Err(format!("'{p}' is not a finite number"));
        }
        *slot = x;
    }
    Ok(DVec3::from_array(v))
}
