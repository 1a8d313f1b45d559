//! What the debugger's overlay draws and in which colour: the kinds of lines the panel toggles,
//! the colours by ray depth or by ray kind, the legend that names them, and the builder that
//! turns segments, crosses, boxes and light shapes into [`LineVertex`] pairs.

use glam::Vec3;
use rayscope::light::Light;
use rayscope::record::RayKind;

use crate::preview::{HIDDEN_ALPHA, LineVertex};

/// A kind of overlay line, each with its own toggle on the panel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineKind {
    /// Rays from the camera through the pixel.
    Camera,
    /// Mirror reflections.
    Reflection,
    /// A glossy reflection's sample rays.
    Glossy,
    /// Rays continuing through transparent surfaces.
    Transmission,
    /// Shadow rays that reached their light point.
    ShadowReached,
    /// Shadow rays that an opaque surface blocked.
    ShadowBlocked,
    /// The points sampled on the lights.
    LightSamples,
    /// The hit triangles' outlines and their geometric and shading normals.
    Normals,
}

impl LineKind {
    /// Every kind, in the panel's order.
    pub const ALL: [LineKind; 8] = [
        LineKind::Camera,
        LineKind::Reflection,
        LineKind::Glossy,
        LineKind::Transmission,
        LineKind::ShadowReached,
        LineKind::ShadowBlocked,
        LineKind::LightSamples,
        LineKind::Normals,
    ];

    /// The kind of a traced ray's line.
    pub fn of_ray(kind: RayKind) -> LineKind {
        match kind {
            RayKind::Camera => LineKind::Camera,
            RayKind::Reflection => LineKind::Reflection,
            RayKind::Glossy => LineKind::Glossy,
            RayKind::Transmission => LineKind::Transmission,
        }
    }

    /// The toggle's label.
    pub fn label(self) -> &'static str {
        match self {
            LineKind::Camera => "Camera rays",
            LineKind::Reflection => "Reflection rays",
            LineKind::Glossy => "Glossy rays",
            LineKind::Transmission => "Transmission rays",
            LineKind::ShadowReached => "Shadow rays that reached the light",
            LineKind::ShadowBlocked => "Blocked shadow rays",
            LineKind::LightSamples => "Light samples",
            LineKind::Normals => "Normals and hit triangles",
        }
    }

    /// The toggle's tooltip: what is drawn, in which colour.
    pub fn tooltip(self) -> &'static str {
        match self {
            LineKind::Camera => "The rays from the camera through the selected pixels (one per sample)",
            LineKind::Reflection => "Mirror reflection rays (perfect mirrors, or glossy materials with 0 gloss rays)",
            LineKind::Glossy => "The sample rays of glossy reflections (drawn fainter: there are many)",
            LineKind::Transmission => "Rays that continue through transparent materials (d < 1)",
            LineKind::ShadowReached => "Shadow rays that got through to their point on the light: green",
            LineKind::ShadowBlocked => {
                "Shadow rays an opaque surface stopped: in the light's colour up to the blocker (a red cross), \
                 dark past it"
            }
            LineKind::LightSamples => {
                "A small cross at each point sampled on a light: green reached, red blocked, violet skipped \
                 (behind the surface, no shadow ray cast)"
            }
            LineKind::Normals => {
                "Each hit triangle's outline (pink), its geometric normal (blue) and, where shading uses \
                 another, the interpolated normal (cyan)"
            }
        }
    }

    fn bit(self) -> u8 {
        1 << self as u8
    }
}

/// Which [`LineKind`]s are drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShownKinds(u8);

impl Default for ShownKinds {
    /// Every kind.
    fn default() -> ShownKinds {
        ShownKinds(LineKind::ALL.iter().fold(0, |m, k| m | k.bit()))
    }
}

impl ShownKinds {
    /// Whether `kind` is drawn.
    pub fn contains(self, kind: LineKind) -> bool {
        self.0 & kind.bit() != 0
    }

    /// Draw `kind` or not.
    pub fn set(&mut self, kind: LineKind, on: bool) {
        if on {
            self.0 |= kind.bit();
        } else {
            self.0 &= !kind.bit();
        }
    }
}

/// How traced rays are coloured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColorBy {
    /// By recursion depth, as the course does: the camera ray white, then warmer per bounce.
    Depth,
    /// By what cast the ray: camera, reflection, glossy, transmission.
    Kind,
    /// By the shutter time of its sample (motion blur): see [`crate::motion::time_color`].
    Time,
}

