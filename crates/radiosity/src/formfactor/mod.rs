//! Form factors: how much of the light leaving one piece of surface arrives at another.
//!
//! F_{R→S} = (1/A_R) ∫_{A_R} ∫_{A_S} cosθ_x cosθ_y V(x, y) / (π r²) dA_y dA_x is the fraction
//! of the power leaving receiver R diffusely that arrives at source S (and, by reciprocity,
//! A_R F_{R→S} = A_S F_{S→R}). Two layers:
//! - **kernels** ([`kernel`]): each method as a function of geometry — a receiver (polygon or
//!   point with a normal), a source polygon and a visibility query ([`Visibility`], shadow
//!   rays through the BVH) — with no mesh indices;
//! - **engines** ([`engine`]): element × patch rows, columns and near-field pairs over a mesh,
//!   built on the kernels (the hemi-cube and Monte Carlo engines do whole rows at once).
//!
//! The methods are selected by name ([`FormFactorMethod`]) from the command line and the
//! scene file. Which pairs are linked, and at what level, is the coupling stage's business
//! ([`crate::coupling`]).

pub mod analytic;
pub mod analytic_point;
pub mod analytic_polygon;
pub mod engine;
pub mod hemicube;
pub mod kernel;
pub mod monte_carlo;
pub mod pair;
pub mod point_sampled;
pub mod quadrature;
pub mod raycast;
pub mod table;

pub use crate::accel::Visibility;
pub use engine::{engine, Engine, KernelEngine};
pub use kernel::{visible_fraction, Division, Kernel, Receiver, SourcePolygon};

use std::fmt;
use std::str::FromStr;

/// The form-factor methods, by the names used on the command line and in scene files.
///
/// See also: [`pair`] for the same methods on a single mesh-free problem, and [`table`] for
/// their accuracy and cost on the reference cases.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum FormFactorMethod {
    /// Element centre to patch by Lambert's exact contour formula, probe-ray visibility
    /// ([`analytic::AnalyticPoint`]).
    AnalyticPoint,
    /// Exact polygon-to-polygon (Schröder & Hanrahan 1993) × a ray-estimated visible
    /// fraction ([`analytic::AnalyticPolygon`]).
    AnalyticPolygon,
    /// The finite sum Σ cosθ_x cosθ_y V ΔA_y / (π r²) over sub-areas of the patch
    /// ([`point_sampled::PointSampled`]).
    PointSampled,
    /// Nusselt's analogue by the hemi-cube (Cohen & Greenberg 1985), z-buffer visibility
    /// ([`hemicube::Hemicube`]).
    Hemicube,
    /// Receiver quadrature × exact point-to-polygon × shadow rays (Wallace, Elmquist &
    /// Haines 1989).
    #[default]
    Raycast,
    /// Cosine-distributed rays from random points of the element, binned by the element (and
    /// so the patch) they hit first ([`monte_carlo::MonteCarlo`]).
    MonteCarlo,
}

impl FormFactorMethod {
    /// Every method, in the order of the lecture (exact to sampled).
    pub const ALL: &'static [FormFactorMethod] = &[
        FormFactorMethod::AnalyticPoint,
        FormFactorMethod::AnalyticPolygon,
        FormFactorMethod::PointSampled,
        FormFactorMethod::Hemicube,
        FormFactorMethod::Raycast,
        FormFactorMethod::MonteCarlo,
    ];

    /// The method's name on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            FormFactorMethod::AnalyticPoint => "analytic-point",
            FormFactorMethod::AnalyticPolygon => "analytic-polygon",
            FormFactorMethod::PointSampled => "point-sampled",
            FormFactorMethod::Hemicube => "hemicube",
            FormFactorMethod::Raycast => "raycast",
            FormFactorMethod::MonteCarlo => "monte-carlo",
        }
    }

    /// The method as a kernel on geometry, with its default parameters.
    pub fn kernel(self) -> Box<dyn Kernel> {
        match self {
            FormFactorMethod::AnalyticPoint => Box::new(analytic::AnalyticPointKernel),
            FormFactorMethod::AnalyticPolygon => Box::new(analytic::AnalyticPolygonKernel),
            FormFactorMethod::PointSampled => {
                Box::new(point_sampled::PointSampledKernel::default())
            }
            FormFactorMethod::Hemicube => Box::new(hemicube::HemicubeKernel::default()),
            FormFactorMethod::Raycast => Box::new(raycast::RaycastKernel::default()),
            FormFactorMethod::MonteCarlo => Box::new(monte_carlo::MonteCarloKernel::default()),
        }
    }
}

impl fmt::Display for FormFactorMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for FormFactorMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Self::ALL.iter().map(|m| m.name()).collect();
                format!(
                    "unknown form-factor method '{s}' (expected one of: {})",
                    names.join(", ")
                )
            })
    }
}
