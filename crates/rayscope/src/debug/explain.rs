//! A pixel's colour as a sum of terms, from the renderer's own numbers.
//!
//! The integrator reports to the recorder, for every ray, its weight (per channel, the product
//! of the factors by which its light reaches the pixel: `ks` for a reflection, `1/n` for each
//! of `n` glossy rays, the opacity `d` and `1 - d` where a transparent surface blends), and for
//! every light point it shades, the Phong terms. A ray's colour is then, in exact arithmetic,
//!
//! ```text
//! pixel = sum over samples s:   weight(s)                               (1/spp)
//!         x sum over rays r:    weight(r) x d(r)                        (d: 1 unless r's surface transmits)
//!         x [ sum over lights l: 1/n(l) x sum over points i of l:
//!                 arrived_i x light_i x (kd cos_i + ks highlight_i) ]   (a ray that hits, shading on)
//!           or the background or the environment map (a ray that misses), or kd (shading off)
//! ```
//!
//! and [`PixelTrace::explain`] lists those terms, grouped per ray and light (the points of a
//! light summed). The renderer nests the same products differently (`d * (direct + ks *
//! reflected) + (1 - d) * behind`), so the terms sum to the pixel to float rounding, not bit
//! for bit. Branches that adaptive depth control did not cast add black and have no term;
//! they are listed under their ray ([`RayWeight::stopped`]).

use std::fmt;

use serde::Serialize;

use crate::debug::pixel::{CulledTile, PixelTrace, SampleTrace};
use crate::environment::EnvironmentLookup;
use crate::math::Color;
use crate::record::{LightTerm, RayKind, RecordedRay, StoppedBranch};
use crate::settings::ShadingModel;

/// What a term is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TermKind {
    /// A light's diffuse light: `kd x cos x light x shadow`.
    Diffuse,
    /// A light's Phong highlight: `ks x max(0, r.v)^shininess x light x shadow`.
    Specular,
    /// A ray that hit nothing returns the background colour.
    Background,
    /// A ray that hit nothing returns the environment map's radiance in its direction.
    Environment,
    /// With shading off, a hit returns its diffuse colour `kd` as it is.
    UnshadedKd,
}

impl TermKind {
    /// Its name in the explanation's text.
    pub fn name(self) -> &'static str {
        match self {
            TermKind::Diffuse => "diffuse",
            TermKind::Specular => "specular",
            TermKind::Background => "background",
            TermKind::Environment => "environment",
            TermKind::UnshadedKd => "kd (unshaded)",
        }
    }
}

/// How a light's points at one hit make a diffuse or specular term.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LightFactors {
    /// The light points it is shaded with at this hit; each weighs `1 / points`.
    pub points: u32,
    /// Of these, the points in front of the surface (the others were skipped, adding
    /// nothing: see [`crate::record::SkipReason`]).
    pub shaded: u32,
    /// Of the shaded points, those whose light arrived (shadow ray not blocked, or no shadows).
    pub reached: u32,
    /// The mean over the shaded points of the cosine (diffuse) or of the highlight
    /// `max(0, r.v)^shininess` (specular).
    pub factor: f32,
    /// The mean over the shaded points of the light's colour.
    pub light_color: Color,
    /// The mean over the shaded points of the fraction of light that arrived.
    pub arrived: Color,
}

