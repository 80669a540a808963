//! Markers found in rendered views of a board: every fully visible marker, no other id, corners near the
//! truth.

use crate::common;

use calib::board_views::{render, View};
use calib::detect::{detect_markers, DetectorSettings};
use calib::{Board, BoardSpec};
use common::opencv_reference;
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

/// OpenCV's detections of the images `cases` lists (`[{"image", "dictionary"}]`), by `tests/opencv/reference.py`.
fn opencv_detections(dir: &Path, cases: &serde_json::Value) -> (serde_json::Value, String) {
    std::fs::write(dir.join("cases.json"), cases.to_string()).unwrap();
    let version = opencv_reference("detect", &dir.join("cases.json"), &dir.join("opencv.json"));
    let json = serde_json::from_str(&std::fs::read_to_string(dir.join("opencv.json")).unwrap()).unwrap();
    (json, version)
}

#[test]
#[ignore = "slow: OpenCV's ArucoDetector (Python) on 12 rendered views"]
fn the_same_markers_as_opencv_and_corners_as_its_or_better() {
    use calib::detect::{Refine, SubpixRule};
    let boards = [
        board("kind = \"aruco_grid\"\ndictionary = \"DICT_5X5_1000\"\nsize = [7, 5]\nmarker_length = 0.035\nmarker_separation = 0.007\n"),
        board("kind = \"charuco\"\ndictionary = \"DICT_6X6_250\"\nsize = [7, 5]\nmarker_length = 0.03\nsquare_length = 0.04\n"),
    ];
    let dir = testkit::scratch_dir("calib", "opencv_detect");
    let size = (640, 480);
    let mut cases = Vec::new();
    let mut scenes = Vec::new();
    for (bi, b) in boards.iter().enumerate() {
        for (k, &(distance, tilt, azimuth, roll)) in VIEWS.iter().enumerate() {
            let view = View::looking_at(b, 600.0, size, distance, tilt, azimuth, roll);
            let gray = render(b, &view, size, 6, 2.0, (bi * 10 + k) as u64);
            let mut png = pganeus_io::Image::new(size.0 as u32, size.1 as u32, 1);
            for (o, v) in png.data.iter_mut().zip(&gray.data) {
                *o = v.round() as u8;
            }
            let path = dir.join(format!("view_{bi}_{k}.png"));
            pganeus_io::write_png(&path, &png).unwrap();
            cases.push(serde_json::json!({"image": path.to_string_lossy(), "dictionary": b.dictionary.name}));
            scenes.push((bi, view, path));
        }
    }
    let (opencv, version) = opencv_detections(&dir, &serde_json::Value::Array(cases));
    let dist = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    let (mut to_opencv, mut ours_err, mut theirs_err) = (Vec::new(), Vec::new(), Vec::new());
    for (bi, view, path) in &scenes {
        let b = &boards[*bi];
        let gray = calib::gray::Gray::from_image(&pganeus_io::read_png(path).unwrap());
        let theirs = &opencv[path.to_string_lossy().as_ref()];
        let their_ids: Vec<usize> = theirs["ids"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as usize)
            .collect();
        let their_corners = |id: usize| -> [[f64; 2]; 4] {
            let i = their_ids.iter().position(|&t| t == id).unwrap();
            let c = &theirs["corners"][i];
            [0, 1, 2, 3].map(|k| [c[k][0].as_f64().unwrap(), c[k][1].as_f64().unwrap()])
        };
        let opencv_rule = DetectorSettings {
            refine: Refine::Subpix(SubpixRule::OPENCV),
            ..DetectorSettings::default()
        };
        let like_opencv = detect_markers(&gray, b.dictionary, &opencv_rule);
        let ours = detect_markers(&gray, b.dictionary, &DetectorSettings::default());
        let mut our_ids: Vec<usize> = ours.iter().map(|m| m.id).collect();
        let mut sorted_theirs = their_ids.clone();
        our_ids.sort();
        sorted_theirs.sort();
        assert_eq!(our_ids, sorted_theirs, "{}: the same markers as OpenCV", path.display());
        for (m, o) in like_opencv.iter().zip(&ours) {
            let theirs = their_corners(m.id);
            let truth = b.marker(m.id).unwrap().corners.map(|c| view.project(c));
            for k in 0..4 {
                to_opencv.push(dist(m.corners[k], theirs[k]));
                ours_err.push(dist(o.corners[k], truth[k]));
                theirs_err.push(dist(theirs[k], truth[k]));
            }
        }
    }
    // Where the two outlines' Douglas-Peucker vertices differ by a pixel, cornerSubPix (stopping at 0.1 px
    // steps, on a biased landscape) ends elsewhere: a few corners.
    let within = to_opencv.iter().filter(|&&d| d <= 0.1).count() as f64 / to_opencv.len() as f64;
    let (to_med, to_max) = summary(&mut to_opencv);
    let (our_med, our_max) = summary(&mut ours_err);
    let (their_med, their_max) = summary(&mut theirs_err);
    eprintln!(
        "OpenCV {version}: {} corners; our cornerSubPix vs OpenCV's: median {to_med:.4} px, {:.1} % within 0.1 px, worst {to_max:.3} px; \
         from the truth: ours (edges) median {our_med:.3} px, worst {our_max:.3} px; OpenCV's median {their_med:.3} px, worst {their_max:.3} px",
        to_opencv.len(),
        within * 100.0
    );
    assert!(
        to_med < 0.01 && within > 0.95,
        "OpenCV's refinement rule here and in OpenCV: median {to_med:.3} px, {within:.3} within 0.1 px"
    );
    assert!(
        our_med < their_med && our_max < their_max,
        "ours {our_med:.3}/{our_max:.3} px, OpenCV's {their_med:.3}/{their_max:.3} px"
    );
}

#[test]
fn chessboard_corners_of_a_charuco_board_are_found_between_its_markers() {
    let b = board(
        "kind = \"charuco\"\ndictionary = \"DICT_4X4_50\"\nsize = [7, 5]\nmarker_length = 0.03\nsquare_length = 0.04\n",
    );
    let size = (640, 480);
    let mut errors = Vec::new();
    for (k, &(distance, tilt, azimuth, roll)) in VIEWS.iter().enumerate() {
        let view = View::looking_at(&b, 600.0, size, distance, tilt, azimuth, roll);
        let image = render(&b, &view, size, 4, 2.0, k as u64);
        let markers = detect_markers(&image, b.dictionary, &DetectorSettings::default());
        let corners = calib::charuco::chessboard_corners(&image, &b, &markers);
        let inside =
            |p: [f64; 2]| p[0] > 30.0 && p[1] > 30.0 && p[0] < size.0 as f64 - 30.0 && p[1] < size.1 as f64 - 30.0;
        let visible = b
            .chessboard_corners
            .iter()
            .filter(|c| inside(view.project(**c)))
            .count();
        assert!(
            corners.len() * 10 >= visible * 9,
            "view {k}: {} of {visible} corners",
            corners.len()
        );
        for c in &corners {
            let t = view.project(b.chessboard_corners[c.id]);
            errors.push(((c.image[0] - t[0]).powi(2) + (c.image[1] - t[1]).powi(2)).sqrt());
        }
    }
    let (median, worst) = summary(&mut errors);
    eprintln!(
        "chessboard corners: {} found, median {median:.3} px, worst {worst:.3} px",
        errors.len()
    );
    assert!(
        median < 0.1 && worst < 0.5,
        "median {median:.3} px, worst {worst:.3} px"
    );
}
