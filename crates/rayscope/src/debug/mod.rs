//! The visual debugger's library side, above the renderer: what a pixel's samples traced and
//! why the pixel has its colour, all from the renderer's own code path (the integrator reports
//! to a [`crate::record::RayRecorder`], which [`crate::record`] defines below the integrator).
//!
//! - [`pixel`]: every sample of a pixel traced into a ray tree, and the pixel's film value
//!   rebuilt from them bit for bit ([`trace_pixel_samples`]).
//! - [`explain`]: the pixel's value as a sum of terms (diffuse, specular, background, ...)
//!   with the factors that make each ([`PixelTrace::explain`]).
//! - [`export`]: the ray trees as an OBJ file of lines and points, for other 3D tools.

pub mod explain;
pub mod export;
pub mod pixel;

pub use explain::{Explanation, LightFactors, RayWeight, Term, TermKind, WeightFactor};
pub use export::{ExportCounts, write_rays_obj};
pub use pixel::{CulledTile, PixelTrace, SampleChoice, SampleTrace, trace_pixel_samples};
