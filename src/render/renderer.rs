//! The offscreen renderer: a wgpu device (GPU, or the software adapter when there is none),
//! MSAA colour and depth targets, a readback into an [`image::RgbImage`], and an object-id pass.

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::{Arc, Mutex, PoisonError};

use bytemuck::Zeroable;
use image::{ImageBuffer, Luma, RgbImage};
use nalgebra::Isometry3;
use wgpu::util::DeviceExt;

use super::cull::{Bounds, View};
use super::error::RenderError;
pub use super::exposure::{
    Exposure, Light, MAX_LIGHTS, MAX_STAIN_BLOBS, RendererOptions, StainBlob,
};
pub use super::gpu_scene::GpuScene;
use super::gpu_scene::ObjectRange;
use super::pipeline::{
    COLOUR_FORMAT, DEPTH_FORMAT, Globals, GpuVertex, ID_FORMAT, OBJECT_STRIDE, ObjectUniform,
    build_pipeline, clip_from_camera, gpu_vertex,
};
use super::scene::{ObjectKind, Scene, SceneObject};
use super::targets::{TargetCache, Targets, padded_row, rgb_from_rgba};

mod sibling;

/// The shading pipelines for one light count.
#[derive(Clone)]
struct Shaded {
    /// Surfaces without stains.
    plain: wgpu::RenderPipeline,
    /// Stainable surfaces.
    stained: wgpu::RenderPipeline,
}

/// The offscreen renderer.
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    options: RendererOptions,
    module: wgpu::ShaderModule,
    layout: wgpu::PipelineLayout,
    /// Shading pipelines by light count and samples per pixel, built when first used by this
    /// renderer or a sibling ([`Renderer::sibling`]).
    shaded: Arc<Mutex<BTreeMap<(usize, u32), Shaded>>>,
    ids: wgpu::RenderPipeline,
    globals_layout: wgpu::BindGroupLayout,
    globals: wgpu::Buffer,
    globals_group: wgpu::BindGroup,
    object_layout: wgpu::BindGroupLayout,
    objects: Option<(wgpu::Buffer, wgpu::BindGroup, usize)>,
    targets: TargetCache,
    /// Held (by this renderer or a sibling) while the device is used: see [`Self::hold_device`].
    device_lock: Arc<Mutex<()>>,
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
        let (globals, globals_group) = sibling::globals_binding(&device, &globals_layout);
        Ok(Self {
            device,
            queue,
            info,
            options,
            module,
            layout,
            shaded: Arc::default(),
            ids,
            globals_layout,
            globals,
            globals_group,
            object_layout,
            objects: None,
            targets: TargetCache::default(),
            device_lock: Arc::default(),
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
        let _device = self.hold_device();
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
        self.render_sampled(scene, exposure, self.options.msaa_samples)
    }

    /// [`Self::render`] with one sample per pixel whatever the renderer's MSAA: for an image
    /// whose reader averages blocks of pixels anyway (the detector's frame), where the samples
    /// would cost more than half of the frame's time and change little of what is read.
    pub fn render_single_sample(
        &mut self,
        scene: &GpuScene,
        exposure: &Exposure,
    ) -> Result<RgbImage, RenderError> {
        self.render_sampled(scene, exposure, 1)
    }

    /// Renders at `samples` samples per pixel (1 or the renderer's MSAA count).
    fn render_sampled(
        &mut self,
        scene: &GpuScene,
        exposure: &Exposure,
        samples: u32,
    ) -> Result<RgbImage, RenderError> {
        let s = self.options.supersample;
        let (w, h) = (exposure.width_px * s, exposure.height_px * s);
        let device_lock = Arc::clone(&self.device_lock);
        let _device = device_lock.lock().unwrap_or_else(PoisonError::into_inner);
        let visible = self.prepare(scene, exposure)?;
        let class = self
            .targets
            .ensure(&self.device, &self.info.name, (w, h, false), samples)?;
        let lights = exposure.lights.len();
        let shaded = {
            let mut built = self.shaded.lock().unwrap_or_else(PoisonError::into_inner);
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
            built
                .entry((lights, samples))
                .or_insert_with(|| Shaded {
                    plain: build("fs_main"),
                    stained: build("fs_stained"),
                })
                .clone()
        };
        let Some(targets) = self.targets.get(class) else {
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
            size: (w, h),
            view,
            resolve,
        };
        self.draw_and_read(&frame, Pipelines::Shaded(&shaded), |rgba| {
            rgb_from_rgba(rgba, padded_row(w) as usize, (width, height), s)
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
        let device_lock = Arc::clone(&self.device_lock);
        let _device = device_lock.lock().unwrap_or_else(PoisonError::into_inner);
        let visible = self.prepare(scene, exposure)?;
        let class = self
            .targets
            .ensure(&self.device, &self.info.name, (w, h, true), 1)?;
        let Some(targets) = self.targets.get(class) else {
            return Err(RenderError::Gpu("render targets missing".into()));
        };
        let frame = Frame {
            scene,
            visible: &visible,
            targets,
            size: (w, h),
            view: &targets.colour_view,
            resolve: None,
        };
        self.draw_and_read(&frame, Pipelines::Ids(&self.ids), |bytes| {
            let row = padded_row(w) as usize;
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
        let view = View::of_exposure(exposure);
        Ok(view.visible(&scene.bounds, &camera_from_object, &scene.draw_order))
    }

    /// How many render targets this renderer has made so far (each size class once while the
    /// renderer keeps it).
    pub fn target_allocations(&self) -> u64 {
        self.targets.allocations()
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
        let (w, h) = frame.size;
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
            // The image fills the target's top-left w x h; the pixels beyond are not read.
            pass.set_viewport(0.0, 0.0, w as f32, h as f32, 0.0, 1.0);
            pass.set_scissor_rect(0, 0, w, h);
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
                    bytes_per_row: Some(padded_row(w)),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        self.queue.submit([encoder.finish()]);
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(error.to_string()));
        }
        let slice = targets
            .readback
            .slice(..u64::from(padded_row(w)) * u64::from(h));
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
    /// The image's size, at most the targets' class.
    size: (u32, u32),
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
