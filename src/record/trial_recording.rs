//! One trial's part of a recording: its cell in 3D, its time series, its camera and its outcome.

use std::sync::{Arc, Mutex, PoisonError};

use nalgebra::Isometry3;
use rapier3d::prelude::RigidBodyHandle;
use rerun::{
    AsComponents, Boxes2D, Image, LineStrips2D, Pinhole, Points2D, RecordingStream,
    RecordingStreamResult, Scalars, SeriesLines, TextLog, TextLogLevel, ViewCoordinates,
};

use super::convert::{mesh_3d, transform};
use super::{METROLOGY, OUTCOMES, PART_TIMELINE, SIM_TIME, TRIAL_TIMELINE, trial_root};
use crate::outcome::{DecisionRecord, Outcome, PartRecord, Phase, TrialRecord};
use crate::render::mesh::Mesh;
use crate::render::{CameraRig, ObjectKind, Scene};
use crate::scenario::Scenario;
use crate::task::{CellView, PerceptionFrame, TrialObserver};

/// Segments of a fitted circle drawn over the image.
const CIRCLE_SEGMENTS: usize = 96;
/// Distance of the camera's image plane in the 3D view, m.
const IMAGE_PLANE_DISTANCE_M: f32 = 0.25;

/// A body that moves, and where its mesh sits on it.
struct MovingObject {
    entity: String,
    body: RigidBodyHandle,
    body_from_object: Isometry3<f64>,
}

/// Records one trial into a shared [`RecordingStream`] under `trials/NNNN/`.
pub struct TrialRecording {
    stream: RecordingStream,
    first_error: Arc<Mutex<Option<String>>>,
    trial_index: u32,
    root: String,
    parts_per_trial: u32,
    bottle_size_m: (f64, f64),
    moving: Vec<MovingObject>,
    parts_seen: usize,
    bottles_seen: Vec<RigidBodyHandle>,
    phase: Option<Phase>,
}

impl TrialRecording {
    /// The recording of trial `trial_index`; failures go to `first_error`.
    pub fn new(
        stream: RecordingStream,
        first_error: Arc<Mutex<Option<String>>>,
        trial_index: u32,
    ) -> Self {
        Self {
            stream,
            first_error,
            trial_index,
            root: trial_root(trial_index),
            parts_per_trial: 1,
            bottle_size_m: (0.0, 0.0),
            moving: Vec::new(),
            parts_seen: 0,
            bottles_seen: Vec::new(),
            phase: None,
        }
    }

    /// Keeps the first failure for [`super::RerunRecorder::finish`].
    fn note(&self, result: RecordingStreamResult<()>) {
        if let Err(e) = result {
            self.first_error
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .get_or_insert_with(|| e.to_string());
        }
    }

    /// Logs `data` at `path` under this trial's root, at the current time.
    fn log(&self, path: &str, data: &impl AsComponents) {
        self.note(self.stream.log(format!("{}/{path}", self.root), data));
    }

    /// Logs `data` at `path` under this trial's root for all times.
    fn log_static(&self, path: &str, data: &impl AsComponents) {
        self.note(
            self.stream
                .log_static(format!("{}/{path}", self.root), data),
        );
    }

    fn set_sim_time(&self, sim_time_s: f64) {
        self.stream.set_duration_secs(SIM_TIME, sim_time_s);
    }

    /// A body that moves from now on: its mesh once, its pose at every sample.
    fn add_moving(&mut self, entity: String, body: RigidBodyHandle, mesh: &Mesh) {
        self.log_static(&entity, &mesh_3d(mesh));
        self.moving.push(MovingObject {
            entity,
            body,
            body_from_object: Isometry3::identity(),
        });
    }

    /// The parts and bottles that appeared since the last sample.
    fn add_new_bodies(&mut self, view: &CellView<'_>) {
        for (i, item) in view.parts().iter().enumerate().skip(self.parts_seen) {
            let (body, part) = (&item.body, &item.instance);
            let mesh = Mesh::axle_part(&part.bore, part.outer_radius_m, part.height_m);
            self.add_moving(format!("cell/part_{i:02}"), *body, &mesh);
            self.log(
                "log",
                &TextLog::new(format!(
                    "part {i}: {}, true roundness {:.3} mm, bore {:.3} mm",
                    part.type_name,
                    part.bore.roundness_m() * 1e3,
                    part.bore.mean_diameter_m() * 1e3
                ))
                .with_level(TextLogLevel::DEBUG),
            );
        }
        self.parts_seen = view.parts().len();
        for body in view.bottles() {
            if self.bottles_seen.contains(&body) {
                continue;
            }
            let (radius_m, height_m) = self.bottle_size_m;
            let entity = format!("cell/bottle_{:02}", self.bottles_seen.len());
            self.add_moving(entity, body, &Mesh::bottle(radius_m, height_m));
            self.bottles_seen.push(body);
        }
    }

