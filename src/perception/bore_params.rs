//! The bore detector's parameters ([`crate::perception::bore::BoreDetector`]) and their defaults,
//! each with the reason for its value.

use crate::perception::bore::EdgeMode;
use crate::perception::filters::FilterMethod;
use crate::perception::roundness::DEFAULT_MAX_UPR;
use crate::perception::subpixel::RayParams;
use crate::perception::threshold::ThresholdMethod;

/// Parameters of [`crate::perception::bore::BoreDetector`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoreDetectorParams {
    /// Denoising filter.
    pub filter: FilterMethod,
    /// Segmentation of the bright rim.
    pub threshold: ThresholdMethod,
    /// Which edge points to fit.
    pub edge_mode: EdgeMode,
    /// Also count as bright every pixel above the filtered image's Otsu level. A wide rim's flat
    /// middle is no brighter than its block's mean, so the adaptive threshold alone leaves it
    /// dark, and noise or a stain at the bore edge then joins the bore to it (on the suite this
    /// lost 10 of 564 bores, all thick walls or noisy frames).
    pub bright_above_otsu: bool,
    /// A second segmentation for the bores the first leaves without a hole: bright where a
    /// pixel exceeds this share of the brightest level within `local_max_reach_tiles` tiles
    /// ([`crate::perception::max_threshold`]); its holes away from the bores already found are
    /// measured as candidates too. Oil across a rim's whole wall (a third of the rim and more
    /// on the heavy-noise suite) opens the first segmentation's ring around the bore. `None`:
    /// one segmentation only.
    pub local_max_share: Option<f64>,
    /// Reach of the local maximum, tiles of
    /// [`crate::perception::max_threshold::TILE_PX`] around the pixel's own.
    pub local_max_reach_tiles: usize,
    /// A bore found by the first segmentation with a roundness above this share of its radius
    /// is measured again from the second segmentation's hole in its place, and the rounder of
    /// the two (by half at least) is kept: oil from the bore edge part way across a rim can join
    /// the bore in the first segmentation and bulge its measured outline.
    pub recheck_roundness_ratio: f64,
    /// Smallest bore radius reported.
    pub min_radius_px: f64,
    /// Largest bore radius reported.
    pub max_radius_px: f64,
    /// Smallest median `(rim - bore) / rim`.
    pub min_contrast_ratio: f64,
    /// Smallest median `rim - bore`, grey levels.
    pub min_contrast_levels: f64,
    /// Farthest the rim walk goes, as a ratio of the outer to the bore radius.
    pub max_outer_ratio: f64,
    /// Smallest median rim width, where the rim ends inside the image.
    pub min_ring_width_px: f64,
    /// Share of the walked rays whose rim must be flat.
    pub min_flat_share: f64,
    /// Largest spread of the rim's level around the bore, as a share of the contrast (see
    /// [`crate::perception::rim::RimScan::rim_spread`]).
    pub max_rim_spread: f64,
    /// Share of rays that must show an edge.
    pub min_valid_share: f64,
    /// Largest roundness as a share of the radius.
    pub max_roundness_ratio: f64,
    /// Largest departure of the levels just either side of an edge from those further out, as a
    /// share of the contrast, for the edge to count (see [`crate::perception::subpixel::EdgePoint::flank_departure`]).
    pub max_flank_departure: f64,
    /// Edges further than this many robust scales from the robust series are outliers.
    pub outlier_scales: f64,
    /// Smallest robust scale of the edge radii, pixels.
    pub edge_scale_floor_px: f64,
    /// Share of the rays that must keep a clean edge.
    pub min_clean_share: f64,
    /// Roundness profile cutoff, undulations per revolution.
    pub max_upr: usize,
    /// Rays per bore: one per this many pixels of the coarse circumference, within `ray_range`.
    pub ray_spacing_px: f64,
    /// Fewest and most rays per bore.
    pub ray_range: [usize; 2],
    /// Ray sampling.
    pub rays: RayParams,
}