/// One term of a pixel's value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Term {
    /// The sample's index.
    pub sample: u32,
    /// The ray's index in the sample's [`crate::record::RayTree::rays`].
    pub ray: usize,
    /// The light, for diffuse and specular terms.
    pub light: Option<usize>,
    /// What it is.
    pub kind: TermKind,
    /// The shading model that made it, for diffuse and specular terms.
    pub model: Option<ShadingModel>,
    /// For the gradient model's diffuse term: the (mean) cosine `n.l` at which the gradient
    /// was read. Its colour is `material`, not multiplied by the cosine again, so the term's
    /// `lights.factor` is 1 there.
    pub gradient_cos: Option<f32>,
    /// The surface's factor: `kd` (diffuse, unshaded), `ks` (specular), or the background;
    /// for the gradient model's diffuse term, the mean over the shaded points of the
    /// gradient's colour at their cosine.
    pub material: Color,
    /// The light's factors, for diffuse and specular terms.
    pub lights: Option<LightFactors>,
    /// The term at its ray: for a light, `1 / points` times the sum over its points of the
    /// renderer's products.
    pub value: Color,
    /// The weight of its ray.
    pub ray_weight: Color,
    /// The opacity `d` of the ray's surface when that surface blends with a transmission ray
    /// (its own light is scaled by `d`).
    pub opacity: Option<f32>,
    /// How the term reaches the sample: `ray_weight`, times `opacity` when there is one.
    pub path_weight: Color,
    /// The sample's share of the pixel.
    pub sample_weight: f32,
    /// `value x path_weight x sample_weight`: what it adds to the pixel.
    pub contribution: Color,
    /// For an environment term: where the ray read the map.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub environment: Option<EnvironmentLookup>,
}

/// One factor by which a ray's weight is its parent's.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum WeightFactor {
    /// The parent surface's specular reflectance (a reflection).
    Ks(Color),
    /// The parent surface's opacity `d`: a reflection of a surface that also transmits.
    Opacity(f32),
    /// `1 - d`: the transmission ray.
    Transmittance(f32),
    /// `1 / n`: one of `n` glossy rays.
    GlossyShare(u32),
}

impl fmt::Display for WeightFactor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WeightFactor::Ks(ks) => write!(f, "ks {}", rgb(*ks)),
            WeightFactor::Opacity(d) => write!(f, "d {}", num(*d)),
            WeightFactor::Transmittance(t) => write!(f, "(1 - d) {}", num(*t)),
            WeightFactor::GlossyShare(n) => write!(f, "1/{n}"),
        }
    }
}

/// How one ray of a sample's tree is weighed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RayWeight {
    /// The sample's index.
    pub sample: u32,
    /// The ray's index in the sample's tree.
    pub ray: usize,
    /// Its kind.
    pub kind: RayKind,
    /// Its parent ray, `None` for the camera ray.
    pub parent: Option<usize>,
    /// The factors by which its weight is its parent's.
    pub factors: Vec<WeightFactor>,
    /// Its weight as the renderer computed it.
    pub weight: Color,
    /// The branches of its hit that adaptive depth control did not cast (adding black).
    pub stopped: Vec<StoppedBranch>,
}

/// A pixel's value as a sum of terms: see the module's documentation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Explanation {
    /// The pixel.
    pub pixel: [u32; 2],
    /// Every recorded ray's weight, sample by sample.
    pub rays: Vec<RayWeight>,
    /// The terms, sample by sample and ray by ray.
    pub terms: Vec<Term>,
    /// The sum of the terms' contributions.
    pub sum: Color,
    /// The pixel's value as the renderer computed it ([`PixelTrace::value`]).
    pub value: Color,
    /// False when a ray tree was cut: the terms of the rays it did not record are missing.
    pub complete: bool,
    /// Samples whose colour was not finite: the film adds black for them, so they have no term.
    pub dropped_samples: Vec<u32>,
    /// The pixel's tile, when the renderer culled it ([`PixelTrace::culled`]).
    pub culled: Option<CulledTile>,
}

impl PixelTrace {
    /// The pixel's value as a sum of terms.
    pub fn explain(&self) -> Explanation {
        let mut e = Explanation {
            pixel: self.pixel,
            rays: Vec::new(),
            terms: Vec::new(),
            sum: Color::ZERO,
            value: self.value,
            complete: true,
            dropped_samples: Vec::new(),
            culled: self.culled,
        };
        for sample in &self.samples {
            e.complete &= sample.tree.cut.is_none();
            if sample.dropped {
                e.dropped_samples.push(sample.index);
                continue;
            }
            for (i, ray) in sample.tree.rays.iter().enumerate() {
                e.rays.push(ray_weight(sample, i));
                sample_terms(sample, i, ray, &mut e.terms);
            }
        }
        e.sum = e.terms.iter().map(|t| t.contribution).sum();
        e
    }
}