/// A ray that hit nothing: drawn a stretch past the scene.
pub const MISS_COLOR: [f32; 4] = [1.0, 0.15, 0.15, 1.0];
/// Shadow ray that reached its light point.
pub const REACHED_COLOR: [f32; 4] = [0.2, 1.0, 0.2, 1.0];
/// The blocker of a shadow ray (a cross), and a light sample that was not reached.
pub const BLOCKED_COLOR: [f32; 4] = [1.0, 0.1, 0.1, 1.0];
/// A blocked shadow ray past its blocker: the light it would have brought is missing.
pub const PAST_BLOCKER_COLOR: [f32; 4] = [0.22, 0.22, 0.25, 0.9];
/// The hit triangle's outline.
pub const TRIANGLE_COLOR: [f32; 4] = [1.0, 0.35, 0.85, 1.0];
/// Geometric normal.
pub const NORMAL_COLOR: [f32; 4] = [0.2, 0.4, 1.0, 1.0];
/// Interpolated (shading) normal.
pub const SHADING_NORMAL_COLOR: [f32; 4] = [0.2, 0.95, 1.0, 1.0];
/// BVH interior boxes.
pub const BOX_COLOR: [f32; 4] = [0.3, 0.9, 0.9, 0.8];
/// BVH leaves.
pub const LEAF_COLOR: [f32; 4] = [1.0, 0.55, 0.1, 0.9];
/// A light point the integrator skipped (behind the surface): no shadow ray was cast.
pub const SKIPPED_COLOR: [f32; 4] = [0.65, 0.5, 1.0, 1.0];
/// What the explanation table's selected row points at (a ray or a light's shadow rays).
pub const HIGHLIGHT_COLOR: [f32; 4] = [1.0, 1.0, 0.0, 1.0];

/// Ray colours by depth: white for the camera ray (as in the course), then warmer per bounce;
/// the last is for every deeper ray.
const BY_DEPTH: [[f32; 3]; 6] =
    [[1.0, 1.0, 1.0], [1.0, 0.8, 0.2], [1.0, 0.5, 0.1], [0.65, 0.45, 1.0], [0.4, 0.75, 1.0], [0.8, 0.8, 0.5]];

/// Glossy rays are drawn fainter, as there are many.
const GLOSSY_ALPHA: f32 = 0.5;

/// A ray's colour by depth; glossy rays fainter.
pub fn depth_color(depth: u32, kind: RayKind) -> [f32; 4] {
    let c = BY_DEPTH[(depth as usize).min(BY_DEPTH.len() - 1)];
    let a = if kind == RayKind::Glossy { GLOSSY_ALPHA } else { 1.0 };
    [c[0], c[1], c[2], a]
}

/// A ray's colour by kind.
pub fn kind_color(kind: RayKind) -> [f32; 4] {
    match kind {
        RayKind::Camera => [1.0, 1.0, 1.0, 1.0],
        RayKind::Reflection => [1.0, 0.8, 0.2, 1.0],
        RayKind::Glossy => [1.0, 0.55, 0.75, GLOSSY_ALPHA],
        RayKind::Transmission => [0.35, 0.85, 1.0, 1.0],
    }
}

/// A light's colour scaled into [0, 1] (lights may be brighter than 1), for its marker and
/// its blocked shadow rays.
pub fn light_line_color(c: Vec3) -> [f32; 4] {
    let c = c / c.max_element().max(1.0);
    [c.x, c.y, c.z, 1.0]
}

/// One entry of the overlay's legend.
#[derive(Clone, Debug, PartialEq)]
pub struct LegendEntry {
    /// The colour as drawn.
    pub color: [f32; 4],
    /// What it means.
    pub meaning: String,
}

/// The legend for the overlay as drawn with `color_by`: every colour and what it means.
pub fn legend(color_by: ColorBy) -> Vec<LegendEntry> {
    let entry = |color: [f32; 4], meaning: &str| LegendEntry { color, meaning: meaning.to_string() };
    let mut out = Vec::new();
    match color_by {
        ColorBy::Depth => {
            for (d, c) in BY_DEPTH.iter().enumerate() {
                let more = if d + 1 == BY_DEPTH.len() { " and deeper" } else { "" };
                let what = if d == 0 { "camera rays".to_string() } else { format!("rays at depth {d}{more}") };
                out.push(entry([c[0], c[1], c[2], 1.0], &what));
            }
            out.push(entry([1.0, 1.0, 1.0, GLOSSY_ALPHA], "glossy rays: fainter"));
        }
        ColorBy::Kind => {
            for k in [RayKind::Camera, RayKind::Reflection, RayKind::Glossy, RayKind::Transmission] {
                out.push(entry(kind_color(k), &format!("{}s", k.noun())));
            }
        }
        ColorBy::Time => out.extend(crate::motion::time_legend()),
    }
    out.push(entry(MISS_COLOR, "a ray that hit nothing"));
    out.push(entry(REACHED_COLOR, "shadow ray that reached the light"));
    out.push(entry([1.0, 0.9, 0.6, 1.0], "blocked shadow ray, up to its blocker: the light's colour"));
    out.push(entry(BLOCKED_COLOR, "the blocker (cross); an unreached light sample"));
    out.push(entry(PAST_BLOCKER_COLOR, "blocked shadow ray past its blocker"));
    out.push(entry(SKIPPED_COLOR, "a light point skipped (behind the surface): no shadow ray"));
    out.push(entry(TRIANGLE_COLOR, "the hit triangle"));
    out.push(entry(NORMAL_COLOR, "geometric normal"));
    out.push(entry(SHADING_NORMAL_COLOR, "shading (interpolated) normal"));
    out.push(entry(BOX_COLOR, "BVH node box"));
    out.push(entry(LEAF_COLOR, "BVH leaf box"));
    out.push(entry(HIGHLIGHT_COLOR, "the explanation row selected"));
    out.extend(crate::motion::path_legend());
    out.push(entry([1.0, 1.0, 1.0, HIDDEN_ALPHA], "faded: a surface hides this part of the line"));
    out
}

