//! Photometric luminaire files (IES LM-63, EULUMDAT) read into one type C goniometric table.
//!
//! A [`Photometry`] is the luminous intensity distribution of a luminaire in type C
//! coordinates (IES LM-75, CIE 121): the polar angle γ is measured from the nadir (γ = 0 along
//! the luminaire's axis, pointing away from it: "down" for a ceiling luminaire, γ = 180° up),
//! and the azimuth C from the C0 half-plane, increasing towards C90 (see `light::Aim` for
//! how C and γ map onto a scene). Both file formats store a table of
//! intensities on a grid of (C, γ) angles, often for only part of the C range when the
//! luminaire is symmetric; parsing expands the table to the full 0–360° C range, applies the
//! file's multipliers so that every value is in candela, and keeps the luminous opening and
//! the descriptive text for reports.
//!
//! Readers: [`from_ies`] (IES LM-63-1986/1991/1995/2002/2019), [`from_eulumdat`] (EULUMDAT,
//! `.ldt`), and [`load`], which picks one by file extension and reads the file with bounded
//! memory and without blocking on special files.
//!
//! Conventions fixed here (both formats):
//! - **Interpolation** ([`Photometry::intensity`]): bilinear in (C, γ) between the table's
//!   angles, periodic in C (the interval from the last C plane to 360° interpolates towards
//!   the C0 plane). Outside the γ range a file covers the intensity is zero: a file whose
//!   vertical angles end at 90° says nothing is emitted upwards.
//! - **Flux** ([`Photometry::flux`]): Φ = ∫₀^{2π} ∫ I(C, γ) sin γ dγ dC integrated exactly
//!   for that bilinear interpolant, so flux and intensity never disagree.
//!
//! See also: [`crate::units`] for the conversion of lumens and candela into the renderer's
//! radiometric RGB units.

mod eulumdat;
mod ies;

use std::f64::consts::PI;
use std::io::Read;
use std::path::Path;

/// Largest photometric file [`load`] reads, bytes (16 MiB). Real files are a few kB to a few
/// hundred kB; the cap keeps a wrongly named large file (or a device) from eating memory.
pub const MAX_FILE_BYTES: u64 = 16 * 1024 * 1024;

/// Most angles a file may list on either axis (C or γ). A 0.1° grid over 0–180° is 1801.
pub const MAX_ANGLES: usize = 10_000;

/// Most intensity values a file may store (C planes × γ angles, before symmetric expansion).
/// 361 × 181 (1° × 1°, full sphere) is 65 341.
pub const MAX_VALUES: usize = 1_000_000;

/// Why a photometric file could not be read.
///
/// Messages read `file: line N: what is wrong` for anything inside a file, so a caller can
/// prefix its own context without repeating the file name.
#[derive(Debug, thiserror::Error)]
pub enum PhotometryError {
    /// The file could not be opened or read.
    #[error("{file}: cannot read: {source}")]
    Read {
        /// The file as the caller named it.
        file: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The path is not a regular file (a directory, FIFO, socket or device); it was not
    /// opened, since reading a FIFO can block forever and a device can be endless.
    #[error("{file}: is a {kind}, not a regular file; refusing to read it")]
    NotRegularFile {
        /// The file as the caller named it.
        file: String,
        /// What it is instead ("directory", "FIFO", "character device", …).
        kind: &'static str,
    },
    /// The file is larger than [`MAX_FILE_BYTES`].
    #[error("{file}: is {bytes} bytes, over the {limit}-byte limit for photometric files")]
    TooLarge {
        /// The file as the caller named it.
        file: String,
        /// Its size (or the bytes read before giving up), bytes.
        bytes: u64,
        /// The limit, bytes.
        limit: u64,
    },
    /// The file extension is neither `.ies` nor `.ldt`.
    #[error("{file}: unknown photometric format (expected a .ies or .ldt file)")]
    UnknownFormat {
        /// The file as the caller named it.
        file: String,
    },
    /// Malformed or out-of-range content: a missing or extra value, a token that is not a
    /// number, a count out of bounds, angles out of order, a negative or non-finite candela.
    #[error("{file}: line {line}: {message}")]
    Syntax {
        /// The file as the caller named it.
        file: String,
        /// 1-based line of the offending input (the last line when the file ends early).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Valid LM-63 or EULUMDAT that uses a feature this reader does not support (tilt
    /// tables, type A or B photometry).
    #[error("{file}: line {line}: unsupported: {message}")]
    Unsupported {
        /// The file as the caller named it.
        file: String,
        /// 1-based line of the feature.
        line: usize,
        /// What is not supported, and what is.
        message: String,
    },
}

impl PhotometryError {
    /// The 1-based line the error points at, if it points inside the file.
    pub fn line(&self) -> Option<usize> {
        match self {
            PhotometryError::Syntax { line, .. } | PhotometryError::Unsupported { line, .. } => {
                Some(*line)
            }
            _ => None,
        }
    }
}

/// The format and version a [`Photometry`] was read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SourceFormat {
    /// IES LM-63 of the given revision.
    Ies(IesVersion),
    /// EULUMDAT (`.ldt`).
    Eulumdat,
}

/// Revisions of IES LM-63, told apart by the file's first line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum IesVersion {
    /// LM-63-1986: no version line; free-form label lines.
    Lm63_1986,
    /// LM-63-1991: first line `IESNA91`.
    Lm63_1991,
    /// LM-63-1995: first line `IESNA:LM-63-1995`.
    Lm63_1995,
    /// LM-63-2002: first line `IESNA:LM-63-2002`.
    Lm63_2002,
    /// LM-63-2019: first line `IES:LM-63-2019`.
    Lm63_2019,
}

/// The C-plane symmetry a file declared, i.e. which part of the C range it stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Symmetry {
    /// One C plane stands for all (rotationally symmetric about the nadir axis).
    /// LM-63: a single horizontal angle 0°; EULUMDAT: Isym 1.
    Rotational,
    /// Symmetric about the C0–C180 and C90–C270 planes; C0…C90 stored.
    /// LM-63: last horizontal angle 90°; EULUMDAT: Isym 4.
    Quadrant,
    /// Symmetric about the C0–C180 plane, I(C) = I(360° − C); C0…C180 stored.
    /// LM-63: last horizontal angle 180°; EULUMDAT: Isym 2.
    BilateralC0C180,
    /// Symmetric about the C90–C270 plane, I(C) = I(180° − C); C90…C270 stored.
    /// LM-63-1995: horizontal angles 90°…270°; EULUMDAT: Isym 3.
    BilateralC90C270,
    /// No symmetry: the whole C range stored.
    /// LM-63: last horizontal angle in (180°, 360°]; EULUMDAT: Isym 0.
    None,
}

/// Dimensions of the luminous opening, m, as the file gives them.
///
/// LM-63-2002 measures `length` along the C0–C180 axis, `width` along C90–C270 and `height`
/// along the nadir axis; negative values encode round shapes (e.g. a negative width and
/// length for a circular opening of that diameter) and are kept with their sign. EULUMDAT's
/// "length/diameter" and "width" of the luminous area (lines 16, 17; width 0 for a circular
/// area of that diameter) map to `length` and `width`, and `height` is the largest of its
/// four C-plane heights (lines 18–21). All zero means a point source.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LuminousOpening {
    /// Width, m.
    pub width_m: f64,
    /// Length, m.
    pub length_m: f64,
    /// Height, m.
    pub height_m: f64,
}

