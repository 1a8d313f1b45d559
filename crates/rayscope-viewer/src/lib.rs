//! The rayscope viewer: a desktop app (eframe/egui on wgpu) with a rasterized preview, the
//! ray-traced view in the course's three imaging modes, every render setting on a panel, and
//! the visual debugger (a pixel's ray tree, shadow rays and light samples, BVH levels, a
//! traversal heat map), and a student's image compared with ours. All tracing is the library's: the debugger shows what the renderer
//! does.
#![warn(missing_docs)]

pub mod app;
pub mod bloom;
pub mod compare;
pub mod environment;
pub mod files;
pub mod heat;
pub mod lens;
pub mod mip;
pub mod motion;
pub mod overlay;
pub mod plural;
pub mod preview;
pub mod scene_file;
pub mod session;
pub mod split;
pub mod state;
pub mod trackball;
pub mod worker;

pub use app::{RayscopeApp, ViewerOptions, run};