/// The factors that make ray `i` of `sample` from its parent.
fn ray_weight(sample: &SampleTrace, i: usize) -> RayWeight {
    let rays = &sample.tree.rays;
    let ray = &rays[i];
    let mut factors = Vec::new();
    if let Some(p) = ray.parent {
        let surface = rays[p].surface;
        let opacity = surface.and_then(|s| s.opacity);
        match ray.kind {
            RayKind::Camera => {}
            RayKind::Transmission => factors.extend(opacity.map(|d| WeightFactor::Transmittance(1.0 - d))),
            RayKind::Reflection | RayKind::Glossy => {
                factors.extend(surface.map(|s| WeightFactor::Ks(s.ks)));
                factors.extend(opacity.map(WeightFactor::Opacity));
                if ray.kind == RayKind::Glossy {
                    let n = rays.iter().filter(|r| r.parent == Some(p) && r.kind == RayKind::Glossy).count();
                    factors.push(WeightFactor::GlossyShare(n as u32));
                }
            }
        }
    }
    RayWeight {
        sample: sample.index,
        ray: i,
        kind: ray.kind,
        parent: ray.parent,
        factors,
        weight: Color::from(ray.weight),
        stopped: ray.stopped.clone(),
    }
}

/// Push the terms of ray `i` of `sample`.
fn sample_terms(sample: &SampleTrace, i: usize, ray: &RecordedRay, out: &mut Vec<Term>) {
    let weight = Color::from(ray.weight);
    let opacity = ray.surface.and_then(|s| s.opacity);
    let path_weight = weight * opacity.unwrap_or(1.0);
    // One model shades every light point of a hit.
    let model = ray.light_terms.first().map(|t| t.model);
    let term = |light, kind, material, lights: Option<LightFactors>, value: Color| Term {
        sample: sample.index,
        ray: i,
        light,
        kind,
        model: lights.and(model),
        gradient_cos: None,
        material,
        lights,
        value,
        ray_weight: weight,
        opacity,
        path_weight,
        sample_weight: sample.weight,
        contribution: value * path_weight * sample.weight,
        environment: None,
    };
    let color = Color::from(ray.color);
    if ray.hit.is_none() {
        let kind = if ray.environment.is_some() { TermKind::Environment } else { TermKind::Background };
        out.push(Term { environment: ray.environment, ..term(None, kind, color, None, color) });
        return;
    }
    let Some(surface) = ray.surface else {
        // No shading factors reported for a hit: shading is off and the ray returned `kd`.
        out.push(term(None, TermKind::UnshadedKd, color, None, color));
        return;
    };
    for light in lights_in_order(ray) {
        let points: Vec<&LightTerm> = ray.light_terms.iter().filter(|t| t.light == light).collect();
        let skipped = ray.skipped_lights.iter().filter(|s| s.light == light).count() as u32;
        let shaded = points.len() as u32;
        let n = points.first().map_or(shaded + skipped, |t| t.samples);
        let reached = points.iter().filter(|t| t.arrived != Color::ZERO).count() as u32;
        // Means over the shaded points, for people; the value is the renderer's own sum.
        let mean = |f: &dyn Fn(&LightTerm) -> Color| {
            if shaded == 0 { Color::ZERO } else { points.iter().map(|t| f(t)).sum::<Color>() / shaded as f32 }
        };
        let factors = |factor: &dyn Fn(&LightTerm) -> f32| LightFactors {
            points: n,
            shaded,
            reached,
            factor: mean(&|t| Color::splat(factor(t))).x,
            light_color: mean(&|t| t.light_color),
            arrived: mean(&|t| t.arrived),
        };
        // The renderer sums a light's points in order, then divides by their count.
        let sum = |f: &dyn Fn(&LightTerm) -> Color| points.iter().map(|t| f(t)).sum::<Color>() / n.max(1) as f32;
        let diffuse = if model == Some(ShadingModel::Gradient) {
            // The gradient's colour changes with each point's cosine: its mean, and the
            // cosine's apart (the colour is not multiplied by it).
            let at = factors(&|t| t.cos).factor;
            let mut t =
                term(Some(light), TermKind::Diffuse, mean(&|t| t.kd), Some(factors(&|_| 1.0)), sum(&|t| t.diffuse));
            t.gradient_cos = Some(at);
            t
        } else {
            let kd = points.first().map_or(Color::ZERO, |t| t.kd);
            term(Some(light), TermKind::Diffuse, kd, Some(factors(&|t| t.cos)), sum(&|t| t.diffuse))
        };
        out.push(diffuse);
        if surface.ks != Color::ZERO && shaded > 0 && model.is_none_or(ShadingModel::has_highlight) {
            let specular = factors(&|t| t.highlight);
            out.push(term(Some(light), TermKind::Specular, surface.ks, Some(specular), sum(&|t| t.specular)));
        }
    }
}

