//! MGF (Materials and Geometry Format) input.
//!
//! MGF is Greg Ward's description language for lighting simulation (G. Ward, "The Materials
//! and Geometry Format", LBL, version 1.0 May 1995 and 1.1 February 1996, the `mgfdoc`
//! shipped with Radiance's `src/cv/mgflib`, which describes the language of MGF parser version
//! 2.0). RenderPark's and Radiance's test scenes use it. Section numbers below refer to that
//! document.
//!
//! # The mapping onto the scene model
//! - **Lengths** are metres: MGF's default unit is the metre (spec §2, "MGF Basics"), and a
//!   file in other units says so with a global `xf -s`. Nothing is rescaled here.
//! - **Entities** (spec §3): `#` comments; `o` object contexts (nested names joined with `.`;
//!   geometry outside any `o` belongs to an object named after its file's stem); `xf`
//!   transforms with every option (`-t -rx -ry -rz -s -mx -my -mz -i N -a N`), nesting, arrays
//!   and the `xf` that ends one; `i` includes (with an optional transform); the colour context
//!   `c` with `cxy`, `cspec`, `cct`, `cmix`; the material context `m` with `sides`, `rd`, `ed`
//!   (and `td`, `rs`, `ts`, `ir`, read and checked but ignored, see below); the vertex context
//!   `v` with `p` and `n`; geometry `f`, `fh`, `sph`, `cyl`, `cone`, `ring`, `torus`, `prism`.
//!   `ies` (IESNA luminaire include) is rejected with a clear error; any other keyword is an
//!   error "unknown MGF entity" (the reference parser only warns; we prefer not to drop
//!   geometry silently).
//! - **Named contexts** (`c`, `m`, `v`) have the spec's four forms (`c`, `c id`, `c id =`,
//!   `c id = template`). Field entities write into the current context; a named context keeps
//!   its changes, the unnamed one is reset by the bare keyword. Geometry takes the material and
//!   the vertices as they are when the geometry entity is read (spec §2.1): a material that
//!   changes after use becomes a second scene material named `name#2` (then `#3`, …).
//! - **Materials**: `rd ρ_d` (diffuse reflectance, photometric, spec §3 `rd`) in the current
//!   colour becomes ρ per RGB channel; `ed ε_d` (diffuse emittance in lumens per square metre,
//!   spec §3 `ed`: "the total lumen output … is the radiating area … multiplied by its
//!   emittance", i.e. a luminous exitance M_v) becomes the emitted radiance L_e; `sides 2`
//!   (the MGF default: the unnamed material is a "two-sided black absorber") sets
//!   [`Material::two_sided`], `sides 1` leaves it one-sided. Our emission is front side only,
//!   so a two-sided emitting material gets a warning. `td`, `rs`, `ts` and `ir` have no place
//!   in a Lambertian radiosity model: each material that sets one of them to a non-default
//!   value gets one warning naming what is ignored.
//! - **Faces**: `f` goes through [`split_into_convex`] (planar convex faces pass unchanged,
//!   non-planar quads are split, planar non-convex faces are ear-clipped); a face whose ear
//!   clipping fails because it has MGF "seams" (a hole joined to the outline by an edge walked
//!   both ways, spec §3 `f`) is triangulated by a seam-aware ear clipper whose triangles are
//!   checked not to overlap. `fh` (face with holes, spec v1.1) joins each hole to the outline
//!   by a bridge to the nearest visible vertex and triangulates the result the same way; holes
//!   must lie strictly inside the outline and no two contours may touch. A face of zero area
//!   is skipped with a warning; a missing vertex is an error. Vertex normals (`n`) are read and
//!   checked but ignored by `f`, `fh` and `prism` (which would use them only for smooth
//!   shading): every polygon is flat with its geometric normal.
//! - **Curved primitives** are tessellated into planar convex polygons whose vertices lie on
//!   the exact surface (see "Tessellation"), outward-facing for positive radii and inward for
//!   the negative radii (`sph`, `cyl`, `cone`, `torus`) or negative `prism` length the spec
//!   allows. `ring` and `torus` need a vertex normal; `ring` faces along it.
//! - **Transforms** apply to geometry only, never to vertices when they are defined (spec
//!   §2.2.2). Arguments act in order ("each subsequent transformation argument affects the
//!   objects relative to their new position"); an enclosed `xf` is applied before the
//!   enclosing ones. A transform that mirrors (an odd number of `-m` or a negative `-s`)
//!   reverses vertex order so faces keep their (mirrored) orientation, as the reference parser
//!   does. `-a N` arrays make N instances of all geometry up to the matching `xf` (or of the
//!   included file); the instance with array indices i, j is put in an object named `ai.j`
//!   inside the current object, as the reference parser names them. Unlike the reference
//!   parser, which re-reads the array body once per instance, we emit every instance of each
//!   geometry entity when it is read: the result is the same unless the body depends on
//!   context changes it makes after its own geometry (the next instance would see them there).
//! - **Includes**: `i file` is resolved against the including file's directory. Every error
//!   and warning names the file it comes from (its path joined onto the top file's directory,
//!   as the user named that) and the line; an included file must balance its own `xf`
//!   contexts (an unclosed `xf` is an error, an unclosed `o` a warning).
//!
//! # Colour
//! Every colour is kept as CIE 1931 XYZ with Y = 1 (a chromaticity). `cxy x y` gives
//! (x/y, 1, (1 − x − y)/y). `cspec` and `cct` integrate a spectrum against the CIE 1931 2°
//! colour-matching functions (CIE 15:2004 table, 5 nm steps from 380 to 780 nm, linearly
//! interpolated): `cspec` samples are linearly interpolated and summed at 1 nm steps (zero
//! outside their range, spec §3 `cspec`); `cct T` sums Planck's law
//! B(λ, T) ∝ λ⁻⁵ / (exp(c₂/λT) − 1), c₂ = 1.4388·10⁻² m·K, at the table's 5 nm steps (CIE 15
//! practice; Illuminant A, 2856 K, comes out within 4·10⁻⁵ of its tabulated (0.44757,
//! 0.40745)). `cmix w₁ c₁ w₂ c₂ …` adds the colours with weights that are relative luminances
//! (spec §6.1.1): XYZ = Σ wᵢ·XYZᵢ with each Yᵢ = 1. (The reference parser mixes spectrally
//! when any operand is spectral, first turning CIE colours into approximate spectra; our XYZ
//! mix is the exact colorimetric sum.)
//!
//! A chromaticity becomes linear-sRGB channel *ratios* c = (R, G, B) through the sRGB matrix
//! (IEC 61966-2-1) derived from its primaries R (0.64, 0.33), G (0.30, 0.60), B (0.15, 0.06) and
//! white point D65 (0.3127, 0.3290): c = M⁻¹·XYZ. [`MgfWhite`] says which chromaticity counts
//! as white:
//! - [`MgfWhite::EqualEnergy`] (the default): MGF colours are measured against an
//!   equal-energy white — the unnamed colour is "neutral (i.e. equal-energy) grey" and
//!   reflectance "assumes an equal-energy white light source" (spec §3 `c`, `rd`) — so the
//!   equal-energy point E (1/3, 1/3) must give equal RGB: c = (M⁻¹·XYZ) ⊘ (M⁻¹·XYZ_E), a
//!   von Kries scaling in the sRGB primaries, the same as using the sRGB primaries with white
//!   point E (what MGF's own `cvrgb.c` example and RenderPark do). Without it every neutral
//!   MGF surface would come out pink (E in D65 sRGB is (1.205, 0.948, 0.909)).
//! - [`MgfWhite::D65`]: absolute sRGB colorimetry, c = M⁻¹·XYZ; D65 gives equal RGB.
//!
//! Channels that come out negative (a colour outside the sRGB gamut) are clamped to 0 with a
//! warning; the ratios are then normalised to unit luminance Y(c) = 0.2126 R + 0.7152 G +
//! 0.0722 B (the project's luminance of linear sRGB), so the photometric value is kept:
//! - ρ = ρ_d · c / Y(c); a channel ≥ 1 is clamped to [`MAX_REFLECTANCE`] with a warning.
//! - L_e = (ε_d / π) / K_m · c / Y(c), K_m = [`LUMINOUS_EFFICACY`] = 683 lm/W: ε_d / π is the
//!   luminance (cd/m²) of a Lambertian emitter of luminous exitance ε_d (lm/m²), and a luminous
//!   quantity V of colour c is V / 683 · c / Y(c) in the project's photometric convention.
//!   (RenderPark converts lm to W with 183.07 lm/W, the efficacy of equal-energy white,
//!   instead of 683, so its radiometric values for the same file are 683/183.07 ≈ 3.73 times
//!   ours.)
//!
//! # Tessellation
//! With n = [`MgfOptions::circle_segments`] (default 24, i.e. 15° per segment; the reference
//! parser uses 20): circles (`cyl`, `cone`, `ring`) get n segments, `torus` n × n quads,
//! `sph` n longitudes × ⌈n/2⌉ latitude bands (quads, triangles at the poles). Every polygon is
//! an isosceles trapezoid or a triangle with its vertices on the exact surface, hence planar
//! and convex. Inscribed facets make the area too small: a cylinder's by the factor
//! sin(π/n)/(π/n) (0.29 % at n = 24). The sphere's facet planes are all at least d_min from
//! the centre (derived in the tests; d_min = 0.98311 r at n = 24), and a convex body between
//! the balls of radii d_min and r has area between 4π·d_min² and 4πr² and volume between
//! (4/3)π·d_min³ and (4/3)πr³ (3.4 % and 5.0 % at n = 24).
//!
//! # Safety
//! Numbers must parse completely and be finite. Includes nest at most [`MAX_INCLUDE_DEPTH`]
//! deep and may not form a cycle; at most 10 000 includes and 10 million logical lines are
//! read in all, a logical line (with `\` continuations) is at most 1 MiB, a face has at most
//! 1024 vertices, an `xf` context at most 100 000 instances (`-i N` ≤ 10⁶, `-a N` ≤ 10⁵),
//! and the scene at most [`MgfOptions::max_surfaces`] surfaces. Nothing panics on bad input;
//! every error names the file and line.
//!
//! See also: [`crate::io::obj`] for the other polygon format.

use crate::geometry::{newell, split_into_convex, GeometryError, Polygon};
use crate::io::error::{Location, SceneError};
use crate::io::obj::{material_problem, scene_name};
use crate::scene::{Material, MaterialId, Origin, Scene, Surface};
use glam::{DMat3, DVec2, DVec3};
use std::collections::{HashMap, HashSet};
use std::f64::consts::PI;
use std::fmt;
use std::io;
use std::path::{Component, Path, PathBuf};

/// Deepest allowed nesting of `i` includes (the top file is depth 1).
pub const MAX_INCLUDE_DEPTH: usize = 32;

/// The largest reflectance a channel may have after colour conversion; larger values are
/// clamped to it with a warning (the scene model needs ρ < 1).
pub const MAX_REFLECTANCE: f64 = 0.99;

/// Luminous efficacy K_m = 683 lm/W used to turn luminous quantities into the project's
/// radiometric ones (see the module documentation, "Colour").
pub const LUMINOUS_EFFICACY: f64 = 683.0;

/// Default number of segments per full circle in tessellations (15° each).
pub const DEFAULT_CIRCLE_SEGMENTS: u32 = 24;

/// Largest accepted [`MgfOptions::circle_segments`] (1° per segment).
pub const MAX_CIRCLE_SEGMENTS: u32 = 360;

/// Luminance weights of linear sRGB, Y = 0.2126 R + 0.7152 G + 0.0722 B (ITU-R BT.709).
const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

const MAX_INCLUDES: usize = 10_000;
const MAX_LINES: usize = 10_000_000;
const MAX_LINE_BYTES: usize = 1 << 20;
const MAX_FACE_VERTICES: usize = 1024;
const MAX_INSTANCES: usize = 100_000;
const MAX_ITERATIONS: i64 = 1_000_000;
const MAX_ARRAY: i64 = 100_000;
const MAX_WARNINGS: usize = 1000;

/// Which chromaticity is white when MGF colours become linear-sRGB ratios.
///
/// See the module documentation, "Colour", for the formulas and why
/// [`MgfWhite::EqualEnergy`] is the default.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MgfWhite {
    /// The equal-energy point E (x = y = 1/3) maps to equal RGB (von Kries scaling of the
    /// sRGB primaries): MGF's neutral grey stays grey.
    #[default]
    EqualEnergy,
    /// Absolute sRGB (IEC 61966-2-1): D65 (0.3127, 0.3290) maps to equal RGB.
    D65,
}

/// How to read an MGF file.
#[derive(Debug, Clone, PartialEq)]
pub struct MgfOptions {
    /// Turn every warning into an error (at the warning's file and line).
    pub strict: bool,
    /// The white point of the colour conversion.
    pub white: MgfWhite,
    /// Segments per full circle for curved primitives, 3 ..= [`MAX_CIRCLE_SEGMENTS`].
    pub circle_segments: u32,
    /// Most surfaces the scene may get (a guard against runaway arrays), ≥ 1.
    pub max_surfaces: usize,
}

impl Default for MgfOptions {
    /// Lenient, equal-energy white, 24 segments per circle, at most one million surfaces.
    fn default() -> Self {
        Self {
            strict: false,
            white: MgfWhite::EqualEnergy,
            circle_segments: DEFAULT_CIRCLE_SEGMENTS,
            max_surfaces: 1_000_000,
        }
    }
}

/// Something in the input that was read with a loss or a guess (an ignored material property,
/// a clamped colour, a skipped zero-area face), and where.
#[derive(Debug, Clone, PartialEq)]
pub struct MgfWarning {
    /// File and line the warning is about.
    pub at: Location,
    /// What happened.
    pub message: String,
}

impl fmt::Display for MgfWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: warning: {}", self.at, self.message)
    }
}

/// A loaded MGF scene and the warnings raised while reading it (in input order).
#[derive(Debug, Clone, PartialEq)]
pub struct MgfScene {
    /// The scene, named after the top file's stem, without camera or point lights.
    pub scene: Scene,
    /// Warnings, each naming file and line; at most 1000 are listed, then one that counts
    /// the rest.
    pub warnings: Vec<MgfWarning>,
}

/// Why an MGF file could not be loaded. Every variant names the file and, where there is one,
/// the line.
#[derive(Debug, thiserror::Error)]
pub enum MgfError {
    /// The top file could not be read.
    #[error("{file}: cannot read: {source}")]
    Read {
        /// The file as the caller named it.
        file: String,
        /// Why.
        #[source]
        source: io::Error,
    },
    /// An `i` entity names a file that cannot be read.
    #[error("{at}: cannot read included file '{file}': {source}")]
    Include {
        /// The `i` entity.
        at: Location,
        /// The included file, resolved against the top file's directory.
        file: String,
        /// Why.
        #[source]
        source: io::Error,
    },
    /// A keyword that is not an MGF entity.
    #[error("{at}: unknown MGF entity '{keyword}'")]
    UnknownEntity {
        /// Where.
        at: Location,
        /// The keyword as written.
        keyword: String,
    },
    /// An MGF entity this loader does not read.
    #[error("{at}: MGF entity '{keyword}' is not supported: {reason}")]
    Unsupported {
        /// Where.
        at: Location,
        /// The entity.
        keyword: String,
        /// Why not, and what to do instead.
        reason: String,
    },
    /// Wrong number or kind of arguments (a word that is not a number, a bad name, a bad
    /// transform option).
    #[error("{at}: {message}")]
    Syntax {
        /// Where.
        at: Location,
        /// What is wrong.
        message: String,
    },
    /// A number that is NaN or infinite.
    #[error("{at}: {what} '{value}' is not a finite number")]
    NonFinite {
        /// Where.
        at: Location,
        /// Which argument.
        what: String,
        /// The word as written.
        value: String,
    },
    /// A reference to a colour, material or vertex that was never defined.
    #[error("{at}: {kind} '{name}' is not defined")]
    Undefined {
        /// Where.
        at: Location,
        /// "colour", "material" or "vertex".
        kind: &'static str,
        /// The name as written.
        name: String,
    },
    /// A value that parses but is not allowed (a zero radius, a reflectance above 1, a
    /// chromaticity outside the CIE diagram, a normal missing where one is needed).
    #[error("{at}: {message}")]
    Invalid {
        /// Where.
        at: Location,
        /// What is wrong.
        message: String,
    },
    /// An `xf` or `o` that closes nothing, or an `xf` left open at the end of its file.
    #[error("{at}: {message}")]
    Context {
        /// The closing entity, or the opening one that is never closed.
        at: Location,
        /// What is wrong.
        message: String,
    },
    /// An include that (directly or not) includes itself.
    #[error("{at}: include cycle: {chain}")]
    IncludeCycle {
        /// The `i` entity that closes the cycle.
        at: Location,
        /// The files of the cycle, "a.mgf → b.mgf → a.mgf".
        chain: String,
    },
    /// Includes nested more than [`MAX_INCLUDE_DEPTH`] deep.
    #[error("{at}: includes nested more than {limit} files deep")]
    IncludeDepth {
        /// The `i` entity one level too deep.
        at: Location,
        /// The limit.
        limit: usize,
    },
    /// A face that is not a usable polygon (non-planar with more than four vertices, out of
    /// range, self-intersecting).
    #[error("{at}: object '{object}': {source}")]
    Geometry {
        /// Where.
        at: Location,
        /// The object the face belongs to.
        object: String,
        /// What is wrong with it.
        #[source]
        source: GeometryError,
    },
    /// One of the safety limits (module documentation, "Safety") was reached.
    #[error("{at}: {message}")]
    Limit {
        /// Where.
        at: Location,
        /// Which limit.
        message: String,
    },
    /// A warning, raised as an error because [`MgfOptions::strict`] is set.
    #[error("{at}: {message} (an error in strict mode)")]
    Strict {
        /// Where.
        at: Location,
        /// The warning.
        message: String,
    },
    /// The options are out of range.
    #[error("{file}: bad MGF options: {message}")]
    Options {
        /// The top file.
        file: String,
        /// What is wrong.
        message: String,
    },
    /// The input defines no surfaces.
    #[error("{file}: scene has no surfaces")]
    Empty {
        /// The top file.
        file: String,
    },
}

