//! A scene's meshes uploaded to the device, with the poses and bounds a frame draws them by.

use nalgebra::Isometry3;

use super::cull::Bounds;

/// A scene's meshes on the device: one vertex buffer, one draw range per object.
pub struct GpuScene {
    pub(super) vertices: wgpu::Buffer,
    /// Each object's vertices: its plain triangles from `start` to `stained`, then its
    /// stainable ones up to `end`.
    pub(super) ranges: Vec<ObjectRange>,
    /// Object indices, nearest kinds first, so early depth tests skip hidden fragments.
    pub(super) draw_order: Vec<usize>,
    pub(super) poses: Vec<Isometry3<f64>>,
    /// Each object's extent, for culling.
    pub(super) bounds: Vec<Bounds>,
}

/// Where an object's vertices lie in a [`GpuScene`]'s buffer.
#[derive(Debug, Clone, Copy)]
pub(super) struct ObjectRange {
    pub(super) start: u32,
    pub(super) stained: u32,
    pub(super) end: u32,
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