/// The lights shaded or skipped at `ray`'s hit, each once, in the order the integrator met them.
fn lights_in_order(ray: &RecordedRay) -> Vec<usize> {
    let mut lights: Vec<usize> =
        ray.light_terms.iter().map(|t| t.light).chain(ray.skipped_lights.iter().map(|s| s.light)).collect();
    lights.sort_unstable();
    lights.dedup();
    lights
}

/// A number for people: four decimals, trailing zeros dropped.
fn num(x: f32) -> String {
    let s = format!("{x:.4}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { &s };
    if s == "-0" { "0".into() } else { s.into() }
}

/// A colour for people: one number when its channels are equal, else `(r, g, b)`.
fn rgb(c: Color) -> String {
    if c.x == c.y && c.y == c.z { num(c.x) } else { format!("({}, {}, {})", num(c.x), num(c.y), num(c.z)) }
}

/// A colour with full precision, for sums a person compares.
fn rgb_exact(c: Color) -> String {
    format!("({:.7}, {:.7}, {:.7})", c.x, c.y, c.z)
}

impl Term {
    /// The factors that make its value, in words: `kd 0.8 x cos 0.71 x light 1 x shadow 3/4`.
    pub fn factors_text(&self) -> String {
        match (self.kind, &self.lights) {
            (TermKind::Diffuse | TermKind::Specular, Some(l)) if l.shaded == 0 => {
                format!("no light: all {} behind the surface", l.points)
            }
            (TermKind::Diffuse | TermKind::Specular, Some(l)) => {
                let mean = if l.shaded > 1 { "mean " } else { "" };
                let model = self.model.map_or(String::new(), |m| format!("{}: ", m.name()));
                let surface = match (self.kind, self.model) {
                    (TermKind::Diffuse, Some(ShadingModel::Gradient)) => format!(
                        "{mean}gradient {} at {mean}cos {}",
                        rgb(self.material),
                        num(self.gradient_cos.unwrap_or(f32::NAN))
                    ),
                    (TermKind::Diffuse, _) => format!("kd {} x {mean}cos {}", rgb(self.material), num(l.factor)),
                    (_, Some(ShadingModel::BlinnPhong)) => {
                        format!("ks {} x {mean}highlight (n.h)^s {}", rgb(self.material), num(l.factor))
                    }
                    _ => format!("ks {} x {mean}highlight (r.v)^s {}", rgb(self.material), num(l.factor)),
                };
                let mut s = format!(
                    "{model}{surface} x {mean}light {} x shadow {}/{}",
                    rgb(l.light_color),
                    l.reached,
                    l.points
                );
                // Through transparent surfaces a shadow ray lets a fraction through.
                let all_or_nothing = Color::splat(l.reached as f32 / l.shaded.max(1) as f32);
                if l.arrived != all_or_nothing {
                    s += &format!(" ({mean}arrived {})", rgb(l.arrived));
                }
                if l.shaded < l.points {
                    s += &format!(" ({} behind the surface)", l.points - l.shaded);
                }
                s
            }
            (TermKind::Environment, _) => match &self.environment {
                Some(e) => format!(
                    "map texel ({}, {}) at u {} v {} (direction {}) = {}",
                    e.texel[0],
                    e.texel[1],
                    num(e.uv[0]),
                    num(e.uv[1]),
                    rgb(Color::from(e.dir)),
                    rgb(self.material)
                ),
                None => rgb(self.material),
            },
            _ => rgb(self.material),
        }
    }
}

impl fmt::Display for Explanation {
    /// The breakdown as aligned text: per sample, per ray (its weight and how it is made), per
    /// light the terms and their factors, then the sum and the renderer's value.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [x, y] = self.pixel;
        writeln!(f, "pixel ({x}, {y}): value = sum of the terms below")?;
        if let Some(CulledTile { x, y, nodes }) = self.culled {
            let s = if nodes == 1 { "" } else { "s" };
            writeln!(
                f,
                "not traced by the renderer: the frustum of its tiles (columns {}..{}, rows {}..{}) meets no leaf \
                 box of the BVH ({nodes} node{s} tested), so they were filled with the background; traced here, \
                 its rays miss",
                x[0], x[1], y[0], y[1]
            )?;
        }
        let rows: Vec<(String, String, String)> = self.rows();
        // Only the terms' rows are aligned; headings run across the columns.
        let terms = rows.iter().filter(|r| !r.1.is_empty());
        let w0 = terms.clone().map(|r| r.0.chars().count()).max().unwrap_or(0);
        let w1 = terms.map(|r| r.1.chars().count()).max().unwrap_or(0);
        for (a, b, c) in rows {
            if b.is_empty() && c.is_empty() {
                writeln!(f, "{a}")?;
            } else {
                writeln!(f, "{a:<w0$}  {b:<w1$}  {c}")?;
            }
        }
        for s in &self.dropped_samples {
            writeln!(f, "sample {s}: not finite, added as black")?;
        }
        if !self.complete {
            writeln!(
                f,
                "incomplete: a ray tree was cut (--max-rays); the terms of the rays it did not record are missing"
            )?;
        }
        writeln!(f, "sum of the terms        {}", rgb_exact(self.sum))?;
        writeln!(f, "the pixel (renderer)    {}", rgb_exact(self.value))
    }
}