/// Descriptive data carried for reports; none of it changes the intensities.
#[derive(Debug, Clone, PartialEq)]
pub struct Metadata {
    /// The format and version read.
    pub format: SourceFormat,
    /// Label lines in file order: LM-63 `[KEYWORD] value` pairs (with `[MORE]` lines joined
    /// onto the value before them with a newline; free-form label lines under the key ""),
    /// or the EULUMDAT text fields under descriptive keys (`REPORT`, `FILENAME`, `DATE`, …).
    pub keywords: Vec<(String, String)>,
    /// Manufacturer (LM-63 `[MANUFAC]`; EULUMDAT line 1, company identification).
    pub manufacturer: Option<String>,
    /// Catalogue number (LM-63 `[LUMCAT]`; EULUMDAT line 10, luminaire number).
    pub catalogue: Option<String>,
    /// Luminaire description (LM-63 `[LUMINAIRE]`; EULUMDAT line 9, luminaire name).
    pub luminaire: Option<String>,
    /// Lamp description (LM-63 `[LAMP]`; EULUMDAT type of lamps of the first lamp set).
    pub lamp: Option<String>,
    /// Input power of the luminaire, W (LM-63 input watts; EULUMDAT wattage of the first
    /// lamp set, including ballast).
    pub input_watts: Option<f64>,
    /// Light output ratio the file states, as a fraction (EULUMDAT LORL / 100; LM-63 has
    /// none).
    pub light_output_ratio: Option<f64>,
    /// LM-63-2019 "file generation type" (second photometric line, second value), as
    /// written, e.g. `1.00001`; `None` for other versions and formats.
    pub file_generation_type: Option<String>,
}

/// A type C goniometric luminous intensity table, expanded to the full C range.
///
/// Invariants (established by the readers): γ angles non-decreasing within [0°, 180°] with
/// first < last; C angles strictly increasing, the first 0° and the last ≤ 360° (a single
/// plane at 0° for a rotationally symmetric luminaire); every candela value finite and ≥ 0.
#[derive(Debug, Clone, PartialEq)]
pub struct Photometry {
    /// The file as the caller named it.
    pub file: String,
    /// The symmetry the file declared (the table is already expanded).
    pub symmetry: Symmetry,
    /// Rated flux of the lamps the intensities refer to, lm: lumens per lamp × number of
    /// lamps (LM-63) or the first lamp set's total flux (EULUMDAT). `None` for absolute
    /// photometry (LM-63 lumens per lamp −1; EULUMDAT negative number of lamps).
    pub lamp_lumens: Option<f64>,
    /// Luminous opening, m.
    pub opening: LuminousOpening,
    /// Descriptive data for reports.
    pub metadata: Metadata,
    c_deg: Vec<f64>,
    gamma_deg: Vec<f64>,
    /// Candela, plane-major: `candela[i * gamma_deg.len() + j]` is I(C_i, γ_j).
    candela: Vec<f64>,
}

/// What a reader hands over: the table as stored plus the descriptive fields.
struct StoredTable {
    symmetry: Symmetry,
    /// The stored C angles (strictly increasing, validated for `symmetry`).
    c_deg: Vec<f64>,
    /// γ angles (non-decreasing, first < last, within [0°, 180°]).
    gamma_deg: Vec<f64>,
    /// Candela with all multipliers applied, plane-major over `c_deg`.
    candela: Vec<f64>,
}

impl Photometry {
    /// Builds the expanded table from what a reader validated.
    fn from_stored(
        file: &str,
        table: StoredTable,
        lamp_lumens: Option<f64>,
        opening: LuminousOpening,
        metadata: Metadata,
    ) -> Self {
        let n_gamma = table.gamma_deg.len();
        debug_assert_eq!(table.candela.len(), table.c_deg.len() * n_gamma);
        let (c_deg, candela) =
            expand_symmetry(table.symmetry, &table.c_deg, &table.candela, n_gamma);
        Self {
            file: file.to_string(),
            symmetry: table.symmetry,
            lamp_lumens,
            opening,
            metadata,
            c_deg,
            gamma_deg: table.gamma_deg,
            candela,
        }
    }

    /// The C angles of the expanded table, degrees: strictly increasing from 0°, the last
    /// ≤ 360° (one angle, 0°, for a rotationally symmetric luminaire).
    pub fn c_angles(&self) -> &[f64] {
        &self.c_deg
    }

    /// The γ angles of the table, degrees: non-decreasing within [0°, 180°].
    pub fn gamma_angles(&self) -> &[f64] {
        &self.gamma_deg
    }

    /// The candela values of C plane `i` (index into [`Photometry::c_angles`]), one per γ
    /// angle; `None` if there is no such plane.
    pub fn plane(&self, i: usize) -> Option<&[f64]> {
        let n = self.gamma_deg.len();
        self.candela.get(i * n..(i + 1) * n)
    }

    /// The largest tabulated intensity, cd.
    pub fn max_intensity(&self) -> f64 {
        self.candela.iter().copied().fold(0.0, f64::max)
    }

    /// Luminous intensity towards (C, γ), cd.
    ///
    /// Bilinear interpolation of the table: along γ, linear between the two tabulated angles
    /// around `gamma_deg` in each of the two C planes around `c_deg`, then linear in C
    /// between those planes. C is periodic: it is taken modulo 360°, and between the last
    /// tabulated plane and 360° the interpolation runs towards the C0 plane. A rotationally
    /// symmetric table ignores C.
    ///
    /// Edge cases: zero outside the γ range the file covers (a table on 0°–90° emits nothing
    /// above the horizontal; γ is not folded, so γ outside [0°, 180°] gives zero too) and for
    /// non-finite angles. At a γ angle listed twice (a step in the distribution) the value
    /// from the larger-angle side is used.
    pub fn intensity(&self, c_deg: f64, gamma_deg: f64) -> f64 {
        if !c_deg.is_finite() {
            return 0.0;
        }
        let Some((j, t)) = locate_gamma(&self.gamma_deg, gamma_deg) else {
            return 0.0;
        };
        let along_gamma = |plane: usize| {
            let n = self.gamma_deg.len();
            let a = self.candela[plane * n + j];
            let b = self.candela[plane * n + j + 1];
            a + (b - a) * t
        };
        if self.c_deg.len() == 1 {
            return along_gamma(0);
        }
        let (i0, i1, s) = locate_c(&self.c_deg, c_deg);
        let a = along_gamma(i0);
        let b = along_gamma(i1);
        a + (b - a) * s
    }

