//! ArUco marker detection: candidates from adaptive thresholds at a few window sizes, their outlines
//! simplified to quadrilaterals, each read through its homography and identified in the dictionary with its
//! error correction, and the corners refined to a fraction of a pixel.
//!
//! The steps follow OpenCV's `ArucoDetector` (so results can be compared with it); corners come from lines
//! fitted to the outline's sides before OpenCV's `cornerSubPix` refinement with its window rule.

mod contours;
mod decode;
mod edges;
mod quad;

use crate::dictionary::Dictionary;
use crate::dictionary::BORDER_BITS;
use crate::gray::{Gray, Integral};
use crate::subpix::{corner_subpix, SubpixSettings};
pub use decode::DecodeSettings;

/// A marker found in an image.
#[derive(Clone, Debug, PartialEq)]
pub struct DetectedMarker {
    /// Its id in the dictionary.
    pub id: usize,
    /// Its corners in pixels (pixel centres at integers), in the marker's own order: top-left, top-right,
    /// bottom-right, bottom-left as printed.
    pub corners: [[f64; 2]; 4],
    /// Inner bits that read wrong (corrected by the dictionary).
    pub bit_errors: u32,
}

/// The detector's settings (OpenCV's `DetectorParameters` where they have a counterpart).
#[derive(Clone, Debug)]
pub struct DetectorSettings {
    /// Window sides of the adaptive thresholds (odd pixels); each gives candidates.
    pub threshold_windows: Vec<usize>,
    /// How much darker than its neighbourhood's mean a pixel must be to count as dark (0–255).
    pub threshold_offset: f32,
    /// The least and most outline length, as a share of the image's larger side.
    pub perimeter_rate: (f64, f64),
    /// Douglas–Peucker tolerance as a share of the outline's length.
    pub polygon_accuracy_rate: f64,
    /// The shortest side, as a share of the outline's length.
    pub min_side_rate: f64,
    /// Candidates with a corner nearer the image's edge than this (pixels) are left out.
    pub min_distance_to_border: f64,
    /// How a candidate's cells are read.
    pub decode: DecodeSettings,
    /// How the corners are refined.
    pub refine: Refine,
}

/// How a marker's corners are refined.
#[derive(Clone, Copy, Debug)]
pub enum Refine {
    /// The corners where the lines of the outline's pixels meet (about half a pixel inside).
    None,
    /// Lines through each side's subpixel edge (in linear light), intersected; the default, unbiased at a black
    /// square's corner.
    Edges,
    /// OpenCV's `CORNER_REFINE_SUBPIX` (for comparisons with OpenCV: about 0.3 px inside a marker's corner).
    Subpix(SubpixRule),
}

/// OpenCV's corner refinement parameters.
#[derive(Clone, Copy, Debug)]
pub struct SubpixRule {
    /// The largest half-window, pixels (`cornerRefinementWinSize`).
    pub max_window: usize,
    /// The half-window as a share of a marker cell's side (`relativeCornerRefinmentWinSize`).
    pub relative_window: f64,
    /// Iterations (`cornerRefinementMaxIterations`).
    pub max_iterations: usize,
    /// Stop below this step, pixels (`cornerRefinementMinAccuracy`).
    pub min_step: f64,
}

impl Default for DetectorSettings {
    fn default() -> Self {
        DetectorSettings {
            threshold_windows: vec![3, 13, 23, 43],
            threshold_offset: 7.0,
            perimeter_rate: (0.03, 4.0),
            polygon_accuracy_rate: 0.03,
            min_side_rate: 0.05,
            min_distance_to_border: 3.0,
            decode: DecodeSettings {
                cell_margin: 0.13,
                max_border_error_rate: 0.35,
                error_correction_rate: 0.6,
                min_contrast: 5.0,
            },
            refine: Refine::Edges,
        }
    }
}