impl Default for BoreDetectorParams {
    fn default() -> Self {
        Self {
            filter: FilterMethod::Median { radius_px: 1 },
            threshold: ThresholdMethod::AdaptiveMean {
                block_radius_px: 20,
                delta: -15,
            },
            edge_mode: EdgeMode::SubPixel,
            bright_above_otsu: true,
            // Between a bore (below 0.3 of its rim's level) and oiled metal (0.55 of it and
            // more), with room for noise on the maximum.
            local_max_share: Some(0.42),
            // A window of about 40 px, the adaptive threshold's block.
            local_max_reach_tiles: 2,
            // Bores out of round by more than 6 % of their radius are rare in any catalogue.
            recheck_roundness_ratio: 0.06,
            // Below the smallest bore asked for (12 px), so that one fitted a hair small stays.
            min_radius_px: 10.0,
            // Bores up to a third of a 1280x960 frame's height and more.
            max_radius_px: 400.0,
            // A dark bore in machined metal keeps at least 0.79 of the rim's level below it under
            // any light on the suite (0.9 and more on the rendered end faces: albedo 0.72 against
            // 0.035); shares are illumination-invariant. A dark plastic cap in a translucent body
            // or between it and a grey belt reaches 0.65.
            min_contrast_ratio: 0.7,
            min_contrast_levels: 25.0,
            // Walls of 1.15 to 3 times the bore, and some margin.
            max_outer_ratio: 3.3,
            min_ring_width_px: 1.5,
            min_flat_share: 0.6,
            // About a linear light gradient and over the brighter half: one machined face keeps
            // within 0.3 under any light and oil on the suites; a lying bottle's dark cap
            // between its body and the belt spreads more.
            max_rim_spread: 0.3,
            min_valid_share: 0.7,
            max_roundness_ratio: 0.25,
            max_flank_departure: 0.05,
            outlier_scales: 3.0,
            edge_scale_floor_px: 0.03,
            min_clean_share: 0.4,
            max_upr: DEFAULT_MAX_UPR,
            // About a ray per pixel of circumference, 180 to 720 (a quarter degree apart at
            // most). Fewer rays are faster but noisier: a ray per two pixels, 128 to 360, halves
            // the rays' time and makes roundness about 20 % noisier (docs/measure.md, "Rays
            // against speed and accuracy"); the default keeps the accuracy.
            ray_spacing_px: 1.0,
            ray_range: [180, 720],
            rays: RayParams::default(),
        }
    }
}

impl BoreDetectorParams {
    /// The defaults for a `width_px` x `height_px` image from any camera: the largest bore
    /// reported grows to half the image's shorter side (the largest a bore whole in view can
    /// be), so a close-up from a high-resolution camera is measured too. Every other limit is
    /// the default's.
    pub fn for_image(width_px: u32, height_px: u32) -> Self {
        let mut params = Self::default();
        let half_short_side = 0.5 * f64::from(width_px.min(height_px));
        params.max_radius_px = params.max_radius_px.max(half_short_side);
        params
    }

    /// The parameters for images with `factor` times the pixels per millimetre these are tuned
    /// for (an area of interest read at a finer pitch): the spatial windows and size limits
    /// scale; the edge profile's, set by the optics' blur in pixels, do not.
    pub fn at_scale(mut self, factor: f64) -> Self {
        let scale_px = |v: u32| ((f64::from(v) * factor).round() as u32).max(1);
        self.threshold = match self.threshold {
            ThresholdMethod::AdaptiveMean {
                block_radius_px,
                delta,
            } => ThresholdMethod::AdaptiveMean {
                block_radius_px: scale_px(block_radius_px),
                delta,
            },
            ThresholdMethod::AdaptiveGaussian { sigma_px, delta } => {
                ThresholdMethod::AdaptiveGaussian {
                    sigma_px: sigma_px * factor as f32,
                    delta,
                }
            }
            global => global,
        };
        self.local_max_reach_tiles =
            ((self.local_max_reach_tiles as f64 * factor).round() as usize).max(1);
        self.min_radius_px *= factor;
        self.max_radius_px *= factor;
        self.min_ring_width_px *= factor;
        self
    }
}
