//! Rendering an image: settings, the parallel tile loop, AOVs, and single-pixel tracing for
//! the debugger (the same code path).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::bvh::TraversalStats;
use crate::camera::Camera;
use crate::film::{Film, FloatImage};
use crate::integrator::{Integrator, RayCounts};
use crate::material::TextureFilter;
use crate::math::Color;
use crate::record::{NoRecorder, RayKind, RayRecorder};
use crate::scene::Scene;

/// Every switch of the renderer. Scene files may set any of them in a `[render]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Phong shading; off shows each surface's diffuse colour unlit.
    pub shading: bool,
    /// Shadow rays towards each light.
    pub shadows: bool,
    /// Recursive mirror reflection for materials with `ks > 0`.
    pub reflections: bool,
    /// Transparency (MTL `d < 1`) for camera rays and shadows.
    pub transparency: bool,
    /// Deepest recursion: rays at this depth cast no reflection or transmission ray.
    pub max_depth: u32,
    /// Interpolate vertex normals across triangles (barycentric); off uses face normals.
    pub interpolate_normals: bool,
    /// Use diffuse textures (`map_Kd`) in place of `kd`.
    pub textures: bool,
    /// How textures are filtered.
    pub texture_filter: TextureFilter,
    /// Colour of rays that hit nothing.
    pub background: Color,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 800,
            height: 800,
            shading: true,
            shadows: true,
            reflections: true,
            transparency: true,
            max_depth: 5,
            interpolate_normals: false,
            textures: true,
            texture_filter: TextureFilter::Bilinear,
            background: Color::ZERO,
        }
    }
}

/// Largest accepted image side, in pixels (a 16k x 16k float film is already 3 GiB).
pub const MAX_IMAGE_SIDE: u32 = 16384;

impl RenderSettings {
    /// Check that the values make sense (a clear message, not a panic or a huge allocation).
    pub fn validate(&self) -> Result<(), crate::Error> {
        if self.width == 0 || self.height == 0 || self.width > MAX_IMAGE_SIDE || self.height > MAX_IMAGE_SIDE {
            return Err(crate::Error::Invalid(format!(
                "image size {}x{} is out of range: each side must be 1 to {MAX_IMAGE_SIDE}",
                self.width, self.height
            )));
        }
        if !self.background.is_finite() {
            return Err(crate::Error::Invalid("background colour must be finite".into()));
        }
        if self.max_depth > 64 {
            return Err(crate::Error::Invalid(format!(
                "max depth {} is out of range (0 to 64)",
                self.max_depth
            )));
        }
        Ok(())
    }
}

/// Progress of a render, as passed to its callback.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderProgress {
    /// Pixels finished.
    pub done: usize,
    /// Pixels in all.
    pub total: usize,
}

/// A finished render.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// The image.
    pub film: Film,
    /// Rays cast.
    pub rays: RayCounts,
    /// Wall-clock time of the tile loop.
    pub elapsed: Duration,
}

impl RenderOutput {
    /// Millions of rays per second, all kinds.
    pub fn mrays_per_second(&self) -> f64 {
        self.rays.total() as f64 / self.elapsed.as_secs_f64().max(1e-9) / 1e6
    }
}

/// Side of the square tiles the image is cut into: small enough to balance load across
/// threads, large enough that the rays of a tile stay coherent in cache.
const TILE: u32 = 16;

struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

fn tiles(width: u32, height: u32) -> Vec<Tile> {
    let mut v = Vec::new();
    for y0 in (0..height).step_by(TILE as usize) {
        for x0 in (0..width).step_by(TILE as usize) {
            v.push(Tile {
                x0,
                y0,
                x1: (x0 + TILE).min(width),
                y1: (y0 + TILE).min(height),
            });
        }
    }
    v
}

/// Run `f` for every pixel in parallel tiles, gathering its values into a row-major vector.
/// Each pixel's value depends only on the pixel, so the result is the same for any number of
/// threads.
fn per_pixel<T: Send + Copy + Default>(
    width: u32,
    height: u32,
    progress: &(dyn Fn(RenderProgress) + Sync),
    f: impl Fn(u32, u32, &mut RayCounts) -> T + Sync,
) -> (Vec<T>, RayCounts) {
    let tiles = tiles(width, height);
    let done = AtomicUsize::new(0);
    let total = width as usize * height as usize;
    let results: Vec<(Vec<T>, RayCounts)> = tiles
        .par_iter()
        .map(|t| {
            let mut counts = RayCounts::default();
            let mut v = Vec::with_capacity(((t.x1 - t.x0) * (t.y1 - t.y0)) as usize);
            for y in t.y0..t.y1 {
                for x in t.x0..t.x1 {
                    v.push(f(x, y, &mut counts));
                }
            }
            let d = done.fetch_add(v.len(), Ordering::Relaxed) + v.len();
            progress(RenderProgress { done: d, total });
            (v, counts)
        })
        .collect();
    let mut out = vec![T::default(); total];
    let mut counts = RayCounts::default();
    for (t, (v, c)) in tiles.iter().zip(results) {
        counts.add(c);
        let w = (t.x1 - t.x0) as usize;
        for (i, row) in v.chunks_exact(w).enumerate() {
            let start = (t.y0 as usize + i) * width as usize + t.x0 as usize;
            out[start..start + w].copy_from_slice(row);
        }
    }
    (out, counts)
}