/// The markers of `dictionary` in the image; each id once (the read with the fewest errors where several
/// outlines give the same marker at the same place).
pub fn detect_markers(gray: &Gray, dictionary: &Dictionary, s: &DetectorSettings) -> Vec<DetectedMarker> {
    let integral = Integral::new(gray);
    let (w, h) = (gray.width, gray.height);
    let larger = w.max(h) as f64;
    let (min_perimeter, max_perimeter) = (s.perimeter_rate.0 * larger, s.perimeter_rate.1 * larger);
    let mut found: Vec<(DetectedMarker, f64)> = Vec::new();
    for &window in &s.threshold_windows {
        let dark = contours::adaptive_threshold(gray, &integral, window / 2, s.threshold_offset);
        let (labels, sizes) = contours::components(&dark, w, h);
        let mut first_pixel = vec![usize::MAX; sizes.len()];
        for (i, &l) in labels.iter().enumerate() {
            if l != 0 && first_pixel[l as usize] == usize::MAX {
                first_pixel[l as usize] = i;
            }
        }
        for label in 1..sizes.len() {
            // A blob too small to hold a marker's outline is left before tracing it.
            if (sizes[label] as f64) < min_perimeter * 0.5 {
                continue;
            }
            let start = (first_pixel[label] % w, first_pixel[label] / w);
            let outline = contours::trace_boundary(&labels, w, h, start, 8 * sizes[label] + 16);
            let length = outline.len() as f64;
            if length < min_perimeter || length > max_perimeter {
                continue;
            }
            let Some((rough, fitted)) = quadrilateral(&outline, s, w, h) else {
                continue;
            };
            // OpenCV refines from the outline's vertices; the edge refinement from the fitted sides' corners.
            let corners = if matches!(s.refine, Refine::Subpix(_)) {
                rough
            } else {
                fitted
            };
            let Some(decoded) = decode::decode(gray, &corners, dictionary, &s.decode) else {
                continue;
            };
            let r = decoded.identified.rotation;
            let ordered = [0, 1, 2, 3].map(|m| corners[(m + 4 - r) % 4]);
            let marker = DetectedMarker {
                id: decoded.identified.id,
                corners: ordered,
                bit_errors: decoded.identified.distance,
            };
            keep_best(&mut found, marker, length);
        }
    }
    let mut markers: Vec<DetectedMarker> = found.into_iter().map(|(m, _)| m).collect();
    let linear = matches!(s.refine, Refine::Edges).then(|| gray.to_linear());
    for m in &mut markers {
        let cell = side_mean(&m.corners) / (dictionary.marker_size + 2 * BORDER_BITS) as f64;
        match s.refine {
            Refine::None => {}
            Refine::Edges => {
                // The corners rotated back to clockwise-as-seen order are what the edge walk expects; the
                // marker's order is a rotation of it, so the refined corners keep their places.
                if let Some(refined) =
                    edges::refine_by_edges(linear.as_ref().expect("made for Edges"), &m.corners, cell, None)
                {
                    m.corners = refined;
                }
            }
            Refine::Subpix(rule) => subpix_corners(gray, &mut m.corners, cell, &rule),
        }
    }
    markers.sort_by_key(|m| m.id);
    markers
}

/// The markers' corners refined again knowing the lens: the edges undistorted before the lines are fitted
/// (a lens bends the sides, and lines through bent sides miss the corners). For the second pass of a calibration.
pub fn refine_with_lens(gray: &Gray, markers: &mut [DetectedMarker], dictionary: &Dictionary, lens: &crate::Lens) {
    let linear = gray.to_linear();
    for m in markers {
        let cell = side_mean(&m.corners) / (dictionary.marker_size + 2 * BORDER_BITS) as f64;
        if let Some(refined) = edges::refine_by_edges(&linear, &m.corners, cell, Some(lens)) {
            m.corners = refined;
        }
    }
}