    /// Total luminous flux of the table, lm.
    ///
    /// Φ = ∫₀^{2π} ∫ I(C, γ) sin γ dγ dC over the γ range of the file, with I the bilinear
    /// interpolant of [`Photometry::intensity`] and C in radians, integrated exactly: on a
    /// γ interval [γ₀, γ₁] of width h a linear function with end values f₀, f₁ gives
    /// ∫ f sin γ dγ = f₀ w₀ + f₁ w₁ with
    ///
    ///   w₀ = cos γ₀ − (sin γ₁ − sin γ₀)/h,  w₁ = (sin γ₁ − sin γ₀)/h − cos γ₁,
    ///
    /// (evaluated in a cancellation-free form, see `gamma_weights`), and the interpolant is
    /// linear in C between planes, so each C interval of width ΔC contributes ΔC times the
    /// mean of its two planes' γ integrals (the trapezoid rule, exact for linear functions).
    /// The periodic interval from the last plane to 360° is included.
    pub fn flux(&self) -> f64 {
        let n = self.gamma_deg.len();
        let weights: Vec<(f64, f64)> = self
            .gamma_deg
            .windows(2)
            .map(|w| gamma_weights(w[0].to_radians(), w[1].to_radians()))
            .collect();
        let plane_integral = |i: usize| -> f64 {
            let p = &self.candela[i * n..(i + 1) * n];
            weights
                .iter()
                .enumerate()
                .map(|(j, &(w0, w1))| p[j] * w0 + p[j + 1] * w1)
                .sum()
        };
        let m = self.c_deg.len();
        if m == 1 {
            return 2.0 * PI * plane_integral(0);
        }
        let integrals: Vec<f64> = (0..m).map(plane_integral).collect();
        let mut total = 0.0;
        for i in 0..m - 1 {
            let dc = (self.c_deg[i + 1] - self.c_deg[i]).to_radians();
            total += dc * 0.5 * (integrals[i] + integrals[i + 1]);
        }
        let last = self.c_deg[m - 1];
        if last < 360.0 {
            let dc = (360.0 - last).to_radians();
            total += dc * 0.5 * (integrals[m - 1] + integrals[0]);
        }
        total
    }

    /// Light output ratio of the table: [`Photometry::flux`] / [`Photometry::lamp_lumens`]
    /// (dimensionless); `None` for absolute photometry.
    pub fn light_output_ratio(&self) -> Option<f64> {
        self.lamp_lumens.map(|lamps| self.flux() / lamps)
    }
}

/// Index `j` and weight `t` ∈ [0, 1] of the γ interval [γ_j, γ_{j+1}] holding `gamma`, or
/// `None` outside [γ_first, γ_last] (and for NaN).
fn locate_gamma(gamma: &[f64], x: f64) -> Option<(usize, f64)> {
    let n = gamma.len();
    if !(x >= gamma[0] && x <= gamma[n - 1]) {
        return None;
    }
    // The last angle ≤ x; with repeated angles, the last of them (the larger-angle side).
    let i = gamma.partition_point(|&g| g <= x) - 1;
    if i >= n - 1 {
        return Some((n - 2, 1.0));
    }
    // gamma[i] ≤ x < gamma[i + 1], so the width is positive.
    Some((i, (x - gamma[i]) / (gamma[i + 1] - gamma[i])))
}

/// The two C planes around `c_deg` (taken modulo 360°) and the weight of the second.
fn locate_c(c: &[f64], c_deg: f64) -> (usize, usize, f64) {
    let mut x = c_deg.rem_euclid(360.0);
    if x >= 360.0 {
        // rem_euclid of a tiny negative number rounds up to 360.
        x = 0.0;
    }
    let m = c.len();
    // c[0] = 0 ≤ x, so i ≥ 0.
    let i = c.partition_point(|&v| v <= x) - 1;
    if i + 1 < m {
        return (i, i + 1, (x - c[i]) / (c[i + 1] - c[i]));
    }
    // x ≥ c[m - 1], which is then < 360: the periodic interval towards C0 at 360°.
    let last = c[m - 1];
    (m - 1, 0, (x - last) / (360.0 - last))
}

/// Exact weights (w₀, w₁) with ∫_{a}^{b} f(γ) sin γ dγ = f(a) w₀ + f(b) w₁ for f linear on
/// [a, b] (radians); (0, 0) for a zero-width interval.
///
/// With m = (a + b)/2 and d = (b − a)/2 the closed forms of [`Photometry::flux`] become
/// w₀ = sin m sin d + cos m φ(d), w₁ = sin m sin d − cos m φ(d), φ(d) = cos d − sin d / d,
/// which avoids subtracting nearly equal numbers; φ uses its Taylor series for small d
/// (−d²/3 + d⁴/30 − d⁶/840 + d⁸/45360, truncation < d¹⁰/4·10⁶, below 1e-19 relative for
/// d < 0.05).
fn gamma_weights(a: f64, b: f64) -> (f64, f64) {
    let d = 0.5 * (b - a);
    if d <= 0.0 {
        return (0.0, 0.0);
    }
    let m = 0.5 * (a + b);
    let phi = if d < 0.05 {
        let d2 = d * d;
        d2 * (-1.0 / 3.0 + d2 * (1.0 / 30.0 + d2 * (-1.0 / 840.0 + d2 / 45360.0)))
    } else {
        d.cos() - d.sin() / d
    };
    let s = m.sin() * d.sin();
    let t = m.cos() * phi;
    (s + t, s - t)
}

/// Expands a stored table to the full C range by the symmetry's mirror images.
///
/// Each symmetry is a set of maps C ↦ ±C + offset (the identity among them); every stored
/// plane is placed at each of its images that falls in [0°, 360°], images of the same plane
/// at the same angle (a plane on a symmetry plane, e.g. C90 under quadrant symmetry) are
/// kept once. Because the maps are affine, linear interpolation between the images gives
/// the mirror image of the interpolation between the stored planes, so nothing is lost or
/// invented. Stored angles are strictly increasing, so two different planes never land on
/// the same angle.
fn expand_symmetry(
    symmetry: Symmetry,
    c_deg: &[f64],
    candela: &[f64],
    n_gamma: usize,
) -> (Vec<f64>, Vec<f64>) {
    let maps: &[(f64, f64)] = match symmetry {
        Symmetry::Rotational | Symmetry::None => return (c_deg.to_vec(), candela.to_vec()),
        // I(C) = I(180 − C) = I(180 + C) = I(360 − C).
        Symmetry::Quadrant => &[(1.0, 0.0), (-1.0, 180.0), (1.0, 180.0), (-1.0, 360.0)],
        // I(C) = I(360 − C).
        Symmetry::BilateralC0C180 => &[(1.0, 0.0), (-1.0, 360.0)],
        // I(C) = I(180 − C); stored 90…270, images 180 − C (−90…90) and 540 − C (270…450).
        Symmetry::BilateralC90C270 => &[(1.0, 0.0), (-1.0, 180.0), (-1.0, 540.0)],
    };
    let mut images: Vec<(f64, usize)> = Vec::with_capacity(maps.len() * c_deg.len());
    for &(sign, offset) in maps {
        for (i, &c) in c_deg.iter().enumerate() {
            let image = sign * c + offset;
            if (0.0..=360.0).contains(&image) {
                images.push((image, i));
            }
        }
    }
    images.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    images.dedup();
    let mut angles = Vec::with_capacity(images.len());
    let mut values = Vec::with_capacity(images.len() * n_gamma);
    for (angle, i) in images {
        angles.push(angle);
        values.extend_from_slice(&candela[i * n_gamma..(i + 1) * n_gamma]);
    }
    (angles, values)
}

/// Reads an IES LM-63 file already in memory. `file` names it in errors and in
/// [`Photometry::file`].
///
/// Versions 1986 (no version line), 1991 (`IESNA91`), 1995 (`IESNA:LM-63-1995`), 2002
/// (`IESNA:LM-63-2002`) and 2019 (`IES:LM-63-2019`); `TILT=NONE` only; photometric type 1
/// (C) only. Candela values are multiplied by the candela multiplier and the ballast factor,
/// and for 1986 and 1991 also by the ballast-lamp photometric factor (that field is "future
/// use" in 1995 and 2002 and the file generation type in 2019, so it is not applied there).
/// See the `ies` module documentation for the full grammar and checks.
pub fn from_ies(text: &str, file: &str) -> Result<Photometry, PhotometryError> {
    ies::parse(text, file)
}

