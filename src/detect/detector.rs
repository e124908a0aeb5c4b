//! The detector: an `ort` session over the shipped network plus its model card.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock, PoisonError};

use image::RgbImage;
use ndarray::{Array2, Array4};
use ort::session::Session;
use ort::value::TensorRef;

use super::nms::{Candidate, non_max_suppression};
use super::runtime::session_builder;
use super::{DetectError, Detection, Letterbox, ModelCard};

/// The shipped network, built into the binary so that an installed binary needs no source tree.
const SHIPPED_ONNX: &[u8] = include_bytes!("../../assets/models/detector.onnx");
/// The shipped network's model card.
const SHIPPED_CARD: &str = include_str!("../../assets/models/detector.json");
/// Where the shipped network comes from in the source tree, for messages.
const SHIPPED_NAME: &str = "assets/models/detector.onnx";

/// Which network a detector runs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DetectorModel {
    /// The network shipped with the crate (`assets/models/detector.onnx` and its card), built
    /// into the binary.
    Shipped,
    /// An ONNX file with its model card beside it (same stem, `.json`): `--model FILE`.
    File(PathBuf),
}

impl std::fmt::Display for DetectorModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Shipped => write!(f, "{SHIPPED_NAME} (built in)"),
            Self::File(path) => write!(f, "{}", path.display()),
        }
    }
}

/// The part detector (see the module docs).
#[derive(Debug)]
pub struct Detector {
    session: Session,
    card: ModelCard,
}

/// One detector shared by every thread that holds it ([`Detector::shared`]): its model card
/// readable without waiting, its network run by one caller at a time.
#[derive(Debug)]
pub struct SharedDetector {
    card: ModelCard,
    model: DetectorModel,
    /// The network, once loaded (by the loader thread [`Detector::shared`] starts, or by the
    /// first caller that needs it before that thread is done), or why it could not be.
    loaded: OnceLock<Result<Mutex<Detector>, String>>,
}

impl SharedDetector {
    /// The model card.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// Class names in class-id order.
    pub fn class_names(&self) -> &[String] {
        &self.card.classes
    }

    /// The detector, once it is loaded and no other caller runs it. A caller that panicked
    /// while holding it left nothing half-done that a later run reads (each run starts from its
    /// own input), so a poisoned lock is taken over.
    pub fn lock(&self) -> Result<MutexGuard<'_, Detector>, DetectError> {
        let loaded = self.loaded.get_or_init(|| {
            Detector::open(&self.model)
                .map(Mutex::new)
                .map_err(|e| e.to_string())
        });
        match loaded {
            Ok(detector) => Ok(detector.lock().unwrap_or_else(PoisonError::into_inner)),
            Err(reason) => Err(DetectError::Runtime {
                context: "the shared detector".into(),
                reason: reason.clone(),
            }),
        }
    }

    /// [`Detector::detect`] on the shared detector.
    pub fn detect(&self, image: &RgbImage) -> Result<Vec<Detection>, DetectError> {
        self.lock()?.detect(image)
    }

    /// [`Detector::detect_binned`] on the shared detector.
    pub fn detect_binned(
        &self,
        binned: &RgbImage,
        bin: u32,
    ) -> Result<Vec<Detection>, DetectError> {
        self.lock()?.detect_binned(binned, bin)
    }
}

/// The detectors this process has loaded, one per network ([`Detector::shared`]).
static LOADED: Mutex<Vec<(DetectorModel, Arc<SharedDetector>)>> = Mutex::new(Vec::new());

impl Detector {
    /// Loads `onnx_path` and the model card beside it (same stem, `.json`).
    pub fn load(onnx_path: &Path) -> Result<Self, DetectError> {
        let card = ModelCard::load(&onnx_path.with_extension("json"))?;
        let context = || format!("loading {}", onnx_path.display());
        let session = session_builder(context)?
            .commit_from_file(onnx_path)
            .map_err(|e| DetectError::runtime(context(), &e))?;
        Ok(Self { session, card })
    }