impl MgfError {
    /// The file and line the error is about (the file alone for whole-file errors).
    pub fn location(&self) -> Location {
        match self {
            Self::Read { file, .. } | Self::Options { file, .. } | Self::Empty { file } => {
                Location::file(file.clone())
            }
            Self::Include { at, .. }
            | Self::UnknownEntity { at, .. }
            | Self::Unsupported { at, .. }
            | Self::Syntax { at, .. }
            | Self::NonFinite { at, .. }
            | Self::Undefined { at, .. }
            | Self::Invalid { at, .. }
            | Self::Context { at, .. }
            | Self::IncludeCycle { at, .. }
            | Self::IncludeDepth { at, .. }
            | Self::Geometry { at, .. }
            | Self::Limit { at, .. }
            | Self::Strict { at, .. } => at.clone(),
        }
    }
}

impl From<MgfError> for SceneError {
    /// Maps onto the scene errors: read failures, geometry and empty scenes keep their
    /// variants; syntax-like errors become [`SceneError::Syntax`], the rest
    /// [`SceneError::Invalid`], with the same message.
    fn from(error: MgfError) -> Self {
        let at = error.location();
        let full = error.to_string();
        let prefix = format!("{at}: ");
        let message = full.strip_prefix(&prefix).unwrap_or(&full).to_owned();
        match error {
            MgfError::Read { file, source } => SceneError::Read { file, source },
            MgfError::Geometry { at, object, source } => {
                SceneError::Geometry { at, object, source }
            }
            MgfError::Empty { file } => SceneError::Empty { file },
            MgfError::UnknownEntity { .. }
            | MgfError::Syntax { .. }
            | MgfError::NonFinite { .. }
            | MgfError::Unsupported { .. } => SceneError::Syntax { at, message },
            _ => SceneError::Invalid { at, message },
        }
    }
}

type Result<T, E = MgfError> = std::result::Result<T, E>;

/// Loads an MGF file and the files it includes, with [`MgfOptions::default`].
///
/// Errors and warnings name files as `path` names them (included files joined onto its
/// directory).
pub fn load_mgf(path: &Path) -> Result<MgfScene> {
    load_mgf_with(path, &MgfOptions::default())
}

/// Loads an MGF file and the files it includes with the given options.
pub fn load_mgf_with(path: &Path, options: &MgfOptions) -> Result<MgfScene> {
    let file = path.display().to_string();
    let text = crate::io::open::read_to_string_checked(path, crate::io::open::Kind::Geometry)
        .map_err(|source| MgfError::Read {
            file: file.clone(),
            source,
        })?;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    parse_mgf_with(&text, &file, options, |relative| {
        crate::io::open::read_to_string_checked(
            &dir.join(relative),
            crate::io::open::Kind::Geometry,
        )
    })
}

/// Parses MGF text already in memory, with [`MgfOptions::default`].
///
/// `file_label` names the input in errors, warnings and each surface's [`Origin`]; the scene
/// is named after its stem. `read_include` is called for every `i` entity with the included
/// file's path resolved against the including file's directory and expressed relative to the
/// top file's directory (`i lamps/lamp.mgf` inside `parts/room.mgf` asks for
/// `parts/lamps/lamp.mgf`), lexically normalised; it returns the file's text.
pub fn parse_mgf(
    text: &str,
    file_label: &str,
    read_include: impl FnMut(&Path) -> io::Result<String>,
) -> Result<MgfScene> {
    parse_mgf_with(text, file_label, &MgfOptions::default(), read_include)
}

/// Parses MGF text already in memory with the given options; see [`parse_mgf`].
pub fn parse_mgf_with(
    text: &str,
    file_label: &str,
    options: &MgfOptions,
    read_include: impl FnMut(&Path) -> io::Result<String>,
) -> Result<MgfScene> {
    if !(3..=MAX_CIRCLE_SEGMENTS).contains(&options.circle_segments) {
        return Err(MgfError::Options {
            file: file_label.to_owned(),
            message: format!(
                "circle_segments {} must be in 3..={MAX_CIRCLE_SEGMENTS}",
                options.circle_segments
            ),
        });
    }
    if options.max_surfaces == 0 {
        return Err(MgfError::Options {
            file: file_label.to_owned(),
            message: "max_surfaces must be at least 1".to_owned(),
        });
    }
    let top = Path::new(file_label);
    let top_relative = PathBuf::from(top.file_name().unwrap_or(top.as_os_str()));
    let mut parser = Parser::new(options, file_label, read_include);
    parser.include_stack.push(top_relative.clone());
    parser.run_file(text, file_label, &top_relative)?;
    parser.finish(file_label)
}

/// Linear-sRGB values of a CIE 1931 XYZ colour, before any clamping or normalisation:
/// M⁻¹·XYZ for [`MgfWhite::D65`], (M⁻¹·XYZ) ⊘ (M⁻¹·(1, 1, 1)) for [`MgfWhite::EqualEnergy`],
/// with M the sRGB primaries' matrix (IEC 61966-2-1, derived from the primaries and D65).
///
/// For example (D65) the D65 white point (0.3127/0.3290, 1, 0.3583/0.3290) gives (1, 1, 1).
pub fn linear_srgb_from_xyz(xyz: [f64; 3], white: MgfWhite) -> [f64; 3] {
    ColourSpace::new(white)
        .rgb(DVec3::from_array(xyz))
        .to_array()
}

// ---------------------------------------------------------------------------------------------
// Colour

/// CIE 1931 2° colour-matching functions x̄, ȳ, z̄ at 5 nm from 380 to 780 nm (CIE 15:2004,
/// Table T.4).
const CIE1931_CMF: [[f64; 3]; 81] = [
    [0.001368, 3.9e-05, 0.006450001],
    [0.002236, 6.4e-05, 0.01054999],
    [0.004243, 0.00012, 0.02005001],
    [0.00765, 0.000217, 0.03621],
    [0.01431, 0.000396, 0.06785001],
    [0.02319, 0.00064, 0.1102],
    [0.04351, 0.00121, 0.2074],
    [0.07763, 0.00218, 0.3713],
    [0.13438, 0.004, 0.6456],
    [0.21477, 0.0073, 1.0390501],
    [0.2839, 0.0116, 1.3856],
    [0.3285, 0.01684, 1.62296],
    [0.34828, 0.023, 1.74706],
    [0.34806, 0.0298, 1.7826],
    [0.3362, 0.038, 1.77211],
    [0.3187, 0.048, 1.7441],
    [0.2908, 0.06, 1.6692],
    [0.2511, 0.0739, 1.5281],
    [0.19536, 0.09098, 1.28764],
    [0.1421, 0.1126, 1.0419],
    [0.09564, 0.13902, 0.8129501],
    [0.05795001, 0.1693, 0.6162],
    [0.03201, 0.20802, 0.46518],
    [0.0147, 0.2586, 0.3533],
    [0.0049, 0.323, 0.272],
    [0.0024, 0.4073, 0.2123],
    [0.0093, 0.503, 0.1582],
    [0.0291, 0.6082, 0.1117],
    [0.06327, 0.71, 0.07824999],
    [0.1096, 0.7932, 0.05725001],
    [0.1655, 0.862, 0.04216],
    [0.2257499, 0.9148501, 0.02984],
    [0.2904, 0.954, 0.0203],
    [0.3597, 0.9803, 0.0134],
    [0.4334499, 0.9949501, 0.008749999],
    [0.5120501, 1.0, 0.005749999],
    [0.5945, 0.995, 0.0039],
    [0.6784, 0.9786, 0.002749999],
    [0.7621, 0.952, 0.0021],
    [0.8425, 0.9154, 0.0018],
    [0.9163, 0.87, 0.001650001],
    [0.9786, 0.8163, 0.0014],
    [1.0263, 0.757, 0.0011],
    [1.0567, 0.6949, 0.001],
    [1.0622, 0.631, 0.0008],
    [1.0456, 0.5668, 0.0006],
    [1.0026, 0.503, 0.00034],
    [0.9384, 0.4412, 0.00024],
    [0.8544499, 0.381, 0.00019],
    [0.7514, 0.321, 0.0001],
    [0.6424, 0.265, 4.999999e-05],
    [0.5419, 0.217, 3.0e-05],
    [0.4479, 0.175, 2.0e-05],
    [0.3608, 0.1382, 1.0e-05],
    [0.2835, 0.107, 0.0],
    [0.2187, 0.0816, 0.0],
    [0.1649, 0.061, 0.0],
    [0.1212, 0.04458, 0.0],
    [0.0874, 0.032, 0.0],
    [0.0636, 0.0232, 0.0],
    [0.04677, 0.017, 0.0],
    [0.0329, 0.01192, 0.0],
    [0.0227, 0.00821, 0.0],
    [0.01584, 0.005723, 0.0],
    [0.01135916, 0.004102, 0.0],
    [0.008110916, 0.002929, 0.0],
    [0.005790346, 0.002091, 0.0],
    [0.004109457, 0.001484, 0.0],
    [0.002899327, 0.001047, 0.0],
    [0.00204919, 0.00074, 0.0],
    [0.001439971, 0.00052, 0.0],
    [0.0009999493, 0.0003611, 0.0],
    [0.0006900786, 0.0002492, 0.0],
    [0.0004760213, 0.0001719, 0.0],
    [0.0003323011, 0.00012, 0.0],
    [0.0002348261, 8.48e-05, 0.0],
    [0.0001661505, 6.0e-05, 0.0],
    [0.000117413, 4.24e-05, 0.0],
    [8.307527e-05, 3.0e-05, 0.0],
    [5.870652e-05, 2.12e-05, 0.0],
    [4.150994e-05, 1.499e-05, 0.0],
];
const CMF_START_NM: f64 = 380.0;
const CMF_STEP_NM: f64 = 5.0;
const CMF_END_NM: f64 = 780.0;

/// Second radiation constant c₂ in µm·K (ITS-90 value, used for CIE Illuminant A).
const PLANCK_C2_UM_K: f64 = 14_388.0;

/// The colour-matching functions at `lambda` nm, linearly interpolated; zero outside the table.
fn cmf(lambda: f64) -> DVec3 {
    if !(CMF_START_NM..=CMF_END_NM).contains(&lambda) {
        return DVec3::ZERO;
    }
    let t = (lambda - CMF_START_NM) / CMF_STEP_NM;
    let i = (t.floor() as usize).min(CIE1931_CMF.len() - 2);
    let f = t - i as f64;
    DVec3::from_array(CIE1931_CMF[i]) * (1.0 - f) + DVec3::from_array(CIE1931_CMF[i + 1]) * f
}

/// XYZ of a sampled spectrum (`values` evenly spaced from `lambda_min` to `lambda_max` nm,
/// linearly interpolated, zero outside), summed at 1 nm steps.
fn spectrum_xyz(lambda_min: f64, lambda_max: f64, values: &[f64]) -> DVec3 {
    let step = (lambda_max - lambda_min) / (values.len() - 1) as f64;
    let first = lambda_min.max(CMF_START_NM).ceil() as i64;
    let last = lambda_max.min(CMF_END_NM).floor() as i64;
    let mut sum = DVec3::ZERO;
    for nm in first..=last {
        let lambda = nm as f64;
        let t = ((lambda - lambda_min) / step).clamp(0.0, (values.len() - 1) as f64);
        let i = (t.floor() as usize).min(values.len() - 2);
        let f = t - i as f64;
        let s = values[i] * (1.0 - f) + values[i + 1] * f;
        sum += cmf(lambda) * s;
    }
    sum
}

/// XYZ (relative) of a black body at `kelvin`, Planck's law summed at the table's 5 nm steps.
fn blackbody_xyz(kelvin: f64) -> DVec3 {
    let mut sum = DVec3::ZERO;
    for (i, row) in CIE1931_CMF.iter().enumerate() {
        let um = (CMF_START_NM + CMF_STEP_NM * i as f64) * 1e-3;
        let x = PLANCK_C2_UM_K / (um * kelvin);
        // 1/(eˣ − 1) written as e⁻ˣ/(1 − e⁻ˣ): no overflow for small temperatures.
        let planck = um.powi(-5) * (-x).exp() / -(-x).exp_m1();
        sum += DVec3::from_array(*row) * planck;
    }
    sum
}

/// A colour as CIE XYZ scaled to Y = 1 (its chromaticity).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Colour {
    xyz: DVec3,
}

impl Default for Colour {
    /// MGF's unnamed colour: "neutral (i.e. equal-energy) grey", x = y = 1/3.
    fn default() -> Self {
        Self { xyz: DVec3::ONE }
    }
}

impl Colour {
    /// The colour of an XYZ triple, if it is one (finite, Y > 0, X and Z ≥ 0).
    fn from_xyz(xyz: DVec3) -> Option<Self> {
        let valid = xyz.is_finite() && xyz.y > 0.0 && xyz.x >= 0.0 && xyz.z >= 0.0;
        valid.then(|| Self { xyz: xyz / xyz.y })
    }

    /// CIE (x, y) chromaticity.
    fn xy(self) -> (f64, f64) {
        let sum = self.xyz.x + self.xyz.y + self.xyz.z;
        (self.xyz.x / sum, self.xyz.y / sum)
    }
}

/// The XYZ → linear-sRGB conversion for one white point.
struct ColourSpace {
    xyz_to_rgb: DMat3,
    white_divisor: DVec3,
}

impl ColourSpace {
    fn new(white: MgfWhite) -> Self {
        let column = |x: f64, y: f64| DVec3::new(x / y, 1.0, (1.0 - x - y) / y);
        let primaries =
            DMat3::from_cols(column(0.64, 0.33), column(0.30, 0.60), column(0.15, 0.06));
        let d65 = column(0.3127, 0.3290);
        let scale = primaries.inverse() * d65;
        let rgb_to_xyz = primaries * DMat3::from_diagonal(scale);
        let xyz_to_rgb = rgb_to_xyz.inverse();
        let white_divisor = match white {
            MgfWhite::D65 => DVec3::ONE,
            MgfWhite::EqualEnergy => xyz_to_rgb * DVec3::ONE,
        };
        Self {
            xyz_to_rgb,
            white_divisor,
        }
    }

    fn rgb(&self, xyz: DVec3) -> DVec3 {
        (self.xyz_to_rgb * xyz) / self.white_divisor
    }

    /// Channel ratios of unit luminance for a colour, and whether a negative channel was
    /// clamped. `None` if nothing positive is left.
    fn ratios(&self, colour: Colour) -> Option<(DVec3, bool)> {
        let rgb = self.rgb(colour.xyz);
        let clipped = rgb.min_element() < -1e-12 * rgb.max_element().abs();
        let rgb = rgb.max(DVec3::ZERO);
        let y = luminance(rgb);
        (y > 0.0 && y.is_finite()).then(|| (rgb / y, clipped))
    }
}

fn luminance(rgb: DVec3) -> f64 {
    LUMINANCE[0] * rgb.x + LUMINANCE[1] * rgb.y + LUMINANCE[2] * rgb.z
}

// ---------------------------------------------------------------------------------------------
// Materials and vertices

/// An MGF material context (spec §3 `m`); values are photometric, colours as given.
#[derive(Debug, Clone, PartialEq)]
struct MgfMaterial {
    two_sided: bool,
    rd: f64,
    rd_colour: Colour,
    rd_at: Option<Location>,
    ed: f64,
    ed_colour: Colour,
    ed_at: Option<Location>,
    /// Non-default settings of properties the radiosity model has no place for:
    /// (entity, what it is, where it was last set).
    ignored: Vec<(&'static str, &'static str, Location)>,
}

impl Default for MgfMaterial {
    /// "A perfect two-sided black absorber" (spec §3 `m`).
    fn default() -> Self {
        Self {
            two_sided: true,
            rd: 0.0,
            rd_colour: Colour::default(),
            rd_at: None,
            ed: 0.0,
            ed_colour: Colour::default(),
            ed_at: None,
            ignored: Vec::new(),
        }
    }
}

impl MgfMaterial {
    /// Equal as far as the scene material is concerned (locations aside).
    fn same_values(&self, other: &Self) -> bool {
        self.two_sided == other.two_sided
            && self.rd == other.rd
            && self.ed == other.ed
            && (self.rd == 0.0 || self.rd_colour == other.rd_colour)
            && (self.ed == 0.0 || self.ed_colour == other.ed_colour)
    }

    fn set_ignored(
        &mut self,
        entity: &'static str,
        what: &'static str,
        at: &Location,
        non_default: bool,
    ) {
        self.ignored.retain(|(e, _, _)| *e != entity);
        if non_default {
            self.ignored.push((entity, what, at.clone()));
        }
    }
}

/// An MGF vertex context: position and optional normal (zero when unset), untransformed.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Vertex {
    p: DVec3,
    n: DVec3,
}

