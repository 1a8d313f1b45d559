//! The rasterized 3D preview: the scene's triangles (and tessellated spheres) with a headlight,
//! and the debugger's lines, drawn with depth into an offscreen texture that egui shows as an
//! image. Rendering offscreen keeps the depth buffer ours (egui's own pass has none) and works
//! the same in a window and in headless tests.
//!
//! Lines are screen-space quads (wgpu's own lines are one pixel wide), one instance per
//! segment, clipped to the near plane before they are widened. Each is drawn twice against the
//! scene's depth: solid where it is in front of every surface, faded where a surface hides it,
//! so a ray tree stays readable inside a closed room. Over the ray-traced image and the heat
//! map the scene is drawn into the depth buffer only ([`Backdrop::DepthOnly`]) and the overlay
//! comes out on a transparent texture that egui lays over the image.

use bytemuck::{Pod, Zeroable};
use eframe::egui_wgpu::{self, wgpu};
use glam::{Mat4, Vec3, Vec4};
use rayscope::camera::Camera;
use rayscope::math::Vec3A;
use rayscope::scene::Scene;

/// A vertex of the scene mesh.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct MeshVertex {
    /// Position.
    pub pos: [f32; 3],
    /// Face normal.
    pub normal: [f32; 3],
    /// Diffuse colour.
    pub color: [f32; 3],
}

/// A vertex of an overlay line (pairs make segments).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct LineVertex {
    /// Position.
    pub pos: [f32; 3],
    /// RGBA colour.
    pub color: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Uniforms {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    /// Target width and height in pixels, the line width in pixels, and the alpha factor of
    /// hidden line parts.
    viewport: [f32; 4],
}

/// How much of a line's opacity is left where a surface hides it.
pub const HIDDEN_ALPHA: f32 = 0.3;

/// What the preview draws behind the overlay.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backdrop {
    /// The shaded scene on a dark background (the raster view).
    Scene,
    /// The shaded scene on a transparent background, over the environment map the viewer
    /// paints beneath it (the raster view of a scene with a map).
    SceneOverMap,
    /// Nothing visible: the scene only in the depth buffer, the background transparent, for
    /// drawing the overlay over another image (the ray-traced view, the heat map).
    DepthOnly,
}

/// The overlay to draw: its lines (pairs of vertices), a version number that changes with them
/// (they upload again only then), the line width in pixels and the backdrop.
#[derive(Clone, Copy, Debug)]
pub struct OverlayDraw<'a> {
    /// Segment end points, two vertices per segment.
    pub lines: &'a [LineVertex],
    /// Changes whenever `lines` does.
    pub version: u64,
    /// Line width in physical pixels.
    pub width_px: f32,
    /// What is drawn behind the lines.
    pub backdrop: Backdrop,
}

const SHADER: &str = r#"
struct U { view_proj: mat4x4<f32>, eye: vec4<f32>, viewport: vec4<f32> };
@group(0) @binding(0) var<uniform> u: U;

struct MeshOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
};

@vertex
fn vs_mesh(@location(0) pos: vec3<f32>, @location(1) normal: vec3<f32>, @location(2) color: vec3<f32>) -> MeshOut {
    var o: MeshOut;
    o.clip = u.view_proj * vec4<f32>(pos, 1.0);
    o.world = pos;
    o.normal = normal;
    o.color = color;
    return o;
}

@fragment
fn fs_mesh(i: MeshOut) -> @location(0) vec4<f32> {
    // A headlight, two-sided: faces seen edge-on darken, so shapes read at a glance.
    let view = normalize(u.eye.xyz - i.world);
    let d = abs(dot(normalize(i.normal), view));
    return vec4<f32>(i.color * (0.25 + 0.75 * d), 1.0);
}

struct LineOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec4<f32>,
};