    /// The network shipped with the crate, from the copy built into the binary.
    pub fn load_default() -> Result<Self, DetectError> {
        let card = ModelCard::from_json(SHIPPED_CARD, Path::new(SHIPPED_NAME))?;
        let context = || format!("loading {}", DetectorModel::Shipped);
        let session = session_builder(context)?
            .commit_from_memory(SHIPPED_ONNX)
            .map_err(|e| DetectError::runtime(context(), &e))?;
        Ok(Self { session, card })
    }

    /// The network `model` names.
    pub fn open(model: &DetectorModel) -> Result<Self, DetectError> {
        match model {
            DetectorModel::Shipped => Self::load_default(),
            DetectorModel::File(path) => Self::load(path),
        }
    }

    /// The process's one detector for `model`: made on the first call, the same instance for
    /// every later call and thread.
    ///
    /// Loading is most of a detector's cost (tract parses and optimises the graph: about as many
    /// instructions as ten detections), and the runtime runs a session for one caller at a time
    /// in any case (ort-tract holds a lock over each run), so workers sharing one detector lose
    /// nothing to each other that a detector each would save. A file's network is loaded here,
    /// so that a bad file is refused before any trial, and read once: a file changed after the
    /// first call is not read again by this process. The shipped network (built in and checked
    /// by the tests) is loaded on a thread of its own, so that a batch's first trials simulate
    /// on the cores that would otherwise wait for it; a detection before it is done waits.
    pub fn shared(model: &DetectorModel) -> Result<Arc<SharedDetector>, DetectError> {
        let mut loaded = LOADED.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((_, detector)) = loaded.iter().find(|(m, _)| m == model) {
            return Ok(Arc::clone(detector));
        }
        let shared = match model {
            DetectorModel::Shipped => {
                let card = ModelCard::from_json(SHIPPED_CARD, Path::new(SHIPPED_NAME))?;
                let shared = Arc::new(SharedDetector {
                    card,
                    model: model.clone(),
                    loaded: OnceLock::new(),
                });
                let loader = Arc::clone(&shared);
                // Without a thread, the first detection loads it.
                let _ = std::thread::Builder::new()
                    .name("detector-load".into())
                    .spawn(move || loader.lock().map(drop));
                shared
            }
            DetectorModel::File(_) => {
                let detector = Self::open(model)?;
                Arc::new(SharedDetector {
                    card: detector.card.clone(),
                    model: model.clone(),
                    loaded: OnceLock::from(Ok(Mutex::new(detector))),
                })
            }
        };
        loaded.push((model.clone(), Arc::clone(&shared)));
        Ok(shared)
    }

    /// Class names in class-id order.
    pub fn class_names(&self) -> &[String] {
        &self.card.classes
    }

    /// The model card.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// The network input for `image` and the letterbox that made it.
    pub fn preprocess(&self, image: &RgbImage) -> Result<(Array4<f32>, Letterbox), DetectError> {
        if image.width() == 0 || image.height() == 0 {
            return Err(DetectError::Image("empty image".into()));
        }
        let c = &self.card;
        Ok(Letterbox::apply(
            image,
            c.input_width,
            c.input_height,
            c.pad_value,
        ))
    }

