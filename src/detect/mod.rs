//! The part detector: it finds tube end faces (class `tube`) and foreign objects (class
//! `foreign`) anywhere in view; the part's type is then named by measurement. A small YOLO-style network (CSP backbone, SPPF, PAN neck, three anchor-free
//! heads) trained on the twin's own renders by `training/`, shipped as ONNX in `assets/models/`
//! with a model card (both built into the binary: [`DetectorModel::Shipped`]), and run here through the `ort` API on its pure-Rust tract backend (or, with
//! the feature `onnxruntime` instead of the default `tract`, on a native ONNX Runtime loaded from
//! `ORT_DYLIB_PATH`).
//!
//! [`Detector::detect`] letterboxes an image to the network's input, runs it, keeps the cells
//! whose score (objectness times best class probability) reaches the card's threshold, runs
//! class-agnostic non-maximum suppression and maps the boxes back to image pixels. The graph
//! itself decodes boxes and applies the sigmoids, so its output rows are
//! `x0, y0, x1, y1, objectness, class probabilities...` in input pixels.

mod detection;
mod detector;
mod error;
mod letterbox;
mod model_card;
mod nms;
mod runtime;

pub use detection::Detection;
pub use detector::{Detector, DetectorModel, SharedDetector};
pub use error::DetectError;
pub use letterbox::Letterbox;
pub use model_card::ModelCard;
pub use nms::{Candidate, non_max_suppression};

/// Class names that mean a foreign object (anything that is no part), in the order they are
/// looked for: the shipped detector's `foreign`, or `bottle` in a model trained per catalogue.
pub const FOREIGN_CLASSES: [&str; 2] = ["foreign", "bottle"];

/// Whether the class `name` is a foreign object's ([`FOREIGN_CLASSES`]).
pub fn is_foreign_class(name: &str) -> bool {
    FOREIGN_CLASSES.contains(&name)
}