/// Reads an EULUMDAT file already in memory. `file` names it in errors and in
/// [`Photometry::file`].
///
/// Intensities in cd/klm are converted to cd as I = value × conversion factor (line 24)
/// × Φ₁ / 1000, where Φ₁ is the total luminous flux of the first lamp set (line 26c); a
/// negative number of lamps in that set marks absolute photometry (Φ₁ is then the
/// luminaire's flux, and [`Photometry::lamp_lumens`] is `None`). See the `eulumdat` module
/// documentation for the layout and checks.
pub fn from_eulumdat(text: &str, file: &str) -> Result<Photometry, PhotometryError> {
    eulumdat::parse(text, file)
}

/// Loads a photometric file, choosing the reader by extension: `.ies` → [`from_ies`],
/// `.ldt` → [`from_eulumdat`] (case-insensitive).
///
/// Safe on any path: the type and size are checked with [`std::fs::metadata`] before the
/// file is opened, so directories, FIFOs, sockets and devices are refused without being
/// opened (a FIFO cannot block the caller, `/dev/zero` cannot fill memory), a file over
/// [`MAX_FILE_BYTES`] is refused, and the read itself stops after `MAX_FILE_BYTES + 1` bytes
/// in case the file grew in between (a path swapped for a FIFO between the check and the
/// open is not guarded against). Text is UTF-8 if it decodes as UTF-8, else Latin-1
/// (ISO 8859-1, one character per byte), the usual encoding of older European files.
pub fn load(path: &Path) -> Result<Photometry, PhotometryError> {
    enum Kind {
        Ies,
        Ldt,
    }
    let file = path.display().to_string();
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let kind = match extension.as_deref() {
        Some("ies") => Kind::Ies,
        Some("ldt") => Kind::Ldt,
        _ => return Err(PhotometryError::UnknownFormat { file }),
    };
    let read_error = |source| PhotometryError::Read {
        file: file.clone(),
        source,
    };
    let metadata = std::fs::metadata(path).map_err(read_error)?;
    if !metadata.is_file() {
        return Err(PhotometryError::NotRegularFile {
            file,
            kind: describe_file_type(&metadata.file_type()),
        });
    }
    if metadata.len() > MAX_FILE_BYTES {
        return Err(PhotometryError::TooLarge {
            file,
            bytes: metadata.len(),
            limit: MAX_FILE_BYTES,
        });
    }
    let handle = std::fs::File::open(path).map_err(read_error)?;
    let mut bytes = Vec::new();
    handle
        .take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(read_error)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(PhotometryError::TooLarge {
            file,
            bytes: bytes.len() as u64,
            limit: MAX_FILE_BYTES,
        });
    }
    let text = match String::from_utf8(bytes) {
        Ok(text) => text,
        Err(e) => e.into_bytes().iter().map(|&b| char::from(b)).collect(),
    };
    match kind {
        Kind::Ies => from_ies(&text, &file),
        Kind::Ldt => from_eulumdat(&text, &file),
    }
}

/// A word for a file type that is not a regular file.
fn describe_file_type(file_type: &std::fs::FileType) -> &'static str {
    if file_type.is_dir() {
        return "directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return "FIFO";
        }
        if file_type.is_socket() {
            return "socket";
        }
        if file_type.is_char_device() {
            return "character device";
        }
        if file_type.is_block_device() {
            return "block device";
        }
    }
    "special file"
}

/// Splits text into lines at `\r\n`, `\n` or a lone `\r` (old Mac files), without the
/// terminators. A final terminator does not start an extra empty line.
fn split_lines(text: &str) -> Vec<&str> {
    let mut lines = Vec::new();
    let bytes = text.as_bytes();
    let mut start = 0;
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'\n' => {
                lines.push(&text[start..i]);
                start = i + 1;
            }
            b'\r' => {
                lines.push(&text[start..i]);
                if bytes.get(i + 1) == Some(&b'\n') {
                    i += 1;
                }
                start = i + 1;
            }
            _ => {}
        }
        i += 1;
    }
    if start < bytes.len() {
        lines.push(&text[start..]);
    }
    lines
}

/// Checks that the text is text: no NUL characters (binary data). Returns the text without
/// a leading byte-order mark.
fn check_text<'a>(text: &'a str, file: &str) -> Result<&'a str, PhotometryError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if let Some(pos) = text.find('\0') {
        let line = 1 + split_lines(&text[..pos]).len()
            - usize::from(!text[..pos].is_empty() && !text[..pos].ends_with(['\n', '\r']));
        return Err(PhotometryError::Syntax {
            file: file.to_string(),
            line,
            message: "contains a NUL character: binary data, not a photometric text file"
                .to_string(),
        });
    }
    if text.trim().is_empty() {
        return Err(PhotometryError::Syntax {
            file: file.to_string(),
            line: 1,
            message: "file is empty".to_string(),
        });
    }
    Ok(text)
}

/// A numeric token with the line it came from.
#[derive(Debug, Clone, Copy)]
struct Token<'a> {
    line: usize,
    text: &'a str,
}

/// Reads tokens in order, naming what was expected when the input runs out.
struct Tokens<'a> {
    tokens: Vec<Token<'a>>,
    next: usize,
    file: &'a str,
    /// Line number reported when the input ends early: the file's last line.
    last_line: usize,
    /// Accept "0,85" for 0.85 (EULUMDAT files from locales with a decimal comma).
    decimal_comma: bool,
}

impl<'a> Tokens<'a> {
    /// Tokens of `lines` (numbered from `first_line`), split at whitespace, at `separators`,
    /// and at DOS end-of-file characters (Ctrl-Z).
    fn new(lines: &[&'a str], first_line: usize, separators: &[char], file: &'a str) -> Self {
        let mut tokens = Vec::new();
        for (k, line) in lines.iter().enumerate() {
            let split = line
                .split(|ch: char| ch.is_whitespace() || ch == '\u{1a}' || separators.contains(&ch))
                .filter(|t| !t.is_empty());
            tokens.extend(split.map(|text| Token {
                line: first_line + k,
                text,
            }));
        }
        Self {
            tokens,
            next: 0,
            file,
            last_line: (first_line + lines.len()).saturating_sub(1).max(1),
            decimal_comma: false,
        }
    }

    /// Also accepts a decimal comma in numbers (never combine with ',' as a separator).
    fn with_decimal_comma(mut self) -> Self {
        self.decimal_comma = true;
        self
    }

    /// The line of the next token (the last line if none is left).
    fn next_line(&self) -> usize {
        self.tokens
            .get(self.next)
            .map_or(self.last_line, |t| t.line)
    }

    /// The line of the token read last (the first line if none was read).
    fn previous_line(&self) -> usize {
        self.next
            .checked_sub(1)
            .and_then(|k| self.tokens.get(k))
            .map_or(self.last_line, |t| t.line)
    }

    fn remaining(&self) -> usize {
        self.tokens.len() - self.next
    }

    fn syntax(&self, line: usize, message: String) -> PhotometryError {
        PhotometryError::Syntax {
            file: self.file.to_string(),
            line,
            message,
        }
    }

    /// The next token, or an error saying the file ended where `what` was expected.
    fn next(&mut self, what: &str) -> Result<Token<'a>, PhotometryError> {
        match self.tokens.get(self.next) {
            Some(&token) => {
                self.next += 1;
                Ok(token)
            }
            None => Err(self.syntax(self.last_line, format!("file ends early: expected {what}"))),
        }
    }

