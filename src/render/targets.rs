//! The render targets a renderer keeps per frame size: MSAA colour and depth, the resolved
//! colour, and the readback buffer.

use super::error::RenderError;
use super::pipeline::{COLOUR_FORMAT, DEPTH_FORMAT, ID_FORMAT};

/// Render-target sizes a renderer keeps before it drops them all and starts again. Each
/// area of interest has its own size, and one target with its 4x MSAA colour and depth costs
/// about 11 MB on a software adapter: a dozen of them per renderer grew a camera batch by some
/// 0.8 MB a trial, to 480 MB at 200 trials (issue 17). Four hold the frame and the latest
/// windows; re-creating a target costs far less than rendering into it.
pub(super) const MAX_TARGET_SIZES: usize = 4;

/// A frame's render targets and readback buffer at one size.
pub(super) struct Targets {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) colour_msaa: Option<wgpu::TextureView>,
    pub(super) colour: wgpu::Texture,
    pub(super) colour_view: wgpu::TextureView,
    pub(super) depth: wgpu::TextureView,
    pub(super) readback: wgpu::Buffer,
    pub(super) padded_row: u32,
}

impl Targets {
    /// Targets of `w` x `h` for the shaded image (`ids` false) or the object ids, at `samples`
    /// samples; `adapter` names the device in errors.
    pub(super) fn new(
        device: &wgpu::Device,
        adapter: &str,
        w: u32,
        h: u32,
        ids: bool,
        samples: u32,
    ) -> Result<Self, RenderError> {
        let limit = device.limits().max_texture_dimension_2d;
        if w > limit || h > limit {
            return Err(RenderError::Unsupported {
                adapter: adapter.to_string(),
                reason: format!("a {w} x {h} target (largest side {limit})"),
            });
        }
        let size = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        let texture = |label: &str, format: wgpu::TextureFormat, samples: u32, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
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
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: u64::from(padded_row) * u64::from(h),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let colour_view = colour.create_view(&wgpu::TextureViewDescriptor::default());
        Ok(Self {
            width: w,
            height: h,
            colour_msaa,
            colour,
            colour_view,
            depth,
            readback,
            padded_row,
        })
    }
}
