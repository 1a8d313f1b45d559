//! Scenes: what a scene file or built-in describes ([`desc`]), the course's built-in scenes
//! ([`builtin`]), and the loaded [`Scene`] with its BVH, ready to trace: here its hits and
//! the shading information at them; its shapes in BVH order and the BVH in `geometry.rs`
//! ([`Geometry`]); and in `visibility.rs` the one way shadow rays are asked
//! ([`Scene::light_visibility`], [`LightVisibility`]).

pub mod builtin;
mod camera_lens;
pub mod desc;
mod geometry;
mod prim_ids;
mod texture_lod;
mod visibility;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

pub use desc::{LoadContext, MeshDesc, SceneDesc, SphereDesc, TransformDesc};
// The mesh file formats scenes read, by extension.
pub use crate::io::mesh_file::MESH_EXTENSIONS;
pub use geometry::{Geometry, Shape, SlotInfo};
pub use prim_ids::PrimIds;
pub use texture_lod::TextureLod;
pub use visibility::LightVisibility;

// The loaders' limit on the size of a file, under the scene whose files it bounds.
pub use crate::io::file::{DEFAULT_MAX_FILE_BYTES, MAX_FILE_BYTES_VAR, max_file_bytes, set_max_file_bytes};

// What a scene is made of, under the names a user of the scene meets them by.
pub use crate::light::{Light, LightSample};
pub use crate::material::{Material, MaterialDesc, Texture};
pub use crate::ray::Ray;

use crate::animation::{AnimationSettings, Shutter};
use crate::bvh::{
    BuildParams, BvhStats, FrustumTest, LoggedQuery, NoObserver, NodeLog, Primitives, TraversalObserver, WideBox,
    WideRef,
};
use crate::camera::{Camera, CameraDesc, CameraMotion};
use crate::environment::Environment;
use crate::error::{Error, Result};
use crate::geometry::{Aabb, Frustum};
use crate::io::file::read_text;
use crate::math::{Color, Vec2, Vec3A, face_forward};
use crate::motion::{Interpolation, MotionPath};
use crate::settings::{RenderSettings, ShadingOptions, TextureFilter};

/// A triangle mesh with per-vertex attributes and a material per triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Name, for the debugger.
    pub name: String,
    /// Vertex positions (world space).
    pub positions: Vec<Vec3A>,
    /// Unit vertex normals, one per position (empty: none).
    pub normals: Vec<Vec3A>,
    /// Texture coordinates, one per position (empty: none).
    pub uvs: Vec<Vec2>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Material of each triangle (index into [`Scene::materials`]).
    pub materials: Vec<u32>,
    /// Motion during the exposure, a translation along a path; positions are at rest (before
    /// the motion).
    pub motion: Option<MotionPath>,
}

/// An analytic sphere with a material.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSphere {
    /// Centre.
    pub center: Vec3A,
    /// Radius.
    pub radius: f32,
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// Motion during the exposure, a translation along a path.
    pub motion: Option<MotionPath>,
}

/// Which primitive a global primitive id names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimRef {
    /// Triangle `face` of mesh `mesh`.
    Triangle {
        /// Mesh index.
        mesh: u32,
        /// Triangle index within the mesh.
        face: u32,
    },
    /// Sphere number `0`.
    Sphere(u32),
}

impl PrimRef {
    /// The primitive's material, from the meshes and spheres its indices point into.
    pub fn material(self, meshes: &[Mesh], spheres: &[SceneSphere]) -> u32 {
        match self {
            PrimRef::Triangle { mesh, face } => meshes[mesh as usize].materials[face as usize],
            PrimRef::Sphere(s) => spheres[s as usize].material,
        }
    }
}

/// The closest hit of a ray with the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter.
    pub t: f32,
    /// Where the primitive sits in the BVH's order ([`Geometry::shapes`], [`Geometry::slots`]);
    /// [`Scene::prim_id`] gives its global id. The hit carries the slot alone because
    /// shading reads slot-ordered data: looking up the global id for every ray was a cache
    /// miss after each incoherent hit (about 5% of their time on the dragon).
    pub slot: u32,
    /// Barycentric weight of vertex 1 (triangles).
    pub u: f32,
    /// Barycentric weight of vertex 2 (triangles).
    pub v: f32,
}