    /// The next token as a finite number.
    fn number(&mut self, what: &str) -> Result<(Token<'a>, f64), PhotometryError> {
        let token = self.next(what)?;
        let parsed = if self.decimal_comma {
            parse_number_with_decimal_comma(token.text)
        } else {
            parse_number(token.text)
        };
        let value = parsed.ok_or_else(|| {
            self.syntax(
                token.line,
                format!("{what}: '{}' is not a number", token.text),
            )
        })?;
        if !value.is_finite() {
            return Err(self.syntax(
                token.line,
                format!("{what}: '{}' is not a finite number", token.text),
            ));
        }
        Ok((token, value))
    }

    /// The next token as an integer in `min..=max` (a number with no fractional part, as
    /// LM-63-1986 allows "3.0" for a count).
    fn integer(&mut self, what: &str, min: i64, max: i64) -> Result<i64, PhotometryError> {
        let (token, value) = self.number(what)?;
        if value.fract() != 0.0 {
            return Err(self.syntax(
                token.line,
                format!("{what}: '{}' is not a whole number", token.text),
            ));
        }
        if value < min as f64 || value > max as f64 {
            return Err(self.syntax(
                token.line,
                format!("{what} is {}, must be between {min} and {max}", token.text),
            ));
        }
        Ok(value as i64)
    }

    /// `n` angles in degrees within [lo, hi], non-decreasing (or strictly increasing).
    fn angles(
        &mut self,
        n: usize,
        what: &str,
        (lo, hi): (f64, f64),
        strictly_increasing: bool,
    ) -> Result<(Vec<f64>, Vec<usize>), PhotometryError> {
        self.ensure(n, what)?;
        let mut angles = Vec::with_capacity(n);
        let mut lines = Vec::with_capacity(n);
        for k in 0..n {
            let (token, value) = self.number(what)?;
            if !(lo..=hi).contains(&value) {
                return Err(self.syntax(
                    token.line,
                    format!("{what}: {value}° is outside [{lo}°, {hi}°]"),
                ));
            }
            if let Some(&previous) = angles.last() {
                let out_of_order = if strictly_increasing {
                    value <= previous
                } else {
                    value < previous
                };
                if out_of_order {
                    let order = if strictly_increasing {
                        "increasing"
                    } else {
                        "non-decreasing"
                    };
                    return Err(self.syntax(
                        token.line,
                        format!(
                            "{what}: angle {} ({value}°) follows {previous}°; angles must be {order}",
                            k + 1
                        ),
                    ));
                }
            }
            angles.push(value);
            lines.push(token.line);
        }
        Ok((angles, lines))
    }

    /// `n` intensity values, finite and ≥ 0, each multiplied by `scale`.
    fn intensities(
        &mut self,
        n: usize,
        what: &str,
        scale: f64,
    ) -> Result<Vec<f64>, PhotometryError> {
        self.ensure(n, what)?;
        let mut values = Vec::with_capacity(n);
        for _ in 0..n {
            let (token, value) = self.number(what)?;
            if value < 0.0 {
                return Err(
                    self.syntax(token.line, format!("{what}: '{}' is negative", token.text))
                );
            }
            values.push(value * scale);
        }
        Ok(values)
    }

    /// Fails, before anything is allocated for them, if fewer than `n` tokens remain.
    fn ensure(&self, n: usize, what: &str) -> Result<(), PhotometryError> {
        let left = self.remaining();
        if left < n {
            return Err(self.syntax(
                self.last_line,
                format!("file ends early: expected {n} {what}, found only {left} values"),
            ));
        }
        Ok(())
    }

    /// Fails on any token left over.
    fn finish(&self, after: &str) -> Result<(), PhotometryError> {
        if let Some(token) = self.tokens.get(self.next) {
            return Err(self.syntax(
                token.line,
                format!(
                    "unexpected extra value '{}' after {after} ({} extra values in all)",
                    token.text,
                    self.remaining()
                ),
            ));
        }
        Ok(())
    }
}

/// Parses a decimal number (Rust float syntax, which accepts "1", "1.", ".5", "1e3", and
/// also "NaN" and "inf", which callers reject as non-finite).
fn parse_number(text: &str) -> Option<f64> {
    text.parse::<f64>().ok()
}

