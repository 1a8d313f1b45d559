//! Arbitrary output variables: per-pixel facts about the first hit of each camera ray (depth,
//! position, normal, albedo, primitive id, BVH nodes visited), rendered in parallel tiles
//! beside the colour image. The camera rays go through the BVH as the renderer's do: in
//! packets of a row's [`PACKET`] neighbouring pixels, or tiles of [`TILE_ROWS`] rows' packets
//! in scenes the renderer traces so ([`traces_camera_tiles`]), and the heat map leaves out the
//! tiles the renderer culls (as the renderer does), so that it counts what the renderer's
//! traversal does.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::bvh::{PACKET, TILE_RUNS, TraversalStats};
use crate::camera::{Camera, CameraMotion, RayGenerator};
use crate::film::FloatImage;
use crate::math::Vec2;
use crate::ray::Ray;
use crate::record::RayRecorder;
use crate::render::{RenderProgress, TILE_ROWS, TileCulling, trace_pixel, traces_camera_tiles};
use crate::scene::{Hit, Scene, TextureLod};
use crate::settings::{RenderSettings, ShadingOptions, TextureFilter};

/// Arbitrary output variables: per-pixel facts about the first hit of the camera ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
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
    /// BVH node boxes tested for the camera ray by the renderer's traversal (a packet of a
    /// row's neighbouring pixels, as rendering traces camera rays): the width of the wide
    /// tree times the nodes entered, the traversal heat map. In a tile the renderer culls
    /// ([`crate::render::TileCulling`]: no ray traced), the pixel's share of the boxes its
    /// tile's frustum test looked at (fractional).
    NodesVisited,
    /// The mip level trilinear filtering reads ([`crate::settings::TextureFilter::Trilinear`],
    /// whatever the settings' filter): of the first textured hit along sample 0 of the pixel,
    /// traced by the renderer with its ray cone, through mirrors and transparent surfaces
    /// (fractional: between two levels it blends them); -1 where no texture was read.
    MipLevel,
}

impl Aov {
    /// Channels per pixel.
    pub fn channels(self) -> u32 {
        match self {
            Aov::Depth | Aov::PrimId | Aov::NodesVisited | Aov::MipLevel => 1,
            Aov::Position | Aov::Normal | Aov::Albedo => 3,
        }
    }
}

/// Render one AOV of the first hits of `camera`'s rays through the pixel centres.
pub fn render_aov(
    scene: &Scene,
    settings: &RenderSettings,
    camera: &Camera,
    aov: Aov,
    progress: &(dyn Fn(RenderProgress) + Sync),
) -> FloatImage {
    let rays = RayGenerator::new(camera, settings.width, settings.height);
    let shading = settings.shading_options();
    let trilinear = RenderSettings { texture_filter: TextureFilter::Trilinear, ..settings.clone() };
    let still = CameraMotion::still(*camera);
    let culling = TileCulling::of(scene, settings, &still).filter(|_| aov == Aov::NodesVisited);
    let width = scene.geometry.wide.width() as f32;
    let tile_runs = traces_camera_tiles(scene);
    let tiles = per_tile(settings.width, settings.height, &AtomicBool::new(false), progress, |x0, x1, y0, y1| {
        let xs = x0..x1;
        if aov == Aov::MipLevel {
            return (y0..y1)
                .map(|y| xs.clone().map(|x| [mip_level(scene, &trilinear, &still, x, y), 0.0, 0.0]).collect())
                .collect();
        }
        // The blocks of `per_tile` are the renderer's tiles.
        if let Some((tile, test)) = culling.as_ref().and_then(|c| c.culled_tile(x0, y0)) {
            let share = width * test.nodes as f32 / tile.pixels() as f32;
            return (y0..y1).map(|_| vec![[share, 0.0, 0.0]; xs.len()]).collect();
        }
        let runs: Vec<Vec<Ray>> =
            (y0..y1).map(|y| xs.clone().map(|x| rays.ray(x, y, Vec2::splat(0.5))).collect()).collect();
        let value = |run: &[Ray], hits: &[Option<Hit>; PACKET], stats: &[TraversalStats; PACKET]| {
            let pixels = run.iter().zip(hits).zip(stats);
            pixels.map(|((ray, hit), stats)| pixel_value(scene, &shading, aov, ray, *hit, stats)).collect()
        };
        if tile_runs {
            let tile: Vec<&[Ray]> = runs.iter().map(Vec::as_slice).collect();
            let mut stats = [[TraversalStats::default(); PACKET]; TILE_RUNS];
            let hits = scene.intersect_tile_counted(&tile, &mut stats);
            return runs.iter().zip(&hits).zip(&stats).map(|((run, hits), stats)| value(run, hits, stats)).collect();
        }
        runs.iter()
            .map(|run| {
                let mut stats = [TraversalStats::default(); PACKET];
                let hits = scene.intersect_packet_counted(run, &mut stats);
                value(run, &hits, &stats)
            })
            .collect()
    });
    let channels = aov.channels() as usize;
    let mut data = vec![0.0; settings.width as usize * settings.height as usize * channels];
    for (t, values) in tiles {
        for ((x, y), v) in t.pixels().zip(values.into_iter().flatten()) {
            let i = (y as usize * settings.width as usize + x as usize) * channels;
            data[i..i + channels].copy_from_slice(&v[..channels]);
        }
    }
    let channels = channels as u32;
    FloatImage { width: settings.width, height: settings.height, channels, data }
}

