//! A synthetic detection dataset in the Ultralytics/YOLO layout: `images/{train,val}/*.png`,
//! `labels/{train,val}/*.txt` (one `class cx cy w h` line per object, normalised to the image),
//! and `data.yaml` naming the classes (the scenario's part types, then `bottle`). Every tenth
//! image (index 9, 19, ...) goes to the validation split: 90/10.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::family::{FAMILY_CLASSES, family_model, family_shot};
use super::renderer::Renderer;
use super::shot::{CameraRig, ObjectTruth, Shot, ShotError};
use crate::cell::CellModel;
use crate::scenario::Scenario;

/// Why a dataset could not be written.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A shot could not be made.
    #[error("image {index}: {source}")]
    Shot {
        /// The image's index.
        index: u64,
        /// What failed.
        source: ShotError,
    },
    /// A file could not be written.
    #[error("cannot write {}: {reason}", path.display())]
    Io {
        /// What failed.
        reason: String,
        /// The file.
        path: PathBuf,
    },
}

/// What was written.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct DatasetSummary {
    /// Images in the training split.
    pub train: usize,
    /// Images in the validation split.
    pub val: usize,
    /// Labelled objects per class, in class order.
    pub objects_per_class: Vec<(String, usize)>,
}

/// The dataset's class names: the part types in scenario order, then `bottle`.
pub fn class_names(scenario: &Scenario) -> Vec<String> {
    let mut names: Vec<String> = scenario.part_types.iter().map(|p| p.name.clone()).collect();
    names.push("bottle".into());
    names
}

/// Whether image `index` belongs to the validation split.
pub fn is_val(index: u64) -> bool {
    index % 10 == 9
}

/// File stem of image `index`.
pub fn image_stem(index: u64) -> String {
    format!("{index:06}")
}

/// YOLO label lines for an image's objects.
pub fn yolo_labels(truths: &[ObjectTruth], width_px: u32, height_px: u32) -> String {
    let (w, h) = (f64::from(width_px), f64::from(height_px));
    let mut text = String::new();
    for t in truths {
        let [x0, y0, x1, y1] = t.bbox_px.map(f64::from);
        // Inclusive pixel ranges: the box spans [x0 - 0.5, x1 + 0.5] in pixel-centre
        // coordinates, i.e. [x0, x1 + 1] from the image's left edge.
        let (cx, cy) = ((x0 + x1 + 1.0) / 2.0 / w, (y0 + y1 + 1.0) / 2.0 / h);
        let (bw, bh) = ((x1 - x0 + 1.0) / w, (y1 - y0 + 1.0) / h);
        let _ = writeln!(text, "{} {cx:.6} {cy:.6} {bw:.6} {bh:.6}", t.class_id);
    }
    text
}

/// One image and its labels, ready to write.
struct Sample {
    image: image::RgbImage,
    truths: Vec<ObjectTruth>,
    /// The label metadata (`labels/SPLIT/STEM.json`), when the set records it.
    meta: Option<serde_json::Value>,
}

/// Writes `count` shots of `model`'s scenario under `out`, rendered at `rig`'s resolution.
pub fn export(
    model: &CellModel,
    rig: &CameraRig,
    renderer: &mut Renderer,
    count: u64,
    out: &Path,
) -> Result<DatasetSummary, DatasetError> {
    let scenario = model.scenario();
    write_set(scenario, rig, &class_names(scenario), count, out, |index| {
        let shot_error = |source: ShotError| DatasetError::Shot { index, source };
        let shot = Shot::pick_station(model, rig, &scenario.sensor, index).map_err(shot_error)?;
        let image = shot
            .render(renderer)
            .map_err(|e| shot_error(ShotError::Render(e)))?;
        Ok(Sample {
            image,
            truths: shot.truth(scenario),
            meta: None,
        })
    })
}

