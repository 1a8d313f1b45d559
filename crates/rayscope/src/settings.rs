//! Every switch of the renderer, in one leaf that the scene, the integrator, the renderer and
//! the user interfaces all read: [`RenderSettings`], their limits and their validation, and the
//! small option types they are made of. It imports nothing of the renderer, so no module below
//! the renderer has to import the renderer to learn how to shade.

use serde::{Deserialize, Serialize};

// The colour type of the settings (and of the film), under the name a user meets it by.
pub use crate::math::Color;

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
    /// The scene-wide shading model: every material that names no `model` of its own is
    /// shaded with it (a material's own model wins).
    pub shading_model: ShadingModel,
    /// Shadow rays towards each light.
    pub shadows: bool,
    /// Recursive mirror reflection for materials with `ks > 0`.
    pub reflections: bool,
    /// Transparency (MTL `d < 1`) for camera rays and shadows.
    pub transparency: bool,
    /// Deepest recursion: rays at this depth cast no reflection or transmission ray.
    pub max_depth: u32,
    /// Adaptive depth control, as POV-Ray's `adc_bailout`: a reflection, glossy or
    /// transmission ray whose weight (the largest colour channel of the product of the factors
    /// by which its light reaches the pixel) is below this is not cast and adds nothing (black).
    /// It bounds the ray tree of surfaces that both reflect and transmit, which otherwise
    /// doubles with every level. 0 turns it off. Default [`DEFAULT_ADC_BAILOUT`].
    pub adc_bailout: f32,
    /// Interpolate vertex normals across triangles (barycentric); off uses face normals.
    pub interpolate_normals: bool,
    /// Use diffuse textures (`map_Kd`) in place of `kd`.
    pub textures: bool,
    /// How textures are filtered.
    pub texture_filter: TextureFilter,
    /// Colour of rays that hit nothing.
    pub background: Color,
    /// Samples (camera rays) per pixel: anti-aliasing, and motion blur over the shutter.
    pub spp: u32,
    /// Shadow rays per area light ("rays per light"); 0 shades each light from its centre.
    pub light_samples: u32,
    /// Rays sampling each glossy reflection; 0 reflects as a perfect mirror.
    pub gloss_samples: u32,
    /// Pixel reconstruction filter.
    pub filter: PixelFilter,
    /// Seed of every random number; the same seed gives the same image.
    pub seed: u64,
    /// Lens radius in scene units, for depth of field ([`crate::lens::ThinLens`]); 0 is a
    /// pinhole (everything sharp, and no lens sampling at all).
    pub aperture: f32,
    /// Depth of the plane in focus, along the view axis; `None` focuses on the camera's
    /// look-at point (a trackball's distance, a look-at camera's target). Read only when
    /// `aperture > 0`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub focus_distance: Option<f32>,
    /// Bloom, a glow around bright pixels added to the finished image (off by default).
    #[serde(skip_serializing_if = "BloomSettings::is_off")]
    pub bloom: BloomSettings,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 800,
            height: 800,
            shading: true,
            shading_model: ShadingModel::Phong,
            shadows: true,
            reflections: true,
            transparency: true,
            max_depth: 5,
            adc_bailout: DEFAULT_ADC_BAILOUT,
            interpolate_normals: false,
            textures: true,
            texture_filter: TextureFilter::Bilinear,
            background: Color::ZERO,
            spp: 1,
            light_samples: 0,
            gloss_samples: 0,
            filter: PixelFilter::Box,
            seed: 0,
            aperture: 0.0,
            focus_distance: None,
            bloom: BloomSettings::default(),
        }
    }
}

/// The default [`RenderSettings::adc_bailout`]: 1/1024, a quarter of POV-Ray's 1/255 (the
/// weight below which a branch carrying light of at most 1 cannot move an 8-bit pixel by one
/// step), so that the course's renders keep every bit. The teapot's `Ks 0.2` reflects the
/// teapot: its fourth reflections weigh 0.2^4 = 0.0016, and 1/255 (or 1/512), which stops
/// them, changes 11 of its 640 000 pixels by one step. 1/1024 is the largest power of two that
/// keeps every built-in scene's default render byte-identical; it still bounds the tree (a
/// weight can halve 10 times before it falls below).
pub const DEFAULT_ADC_BAILOUT: f32 = 1.0 / 1024.0;