/// One of the spec's four forms of `c`, `m` and `v`.
enum ContextOp<'a> {
    Unnamed,
    Recall(&'a str),
    New(&'a str),
    Copy(&'a str, &'a str),
}

/// A named context family: the current context (named or not) and the saved named ones.
struct Contexts<T> {
    kind: &'static str,
    named: HashMap<String, T>,
    current_name: Option<String>,
    current: T,
}

impl<T: Clone + Default> Contexts<T> {
    fn new(kind: &'static str) -> Self {
        Self {
            kind,
            named: HashMap::new(),
            current_name: None,
            current: T::default(),
        }
    }

    fn get(&self, name: &str) -> Option<&T> {
        if self.current_name.as_deref() == Some(name) {
            Some(&self.current)
        } else {
            self.named.get(name)
        }
    }

    fn lookup(&self, name: &str, at: &Location) -> Result<&T> {
        self.get(name).ok_or_else(|| MgfError::Undefined {
            at: at.clone(),
            kind: self.kind,
            name: name.to_owned(),
        })
    }

    fn select(&mut self, op: ContextOp<'_>, at: &Location) -> Result<()> {
        let value = match op {
            ContextOp::Unnamed => T::default(),
            ContextOp::Recall(name) | ContextOp::Copy(_, name) => self.lookup(name, at)?.clone(),
            ContextOp::New(_) => T::default(),
        };
        if let Some(name) = self.current_name.take() {
            let saved = std::mem::take(&mut self.current);
            self.named.insert(name, saved);
        }
        self.current = value;
        self.current_name = match op {
            ContextOp::Unnamed => None,
            ContextOp::Recall(name) | ContextOp::New(name) | ContextOp::Copy(name, _) => {
                Some(name.to_owned())
            }
        };
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Transforms

/// A similarity transform p ↦ m·p + t (rotation, uniform scale, mirror, translation).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Similarity {
    m: DMat3,
    t: DVec3,
}

impl Similarity {
    const IDENTITY: Self = Self {
        m: DMat3::IDENTITY,
        t: DVec3::ZERO,
    };

    fn linear(m: DMat3) -> Self {
        Self { m, t: DVec3::ZERO }
    }

    fn point(&self, p: DVec3) -> DVec3 {
        self.m * p + self.t
    }

    /// `outer ∘ self`: first self, then outer.
    fn then(self, outer: Self) -> Self {
        Self {
            m: outer.m * self.m,
            t: outer.m * self.t + outer.t,
        }
    }

    /// self applied `n` times (exponentiation by squaring).
    fn pow(self, mut n: u64) -> Self {
        let mut result = Self::IDENTITY;
        let mut base = self;
        while n > 0 {
            if n & 1 == 1 {
                result = result.then(base);
            }
            base = base.then(base);
            n >>= 1;
        }
        result
    }

    fn reverses(&self) -> bool {
        self.m.determinant() < 0.0
    }

    fn is_usable(&self) -> bool {
        let det = self.m.determinant();
        self.m.is_finite() && self.t.is_finite() && det.is_finite() && det != 0.0
    }
}

/// One instance of the geometry in an `xf` context: its total transform and the array
/// object names to insert (object-stack depth, name such as `a1.2`).
#[derive(Debug, Clone)]
struct Instance {
    xf: Similarity,
    arrays: Vec<(usize, String)>,
}

/// An open `xf` context: the cumulative instances (enclosing contexts included).
struct XfLevel {
    instances: Vec<Instance>,
    opened_at: Location,
}

// ---------------------------------------------------------------------------------------------
// The parser

/// What one file being read needs to know about itself.
struct FileCtx<'a> {
    label: &'a str,
    relative: &'a Path,
    stem: String,
    xf_base: usize,
    object_base: usize,
}

struct Parser<'o, F> {
    options: &'o MgfOptions,
    read_include: F,
    top_dir: PathBuf,
    space: ColourSpace,
    colours: Contexts<Colour>,
    materials: Contexts<MgfMaterial>,
    vertices: Contexts<Vertex>,
    objects: Vec<(String, Location)>,
    xforms: Vec<XfLevel>,
    root: Vec<Instance>,
    include_stack: Vec<PathBuf>,
    includes: usize,
    lines: usize,
    used: HashMap<Option<String>, Vec<(MgfMaterial, MaterialId)>>,
    material_names: HashSet<String>,
    scene_materials: Vec<Material>,
    surfaces: Vec<Surface>,
    warnings: Vec<MgfWarning>,
    unlisted_warnings: usize,
}

/// The arguments of an entity after its keyword.
type Args<'a, 'b> = &'a [&'b str];

impl<'o, F: FnMut(&Path) -> io::Result<String>> Parser<'o, F> {
    fn new(options: &'o MgfOptions, file_label: &str, read_include: F) -> Self {
        Self {
            options,
            read_include,
            top_dir: Path::new(file_label)
                .parent()
                .unwrap_or(Path::new(""))
                .to_path_buf(),
            space: ColourSpace::new(options.white),
            colours: Contexts::new("colour"),
            materials: Contexts::new("material"),
            vertices: Contexts::new("vertex"),
            objects: Vec::new(),
            xforms: Vec::new(),
            root: vec![Instance {
                xf: Similarity::IDENTITY,
                arrays: Vec::new(),
            }],
            include_stack: Vec::new(),
            includes: 0,
            lines: 0,
            used: HashMap::new(),
            material_names: HashSet::new(),
            scene_materials: Vec::new(),
            surfaces: Vec::new(),
            warnings: Vec::new(),
            unlisted_warnings: 0,
        }
    }

    fn finish(mut self, file_label: &str) -> Result<MgfScene> {
        if self.surfaces.is_empty() {
            return Err(MgfError::Empty {
                file: file_label.to_owned(),
            });
        }
        if self.unlisted_warnings > 0 {
            self.warnings.push(MgfWarning {
                at: Location::file(file_label),
                message: format!("{} more warnings not listed", self.unlisted_warnings),
            });
        }
        Ok(MgfScene {
            scene: Scene {
                name: scene_name(file_label),
                materials: self.scene_materials,
                surfaces: self.surfaces,
                lights: Vec::new(),
                camera: None,
            },
            warnings: self.warnings,
        })
    }

    /// Records a warning, or fails in strict mode.
    fn warn(&mut self, at: &Location, message: String) -> Result<()> {
        if self.options.strict {
            return Err(MgfError::Strict {
                at: at.clone(),
                message,
            });
        }
        if self.warnings.len() < MAX_WARNINGS {
            self.warnings.push(MgfWarning {
                at: at.clone(),
                message,
            });
        } else {
            self.unlisted_warnings += 1;
        }
        Ok(())
    }