/// Segments as the preview draws them, two vertices each.
#[derive(Default)]
pub struct Lines(pub Vec<LineVertex>);

impl Lines {
    /// The segment from `a` to `b`.
    pub fn line(&mut self, a: Vec3, b: Vec3, color: [f32; 4]) {
        self.0.push(LineVertex { pos: a.to_array(), color });
        self.0.push(LineVertex { pos: b.to_array(), color });
    }

    /// A cross of half-size `s` at `p`, along the axes.
    pub fn cross(&mut self, p: Vec3, s: f32, color: [f32; 4]) {
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            self.line(p - axis * s, p + axis * s, color);
        }
    }

    /// The twelve edges of a box.
    pub fn aabb(&mut self, lo: Vec3, hi: Vec3, color: [f32; 4]) {
        let c = |i: u32| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        for (a, b) in [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)] {
            self.line(c(a), c(b), color);
        }
    }

    fn circle(&mut self, center: Vec3, u: Vec3, v: Vec3, color: [f32; 4]) {
        let n = 48;
        for i in 0..n {
            let a = std::f32::consts::TAU * i as f32 / n as f32;
            let b = std::f32::consts::TAU * (i + 1) as f32 / n as f32;
            self.line(center + u * a.cos() + v * a.sin(), center + u * b.cos() + v * b.sin(), color);
        }
    }

    /// A light as the course drew it: a cross for a point light, a line for a segment, a quad
    /// for a parallelogram, a wire sphere; in the light's colour (`color` overrides it, for a
    /// highlight). `r` is the scene's radius, for the cross's size.
    pub fn light(&mut self, light: &Light, r: f32, color: Option<[f32; 4]>) {
        let col = |c: Vec3| color.unwrap_or_else(|| light_line_color(c));
        match *light {
            Light::Point { position, color } => self.cross(position, 0.03 * r, col(color)),
            Light::Segment { endpoint0, endpoint1, color0, color1 } => {
                let n = 16;
                for i in 0..n {
                    let (a, b) = (i as f32 / n as f32, (i + 1) as f32 / n as f32);
                    self.line(
                        endpoint0.lerp(endpoint1, a),
                        endpoint0.lerp(endpoint1, b),
                        col(color0.lerp(color1, (a + b) * 0.5)),
                    );
                }
            }
            Light::Parallelogram { v0, edge01, edge02, color0, color1, color2, color3 } => {
                let p = [v0, v0 + edge01, v0 + edge01 + edge02, v0 + edge02];
                let c = [color0, color1, color3, color2];
                for i in 0..4 {
                    self.line(p[i], p[(i + 1) % 4], col((c[i] + c[(i + 1) % 4]) * 0.5));
                }
            }
            Light::Sphere { center, radius, color } => {
                let c = col(color);
                self.circle(center, Vec3::X * radius, Vec3::Y * radius, c);
                self.circle(center, Vec3::Y * radius, Vec3::Z * radius, c);
                self.circle(center, Vec3::Z * radius, Vec3::X * radius, c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_toggle_one_at_a_time() {
        let mut k = ShownKinds::default();
        assert!(LineKind::ALL.iter().all(|&l| k.contains(l)));
        k.set(LineKind::Glossy, false);
        assert!(!k.contains(LineKind::Glossy));
        assert!(LineKind::ALL.iter().filter(|&&l| l != LineKind::Glossy).all(|&l| k.contains(l)));
        k.set(LineKind::Glossy, true);
        assert_eq!(k, ShownKinds::default());
    }

    #[test]
    fn the_legend_names_every_colour_drawn() {
        for by in [ColorBy::Depth, ColorBy::Kind] {
            let legend = legend(by);
            for c in [MISS_COLOR, REACHED_COLOR, BLOCKED_COLOR, PAST_BLOCKER_COLOR, TRIANGLE_COLOR, NORMAL_COLOR] {
                assert!(legend.iter().any(|e| e.color == c), "{c:?} in the {by:?} legend");
            }
            for k in [RayKind::Camera, RayKind::Reflection, RayKind::Transmission] {
                let c = if by == ColorBy::Depth { depth_color(1, k) } else { kind_color(k) };
                assert!(legend.iter().any(|e| e.color[..3] == c[..3]), "{k:?} by {by:?}");
            }
        }
    }
}
