//! The offscreen renderer: a wgpu device (GPU, or the software adapter when there is none),
//! MSAA colour and depth targets, a readback into an [`image::RgbImage`], and an object-id pass.

use std::collections::BTreeMap;
use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use image::{ImageBuffer, Luma, RgbImage};
use nalgebra::{Isometry3, Matrix4, Point3, Vector3};
use wgpu::util::DeviceExt;

use super::cull::{Bounds, View};
use super::error::RenderError;
use super::mesh::MeshVertex;
use super::scene::{ObjectKind, Scene, SceneObject};
use crate::perception::calibration::CameraCalibration;

/// Nearest depth drawn, m.
const NEAR_M: f64 = 0.02;
/// Farthest depth drawn, m.
const FAR_M: f64 = 20.0;
/// Most lights a frame may use.
pub const MAX_LIGHTS: usize = 4;
/// Most stain blobs a frame may use.
pub const MAX_STAIN_BLOBS: usize = 32;
/// Per-object uniforms are bound at multiples of this offset.
const OBJECT_STRIDE: u64 = 256;
const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
/// Render-target sizes a renderer keeps before it drops them all and starts again. Each
/// area of interest has its own size, and one target with its 4x MSAA colour and depth costs
/// about 11 MB on a software adapter: a dozen of them per renderer grew a camera batch by some
/// 0.8 MB a trial, to 480 MB at 200 trials (issue 17). Four hold the frame and the latest
/// windows; re-creating a target costs far less than rendering into it.
const MAX_TARGET_SIZES: usize = 4;

/// A directional light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Light {
    /// Direction the light travels, world frame, unit length.
    pub direction_in_world: Vector3<f64>,
    /// Intensity (1 lights a white surface facing it fully).
    pub intensity: f64,
}

/// A soft dark blob on a stainable surface: one lobe of an oil stain or a speck of dirt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StainBlob {
    /// Centre, world frame (on the surface).
    pub centre_in_world: Point3<f64>,
    /// Radius, m.
    pub radius_m: f64,
    /// Share of light the stain lets through at its core.
    pub transmission: f64,
    /// Share of the radius over which the stain fades out.
    pub soft_edge: f64,
}

/// Everything about one exposure besides the scene: the camera and the light on the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Exposure {
    /// The camera as it really stands (calibration plus any pose jitter).
    pub camera: CameraCalibration,
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
    /// Ambient light, a share of full light.
    pub ambient: f64,
    /// Directional lights (at most [`MAX_LIGHTS`]).
    pub lights: Vec<Light>,
    /// Stains and dirt (at most [`MAX_STAIN_BLOBS`]).
    pub stains: Vec<StainBlob>,
}

/// Options fixed for a renderer's life.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RendererOptions {
    /// MSAA samples per pixel: 1 or 4.
    pub msaa_samples: u32,
    /// Supersampling per axis (1 to 4) on top of MSAA.
    pub supersample: u32,
}