    /// Runs the network on an input tensor: rows `x0, y0, x1, y1, objectness, class
    /// probabilities...` in input pixels, one per head cell.
    pub fn run_raw(&mut self, input: &Array4<f32>) -> Result<Array2<f32>, DetectError> {
        let tensor = TensorRef::from_array_view(input)
            .map_err(|e| DetectError::runtime("making the input tensor", &e))?;
        let outputs = self
            .session
            .run(ort::inputs![tensor])
            .map_err(|e| DetectError::runtime("running the detector", &e))?;
        let (shape, data) = outputs[0]
            .try_extract_tensor::<f32>()
            .map_err(|e| DetectError::runtime("reading the detector's output", &e))?;
        let columns = 5 + self.card.classes.len();
        let dims: Vec<i64> = shape.iter().copied().collect();
        let [1, rows, cols] = dims[..] else {
            return Err(DetectError::Output(format!(
                "shape {dims:?}, expected [1, cells, {columns}]"
            )));
        };
        if usize::try_from(cols).ok() != Some(columns) {
            return Err(DetectError::Output(format!(
                "{cols} columns, the card's {} classes need {columns}",
                self.card.classes.len()
            )));
        }
        let rows = usize::try_from(rows).map_err(|e| DetectError::Output(e.to_string()))?;
        Array2::from_shape_vec((rows, columns), data.to_vec())
            .map_err(|e| DetectError::Output(e.to_string()))
    }

    /// The objects in `image`: scored, thresholded at the card's operating point, suppressed
    /// across classes, boxes in image pixels, best first.
    pub fn detect(&mut self, image: &RgbImage) -> Result<Vec<Detection>, DetectError> {
        let (input, letterbox) = self.preprocess(image)?;
        self.detect_input(&input, &letterbox, image.dimensions())
    }

    /// The objects in the frame that `binned` is the `bin` x `bin` binning of (block means), as
    /// [`Self::detect`] finds them in that frame with each binned value spread over its block,
    /// bit for bit, without spreading it: boxes in the frame's pixels.
    ///
    /// `bin` is the letterbox's whole factor for the frame (the renderer's `reader_bin`), so
    /// that `binned` is the frame fitted to the input: the letterbox's block means of the frame
    /// are `binned`'s values. A `binned` that does not fit the input unscaled is an error for
    /// a `bin` of 2 or more; a `bin` of 1 is [`Self::detect`].
    pub fn detect_binned(
        &mut self,
        binned: &RgbImage,
        bin: u32,
    ) -> Result<Vec<Detection>, DetectError> {
        if bin < 2 {
            return self.detect(binned);
        }
        let (input, letterbox) = self.preprocess(binned)?;
        if letterbox.scale != 1.0 {
            return Err(DetectError::Image(format!(
                "a {}x{} frame binned {bin}x{bin} does not fit the {}x{} input unscaled",
                binned.width(),
                binned.height(),
                self.card.input_width,
                self.card.input_height
            )));
        }
        let (w, h) = binned.dimensions();
        let frame = (w * bin, h * bin);
        // The frame's letterbox: the same fitted size and padding, `bin` times the pitch.
        let letterbox = Letterbox {
            scale: w as f32 / frame.0 as f32,
            ..letterbox
        };
        self.detect_input(&input, &letterbox, frame)
    }

    /// The objects in the network input `input`, boxes mapped through `letterbox` into an image
    /// of `(width, height)`.
    fn detect_input(
        &mut self,
        input: &Array4<f32>,
        letterbox: &Letterbox,
        (width, height): (u32, u32),
    ) -> Result<Vec<Detection>, DetectError> {
        let raw = self.run_raw(input)?;
        let threshold = self.card.score_threshold;
        let candidates =
            raw.rows()
                .into_iter()
                .filter_map(|row| {
                    let (class_id, p) = row.iter().skip(5).enumerate().fold(
                        (0, f32::NEG_INFINITY),
                        |best, (i, &p)| {
                            if p > best.1 { (i, p) } else { best }
                        },
                    );
                    let score = row[4] * p;
                    (score >= threshold).then(|| Candidate {
                        class_id,
                        score,
                        box_px: [row[0], row[1], row[2], row[3]],
                    })
                })
                .collect();
        let kept = non_max_suppression(candidates, self.card.nms_iou_threshold);
        Ok(kept
            .into_iter()
            .map(|c| Detection {
                class_id: c.class_id,
                class_name: self.card.classes[c.class_id].clone(),
                score: c.score,
                box_px: letterbox.to_image(c.box_px, width, height),
            })
            .collect())
    }
}
