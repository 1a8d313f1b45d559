//! A pixel's ray trees as a Wavefront OBJ file of lines and points, to open beside the scene
//! in Blender or any 3D viewer.
//!
//! One group (`g`) per kind of element: camera, reflection, glossy and transmission rays
//! (origin to hit), shadow rays that reached their light, shadow rays blocked (up to the
//! blocker) and what lies past the blocker, each as a line `l`; hit points and the light points
//! sampled (shaded or skipped) as points `p`. A ray that hit nothing is drawn as long as the
//! recorded points' extent, since it has no end.

use std::fmt::Write as _;
use std::path::Path;

use crate::debug::pixel::PixelTrace;
use crate::math::Vec3A;
use crate::output::write_file;
use crate::record::{RayKind, RecordedRay};

/// What an export wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExportCounts {
    /// Line elements (`l`): one per ray, one per shadow ray, two per blocked shadow ray.
    pub segments: usize,
    /// Point elements (`p`): hit points and light points.
    pub points: usize,
}

/// The groups of the file, in the order written.
const GROUPS: [&str; 9] = [
    "camera",
    "reflection",
    "glossy",
    "transmission",
    "shadow-reached",
    "shadow-blocked",
    "shadow-past-blocker",
    "light-points",
    "hit-points",
];

/// The group of a ray of `kind`.
fn ray_group(kind: RayKind) -> usize {
    match kind {
        RayKind::Camera => 0,
        RayKind::Reflection => 1,
        RayKind::Glossy => 2,
        RayKind::Transmission => 3,
    }
}

/// Elements collected per group before writing, with the vertices they index.
#[derive(Default)]
struct ObjBuilder {
    vertices: Vec<[f32; 3]>,
    /// Per group, its elements as vertex indices (1-based): two for a line, one for a point.
    groups: [Vec<Vec<usize>>; GROUPS.len()],
}

impl ObjBuilder {
    fn vertex(&mut self, p: [f32; 3]) -> usize {
        self.vertices.push(p);
        self.vertices.len()
    }

    fn line(&mut self, group: usize, a: [f32; 3], b: [f32; 3]) {
        let (a, b) = (self.vertex(a), self.vertex(b));
        self.groups[group].push(vec![a, b]);
    }

    fn point(&mut self, group: usize, p: [f32; 3]) {
        let v = self.vertex(p);
        self.groups[group].push(vec![v]);
    }

    fn add_ray(&mut self, ray: &RecordedRay, miss_length: f32) {
        let end = match &ray.hit {
            Some(hit) => hit.point,
            None => (Vec3A::from(ray.origin) + Vec3A::from(ray.dir).normalize_or_zero() * miss_length).to_array(),
        };
        self.line(ray_group(ray.kind), ray.origin, end);
        if let Some(hit) = &ray.hit {
            self.point(8, hit.point);
        }
        for s in &ray.shadows {
            match s.blocked_at {
                Some(b) => {
                    self.line(5, s.from, b);
                    self.line(6, b, s.to);
                }
                None if s.transmitted == [0.0; 3] => self.line(5, s.from, s.to),
                None => self.line(4, s.from, s.to),
            }
        }
        for t in &ray.light_terms {
            self.point(7, t.to.to_array());
        }
        for t in &ray.skipped_lights {
            self.point(7, t.to.to_array());
        }
    }

    fn text(&self) -> String {
        let mut out = String::from("# rayscope ray trees: one group per kind of ray\n");
        for v in &self.vertices {
            let _ = writeln!(out, "v {} {} {}", v[0], v[1], v[2]);
        }
        for (name, elements) in GROUPS.iter().zip(&self.groups) {
            if elements.is_empty() {
                continue;
            }
            let _ = writeln!(out, "g {name}");
            for e in elements {
                let tag = if e.len() == 2 { 'l' } else { 'p' };
                let idx: Vec<String> = e.iter().map(|i| i.to_string()).collect();
                let _ = writeln!(out, "{tag} {}", idx.join(" "));
            }
        }
        out
    }

    fn counts(&self) -> ExportCounts {
        let all = self.groups.iter().flatten();
        let segments = all.clone().filter(|e| e.len() == 2).count();
        ExportCounts { segments, points: all.count() - segments }
    }
}

/// The largest extent of the points the trees recorded (origins, hits, light points), at
/// least 1: how long a ray that hit nothing is drawn.
fn extent(trace: &PixelTrace) -> f32 {
    let mut lo = Vec3A::splat(f32::INFINITY);
    let mut hi = Vec3A::splat(f32::NEG_INFINITY);
    let rays = trace.samples.iter().flat_map(|s| &s.tree.rays);
    for r in rays {
        let points = std::iter::once(r.origin).chain(r.hit.map(|h| h.point)).chain(r.shadows.iter().map(|s| s.to));
        for p in points {
            lo = lo.min(Vec3A::from(p));
            hi = hi.max(Vec3A::from(p));
        }
    }
    let d = (hi - lo).max_element();
    if d.is_finite() { d.max(1.0) } else { 1.0 }
}

/// Write the rays of every sample of `trace` to `path` as OBJ, atomically; returns what it wrote.
pub fn write_rays_obj(trace: &PixelTrace, path: &Path) -> crate::Result<ExportCounts> {
    let mut obj = ObjBuilder::default();
    let miss_length = extent(trace);
    for sample in &trace.samples {
        for ray in &sample.tree.rays {
            obj.add_ray(ray, miss_length);
        }
    }
    let text = obj.text();
    write_file(path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
    Ok(obj.counts())
}