/// The mip level sample 0 of pixel `(x, y)` reads at its first textured hit, as the renderer
/// traces it with `settings` (trilinear); -1 where it reads none.
fn mip_level(scene: &Scene, settings: &RenderSettings, camera: &CameraMotion, x: u32, y: u32) -> f32 {
    let mut first = FirstLod(None);
    trace_pixel(scene, settings, camera, x, y, 0, &mut first);
    first.0.map_or(-1.0, |lod| lod.level)
}

/// A recorder that keeps the first trilinear texture lookup's level of detail, and nothing
/// else (it does not ask for the debugger's records).
struct FirstLod(Option<TextureLod>);

impl RayRecorder for FirstLod {
    const RECORDS: bool = false;
    fn texture_lod(&mut self, lod: &TextureLod) {
        self.0.get_or_insert(*lod);
    }
}

/// The value of `aov` for the camera ray `ray` whose closest hit is `hit`, found by a traversal
/// that `stats` counted.
fn pixel_value(
    scene: &Scene,
    shading: &ShadingOptions,
    aov: Aov,
    ray: &Ray,
    hit: Option<Hit>,
    stats: &TraversalStats,
) -> [f32; 3] {
    let nan = [f32::NAN; 3];
    match (aov, hit) {
        (Aov::MipLevel, _) => unreachable!("the mip level is traced by the renderer, not read at the first hit"),
        (Aov::NodesVisited, _) => [stats.nodes_visited as f32, 0.0, 0.0],
        (Aov::Depth, None) => nan,
        (Aov::Depth, Some(h)) => [h.t, 0.0, 0.0],
        (Aov::PrimId, None) => [-1.0, 0.0, 0.0],
        (Aov::PrimId, Some(h)) => [scene.prim_id(&h) as f32, 0.0, 0.0],
        (Aov::Position, None) => nan,
        (Aov::Normal | Aov::Albedo, None) => [0.0; 3],
        (_, Some(h)) => {
            let si = scene.surface(ray, &h, shading);
            match aov {
                Aov::Position => si.point.to_array(),
                Aov::Normal => si.shading_normal.to_array(),
                _ => si.kd.to_array(),
            }
        }
    }
}

/// Side of the square tiles the image is cut into: small enough to balance load across
/// threads, large enough that the rays of a tile stay coherent in cache. A multiple of
/// [`PACKET`] and of [`TILE_ROWS`], so that a tile's blocks of pixels are the renderer's
/// packets and tiles.
const TILE: u32 = 16;

// A tile's blocks are the renderer's packets, tiles and culled tiles (`render_aov`).
const _: () = assert!(TILE.is_multiple_of(PACKET as u32) && TILE.is_multiple_of(TILE_ROWS as u32));

#[derive(Clone, Copy)]
struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl Tile {
    fn pixels(self) -> impl Iterator<Item = (u32, u32)> {
        (self.y0..self.y1).flat_map(move |y| (self.x0..self.x1).map(move |x| (x, y)))
    }
}

fn tiles(width: u32, height: u32) -> Vec<Tile> {
    let mut v = Vec::new();
    for y0 in (0..height).step_by(TILE as usize) {
        for x0 in (0..width).step_by(TILE as usize) {
            v.push(Tile { x0, y0, x1: (x0 + TILE).min(width), y1: (y0 + TILE).min(height) });
        }
    }
    v
}

/// Run `f` for every block of pixels in parallel tiles (`f(x0, x1, y0, y1)`: pixels `x0..x1`
/// of rows `y0..y1`, the renderer's tile of up to [`TILE_ROWS`] runs of up to [`PACKET`]
/// pixels, from multiples of those, its values row by row), skipping tiles not yet started
/// once `cancel` is set. Returns, per tile, its pixels' results in order (`None` for skipped
/// tiles). Each result depends only on its block, so the outcome is the same for any number
/// of threads.
fn per_tile<T: Send>(
    width: u32,
    height: u32,
    cancel: &AtomicBool,
    progress: &(dyn Fn(RenderProgress) + Sync),
    f: impl Fn(u32, u32, u32, u32) -> Vec<Vec<T>> + Sync,
) -> Vec<(Tile, Option<Vec<T>>)> {
    let tiles = tiles(width, height);
    let done = AtomicUsize::new(0);
    let total = width as usize * height as usize;
    tiles
        .into_par_iter()
        .map(|t| {
            if cancel.load(Ordering::Relaxed) {
                return (t, None);
            }
            let mut v: Vec<T> = Vec::with_capacity(((t.x1 - t.x0) * (t.y1 - t.y0)) as usize);
            for y0 in (t.y0..t.y1).step_by(TILE_ROWS) {
                let y1 = (y0 + TILE_ROWS as u32).min(t.y1);
                let mut rows: Vec<Vec<T>> = (y0..y1).map(|_| Vec::new()).collect();
                for x0 in (t.x0..t.x1).step_by(PACKET) {
                    let block = f(x0, (x0 + PACKET as u32).min(t.x1), y0, y1);
                    for (row, values) in rows.iter_mut().zip(block) {
                        row.extend(values);
                    }
                }
                v.extend(rows.into_iter().flatten());
            }
            let d = done.fetch_add(v.len(), Ordering::Relaxed) + v.len();
            progress(RenderProgress { done: d, total });
            (t, Some(v))
        })
        .collect()
}