/// Everything shading needs to know about a hit point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceInteraction {
    /// The hit point.
    pub point: Vec3A,
    /// Unit geometric normal, turned towards the incoming ray's origin.
    pub geo_normal: Vec3A,
    /// Unit shading normal (interpolated when enabled), on the same side as `geo_normal`.
    pub shading_normal: Vec3A,
    /// Texture coordinates (zero without UVs).
    pub uv: Vec2,
    /// Material index.
    pub material: u32,
    /// Diffuse colour at the point: the texture where there is one, else `kd`.
    pub kd: Color,
}

/// A loaded scene with its acceleration structure, ready to trace. Immutable once built, so
/// threads share it by reference.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Display name.
    pub name: String,
    /// The camera as described (its pose when the shutter opens).
    pub camera: CameraDesc,
    /// The camera's pose when the shutter closes, if it moves.
    pub camera_end: Option<CameraDesc>,
    /// The camera's translation along a path over the exposure, if it moves so.
    pub camera_path: Option<MotionPath>,
    /// Triangle meshes.
    pub meshes: Vec<Mesh>,
    /// Spheres.
    pub spheres: Vec<SceneSphere>,
    /// Materials referenced by index.
    pub materials: Vec<Material>,
    /// Textures referenced by materials.
    pub textures: Vec<Texture>,
    /// Light sources.
    pub lights: Vec<Light>,
    /// Render settings the scene asks for (overridable by the user).
    pub render: Option<RenderSettings>,
    /// How the scene file animates it (`[animation]`; overridable by the user).
    pub animation: Option<AnimationSettings>,
    /// The environment map rays that miss return (`None`: the background colour).
    pub environment: Option<Environment>,
    /// Global primitive id to primitive ([`Scene::prim`]).
    prim_ids: PrimIds,
    /// Shapes and BVH.
    pub geometry: Geometry,
    /// How long the BVH build took.
    pub build_time: Duration,
    /// Whether any material is not fully opaque (shadow rays must then look through).
    pub has_transparency: bool,
    /// What the loaders accepted but ignored (e.g. texture coordinate indices in an OBJ file
    /// without texture coordinates), one message each, naming the file and line.
    pub warnings: Vec<String>,
    /// The structure of the glTF files the scene read (nodes, meshes, and each material with
    /// its mapping to Phong), one line each, for the debugger.
    pub outline: Vec<String>,
}

impl Scene {
    /// Load a built-in scene by name, a `.toml` scene file, or a bare `.obj`, `.ply`, `.gltf`
    /// or `.glb` mesh (normalised, lit by the course's point light at (-1, 1, -1); a glTF
    /// file's own camera and lights where it has them: [`SceneDesc::for_mesh_file`]).
    pub fn load(spec: &str, assets: Option<&Path>) -> Result<Scene> {
        let path = Path::new(spec);
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        let (desc, base) = match ext.as_deref() {
            Some("toml") => {
                let text = read_text(path)?;
                (SceneDesc::from_toml(&text, path)?, path.parent().map(Path::to_path_buf))
            }
            Some("obj" | "ply" | "gltf" | "glb") => (SceneDesc::for_mesh_file(path)?, None),
            // A built-in scene's name has no extension and no folder: anything else is a path
            // to a file of some other kind (or none), not read as a scene's name.
            e if e.is_some() || spec.contains('/') || spec.contains(std::path::MAIN_SEPARATOR) => {
                return Err(Error::UnsupportedScene { path: path.to_path_buf(), known: builtin::builtin_names() });
            }
            _ => (builtin::scene_desc(spec)?, None),
        };
        let ctx =
            LoadContext { base_dir: base.unwrap_or_else(|| PathBuf::from(".")), assets: assets.map(Path::to_path_buf) };
        Scene::from_desc(&desc, &ctx)
    }

    /// Load what `desc` describes and build the BVH.
    pub fn from_desc(desc: &SceneDesc, ctx: &LoadContext) -> Result<Scene> {
        desc::load(desc, ctx)
    }

