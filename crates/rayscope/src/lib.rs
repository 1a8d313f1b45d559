//! rayscope: a fast, inspectable Whitted-style CPU ray tracer.
//!
//! The library holds everything but the user interfaces: scene description and loading
//! ([`scene`], [`io`]), geometry and the BVH ([`geometry`], [`bvh`]), the Phong/Whitted
//! integrator ([`integrator`]), the film and image output ([`film`], [`output`]), and the ray
//! recorder that the visual debugger uses ([`record`]). The CLI and the viewer only map their
//! inputs onto these types.
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
#![warn(missing_docs)]

pub mod aov;
pub mod bvh;
pub mod camera;
pub mod error;
pub mod film;
pub mod filter;
pub mod geometry;
pub mod integrator;
pub mod io;
pub mod light;
pub mod material;
pub mod math;
pub mod output;
pub mod progressive;
pub mod ray;
pub mod record;
pub mod render;
pub mod sampler;
pub mod scene;
pub mod settings;

pub use error::{Error, Result};
