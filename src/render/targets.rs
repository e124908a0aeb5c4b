//! The render targets a renderer keeps per frame size: MSAA colour and depth, the resolved
//! colour, and the readback buffer.

use std::collections::BTreeMap;

use image::RgbImage;

use super::error::RenderError;
use super::pipeline::{COLOUR_FORMAT, DEPTH_FORMAT, ID_FORMAT};

/// Render-target size classes a renderer keeps before it drops them all and starts again.
/// Each area of interest has its own size; a target is made at the size's class (each side
/// rounded up to [`SIZE_CLASS_PX`]) and a smaller image is drawn into its top-left corner, so
/// the few classes a camera uses stay allocated for the renderer's life (a target is about
/// 11 MB with 4x MSAA colour and depth on a software adapter, so one per exact size grows
/// memory trial by trial).
pub(super) const MAX_TARGET_SIZES: usize = 8;

/// The step target sides are rounded up to.
pub(super) const SIZE_CLASS_PX: u32 = 256;

/// The size class holding a `w` x `h` image: each side rounded up to [`SIZE_CLASS_PX`], but
/// no larger than `limit` (a side over the limit is refused by [`Targets::new`]).
pub(super) fn size_class(w: u32, h: u32, limit: u32) -> (u32, u32) {
    let side = |v: u32| {
        v.div_ceil(SIZE_CLASS_PX)
            .saturating_mul(SIZE_CLASS_PX)
            .min(limit)
            .max(v)
    };
    (side(w), side(h))
}

/// Bytes of one row of a `w`-pixel image in a readback buffer (4 bytes a pixel, rows aligned
/// as texture copies require).
pub(super) fn padded_row(w: u32) -> u32 {
    (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

/// The `width` x `height` RGB image in mapped RGBA rows `row` bytes apart, each image pixel the
/// rounded mean of `s` x `s` target pixels (supersampling; `s` = 1 copies).
pub(super) fn rgb_from_rgba(
    rgba: &[u8],
    row: usize,
    (width, height): (u32, u32),
    s: u32,
) -> RgbImage {
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
}

/// The targets a renderer keeps, by size class, kind (shaded or ids) and samples per pixel.
#[derive(Default)]
pub(super) struct TargetCache {
    targets: BTreeMap<ClassKey, Targets>,
    allocations: u64,
}

/// A key of [`TargetCache`]: a size class, whether the targets hold object ids, and the samples
/// per pixel.
pub(super) type ClassKey = (u32, u32, bool, u32);

impl TargetCache {
    /// Makes sure targets of the size class holding a `w` x `h` image of the kind `ids` exist
    /// (`size` is `(w, h, ids)`), with `samples` samples, and returns the class's key.
    pub(super) fn ensure(
        &mut self,
        device: &wgpu::Device,
        adapter: &str,
        size: (u32, u32, bool),
        samples: u32,
    ) -> Result<ClassKey, RenderError> {
        let (w, h, ids) = size;
        let (cw, ch) = size_class(w, h, device.limits().max_texture_dimension_2d);
        let key = (cw, ch, ids, samples);
        if self.targets.contains_key(&key) {
            return Ok(key);
        }
        // A bound on the classes, should a caller use very many.
        if self.targets.len() >= MAX_TARGET_SIZES {
            self.targets.clear();
        }
        let targets = Targets::new(device, adapter, cw, ch, ids, samples)?;
        self.targets.insert(key, targets);
        self.allocations += 1;
        Ok(key)
    }

    /// The targets of a class [`TargetCache::ensure`] returned.
    pub(super) fn get(&self, key: ClassKey) -> Option<&Targets> {
        self.targets.get(&key)
    }

    /// How many targets have been made.
    pub(super) fn allocations(&self) -> u64 {
        self.allocations
    }
}

/// A frame's render targets and readback buffer at one size class: a smaller image is drawn
/// into its top-left corner.
pub(super) struct Targets {
    pub(super) colour_msaa: Option<wgpu::TextureView>,
    pub(super) colour: wgpu::Texture,
    pub(super) colour_view: wgpu::TextureView,
    pub(super) depth: wgpu::TextureView,
    pub(super) readback: wgpu::Buffer,
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
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: u64::from(padded_row(w)) * u64::from(h),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let colour_view = colour.create_view(&wgpu::TextureViewDescriptor::default());
        Ok(Self {
            colour_msaa,
            colour,
            colour_view,
            depth,
            readback,
        })
    }
}
