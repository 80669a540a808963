//! Markers found in rendered views of a board: every fully visible marker, no other id, corners near the
//! truth.

mod common;

use calib::detect::{detect_markers, DetectorSettings};
use calib::{Board, BoardSpec};
use common::{render, View};
use std::path::Path;

fn board(text: &str) -> Board {
    Board::new(BoardSpec::parse(text, Path::new("board.toml")).unwrap()).unwrap()
}

/// Detects in each view; returns every corner's distance to the truth.
fn check_views(board: &Board, views: &[(f64, f64, f64, f64)], noise: f64) -> Vec<f64> {
    let size = (640, 480);
    let mut errors = Vec::new();
    for (k, &(distance, tilt, azimuth, roll)) in views.iter().enumerate() {
        let view = View::looking_at(board, 600.0, size, distance, tilt, azimuth, roll);
        let image = render(board, &view, size, 4, noise, k as u64);
        let found = detect_markers(&image, board.dictionary, &DetectorSettings::default());
        let inside = |p: [f64; 2]| p[0] > 4.0 && p[1] > 4.0 && p[0] < size.0 as f64 - 5.0 && p[1] < size.1 as f64 - 5.0;
        let visible: Vec<usize> = board
            .markers
            .iter()
            .filter(|m| m.corners.iter().all(|&c| inside(view.project(c))))
            .map(|m| m.id)
            .collect();
        for m in &found {
            let truth = board
                .marker(m.id)
                .unwrap_or_else(|| panic!("view {k}: id {} is not on the board", m.id));
            for (c, t) in m.corners.iter().zip(&truth.corners) {
                let p = view.project(*t);
                errors.push(((c[0] - p[0]).powi(2) + (c[1] - p[1]).powi(2)).sqrt());
            }
        }
        let missed: Vec<usize> = visible
            .iter()
            .filter(|id| !found.iter().any(|m| m.id == **id))
            .copied()
            .collect();
        assert!(
            missed.is_empty(),
            "view {k} ({distance} m, tilt {tilt:.2}, roll {roll:.2}): missed {missed:?} of {}",
            visible.len()
        );
    }
    errors
}

fn summary(errors: &mut [f64]) -> (f64, f64) {
    errors.sort_by(f64::total_cmp);
    (errors[errors.len() / 2], errors[errors.len() - 1])
}

const VIEWS: [(f64, f64, f64, f64); 6] = [
    (0.45, 0.0, 0.0, 0.0),
    (0.5, 0.5, 0.3, 0.4),
    (0.55, 0.8, 2.0, -1.2),
    (0.4, 0.3, -1.0, 2.6),
    (0.6, 0.9, 1.0, 0.1),
    (0.5, 0.6, 3.5, -2.9),
];

#[test]
fn every_visible_marker_of_a_grid_is_found_with_subpixel_corners() {
    let b = board("kind = \"aruco_grid\"\ndictionary = \"DICT_5X5_1000\"\nsize = [7, 5]\nmarker_length = 0.035\nmarker_separation = 0.007\n");
    let mut errors = check_views(&b, &VIEWS, 2.0);
    let (median, worst) = summary(&mut errors);
    eprintln!(
        "aruco grid: {} corners, median {median:.3} px, worst {worst:.3} px",
        errors.len()
    );
    assert!(
        median < 0.1 && worst < 0.5,
        "median {median:.3} px, worst {worst:.3} px"
    );
}

#[test]
fn every_visible_marker_of_a_charuco_board_is_found() {
    let b = board(
        "kind = \"charuco\"\ndictionary = \"DICT_4X4_50\"\nsize = [7, 5]\nmarker_length = 0.03\nsquare_length = 0.04\n",
    );
    let mut errors = check_views(&b, &VIEWS, 2.0);
    let (median, worst) = summary(&mut errors);
    eprintln!(
        "charuco: {} corners, median {median:.3} px, worst {worst:.3} px",
        errors.len()
    );
    assert!(
        median < 0.1 && worst < 0.5,
        "median {median:.3} px, worst {worst:.3} px"
    );
}