impl SubpixRule {
    /// OpenCV's defaults (`cornerRefinementWinSize` 5, `relativeCornerRefinmentWinSize` 0.3, 30 iterations,
    /// 0.1 px).
    pub const OPENCV: SubpixRule = SubpixRule {
        max_window: 5,
        relative_window: 0.3,
        max_iterations: 30,
        min_step: 0.1,
    };
}

/// OpenCV's refinement of a marker's corners: `cornerSubPix` with its window rule.
fn subpix_corners(gray: &Gray, corners: &mut [[f64; 2]; 4], cell: f64, refine: &SubpixRule) {
    {
        {
            let half_window = ((refine.relative_window * cell).round() as usize).clamp(1, refine.max_window);
            let settings = SubpixSettings {
                half_window,
                max_iterations: refine.max_iterations,
                min_step: refine.min_step,
            };
            for c in corners.iter_mut() {
                *c = corner_subpix(gray, *c, &settings);
            }
        }
    }
}

/// The outline as a convex quadrilateral with sides long enough and corners away from the image edge,
/// clockwise as seen: its vertices on the outline, and the corners where the lines fitted to its sides meet.
type Quad = [[f64; 2]; 4];
fn quadrilateral(outline: &[[i64; 2]], s: &DetectorSettings, w: usize, h: usize) -> Option<(Quad, Quad)> {
    let length = quad::perimeter(outline);
    let mut vertices = quad::simplify_closed(outline, s.polygon_accuracy_rate * length);
    if vertices.len() != 4 {
        return None;
    }
    vertices.sort_unstable();
    let idx = [vertices[0], vertices[1], vertices[2], vertices[3]];
    let rough = idx.map(|i| [outline[i][0] as f64, outline[i][1] as f64]);
    if !quad::is_convex(&rough) {
        return None;
    }
    let min_side = (0..4)
        .map(|i| {
            let (a, b) = (rough[i], rough[(i + 1) % 4]);
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
        })
        .fold(f64::INFINITY, f64::min);
    if min_side < s.min_side_rate * length {
        return None;
    }
    let corners = quad::corners_from_sides(outline, &idx).unwrap_or(rough);
    let margin = s.min_distance_to_border;
    if corners
        .iter()
        .any(|c| c[0] < margin || c[1] < margin || c[0] > w as f64 - 1.0 - margin || c[1] > h as f64 - 1.0 - margin)
    {
        return None;
    }
    // The traced outline runs through the dark pixels' centres, half a pixel inside the edge: the corners
    // start there and the refinement moves them onto the edge.
    quad::is_convex(&corners).then(|| (quad::clockwise(rough), quad::clockwise(corners)))
}

fn side_mean(c: &[[f64; 2]; 4]) -> f64 {
    (0..4)
        .map(|i| {
            let (a, b) = (c[i], c[(i + 1) % 4]);
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
        })
        .sum::<f64>()
        / 4.0
}

/// Adds `m` unless the same marker is already there at the same place with fewer errors (or as few and a
/// longer outline: the outer edge of its border rather than an inner one).
fn keep_best(found: &mut Vec<(DetectedMarker, f64)>, m: DetectedMarker, length: f64) {
    let centre = |c: &[[f64; 2]; 4]| {
        [
            (c[0][0] + c[1][0] + c[2][0] + c[3][0]) / 4.0,
            (c[0][1] + c[1][1] + c[2][1] + c[3][1]) / 4.0,
        ]
    };
    let cm = centre(&m.corners);
    let near = side_mean(&m.corners) * 0.5;
    if let Some(i) = found.iter().position(|(f, _)| {
        let cf = centre(&f.corners);
        f.id == m.id && ((cf[0] - cm[0]).powi(2) + (cf[1] - cm[1]).powi(2)).sqrt() < near
    }) {
        let (old, old_length) = &found[i];
        if (m.bit_errors, -length) < (old.bit_errors, -*old_length) {
            found[i] = (m, length);
        }
    } else {
        found.push((m, length));
    }
}
