//! The GPU side of the camera shader: vertex and uniform layouts, the projection, and the
//! render pipelines.

use bytemuck::{Pod, Zeroable};
use nalgebra::Matrix4;

use super::exposure::{MAX_LIGHTS, MAX_STAIN_BLOBS};
use super::mesh::MeshVertex;
use crate::camera::CameraCalibration;

/// Nearest depth drawn, m.
pub(super) const NEAR_M: f64 = 0.02;
/// Farthest depth drawn, m.
pub(super) const FAR_M: f64 = 20.0;
/// Per-object uniforms are bound at multiples of this offset.
pub(super) const OBJECT_STRIDE: u64 = 256;
/// The shaded image's format.
pub(super) const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// The depth buffer's format.
pub(super) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The object-id image's format.
pub(super) const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(super) struct GpuVertex {
    pub(super) position: [f32; 3],
    pub(super) normal: [f32; 3],
    pub(super) albedo: [f32; 3],
    pub(super) surface: [f32; 3],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(super) struct Globals {
    pub(super) clip_from_camera: [f32; 16],
    pub(super) ambient: [f32; 4],
    pub(super) light_dir: [[f32; 4]; MAX_LIGHTS],
    pub(super) light_rgb: [[f32; 4]; MAX_LIGHTS],
    pub(super) stain_centre: [[f32; 4]; MAX_STAIN_BLOBS],
    pub(super) stain_params: [[f32; 4]; MAX_STAIN_BLOBS],
    pub(super) counts: [u32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(super) struct ObjectUniform {
    pub(super) camera_from_object: [f32; 16],
    pub(super) id: [u32; 4],
    pub(super) padding: [u32; 44],
}

/// The clip-space projection that puts a camera-frame point where `camera.project` puts it:
/// pixel centres at integers map to framebuffer coordinates `u + 0.5`.
pub(super) fn clip_from_camera(
    camera: &CameraCalibration,
    width_px: u32,
    height_px: u32,
) -> [f32; 16] {
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
pub(super) fn build_pipeline(
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

pub(super) fn gpu_vertex(v: &MeshVertex) -> GpuVertex {
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