// One instance per segment a-b, six vertices: a quad `u.viewport.z` pixels wide around it.
@vertex
fn vs_line(
    @builtin(vertex_index) vi: u32,
    @location(0) a: vec3<f32>,
    @location(1) ca: vec4<f32>,
    @location(2) b: vec3<f32>,
    @location(3) cb: vec4<f32>,
) -> LineOut {
    var o: LineOut;
    var pa = u.view_proj * vec4<f32>(a, 1.0);
    var pb = u.view_proj * vec4<f32>(b, 1.0);
    // Pull lines slightly towards the eye so those lying on surfaces win the depth test.
    pa.z = pa.z - 2e-4 * pa.w;
    pb.z = pb.z - 2e-4 * pb.w;
    if (pa.z < 0.0 && pb.z < 0.0) {
        // Wholly behind the near plane: a degenerate quad outside the clip volume.
        o.clip = vec4<f32>(0.0, 0.0, -1.0, 1.0);
        o.color = vec4<f32>(0.0);
        return o;
    }
    // Clip to the near plane (z = 0) before dividing by w: a camera ray starts at the eye.
    if (pa.z < 0.0) {
        pa = mix(pa, pb, pa.z / (pa.z - pb.z));
    }
    if (pb.z < 0.0) {
        pb = mix(pb, pa, pb.z / (pb.z - pa.z));
    }
    let half_px = u.viewport.xy * 0.5;
    let sa = pa.xy / pa.w * half_px;
    let sb = pb.xy / pb.w * half_px;
    var dir = vec2<f32>(1.0, 0.0);
    if (distance(sa, sb) > 1e-6) {
        dir = normalize(sb - sa);
    }
    let normal = vec2<f32>(-dir.y, dir.x);
    // Corners (end, side): (0,-1) (0,1) (1,1) (0,-1) (1,1) (1,-1).
    let ends = array<f32, 6>(0.0, 0.0, 1.0, 0.0, 1.0, 1.0);
    let sides = array<f32, 6>(-1.0, 1.0, 1.0, -1.0, 1.0, -1.0);
    let end = ends[vi];
    var p = mix(pa, pb, end);
    // Square caps: half a width past each end, so joined segments leave no notch.
    let off_px = (normal * sides[vi] + dir * (end * 2.0 - 1.0)) * u.viewport.z * 0.5;
    p = vec4<f32>(p.xy + off_px / half_px * p.w, p.z, p.w);
    o.clip = p;
    o.color = mix(ca, cb, end);
    return o;
}

@fragment
fn fs_line(i: LineOut) -> @location(0) vec4<f32> {
    return i.color;
}

// The parts of lines that a surface hides: the same colour, fainter.
@fragment
fn fs_line_hidden(i: LineOut) -> @location(0) vec4<f32> {
    return vec4<f32>(i.color.rgb, i.color.a * u.viewport.w);
}
"#;

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

struct Target {
    size: [u32; 2],
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    texture_id: egui::TextureId,
}

/// The preview renderer; one per window.
pub struct Preview {
    mesh_pipeline: wgpu::RenderPipeline,
    /// The scene into the depth buffer only, for [`Backdrop::DepthOnly`].
    depth_only_pipeline: wgpu::RenderPipeline,
    /// Lines where they are in front of the scene.
    line_pipeline: wgpu::RenderPipeline,
    /// Lines where the scene hides them, faded.
    hidden_line_pipeline: wgpu::RenderPipeline,
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    mesh: Option<(wgpu::Buffer, u32, usize)>,
    /// The overlay's vertex buffer (none when there are no lines), its segment count and the
    /// version of the lines it holds.
    lines: Option<(Option<wgpu::Buffer>, u32, u64)>,
    target: Option<Target>,
}

/// What differs between the preview's pipelines.
#[derive(Clone)]
struct PipelineSpec<'a> {
    vs: &'static str,
    fs: &'static str,
    buffer: wgpu::VertexBufferLayout<'a>,
    depth_write: bool,
    depth_compare: wgpu::CompareFunction,
    write_mask: wgpu::ColorWrites,
}

/// The projection that matches the ray tracer's camera: local +z forward, screen right along
/// local -x, vertical field of view `fov_y`, wgpu's depth range [0, 1].
pub fn view_projection(camera: &Camera, aspect: f32, near: f32, far: f32) -> Mat4 {
    let h = (camera.fov_y.to_radians() * 0.5).tan();
    let world_to_local =
        Mat4::from_quat(camera.rotation.inverse()) * Mat4::from_translation(-Vec3::from(camera.position));
    let a = far / (far - near);
    let proj = Mat4::from_cols(
        Vec4::new(-1.0 / (h * aspect), 0.0, 0.0, 0.0),
        Vec4::new(0.0, 1.0 / h, 0.0, 0.0),
        Vec4::new(0.0, 0.0, a, 1.0),
        Vec4::new(0.0, 0.0, -a * near, 0.0),
    );
    proj * world_to_local
}

/// Near and far planes that hold the whole scene (and some room around it for rays).
pub fn depth_range(scene: &Scene, camera: &Camera) -> (f32, f32) {
    let (center, radius) = match scene.geometry.bvh.nodes.first() {
        Some(root) => {
            let b = root.bounds();
            (b.center(), (b.max - b.min).length().max(1e-3) * 0.5)
        }
        None => (Vec3A::ZERO, 1.0),
    };
    let d = camera.position.distance(center);
    let far = d + 4.0 * radius + 1.0;
    (far * 1e-5, far)
}

