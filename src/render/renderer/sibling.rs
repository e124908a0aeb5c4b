//! Renderers that share one device: a second worker's renderer made on the first one's device
//! draws with the same compiled pipelines.
//!
//! On the software adapter (llvmpipe over wgpu's GL backend) each device is a GL context, and
//! llvmpipe compiles (LLVM) a pipeline's shaders for each context at its first draw: about 0.85 G
//! instructions a context for the camera's pipelines, once more for every worker thread that
//! made its own renderer (callgrind, paper_50 camera, `--jobs 2`). A sibling shares the device,
//! the queue and the pipelines, so they compile once per process; it has its own uniform
//! buffers and render targets. Siblings take turns at the device: each upload and render holds
//! the family's lock ([`Renderer::hold_device`]), for wgpu's GL backend gives up (panics) on a
//! thread that waits for its context longer than a few seconds, as one could behind several
//! renders. Images do not depend on which sibling drew them.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use super::{Globals, RenderError, Renderer, RendererOptions, TargetCache};

/// The first renderer this process made for each set of options ([`Renderer::shared`]); never
/// lent out, only its siblings are.
static FIRST: Mutex<Vec<(RendererOptions, Renderer)>> = Mutex::new(Vec::new());

/// A uniform buffer for a frame's [`Globals`] and its bind group in `layout`.
pub(super) fn globals_binding(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
) -> (wgpu::Buffer, wgpu::BindGroup) {
    let globals = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("globals"),
        size: std::mem::size_of::<Globals>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("globals"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: globals.as_entire_binding(),
        }],
    });
    (globals, group)
}

impl Renderer {
    /// A renderer with `options` on the process's device for them: a sibling of the first
    /// renderer made with these options, made on the first call. A batch's camera pipeline, and
    /// each of a suite's, draw on one device and compile the shaders once.
    pub fn shared(options: RendererOptions) -> Result<Self, RenderError> {
        let mut first = FIRST.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((_, renderer)) = first.iter().find(|(o, _)| *o == options) {
            return Ok(renderer.sibling());
        }
        let renderer = Self::new(options)?;
        let sibling = renderer.sibling();
        first.push((options, renderer));
        Ok(sibling)
    }

    /// A renderer on this one's device and with its pipelines (those built so far and those
    /// either builds later), but its own uniforms and render targets: for another thread, without
    /// a second device or a second compilation of the shaders (see the module docs).
    pub fn sibling(&self) -> Self {
        let (globals, globals_group) = globals_binding(&self.device, &self.globals_layout);
        Self {
            device: self.device.clone(),
            queue: self.queue.clone(),
            info: self.info.clone(),
            options: self.options,
            module: self.module.clone(),
            layout: self.layout.clone(),
            shaded: Arc::clone(&self.shaded),
            ids: self.ids.clone(),
            globals_layout: self.globals_layout.clone(),
            globals,
            globals_group,
            object_layout: self.object_layout.clone(),
            objects: None,
            targets: TargetCache::default(),
            device_lock: Arc::clone(&self.device_lock),
        }
    }

    /// Holds the device for this renderer and its siblings until the guard drops: for dropping a
    /// [`super::GpuScene`] (which frees device memory) where a sibling may be drawing. Uploads and
    /// renders hold it themselves; holding it around one of them deadlocks.
    pub fn hold_device(&self) -> MutexGuard<'_, ()> {
        self.device_lock
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }
}