    fn run_file(&mut self, text: &str, label: &str, relative: &Path) -> Result<()> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let ctx = FileCtx {
            label,
            relative,
            stem: scene_name(label),
            xf_base: self.xforms.len(),
            object_base: self.objects.len(),
        };
        let mut physical = text.lines().enumerate();
        let mut logical = String::new();
        while let Some((index, first)) = physical.next() {
            let at = Location::line(label, index + 1);
            logical.clear();
            let mut line = first;
            loop {
                let trimmed = line.trim_end();
                match trimmed.strip_suffix('\\') {
                    Some(head) => {
                        logical.push_str(head);
                        logical.push(' ');
                        match physical.next() {
                            Some((_, next)) => line = next,
                            None => break,
                        }
                    }
                    None => {
                        logical.push_str(trimmed);
                        break;
                    }
                }
                if logical.len() > MAX_LINE_BYTES {
                    return Err(MgfError::Limit {
                        at,
                        message: format!("continued line longer than {MAX_LINE_BYTES} bytes"),
                    });
                }
            }
            if logical.len() > MAX_LINE_BYTES {
                return Err(MgfError::Limit {
                    at,
                    message: format!("line longer than {MAX_LINE_BYTES} bytes"),
                });
            }
            self.lines += 1;
            if self.lines > MAX_LINES {
                return Err(MgfError::Limit {
                    at,
                    message: format!("more than {MAX_LINES} lines read (includes counted)"),
                });
            }
            let words: Vec<&str> = logical.split_whitespace().collect();
            if let Some((keyword, args)) = words.split_first() {
                self.entity(keyword, args, &at, &ctx)?;
            }
        }
        if let Some(level) = self.xforms.get(ctx.xf_base) {
            return Err(MgfError::Context {
                at: level.opened_at.clone(),
                message: "'xf' context is never closed (no matching 'xf' before the end of \
                          its file)"
                    .to_owned(),
            });
        }
        while self.objects.len() > ctx.object_base {
            if let Some((name, opened_at)) = self.objects.pop() {
                self.warn(
                    &opened_at,
                    format!(
                        "object '{name}' is not closed before the end of its file; closed there"
                    ),
                )?;
            }
        }
        Ok(())
    }

    fn entity(&mut self, keyword: &str, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        if keyword.starts_with('#') {
            return Ok(());
        }
        match keyword {
            "o" => self.object(args, at, ctx),
            "xf" => self.xf(args, at, ctx),
            "i" => self.include(args, at, ctx),
            "ies" => Err(MgfError::Unsupported {
                at: at.clone(),
                keyword: keyword.to_owned(),
                reason: "IES luminaires are not read from MGF; convert the luminaire to \
                         emitting MGF geometry"
                    .to_owned(),
            }),
            "c" => {
                let op = context_op(keyword, args, at)?;
                self.colours.select(op, at)
            }
            "cxy" => self.cxy(args, at),
            "cspec" => self.cspec(args, at),
            "cct" => self.cct(args, at),
            "cmix" => self.cmix(args, at),
            "m" => {
                let op = context_op(keyword, args, at)?;
                self.materials.select(op, at)
            }
            "sides" | "rd" | "td" | "ed" | "rs" | "ts" | "ir" => {
                self.material_field(keyword, args, at)
            }
            "v" => {
                let op = context_op(keyword, args, at)?;
                self.vertices.select(op, at)
            }
            "p" | "n" => {
                let v = vector(at, keyword, args)?;
                if keyword == "p" {
                    self.vertices.current.p = v;
                } else {
                    let length = v.length();
                    self.vertices.current.n = if length > 0.0 { v / length } else { v };
                }
                Ok(())
            }
            "f" => self.face(args, at, ctx),
            "fh" => self.face_with_holes(args, at, ctx),
            "sph" => self.sphere(args, at, ctx),
            "cyl" => self.cylinder(args, at, ctx),
            "cone" => self.cone(args, at, ctx),
            "ring" => self.ring(args, at, ctx),
            "torus" => self.torus(args, at, ctx),
            "prism" => self.prism(args, at, ctx),
            _ => Err(MgfError::UnknownEntity {
                at: at.clone(),
                keyword: keyword.to_owned(),
            }),
        }
    }

    // --- hierarchical contexts ---------------------------------------------------------------

    fn object(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        match args {
            [] => {
                if self.objects.len() <= ctx.object_base {
                    return Err(MgfError::Context {
                        at: at.clone(),
                        message: "'o' ends an object, but no object was begun in this file"
                            .to_owned(),
                    });
                }
                self.objects.pop();
                Ok(())
            }
            [name] => {
                self.objects.push(((*name).to_owned(), at.clone()));
                Ok(())
            }
            _ => Err(syntax(
                at,
                format!("'o' takes one object name, got {} words", args.len()),
            )),
        }
    }

    fn xf(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        if args.is_empty() {
            if self.xforms.len() <= ctx.xf_base {
                return Err(MgfError::Context {
                    at: at.clone(),
                    message: "'xf' ends a transform, but no transform was begun in this file"
                        .to_owned(),
                });
            }
            self.xforms.pop();
            return Ok(());
        }
        self.push_transform(args, at)
    }

    fn push_transform(&mut self, args: Args, at: &Location) -> Result<()> {
        let local = parse_transform(args, at, self.objects.len())?;
        let outer = self.instances();
        let count = outer.len().saturating_mul(local.len());
        if count > MAX_INSTANCES {
            return Err(MgfError::Limit {
                at: at.clone(),
                message: format!(
                    "transform arrays make {count} instances (at most {MAX_INSTANCES})"
                ),
            });
        }
        let mut instances = Vec::with_capacity(count);
        for o in outer {
            for l in &local {
                let xf = l.xf.then(o.xf);
                if !xf.is_usable() {
                    return Err(MgfError::Invalid {
                        at: at.clone(),
                        message: "transform overflows or collapses to zero scale".to_owned(),
                    });
                }
                let mut arrays = o.arrays.clone();
                arrays.extend(l.arrays.iter().cloned());
                instances.push(Instance { xf, arrays });
            }
        }
        self.xforms.push(XfLevel {
            instances,
            opened_at: at.clone(),
        });
        Ok(())
    }

    fn instances(&self) -> &[Instance] {
        self.xforms.last().map_or(&self.root, |l| &l.instances)
    }

    fn include(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        let Some((name, transform)) = args.split_first() else {
            return Err(syntax(at, "'i' needs a file name".to_owned()));
        };
        let written = Path::new(name);
        if written
            .components()
            .any(|c| matches!(c, Component::RootDir | Component::Prefix(_)))
        {
            return Err(invalid(
                at,
                format!("include path '{name}' must be relative to the including file"),
            ));
        }
        let dir = ctx.relative.parent().unwrap_or(Path::new(""));
        let relative = normalise(&dir.join(written));
        let label = self.label_for(&relative);
        if let Some(start) = self.include_stack.iter().position(|p| *p == relative) {
            let chain: Vec<String> = self.include_stack[start..]
                .iter()
                .chain(std::iter::once(&relative))
                .map(|p| self.label_for(p))
                .collect();
            return Err(MgfError::IncludeCycle {
                at: at.clone(),
                chain: chain.join(" → "),
            });
        }
        if self.include_stack.len() >= MAX_INCLUDE_DEPTH {
            return Err(MgfError::IncludeDepth {
                at: at.clone(),
                limit: MAX_INCLUDE_DEPTH,
            });
        }
        self.includes += 1;
        if self.includes > MAX_INCLUDES {
            return Err(MgfError::Limit {
                at: at.clone(),
                message: format!("more than {MAX_INCLUDES} includes"),
            });
        }
        let text = (self.read_include)(&relative).map_err(|source| MgfError::Include {
            at: at.clone(),
            file: label.clone(),
            source,
        })?;
        let pushed = !transform.is_empty();
        if pushed {
            self.push_transform(transform, at)?;
        }
        self.include_stack.push(relative.clone());
        let result = self.run_file(&text, &label, &relative);
        self.include_stack.pop();
        result?;
        if pushed {
            self.xforms.pop();
        }
        Ok(())
    }

    fn label_for(&self, relative: &Path) -> String {
        self.top_dir.join(relative).display().to_string()
    }

    // --- colour ------------------------------------------------------------------------------

    fn cxy(&mut self, args: Args, at: &Location) -> Result<()> {
        let [x, y] = fixed::<2>(at, "cxy", args, "x y")?;
        let (x, y) = (number(at, "x", x)?, number(at, "y", y)?);
        if !(x >= 0.0 && y > 0.0 && x + y <= 1.0) {
            return Err(invalid(
                at,
                format!("chromaticity ({x}, {y}) is not a colour: need x ≥ 0, y > 0 and x + y ≤ 1"),
            ));
        }
        self.colours.current = Colour {
            xyz: DVec3::new(x / y, 1.0, (1.0 - x - y) / y),
        };
        Ok(())
    }

    fn cspec(&mut self, args: Args, at: &Location) -> Result<()> {
        if args.len() < 4 {
            return Err(syntax(
                at,
                format!(
                    "'cspec' needs 'λ_min λ_max v1 v2 …' with at least two values, got {} \
                     arguments",
                    args.len()
                ),
            ));
        }
        let lo = number(at, "λ_min", args[0])?;
        let hi = number(at, "λ_max", args[1])?;
        if !(lo > 0.0 && hi > lo) {
            return Err(invalid(
                at,
                format!("spectrum range {lo}..{hi} nm must have 0 < λ_min < λ_max"),
            ));
        }
        let values = args[2..]
            .iter()
            .map(|w| number(at, "spectral value", w))
            .collect::<Result<Vec<f64>>>()?;
        let xyz = spectrum_xyz(lo, hi, &values);
        self.colours.current = Colour::from_xyz(xyz).ok_or_else(|| {
            invalid(
                at,
                "spectrum has no positive visible luminance (380–780 nm) or is not a colour"
                    .to_owned(),
            )
        })?;
        Ok(())
    }

    fn cct(&mut self, args: Args, at: &Location) -> Result<()> {
        let [t] = fixed::<1>(at, "cct", args, "a temperature in kelvin")?;
        let t = number(at, "temperature", t)?;
        if t <= 0.0 {
            return Err(invalid(at, format!("temperature {t} K must be > 0")));
        }
        self.colours.current = Colour::from_xyz(blackbody_xyz(t)).ok_or_else(|| {
            invalid(
                at,
                format!("a black body at {t} K gives no visible light in double precision"),
            )
        })?;
        Ok(())
    }

    fn cmix(&mut self, args: Args, at: &Location) -> Result<()> {
        if args.is_empty() || args.len() % 2 != 0 {
            return Err(syntax(
                at,
                format!(
                    "'cmix' needs pairs 'w1 c1 w2 c2 …', got {} arguments",
                    args.len()
                ),
            ));
        }
        let mut xyz = DVec3::ZERO;
        for pair in args.chunks_exact(2) {
            let w = number(at, "weight", pair[0])?;
            let colour = self.colours.lookup(pair[1], at)?;
            xyz += colour.xyz * w;
        }
        self.colours.current = Colour::from_xyz(xyz).ok_or_else(|| {
            invalid(
                at,
                "mixture is not a colour (its luminance must be > 0 and X, Z ≥ 0)".to_owned(),
            )
        })?;
        Ok(())
    }

    // --- material ----------------------------------------------------------------------------

    fn material_field(&mut self, keyword: &str, args: Args, at: &Location) -> Result<()> {
        let colour = self.colours.current;
        let m = &mut self.materials.current;
        match keyword {
            "sides" => {
                let [n] = fixed::<1>(at, keyword, args, "1 or 2")?;
                m.two_sided = match *n {
                    "1" => false,
                    "2" => true,
                    other => {
                        return Err(invalid(
                            at,
                            format!("'sides' must be 1 or 2, got '{other}'"),
                        ))
                    }
                };
            }
            "rd" => {
                let [v] = fixed::<1>(at, keyword, args, "a diffuse reflectance")?;
                m.rd = unit_interval(at, "diffuse reflectance", v)?;
                m.rd_colour = colour;
                m.rd_at = Some(at.clone());
            }
            "ed" => {
                let [v] = fixed::<1>(at, keyword, args, "a diffuse emittance in lm/m²")?;
                let ed = number(at, "diffuse emittance", v)?;
                if ed < 0.0 {
                    return Err(invalid(at, format!("diffuse emittance {ed} must be ≥ 0")));
                }
                m.ed = ed;
                m.ed_colour = colour;
                m.ed_at = Some(at.clone());
            }
            "td" => {
                let [v] = fixed::<1>(at, keyword, args, "a diffuse transmittance")?;
                let td = unit_interval(at, "diffuse transmittance", v)?;
                m.set_ignored("td", "diffuse transmittance", at, td > 0.0);
            }
            "rs" | "ts" => {
                let [v, a] = fixed::<2>(at, keyword, args, "a value and a roughness")?;
                let (entity, what) = if keyword == "rs" {
                    ("rs", "specular reflectance")
                } else {
                    ("ts", "specular transmittance")
                };
                let value = unit_interval(at, what, v)?;
                let roughness = number(at, "roughness", a)?;
                if roughness < 0.0 {
                    return Err(invalid(at, format!("roughness {roughness} must be ≥ 0")));
                }
                m.set_ignored(entity, what, at, value > 0.0);
            }
            _ => {
                let [re, im] = fixed::<2>(at, keyword, args, "n_real n_imag")?;
                let re = number(at, "index of refraction", re)?;
                let im = number(at, "extinction coefficient", im)?;
                if re <= 0.0 || im < 0.0 {
                    return Err(invalid(
                        at,
                        format!("index of refraction ({re}, {im}) needs n_real > 0, n_imag ≥ 0"),
                    ));
                }
                m.set_ignored("ir", "index of refraction", at, re != 1.0 || im != 0.0);
            }
        }
        Ok(())
    }

    /// The scene material for the current MGF material, made on first use.
    fn current_material(&mut self, at: &Location) -> Result<MaterialId> {
        let name = self.materials.current_name.clone();
        let material = self.materials.current.clone();
        if let Some(variants) = self.used.get(&name) {
            if let Some((_, id)) = variants.iter().find(|(m, _)| m.same_values(&material)) {
                return Ok(*id);
            }
        }
        let converted = self.convert_material(name.as_deref(), &material, at)?;
        let id = MaterialId(self.scene_materials.len() as u32);
        self.material_names.insert(converted.name.clone());
        self.scene_materials.push(converted);
        self.used.entry(name).or_default().push((material, id));
        Ok(id)
    }

    fn convert_material(
        &mut self,
        name: Option<&str>,
        m: &MgfMaterial,
        used_at: &Location,
    ) -> Result<Material> {
        let base = name.unwrap_or("_unnamed");
        let mut unique = base.to_owned();
        let mut k = 2;
        while self.material_names.contains(&unique) {
            unique = format!("{base}#{k}");
            k += 1;
        }
        let mut reflectance = [0.0; 3];
        if m.rd > 0.0 {
            let at = m.rd_at.clone().unwrap_or_else(|| used_at.clone());
            let c = self.colour_ratios(m.rd_colour, &at, base, "diffuse")?;
            let mut clamped = false;
            for (r, c) in reflectance.iter_mut().zip(c.to_array()) {
                *r = m.rd * c;
                if *r >= 1.0 {
                    *r = MAX_REFLECTANCE;
                    clamped = true;
                }
            }
            if clamped {
                let (x, y) = m.rd_colour.xy();
                self.warn(
                    &at,
                    format!(
                        "material '{base}': reflectance {} in colour ({x:.4}, {y:.4}) is ≥ 1 in \
                         some RGB channel; clamped to {MAX_REFLECTANCE}, giving {reflectance:?}",
                        m.rd
                    ),
                )?;
            }
        }
        let mut emission = [0.0; 3];
        if m.ed > 0.0 {
            let at = m.ed_at.clone().unwrap_or_else(|| used_at.clone());
            let c = self.colour_ratios(m.ed_colour, &at, base, "emission")?;
            let luminance = m.ed / PI / LUMINOUS_EFFICACY;
            emission = (c * luminance).to_array();
            if m.two_sided {
                self.warn(
                    &at,
                    format!(
                        "material '{base}' is two-sided (the MGF default) and emits; the scene \
                         model emits from the front side only (add 'sides 1' to silence this)"
                    ),
                )?;
            }
        }
        if let Some((_, _, first)) = m.ignored.first() {
            let what: Vec<String> = m
                .ignored
                .iter()
                .map(|(entity, what, _)| format!("{entity} ({what})"))
                .collect();
            self.warn(
                first,
                format!(
                    "material '{base}': {} ignored; the radiosity model is Lambertian \
                     (diffuse reflection and emission only)",
                    what.join(", ")
                ),
            )?;
        }
        let mut material = Material::new(unique, reflectance, emission);
        material.two_sided = m.two_sided;
        if let Some(problem) = material_problem(&material) {
            return Err(MgfError::Invalid {
                at: used_at.clone(),
                message: format!("material '{base}': {problem}"),
            });
        }
        Ok(material)
    }

    fn colour_ratios(
        &mut self,
        colour: Colour,
        at: &Location,
        material: &str,
        what: &str,
    ) -> Result<DVec3> {
        let (x, y) = colour.xy();
        let Some((ratios, clipped)) = self.space.ratios(colour) else {
            return Err(invalid(
                at,
                format!(
                    "material '{material}': {what} colour ({x:.4}, {y:.4}) has no luminance \
                     inside the sRGB gamut"
                ),
            ));
        };
        if clipped {
            self.warn(
                at,
                format!(
                    "material '{material}': {what} colour ({x:.4}, {y:.4}) is outside the sRGB \
                     gamut; negative channels clamped to 0, luminance kept"
                ),
            )?;
        }
        Ok(ratios)
    }

    // --- geometry ----------------------------------------------------------------------------

    fn vertex(&self, name: &str, at: &Location) -> Result<Vertex> {
        self.vertices.lookup(name, at).copied()
    }

    fn points(&self, names: &[&str], at: &Location) -> Result<Vec<DVec3>> {
        names.iter().map(|n| Ok(self.vertex(n, at)?.p)).collect()
    }

    fn face(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        if args.len() < 3 {
            return Err(syntax(
                at,
                format!("'f' needs at least three vertices, got {}", args.len()),
            ));
        }
        check_face_size(at, args.len())?;
        let points = self.points(args, at)?;
        self.emit(at, ctx, "f", vec![points], Shape::Face)
    }

    fn face_with_holes(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        check_face_size(at, args.len())?;
        let mut contours: Vec<Vec<DVec3>> = vec![Vec::new()];
        for word in args {
            if *word == "-" {
                contours.push(Vec::new());
            } else if let Some(last) = contours.last_mut() {
                last.push(self.vertex(word, at)?.p);
            }
        }
        if let Some(short) = contours.iter().position(|c| c.len() < 3) {
            let which = if short == 0 {
                "the outline".to_owned()
            } else {
                format!("hole {short}")
            };
            return Err(syntax(
                at,
                format!("'fh': {which} has fewer than three vertices"),
            ));
        }
        let outline = contours.remove(0);
        if contours.is_empty() {
            return self.emit(at, ctx, "fh", vec![outline], Shape::Face);
        }
        let seamed = bridge_holes(&outline, &contours)
            .map_err(|problem| invalid(at, format!("'fh': {problem}")))?;
        self.emit(at, ctx, "fh", vec![seamed], Shape::Seamed)
    }

    fn sphere(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        let [centre, radius] = fixed::<2>(at, "sph", args, "a centre vertex and a radius")?;
        let centre = self.vertex(centre, at)?.p;
        let radius = number(at, "radius", radius)?;
        if radius == 0.0 {
            return Err(invalid(at, "sphere radius must not be zero".to_owned()));
        }
        let mut loops = sphere_loops(centre, radius.abs(), self.options.circle_segments);
        if radius < 0.0 {
            loops.iter_mut().for_each(|l| l.reverse());
        }
        self.emit(at, ctx, "sph", loops, Shape::Convex)
    }

    fn cylinder(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        let [v1, radius, v2] = fixed::<3>(at, "cyl", args, "'v1 radius v2'")?;
        let radius = number(at, "radius", radius)?;
        if radius == 0.0 {
            return Err(invalid(at, "cylinder radius must not be zero".to_owned()));
        }
        self.cone_like("cyl", v1, radius, v2, radius, at, ctx)
    }

    fn cone(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        let [v1, r1, v2, r2] = fixed::<4>(at, "cone", args, "'v1 radius1 v2 radius2'")?;
        let r1 = number(at, "radius 1", r1)?;
        let r2 = number(at, "radius 2", r2)?;
        if r1 == 0.0 && r2 == 0.0 {
            return Err(invalid(at, "cone radii must not both be zero".to_owned()));
        }
        if r1 * r2 < 0.0 {
            return Err(invalid(
                at,
                format!("cone radii {r1} and {r2} must have the same sign"),
            ));
        }
        self.cone_like("cone", v1, r1, v2, r2, at, ctx)
    }

    #[allow(clippy::too_many_arguments)]
    fn cone_like(
        &mut self,
        entity: &'static str,
        v1: &str,
        r1: f64,
        v2: &str,
        r2: f64,
        at: &Location,
        ctx: &FileCtx,
    ) -> Result<()> {
        let (p1, p2) = (self.vertex(v1, at)?.p, self.vertex(v2, at)?.p);
        if p1 == p2 {
            return Err(invalid(
                at,
                format!("'{entity}' end points '{v1}' and '{v2}' coincide (use 'ring')"),
            ));
        }
        let mut loops = cone_loops(p1, r1.abs(), p2, r2.abs(), self.options.circle_segments);
        if r1 < 0.0 || r2 < 0.0 {
            loops.iter_mut().for_each(|l| l.reverse());
        }
        self.emit(at, ctx, entity, loops, Shape::Convex)
    }

    fn ring(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        let [centre, rmin, rmax] = fixed::<3>(at, "ring", args, "'centre r_min r_max'")?;
        let vertex = self.vertex(centre, at)?;
        let (rmin, rmax) = (number(at, "r_min", rmin)?, number(at, "r_max", rmax)?);
        if !(rmin >= 0.0 && rmax > rmin) {
            return Err(invalid(
                at,
                format!("ring radii need 0 ≤ r_min < r_max, got {rmin} and {rmax}"),
            ));
        }
        let normal = needs_normal(vertex, centre, "ring", at)?;
        let loops = ring_loops(vertex.p, normal, rmin, rmax, self.options.circle_segments);
        self.emit(at, ctx, "ring", loops, Shape::Convex)
    }

    fn torus(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        let [centre, rmin, rmax] = fixed::<3>(at, "torus", args, "'centre r_min r_max'")?;
        let vertex = self.vertex(centre, at)?;
        let (rmin, rmax) = (number(at, "r_min", rmin)?, number(at, "r_max", rmax)?);
        let sign_ok = (rmin >= 0.0 && rmax > 0.0) || (rmin <= 0.0 && rmax < 0.0);
        if !sign_ok || rmax.abs() <= rmin.abs() {
            return Err(invalid(
                at,
                format!(
                    "torus radii need the same sign and |r_max| > |r_min|, got {rmin} and {rmax}"
                ),
            ));
        }
        let normal = needs_normal(vertex, centre, "torus", at)?;
        let mut loops = torus_loops(
            vertex.p,
            normal,
            rmin.abs(),
            rmax.abs(),
            self.options.circle_segments,
        );
        if rmax < 0.0 {
            loops.iter_mut().for_each(|l| l.reverse());
        }
        self.emit(at, ctx, "torus", loops, Shape::Convex)
    }

    fn prism(&mut self, args: Args, at: &Location, ctx: &FileCtx) -> Result<()> {
        let Some((length, names)) = args.split_last() else {
            return Err(syntax(at, "'prism' needs vertices and a length".to_owned()));
        };
        if names.len() < 3 {
            return Err(syntax(
                at,
                format!("'prism' needs at least three vertices, got {}", names.len()),
            ));
        }
        check_face_size(at, names.len())?;
        let length = number(at, "length", length)?;
        if length == 0.0 {
            return Err(invalid(at, "prism length must not be zero".to_owned()));
        }
        let base = self.points(names, at)?;
        let (normal, area) = newell(&base);
        if area.is_nan() || area <= 0.0 {
            return self.warn(
                at,
                "'prism' base has zero area (collinear or repeated vertices); skipped".to_owned(),
            );
        }
        // Extruded away from the base's normal (spec §3 `prism`), so every face points out;
        // a negative length extrudes the other way and every face points in.
        let offset = -normal * length;
        let mut top: Vec<DVec3> = base.iter().map(|p| *p + offset).collect();
        top.reverse();
        let mut loops = vec![base.clone(), top];
        for i in 0..base.len() {
            let (a, b) = (base[i], base[(i + 1) % base.len()]);
            loops.push(vec![b, a, a + offset, b + offset]);
        }
        self.emit(at, ctx, "prism", loops, Shape::Face)
    }

    /// Turns local polygon loops into surfaces: one copy per instance of the current
    /// transform, each vertex transformed, the order reversed by mirroring transforms.
    fn emit(
        &mut self,
        at: &Location,
        ctx: &FileCtx,
        entity: &str,
        loops: Vec<Vec<DVec3>>,
        shape: Shape,
    ) -> Result<()> {
        let material = self.current_material(at)?;
        let instances = self.instances();
        let origin = Origin {
            file: Some(ctx.label.to_owned()),
            line: at.line,
        };
        let geometry_error = |source: GeometryError, arrays: &[(usize, String)]| {
            let (object, _) = object_names(&self.objects, arrays, &ctx.stem);
            MgfError::Geometry {
                at: at.clone(),
                object,
                source,
            }
        };
        // Split once, in the entity's own coordinates: the transforms are similarities, which
        // keep the pieces planar and convex. A loop whose local coordinates are out of range
        // (a file in small units scaled down) is split after transforming instead.
        let mut skipped = false;
        let mut pieces: Vec<Vec<DVec3>> = Vec::with_capacity(loops.len());
        for l in loops {
            if shape == Shape::Convex {
                pieces.push(l);
                continue;
            }
            match convex_pieces(l.clone(), shape) {
                Ok(p) => pieces.extend(p.iter().map(|p| p.vertices().to_vec())),
                Err(GeometryError::Degenerate { .. } | GeometryError::TooFewVertices(_)) => {
                    skipped = true;
                }
                Err(GeometryError::OutOfRange { .. }) => pieces.push(l),
                Err(source) => {
                    let arrays = instances.first().map_or(&[][..], |i| &i.arrays[..]);
                    return Err(geometry_error(source, arrays));
                }
            }
        }
        let room = self
            .options
            .max_surfaces
            .saturating_sub(self.surfaces.len());
        let too_many = || MgfError::Limit {
            at: at.clone(),
            message: format!(
                "more than {} surfaces (MgfOptions::max_surfaces)",
                self.options.max_surfaces
            ),
        };
        let estimate = pieces.len().saturating_mul(instances.len());
        if estimate > room {
            return Err(too_many());
        }
        let mut made = Vec::with_capacity(estimate);
        for instance in instances {
            let (object, group) = object_names(&self.objects, &instance.arrays, &ctx.stem);
            for piece in &pieces {
                let mut vertices: Vec<DVec3> =
                    piece.iter().map(|p| instance.xf.point(*p)).collect();
                if instance.xf.reverses() {
                    vertices.reverse();
                }
                let polygons = match Polygon::new(vertices.clone()) {
                    Ok(p) => Ok(vec![p]),
                    Err(GeometryError::NonConvex | GeometryError::NonPlanar { .. }) => {
                        convex_pieces(vertices, shape)
                    }
                    Err(e) => Err(e),
                };
                let polygons = match polygons {
                    Ok(p) => p,
                    Err(GeometryError::Degenerate { .. } | GeometryError::TooFewVertices(_)) => {
                        skipped = true;
                        continue;
                    }
                    Err(source) => return Err(geometry_error(source, &instance.arrays)),
                };
                if made.len() + polygons.len() > room {
                    return Err(too_many());
                }
                for polygon in polygons {
                    made.push(Surface {
                        object: object.clone(),
                        group: group.clone(),
                        material,
                        polygon,
                        origin: origin.clone(),
                    });
                }
            }
        }
        self.surfaces.append(&mut made);
        if skipped {
            self.warn(
                at,
                format!(
                    "'{entity}': zero-area polygon skipped (collinear or repeated vertices, or \
                     too small)"
                ),
            )?;
        }
        Ok(())
    }
}

/// How [`convex_pieces`] treats a loop.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Shape {
    /// Already planar and convex (tessellations).
    Convex,
    /// An `f` face: [`split_into_convex`], then the seam-aware triangulator.
    Face,
    /// A polygon known to have seams (an `fh` with its holes bridged).
    Seamed,
}

fn convex_pieces(vertices: Vec<DVec3>, shape: Shape) -> Result<Vec<Polygon>, GeometryError> {
    let seamed = |vertices: &[DVec3]| -> Result<Vec<Polygon>, GeometryError> {
        let triangles = triangulate_seamed(vertices).ok_or(GeometryError::NonConvex)?;
        let mut out = Vec::with_capacity(triangles.len());
        for t in triangles {
            match Polygon::new(t.to_vec()) {
                Ok(p) => out.push(p),
                Err(GeometryError::Degenerate { .. } | GeometryError::TooFewVertices(_)) => {}
                Err(e) => return Err(e),
            }
        }
        Ok(out)
    };
    match shape {
        Shape::Convex => split_into_convex(vertices),
        Shape::Seamed => seamed(&vertices),
        Shape::Face => match split_into_convex(vertices.clone()) {
            Err(GeometryError::NonConvex) => seamed(&vertices),
            other => other,
        },
    }
}

/// Object and group names for a surface: the object stack joined with '.', array instance
/// names inserted where their `xf` began; the group is the outermost name. Without any, the
/// file's stem.
fn object_names(
    objects: &[(String, Location)],
    arrays: &[(usize, String)],
    stem: &str,
) -> (String, String) {
    let mut parts: Vec<&str> = Vec::with_capacity(objects.len() + arrays.len());
    for depth in 0..=objects.len() {
        parts.extend(
            arrays
                .iter()
                .filter(|(d, _)| (*d).min(objects.len()) == depth)
                .map(|(_, name)| name.as_str()),
        );
        if let Some((name, _)) = objects.get(depth) {
            parts.push(name);
        }
    }
    if parts.is_empty() {
        return (stem.to_owned(), stem.to_owned());
    }
    (parts.join("."), parts[0].to_owned())
}

// ---------------------------------------------------------------------------------------------
// Argument helpers

fn syntax(at: &Location, message: String) -> MgfError {
    MgfError::Syntax {
        at: at.clone(),
        message,
    }
}

fn invalid(at: &Location, message: String) -> MgfError {
    MgfError::Invalid {
        at: at.clone(),
        message,
    }
}

/// Exactly `N` arguments.
fn fixed<'a, 'b, const N: usize>(
    at: &Location,
    keyword: &str,
    args: &'a [&'b str],
    usage: &str,
) -> Result<&'a [&'b str; N]> {
    args.try_into().map_err(|_| {
        syntax(
            at,
            format!(
                "'{keyword}' needs {usage} ({N} argument{}), got {}",
                if N == 1 { "" } else { "s" },
                args.len()
            ),
        )
    })
}

