//! rayscope: a fast, inspectable Whitted-style CPU ray tracer.
//!
//! The library holds everything but the user interfaces. Its surface is small: a [`scene`] is
//! loaded (from a file, an OBJ or a built-in) and seen through a [`camera`] (a pinhole, or a
//! thin [`lens`] for depth of field); [`settings`] say
//! how to render it, and [`animation`] which span of the scene's timeline each frame shows; [`render`] makes an image into a [`film`] (and traces single pixels for
//! the debugger, whose rays [`record`] keeps; [`debug`] traces every sample of a pixel and
//! explains its colour), [`progressive`] accumulates frames, [`aov`] renders per-pixel facts of
//! the first hits, [`output`] writes images, [`export`] writes scenes as OBJ or glTF, and [`compare`] measures how another image differs
//! from a render. The CLI and the
//! viewer only map their inputs onto these types.
//!
//! ```
//! use rayscope::{render::render, scene::{builtin, LoadContext, Scene}, settings::RenderSettings};
//!
//! let desc = builtin::scene_desc("cornell-box").unwrap();
//! let scene = Scene::from_desc(&desc, &LoadContext::default()).unwrap();
//! let settings = RenderSettings { width: 32, height: 32, ..RenderSettings::default() };
//! let image = render(&scene, &settings, &|_| {});
//! assert_eq!(image.film.width(), 32);
//! ```
//!
//! Underneath, in layers that import only the ones below them: [`settings`] and the math at
//! the bottom, then geometry and the BVH, the scene, the integrator, and the renderer on top.
#![warn(missing_docs)]

pub mod animation;
pub mod aov;
pub mod camera;
pub mod compare;
pub mod debug;
pub mod environment;
pub mod export;
pub mod film;
pub mod lens;
pub mod motion;
pub mod output;
pub mod partial;
pub mod post;
pub mod progressive;
pub mod record;
pub mod render;
pub mod scene;
pub mod settings;

// The layers under the surface: public only for the benches, the tests, the CLI's `bench`
// command (the BVH), the viewer (rays, lights, vectors) and the fuzz targets (`fuzzing`), not
// documented as the library's.
#[doc(hidden)]
pub mod bvh;
#[doc(hidden)]
pub mod fuzzing;
#[doc(hidden)]
pub mod geometry;
#[doc(hidden)]
pub mod gradient;
#[doc(hidden)]
pub mod light;
#[doc(hidden)]
pub mod material;
#[doc(hidden)]
pub mod math;
#[doc(hidden)]
pub mod mipmap;
#[doc(hidden)]
pub mod ray;
#[doc(hidden)]
pub mod sampler;

mod cone;
mod error;
mod filter;
mod integrator;
mod io;
mod pages;
mod sky;

pub use error::{Error, Result};