    /// The scenery and the robot's links as built; the fixed ones placed for good.
    fn log_scene(&mut self, scenario: &Scenario, view: &CellView<'_>) {
        let scene = Scene::from_cell(view.cell, scenario);
        let named = |name: &str| scene.objects.iter().filter(|o| o.name == name).count();
        for (k, object) in scene.objects.iter().enumerate() {
            // Parts and bottles are followed through the trial's own lists.
            if object.kind != ObjectKind::Scenery {
                continue;
            }
            // A link with one collider keeps its name; the rest get their index in the scene.
            let entity = if named(&object.name) == 1 {
                format!("cell/{}", object.name)
            } else {
                format!("cell/{}_{k:02}", object.name)
            };
            let moving = object.body.filter(|body| view.is_moving(*body));
            let world_from_body = moving.and_then(|body| view.body_pose(body));
            match (moving, world_from_body) {
                (Some(body), Some(world_from_body)) => {
                    self.log_static(&entity, &mesh_3d(&object.mesh));
                    self.moving.push(MovingObject {
                        entity,
                        body,
                        body_from_object: world_from_body.inverse() * object.world_from_object,
                    });
                }
                _ => {
                    self.log_static(&entity, &mesh_3d(&object.mesh));
                    self.log_static(&entity, &transform(&object.world_from_object));
                }
            }
        }
    }

    /// The scenario's camera: its pose and intrinsics, so the image shows in 3D too.
    fn log_camera(&self, scenario: &Scenario) {
        let Ok(rig) = CameraRig::from_scenario(scenario) else {
            return;
        };
        let c = &rig.calibration;
        self.log_static("cell/camera", &transform(&c.world_from_camera));
        // Rerun puts pixel (0, 0)'s corner at the origin; perception its centre.
        let pinhole = Pinhole::new([
            [c.fx_px as f32, 0.0, 0.0],
            [0.0, c.fy_px as f32, 0.0],
            [c.cx_px as f32 + 0.5, c.cy_px as f32 + 0.5, 1.0],
        ])
        .with_resolution([rig.width_px as f32, rig.height_px as f32])
        .with_image_plane_distance(IMAGE_PLANE_DISTANCE_M);
        self.log_static("cell/camera", &pinhole);
    }

    /// Measured against true roundness and bore diameter of one part, on the `part` timeline.
    fn log_metrology(&self, part_index: u64, part: &PartRecord, decision: Option<&DecisionRecord>) {
        self.stream
            .set_time_sequence(PART_TIMELINE, part_index as i64);
        let measured_roundness = decision.and_then(|d| d.measured_roundness_mm);
        let measured_diameter = decision.and_then(|d| d.measured_bore_diameter_mm);
        let series = [
            ("roundness_mm/true", Some(part.true_roundness_mm)),
            ("roundness_mm/measured", measured_roundness),
            ("bore_diameter_mm/true", Some(part.true_bore_diameter_mm)),
            ("bore_diameter_mm/measured", measured_diameter),
        ];
        for (path, value) in series {
            if let Some(value) = value {
                self.note(
                    self.stream
                        .log(format!("{METROLOGY}/{path}"), &Scalars::single(value)),
                );
            }
        }
    }
}

impl TrialObserver for TrialRecording {
    fn begin_trial(&mut self, trial_index: u32, scenario: &Scenario, view: &CellView<'_>) {
        self.trial_index = trial_index;
        self.root = trial_root(trial_index);
        self.parts_per_trial = scenario.parts_per_trial.max(1);
        self.bottle_size_m = (scenario.bottle.radius_m, scenario.bottle.height_m);
        self.stream.reset_time();
        self.stream
            .set_time_sequence(TRIAL_TIMELINE, i64::from(trial_index));
        self.set_sim_time(view.sim_time_s());
        self.log_static("cell", &ViewCoordinates::RIGHT_HAND_Z_UP());
        self.log_scene(scenario, view);
        self.log_camera(scenario);
        let joints = view.cell.arm.kinematics().joints.clone();
        self.log_static("joints_rad", &SeriesLines::new().with_names(joints));
        self.log_static(
            "gripper/grip_force_n",
            &SeriesLines::new().with_names(["left jaw", "right jaw"]),
        );
    }