/// Render `scene` with `settings` on the current rayon pool, calling `progress` as tiles finish.
pub fn render(scene: &Scene, settings: &RenderSettings, progress: &(dyn Fn(RenderProgress) + Sync)) -> RenderOutput {
    let start = Instant::now();
    let camera = scene.camera();
    let integrator = Integrator::new(scene, settings);
    let (pixels, rays) = per_pixel(settings.width, settings.height, progress, |x, y, counts| {
        trace_pixel_with(&integrator, &camera, x, y, &mut NoRecorder, counts)
    });
    let mut film = Film::new(settings.width, settings.height);
    for (i, c) in pixels.into_iter().enumerate() {
        film.set(i as u32 % settings.width, i as u32 / settings.width, c);
    }
    RenderOutput {
        film,
        rays,
        elapsed: start.elapsed(),
    }
}

fn trace_pixel_with<R: RayRecorder>(
    integrator: &Integrator,
    camera: &Camera,
    x: u32,
    y: u32,
    rec: &mut R,
    counts: &mut RayCounts,
) -> Color {
    let s = integrator.settings;
    let ray = camera.pixel_ray(x, y, s.width, s.height);
    integrator.li(&ray, RayKind::Camera, 0, rec, counts)
}

/// Trace pixel `(x, y)` alone, exactly as [`render`] does, reporting every ray to `rec`.
pub fn trace_pixel<R: RayRecorder>(scene: &Scene, settings: &RenderSettings, x: u32, y: u32, rec: &mut R) -> Color {
    let integrator = Integrator::new(scene, settings);
    trace_pixel_with(&integrator, &scene.camera(), x, y, rec, &mut RayCounts::default())
}

/// Arbitrary output variables: per-pixel facts about the first hit of the camera ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Aov {
    /// Distance along the (unit-length) camera ray; NaN where it hits nothing.
    Depth,
    /// World-space hit point; NaN where nothing is hit.
    Position,
    /// Shading normal (facing the camera); zero where nothing is hit.
    Normal,
    /// Diffuse colour (`kd` or texture); zero where nothing is hit.
    Albedo,
    /// Global primitive id (exact up to 2^24); -1 where nothing is hit.
    PrimId,
    /// BVH nodes visited by the camera ray: the traversal heat map.
    NodesVisited,
}

impl Aov {
    /// Channels per pixel.
    pub fn channels(self) -> u32 {
        match self {
            Aov::Depth | Aov::PrimId | Aov::NodesVisited => 1,
            Aov::Position | Aov::Normal | Aov::Albedo => 3,
        }
    }
}

/// Render one AOV of the camera rays' first hits.
pub fn render_aov(
    scene: &Scene,
    settings: &RenderSettings,
    aov: Aov,
    progress: &(dyn Fn(RenderProgress) + Sync),
) -> FloatImage {
    let camera = scene.camera();
    let (pixels, _) = per_pixel(settings.width, settings.height, progress, |x, y, _| {
        let ray = camera.pixel_ray(x, y, settings.width, settings.height);
        let mut stats = TraversalStats::default();
        let hit = scene.intersect_counted(&ray, &mut stats);
        let nan = [f32::NAN; 3];
        let v: [f32; 3] = match (aov, hit) {
            (Aov::NodesVisited, _) => [stats.nodes_visited as f32, 0.0, 0.0],
            (Aov::Depth, None) => nan,
            (Aov::Depth, Some(h)) => [h.t, 0.0, 0.0],
            (Aov::PrimId, None) => [-1.0, 0.0, 0.0],
            (Aov::PrimId, Some(h)) => [h.prim as f32, 0.0, 0.0],
            (Aov::Position, None) => nan,
            (Aov::Normal | Aov::Albedo, None) => [0.0; 3],
            (_, Some(h)) => {
                let si = scene.surface(&ray, &h, settings);
                match aov {
                    Aov::Position => si.point.to_array(),
                    Aov::Normal => si.shading_normal.to_array(),
                    _ => si.kd.to_array(),
                }
            }
        };
        v
    });
    let channels = aov.channels();
    let data = pixels.iter().flat_map(|p| p[..channels as usize].to_vec()).collect();
    FloatImage {
        width: settings.width,
        height: settings.height,
        channels,
        data,
    }
}
