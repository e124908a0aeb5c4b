//! One detected object.

use serde::Serialize;

/// An object the detector found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Detection {
    /// Index into the model card's class names.
    pub class_id: usize,
    /// The class's name (a part type, or `bottle`).
    pub class_name: String,
    /// Objectness times class probability, 0..1.
    pub score: f32,
    /// Box corners `x0, y0, x1, y1` in image pixels (edges, not pixel centres).
    pub box_px: [f32; 4],
}