impl Explanation {
    /// The text's lines: a heading line (one column), or a term as (label, factors, result).
    fn rows(&self) -> Vec<(String, String, String)> {
        let mut rows = Vec::new();
        let mut terms = self.terms.iter().peekable();
        let mut sample = None;
        for ray in &self.rays {
            if sample != Some(ray.sample) {
                sample = Some(ray.sample);
                let w = self.terms.iter().find(|t| t.sample == ray.sample).map_or(0.0, |t| t.sample_weight);
                rows.push((format!("sample {} (weighs {})", ray.sample, num(w)), String::new(), String::new()));
            }
            let of = ray.parent.map_or(String::new(), |p| format!(" of ray {p}"));
            let parent = ray.parent.and_then(|p| self.rays.iter().find(|r| r.sample == ray.sample && r.ray == p));
            let made = match parent {
                Some(p) if !ray.factors.is_empty() => {
                    let f: Vec<String> = ray.factors.iter().map(|f| f.to_string()).collect();
                    format!(" = ray {}'s {} x {}", p.ray, rgb(p.weight), f.join(" x "))
                }
                _ => String::new(),
            };
            rows.push((
                format!("  ray {} {}{of}: weight {}{made}", ray.ray, ray.kind.noun(), rgb(ray.weight)),
                String::new(),
                String::new(),
            ));
            for b in &ray.stopped {
                rows.push((format!("    {b}"), String::new(), String::new()));
            }
            while let Some(t) = terms.next_if(|t| t.sample == ray.sample && t.ray == ray.ray) {
                let light = t.light.map_or(String::new(), |l| format!(" light {l}"));
                rows.push((
                    format!("    {}{light}", t.kind.name()),
                    t.factors_text(),
                    format!(
                        "= {} x weight {}{} x {} = {}",
                        rgb(t.value),
                        rgb(t.ray_weight),
                        t.opacity.map_or(String::new(), |d| format!(" x d {}", num(d))),
                        num(t.sample_weight),
                        rgb(t.contribution)
                    ),
                ));
            }
        }
        rows
    }
}