/// Writes `count` family shots ([`super::family`]) of `model`'s scenario under `out`, at `rig`'s
/// resolution: classes `tube` and `foreign`, and beside each label file a JSON file with the
/// shot's camera (tilt, its direction, distance, roll, field of view), its tubes (bore, outer
/// diameter, height, finish, share of the end face in view) and every labelled object's truth,
/// so evaluation can band by them. `occlude` sets a bottle down in front of a tube in some shots
/// ([`super::family::family_shot`]).
pub fn export_family(
    model: &CellModel,
    rig: &CameraRig,
    renderer: &mut Renderer,
    count: u64,
    occlude: bool,
    out: &Path,
) -> Result<DatasetSummary, DatasetError> {
    let model = &family_model(model).map_err(|e| DatasetError::Shot {
        index: 0,
        source: ShotError::Cell(e),
    })?;
    let scenario = model.scenario();
    let names: Vec<String> = FAMILY_CLASSES.iter().map(|c| (*c).to_string()).collect();
    write_set(scenario, rig, &names, count, out, |index| {
        let shot_error = |source: ShotError| DatasetError::Shot { index, source };
        let family = family_shot(model, rig, index, occlude).map_err(shot_error)?;
        let image = family
            .shot
            .render(renderer)
            .map_err(|e| shot_error(ShotError::Render(e)))?;
        let truths = family.truth();
        let meta = serde_json::json!({
            "camera": family.camera,
            "tubes": family.tubes,
            "objects": truths,
        });
        Ok(Sample {
            image,
            truths,
            meta: Some(meta),
        })
    })
}

/// Writes a set: `data.yaml` naming `names`, then `count` samples from `sample`.
fn write_set(
    scenario: &crate::scenario::Scenario,
    rig: &CameraRig,
    names: &[String],
    count: u64,
    out: &Path,
    mut sample: impl FnMut(u64) -> Result<Sample, DatasetError>,
) -> Result<DatasetSummary, DatasetError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |e: std::io::Error| DatasetError::Io {
            reason: e.to_string(),
            path,
        }
    };
    for split in ["train", "val"] {
        for kind in ["images", "labels"] {
            let dir = out.join(kind).join(split);
            std::fs::create_dir_all(&dir).map_err(io(&dir))?;
        }
    }
    let mut yaml = format!(
        "# twincell synthetic pick-station images: scenario `{}`, seed {}, {count} images, \
         {} x {} px.\n# Paths are relative to this file's directory.\ntrain: images/train\n\
         val: images/val\nnc: {}\nnames:\n",
        scenario.name,
        scenario.seed,
        rig.width_px,
        rig.height_px,
        names.len()
    );
    for (i, name) in names.iter().enumerate() {
        let _ = writeln!(yaml, "  {i}: {name}");
    }
    let yaml_path = out.join("data.yaml");
    std::fs::write(&yaml_path, yaml).map_err(io(&yaml_path))?;

    let mut summary = DatasetSummary {
        train: 0,
        val: 0,
        objects_per_class: names.iter().map(|n| (n.clone(), 0)).collect(),
    };
    for index in 0..count {
        let Sample {
            image,
            truths,
            meta,
        } = sample(index)?;
        let split = if is_val(index) {
            summary.val += 1;
            "val"
        } else {
            summary.train += 1;
            "train"
        };
        for t in &truths {
            if let Some(entry) = summary.objects_per_class.get_mut(t.class_id) {
                entry.1 += 1;
            }
        }
        let stem = image_stem(index);
        let image_path = out.join("images").join(split).join(format!("{stem}.png"));
        image.save(&image_path).map_err(|e| DatasetError::Io {
            reason: e.to_string(),
            path: image_path.clone(),
        })?;
        let label_path = out.join("labels").join(split).join(format!("{stem}.txt"));
        std::fs::write(
            &label_path,
            yolo_labels(&truths, image.width(), image.height()),
        )
        .map_err(io(&label_path))?;
        if let Some(meta) = meta {
            let meta_path = out.join("labels").join(split).join(format!("{stem}.json"));
            std::fs::write(&meta_path, meta.to_string() + "\n").map_err(io(&meta_path))?;
        }
    }
    Ok(summary)
}