impl Default for RendererOptions {
    fn default() -> Self {
        Self {
            msaa_samples: 4,
            supersample: 1,
        }
    }
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuVertex {
    position: [f32; 3],
    normal: [f32; 3],
    albedo: [f32; 3],
    surface: [f32; 3],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Globals {
    clip_from_camera: [f32; 16],
    ambient: [f32; 4],
    light_dir: [[f32; 4]; MAX_LIGHTS],
    light_rgb: [[f32; 4]; MAX_LIGHTS],
    stain_centre: [[f32; 4]; MAX_STAIN_BLOBS],
    stain_params: [[f32; 4]; MAX_STAIN_BLOBS],
    counts: [u32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct ObjectUniform {
    camera_from_object: [f32; 16],
    id: [u32; 4],
    padding: [u32; 44],
}

/// A scene's meshes on the device: one vertex buffer, one draw range per object.
pub struct GpuScene {
    vertices: wgpu::Buffer,
    /// Each object's vertices: its plain triangles from `start` to `stained`, then its
    /// stainable ones up to `end`.
    ranges: Vec<ObjectRange>,
    /// Object indices, nearest kinds first, so early depth tests skip hidden fragments.
    draw_order: Vec<usize>,
    poses: Vec<Isometry3<f64>>,
    /// Each object's extent, for culling.
    bounds: Vec<Bounds>,
}

/// Where an object's vertices lie in a [`GpuScene`]'s buffer.
#[derive(Debug, Clone, Copy)]
struct ObjectRange {
    start: u32,
    stained: u32,
    end: u32,
}

impl GpuScene {
    /// Number of objects.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// Whether the scene has no objects.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// Updates object `index`'s pose (as the physics moves it) without re-uploading meshes.
    pub fn set_pose(&mut self, index: usize, world_from_object: Isometry3<f64>) {
        if let Some(pose) = self.poses.get_mut(index) {
            *pose = world_from_object;
        }
    }
}

/// The shading pipelines for one light count.
struct Shaded {
    /// Surfaces without stains.
    plain: wgpu::RenderPipeline,
    /// Stainable surfaces.
    stained: wgpu::RenderPipeline,
}

struct Targets {
    width: u32,
    height: u32,
    colour_msaa: Option<wgpu::TextureView>,
    colour: wgpu::Texture,
    colour_view: wgpu::TextureView,
    depth: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
}

/// The offscreen renderer.
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    options: RendererOptions,
    module: wgpu::ShaderModule,
    layout: wgpu::PipelineLayout,
    /// Shading pipelines by light count, built when a count is first used.
    shaded: BTreeMap<usize, Shaded>,
    ids: wgpu::RenderPipeline,
    globals: wgpu::Buffer,
    globals_group: wgpu::BindGroup,
    object_layout: wgpu::BindGroupLayout,
    objects: Option<(wgpu::Buffer, wgpu::BindGroup, usize)>,
    targets: BTreeMap<(u32, u32, bool), Targets>,
}

impl Renderer {
    /// Opens the first adapter wgpu offers (a GPU when there is one, else a software adapter)
    /// and builds the pipelines. `WGPU_BACKEND` (gl, vulkan) narrows the choice.
    pub fn new(options: RendererOptions) -> Result<Self, RenderError> {
        if !matches!(options.msaa_samples, 1 | 4) || !(1..=4).contains(&options.supersample) {
            return Err(RenderError::Unsupported {
                adapter: String::new(),
                reason: format!(
                    "msaa_samples {} (1 or 4), supersample {} (1 to 4)",
                    options.msaa_samples, options.supersample
                ),
            });
        }
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| RenderError::NoAdapter {
            reason: e.to_string(),
        })?;
        let info = adapter.get_info();
        let device_error = |reason: String| RenderError::Device {
            adapter: info.name.clone(),
            backend: info.backend.to_string(),
            reason,
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("twincell camera"),
            required_features: wgpu::Features::empty(),
            required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| device_error(e.to_string()))?;
        for format in [COLOUR_FORMAT, DEPTH_FORMAT] {
            let flags = adapter.get_texture_format_features(format).flags;
            if !flags.sample_count_supported(options.msaa_samples) {
                return Err(RenderError::Unsupported {
                    adapter: info.name.clone(),
                    reason: format!("{}x MSAA on {format:?}", options.msaa_samples),
                });
            }
        }
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("camera shader"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shader.wgsl").into()),
        });
        let uniform_entry = |dynamic: bool| wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: dynamic,
                min_binding_size: None,
            },
            count: None,
        };
        let globals_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("globals"),
            entries: &[uniform_entry(false)],
        });
        let object_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("object"),
            entries: &[uniform_entry(true)],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("camera"),
            bind_group_layouts: &[Some(&globals_layout), Some(&object_layout)],
            immediate_size: 0,
        });
        let ids = build_pipeline(&device, &module, &layout, "fs_id", ID_FORMAT, 1, 0);
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("globals"),
            size: std::mem::size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let globals_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("globals"),
            layout: &globals_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: globals.as_entire_binding(),
            }],
        });
        Ok(Self {
            device,
            queue,
            info,
            options,
            module,
            layout,
            shaded: BTreeMap::new(),
            ids,
            globals,
            globals_group,
            object_layout,
            objects: None,
            targets: BTreeMap::new(),
        })
    }

    /// The adapter's name and backend, e.g. `llvmpipe (LLVM 15.0.7, 256 bits) (Gl)`.
    pub fn adapter_name(&self) -> String {
        format!("{} ({:?})", self.info.name, self.info.backend)
    }

    /// The adapter's description from wgpu.
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.info
    }

    /// The options the renderer was built with.
    pub fn options(&self) -> RendererOptions {
        self.options
    }

    /// Uploads a scene's meshes.
    pub fn upload(&self, scene: &Scene) -> GpuScene {
        let mut vertices = Vec::with_capacity(scene.triangle_count() * 3);
        let mut ranges = Vec::with_capacity(scene.objects.len());
        let mut bounds = Vec::with_capacity(scene.objects.len());
        for object in &scene.objects {
            let start = vertices.len() as u32;
            // Plain triangles first, then the stainable ones (a triangle has one material).
            let mut stained = start;
            for stainable in [false, true] {
                stained = vertices.len() as u32;
                for triangle in object.mesh.vertices.chunks_exact(3) {
                    if triangle[0].material.stainable == stainable {
                        vertices.extend(triangle.iter().map(gpu_vertex));
                    }
                }
            }
            ranges.push(ObjectRange {
                start,
                stained,
                end: vertices.len() as u32,
            });
            bounds.push(Bounds::of(&object.mesh.vertices));
        }
        // Front to back for a camera above the belt: parts and the bottle, the robot, the belt,
        // then the rest (frame, bins, floor). Software rasterisers shade far less this way.
        let rank = |object: &SceneObject| match object.kind {
            ObjectKind::Part(_) | ObjectKind::Bottle => 0,
            ObjectKind::Scenery if object.name == "belt" => 2,
            ObjectKind::Scenery if object.name == "scenery" => 3,
            ObjectKind::Scenery => 1,
        };
        let mut draw_order: Vec<usize> = (0..scene.objects.len()).collect();
        draw_order.sort_by_key(|&i| rank(&scene.objects[i]));
        if vertices.is_empty() {
            vertices.push(GpuVertex::zeroed());
        }
        let buffer = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("scene vertices"),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::VERTEX,
            });
        GpuScene {
            vertices: buffer,
            ranges,
            draw_order,
            poses: scene.objects.iter().map(|o| o.world_from_object).collect(),
            bounds,
        }
    }

    /// Renders `scene` as `exposure` sees it and reads the image back.
    pub fn render(
        &mut self,
        scene: &GpuScene,
        exposure: &Exposure,
    ) -> Result<RgbImage, RenderError> {
        let s = self.options.supersample;
        let (w, h) = (exposure.width_px * s, exposure.height_px * s);
        let visible = self.prepare(scene, exposure)?;
        let samples = self.options.msaa_samples;
        self.ensure_targets(w, h, false, samples)?;
        let lights = exposure.lights.len();
        if !self.shaded.contains_key(&lights) {
            let build = |entry| {
                build_pipeline(
                    &self.device,
                    &self.module,
                    &self.layout,
                    entry,
                    COLOUR_FORMAT,
                    samples,
                    lights,
                )
            };
            let shaded = Shaded {
                plain: build("fs_main"),
                stained: build("fs_stained"),
            };
            self.shaded.insert(lights, shaded);
        }
        let (Some(targets), Some(shaded)) =
            (self.targets.get(&(w, h, false)), self.shaded.get(&lights))
        else {
            return Err(RenderError::Gpu("render targets missing".into()));
        };
        let (view, resolve) = match &targets.colour_msaa {
            Some(msaa) => (msaa, Some(&targets.colour_view)),
            None => (&targets.colour_view, None),
        };
        let (width, height) = (exposure.width_px, exposure.height_px);
        let frame = Frame {
            scene,
            visible: &visible,
            targets,
            view,
            resolve,
        };
        self.draw_and_read(&frame, Pipelines::Shaded(shaded), |rgba| {
            let row = targets.padded_row as usize;
            let mut image = RgbImage::new(width, height);
            if s == 1 {
                let width = width as usize;
                for (out_row, in_row) in image.chunks_exact_mut(width * 3).zip(rgba.chunks(row)) {
                    for (out, px) in out_row.chunks_exact_mut(3).zip(in_row.chunks_exact(4)) {
                        out.copy_from_slice(&px[..3]);
                    }
                }
                return image;
            }
            let norm = 1.0 / f64::from(s * s);
            for (x, y, pixel) in image.enumerate_pixels_mut() {
                let mut sum = [0u32; 3];
                for dy in 0..s {
                    let base = ((y * s + dy) as usize) * row;
                    for dx in 0..s {
                        let i = base + ((x * s + dx) as usize) * 4;
                        for c in 0..3 {
                            sum[c] += u32::from(rgba[i + c]);
                        }
                    }
                }
                pixel.0 = sum.map(|v| (f64::from(v) * norm).round() as u8);
            }
            image
        })
    }

    /// Renders which object covers each pixel centre (no anti-aliasing): the object's index in
    /// the scene plus one, 0 where nothing was drawn.
    pub fn render_ids(
        &mut self,
        scene: &GpuScene,
        exposure: &Exposure,
    ) -> Result<ImageBuffer<Luma<u32>, Vec<u32>>, RenderError> {
        let (w, h) = (exposure.width_px, exposure.height_px);
        let visible = self.prepare(scene, exposure)?;
        self.ensure_targets(w, h, true, 1)?;
        let Some(targets) = self.targets.get(&(w, h, true)) else {
            return Err(RenderError::Gpu("render targets missing".into()));
        };
        let frame = Frame {
            scene,
            visible: &visible,
            targets,
            view: &targets.colour_view,
            resolve: None,
        };
        self.draw_and_read(&frame, Pipelines::Ids(&self.ids), |bytes| {
            let row = targets.padded_row as usize;
            let mut ids: ImageBuffer<Luma<u32>, Vec<u32>> = ImageBuffer::new(w, h);
            for (x, y, pixel) in ids.enumerate_pixels_mut() {
                let i = y as usize * row + x as usize * 4;
                pixel.0 = [u32::from_le_bytes([
                    bytes[i],
                    bytes[i + 1],
                    bytes[i + 2],
                    bytes[i + 3],
                ])];
            }
            ids
        })
    }

    /// Writes the frame's and the objects' uniforms; returns the objects the camera may see
    /// (in its view frustum and not hidden behind a convex occluder), in drawing order.
    fn prepare(
        &mut self,
        scene: &GpuScene,
        exposure: &Exposure,
    ) -> Result<Vec<usize>, RenderError> {
        if exposure.lights.len() > MAX_LIGHTS || exposure.stains.len() > MAX_STAIN_BLOBS {
            return Err(RenderError::Unsupported {
                adapter: self.info.name.clone(),
                reason: format!(
                    "{} lights and {} stain blobs (at most {MAX_LIGHTS} and {MAX_STAIN_BLOBS})",
                    exposure.lights.len(),
                    exposure.stains.len()
                ),
            });
        }
        let camera = &exposure.camera;
        let camera_from_world = camera.world_from_camera.inverse();
        let mut globals = Globals::zeroed();
        globals.clip_from_camera = clip_from_camera(camera, exposure.width_px, exposure.height_px);
        let a = exposure.ambient as f32;
        globals.ambient = [a, a, a, 1.0];
        for (i, light) in exposure.lights.iter().enumerate() {
            let towards = -(camera_from_world.rotation * light.direction_in_world).normalize();
            globals.light_dir[i] = [towards.x as f32, towards.y as f32, towards.z as f32, 0.0];
            let e = light.intensity as f32;
            globals.light_rgb[i] = [e, e, e, 1.0];
        }
        for (i, stain) in exposure.stains.iter().enumerate() {
            let c = camera_from_world * stain.centre_in_world;
            globals.stain_centre[i] = [c.x as f32, c.y as f32, c.z as f32, stain.radius_m as f32];
            globals.stain_params[i] = [stain.transmission as f32, stain.soft_edge as f32, 0.0, 0.0];
        }
        globals.counts = [0, exposure.stains.len() as u32, 0, 0];
        self.queue
            .write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));

        let count = scene.poses.len().max(1);
        if self.objects.as_ref().is_none_or(|(_, _, n)| *n < count) {
            let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("objects"),
                size: OBJECT_STRIDE * count as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let group =
                self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("objects"),
                    layout: &self.object_layout,
                    entries: &[wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &buffer,
                            offset: 0,
                            size: std::num::NonZeroU64::new(
                                std::mem::size_of::<ObjectUniform>() as u64
                            ),
                        }),
                    }],
                });
            self.objects = Some((buffer, group, count));
        }
        let camera_from_object: Vec<Isometry3<f64>> = scene
            .poses
            .iter()
            .map(|world_from_object| camera_from_world * world_from_object)
            .collect();
        let uniforms: Vec<ObjectUniform> = camera_from_object
            .iter()
            .enumerate()
            .map(|(i, pose)| {
                let mut matrix = [0.0f32; 16];
                matrix.copy_from_slice(pose.to_homogeneous().cast::<f32>().as_slice());
                ObjectUniform {
                    camera_from_object: matrix,
                    id: [i as u32 + 1, 0, 0, 0],
                    padding: [0; 44],
                }
            })
            .collect();
        if let Some((buffer, _, _)) = &self.objects
            && !uniforms.is_empty()
        {
            self.queue
                .write_buffer(buffer, 0, bytemuck::cast_slice(&uniforms));
        }
        let view = View::new(camera, exposure.width_px, exposure.height_px, NEAR_M, FAR_M);
        Ok(view.visible(&scene.bounds, &camera_from_object, &scene.draw_order))
    }

    fn ensure_targets(
        &mut self,
        w: u32,
        h: u32,
        ids: bool,
        samples: u32,
    ) -> Result<(), RenderError> {
        if self.targets.contains_key(&(w, h, ids)) {
            return Ok(());
        }
        // Areas of interest come in many sizes: keep a bounded set of targets.
        if self.targets.len() >= MAX_TARGET_SIZES {
            self.targets.clear();
        }
        let limit = self.device.limits().max_texture_dimension_2d;
        if w > limit || h > limit {
            return Err(RenderError::Unsupported {
                adapter: self.info.name.clone(),
                reason: format!("a {w} x {h} target (largest side {limit})"),
            });
        }
        let size = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        let texture = |label: &str, format: wgpu::TextureFormat, samples: u32, usage| {
            self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let format = if ids { ID_FORMAT } else { COLOUR_FORMAT };
        let attachment = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let colour = texture(
            "colour",
            format,
            1,
            attachment | wgpu::TextureUsages::COPY_SRC,
        );
        let colour_msaa = (samples > 1).then(|| {
            texture("colour msaa", format, samples, attachment)
                .create_view(&wgpu::TextureViewDescriptor::default())
        });
        let depth = texture("depth", DEPTH_FORMAT, samples, attachment)
            .create_view(&wgpu::TextureViewDescriptor::default());
        let padded_row = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: u64::from(padded_row) * u64::from(h),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let colour_view = colour.create_view(&wgpu::TextureViewDescriptor::default());
        self.targets.insert(
            (w, h, ids),
            Targets {
                width: w,
                height: h,
                colour_msaa,
                colour,
                colour_view,
                depth,
                readback,
                padded_row,
            },
        );
        Ok(())
    }

    /// Draws a frame, copies its colour target out and hands the mapped rows (`padded_row`
    /// bytes apart) to `read`.
    fn draw_and_read<T>(
        &self,
        frame: &Frame,
        pipelines: Pipelines,
        read: impl FnOnce(&[u8]) -> T,
    ) -> Result<T, RenderError> {
        let Some((_, object_group, _)) = &self.objects else {
            return Err(RenderError::Gpu("object uniforms missing".into()));
        };
        let (scene, targets) = (frame.scene, frame.targets);
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("frame"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: frame.view,
                    depth_slice: None,
                    resolve_target: frame.resolve,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        // Only the resolved image is read.
                        store: if frame.resolve.is_some() {
                            wgpu::StoreOp::Discard
                        } else {
                            wgpu::StoreOp::Store
                        },
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &self.globals_group, &[]);
            pass.set_vertex_buffer(0, scene.vertices.slice(..));
            let mut draw = |pipeline: &wgpu::RenderPipeline,
                            part: fn(&ObjectRange) -> Range<u32>| {
                pass.set_pipeline(pipeline);
                for &i in frame.visible {
                    let range = part(&scene.ranges[i]);
                    if !range.is_empty() {
                        pass.set_bind_group(1, object_group, &[(i as u64 * OBJECT_STRIDE) as u32]);
                        pass.draw(range, 0..1);
                    }
                }
            };
            match pipelines {
                Pipelines::Shaded(shaded) => {
                    // Stainable end faces lie nearest the camera: first, for the depth test.
                    draw(&shaded.stained, |r| r.stained..r.end);
                    draw(&shaded.plain, |r| r.start..r.stained);
                }
                Pipelines::Ids(ids) => draw(ids, |r| r.start..r.end),
            }
        }
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &targets.colour,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &targets.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(targets.padded_row),
                    rows_per_image: Some(targets.height),
                },
            },
            wgpu::Extent3d {
                width: targets.width,
                height: targets.height,
                depth_or_array_layers: 1,
            },
        );
        self.queue.submit([encoder.finish()]);
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(error.to_string()));
        }
        let slice = targets.readback.slice(..);
        let (sender, receiver) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |result| {
            let _ = sender.send(result);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        match receiver.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(RenderError::Readback(e.to_string())),
            Err(e) => return Err(RenderError::Readback(e.to_string())),
        }
        let result = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| RenderError::Readback(e.to_string()))?;
            read(&view)
        };
        targets.readback.unmap();
        Ok(result)
    }
}