    /// Assemble a scene from loaded parts and build its BVH.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        name: String,
        camera: CameraDesc,
        meshes: Vec<Mesh>,
        spheres: Vec<SceneSphere>,
        materials: Vec<Material>,
        textures: Vec<Texture>,
        lights: Vec<Light>,
        render: Option<RenderSettings>,
    ) -> Scene {
        let prim_ids = PrimIds::new(&meshes, spheres.len());
        let start = Instant::now();
        let geometry = Geometry::build_by(
            &meshes,
            &spheres,
            prim_ids.len(),
            |i| prim_ids.get(i),
            &BuildParams::default(),
            Shutter::STILL,
        );
        let build_time = start.elapsed();
        let has_transparency = materials.iter().any(|m| m.transparency < 1.0);
        Scene {
            name,
            camera,
            camera_end: None,
            camera_path: None,
            meshes,
            spheres,
            materials,
            textures,
            lights,
            render,
            animation: None,
            environment: None,
            prim_ids,
            geometry,
            build_time,
            has_transparency,
            warnings: Vec::new(),
            outline: Vec::new(),
        }
    }

    /// The scene's camera (its pose when the shutter opens).
    pub fn camera(&self) -> Camera {
        Camera::from_desc(&self.camera)
    }

    /// The scene's camera over the exposure.
    pub fn camera_motion(&self) -> CameraMotion {
        CameraMotion {
            start: self.camera(),
            end: self.camera_end.as_ref().map(Camera::from_desc),
            path: self.camera_path.clone(),
            shutter: self.shutter(),
        }
    }

    /// The scene time an image of the scene exposes ([`Shutter::STILL`] unless
    /// [`Scene::set_shutter`] chose a frame's).
    pub fn shutter(&self) -> Shutter {
        self.geometry.shutter
    }

    /// Expose the scene times `shutter` covers (a frame of an animation): the BVH is rebuilt
    /// around the moving shapes' bounds over those times when anything moves (a static
    /// scene's tree does not depend on them and is kept). Returns whether it was rebuilt
    /// (its time in [`Scene::build_time`]).
    pub fn set_shutter(&mut self, shutter: Shutter) -> bool {
        if shutter == self.geometry.shutter {
            return false;
        }
        if !geometry::anything_moves(&self.meshes, &self.spheres) {
            self.geometry.shutter = shutter;
            return false;
        }
        let start = Instant::now();
        self.geometry = self.rebuilt(shutter);
        self.build_time = start.elapsed();
        true
    }

    /// Whether anything moves over time (a mesh, a sphere or the camera): without, every
    /// frame of an animation is the same image.
    pub fn has_motion(&self) -> bool {
        geometry::anything_moves(&self.meshes, &self.spheres)
            || self.camera_path.as_ref().is_some_and(|p| !p.is_still())
            || self.camera_end.is_some()
    }

    /// Interpolate every path of the scene (its meshes', spheres' and camera's) as
    /// `interpolation`, and rebuild the BVH around the paths' new bounds.
    pub fn set_motion_interpolation(&mut self, interpolation: Interpolation) {
        let paths = self.meshes.iter_mut().map(|m| &mut m.motion);
        let paths = paths.chain(self.spheres.iter_mut().map(|s| &mut s.motion)).chain([&mut self.camera_path]);
        let mut changed = false;
        for path in paths.flatten() {
            changed |= path.interpolation() != interpolation;
            *path = path.with_interpolation(interpolation);
        }
        if changed {
            let start = Instant::now();
            self.geometry = self.rebuilt(self.shutter());
            self.build_time = start.elapsed();
        }
    }

    /// Whether anything moves along a path (a mesh, a sphere or the camera).
    pub fn has_paths(&self) -> bool {
        self.meshes.iter().any(|m| m.motion.is_some())
            || self.spheres.iter().any(|s| s.motion.is_some())
            || self.camera_path.is_some()
    }

    /// The geometry over the scene's shapes for the times `shutter` exposes.
    fn rebuilt(&self, shutter: Shutter) -> Geometry {
        let (meshes, spheres, ids) = (&self.meshes, &self.spheres, &self.prim_ids);
        Geometry::build_by(meshes, spheres, ids.len(), |i| ids.get(i), &BuildParams::default(), shutter)
    }

    /// The primitive of global id `id` (below [`Scene::prim_count`]).
    pub fn prim(&self, id: u32) -> PrimRef {
        self.prim_ids.get(id)
    }

    /// Number of primitives (triangles and spheres).
    pub fn prim_count(&self) -> usize {
        self.prim_ids.len()
    }

    /// Every primitive, by global id (what [`Geometry::build`] takes).
    pub fn prim_refs(&self) -> Vec<PrimRef> {
        (0..self.prim_count() as u32).map(|i| self.prim(i)).collect()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.triangles.len()).sum()
    }

    /// BVH statistics.
    pub fn bvh_stats(&self) -> BvhStats {
        self.geometry.bvh.stats()
    }

    /// The closest hit along `ray`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.geometry.intersect(ray, &mut NoObserver)
    }

    /// Whether a ray inside `frustum` may hit anything (`may_hit` false proves that none
    /// does): the test rendering skips the traversal of a tile's camera rays by.
    pub fn frustum_test(&self, frustum: &Frustum) -> FrustumTest {
        self.geometry.wide.frustum_test(frustum)
    }

    /// The closest hits of up to [`crate::bvh::PACKET`] rays (camera rays of
    /// neighbouring pixels): each is what [`Scene::intersect`] gives, found in one traversal
    /// when the rays share an origin.
    #[inline(always)]
    pub fn intersect_packet(&self, rays: &[Ray]) -> [Option<Hit>; crate::bvh::PACKET] {
        self.geometry.intersect_packet(rays)
    }

    /// [`Scene::intersect`], reporting the traversal to `stats`.
    #[inline]
    pub fn intersect_counted<O: TraversalObserver>(&self, ray: &Ray, stats: &mut O) -> Option<Hit> {
        self.geometry.intersect(ray, stats)
    }

    /// [`Scene::intersect_packet`], reporting each ray's traversal to its observer in `obs`
    /// (`obs[i]` for `rays[i]`): the renderer's camera-ray traversal, observed (see
    /// [`crate::bvh::WideBvh::intersect_packet_counted`]).
    #[inline]
    pub fn intersect_packet_counted<O: TraversalObserver>(
        &self,
        rays: &[Ray],
        obs: &mut [O; crate::bvh::PACKET],
    ) -> [Option<Hit>; crate::bvh::PACKET] {
        self.geometry.intersect_packet_counted(rays, obs)
    }

    /// The closest hits of up to [`crate::bvh::TILE_RUNS`] runs of up to
    /// [`crate::bvh::PACKET`] rays each (the camera rays of a tile of pixels, row by row):
    /// each is what [`Scene::intersect`] gives, found in one traversal of the tile when the
    /// rays share an origin.
    #[inline(always)]
    pub fn intersect_tile(&self, runs: &[&[Ray]]) -> [[Option<Hit>; crate::bvh::PACKET]; crate::bvh::TILE_RUNS] {
        self.geometry.intersect_tile(runs)
    }

    /// [`Scene::intersect_tile`], reporting each ray's traversal to its observer in `obs`
    /// (`obs[r][i]` for `runs[r][i]`; see [`crate::bvh::WideBvh::intersect_tile_counted`]).
    #[inline]
    pub fn intersect_tile_counted<O: TraversalObserver>(
        &self,
        runs: &[&[Ray]],
        obs: &mut [[O; crate::bvh::PACKET]; crate::bvh::TILE_RUNS],
    ) -> [[Option<Hit>; crate::bvh::PACKET]; crate::bvh::TILE_RUNS] {
        self.geometry.intersect_tile_counted(runs, obs)
    }

    /// Levels of the wide BVH that rendering traverses, counting the boxes of its leaves:
    /// [`Scene::wide_boxes_at_level`] takes `0..wide_levels()`.
    pub fn wide_levels(&self) -> u32 {
        self.geometry.wide.box_levels()
    }

    /// The boxes of level `level` of the wide BVH that rendering traverses: its nodes at that
    /// level and the leaves at or above it (so every primitive is in a drawn box), each named
    /// as [`crate::record::RecordedTraversal::visits`] names what a ray entered. The course's
    /// binary tree's levels stay in [`crate::bvh::Bvh::boxes_at_level`]
    /// (`scene.geometry.bvh`).
    pub fn wide_boxes_at_level(&self, level: u32) -> Vec<WideBox> {
        self.geometry.wide.boxes_at_level(level)
    }

    /// The box the wide BVH's traversal tests for `at`: a node's, or the leaf's in its parent;
    /// `None` when the tree has no such node or slot.
    pub fn wide_box(&self, at: WideRef) -> Option<Aabb> {
        self.geometry.wide.wide_box(at)
    }

    /// The boxes of what one logged query of the wide BVH entered (a
    /// [`crate::bvh::TraversalLog`] observed it), in order, with their levels.
    pub fn visited_boxes(&self, query: &LoggedQuery) -> Vec<WideBox> {
        self.geometry.wide.visited_boxes(&query.entered)
    }

    /// The binary BVH nodes a closest-hit query for `ray` enters, in traversal order: the
    /// course's tree, which rendering does not traverse (it traverses the wide one, whose
    /// visits the ray recorder keeps: [`crate::record::RecordedTraversal`]). Pass the
    /// recorded ray with its interval and time ([`crate::record::RecordedTraversal::ray`]),
    /// so that the replay stops where the ray does.
    pub fn visited_nodes(&self, ray: &Ray) -> Vec<u32> {
        let mut log = NodeLog::default();
        self.geometry.intersect_binary(ray, &mut log);
        log.0
    }

    /// The global primitive id of a hit (triangles of all meshes in order, then spheres).
    #[inline]
    pub fn prim_id(&self, hit: &Hit) -> u32 {
        self.geometry.prim_id(hit.slot)
    }

    /// The material of primitive `prim` (a global id).
    pub fn material_of(&self, prim: u32) -> u32 {
        self.prim(prim).material(&self.meshes, &self.spheres)
    }

    /// The world-space corners of triangle `prim` when the shutter opens, or `None` for a
    /// sphere.
    pub fn triangle_vertices(&self, prim: u32) -> Option<[Vec3A; 3]> {
        match self.prim(prim) {
            PrimRef::Triangle { mesh, face } => {
                let m = &self.meshes[mesh as usize];
                let o = m.motion.as_ref().map_or(Vec3A::ZERO, MotionPath::start);
                Some(m.triangles[face as usize].map(|i| m.positions[i as usize] + o))
            }
            PrimRef::Sphere(_) => None,
        }
    }

    /// Shading information at `hit` on `ray`. A trilinear texture lookup here has no
    /// footprint and reads the finest level ([`Scene::surface_in_cone`] has one). Not marked
    /// `#[inline]`, as before the footprint: the compiler's own choice keeps the camera rays'
    /// loop as it was.
    pub fn surface(&self, ray: &Ray, hit: &Hit, options: &ShadingOptions) -> SurfaceInteraction {
        self.surface_at(ray, hit, options, None).si
    }

    /// [`Scene::surface`] for a ray whose cone is `width` wide at the hit
    /// ([`crate::settings::TextureFilter::Trilinear`]): a trilinear texture lookup reads the mip
    /// level of the cone's footprint on the surface, which the answer tells.
    pub fn surface_in_cone(&self, ray: &Ray, hit: &Hit, options: &ShadingOptions, width: f32) -> ConeSurface {
        self.surface_at(ray, hit, options, Some(width))
    }

    /// The curvature (1 / radius) of the surface at `hit`, for a reflected ray cone: a
    /// sphere's; for a triangle whose normals are interpolated, the largest turn of its vertex
    /// normals per unit of length along an edge; 0 for a flat triangle.
    pub fn curvature(&self, hit: &Hit, options: &ShadingOptions) -> f32 {
        match self.geometry.slots[hit.slot as usize].prim {
            PrimRef::Sphere(s) => 1.0 / self.spheres[s as usize].radius,
            PrimRef::Triangle { mesh, face } => {
                let m = &self.meshes[mesh as usize];
                if !options.interpolate_normals || m.normals.is_empty() {
                    return 0.0;
                }
                let c = m.triangles[face as usize].map(|i| i as usize);
                let turn = |a: usize, b: usize| {
                    let len = (m.positions[b] - m.positions[a]).length();
                    if len > 0.0 { (m.normals[b] - m.normals[a]).length() / len } else { 0.0 }
                };
                turn(c[0], c[1]).max(turn(c[1], c[2])).max(turn(c[2], c[0]))
            }
        }
    }

    /// [`Scene::surface`], with the texture's mip level chosen by a cone of `cone` width when
    /// there is one (inlined: `surface`'s constant `None` removes the footprint's code).
    #[inline(always)]
    fn surface_at(&self, ray: &Ray, hit: &Hit, options: &ShadingOptions, cone: Option<f32>) -> ConeSurface {
        let point = ray.at(hit.t);
        // Read in slot order (neighbouring rays, neighbouring slots); the mesh's own arrays
        // only for what the slot does not hold.
        let SlotInfo { prim, material } = self.geometry.slots[hit.slot as usize];
        let (geo, shading, uv, material, uv_density) = match prim {
            PrimRef::Triangle { mesh, face } => {
                let m = &self.meshes[mesh as usize];
                let corners = || m.triangles[face as usize].map(|i| i as usize);
                let geo = match self.geometry.triangle(hit.slot) {
                    // The same edges as the mesh's, for a mesh with no motion offset.
                    Some(t) if m.motion.is_none() => t.normal().normalize_or_zero(),
                    _ => {
                        let [a, b, c] = corners();
                        (m.positions[b] - m.positions[a]).cross(m.positions[c] - m.positions[a]).normalize_or_zero()
                    }
                };
                let w = Vec3A::new(1.0 - hit.u - hit.v, hit.u, hit.v);
                let smooth = options.interpolate_normals && !m.normals.is_empty();
                let (shading, uv) = if smooth || !m.uvs.is_empty() {
                    let [a, b, c] = corners();
                    let shading = if smooth {
                        (w.x * m.normals[a] + w.y * m.normals[b] + w.z * m.normals[c]).normalize_or(geo)
                    } else {
                        geo
                    };
                    let uv =
                        if m.uvs.is_empty() { Vec2::ZERO } else { w.x * m.uvs[a] + w.y * m.uvs[b] + w.z * m.uvs[c] };
                    (shading, uv)
                } else {
                    (geo, Vec2::ZERO)
                };
                // The texture's stretch, for a footprint: uv area per world area.
                let uv_density = if cone.is_some() && !m.uvs.is_empty() {
                    let [a, b, c] = corners();
                    let world = (m.positions[b] - m.positions[a]).cross(m.positions[c] - m.positions[a]).length();
                    (m.uvs[b] - m.uvs[a]).perp_dot(m.uvs[c] - m.uvs[a]).abs() / world
                } else {
                    0.0
                };
                (geo, shading, uv, material, uv_density)
            }
            PrimRef::Sphere(s) => {
                let s = &self.spheres[s as usize];
                let center = s.center + s.motion.as_ref().map_or(Vec3A::ZERO, |m| m.at(self.shutter().time(ray.time)));
                let n = ((point - center) / s.radius).normalize_or_zero();
                // Spherical coordinates, for textured spheres.
                let uv = Vec2::new(
                    0.5 + n.z.atan2(n.x) / std::f32::consts::TAU,
                    0.5 + n.y.clamp(-1.0, 1.0).asin() / std::f32::consts::PI,
                );
                // The unit uv square covers the sphere's area (stretched towards the poles).
                let uv_density =
                    if cone.is_some() { 1.0 / (4.0 * std::f32::consts::PI * s.radius * s.radius) } else { 0.0 };
                (n, n, uv, material, uv_density)
            }
        };
        // Shade the side the ray arrives from: the course's meshes are not consistently
        // oriented and are seen from both sides.
        let geo_normal = face_forward(geo, -ray.dir);
        let shading_normal = face_forward(shading, geo_normal);
        let mat = &self.materials[material as usize];
        let mut lod = None;
        let kd = match (mat.texture, options.textures, cone) {
            (Some(t), true, Some(width)) if options.texture_filter == TextureFilter::Trilinear => {
                let texture = &self.textures[t];
                let l = TextureLod::of(texture, t, width, geo_normal.dot(ray.dir).abs(), uv_density);
                lod = Some(l);
                texture.sample_lod(uv, l.level)
            }
            (Some(t), true, _) => self.textures[t].sample(uv, options.texture_filter),
            _ => mat.kd,
        };
        ConeSurface { si: SurfaceInteraction { point, geo_normal, shading_normal, uv, material, kd }, lod }
    }
}

/// [`Scene::surface_in_cone`]'s answer: the shading information, and the mip level its
/// texture lookup read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeSurface {
    /// The shading information.
    pub si: SurfaceInteraction,
    /// The trilinear lookup's footprint and level; `None` where no texture was read
    /// trilinearly.
    pub lod: Option<TextureLod>,
}
