//! Class-agnostic non-maximum suppression.

/// A scored box before suppression.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Best class.
    pub class_id: usize,
    /// Objectness times that class's probability.
    pub score: f32,
    /// `x0, y0, x1, y1`.
    pub box_px: [f32; 4],
}

fn iou(a: &[f32; 4], b: &[f32; 4]) -> f32 {
    let iw = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let ih = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = iw * ih;
    let area = |r: &[f32; 4]| (r[2] - r[0]).max(0.0) * (r[3] - r[1]).max(0.0);
    let union = area(a) + area(b) - inter;
    if union > 0.0 { inter / union } else { 0.0 }
}

/// Greedy suppression over all classes together (a wrong-size class box on the same part is
/// suppressed by the right one): candidates in descending score (ties: earlier first); one that
/// overlaps a kept box by IoU above `iou_threshold` is dropped. Returns the kept candidates in
/// that order.
pub fn non_max_suppression(mut candidates: Vec<Candidate>, iou_threshold: f32) -> Vec<Candidate> {
    // A stable sort keeps equal scores in input order: the result does not depend on chance.
    candidates.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut kept: Vec<Candidate> = Vec::new();
    for c in candidates {
        if kept
            .iter()
            .all(|k| iou(&k.box_px, &c.box_px) <= iou_threshold)
        {
            kept.push(c);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cand(class_id: usize, score: f32, box_px: [f32; 4]) -> Candidate {
        Candidate {
            class_id,
            score,
            box_px,
        }
    }

    #[test]
    fn overlapping_boxes_of_different_classes_keep_only_the_best() {
        let kept = non_max_suppression(
            vec![
                cand(1, 0.6, [0.0, 0.0, 10.0, 10.0]),
                cand(0, 0.9, [1.0, 0.0, 11.0, 10.0]),
                cand(2, 0.5, [50.0, 50.0, 60.0, 60.0]),
            ],
            0.5,
        );
        assert_eq!(kept.len(), 2);
        assert_eq!((kept[0].class_id, kept[1].class_id), (0, 2));
    }

    #[test]
    fn iou_of_disjoint_and_identical_boxes() {
        assert_eq!(iou(&[0.0, 0.0, 1.0, 1.0], &[2.0, 2.0, 3.0, 3.0]), 0.0);
        assert_eq!(iou(&[0.0, 0.0, 2.0, 2.0], &[0.0, 0.0, 2.0, 2.0]), 1.0);
    }
}
