//! ChArUco corners: each inner chessboard corner predicted from the detected markers in the two white
//! squares beside it (the homography of their corners), then refined by `cornerSubPix`, which is unbiased at
//! a chessboard's X-shaped corner.

use crate::board::{Board, BoardKind};
use crate::detect::DetectedMarker;
use crate::gray::Gray;
use crate::homography;
use crate::subpix::{corner_subpix, SubpixSettings};

/// A chessboard corner found in an image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChessCorner {
    /// Its index in [`Board::chessboard_corners`] (OpenCV's ChArUco id).
    pub id: usize,
    /// Where it is seen, pixels.
    pub image: [f64; 2],
}

/// The inner corners of a ChArUco board with both neighbouring markers detected; empty for other boards.
pub fn chessboard_corners(gray: &Gray, board: &Board, markers: &[DetectedMarker]) -> Vec<ChessCorner> {
    if board.spec.kind != BoardKind::Charuco {
        return Vec::new();
    }
    let sq = board.spec.square_length.expect("charuco");
    let mut out = Vec::new();
    for (id, corner) in board.chessboard_corners.iter().enumerate() {
        // The chessboard corner (x, y) touches squares (x-1..x, y-1..y) of the board, two of them white.
        let (x, y) = ((corner[0] / sq).round() as usize, (corner[1] / sq).round() as usize);
        let mut from = Vec::new();
        let mut to = Vec::new();
        for (sx, sy) in [(x - 1, y - 1), (x, y - 1), (x - 1, y), (x, y)] {
            let Some(index) = board.marker_in_square(sx, sy) else {
                continue;
            };
            let marker = &board.markers[index];
            if let Some(found) = markers.iter().find(|m| m.id == marker.id) {
                from.extend_from_slice(&marker.corners);
                to.extend_from_slice(&found.corners);
            }
        }
        if from.len() < 8 {
            continue; // both markers beside the corner are needed
        }
        let Some(h) = homography::fit(&from, &to) else { continue };
        let predicted = homography::apply(&h, *corner);
        // The window stays clear of the markers' edges: under half the way to the nearest marker corner.
        let nearest = to
            .iter()
            .map(|p| ((p[0] - predicted[0]).powi(2) + (p[1] - predicted[1]).powi(2)).sqrt())
            .fold(f64::INFINITY, f64::min);
        let half_window = ((0.5 * nearest).floor() as usize).clamp(2, 10);
        if !(predicted[0] > half_window as f64 + 1.0
            && predicted[1] > half_window as f64 + 1.0
            && predicted[0] < (gray.width - half_window - 2) as f64
            && predicted[1] < (gray.height - half_window - 2) as f64)
        {
            continue;
        }
        let settings = SubpixSettings {
            half_window,
            max_iterations: 50,
            min_step: 0.001,
        };
        let refined = corner_subpix(gray, predicted, &settings);
        if refined == predicted {
            continue; // the refinement left its window: no chessboard corner here
        }
        out.push(ChessCorner { id, image: refined });
    }
    out
}
