//! The bore detector's segmentation ([`crate::perception::bore`]): the filtered frame, and the
//! binary image of what is bright in it (the adaptive threshold, every pixel above Otsu's level,
//! and a bright frame round it) whose hole borders are the bore candidates.

use crate::perception::border_cut::brighten_frame;
use crate::perception::bore::BoreDetectorParams;
use crate::perception::filters::{FilterMethod, median_3x3_with_histogram};
use crate::perception::max_threshold::local_max_threshold;
use crate::perception::threshold::{
    ThresholdMethod, adaptive_mean_threshold_floored, brighten_above, otsu_level,
    otsu_level_of_histogram,
};
use image::GrayImage;

/// The filtered `image` and its binary image, as `params` say.
pub(crate) fn segment(params: &BoreDetectorParams, image: &GrayImage) -> (GrayImage, GrayImage) {
    // Otsu's level needs the filtered image's histogram: the 3x3 median counts it as it
    // writes its output.
    let (filtered, histogram) = match (params.filter, params.bright_above_otsu) {
        (FilterMethod::Median { radius_px: 1 }, true) => {
            let (filtered, histogram) = median_3x3_with_histogram(image);
            (filtered, Some(histogram))
        }
        (filter, _) => (filter.apply(image), None),
    };
    let otsu_level = |filtered: &GrayImage| match &histogram {
        Some(histogram) => otsu_level_of_histogram(histogram, filtered.width() * filtered.height()),
        None => otsu_level(filtered),
    };
    let mut binary = match (params.threshold, params.bright_above_otsu) {
        (
            ThresholdMethod::AdaptiveMean {
                block_radius_px,
                delta,
            },
            true,
        ) => adaptive_mean_threshold_floored(
            &filtered,
            block_radius_px,
            delta,
            otsu_level(&filtered),
        ),
        (method, true) => {
            let mut binary = method.apply(&filtered);
            brighten_above(&mut binary, &filtered, otsu_level(&filtered));
            binary
        }
        (method, false) => method.apply(&filtered),
    };
    // A bright frame closes a bore cut by the border into a hole whose border runs along
    // the frame, so it can be recognised and skipped rather than lost without a word.
    brighten_frame(&mut binary);
    (filtered, binary)
}

/// The second segmentation of `filtered` (against the local maximum) with its bright frame, if
/// `params` ask for one.
pub(crate) fn second_segmentation(
    params: &BoreDetectorParams,
    filtered: &GrayImage,
) -> Option<GrayImage> {
    let share = params.local_max_share?;
    // A bore is at least `min_contrast_levels` darker than its rim.
    let floor = params.min_contrast_levels.clamp(0.0, 255.0) as u8;
    let mut binary = local_max_threshold(filtered, params.local_max_reach_tiles, share, floor);
    brighten_frame(&mut binary);
    Some(binary)
}