/// Deepest accepted [`RenderSettings::max_depth`].
pub const MAX_DEPTH: u32 = 64;

/// Largest accepted image side, in pixels (a 16k x 16k float film is already 3 GiB).
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// Largest accepted count of samples, shadow rays per light or glossy rays.
pub const MAX_SAMPLES: u32 = 1 << 16;

impl RenderSettings {
    /// Check that the values make sense (a clear message, not a panic or a huge allocation).
    pub fn validate(&self) -> Result<(), crate::Error> {
        let bad = |m: String| Err(crate::Error::Invalid(m));
        if self.width == 0 || self.height == 0 || self.width > MAX_IMAGE_SIDE || self.height > MAX_IMAGE_SIDE {
            return bad(format!(
                "image size {}x{} is out of range: each side must be 1 to {MAX_IMAGE_SIDE}",
                self.width, self.height
            ));
        }
        if !self.background.is_finite() {
            return bad("background colour must be finite".into());
        }
        if self.max_depth > MAX_DEPTH {
            return bad(format!("max depth {} is out of range (0 to {MAX_DEPTH})", self.max_depth));
        }
        if !(0.0..=1.0).contains(&self.adc_bailout) {
            return bad(format!("adc_bailout {} is out of range (0 to 1; 0 turns it off)", self.adc_bailout));
        }
        if self.spp == 0 || self.spp > MAX_SAMPLES {
            return bad(format!("samples per pixel {} is out of range (1 to {MAX_SAMPLES})", self.spp));
        }
        if !(self.aperture.is_finite() && self.aperture >= 0.0) {
            return bad(format!("aperture {} must be a finite lens radius of 0 or more", self.aperture));
        }
        if let Some(d) = self.focus_distance.filter(|d| !(d.is_finite() && *d > 0.0)) {
            return bad(format!("focus distance {d} must be finite and greater than 0"));
        }
        for (what, n) in [("light samples", self.light_samples), ("gloss samples", self.gloss_samples)] {
            if n > MAX_SAMPLES {
                return bad(format!("{what} {n} is out of range (0 to {MAX_SAMPLES})"));
            }
        }
        self.bloom.validate()
    }

    /// The options the scene's surface queries read ([`ShadingOptions`]).
    #[inline]
    pub fn shading_options(&self) -> ShadingOptions {
        ShadingOptions {
            interpolate_normals: self.interpolate_normals,
            textures: self.textures,
            texture_filter: self.texture_filter,
        }
    }
}

/// The settings that decide what a surface looks like at a hit point: all that the scene's
/// shading queries (`Scene::surface`, `Scene::transmittance`) read, so that they need not see
/// the rest of [`RenderSettings`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadingOptions {
    /// Interpolate vertex normals across triangles ([`RenderSettings::interpolate_normals`]).
    pub interpolate_normals: bool,
    /// Use diffuse textures ([`RenderSettings::textures`]).
    pub textures: bool,
    /// How textures are filtered ([`RenderSettings::texture_filter`]).
    pub texture_filter: TextureFilter,
}

impl Default for ShadingOptions {
    /// The options of the default settings.
    fn default() -> Self {
        RenderSettings::default().shading_options()
    }
}

/// How a surface turns the light of one light point into colour: the diffuse and specular
/// terms of the direct lighting (reflections and transparency are the same for every model).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ShadingModel {
    /// The course's Phong: `kd (n.l) + ks max(0, r.v)^shininess`, `r` the light's mirror
    /// direction.
    #[default]
    Phong,
    /// Blinn-Phong: `kd (n.l) + ks max(0, n.h)^shininess`, `h` the half vector of the light
    /// and view directions. Equal to Phong where the viewer sits at the light's mirror
    /// direction; elsewhere its highlight is wider for the same exponent.
    BlinnPhong,
    /// Lambert: the diffuse term `kd (n.l)` alone, no highlight (`ks` still weights mirror
    /// reflections).
    Lambert,
    /// The course's toon-style model: the diffuse colour read from the material's gradient at
    /// the cosine `n.l` (not multiplied by it again), plus Phong's highlight. A material
    /// without a gradient reads the ramp from black at 0 to `kd` at 1, which is Lambert's
    /// diffuse term.
    Gradient,
}