fn number(at: &Location, what: &str, word: &str) -> Result<f64> {
    let value: f64 = word
        .parse()
        .map_err(|_| syntax(at, format!("{what} '{word}' is not a number")))?;
    if !value.is_finite() {
        return Err(MgfError::NonFinite {
            at: at.clone(),
            what: what.to_owned(),
            value: word.to_owned(),
        });
    }
    Ok(value)
}

fn unit_interval(at: &Location, what: &str, word: &str) -> Result<f64> {
    let value = number(at, what, word)?;
    if !(0.0..=1.0).contains(&value) {
        return Err(invalid(at, format!("{what} {value} must be in [0, 1]")));
    }
    Ok(value)
}

fn vector(at: &Location, keyword: &str, args: Args) -> Result<DVec3> {
    let [x, y, z] = fixed::<3>(at, keyword, args, "x y z")?;
    Ok(DVec3::new(
        number(at, "x", x)?,
        number(at, "y", y)?,
        number(at, "z", z)?,
    ))
}

fn integer(at: &Location, what: &str, word: &str) -> Result<i64> {
    word.parse()
        .map_err(|_| syntax(at, format!("{what} '{word}' is not an integer")))
}

fn check_face_size(at: &Location, count: usize) -> Result<()> {
    if count > MAX_FACE_VERTICES {
        return Err(MgfError::Limit {
            at: at.clone(),
            message: format!("face has {count} vertices (at most {MAX_FACE_VERTICES})"),
        });
    }
    Ok(())
}

fn needs_normal(vertex: Vertex, name: &str, entity: &str, at: &Location) -> Result<DVec3> {
    if vertex.n == DVec3::ZERO {
        return Err(invalid(
            at,
            format!("'{entity}' centre vertex '{name}' has no normal ('n')"),
        ));
    }
    Ok(vertex.n)
}

/// The spec's four forms of a context entity.
fn context_op<'b>(keyword: &str, args: &[&'b str], at: &Location) -> Result<ContextOp<'b>> {
    let check = |name: &'b str| -> Result<&'b str> {
        let mut chars = name.chars();
        let first_ok = chars
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_');
        if first_ok && name.chars().all(|c| c.is_ascii_graphic()) {
            Ok(name)
        } else {
            Err(syntax(
                at,
                format!("'{name}' is not an MGF name (a letter, then printing ASCII characters)"),
            ))
        }
    };
    match args {
        [] => Ok(ContextOp::Unnamed),
        [name] => Ok(ContextOp::Recall(check(name)?)),
        [name, "="] => Ok(ContextOp::New(check(name)?)),
        [name, "=", template] => Ok(ContextOp::Copy(check(name)?, check(template)?)),
        _ => Err(syntax(
            at,
            format!("'{keyword}' takes '', 'name', 'name =' or 'name = template'"),
        )),
    }
}

/// Parses `xf` arguments into the instances of one context (array names at `object_depth`).
fn parse_transform(args: Args, at: &Location, object_depth: usize) -> Result<Vec<Instance>> {
    enum Repeat {
        Iterate(u64),
        Array(u64),
    }
    let mut segments: Vec<(Repeat, Similarity)> = Vec::new();
    let mut repeat = Repeat::Iterate(1);
    let mut current = Similarity::IDENTITY;
    let mut i = 0;
    let bad = |message: String| syntax(at, format!("bad 'xf' argument: {message}"));
    let take = |i: usize, n: usize, flag: &str| xf_values(args, i, n, flag, at);
    while i < args.len() {
        let flag = args[i];
        let step = match flag {
            "-t" => {
                let v = take(i, 3, flag)?;
                let t = DVec3::new(
                    number(at, "translation", v[0])?,
                    number(at, "translation", v[1])?,
                    number(at, "translation", v[2])?,
                );
                i += 4;
                Similarity {
                    m: DMat3::IDENTITY,
                    t,
                }
            }
            "-rx" | "-ry" | "-rz" => {
                let v = take(i, 1, flag)?;
                let angle = number(at, "rotation angle", v[0])?.to_radians();
                i += 2;
                Similarity::linear(match flag {
                    "-rx" => DMat3::from_rotation_x(angle),
                    "-ry" => DMat3::from_rotation_y(angle),
                    _ => DMat3::from_rotation_z(angle),
                })
            }
            "-s" => {
                let v = take(i, 1, flag)?;
                let s = number(at, "scale factor", v[0])?;
                if s == 0.0 {
                    return Err(bad("scale factor must not be zero".to_owned()));
                }
                i += 2;
                Similarity::linear(DMat3::from_diagonal(DVec3::splat(s)))
            }
            "-mx" | "-my" | "-mz" => {
                let mut d = DVec3::ONE;
                match flag {
                    "-mx" => d.x = -1.0,
                    "-my" => d.y = -1.0,
                    _ => d.z = -1.0,
                }
                i += 1;
                Similarity::linear(DMat3::from_diagonal(d))
            }
            "-i" | "-a" => {
                let v = take(i, 1, flag)?;
                let n = integer(at, "repeat count", v[0])?;
                let (low, high) = if flag == "-i" {
                    (0, MAX_ITERATIONS)
                } else {
                    (1, MAX_ARRAY)
                };
                if !(low..=high).contains(&n) {
                    return Err(bad(format!("'{flag} {n}' must be in {low}..={high}")));
                }
                segments.push((repeat, current));
                repeat = if flag == "-i" {
                    Repeat::Iterate(n as u64)
                } else {
                    Repeat::Array(n as u64)
                };
                current = Similarity::IDENTITY;
                i += 2;
                continue;
            }
            other => {
                return Err(bad(format!(
                    "'{other}' (expected -t, -rx, -ry, -rz, -s, -mx, -my, -mz, -i or -a)"
                )))
            }
        };
        current = current.then(step);
    }
    segments.push((repeat, current));

    let mut instances: Vec<(Similarity, Vec<u64>)> = vec![(Similarity::IDENTITY, Vec::new())];
    for (repeat, step) in segments {
        match repeat {
            Repeat::Iterate(n) => {
                let power = step.pow(n);
                for (xf, _) in &mut instances {
                    *xf = xf.then(power);
                }
            }
            Repeat::Array(n) => {
                let count = instances.len().saturating_mul(n as usize);
                if count > MAX_INSTANCES {
                    return Err(MgfError::Limit {
                        at: at.clone(),
                        message: format!(
                            "transform arrays make {count} instances (at most {MAX_INSTANCES})"
                        ),
                    });
                }
                let mut next = Vec::with_capacity(count);
                for k in 0..n {
                    let power = step.pow(k);
                    for (xf, index) in &instances {
                        let mut index = index.clone();
                        index.push(k);
                        next.push((xf.then(power), index));
                    }
                }
                instances = next;
            }
        }
    }
    instances
        .into_iter()
        .map(|(xf, index)| {
            if !xf.is_usable() {
                return Err(invalid(
                    at,
                    "transform overflows or collapses to zero scale".to_owned(),
                ));
            }
            let arrays = if index.is_empty() {
                Vec::new()
            } else {
                let names: Vec<String> = index.iter().map(u64::to_string).collect();
                vec![(object_depth, format!("a{}", names.join(".")))]
            };
            Ok(Instance { xf, arrays })
        })
        .collect()
}

/// The `n` values after the `xf` option at `i`.
fn xf_values<'a, 'b>(
    args: &'a [&'b str],
    i: usize,
    n: usize,
    flag: &str,
    at: &Location,
) -> Result<&'a [&'b str]> {
    args.get(i + 1..i + 1 + n).ok_or_else(|| {
        syntax(
            at,
            format!("bad 'xf' argument: '{flag}' needs {n} value(s)"),
        )
    })
}

/// `path` with `.` and `name/..` removed, without touching the file system.
fn normalise(path: &Path) -> PathBuf {
    let mut out: Vec<Component> = Vec::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => match out.last() {
                Some(Component::Normal(_)) => {
                    out.pop();
                }
                Some(Component::RootDir | Component::Prefix(_)) => {}
                _ => out.push(c),
            },
            other => out.push(other),
        }
    }
    out.iter().collect()
}

// ---------------------------------------------------------------------------------------------
// Tessellation (local coordinates; see the module documentation)

/// Unit vectors u, w with u × w = axis (axis a unit vector).
fn frame(axis: DVec3) -> (DVec3, DVec3) {
    let helper = if axis.x.abs() <= axis.y.abs() && axis.x.abs() <= axis.z.abs() {
        DVec3::X
    } else if axis.y.abs() <= axis.z.abs() {
        DVec3::Y
    } else {
        DVec3::Z
    };
    let u = helper.cross(axis).normalize();
    (u, axis.cross(u))
}

/// Angle of segment `j` of `n` (exactly the same value for j and j + n).
fn segment_angle(j: u32, n: u32) -> f64 {
    2.0 * PI * f64::from(j % n) / f64::from(n)
}

/// Latitude/longitude sphere: `n` longitudes, ⌈n/2⌉ bands, triangles at the poles,
/// outward-facing.
fn sphere_loops(centre: DVec3, radius: f64, n: u32) -> Vec<Vec<DVec3>> {
    let bands = n.div_ceil(2).max(2);
    let point = |band: u32, j: u32| {
        let theta = PI * f64::from(band) / f64::from(bands);
        let phi = segment_angle(j, n);
        let (st, ct) = theta.sin_cos();
        centre + radius * DVec3::new(st * phi.cos(), st * phi.sin(), ct)
    };
    let north = centre + DVec3::Z * radius;
    let south = centre - DVec3::Z * radius;
    let mut loops = Vec::with_capacity((bands * n) as usize);
    for j in 0..n {
        loops.push(vec![north, point(1, j), point(1, j + 1)]);
        for band in 1..bands - 1 {
            loops.push(vec![
                point(band, j),
                point(band + 1, j),
                point(band + 1, j + 1),
                point(band, j + 1),
            ]);
        }
        loops.push(vec![point(bands - 1, j), south, point(bands - 1, j + 1)]);
    }
    loops
}

/// Open truncated cone from `p1` (radius `r1`) to `p2` (radius `r2`), outward-facing; one
/// radius may be zero (triangles meeting at the apex).
fn cone_loops(p1: DVec3, r1: f64, p2: DVec3, r2: f64, n: u32) -> Vec<Vec<DVec3>> {
    let (u, w) = frame((p2 - p1).normalize());
    let at = |c: DVec3, r: f64, j: u32| {
        let a = segment_angle(j, n);
        c + r * (u * a.cos() + w * a.sin())
    };
    (0..n)
        .map(|j| {
            let mut l = Vec::with_capacity(4);
            if r1 > 0.0 {
                l.extend([at(p1, r1, j), at(p1, r1, j + 1)]);
            } else {
                l.push(p1);
            }
            if r2 > 0.0 {
                l.extend([at(p2, r2, j + 1), at(p2, r2, j)]);
            } else {
                l.push(p2);
            }
            l
        })
        .collect()
}

/// Flat annulus (a disc when `rmin` is 0) facing along `normal`.
fn ring_loops(centre: DVec3, normal: DVec3, rmin: f64, rmax: f64, n: u32) -> Vec<Vec<DVec3>> {
    let (u, w) = frame(normal);
    let at = |r: f64, j: u32| {
        let a = segment_angle(j, n);
        centre + r * (u * a.cos() + w * a.sin())
    };
    (0..n)
        .map(|j| {
            if rmin > 0.0 {
                vec![at(rmin, j), at(rmax, j), at(rmax, j + 1), at(rmin, j + 1)]
            } else {
                vec![centre, at(rmax, j), at(rmax, j + 1)]
            }
        })
        .collect()
}

