//! The model card: the JSON beside the ONNX file that says what the network expects and emits.

use std::path::Path;

use serde::Deserialize;

use super::DetectError;

/// What the detector needs from the card; the card also records training data, seeds and
/// metrics, which inference ignores.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct ModelCard {
    /// Class names in the network's class order.
    pub classes: Vec<String>,
    /// Network input width, px.
    pub input_width: u32,
    /// Network input height, px.
    pub input_height: u32,
    /// Grey level (0-255) of the letterbox padding.
    pub pad_value: u8,
    /// Operating threshold on objectness times class probability.
    pub score_threshold: f32,
    /// Boxes overlapping a better one by more than this IoU are suppressed, whatever their class.
    pub nms_iou_threshold: f32,
}

impl ModelCard {
    /// Reads and checks a card.
    pub fn load(path: &Path) -> Result<Self, DetectError> {
        let err = |reason: String| DetectError::Card {
            path: path.to_path_buf(),
            reason,
        };
        let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
        Self::from_json(&text, path)
    }

    /// Parses and checks the card `text` (read from `path`, named in errors).
    pub fn from_json(text: &str, path: &Path) -> Result<Self, DetectError> {
        let err = |reason: String| DetectError::Card {
            path: path.to_path_buf(),
            reason,
        };
        let card: Self = serde_json::from_str(text).map_err(|e| err(e.to_string()))?;
        card.validate().map_err(err)?;
        Ok(card)
    }

    fn validate(&self) -> Result<(), String> {
        if self.classes.is_empty() {
            return Err("classes: empty".into());
        }
        if self.input_width == 0 || self.input_height == 0 {
            return Err("input_width, input_height: must be positive".into());
        }
        if !(0.0..=1.0).contains(&self.score_threshold) {
            return Err(format!(
                "score_threshold: {} is not in [0, 1]",
                self.score_threshold
            ));
        }
        if !(0.0..=1.0).contains(&self.nms_iou_threshold) {
            return Err(format!(
                "nms_iou_threshold: {} is not in [0, 1]",
                self.nms_iou_threshold
            ));
        }
        Ok(())
    }
}