impl ShadingModel {
    /// Every model, in the order of the user interfaces.
    pub const ALL: [ShadingModel; 4] =
        [ShadingModel::Phong, ShadingModel::BlinnPhong, ShadingModel::Lambert, ShadingModel::Gradient];

    /// Its name in scene files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ShadingModel::Phong => "phong",
            ShadingModel::BlinnPhong => "blinn-phong",
            ShadingModel::Lambert => "lambert",
            ShadingModel::Gradient => "gradient",
        }
    }

    /// Whether it has a specular highlight term.
    pub fn has_highlight(self) -> bool {
        !matches!(self, ShadingModel::Lambert)
    }
}

/// Bloom: a post-process on the linear image (the film's values, before clamping and
/// encoding) that adds a glow around bright pixels. The bright pass keeps what exceeds
/// `threshold` (per channel, `max(c - threshold, 0)`), a separable Gaussian of `radius`
/// pixels blurs it, and `strength` times the blur is added to the image. Off while `strength`
/// is 0 (the default): the image keeps every bit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BloomSettings {
    /// Values above this (per channel, linear) glow. Default 1, the brightest an 8-bit image
    /// shows.
    pub threshold: f32,
    /// The Gaussian's reach in pixels: it spans `-ceil(radius)..=ceil(radius)` with standard
    /// deviation `radius / 3`. 0 to [`MAX_BLOOM_RADIUS`]. Default 8.
    pub radius: f32,
    /// Factor on the blurred bright pass added to the image; 0 (the default) turns bloom off.
    pub strength: f32,
}

/// Largest accepted [`BloomSettings::radius`], in pixels.
pub const MAX_BLOOM_RADIUS: f32 = 512.0;

impl Default for BloomSettings {
    /// Off (strength 0), threshold 1, radius 8 pixels.
    fn default() -> Self {
        BloomSettings { threshold: 1.0, radius: 8.0, strength: 0.0 }
    }
}

impl BloomSettings {
    /// Whether bloom leaves the image as it is (strength 0).
    pub fn is_off(&self) -> bool {
        self.strength == 0.0
    }

    /// Check the values; the message names the command line's flag (the scene file's key is
    /// the flag's last word, in `[render.bloom]`).
    pub fn validate(&self) -> Result<(), crate::Error> {
        let bad = |m: String| Err(crate::Error::Invalid(m));
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return bad(format!("--bloom-threshold {}: must be a finite number, at least 0", self.threshold));
        }
        if !(self.radius.is_finite() && (0.0..=MAX_BLOOM_RADIUS).contains(&self.radius)) {
            return bad(format!("--bloom-radius {}: must be 0 to {MAX_BLOOM_RADIUS} pixels", self.radius));
        }
        if !(self.strength.is_finite() && self.strength >= 0.0) {
            return bad(format!("--bloom-strength {}: must be a finite number, at least 0", self.strength));
        }
        Ok(())
    }
}

/// A pixel filter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum PixelFilter {
    /// Uniform over the pixel (radius 0.5).
    #[default]
    Box,
    /// Triangle (tent) of radius 1 pixel.
    Tent,
    /// Gaussian of standard deviation 0.5 pixel, truncated at 1.5 pixels.
    Gaussian,
}

/// How textures are looked up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum TextureFilter {
    /// The texel under the point.
    Nearest,
    /// Bilinear blend of the four nearest texels.
    #[default]
    Bilinear,
    /// Mipmapping: bilinear in the two levels of the texture's mip pyramid around the level
    /// of detail of the ray's footprint (a ray cone carried from the camera through
    /// reflections), blended linearly. Environment maps are read bilinearly.
    Trilinear,
}