/// Torus with inner and outer radii `rmin`, `rmax` (tube radius (rmax − rmin)/2) in the plane
/// perpendicular to `normal`, outward-facing; n × n quads.
fn torus_loops(centre: DVec3, normal: DVec3, rmin: f64, rmax: f64, n: u32) -> Vec<Vec<DVec3>> {
    let (u, w) = frame(normal);
    let major = 0.5 * (rmax + rmin);
    let minor = 0.5 * (rmax - rmin);
    let at = |i: u32, j: u32| {
        let (a, b) = (segment_angle(i, n), segment_angle(j, n));
        let radial = u * a.cos() + w * a.sin();
        // At the inner equator of a horn torus (rmin = 0) every point is the centre.
        let ring = if j % n * 2 == n && rmin == 0.0 {
            0.0
        } else {
            major + minor * b.cos()
        };
        centre + radial * ring + normal * (minor * b.sin())
    };
    let mut loops = Vec::with_capacity((n * n) as usize);
    for i in 0..n {
        for j in 0..n {
            loops.push(vec![at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    loops
}

// ---------------------------------------------------------------------------------------------
// Faces with seams and holes

fn cross2(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Projects a planar loop onto its own plane (u, w with u × w = the Newell normal, so the
/// loop is counter-clockwise). Returns the 2-D points and a length scale.
fn project(vertices: &[DVec3], normal: DVec3) -> (Vec<DVec2>, f64) {
    let (u, w) = frame(normal);
    let origin = vertices[0];
    let points: Vec<DVec2> = vertices
        .iter()
        .map(|v| {
            let d = *v - origin;
            DVec2::new(d.dot(u), d.dot(w))
        })
        .collect();
    let (lo, hi) = points.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    (points, (hi - lo).length())
}

/// Ear clipping of a planar, weakly simple loop: a simple polygon, or one whose holes are
/// joined to the outline by seams (edges walked once each way, spec §3 `f`). Vertices at the
/// same position as an ear's corners do not block it (they are the other side of a seam).
/// Returns `None` when no ear can be found or the triangles overlap (the input was not weakly
/// simple).
fn triangulate_seamed(vertices: &[DVec3]) -> Option<Vec<[DVec3; 3]>> {
    if vertices.len() < 3 || vertices.len() > 2 * MAX_FACE_VERTICES + 2 {
        return None;
    }
    let (normal, area) = newell(vertices);
    if area.is_nan() || area <= 0.0 {
        return None;
    }
    let (pts, scale) = project(vertices, normal);
    let area_eps = 1e-12 * scale * scale;
    let near = |a: DVec2, b: DVec2| (a - b).length() <= 1e-12 * scale;
    let mut idx: Vec<usize> = (0..pts.len()).collect();
    let mut triangles: Vec<[usize; 3]> = Vec::new();
    while idx.len() > 3 {
        let m = idx.len();
        let mut clipped = false;
        for i in 0..m {
            let (ia, ib, ic) = (idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]);
            let (a, b, c) = (pts[ia], pts[ib], pts[ic]);
            let turn = cross2(b - a, c - b);
            if turn.abs() <= area_eps {
                // A straight vertex or the tip of a zero-width spike: no area lost.
                idx.remove(i);
                clipped = true;
                break;
            }
            if turn < 0.0 {
                continue;
            }
            let blocked = idx.iter().any(|&k| {
                let p = pts[k];
                k != ia
                    && k != ib
                    && k != ic
                    && !near(p, a)
                    && !near(p, b)
                    && !near(p, c)
                    && cross2(b - a, p - a) >= -area_eps
                    && cross2(c - b, p - b) >= -area_eps
                    && cross2(a - c, p - c) >= -area_eps
            });
            if !blocked {
                triangles.push([ia, ib, ic]);
                idx.remove(i);
                clipped = true;
                break;
            }
        }
        if !clipped {
            return None;
        }
    }
    if idx.len() == 3 {
        let (a, b, c) = (pts[idx[0]], pts[idx[1]], pts[idx[2]]);
        let turn = cross2(b - a, c - b);
        if turn > area_eps {
            triangles.push([idx[0], idx[1], idx[2]]);
        } else if turn < -area_eps {
            return None;
        }
    }
    // Interiors must be disjoint (separating-axis test, touching allowed).
    let tri2 = |t: &[usize; 3]| [pts[t[0]], pts[t[1]], pts[t[2]]];
    let tolerance = 1e-9 * scale;
    for (i, s) in triangles.iter().enumerate() {
        let s = tri2(s);
        for t in &triangles[i + 1..] {
            if overlap(&s, &tri2(t), tolerance) {
                return None;
            }
        }
    }
    Some(
        triangles
            .iter()
            .map(|t| [vertices[t[0]], vertices[t[1]], vertices[t[2]]])
            .collect(),
    )
}

/// Whether two counter-clockwise triangles share interior points (more than `tolerance`).
fn overlap(s: &[DVec2; 3], t: &[DVec2; 3], tolerance: f64) -> bool {
    for tri in [s, t] {
        for k in 0..3 {
            let edge = tri[(k + 1) % 3] - tri[k];
            let axis = DVec2::new(-edge.y, edge.x).normalize_or_zero();
            let range = |q: &[DVec2; 3]| {
                q.iter()
                    .map(|p| p.dot(axis))
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                        (lo.min(x), hi.max(x))
                    })
            };
            let (a0, a1) = range(s);
            let (b0, b1) = range(t);
            if a1 <= b0 + tolerance || b1 <= a0 + tolerance {
                return false;
            }
        }
    }
    true
}

/// Whether closed segments ab and cd share a point (within `eps` of area scale).
fn segments_touch(a: DVec2, b: DVec2, c: DVec2, d: DVec2, eps: f64) -> bool {
    let o1 = cross2(b - a, c - a);
    let o2 = cross2(b - a, d - a);
    let o3 = cross2(d - c, a - c);
    let o4 = cross2(d - c, b - c);
    let on = |p: DVec2, q: DVec2, r: DVec2| {
        // r on segment pq, given collinear.
        r.x >= p.x.min(q.x) - eps.sqrt()
            && r.x <= p.x.max(q.x) + eps.sqrt()
            && r.y >= p.y.min(q.y) - eps.sqrt()
            && r.y <= p.y.max(q.y) + eps.sqrt()
    };
    if ((o1 > eps && o2 < -eps) || (o1 < -eps && o2 > eps))
        && ((o3 > eps && o4 < -eps) || (o3 < -eps && o4 > eps))
    {
        return true;
    }
    (o1.abs() <= eps && on(a, b, c))
        || (o2.abs() <= eps && on(a, b, d))
        || (o3.abs() <= eps && on(c, d, a))
        || (o4.abs() <= eps && on(c, d, b))
}

/// Whether `p` is strictly inside the polygon `poly` (even-odd rule).
fn inside(poly: &[DVec2], p: DVec2) -> bool {
    let mut result = false;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        if (a.y > p.y) != (b.y > p.y) {
            let x = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
            if p.x < x {
                result = !result;
            }
        }
    }
    result
}

/// Joins each hole to the outline with a seam (a bridge walked both ways) from its vertex of
/// largest first coordinate to the nearest vertex that sees it, giving one weakly simple loop
/// for [`triangulate_seamed`]. Holes may be given in either orientation; they must lie
/// strictly inside the outline, and no two contours may touch.
fn bridge_holes(
    outline: &[DVec3],
    holes: &[Vec<DVec3>],
) -> std::result::Result<Vec<DVec3>, String> {
    let (normal, area) = newell(outline);
    if area.is_nan() || area <= 0.0 {
        return Err("the outline has zero area".to_owned());
    }
    let mut all: Vec<DVec3> = outline.to_vec();
    let mut contours: Vec<Vec<usize>> = vec![(0..outline.len()).collect()];
    for hole in holes {
        let start = all.len();
        all.extend_from_slice(hole);
        contours.push((start..all.len()).collect());
    }
    let (pts, scale) = project(&all, normal);
    let eps = 1e-12 * scale * scale;
    let signed_area = |c: &[usize]| {
        (0..c.len())
            .map(|i| cross2(pts[c[i]], pts[c[(i + 1) % c.len()]]))
            .sum::<f64>()
            * 0.5
    };
    let outline_2d: Vec<DVec2> = contours[0].iter().map(|&i| pts[i]).collect();
    for (h, contour) in contours.iter_mut().enumerate().skip(1) {
        let a = signed_area(contour);
        if a.abs() <= eps {
            return Err(format!("hole {h} has zero area"));
        }
        if a > 0.0 {
            contour.reverse(); // holes run clockwise
        }
        if let Some(&k) = contour.iter().find(|&&k| !inside(&outline_2d, pts[k])) {
            return Err(format!(
                "hole {h} has a vertex at {:?} that is not strictly inside the outline",
                all[k]
            ));
        }
    }
    // No two contours may touch or cross; no hole may lie inside another.
    let edges = |c: &[usize]| -> Vec<(usize, usize)> {
        (0..c.len()).map(|i| (c[i], c[(i + 1) % c.len()])).collect()
    };
    for i in 0..contours.len() {
        for j in i + 1..contours.len() {
            for (a, b) in edges(&contours[i]) {
                for (c, d) in edges(&contours[j]) {
                    if segments_touch(pts[a], pts[b], pts[c], pts[d], eps) {
                        return Err(format!("contours {i} and {j} touch or cross"));
                    }
                }
            }
            if i > 0 {
                let ci: Vec<DVec2> = contours[i].iter().map(|&k| pts[k]).collect();
                let cj: Vec<DVec2> = contours[j].iter().map(|&k| pts[k]).collect();
                if inside(&ci, cj[0]) || inside(&cj, ci[0]) {
                    return Err(format!("holes {i} and {j} are nested"));
                }
            }
        }
    }

    let mut merged = contours[0].clone();
    let mut remaining: Vec<Vec<usize>> = contours[1..].to_vec();
    remaining.sort_by(|a, b| {
        let max_x = |c: &Vec<usize>| c.iter().map(|&k| pts[k].x).fold(f64::MIN, f64::max);
        max_x(b).total_cmp(&max_x(a))
    });
    while !remaining.is_empty() {
        let hole = remaining.remove(0);
        let (hm, &m) = hole
            .iter()
            .enumerate()
            .max_by(|a, b| pts[*a.1].x.total_cmp(&pts[*b.1].x))
            .ok_or_else(|| "empty hole".to_owned())?;
        let pm = pts[m];
        let mut candidates: Vec<usize> = (0..merged.len()).collect();
        candidates.sort_by(|&a, &b| {
            (pts[merged[a]] - pm)
                .length_squared()
                .total_cmp(&(pts[merged[b]] - pm).length_squared())
        });
        let blockers: Vec<(usize, usize)> = edges(&merged)
            .into_iter()
            .chain(edges(&hole))
            .chain(remaining.iter().flat_map(|c| edges(c)))
            .collect();
        let visible = |slot: usize| {
            let n = merged.len();
            let p = pts[merged[slot]];
            let (prev, next) = (pts[merged[(slot + n - 1) % n]], pts[merged[(slot + 1) % n]]);
            // The bridge must leave p into the polygon's interior wedge.
            let left_in = cross2(p - prev, pm - p) > eps;
            let left_out = cross2(next - p, pm - p) > eps;
            let convex = cross2(p - prev, next - p) > 0.0;
            let in_wedge = if convex {
                left_in && left_out
            } else {
                left_in || left_out
            };
            in_wedge
                && blockers.iter().all(|&(a, b)| {
                    let (pa, pb) = (pts[a], pts[b]);
                    let at = |q: DVec2, end: DVec2| (q - end).length() <= 1e-12 * scale;
                    let end = [(p, pm), (pm, p)].into_iter().find_map(|(end, far)| {
                        if at(pa, end) {
                            Some((end, far, pb))
                        } else if at(pb, end) {
                            Some((end, far, pa))
                        } else {
                            None
                        }
                    });
                    if let Some((end, far, other)) = end {
                        // An edge meeting the bridge at one end may only touch it there: not
                        // run along it.
                        let o = cross2(far - end, other - end);
                        o.abs() > eps || (other - end).dot(far - end) <= 0.0
                    } else {
                        !segments_touch(p, pm, pa, pb, eps)
                    }
                })
        };
        let slot = candidates
            .into_iter()
            .find(|&s| visible(s))
            .ok_or_else(|| "a hole cannot be joined to the outline".to_owned())?;
        let mut spliced = Vec::with_capacity(merged.len() + hole.len() + 2);
        spliced.extend_from_slice(&merged[..=slot]);
        spliced.extend((0..hole.len()).map(|k| hole[(hm + k) % hole.len()]));
        spliced.push(m);
        spliced.push(merged[slot]);
        spliced.extend_from_slice(&merged[slot + 1..]);
        merged = spliced;
    }
    Ok(merged.iter().map(|&k| all[k]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::obj::parse_obj;

    fn no_include(_: &Path) -> io::Result<String> {
        Err(io::ErrorKind::NotFound.into())
    }

    fn load(text: &str) -> MgfScene {
        parse_mgf(text, "t.mgf", no_include).unwrap_or_else(|e| panic!("{e}"))
    }

    fn load_with(text: &str, options: &MgfOptions) -> MgfScene {
        parse_mgf_with(text, "t.mgf", options, no_include).unwrap_or_else(|e| panic!("{e}"))
    }

    fn fail(text: &str) -> MgfError {
        match parse_mgf(text, "t.mgf", no_include) {
            Ok(_) => panic!("{text:?} loaded"),
            Err(e) => e,
        }
    }

    /// In-memory includes, keyed by the path the loader asks for.
    fn files(list: &[(&str, &str)]) -> impl FnMut(&Path) -> io::Result<String> {
        let map: HashMap<PathBuf, String> = list
            .iter()
            .map(|(k, v)| (PathBuf::from(k), (*v).to_owned()))
            .collect();
        move |p: &Path| map.get(p).cloned().ok_or(io::ErrorKind::NotFound.into())
    }

    fn total_area(scene: &Scene) -> f64 {
        scene.surfaces.iter().map(|s| s.polygon.area()).sum()
    }

    /// Enclosed volume by the divergence theorem, V = Σ (a · (b × c)) / 6 over the fan
    /// triangles: positive for a closed outward-facing surface, negative for inward.
    fn volume(scene: &Scene, centre: DVec3) -> f64 {
        scene
            .surfaces
            .iter()
            .flat_map(|s| s.polygon.triangles())
            .map(|[a, b, c]| (a - centre).dot((b - centre).cross(c - centre)) / 6.0)
            .sum()
    }

    fn rgb_luminance(c: [f64; 3]) -> f64 {
        luminance(DVec3::from_array(c))
    }

    fn close(a: f64, b: f64, tolerance: f64) -> bool {
        (a - b).abs() <= tolerance * b.abs().max(1e-300)
    }

    // --- the two scenes ----------------------------------------------------------------------

    #[test]
    fn cornell_mgf_reproduces_the_obj() {
        let mgf = parse_mgf(
            include_str!("../../scenes/cornell.mgf"),
            "scenes/cornell.mgf",
            no_include,
        )
        .unwrap();
        assert!(mgf.warnings.is_empty(), "{:?}", mgf.warnings);
        let obj = parse_obj(
            include_str!("../../scenes/cornell.obj"),
            "scenes/cornell.obj",
            |_| Ok(include_str!("../../scenes/cornell.mtl").to_owned()),
        )
        .unwrap();
        let (m, o) = (&mgf.scene, &obj);
        assert_eq!(m.name, "cornell");
        assert_eq!(m.surfaces.len(), o.surfaces.len());
        for (a, b) in m.surfaces.iter().zip(&o.surfaces) {
            assert_eq!(a.object, b.object);
            let (va, vb) = (a.polygon.vertices(), b.polygon.vertices());
            assert_eq!(va.len(), vb.len(), "{}", a.object);
            for (p, q) in va.iter().zip(vb) {
                // Both formats store the same decimal, so the doubles are identical; the
                // brief's bound is 1e-12.
                assert!((*p - *q).abs().max_element() <= 1e-12, "{}", a.object);
            }
            let (ma, mb) = (m.material(a), o.material(b));
            assert_eq!(ma.name, mb.name);
            assert!(!ma.two_sided);
            for k in 0..3 {
                // xy and rd are written with 17 significant digits; the conversion back is a
                // few double operations (error ~1e-15), well inside the 1e-9 asked for.
                assert!(
                    close(ma.reflectance[k], mb.reflectance[k], 1e-9),
                    "{ma:?} {mb:?}"
                );
                assert!(
                    close(ma.emission[k], mb.emission[k], 1e-9) || ma.emission[k] == mb.emission[k],
                    "{ma:?} {mb:?}"
                );
            }
        }
        assert_eq!(m.materials.len(), o.materials.len());
    }

    #[test]
    fn room_scene_loads_with_its_lamp() {
        let lamp = include_str!("../../scenes/mgf_room_lamp.mgf");
        let room = parse_mgf(
            include_str!("../../scenes/mgf_room.mgf"),
            "scenes/mgf_room.mgf",
            files(&[("mgf_room_lamp.mgf", lamp)]),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let scene = &room.scene;
        let names = scene.object_names();
        for expected in [
            "room.floor",
            "room.walls.back",
            "room.walls.left",
            "table.top",
            "table.legs.a0.0",
            "table.legs.a1.1",
            "ball",
            "column",
            "cabinet",
            "lamp.cord",
            "lamp.shade",
            "lamp.bulb",
        ] {
            assert!(
                names.iter().any(|n| n == expected),
                "{expected} in {names:?}"
            );
        }
        // One warning: the table top's specular gloss.
        assert_eq!(room.warnings.len(), 1, "{:?}", room.warnings);
        assert!(room.warnings[0]
            .message
            .contains("rs (specular reflectance)"));
        assert_eq!(
            room.warnings[0].at,
            Location::line("scenes/mgf_room.mgf", 42)
        );
        let lamp_surface = scene
            .surfaces
            .iter()
            .find(|s| s.object == "lamp.bulb")
            .unwrap();
        assert_eq!(
            lamp_surface.origin.file.as_deref(),
            Some("scenes/mgf_room_lamp.mgf")
        );
        // The bulb hangs at ceiling (2.5) − 0.55, facing down.
        assert!((lamp_surface.polygon.vertices()[0].y - 1.95).abs() < 1e-12);
        assert!((lamp_surface.polygon.normal() - DVec3::NEG_Y).length() < 1e-12);
        let bulb = scene.material(lamp_surface);
        // 2700 K is warm: red > green > blue; luminance ε/(π·683).
        assert!(bulb.emission[0] > bulb.emission[1] && bulb.emission[1] > bulb.emission[2]);
        let expected = 31830.988618379067 / PI / 683.0;
        assert!(close(rgb_luminance(bulb.emission), expected, 1e-12));
        // Area of the back wall: 4 × 2.5 minus the 1 × 0.8 window.
        let back: f64 = scene
            .surfaces
            .iter()
            .filter(|s| s.object == "room.walls.back")
            .map(|s| s.polygon.area())
            .sum();
        assert!((back - 9.2).abs() < 1e-12);
        // Every named scene material is there once; the cabinet copies plaster's sides.
        let cabinet = scene
            .materials
            .iter()
            .find(|m| m.name == "cabinet")
            .unwrap();
        assert!(!cabinet.two_sided);
        assert_eq!(cabinet.reflectance, [0.6; 3]);
        let shade = scene
            .materials
            .iter()
            .find(|m| m.name == "lamp_shade")
            .unwrap();
        assert!(shade.two_sided);
        // The lamp also loads on its own.
        let alone = parse_mgf(lamp, "scenes/mgf_room_lamp.mgf", no_include).unwrap();
        assert!(alone.warnings.is_empty(), "{:?}", alone.warnings);
        assert_eq!(alone.scene.object_names(), ["cord", "shade", "bulb"]);
    }

    // --- entities ----------------------------------------------------------------------------

    const TRIANGLE: &str = "v a =\n\tp 0 0 0\nv b =\n\tp 1 0 0\nv c =\n\tp 0 1 0\n";

    #[test]
    fn comments_continuations_and_blank_lines() {
        let text = format!(
            "# a comment \\\n continued\n\n{TRIANGLE}#no space after the hash\nf a \\\n b \\\n c\n"
        );
        let scene = load(&text).scene;
        assert_eq!(scene.surfaces.len(), 1);
        // The face starts on line 11 (after the comment's two lines, a blank, six vertex
        // lines and the second comment).
        assert_eq!(scene.surfaces[0].origin.line, Some(11));
        assert!((scene.surfaces[0].polygon.area() - 0.5).abs() < 1e-15);
    }

    #[test]
    fn vertex_contexts_have_four_forms_and_apply_when_used() {
        let text = format!(
            "{TRIANGLE}v d = a\n\tp 0 0 5\nf a b c\nv a\n\tp 0 0 1\nf a b c\nv\n\tp 9 9 9\nf d b c\n"
        );
        let scene = load(&text).scene;
        let v: Vec<DVec3> = scene
            .surfaces
            .iter()
            .map(|s| s.polygon.vertices()[0])
            .collect();
        // The first face keeps a's first position; the second sees the changed a; the copy d
        // was changed independently; the unnamed vertex does not touch named ones.
        assert_eq!(v, [DVec3::ZERO, DVec3::Z, DVec3::new(0.0, 0.0, 5.0)]);
    }

    #[test]
    fn objects_nest_with_dots_and_default_to_the_file_stem() {
        let text = format!("{TRIANGLE}f a b c\no house\no roof\nf a b c\no\nf a b c\no\n");
        let scene = load(&text).scene;
        let names: Vec<(&str, &str)> = scene
            .surfaces
            .iter()
            .map(|s| (s.object.as_str(), s.group.as_str()))
            .collect();
        assert_eq!(
            names,
            [("t", "t"), ("house.roof", "house"), ("house", "house")]
        );
    }

    #[test]
    fn non_convex_faces_are_split_and_zero_area_faces_skipped() {
        let l_shape = "v p0 =\np 0 0 0\nv p1 =\np 2 0 0\nv p2 =\np 2 1 0\nv p3 =\np 1 1 0\n\
                       v p4 =\np 1 2 0\nv p5 =\np 0 2 0\nf p0 p1 p2 p3 p4 p5\nf p0 p1 p1\n";
        let loaded = load(l_shape);
        assert!((total_area(&loaded.scene) - 3.0).abs() < 1e-12);
        assert!(loaded
            .scene
            .surfaces
            .iter()
            .all(|s| s.polygon.normal().z > 0.999));
        assert_eq!(loaded.warnings.len(), 1);
        assert_eq!(loaded.warnings[0].at, Location::line("t.mgf", 14));
        assert!(loaded.warnings[0].message.contains("zero-area"));
    }

    /// A square with a square hole joined by a seam, the way spec §3 `f` (figure 2) writes a
    /// wall with a window: "f v1 v2 v3 v4 v5 v6 v7 v8 v5 v4".
    #[test]
    fn the_seam_triangulator_refuses_what_is_not_weakly_simple() {
        let p = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        // The spec's seam polygon triangulates into triangles covering area 12.
        let seamed = [
            p(0.0, 0.0),
            p(4.0, 0.0),
            p(4.0, 4.0),
            p(0.0, 4.0),
            p(1.0, 3.0),
            p(3.0, 3.0),
            p(3.0, 1.0),
            p(1.0, 1.0),
            p(1.0, 3.0),
            p(0.0, 4.0),
        ];
        let triangles = triangulate_seamed(&seamed).unwrap();
        let area: f64 = triangles.iter().map(|t| newell(t).1).sum();
        assert!((area - 12.0).abs() < 1e-12);
        // A self-intersecting loop with unequal lobes (not weakly simple): refused, not
        // triangulated into overlapping pieces.
        let crossed = [p(0.0, 0.0), p(3.0, 3.0), p(3.0, 0.0), p(0.0, 1.0)];
        assert!(triangulate_seamed(&crossed).is_none());
    }

    #[test]
    fn faces_with_seams_are_triangulated_without_the_hole() {
        let text = "v o1 =\np 0 0 0\nv o2 =\np 4 0 0\nv o3 =\np 4 4 0\nv o4 =\np 0 4 0\n\
                    v h1 =\np 1 3 0\nv h2 =\np 3 3 0\nv h3 =\np 3 1 0\nv h4 =\np 1 1 0\n\
                    f o1 o2 o3 o4 h1 h2 h3 h4 h1 o4\n";
        let scene = load(text).scene;
        assert!((total_area(&scene) - 12.0).abs() < 1e-12);
        for s in &scene.surfaces {
            assert!(s.polygon.normal().z > 0.999);
            let c = s.polygon.centroid();
            assert!(!(c.x > 1.0 && c.x < 3.0 && c.y > 1.0 && c.y < 3.0), "{c}");
        }
    }

    fn window_wall(holes: &str) -> String {
        format!(
            "v o1 =\np 0 0 0\nv o2 =\np 4 0 0\nv o3 =\np 4 2.5 0\nv o4 =\np 0 2.5 0\n\
             v a1 =\np 0.5 0.5 0\nv a2 =\np 1.5 0.5 0\nv a3 =\np 1.5 1.5 0\nv a4 =\np 0.5 1.5 0\n\
             v b1 =\np 2.5 1 0\nv b2 =\np 3.5 1 0\nv b3 =\np 3.5 2 0\nv b4 =\np 2.5 2 0\n\
             v z1 =\np 5 1 0\nfh o1 o2 o3 o4 {holes}\n"
        )
    }

    #[test]
    fn faces_with_holes_keep_their_area_and_orientation() {
        // Holes clockwise (as the spec asks), counter-clockwise (accepted), and two at once.
        for (holes, area) in [
            ("- a4 a3 a2 a1", 9.0),
            ("- a1 a2 a3 a4", 9.0),
            ("- a4 a3 a2 a1 - b1 b2 b3 b4", 8.0),
        ] {
            let scene = load(&window_wall(holes)).scene;
            assert!((total_area(&scene) - area).abs() < 1e-12, "{holes}");
            for s in &scene.surfaces {
                assert!(s.polygon.normal().z > 0.999, "{holes}");
                let c = s.polygon.centroid();
                let in_a = c.x > 0.5 && c.x < 1.5 && c.y > 0.5 && c.y < 1.5;
                let in_b = area < 9.0 && c.x > 2.5 && c.x < 3.5 && c.y > 1.0 && c.y < 2.0;
                assert!(!in_a && !in_b, "{holes}: {c}");
            }
        }
    }

    #[test]
    fn bad_holes_are_clear_errors() {
        for holes in ["- a1 a2 z1", "- a1 a2 o3", "- a1 a2"] {
            let e = fail(&window_wall(holes));
            assert_eq!(e.location(), Location::line("t.mgf", 27), "{holes}: {e}");
            assert!(e.to_string().contains("'fh'"), "{e}");
        }
    }

    #[test]
    fn materials_default_two_sided_black_and_take_the_current_colour() {
        let text = format!(
            "{TRIANGLE}f a b c\nm grey =\nc\nrd 0.5\nf a b c\nm red = grey\nsides 1\nc\n\
             cxy 0.5 0.3\nrd 0.2\nc\nf a b c\n"
        );
        let scene = load(&text).scene;
        let m: Vec<&Material> = scene.surfaces.iter().map(|s| scene.material(s)).collect();
        assert_eq!(m[0].name, "_unnamed");
        assert_eq!((m[0].reflectance, m[0].two_sided), ([0.0; 3], true));
        assert_eq!((m[1].name.as_str(), m[1].reflectance), ("grey", [0.5; 3]));
        assert!(m[1].two_sided);
        // rd took the colour current when it was given, not the one reset after it.
        assert_eq!(m[2].name, "red");
        assert!(!m[2].two_sided);
        assert!(m[2].reflectance[0] > m[2].reflectance[1]);
        assert!(close(rgb_luminance(m[2].reflectance), 0.2, 1e-12));
    }

    #[test]
    fn a_material_changed_after_use_becomes_a_second_material() {
        let text = format!("{TRIANGLE}m w =\nrd 0.5\nf a b c\nrd 0.25\nf a b c\nm w\nf a b c\n");
        let scene = load(&text).scene;
        let names: Vec<&str> = scene
            .surfaces
            .iter()
            .map(|s| scene.material(s).name.as_str())
            .collect();
        assert_eq!(names, ["w", "w#2", "w#2"]);
        assert_eq!(scene.materials[1].reflectance, [0.25; 3]);
    }

    #[test]
    fn ignored_properties_warn_once_per_material() {
        let text = format!(
            "{TRIANGLE}m glass =\nrs 0.04 0\nts 0.8 0\nir 1.5 0\ntd 0.1\nrd 0.05\nf a b c\nf a b c\n\
             m matte =\nrs 0 0\nir 1 0\nrd 0.5\nf a b c\n"
        );
        let loaded = load(&text);
        assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
        let w = &loaded.warnings[0];
        assert_eq!(w.at, Location::line("t.mgf", 8));
        for part in [
            "rs (specular reflectance)",
            "ts (specular transmittance)",
            "ir (index of refraction)",
            "td (diffuse transmittance)",
        ] {
            assert!(w.message.contains(part), "{}", w.message);
        }
        let strict = MgfOptions {
            strict: true,
            ..MgfOptions::default()
        };
        let e = parse_mgf_with(&text, "t.mgf", &strict, no_include).unwrap_err();
        assert!(matches!(e, MgfError::Strict { .. }));
        assert_eq!(e.location(), Location::line("t.mgf", 8));
    }

    // --- colour and photometry ---------------------------------------------------------------

    #[test]
    fn d65_gives_equal_rgb_in_absolute_srgb() {
        let d65 = [0.3127 / 0.3290, 1.0, (1.0 - 0.3127 - 0.3290) / 0.3290];
        let rgb = linear_srgb_from_xyz(d65, MgfWhite::D65);
        for c in rgb {
            assert!((c - 1.0).abs() < 1e-12, "{rgb:?}");
        }
        // Under the default white, the equal-energy point is the one that is grey.
        let rgb = linear_srgb_from_xyz([1.0; 3], MgfWhite::EqualEnergy);
        for c in rgb {
            assert!((c - 1.0).abs() < 1e-12, "{rgb:?}");
        }
    }

    #[test]
    fn srgb_matrix_matches_the_published_one() {
        // IEC 61966-2-1's XYZ → sRGB matrix, printed to four decimals.
        let published = [
            [3.2406, -1.5372, -0.4986],
            [-0.9689, 1.8758, 0.0415],
            [0.0557, -0.2040, 1.0570],
        ];
        for i in 0..3 {
            let mut xyz = [0.0; 3];
            xyz[i] = 1.0;
            let column = linear_srgb_from_xyz(xyz, MgfWhite::D65);
            for j in 0..3 {
                let expected = published[j][i];
                // Four printed decimals: ±5e-5, plus the primaries' own rounding in the
                // published derivation (differences of up to 3e-4 are known).
                assert!((column[j] - expected).abs() < 5e-4, "{j} {i}: {column:?}");
            }
        }
    }

    #[test]
    fn black_body_at_2856_k_is_illuminant_a() {
        // CIE Illuminant A is a Planckian radiator at 2856 K, chromaticity (0.44757, 0.40745)
        // (CIE 15:2004, Table T.3). Our 5 nm, 380–780 nm summation is within 4e-5 of it.
        let (x, y) = Colour::from_xyz(blackbody_xyz(2856.0)).unwrap().xy();
        assert!(
            (x - 0.44757).abs() < 1e-4 && (y - 0.40745).abs() < 1e-4,
            "{x} {y}"
        );
        // And it gets bluer with temperature, approaching the locus' limit (0.240, 0.234).
        let (x, y) = Colour::from_xyz(blackbody_xyz(1e6)).unwrap().xy();
        assert!(
            (x - 0.24).abs() < 3e-3 && (y - 0.234).abs() < 3e-3,
            "{x} {y}"
        );
        // Tiny temperatures give no visible light in double precision: an error, not NaN.
        assert!(Colour::from_xyz(blackbody_xyz(1.0)).is_none());
    }

    #[test]
    fn flat_spectrum_is_equal_energy_and_cmix_follows_the_spec_example() {
        // The CIE 1931 functions have equal integrals, so a flat spectrum has chromaticity
        // (1/3, 1/3). The 5 nm table's sums agree to 1e-5; our 1 nm sum of the interpolated
        // table (a trapezoid rule) halves the end samples, which moves xy by another 1.4e-5.
        let (x, y) = Colour::from_xyz(spectrum_xyz(380.0, 780.0, &[1.0, 1.0]))
            .unwrap()
            .xy();
        assert!(
            (x - 1.0 / 3.0).abs() < 3e-5 && (y - 1.0 / 3.0).abs() < 3e-5,
            "{x} {y}"
        );
        // Spec §6.1.1: with primaries R (0.64, 0.33), G (0.29, 0.60), B (0.15, 0.06),
        // "cmix 0.265 R 0.670 G 0.065 B" is white (x = y = 1/3; the weights are rounded to
        // three digits, which moves xy by up to 1e-3).
        let text = format!(
            "{TRIANGLE}c R =\ncxy 0.640 0.330\nc G =\ncxy 0.290 0.600\nc B =\ncxy 0.150 0.060\n\
             c white =\ncmix 0.265 R 0.670 G 0.065 B\nm w =\nrd 0.5\nf a b c\n"
        );
        let scene = load(&text).scene;
        let rho = scene.materials[0].reflectance;
        for c in rho {
            assert!((c - 0.5).abs() < 5e-3, "{rho:?}");
        }
    }

    #[test]
    fn reflectance_keeps_its_luminance_and_channel_ratios() {
        for white in [MgfWhite::EqualEnergy, MgfWhite::D65] {
            let options = MgfOptions {
                white,
                ..MgfOptions::default()
            };
            let text = format!("{TRIANGLE}m m =\nc\ncxy 0.30 0.40\nrd 0.3\nf a b c\n");
            let rho = load_with(&text, &options).scene.materials[0].reflectance;
            assert!(close(rgb_luminance(rho), 0.3, 1e-12));
            let xyz = [0.30 / 0.40, 1.0, 0.30 / 0.40];
            let raw = linear_srgb_from_xyz(xyz, white);
            assert!(close(rho[0] / rho[1], raw[0] / raw[1], 1e-12));
            assert!(close(rho[2] / rho[1], raw[2] / raw[1], 1e-12));
        }
    }

    #[test]
    fn emittance_in_lux_becomes_radiance() {
        // Neutral grey under the equal-energy white: L_e = ε/(π·683) in every channel.
        let text = format!("{TRIANGLE}m lamp =\nsides 1\ned 683\nf a b c\n");
        let loaded = load(&text);
        assert!(loaded.warnings.is_empty());
        for l in loaded.scene.materials[0].emission {
            assert!(close(l, 1.0 / PI, 1e-15));
        }
        // Coloured: the luminance is still ε/(π·683).
        let text = format!("{TRIANGLE}m lamp =\nsides 1\nc\ncct 3000\ned 1000\nf a b c\n");
        let le = load(&text).scene.materials[0].emission;
        assert!(close(rgb_luminance(le), 1000.0 / PI / 683.0, 1e-12));
        assert!(le[0] > le[1] && le[1] > le[2]);
        // A two-sided emitter (the MGF default) warns: we emit from the front only.
        let text = format!("{TRIANGLE}m lamp =\ned 100\nf a b c\n");
        let loaded = load(&text);
        assert_eq!(loaded.warnings.len(), 1);
        assert_eq!(loaded.warnings[0].at, Location::line("t.mgf", 8));
    }

    #[test]
    fn bright_and_out_of_gamut_colours_are_clamped_with_warnings() {
        // Saturated red at ρ_d = 0.5: the red channel needs 0.5/0.2126 > 1.
        let text = format!("{TRIANGLE}m r =\nc\ncxy 0.64 0.33\nrd 0.5\nf a b c\n");
        let loaded = load(&text);
        assert_eq!(loaded.scene.materials[0].reflectance[0], MAX_REFLECTANCE);
        assert_eq!(loaded.warnings.len(), 1);
        assert_eq!(loaded.warnings[0].at, Location::line("t.mgf", 10));
        // Spectral green (520 nm) is outside sRGB: negative channels clamp to 0, Y kept.
        let text = format!("{TRIANGLE}m g =\nc\ncxy 0.0743 0.8338\nrd 0.2\nf a b c\n");
        let loaded = load(&text);
        let rho = loaded.scene.materials[0].reflectance;
        assert!(
            rho.iter().all(|&c| c >= 0.0) && rho.contains(&0.0),
            "{rho:?}"
        );
        assert!(close(rgb_luminance(rho), 0.2, 1e-12));
        assert!(loaded.warnings[0]
            .message
            .contains("outside the sRGB gamut"));
        let strict = MgfOptions {
            strict: true,
            ..MgfOptions::default()
        };
        assert!(parse_mgf_with(&text, "t.mgf", &strict, no_include).is_err());
    }

    // --- tessellation ------------------------------------------------------------------------

    fn primitive(body: &str, n: u32) -> Scene {
        let text = format!(
            "v c =\np 1 2 3\nn 0 0 1\nv top =\np 1 2 4.5\nv tilted =\np 2 3 4\nn 1 1 1\n{body}\n"
        );
        let options = MgfOptions {
            circle_segments: n,
            ..MgfOptions::default()
        };
        load_with(&text, &options).scene
    }

    /// Smallest distance from the centre to the plane of a latitude/longitude facet, for
    /// `n` longitudes and ⌈n/2⌉ bands. A facet between polar angles θ₁ < θ₂ is symmetric
    /// about its middle meridian, so its normal is (sin α · that meridian, cos α) with
    /// tan α = (cos θ₁ − cos θ₂) / (cos(π/n)(sin θ₂ − sin θ₁)) (equal distance of its corners
    /// at θ₁ and θ₂), and the distance is r (sin α sin θ₁ cos(π/n) + cos α cos θ₁).
    fn sphere_inradius(r: f64, n: u32) -> f64 {
        let bands = n.div_ceil(2).max(2);
        let c = (PI / f64::from(n)).cos();
        (0..bands)
            .map(|i| {
                let t1 = PI * f64::from(i) / f64::from(bands);
                let t2 = PI * f64::from(i + 1) / f64::from(bands);
                let alpha = (t1.cos() - t2.cos()).atan2(c * (t2.sin() - t1.sin()));
                (r * (alpha.sin() * t1.sin() * c + alpha.cos() * t1.cos())).abs()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn sphere_area_and_volume_are_within_the_tessellation_bound() {
        let (r, centre) = (0.7, DVec3::new(1.0, 2.0, 3.0));
        assert!((sphere_inradius(1.0, 24) - 0.983_105_6).abs() < 1e-7);
        for n in [3, 7, 24, 61] {
            let scene = primitive(&format!("sph c {r}"), n);
            let d = sphere_inradius(r, n);
            // The polyhedron is convex, inscribed in the sphere and contains the ball of
            // radius d (every facet plane is at least d from the centre), so its area and
            // volume lie between the two balls' (monotonicity of both under inclusion for
            // convex bodies).
            let (a, v) = (total_area(&scene), volume(&scene, centre));
            let slack = 1e-12;
            assert!(a <= 4.0 * PI * r * r * (1.0 + slack), "{n}: {a}");
            assert!(a >= 4.0 * PI * d * d * (1.0 - slack), "{n}: {a}");
            assert!(v <= 4.0 / 3.0 * PI * r.powi(3) * (1.0 + slack), "{n}: {v}");
            assert!(v >= 4.0 / 3.0 * PI * d.powi(3) * (1.0 - slack), "{n}: {v}");
            for s in &scene.surfaces {
                assert!((s.polygon.centroid() - centre).dot(s.polygon.normal()) > 0.0);
                for p in s.polygon.vertices() {
                    assert!(((*p - centre).length() - r).abs() < 1e-12);
                }
            }
        }
        // Negative radius: the same sphere facing in.
        let scene = primitive(&format!("sph c -{r}"), 24);
        assert!(volume(&scene, centre) < 0.0);
        assert!(scene
            .surfaces
            .iter()
            .all(|s| (s.polygon.centroid() - centre).dot(s.polygon.normal()) < 0.0));
    }

    #[test]
    fn cylinder_cone_and_ring_areas_match_their_polygons() {
        let n = 24;
        let (nf, h, r) = (f64::from(n), 1.5, 0.4);
        let half = PI / nf;
        // Cylinder: n rectangles of width 2r sin(π/n) and height h.
        let scene = primitive("cyl c 0.4 top", n);
        assert_eq!(scene.surfaces.len(), n as usize);
        let expected = nf * 2.0 * r * half.sin() * h;
        assert!(close(total_area(&scene), expected, 1e-12));
        assert!(close(
            expected / (2.0 * PI * r * h),
            half.sin() / half,
            1e-12
        ));
        let axis = DVec3::new(1.0, 2.0, 3.0);
        for s in &scene.surfaces {
            let c = s.polygon.centroid();
            let radial = c - DVec3::new(axis.x, axis.y, c.z);
            assert!(radial.dot(s.polygon.normal()) > 0.0);
        }
        let inward = primitive("cyl c -0.4 top", n);
        assert!(inward.surfaces.iter().all(|s| {
            let c = s.polygon.centroid();
            (c - DVec3::new(axis.x, axis.y, c.z)).dot(s.polygon.normal()) < 0.0
        }));
        // Cone to a point: n triangles, base 2r sin(π/n), slant height √(h² + (r cos(π/n))²).
        let scene = primitive("cone c 0.4 top 0", n);
        let expected = nf * r * half.sin() * (h * h + (r * half.cos()).powi(2)).sqrt();
        assert!(close(total_area(&scene), expected, 1e-12));
        // Ring: n trapezoids of the annulus, (n/2) sin(2π/n)(r_max² − r_min²), facing n.
        let scene = primitive("ring tilted 0.1 0.4", n);
        let expected = nf / 2.0 * (2.0 * half).sin() * (0.16 - 0.01);
        assert!(close(total_area(&scene), expected, 1e-12));
        let normal = DVec3::ONE.normalize();
        assert!(scene
            .surfaces
            .iter()
            .all(|s| (s.polygon.normal() - normal).length() < 1e-12));
    }

    #[test]
    fn torus_is_closed_outward_and_matches_its_trapezoids() {
        let n = 24;
        let (rmin, rmax) = (0.3, 0.5);
        let (major, minor) = (0.4, 0.1);
        let centre = DVec3::new(1.0, 2.0, 3.0);
        let scene = primitive(&format!("torus c {rmin} {rmax}"), n);
        // Each quad is an isosceles trapezoid between tube angles v_j and v_j+1 with parallel
        // sides 2ρ sin(π/n) (ρ = R + r cos v, the distance from the axis) and height
        // √((r Δsin v)² + (cos(π/n) Δρ)²).
        let half = PI / f64::from(n);
        let mut expected = 0.0;
        for j in 0..n {
            let (v0, v1) = (segment_angle(j, n), segment_angle(j + 1, n));
            let (r0, r1) = (major + minor * v0.cos(), major + minor * v1.cos());
            let height =
                ((minor * (v1.sin() - v0.sin())).powi(2) + (half.cos() * (r1 - r0)).powi(2)).sqrt();
            expected += f64::from(n) * (r0 + r1) * half.sin() * height;
        }
        assert!(close(total_area(&scene), expected, 1e-12));
        // Both circles are inscribed polygons, each losing ≈ (π/n)²/6 of the length: the
        // area is within 1 % of 4π²Rr at n = 24.
        assert!(close(
            total_area(&scene),
            4.0 * PI * PI * major * minor,
            1e-2
        ));
        assert!(volume(&scene, centre) > 0.0);
        for s in &scene.surfaces {
            let c = s.polygon.centroid() - centre;
            let tube = DVec3::new(c.x, c.y, 0.0).normalize() * major;
            assert!((c - tube).dot(s.polygon.normal()) > 0.0);
        }
        let inward = primitive(&format!("torus c -{rmin} -{rmax}"), n);
        assert!(volume(&inward, centre) < 0.0);
        // A horn torus (r_min = 0) closes at the centre with triangles.
        let horn = primitive("torus c 0 0.5", n);
        assert!(volume(&horn, centre) > 0.0);
    }

    #[test]
    fn prism_is_a_closed_solid_facing_out() {
        // Spec §3 `prism`: "Make a unit cube starting at the origin and extending to the
        // positive octant"; the base's right-hand-rule normal looks along −z.
        let cube = "v cv0 =\np 0 0 0\nv cv1 =\np 0 1 0\nv cv2 =\np 1 1 0\nv cv3 =\np 1 0 0\n";
        let scene = load(&format!("{cube}prism cv0 cv1 cv2 cv3 1\n")).scene;
        assert_eq!(scene.surfaces.len(), 6);
        assert!((total_area(&scene) - 6.0).abs() < 1e-12);
        let centre = DVec3::splat(0.5);
        assert!((volume(&scene, centre) - 1.0).abs() < 1e-12);
        let (lo, hi) = scene.bounds();
        assert_eq!((lo, hi), (DVec3::ZERO, DVec3::ONE));
        assert!(scene
            .surfaces
            .iter()
            .all(|s| (s.polygon.centroid() - centre).dot(s.polygon.normal()) > 0.0));
        // Negative length: extruded the other way (along the base normal), facing in.
        let scene = load(&format!("{cube}prism cv0 cv1 cv2 cv3 -1\n")).scene;
        assert_eq!(scene.bounds().0, DVec3::new(0.0, 0.0, -1.0));
        assert!((volume(&scene, DVec3::new(0.5, 0.5, -0.5)) + 1.0).abs() < 1e-12);
    }

    // --- transforms --------------------------------------------------------------------------

    fn first_vertices(scene: &Scene) -> Vec<Vec<DVec3>> {
        scene
            .surfaces
            .iter()
            .map(|s| s.polygon.vertices().to_vec())
            .collect()
    }

    fn assert_points(actual: &[DVec3], expected: &[DVec3]) {
        assert_eq!(actual.len(), expected.len());
        for (a, e) in actual.iter().zip(expected) {
            // Rotations by multiples of 90° are exact up to cos(π/2) ≈ 6e-17 terms.
            assert!((*a - *e).length() < 1e-12, "{actual:?} vs {expected:?}");
        }
    }

    #[test]
    fn transform_arguments_act_in_order() {
        let text = "v a =\np 1 0 0\nv b =\np 1 1 0\nv c =\np 0 1 0\n\
                    xf -s 2 -rz 90 -t 1 0 0\nf a b c\nxf\n\
                    xf -rx 90 -t 0 0 1 -ry 90\nf a b c\nxf\n\
                    xf -i 3 -rz 30\nf a b c\nxf\n";
        let v = first_vertices(&load(text).scene);
        // Scale 2, then +90° about z ((x, y) → (−y, x)), then +1 in x.
        assert_points(
            &v[0],
            &[
                DVec3::new(1.0, 2.0, 0.0),
                DVec3::new(-1.0, 2.0, 0.0),
                DVec3::new(-1.0, 0.0, 0.0),
            ],
        );
        // +90° about x ((y, z) → (−z, y)), +1 in z, then +90° about y ((z, x) → (−x, z)):
        // (1,0,0) → (1,0,0) → (1,0,1) → (1,0,−1); (1,1,0) → (1,0,1) → (1,0,2) → (2,0,−1);
        // (0,1,0) → (0,0,1) → (0,0,2) → (2,0,0).
        assert_points(
            &v[1],
            &[
                DVec3::new(1.0, 0.0, -1.0),
                DVec3::new(2.0, 0.0, -1.0),
                DVec3::new(2.0, 0.0, 0.0),
            ],
        );
        // -i 3 -rz 30 is one rotation by 90°.
        assert_points(
            &v[2],
            &[
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(-1.0, 1.0, 0.0),
                DVec3::new(-1.0, 0.0, 0.0),
            ],
        );
    }

    #[test]
    fn nested_transforms_apply_the_inner_one_first() {
        // Spec §2.2.2: "The final ring center is (5,-10,0) … The normal orientation is
        // (0,0,-1)".
        let text = "xf -t 5 0 0\nv v1 =\np 0 10 0\nn 0 0 1\nxf -rx 180\nring v1 0 2\nxf\nxf\n";
        let scene = load(text).scene;
        let area = total_area(&scene);
        let centre: DVec3 = scene
            .surfaces
            .iter()
            .map(|s| s.polygon.centroid() * s.polygon.area())
            .sum::<DVec3>()
            / area;
        assert!(
            (centre - DVec3::new(5.0, -10.0, 0.0)).length() < 1e-12,
            "{centre}"
        );
        assert!(scene
            .surfaces
            .iter()
            .all(|s| (s.polygon.normal() - DVec3::NEG_Z).length() < 1e-12));
    }

    #[test]
    fn mirrors_keep_faces_mirrored_not_flipped() {
        // A face looking along +z mirrored in x still looks along +z; one looking along +x
        // looks along −x.
        let text = "v a =\np 1 0 0\nv b =\np 0 1 0\nv c =\np 0 0 0\nv d =\np 0 0 1\n\
                    xf -mx\nf a b c\nf c b d\nxf\nxf -s -1\nf a b c\nxf\n";
        let scene = load(text).scene;
        let normals: Vec<DVec3> = scene.surfaces.iter().map(|s| s.polygon.normal()).collect();
        assert!((normals[0] - DVec3::Z).length() < 1e-12);
        assert!((normals[1] - DVec3::NEG_X).length() < 1e-12, "{normals:?}");
        // -s -1 is the point reflection: +z becomes −z.
        assert!((normals[2] - DVec3::NEG_Z).length() < 1e-12);
    }

    #[test]
    fn arrays_make_named_instances() {
        // Spec §2.2.3: 60 spheres in a 3 × 4 × 5 array moved to (15, 30, 45).
        let text = "v v0 =\np 0 0 0\no grid\n\
                    xf -a 3 -t 1 0 0 -a 4 -t 0 1 0 -a 5 -t 0 0 1 -i 1 -t 15 30 45\n\
                    sph v0 0.1\nxf\no\n";
        let options = MgfOptions {
            circle_segments: 4,
            ..MgfOptions::default()
        };
        let scene = load_with(text, &options).scene;
        let names = scene.object_names();
        assert_eq!(names.len(), 60);
        assert_eq!(names[0], "grid.a0.0.0");
        assert!(names.contains(&"grid.a2.3.4".to_owned()));
        let (lo, hi) = scene.bounds();
        assert!((lo - DVec3::new(14.9, 29.9, 44.9)).length() < 1e-9, "{lo}");
        assert!((hi - DVec3::new(17.1, 33.1, 49.1)).length() < 1e-9, "{hi}");
        // An array inside an array multiplies; the inner names follow the outer.
        let text = "v a =\np 0 0 0\nv b =\np 1 0 0\nv c =\np 0 1 0\n\
                    xf -a 2 -t 0 0 1\no part\nxf -a 3 -t 2 0 0\nf a b c\nxf\no\nxf\n";
        let scene = load(text).scene;
        assert_eq!(scene.surfaces.len(), 6);
        assert_eq!(scene.object_names()[5], "a1.part.a2");
        assert_eq!(
            scene.surfaces[5].polygon.vertices()[0],
            DVec3::new(4.0, 0.0, 1.0)
        );
    }

    // --- includes ----------------------------------------------------------------------------

    #[test]
    fn includes_resolve_against_the_including_file() {
        let top = "v a =\np 0 0 0\ni parts/wing.mgf -t 0 0 2\n";
        let wing = "v b =\np 1 0 0\ni ../lib/tip.mgf\nf a b c\n";
        let tip = "v c =\np 0 1 0\n";
        let mut asked = Vec::new();
        let mut read = files(&[("parts/wing.mgf", wing), ("lib/tip.mgf", tip)]);
        let scene = parse_mgf(top, "scenes/top.mgf", |p| {
            asked.push(p.to_path_buf());
            read(p)
        })
        .unwrap()
        .scene;
        assert_eq!(
            asked,
            [
                PathBuf::from("parts/wing.mgf"),
                PathBuf::from("lib/tip.mgf")
            ]
        );
        let s = &scene.surfaces[0];
        assert_eq!(s.origin.file.as_deref(), Some("scenes/parts/wing.mgf"));
        assert_eq!(s.origin.line, Some(4));
        assert_eq!(s.object, "wing");
        assert_eq!(s.polygon.vertices()[0], DVec3::new(0.0, 0.0, 2.0));
    }

    #[test]
    fn include_problems_name_the_file_and_line() {
        let cycle = parse_mgf(
            "i a.mgf\n",
            "top.mgf",
            files(&[("a.mgf", "# a\ni b.mgf\n"), ("b.mgf", "i a.mgf\n")]),
        )
        .unwrap_err();
        assert_eq!(cycle.location(), Location::line("b.mgf", 1));
        assert!(
            cycle.to_string().ends_with("a.mgf → b.mgf → a.mgf"),
            "{cycle}"
        );
        let itself = parse_mgf("\ni top.mgf\n", "top.mgf", no_include).unwrap_err();
        assert!(matches!(itself, MgfError::IncludeCycle { .. }), "{itself}");

        // A chain f0 → f1 → … deeper than the limit.
        let chain: Vec<(String, String)> = (1..=40)
            .map(|k| (format!("f{k}.mgf"), format!("i f{}.mgf\n", k + 1)))
            .collect();
        let refs: Vec<(&str, &str)> = chain
            .iter()
            .map(|(a, b)| (a.as_str(), b.as_str()))
            .collect();
        let deep = parse_mgf("i f1.mgf\n", "f0.mgf", files(&refs)).unwrap_err();
        assert!(matches!(deep, MgfError::IncludeDepth { .. }), "{deep}");
        assert_eq!(deep.location(), Location::line("f31.mgf", 1));

        let missing = parse_mgf("# x\ni nowhere.mgf\n", "d/top.mgf", no_include).unwrap_err();
        assert_eq!(missing.location(), Location::line("d/top.mgf", 2));
        assert!(missing.to_string().contains("d/nowhere.mgf"), "{missing}");

        // An include must balance its own xf contexts.
        let open = parse_mgf(
            "i a.mgf\n",
            "top.mgf",
            files(&[("a.mgf", "\n\nxf -t 1 0 0\n")]),
        )
        .unwrap_err();
        assert_eq!(open.location(), Location::line("a.mgf", 3));
        let closes_outer = parse_mgf(
            "xf -t 1 0 0\ni a.mgf\nxf\n",
            "top.mgf",
            files(&[("a.mgf", "xf\n")]),
        )
        .unwrap_err();
        assert_eq!(closes_outer.location(), Location::line("a.mgf", 1));
    }

    // --- errors ------------------------------------------------------------------------------

    #[test]
    fn malformed_inputs_are_errors_naming_file_and_line() {
        let v = "v a =\np 0 0 0\nv b =\np 1 0 0\nv c =\np 0 1 0\nv n =\np 0 0 0\nn 0 0 1\n";
        // (input after the 9 vertex lines, line of the error, words the message contains)
        let cases: &[(&str, usize, &str)] = &[
            ("foo 1 2\n", 10, "unknown MGF entity 'foo'"),
            ("f a b missing\n", 10, "vertex 'missing' is not defined"),
            ("v d =\np nan 0 0\n", 11, "'nan' is not a finite number"),
            ("v d =\np 1e999 0 0\n", 11, "not a finite number"),
            ("p 1 2\n", 10, "'p' needs x y z"),
            ("n 0 x 1\n", 10, "'x' is not a number"),
            ("xf -q 1\n", 10, "bad 'xf' argument: '-q'"),
            ("xf -t 1 2\n", 10, "'-t' needs 3 value(s)"),
            ("xf -s 0\n", 10, "scale factor must not be zero"),
            ("xf -a 0 -t 1 0 0\n", 10, "'-a 0' must be in 1..=100000"),
            ("xf -i 2.5 -t 1 0 0\n", 10, "'2.5' is not an integer"),
            ("xf -rz inf\n", 10, "not a finite number"),
            ("xf\n", 10, "no transform was begun"),
            ("o\n", 10, "no object was begun"),
            ("xf -t 1 0 0\nf a b c\n", 10, "never closed"),
            ("c nothere\n", 10, "colour 'nothere' is not defined"),
            ("m nothere\n", 10, "material 'nothere' is not defined"),
            ("m x = nothere\n", 10, "material 'nothere' is not defined"),
            ("c 1bad =\n", 10, "not an MGF name"),
            ("c a b c d\n", 10, "'c' takes"),
            ("cxy 0.7 0.5\n", 10, "is not a colour"),
            ("cspec 700 400 1 1\n", 10, "0 < λ_min < λ_max"),
            ("cspec 900 1000 1 1\n", 10, "no positive visible luminance"),
            ("cct -5\n", 10, "must be > 0"),
            ("cmix 1 a 2\n", 10, "needs pairs"),
            ("cmix 1 nocolour\n", 10, "colour 'nocolour' is not defined"),
            ("rd 1.5\n", 10, "must be in [0, 1]"),
            ("ed -1\n", 10, "must be ≥ 0"),
            ("sides 3\n", 10, "must be 1 or 2"),
            ("rs 0.1\n", 10, "'rs' needs a value and a roughness"),
            ("ir 0 0\n", 10, "n_real > 0"),
            ("f a b\n", 10, "at least three vertices"),
            ("sph a 0\n", 10, "radius must not be zero"),
            ("sph a\n", 10, "'sph' needs"),
            ("cyl a 1 a\n", 10, "coincide"),
            ("cone a -1 b 1\n", 10, "same sign"),
            ("cone a 0 b 0\n", 10, "both be zero"),
            ("ring a 0 1\n", 10, "has no normal"),
            ("ring n 1 0.5\n", 10, "0 ≤ r_min < r_max"),
            ("torus n 0.3 0.2\n", 10, "|r_max| > |r_min|"),
            ("torus n -0.1 0.2\n", 10, "same sign"),
            ("prism a b c 0\n", 10, "length must not be zero"),
            ("prism a b\n", 10, "at least three vertices"),
            ("ies lamp.ies\n", 10, "not supported"),
            ("i\n", 10, "needs a file name"),
            ("i /etc/scene.mgf\n", 10, "must be relative"),
            ("o a b\n", 10, "one object name"),
            (
                "v d =\np 0 0 1\nv e =\np 1 1 0.5\nf a b d e c\n",
                14,
                "not planar",
            ),
            ("f a \\\n b \\\n nope\n", 10, "'nope' is not defined"),
            (
                "xf -a 1000 -t 1 0 0 -a 1000 -t 0 1 0\n",
                10,
                "at most 100000",
            ),
            ("xf -i 1000 -s 10\nf a b c\nxf\n", 10, "overflows"),
        ];
        assert!(cases.len() >= 20);
        for (input, line, words) in cases {
            let text = format!("{v}{input}");
            let e = fail(&text);
            assert_eq!(
                e.location(),
                Location::line("t.mgf", *line),
                "{input:?}: {e}"
            );
            let message = e.to_string();
            assert!(
                message.starts_with(&format!("t.mgf: line {line}: ")),
                "{input:?}: {message}"
            );
            assert!(message.contains(words), "{input:?}: {message}");
            // The same error through SceneError keeps the place and the words.
            let scene_error: SceneError = e.into();
            assert!(scene_error.to_string().contains(words), "{scene_error}");
        }
        // Whole-file errors: nothing to draw, bad options.
        let e = fail(v);
        assert!(matches!(e, MgfError::Empty { .. }));
        assert_eq!(e.to_string(), "t.mgf: scene has no surfaces");
        let options = MgfOptions {
            circle_segments: 100_000,
            ..MgfOptions::default()
        };
        assert!(parse_mgf_with(v, "t.mgf", &options, no_include).is_err());
        // Too many surfaces for the limit.
        let options = MgfOptions {
            max_surfaces: 10,
            ..MgfOptions::default()
        };
        let e =
            parse_mgf_with(&format!("{v}sph a 1\n"), "t.mgf", &options, no_include).unwrap_err();
        assert_eq!(e.location(), Location::line("t.mgf", 10));
    }

    #[test]
    fn garbage_never_panics() {
        // Every prefix of a scene that uses every entity, and the scene with every line
        // doubled, either loads or fails with an error.
        let room = include_str!("../../scenes/mgf_room.mgf");
        let lamp = include_str!("../../scenes/mgf_room_lamp.mgf");
        let lines: Vec<&str> = room.lines().collect();
        for k in 0..lines.len() {
            let text = lines[..k].join("\n");
            let _ = parse_mgf(&text, "r.mgf", files(&[("mgf_room_lamp.mgf", lamp)]));
        }
        let doubled: String = lines.iter().map(|l| format!("{l}\n{l}\n")).collect();
        let _ = parse_mgf(&doubled, "r.mgf", files(&[("mgf_room_lamp.mgf", lamp)]));
        for junk in [
            "\u{feff}",
            "\\",
            "# \\",
            "m\u{e9} =",
            "f",
            "-",
            "fh a - - b",
            "xf -a",
        ] {
            let _ = parse_mgf(junk, "j.mgf", no_include);
        }
    }
}
