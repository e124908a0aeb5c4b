//! The camera frames of failed and misjudged trials, saved small beside the records
//! (`DIR/images/trial-NNNN.jpg`) for the report page: the frame as the sensor delivered it,
//! with the detector's boxes and the fitted bore drawn on it.
//!
//! A [`TrialImages`] observer keeps the trial's camera frames while it runs and, when the trial
//! ends failed or misjudged, writes the frame that decided it, before the batch writes the
//! record: so every record on disk that wants an image has it, a resumed batch keeps the
//! images of the trials it keeps, and a rerun trial writes the same bytes again.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use image::imageops::FilterType;
use image::{Rgb, RgbImage};
use imageproc::drawing::{draw_cross_mut, draw_hollow_circle_mut, draw_hollow_rect_mut};
use imageproc::rect::Rect;

use super::{BatchError, Outcome, TrialRecord};
use crate::outcome::{DecisionRecord, PartRecord};
use crate::scenario::Scenario;
use crate::task::{CellView, PerceptionFrame, TrialObserver, TrialObserverFactory};

/// Directory of the saved frames, inside a batch's output directory.
pub const IMAGES_DIR: &str = "images";
/// Width of a saved frame, px (the height keeps the camera's aspect).
pub const THUMBNAIL_WIDTH_PX: u32 = 320;
/// JPEG quality of a saved frame.
const JPEG_QUALITY: u8 = 85;

const PART_BOX: Rgb<u8> = Rgb([255, 200, 0]);
const BOTTLE_BOX: Rgb<u8> = Rgb([230, 0, 230]);
const BORE: Rgb<u8> = Rgb([255, 40, 40]);
const EDGE: Rgb<u8> = Rgb([0, 230, 0]);

/// Where trial `trial`'s frame lies in the batch directory `dir`.
pub fn trial_image_path(dir: &Path, trial: u32) -> PathBuf {
    dir.join(IMAGES_DIR).join(format!("trial-{trial:04}.jpg"))
}

/// Whether a decision disagrees with the truth: a verdict other than the true one, or a type
/// other than the true one.
pub fn decision_misjudged(part: &PartRecord, decision: &DecisionRecord) -> bool {
    decision.accept != part.truly_acceptable || decision.detected_type != part.part_type
}

/// The first part of `record` that failed, was let through or was misjudged, as an index into its stream's
/// parts (`Some(0)` for a single-part trial's part); `None` when there is none.
fn first_bad_part(record: &TrialRecord) -> Option<usize> {
    record.parts().iter().position(|p| {
        p.outcome != Outcome::Success || p.decision.is_some_and(|d| decision_misjudged(p.part, d))
    })
}

/// Whether the report shows `record` with its camera frame: it failed, its part was let
/// through as unpickable (the frame shows why), or a decision in it
/// disagrees with the truth (accept/reject or type), even where the uncertainty band let the
/// part's bin count as right.
pub fn wants_image(record: &TrialRecord) -> bool {
    record.outcome != Outcome::Success || first_bad_part(record).is_some()
}

/// Saves the frames of the failed and misjudged trials of a batch into `DIR/images/`.
#[derive(Debug, Clone)]
pub struct TrialImages {
    dir: PathBuf,
}

impl TrialImages {
    /// Saves into the batch directory `dir` (its `images/` is made when first needed).
    pub fn new(dir: &Path) -> Self {
        Self {
            dir: dir.to_path_buf(),
        }
    }
}

impl TrialObserverFactory for TrialImages {
    fn observer(&self, _trial_index: u32) -> Box<dyn TrialObserver> {
        Box::new(FrameKeeper {
            dir: self.dir.clone(),
            frames: Vec::new(),
        })
    }
}

/// One trial's camera frames, in the order they were taken.
struct FrameKeeper {
    dir: PathBuf,
    frames: Vec<PerceptionFrame>,
}

impl FrameKeeper {
    /// The frame that decided `record`: a stream's look at its first failed or misjudged part
    /// (the looks at parts are the frames whose station holds a part type), else the last.
    fn deciding_frame(&self, record: &TrialRecord) -> Option<&PerceptionFrame> {
        let part_looks = || {
            self.frames.iter().filter(|f| {
                f.station
                    .as_deref()
                    .is_some_and(|s| s != "bottle" && !s.is_empty())
            })
        };
        match (&record.stream, first_bad_part(record)) {
            (Some(_), Some(k)) => part_looks().nth(k).or(self.frames.last()),
            _ => self.frames.last(),
        }
    }
}

impl TrialObserver for FrameKeeper {
    fn begin_trial(&mut self, _trial_index: u32, _scenario: &Scenario, _view: &CellView<'_>) {
        self.frames.clear();
    }