/// Triangles of the preview: every scene triangle with its face normal and material colour
/// (a texture's mean colour), and spheres tessellated.
pub fn scene_vertices(scene: &Scene) -> Vec<MeshVertex> {
    let color_of = |m: u32| {
        let mat = &scene.materials[m as usize];
        match mat.texture {
            Some(t) => {
                let tex = &scene.textures[t];
                tex.texels.iter().copied().sum::<glam::Vec3>() / tex.texels.len().max(1) as f32
            }
            None => mat.kd,
        }
        .to_array()
    };
    let mut out = Vec::with_capacity(scene.triangle_count() * 3);
    for p in 0..scene.triangle_count() as u32 {
        let v = scene.triangle_vertices(p).expect("triangles come first");
        let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero().to_array();
        let color = color_of(scene.material_of(p));
        out.extend(v.iter().map(|p| MeshVertex { pos: p.to_array(), normal: n, color }));
    }
    let (rings, segs) = (16, 32);
    for s in &scene.spheres {
        let c = s.center + s.motion.as_ref().map_or(Vec3A::ZERO, |m| m.start());
        let color = color_of(s.material);
        let point = |i: u32, j: u32| {
            let th = std::f32::consts::PI * i as f32 / rings as f32;
            let ph = std::f32::consts::TAU * j as f32 / segs as f32;
            Vec3A::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin())
        };
        for i in 0..rings {
            for j in 0..segs {
                let q = [point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1)];
                for k in [0, 1, 2, 0, 2, 3] {
                    let n = q[k];
                    out.push(MeshVertex { pos: (c + n * s.radius).to_array(), normal: n.to_array(), color });
                }
            }
        }
    }
    out
}