/// [`parse_number`], also reading a single decimal comma ("0,85") when there is no point.
fn parse_number_with_decimal_comma(text: &str) -> Option<f64> {
    parse_number(text).or_else(|| {
        if text.matches(',').count() == 1 && !text.contains('.') {
            parse_number(&text.replace(',', "."))
        } else {
            None
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An LM-63-2002 file with the given horizontal angles and one row of candela values per
    /// horizontal angle.
    pub(super) fn ies_file(vertical: &[f64], horizontal: &[f64], rows: &[Vec<f64>]) -> String {
        let join = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let mut s = String::from("IESNA:LM-63-2002\n[TEST] unit test\n[MANUFAC] none\nTILT=NONE\n");
        s += &format!(
            "1 -1 1 {} {} 1 2 0 0 0\n1 1 0\n",
            vertical.len(),
            horizontal.len()
        );
        s += &join(vertical);
        s += "\n";
        s += &join(horizontal);
        s += "\n";
        for row in rows {
            s += &join(row);
            s += "\n";
        }
        s
    }

    fn degrees(from: f64, to: f64, step: f64) -> Vec<f64> {
        let n = ((to - from) / step).round() as usize;
        (0..=n).map(|k| from + step * k as f64).collect()
    }

    #[test]
    fn isotropic_source_is_flat_with_flux_4_pi_i0() {
        let i0 = 250.0;
        let vertical = degrees(0.0, 180.0, 22.5);
        let row = vec![i0; vertical.len()];
        let p = from_ies(&ies_file(&vertical, &[0.0], &[row]), "iso.ies").unwrap();
        assert_eq!(p.symmetry, Symmetry::Rotational);
        for c in [0.0, 17.0, 123.4, 359.9, -45.0, 720.5] {
            for g in [0.0, 0.1, 44.0, 90.0, 133.3, 180.0] {
                assert_eq!(p.intensity(c, g), i0, "C = {c}, γ = {g}");
            }
        }
        // Exact integration: the only error is rounding in a sum of 8 weights (each ~1e-16).
        let phi = p.flux();
        assert!(
            (phi - 4.0 * PI * i0).abs() <= 1e-9 * 4.0 * PI * i0,
            "Φ = {phi}, 4π I0 = {}",
            4.0 * PI * i0
        );
        // Same with a non-rotational (full) table of equal planes, sampled irregularly.
        let horizontal = [0.0, 10.0, 95.0, 200.0, 300.0];
        let vertical = [0.0, 1.0, 7.5, 60.0, 90.0, 91.0, 179.0, 180.0];
        let rows = vec![vec![i0; vertical.len()]; horizontal.len()];
        let p = from_ies(&ies_file(&vertical, &horizontal, &rows), "iso.ies").unwrap();
        assert_eq!(p.symmetry, Symmetry::None);
        assert!((p.flux() - 4.0 * PI * i0).abs() <= 1e-9 * 4.0 * PI * i0);
        assert_eq!(p.intensity(330.0, 120.0), i0);
    }

    #[test]
    fn lambertian_flux_matches_pi_i0_within_the_interpolation_error() {
        // I = I0 cos γ sampled every h = 5° on [0°, 90°]. Linear interpolation of cos γ lies
        // below it by (cos ξ / 2)(γ − γ_j)(γ_{j+1} − γ), whose mean over an interval is
        // ≈ cos γ · h²/12, so the table flux falls short of the exact π I0 by
        //   2π I0 ∫₀^{π/2} (h²/12) cos γ sin γ dγ = π I0 h²/12   (plus O(h⁴)),
        // i.e. a relative deficit of h²/12 = 6.35e-4; rigorously 0 < deficit ≤ h²/4.
        let i0 = 1000.0;
        let vertical = degrees(0.0, 90.0, 5.0);
        let row: Vec<f64> = vertical.iter().map(|g| i0 * g.to_radians().cos()).collect();
        let p = from_ies(&ies_file(&vertical, &[0.0], &[row]), "lambert.ies").unwrap();
        let h = 5f64.to_radians();
        let deficit = (PI * i0 - p.flux()) / (PI * i0);
        assert!(deficit > 0.0 && deficit <= h * h / 4.0, "deficit {deficit}");
        // The O(h⁴) remainder is h²/12 · O(h²) ≈ 0.1 % of the leading term; allow 1 %.
        let leading = h * h / 12.0;
        assert!(
            (deficit / leading - 1.0).abs() < 0.01,
            "deficit {deficit}, predicted {leading}"
        );
        // Nothing above the horizontal: the file covers γ ≤ 90°.
        assert_eq!(p.intensity(0.0, 90.5), 0.0);
        assert_eq!(p.intensity(0.0, 180.0), 0.0);
        // Between samples the interpolant is linear.
        let mid = 0.5 * (i0 * 10f64.to_radians().cos() + i0 * 15f64.to_radians().cos());
        assert!((p.intensity(42.0, 12.5) - mid).abs() < 1e-9);
    }

    /// A quadrant-symmetric distribution with different C0, C45, C90 planes.
    fn quadrant_rows() -> (Vec<f64>, Vec<f64>, Vec<Vec<f64>>) {
        let vertical = vec![0.0, 30.0, 60.0, 90.0, 120.0, 180.0];
        let c0 = vec![500.0, 420.0, 150.0, 10.0, 5.0, 0.0];
        let c45 = vec![500.0, 460.0, 260.0, 30.0, 8.0, 0.0];
        let c90 = vec![500.0, 480.0, 300.0, 60.0, 12.0, 0.0];
        (vertical, vec![0.0, 45.0, 90.0], vec![c0, c45, c90])
    }

    #[test]
    fn symmetric_and_full_forms_agree() {
        let (vertical, _, planes) = quadrant_rows();
        let [c0, c45, c90] = [&planes[0], &planes[1], &planes[2]].map(|p| p.clone());
        let quadrant = from_ies(
            &ies_file(&vertical, &[0.0, 45.0, 90.0], &planes),
            "quadrant.ies",
        )
        .unwrap();
        let bilateral = from_ies(
            &ies_file(
                &vertical,
                &[0.0, 45.0, 90.0, 135.0, 180.0],
                &[
                    c0.clone(),
                    c45.clone(),
                    c90.clone(),
                    c45.clone(),
                    c0.clone(),
                ],
            ),
            "bilateral.ies",
        )
        .unwrap();
        let full_rows = vec![
            c0.clone(),
            c45.clone(),
            c90.clone(),
            c45.clone(),
            c0.clone(),
            c45.clone(),
            c90.clone(),
            c45.clone(),
            c0.clone(),
        ];
        let full = from_ies(
            &ies_file(&vertical, &degrees(0.0, 360.0, 45.0), &full_rows),
            "full.ies",
        )
        .unwrap();
        // Full form without the repeated 360° plane: the periodic interval closes it.
        let open = from_ies(
            &ies_file(&vertical, &degrees(0.0, 315.0, 45.0), &full_rows[..8]),
            "open.ies",
        )
        .unwrap();
        // LM-63-1995 form: C90…C270 stored, symmetric about the C90–C270 plane.
        let c90_270 = from_ies(
            &ies_file(
                &vertical,
                &[90.0, 135.0, 180.0, 225.0, 270.0],
                &[
                    c90.clone(),
                    c45.clone(),
                    c0.clone(),
                    c45.clone(),
                    c90.clone(),
                ],
            ),
            "c90.ies",
        )
        .unwrap();
        assert_eq!(quadrant.symmetry, Symmetry::Quadrant);
        assert_eq!(bilateral.symmetry, Symmetry::BilateralC0C180);
        assert_eq!(full.symmetry, Symmetry::None);
        assert_eq!(c90_270.symmetry, Symmetry::BilateralC90C270);
        assert_eq!(quadrant.c_angles(), full.c_angles());
        for k in 0..200 {
            // A deterministic scatter of directions, including the table's own angles.
            let c = (k as f64 * 37.3) % 400.0 - 20.0;
            let g = (k as f64 * 13.7) % 185.0;
            let reference = full.intensity(c, g);
            for other in [&quadrant, &bilateral, &open, &c90_270] {
                // Same numbers interpolated between the same angles: equal to rounding.
                assert!(
                    (other.intensity(c, g) - reference).abs() <= 1e-12 * reference.max(1.0),
                    "{}: C = {c}, γ = {g}: {} vs {reference}",
                    other.file,
                    other.intensity(c, g)
                );
            }
        }
        for other in [&quadrant, &bilateral, &open, &c90_270] {
            assert!((other.flux() - full.flux()).abs() <= 1e-12 * full.flux());
        }
    }

    #[test]
    fn flux_integrates_the_interpolant_itself() {
        // An irregular, asymmetric table; flux() must equal a brute-force integration of
        // intensity(): per cell, 8-point Gauss–Legendre in C (exact for the linear C
        // dependence) × 16-point Gauss–Legendre in γ (exact to degree 31; for (a + bγ) sin γ
        // on intervals of at most 1 rad the remainder is many orders below 1e-15).
        let vertical = [0.0, 2.5, 10.0, 10.0, 33.0, 90.0, 140.0, 180.0];
        let horizontal = [0.0, 20.0, 90.0, 100.0, 250.0, 330.0];
        let rows: Vec<Vec<f64>> = (0..horizontal.len())
            .map(|i| {
                (0..vertical.len())
                    .map(|j| ((i * 7 + j * 13) % 11) as f64 * 37.0 + 1.0)
                    .collect()
            })
            .collect();
        let p = from_ies(&ies_file(&vertical, &horizontal, &rows), "irregular.ies").unwrap();
        let (x16, w16) = gauss_legendre(16);
        let (x8, w8) = gauss_legendre(8);
        let mut c_edges = p.c_angles().to_vec();
        c_edges.push(360.0);
        let mut brute = 0.0;
        for cw in c_edges.windows(2) {
            for gw in vertical.windows(2) {
                if gw[1] == gw[0] {
                    continue;
                }
                for (xc, wc) in x8.iter().zip(&w8) {
                    let c = 0.5 * (cw[0] + cw[1]) + 0.5 * (cw[1] - cw[0]) * xc;
                    for (xg, wg) in x16.iter().zip(&w16) {
                        let g = 0.5 * (gw[0] + gw[1]) + 0.5 * (gw[1] - gw[0]) * xg;
                        let jac =
                            0.25 * (cw[1] - cw[0]).to_radians() * (gw[1] - gw[0]).to_radians();
                        brute += wc * wg * jac * p.intensity(c, g) * g.to_radians().sin();
                    }
                }
            }
        }
        let phi = p.flux();
        assert!(
            (phi - brute).abs() <= 1e-10 * brute,
            "flux {phi}, quadrature {brute}"
        );
    }

    /// Gauss–Legendre nodes and weights on [−1, 1]: Newton's method on the Legendre
    /// polynomial P_n from the usual cosine starting guesses; w = 2 / ((1 − x²) P_n'(x)²).
    fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
        // (P_n(z), P_n'(z)) by the three-term recurrence.
        let legendre = |z: f64| {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            (p1, n as f64 * (z * p1 - p0) / (z * z - 1.0))
        };
        let mut nodes = Vec::with_capacity(n);
        let mut weights = Vec::with_capacity(n);
        for i in 0..n {
            let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            for _ in 0..50 {
                let (p, dp) = legendre(z);
                z -= p / dp;
            }
            let (_, dp) = legendre(z);
            nodes.push(z);
            weights.push(2.0 / ((1.0 - z * z) * dp * dp));
        }
        (nodes, weights)
    }

    #[test]
    fn gamma_weights_match_the_direct_closed_form() {
        // Wide intervals: the direct formula has no cancellation worth speaking of.
        for (a, b) in [(0.0, 0.5), (0.3, 1.9), (1.0, PI), (0.0, PI)] {
            let h = b - a;
            let w0 = a.cos() - (b.sin() - a.sin()) / h;
            let w1 = (b.sin() - a.sin()) / h - b.cos();
            let (v0, v1) = gamma_weights(a, b);
            assert!((v0 - w0).abs() < 1e-14 && (v1 - w1).abs() < 1e-14);
        }
        // Series branch against the direct formula at the switch-over (d = 0.05 − ε), where
        // the direct form still has ~1e-13 relative accuracy.
        let (a, b) = (0.7, 0.7 + 0.0999);
        let h = b - a;
        let (v0, v1) = gamma_weights(a, b);
        let w0 = a.cos() - (b.sin() - a.sin()) / h;
        let w1 = (b.sin() - a.sin()) / h - b.cos();
        assert!((v0 - w0).abs() < 1e-13 * w0.abs() + 1e-16);
        assert!((v1 - w1).abs() < 1e-13 * w1.abs() + 1e-16);
        // Tiny interval at the pole: w0 ≈ h²/6, w1 ≈ h²/3 (∫₀^h γ sin γ ≈ h³/3, /h).
        let h = 1e-6;
        let (v0, v1) = gamma_weights(0.0, h);
        assert!((v0 / (h * h / 6.0) - 1.0).abs() < 1e-9);
        assert!((v1 / (h * h / 3.0) - 1.0).abs() < 1e-9);
        assert_eq!(gamma_weights(1.0, 1.0), (0.0, 0.0));
    }

    #[test]
    fn interpolation_is_bilinear_and_periodic() {
        let vertical = [0.0, 90.0];
        let horizontal = [0.0, 90.0, 180.0, 270.0];
        let rows = vec![
            vec![100.0, 0.0],
            vec![200.0, 0.0],
            vec![300.0, 0.0],
            vec![400.0, 0.0],
        ];
        let p = from_ies(&ies_file(&vertical, &horizontal, &rows), "t.ies").unwrap();
        assert!((p.intensity(45.0, 0.0) - 150.0).abs() < 1e-12);
        assert!((p.intensity(45.0, 45.0) - 75.0).abs() < 1e-12);
        // Between C270 and C360 ≡ C0: from 400 back to 100.
        assert!((p.intensity(315.0, 0.0) - 250.0).abs() < 1e-12);
        assert!((p.intensity(-45.0, 0.0) - 250.0).abs() < 1e-12);
        assert!((p.intensity(675.0, 0.0) - 250.0).abs() < 1e-12);
        assert!((p.intensity(-1e-300, 0.0) - 100.0).abs() < 1e-9);
        assert_eq!(p.intensity(f64::NAN, 0.0), 0.0);
        assert_eq!(p.intensity(0.0, f64::NAN), 0.0);
        assert_eq!(p.intensity(0.0, -1.0), 0.0);
        assert_eq!(p.max_intensity(), 400.0);
    }

    #[test]
    fn repeated_gamma_angle_is_a_step() {
        let vertical = [0.0, 45.0, 45.0, 90.0];
        let rows = vec![vec![100.0, 100.0, 20.0, 20.0]];
        let p = from_ies(&ies_file(&vertical, &[0.0], &rows), "step.ies").unwrap();
        assert_eq!(p.intensity(0.0, 44.999), 100.0);
        assert_eq!(p.intensity(0.0, 45.0), 20.0);
        assert_eq!(p.intensity(0.0, 60.0), 20.0);
        // Φ = 2π [100 (1 − cos 45°) + 20 cos 45°].
        let expected = 2.0 * PI * (100.0 * (1.0 - 0.5f64.sqrt()) + 20.0 * 0.5f64.sqrt());
        assert!((p.flux() - expected).abs() < 1e-9 * expected);
    }

    #[test]
    fn split_lines_handles_every_terminator() {
        assert_eq!(split_lines("a\r\nb\nc\rd"), vec!["a", "b", "c", "d"]);
        assert_eq!(split_lines("a\n\nb\n"), vec!["a", "", "b"]);
        assert_eq!(split_lines(""), Vec::<&str>::new());
    }

    #[test]
    fn nul_bytes_are_reported_on_their_line() {
        let e = check_text("line one\nline two\nab\0cd", "bin.ies").unwrap_err();
        assert_eq!(e.line(), Some(3), "{e}");
        let e = check_text("\0", "bin.ies").unwrap_err();
        assert_eq!(e.line(), Some(1), "{e}");
        let e = check_text("x\n\0", "bin.ies").unwrap_err();
        assert_eq!(e.line(), Some(2), "{e}");
    }

    #[test]
    fn load_chooses_by_extension_and_refuses_others() {
        let dir = tempfile::tempdir().unwrap();
        let (vertical, horizontal, rows) = quadrant_rows();
        let path = dir.path().join("LUM.IES");
        std::fs::write(&path, ies_file(&vertical, &horizontal, &rows)).unwrap();
        let p = load(&path).unwrap();
        assert_eq!(p.metadata.format, SourceFormat::Ies(IesVersion::Lm63_2002));
        assert_eq!(p.file, path.display().to_string());
        let other = dir.path().join("lum.txt");
        std::fs::write(&other, "x").unwrap();
        let e = load(&other).unwrap_err();
        assert!(matches!(e, PhotometryError::UnknownFormat { .. }), "{e}");
        assert!(e.to_string().contains("lum.txt"), "{e}");
        let missing = load(&dir.path().join("missing.ldt")).unwrap_err();
        assert!(matches!(missing, PhotometryError::Read { .. }), "{missing}");
        let subdir = dir.path().join("dir.ies");
        std::fs::create_dir(&subdir).unwrap();
        let e = load(&subdir).unwrap_err();
        assert!(
            matches!(
                e,
                PhotometryError::NotRegularFile {
                    kind: "directory",
                    ..
                }
            ),
            "{e}"
        );
        // Bytes that are not text at all: every byte value, NUL included.
        let garbage = dir.path().join("garbage.ldt");
        std::fs::write(
            &garbage,
            (0..=255u8).cycle().take(4096).collect::<Vec<u8>>(),
        )
        .unwrap();
        let e = load(&garbage).unwrap_err();
        assert!(matches!(e, PhotometryError::Syntax { line: 1, .. }), "{e}");
        assert!(e
            .to_string()
            .starts_with(&format!("{}: line 1: ", garbage.display())));
        // Latin-1 text (not UTF-8) in a keyword still loads.
        let mut bytes = b"IESNA:LM-63-2002\n[MANUFAC] Leuchten M\xfcller\n".to_vec();
        bytes.extend_from_slice(
            ies_file(&vertical, &horizontal, &rows)
                .split_once("TILT")
                .map(|(_, t)| format!("TILT{t}"))
                .unwrap()
                .as_bytes(),
        );
        let latin = dir.path().join("latin1.ies");
        std::fs::write(&latin, bytes).unwrap();
        let p = load(&latin).unwrap();
        assert_eq!(p.metadata.manufacturer.as_deref(), Some("Leuchten Müller"));
    }

    #[test]
    fn office_louvre_ies_and_ldt_agree_and_carry_the_stated_flux() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/office");
        let ies = load(&dir.join("recessed_louvre.ies")).unwrap();
        let ldt = load(&dir.join("recessed_louvre.ldt")).unwrap();
        assert_eq!(
            ies.metadata.format,
            SourceFormat::Ies(IesVersion::Lm63_2002)
        );
        assert_eq!(ldt.metadata.format, SourceFormat::Eulumdat);
        assert_eq!(ies.symmetry, Symmetry::Quadrant);
        assert_eq!(ldt.symmetry, Symmetry::Quadrant);
        let test = &ies
            .metadata
            .keywords
            .iter()
            .find(|(k, _)| k == "TEST")
            .unwrap()
            .1;
        assert!(test.contains("synthetic"), "{test}");
        // Both files were written from one table: the IES in cd to 0.1 cd (±0.05 cd), the
        // LDT in cd/klm to 0.1 cd/klm, i.e. ±0.2 cd at 4 klm. At the nodes they differ by at
        // most 0.25 cd, and a bilinear interpolant of the differences never exceeds its
        // largest node value, so the bound holds everywhere.
        for k in 0..=145 {
            for j in 0..=73 {
                let (c, g) = (k as f64 * 2.5, j as f64 * 2.5);
                let (a, b) = (ies.intensity(c, g), ldt.intensity(c, g));
                assert!((a - b).abs() <= 0.25 + 1e-9, "C = {c}, γ = {g}: {a} vs {b}");
            }
        }
        // Stated: lamp flux 4000 lm, light output ratio 0.85 → 3400 lm. The unrounded table
        // integrates to 3400 lm exactly; rounding moves each value by at most 0.05 cd (IES)
        // or 0.2 cd (LDT), which over the 2π sr below the horizontal (∫ sin γ dγ dC = 2π)
        // moves Φ by at most 0.05·2π = 0.31 lm or 0.2·2π = 1.26 lm.
        let stated_lamps = 4000.0;
        let stated_ratio = 0.85;
        assert_eq!(ies.lamp_lumens, Some(stated_lamps));
        assert_eq!(ldt.lamp_lumens, Some(stated_lamps));
        assert_eq!(ldt.metadata.light_output_ratio, Some(stated_ratio));
        let target = stated_lamps * stated_ratio;
        assert!(
            (ies.flux() - target).abs() <= 0.05 * 2.0 * PI,
            "{}",
            ies.flux()
        );
        assert!(
            (ldt.flux() - target).abs() <= 0.2 * 2.0 * PI,
            "{}",
            ldt.flux()
        );
        // The shape the files claim: nothing upwards, a mild batwing, louvre cut-off.
        let i0 = ies.intensity(0.0, 0.0);
        assert!(ies.max_intensity() > i0 && ies.max_intensity() < 1.1 * i0);
        assert_eq!(ies.intensity(0.0, 95.0), 0.0);
        assert_eq!(ldt.intensity(45.0, 135.0), 0.0);
        assert!(ies.intensity(0.0, 70.0) < 0.05 * i0);
        assert!(ies.intensity(45.0, 75.0) < 0.15 * i0);
        assert!(ies.intensity(0.0, 70.0) < ies.intensity(45.0, 70.0));
        assert!((ies.opening.width_m - 0.56).abs() < 1e-12);
        assert!((ldt.opening.length_m - 0.56).abs() < 1e-12);
    }

    /// Runs `load` on another thread and fails the test if it does not return within 5 s
    /// (a FIFO opened for reading blocks until a writer appears).
    #[cfg(unix)]
    fn load_with_deadline(path: &Path) -> Result<Photometry, PhotometryError> {
        let (send, receive) = std::sync::mpsc::channel();
        let path = path.to_path_buf();
        std::thread::spawn(move || {
            let _ = send.send(load(&path));
        });
        receive
            .recv_timeout(std::time::Duration::from_secs(5))
            .expect("load did not return within 5 s")
    }

    #[cfg(unix)]
    #[test]
    fn load_refuses_fifos_and_devices_without_opening_them() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe.ies");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .expect("mkfifo must be available to run this test");
        assert!(status.success());
        let start = std::time::Instant::now();
        let e = load_with_deadline(&fifo).unwrap_err();
        assert!(
            matches!(e, PhotometryError::NotRegularFile { kind: "FIFO", .. }),
            "{e}"
        );
        assert!(start.elapsed().as_secs_f64() < 1.0);
        assert!(e.to_string().contains("pipe.ies"), "{e}");
        // An endless device behind a photometric name.
        let zero = dir.path().join("zero.ldt");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        let e = load_with_deadline(&zero).unwrap_err();
        assert!(
            matches!(
                e,
                PhotometryError::NotRegularFile {
                    kind: "character device",
                    ..
                }
            ),
            "{e}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn load_refuses_oversized_files_quickly() {
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.ies");
        // Sparse: 17 MiB of length without writing 17 MiB.
        let handle = std::fs::File::create(&big).unwrap();
        handle.set_len(MAX_FILE_BYTES + (1 << 20)).unwrap();
        drop(handle);
        let start = std::time::Instant::now();
        let e = load_with_deadline(&big).unwrap_err();
        assert!(start.elapsed().as_secs_f64() < 1.0);
        match &e {
            PhotometryError::TooLarge { bytes, limit, .. } => {
                assert_eq!(*bytes, MAX_FILE_BYTES + (1 << 20));
                assert_eq!(*limit, MAX_FILE_BYTES);
            }
            other => panic!("expected TooLarge, got {other}"),
        }
        assert!(e.to_string().contains("big.ies") && e.to_string().contains("limit"));
        // Exactly at the limit is allowed through to the parser (which then rejects the
        // zeros as binary data on line 1).
        let edge = dir.path().join("edge.ies");
        std::fs::File::create(&edge)
            .unwrap()
            .set_len(MAX_FILE_BYTES)
            .unwrap();
        let e = load_with_deadline(&edge).unwrap_err();
        assert!(matches!(e, PhotometryError::Syntax { line: 1, .. }), "{e}");
    }
}