    fn sample(&mut self, _sim_time_s: f64, _view: &CellView<'_>) {}

    fn perception(&mut self, _sim_time_s: f64, frame: &PerceptionFrame) {
        self.frames.push(frame.clone());
    }

    fn finish_trial(&mut self, outcome: &TrialRecord) {
        if !wants_image(outcome) {
            return;
        }
        let Some(frame) = self.deciding_frame(outcome) else {
            return;
        };
        let path = trial_image_path(&self.dir, outcome.trial);
        if let Err(err) = write_thumbnail(frame, &path) {
            // An observer cannot fail the trial: the page says the image is missing.
            tracing::warn!("trial {}: {err}", outcome.trial);
        }
    }
}

/// `frame` with its detections (parts amber, bottles magenta), the fitted bore (red circle and
/// centre) and the edge points it was fitted to (green), scaled to [`THUMBNAIL_WIDTH_PX`].
pub fn annotated_thumbnail(frame: &PerceptionFrame) -> RgbImage {
    let mut image = frame.image.clone();
    for detection in &frame.detections {
        let [x0, y0, x1, y1] = detection.box_px;
        let colour = if matches!(detection.class_name.as_str(), "bottle" | "foreign") {
            BOTTLE_BOX
        } else {
            PART_BOX
        };
        // Two nested outlines: one pixel would vanish at half scale.
        for inset in 0..2 {
            let inset_px = inset as f32;
            let (w, h) = (x1 - x0 - 2.0 * inset_px, y1 - y0 - 2.0 * inset_px);
            if w >= 1.0 && h >= 1.0 {
                let rect = Rect::at((x0 + inset_px) as i32, (y0 + inset_px) as i32)
                    .of_size(w as u32, h as u32);
                draw_hollow_rect_mut(&mut image, rect, colour);
            }
        }
    }
    for bore in &frame.bores {
        for [x, y] in &bore.contour_px {
            let (x, y) = (x.round(), y.round());
            if x >= 0.0 && y >= 0.0 && (x as u32) < image.width() && (y as u32) < image.height() {
                image.put_pixel(x as u32, y as u32, EDGE);
            }
        }
        let centre = (
            bore.centre_px[0].round() as i32,
            bore.centre_px[1].round() as i32,
        );
        for dr in [-1, 0, 1] {
            draw_hollow_circle_mut(&mut image, centre, bore.radius_px.round() as i32 + dr, BORE);
        }
        draw_cross_mut(&mut image, BORE, centre.0, centre.1);
    }
    let (w, h) = image.dimensions();
    let height = (u64::from(THUMBNAIL_WIDTH_PX) * u64::from(h) / u64::from(w.max(1))).max(1);
    let height = u32::try_from(height).unwrap_or(THUMBNAIL_WIDTH_PX);
    image::imageops::resize(&image, THUMBNAIL_WIDTH_PX, height, FilterType::Triangle)
}

/// Writes `frame`'s annotated thumbnail as a JPEG to `path` (its directory made if missing).
fn write_thumbnail(frame: &PerceptionFrame, path: &Path) -> Result<(), BatchError> {
    let thumbnail = annotated_thumbnail(frame);
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, JPEG_QUALITY)
        .encode_image(&thumbnail)
        .map_err(|e| BatchError::Write {
            path: path.to_path_buf(),
            source: io::Error::other(e),
        })?;
    if let Some(parent) = path.parent() {
        fs::create_dir_all(parent).map_err(|source| BatchError::CreateDir {
            path: parent.to_path_buf(),
            source,
        })?;
    }
    fs::write(path, bytes).map_err(|source| BatchError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Removes the `images/` of an earlier batch in `dir`, if any.
pub fn remove_trial_images(dir: &Path) -> Result<(), BatchError> {
    let path = dir.join(IMAGES_DIR);
    match fs::remove_dir_all(&path) {
        Ok(()) => Ok(()),
        Err(err) if err.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(source) => Err(BatchError::Write { path, source }),
    }
}

/// Copies the frames of `trials` (trial index and the shard directory that holds its record)
/// into `out_dir/images/`, replacing what was there; trials without a frame are skipped.
pub fn copy_trial_images<'a>(
    trials: impl Iterator<Item = (u32, &'a Path)>,
    out_dir: &Path,
) -> Result<(), BatchError> {
    // Read first: a shard directory may be the output directory itself.
    let mut found = Vec::new();
    for (trial, dir) in trials {
        let path = trial_image_path(dir, trial);
        match fs::read(&path) {
            Ok(bytes) => found.push((trial, bytes)),
            Err(err) if err.kind() == io::ErrorKind::NotFound => {}
            Err(source) => return Err(BatchError::Write { path, source }),
        }
    }
    remove_trial_images(out_dir)?;
    for (trial, bytes) in found {
        let path = trial_image_path(out_dir, trial);
        if let Some(parent) = path.parent() {
            fs::create_dir_all(parent).map_err(|source| BatchError::CreateDir {
                path: parent.to_path_buf(),
                source,
            })?;
        }
        fs::write(&path, bytes).map_err(|source| BatchError::Write { path, source })?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outcome::FailureReason;
    use crate::task::{BoreView, DetectionView};

    fn frame() -> PerceptionFrame {
        PerceptionFrame {
            image: RgbImage::from_pixel(640, 480, Rgb([40, 40, 40])),
            detections: vec![
                DetectionView {
                    class_name: "axle_b28".into(),
                    score: 0.9,
                    box_px: [100.0, 100.0, 200.0, 200.0],
                },
                DetectionView {
                    class_name: "bottle".into(),
                    score: 0.8,
                    box_px: [300.0, 120.0, 380.0, 300.0],
                },
            ],
            bores: vec![BoreView {
                centre_px: [150.0, 150.0],
                radius_px: 30.0,
                contour_px: vec![[180.0, 150.0], [150.0, 180.0]],
                measured_roundness_mm: Some(0.2),
                true_roundness_mm: Some(0.21),
                measured_diameter_mm: Some(28.0),
                true_diameter_mm: Some(28.0),
            }],
            station: Some("axle_b28".into()),
        }
    }

    #[test]
    fn the_thumbnail_is_small_and_shows_boxes_and_bore() {
        let thumb = annotated_thumbnail(&frame());
        assert_eq!(thumb.dimensions(), (320, 240));
        // The box edges and the bore circle survive the halving (pixels differ from the grey).
        let coloured = |x: u32, y: u32| {
            let p = thumb.get_pixel(x, y);
            p[0].abs_diff(p[1]) > 40 || p[1].abs_diff(p[2]) > 40
        };
        assert!(coloured(50, 75), "part box top edge");
        assert!(coloured(150, 100), "bottle box left edge");
        assert!(coloured(90, 75), "bore circle's right point");
        assert!(!coloured(20, 20), "background");
    }

    #[test]
    fn failed_and_misjudged_trials_want_an_image() {
        let failed = TrialRecord::failed(3, 9, FailureReason::Collision, "x");
        assert!(wants_image(&failed));
        let part = PartRecord {
            part_type: "axle_b28".into(),
            true_roundness_mm: 0.48,
            true_bore_diameter_mm: 28.0,
            truly_acceptable: true,
            clear_cut: false,
            correct_bin: "group_b".into(),
        };
        let decision = DecisionRecord {
            detected_type: "axle_b28".into(),
            measured_roundness_mm: Some(0.52),
            measured_bore_diameter_mm: Some(28.0),
            accept: false,
            bin: "reject".into(),
            note: None,
        };
        let mut ok = failed.clone();
        ok.outcome = Outcome::Success;
        ok.failure = None;
        ok.part = Some(part.clone());
        ok.decision = Some(DecisionRecord {
            accept: true,
            ..decision.clone()
        });
        assert!(!wants_image(&ok));
        // Rejected within the tolerance: a success inside the band, but misjudged.
        ok.decision = Some(decision.clone());
        assert!(wants_image(&ok));
        // The right verdict on the wrong type.
        ok.decision = Some(DecisionRecord {
            accept: true,
            detected_type: "axle_b32".into(),
            ..decision
        });
        assert!(wants_image(&ok));
    }

    #[test]
    fn an_image_is_written_for_a_failed_trial_only() {
        let dir = std::env::temp_dir().join(format!("twincell-images-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        let factory = TrialImages::new(&dir);
        let mut observer = factory.observer(7);
        observer.perception(1.0, &frame());
        let mut record = TrialRecord::failed(7, 1, FailureReason::Collision, "x");
        observer.finish_trial(&record);
        let bytes = fs::read(trial_image_path(&dir, 7)).expect("image written");
        let image = image::load_from_memory(&bytes).expect("a JPEG");
        assert_eq!((image.width(), image.height()), (320, 240));
        let mut observer = factory.observer(8);
        observer.perception(1.0, &frame());
        record.trial = 8;
        record.outcome = Outcome::Success;
        record.failure = None;
        observer.finish_trial(&record);
        assert!(!trial_image_path(&dir, 8).exists());
        // Merging copies the images of the trials named, from their shard directories.
        let out = dir.join("merged");
        copy_trial_images([(7, dir.as_path()), (8, dir.as_path())].into_iter(), &out)
            .expect("copy");
        assert_eq!(fs::read(trial_image_path(&out, 7)).expect("copied"), bytes);
        assert!(!trial_image_path(&out, 8).exists());
        let _ = fs::remove_dir_all(&dir);
    }
}