impl Preview {
    /// Create the pipelines on `device`.
    pub fn new(device: &wgpu::Device) -> Preview {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("rayscope preview"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("rayscope preview uniforms"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("rayscope preview"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("rayscope preview"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: uniforms.as_entire_binding() }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("rayscope preview"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |p: PipelineSpec<'_>| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(p.fs),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &shader,
                    entry_point: Some(p.vs),
                    compilation_options: Default::default(),
                    buffers: &[Some(p.buffer)],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(p.depth_write),
                    depth_compare: Some(p.depth_compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &shader,
                    entry_point: Some(p.fs),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: COLOR_FORMAT,
                        blend: Some(wgpu::BlendState::ALPHA_BLENDING),
                        write_mask: p.write_mask,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let mesh_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3];
        let mesh_buffer = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<MeshVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &mesh_attrs,
        };
        // A segment is two consecutive `LineVertex`es, read per instance.
        let line_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4, 2 => Float32x3, 3 => Float32x4];
        let line_buffer = wgpu::VertexBufferLayout {
            array_stride: 2 * std::mem::size_of::<LineVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &line_attrs,
        };
        let mesh = PipelineSpec {
            vs: "vs_mesh",
            fs: "fs_mesh",
            buffer: mesh_buffer.clone(),
            depth_write: true,
            depth_compare: wgpu::CompareFunction::LessEqual,
            write_mask: wgpu::ColorWrites::ALL,
        };
        let line = PipelineSpec {
            vs: "vs_line",
            fs: "fs_line",
            buffer: line_buffer,
            depth_write: false,
            depth_compare: wgpu::CompareFunction::LessEqual,
            write_mask: wgpu::ColorWrites::ALL,
        };
        let mesh_pipeline = pipeline(mesh.clone());
        let depth_only_pipeline = pipeline(PipelineSpec { write_mask: wgpu::ColorWrites::empty(), ..mesh });
        let line_pipeline = pipeline(line.clone());
        let hidden_line_pipeline =
            pipeline(PipelineSpec { fs: "fs_line_hidden", depth_compare: wgpu::CompareFunction::Greater, ..line });
        Preview {
            mesh_pipeline,
            depth_only_pipeline,
            line_pipeline,
            hidden_line_pipeline,
            uniforms,
            bind_group,
            mesh: None,
            lines: None,
            target: None,
        }
    }

    /// Draw `scene` (identified by `scene_key`, so its vertices upload once) and the overlay
    /// as seen by `camera` into a `size`-pixel texture, and return its egui texture id.
    pub fn render(
        &mut self,
        rs: &egui_wgpu::RenderState,
        scene: &Scene,
        scene_key: usize,
        camera: &Camera,
        size: [u32; 2],
        overlay: OverlayDraw<'_>,
    ) -> egui::TextureId {
        let OverlayDraw { lines, version, width_px, backdrop } = overlay;
        use wgpu::util::DeviceExt;
        let device = &rs.device;
        let size = [size[0].clamp(1, 8192), size[1].clamp(1, 8192)];
        if self.target.as_ref().is_none_or(|t| t.size != size) {
            let old = self.target.take().map(|t| t.texture_id);
            self.target = Some(self.make_target(rs, size, old));
        }
        if self.mesh.as_ref().is_none_or(|m| m.2 != scene_key) {
            let v = scene_vertices(scene);
            let buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("rayscope preview mesh"),
                contents: bytemuck::cast_slice(&v),
                usage: wgpu::BufferUsages::VERTEX,
            });
            self.mesh = Some((buf, v.len() as u32, scene_key));
        }
        if self.lines.as_ref().is_none_or(|l| l.2 != version) {
            let buf = (!lines.is_empty()).then(|| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("rayscope preview lines"),
                    contents: bytemuck::cast_slice(lines),
                    usage: wgpu::BufferUsages::VERTEX,
                })
            });
            self.lines = Some((buf, (lines.len() / 2) as u32, version));
        }
        let (near, far) = depth_range(scene, camera);
        let u = Uniforms {
            view_proj: view_projection(camera, size[0] as f32 / size[1] as f32, near, far).to_cols_array_2d(),
            eye: [camera.position.x, camera.position.y, camera.position.z, 1.0],
            viewport: [size[0] as f32, size[1] as f32, width_px.max(0.5), HIDDEN_ALPHA],
        };
        let clear = match backdrop {
            Backdrop::Scene => wgpu::Color { r: 0.06, g: 0.06, b: 0.07, a: 1.0 },
            Backdrop::DepthOnly | Backdrop::SceneOverMap => wgpu::Color::TRANSPARENT,
        };
        rs.queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&u));
        let target = self.target.as_ref().expect("made above");
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("rayscope preview") });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("rayscope preview"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target.color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Store },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &target.depth_view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            if let Some((buf, n, _)) = &self.mesh {
                pass.set_pipeline(match backdrop {
                    Backdrop::Scene | Backdrop::SceneOverMap => &self.mesh_pipeline,
                    Backdrop::DepthOnly => &self.depth_only_pipeline,
                });
                pass.set_vertex_buffer(0, buf.slice(..));
                pass.draw(0..*n, 0..1);
            }
            if let Some((Some(buf), n, _)) = &self.lines {
                pass.set_vertex_buffer(0, buf.slice(..));
                // Neither pass writes depth, and a fragment passes exactly one of the two tests.
                for pipeline in [&self.hidden_line_pipeline, &self.line_pipeline] {
                    pass.set_pipeline(pipeline);
                    pass.draw(0..6, 0..*n);
                }
            }
        }
        rs.queue.submit([encoder.finish()]);
        target.texture_id
    }

    fn make_target(&self, rs: &egui_wgpu::RenderState, size: [u32; 2], reuse: Option<egui::TextureId>) -> Target {
        let device = &rs.device;
        let extent = wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 };
        let texture = |format, usage, label| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: extent,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = texture(
            COLOR_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            "rayscope preview colour",
        );
        let depth = texture(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT, "rayscope preview depth");
        let color_view = color.create_view(&Default::default());
        let depth_view = depth.create_view(&Default::default());
        let mut renderer = rs.renderer.write();
        let texture_id = match reuse {
            Some(id) => {
                renderer.update_egui_texture_from_wgpu_texture(device, &color_view, wgpu::FilterMode::Linear, id);
                id
            }
            None => renderer.register_native_texture(device, &color_view, wgpu::FilterMode::Linear),
        };
        Target { size, color_view, depth_view, texture_id }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayscope::camera::CameraDesc;
    use rayscope::math::Vec2;

    #[test]
    fn projection_matches_the_ray_tracer() {
        // A point along the primary ray of a screen position projects back onto it.
        let cam = Camera::from_desc(&CameraDesc::default());
        let m = view_projection(&cam, 1.5, 0.01, 100.0);
        for ndc in [Vec2::new(0.3, -0.4), Vec2::new(-0.9, 0.8), Vec2::ZERO] {
            let ray = cam.ray(ndc, 1.5);
            let p = ray.at(2.5);
            let clip = m * Vec4::new(p.x, p.y, p.z, 1.0);
            let got = Vec2::new(clip.x / clip.w, clip.y / clip.w);
            assert!((got - ndc).length() < 1e-4, "{ndc} -> {got}");
            let z = clip.z / clip.w;
            assert!((0.0..=1.0).contains(&z));
        }
    }
}
