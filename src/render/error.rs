//! Why a frame could not be rendered.

/// A rendering failure: no adapter, a device that refused, a readback that failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No wgpu adapter (GPU or software) could be found.
    #[error(
        "no graphics adapter found ({reason}); twincell renders on a GPU or on a software \
         adapter: Mesa llvmpipe through GL/EGL (package libegl-mesa0 / libgl1-mesa-dri) or \
         lavapipe through Vulkan (`apt-get install mesa-vulkan-drivers libvulkan1`); \
         WGPU_BACKEND=gl or vulkan picks one"
    )]
    NoAdapter {
        /// What wgpu reported.
        reason: String,
    },
    /// The adapter was found but refused to open a device.
    #[error("adapter `{adapter}` ({backend}) could not open a device: {reason}")]
    Device {
        /// The adapter's name.
        adapter: String,
        /// Its backend.
        backend: String,
        /// What wgpu reported.
        reason: String,
    },
    /// The adapter cannot render what was asked (a size, a sample count).
    #[error("adapter `{adapter}` cannot render this: {reason}")]
    Unsupported {
        /// The adapter's name.
        adapter: String,
        /// What is missing.
        reason: String,
    },
    /// Reading the frame back from the device failed.
    #[error("reading the frame back failed: {0}")]
    Readback(String),
    /// A validation or out-of-memory error inside wgpu.
    #[error("wgpu error: {0}")]
    Gpu(String),
}