    fn sample(&mut self, sim_time_s: f64, view: &CellView<'_>) {
        self.set_sim_time(sim_time_s);
        self.add_new_bodies(view);
        for object in &self.moving {
            if let Some(world_from_body) = view.body_pose(object.body) {
                self.log(
                    &object.entity,
                    &transform(&(world_from_body * object.body_from_object)),
                );
            }
        }
        self.log("joints_rad", &Scalars::new(view.joint_positions_rad()));
        let [left_m, right_m] = view.jaw_positions_m();
        self.log(
            "gripper/opening_mm",
            &Scalars::single((left_m + right_m) * 1e3),
        );
        self.log(
            "gripper/grip_force_n",
            &Scalars::new(view.jaw_grip_force_n()),
        );
        self.log(
            "gripper/force_limit_n",
            &Scalars::single(view.grip_force_limit_n),
        );
        if Some(view.phase) != self.phase {
            self.phase = Some(view.phase);
            self.log(
                "log",
                &TextLog::new(format!("phase: {}", view.phase)).with_level(TextLogLevel::DEBUG),
            );
        }
    }

    fn perception(&mut self, sim_time_s: f64, frame: &PerceptionFrame) {
        self.set_sim_time(sim_time_s);
        let (width, height) = frame.image.dimensions();
        self.log(
            "cell/camera/image",
            &Image::from_rgb24(frame.image.as_raw().clone(), [width, height]),
        );
        let detections = &frame.detections;
        self.log(
            "cell/camera/detections",
            &Boxes2D::from_mins_and_sizes(
                detections.iter().map(|d| [d.box_px[0], d.box_px[1]]),
                detections
                    .iter()
                    .map(|d| [d.box_px[2] - d.box_px[0], d.box_px[3] - d.box_px[1]]),
            )
            .with_labels(
                detections
                    .iter()
                    .map(|d| format!("{} {:.2}", d.class_name, d.score)),
            ),
        );
        // Perception puts pixel centres at integers; Rerun at half-integers.
        let to_image = |p: &[f64; 2]| [(p[0] + 0.5) as f32, (p[1] + 0.5) as f32];
        let contours = frame.bores.iter().map(|bore| {
            let mut strip: Vec<[f32; 2]> = bore.contour_px.iter().map(to_image).collect();
            strip.extend(strip.first().copied());
            strip
        });
        self.log("cell/camera/bore_contours", &LineStrips2D::new(contours));
        let circles = frame.bores.iter().map(|bore| {
            (0..=CIRCLE_SEGMENTS)
                .map(|k| {
                    let t = std::f64::consts::TAU * k as f64 / CIRCLE_SEGMENTS as f64;
                    to_image(&[
                        bore.centre_px[0] + bore.radius_px * t.cos(),
                        bore.centre_px[1] + bore.radius_px * t.sin(),
                    ])
                })
                .collect::<Vec<_>>()
        });
        let labels = frame.bores.iter().map(|bore| {
            let mm = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v:.3}"));
            format!(
                "roundness {} mm (true {}), diameter {} mm (true {})",
                mm(bore.measured_roundness_mm),
                mm(bore.true_roundness_mm),
                mm(bore.measured_diameter_mm),
                mm(bore.true_diameter_mm)
            )
        });
        self.log(
            "cell/camera/bore_circles",
            &LineStrips2D::new(circles).with_labels(labels),
        );
        self.log(
            "cell/camera/bore_centres",
            &Points2D::new(frame.bores.iter().map(|b| to_image(&b.centre_px))),
        );
    }

    fn finish_trial(&mut self, outcome: &TrialRecord) {
        self.set_sim_time(outcome.sim_time_s);
        let (level, verdict) = match outcome.outcome {
            Outcome::Success => (TextLogLevel::INFO, "success".to_string()),
            Outcome::Passed => (
                TextLogLevel::WARN,
                format!("passed: {}", outcome.detail.as_deref().unwrap_or("")),
            ),
            Outcome::Failure => (
                TextLogLevel::ERROR,
                format!(
                    "failure ({}): {}",
                    outcome.failure.map_or("unknown", |f| f.as_str()),
                    outcome.detail.as_deref().unwrap_or("")
                ),
            ),
        };
        let text = format!(
            "trial {} (seed {}): {verdict}; bin {}, cycle {:.2} s",
            outcome.trial,
            outcome.seed,
            outcome.placed_bin.as_deref().unwrap_or("none"),
            outcome.cycle_time_s
        );
        self.log("log", &TextLog::new(text.clone()).with_level(level));
        // Across trials: on the trial timeline only.
        self.stream.disable_timeline(SIM_TIME);
        self.note(
            self.stream
                .log(OUTCOMES, &TextLog::new(text).with_level(level)),
        );
        let first_part = u64::from(self.trial_index) * u64::from(self.parts_per_trial);
        if let Some(part) = &outcome.part {
            self.log_metrology(first_part, part, outcome.decision.as_ref());
        }
        for part in outcome.stream.iter().flat_map(|s| &s.parts) {
            self.log_metrology(
                first_part + u64::from(part.index),
                &part.part,
                part.decision.as_ref(),
            );
        }
        self.stream.reset_time();
    }
}