/// One frame to draw: the scene, the objects in view, the targets and the views drawn into.
struct Frame<'a> {
    scene: &'a GpuScene,
    visible: &'a [usize],
    targets: &'a Targets,
    view: &'a wgpu::TextureView,
    resolve: Option<&'a wgpu::TextureView>,
}

/// The pipelines a frame is drawn with.
enum Pipelines<'a> {
    /// The shaded image.
    Shaded(&'a Shaded),
    /// Object ids.
    Ids(&'a wgpu::RenderPipeline),
}

/// The clip-space projection that puts a camera-frame point where `camera.project` puts it:
/// pixel centres at integers map to framebuffer coordinates `u + 0.5`.
fn clip_from_camera(camera: &CameraCalibration, width_px: u32, height_px: u32) -> [f32; 16] {
    let (w, h) = (f64::from(width_px), f64::from(height_px));
    let depth_scale = FAR_M / (FAR_M - NEAR_M);
    #[rustfmt::skip]
    let m = Matrix4::new(
        2.0 * camera.fx_px / w, 0.0, 2.0 * (camera.cx_px + 0.5) / w - 1.0, 0.0,
        0.0, -2.0 * camera.fy_px / h, 1.0 - 2.0 * (camera.cy_px + 0.5) / h, 0.0,
        0.0, 0.0, depth_scale, -depth_scale * NEAR_M,
        0.0, 0.0, 1.0, 0.0,
    );
    let mut out = [0.0f32; 16];
    out.copy_from_slice(m.cast::<f32>().as_slice());
    out
}

/// A render pipeline of the camera shader: fragment entry `entry` into `format` at `samples`
/// samples, the shader's light loop fixed at `light_count`. Back faces are culled: every mesh
/// is closed with outward, counter-clockwise faces, so a back face is always hidden.
fn build_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    entry: &str,
    format: wgpu::TextureFormat,
    samples: u32,
    light_count: usize,
) -> wgpu::RenderPipeline {
    let attributes =
        wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x3];
    let constants = [("LIGHT_COUNT", light_count as f64)];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(entry),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<GpuVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &attributes,
            })],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: Some(wgpu::Face::Back),
            ..wgpu::PrimitiveState::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState {
            count: samples,
            mask: !0,
            alpha_to_coverage_enabled: false,
        },
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                ..wgpu::PipelineCompilationOptions::default()
            },
            targets: &[Some(wgpu::ColorTargetState {
                format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

fn gpu_vertex(v: &MeshVertex) -> GpuVertex {
    let m = v.material;
    GpuVertex {
        position: [
            v.position.x as f32,
            v.position.y as f32,
            v.position.z as f32,
        ],
        normal: [v.normal.x as f32, v.normal.y as f32, v.normal.z as f32],
        albedo: m.albedo,
        surface: [m.specular, m.shininess, m.sheen],
    }
}
