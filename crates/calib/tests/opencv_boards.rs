//! The boards this crate draws are OpenCV's, pixel for pixel.
//!
//! The fast test compares with images OpenCV 4.12 drew (`tests/data/boards/`, made by
//! `tests/opencv/reference.py boards`); the slow one asks OpenCV itself for many more boards (the Python of
//! `PGANEUS_OPENCV_PYTHON`, else `python3`, with opencv-contrib-python-headless, as `.ci/run` installs it).

use crate::common;

use std::path::{Path, PathBuf};

use common::opencv_reference;

use calib::board::{Board, BoardKind, BoardSpec};
use calib::draw::board_image;
use serde_json::{json, Value};

fn spec_of(case: &Value) -> BoardSpec {
    let kind = match case["kind"].as_str().unwrap() {
        "aruco_grid" => BoardKind::ArucoGrid,
        _ => BoardKind::Charuco,
    };
    BoardSpec {
        kind,
        dictionary: case["dictionary"].as_str().unwrap().into(),
        size: [
            case["size"][0].as_u64().unwrap() as u32,
            case["size"][1].as_u64().unwrap() as u32,
        ],
        marker_length: case["marker_length"].as_f64().unwrap(),
        marker_separation: case["marker_separation"].as_f64(),
        square_length: case["square_length"].as_f64(),
        legacy: case["legacy"].as_bool().unwrap_or(false),
        first_id: case["first_id"].as_u64().unwrap() as usize,
    }
}

/// Each case drawn here against OpenCV's image in `dir` (or OpenCV's refusal listed in `dir/refused.json`).
fn compare_with(cases: &[Value], dir: &Path) -> (usize, usize) {
    let refused: Vec<String> =
        serde_json::from_str(&std::fs::read_to_string(dir.join("refused.json")).unwrap()).unwrap();
    let (mut drawn, mut refusals) = (0, 0);
    for case in cases {
        let name = case["name"].as_str().unwrap();
        let board = Board::new(spec_of(case)).unwrap();
        let (w, h, m) = (
            case["width"].as_u64().unwrap(),
            case["height"].as_u64().unwrap(),
            case["margin"].as_u64().unwrap(),
        );
        let ours = board_image(&board, w as u32, h as u32, m as u32);
        if refused.iter().any(|r| r == name) {
            assert!(
                ours.is_none(),
                "{name}: OpenCV refuses to draw this board at {w} x {h}, we drew it"
            );
            refusals += 1;
            continue;
        }
        let ours = ours.unwrap_or_else(|| panic!("{name}: OpenCV draws this board at {w} x {h}, we refused"));
        let theirs = pganeus_io::read_png(&dir.join(format!("{name}.png")))
            .unwrap()
            .to_gray();
        assert_eq!((ours.width, ours.height), (theirs.width, theirs.height), "{name}");
        let differing = ours.data.iter().zip(&theirs.data).filter(|(a, b)| a != b).count();
        if differing > 0 {
            let _ = pganeus_io::write_png(&std::env::temp_dir().join(format!("ours_{name}.png")), &ours);
            let first = ours.data.iter().zip(&theirs.data).position(|(a, b)| a != b).unwrap();
            panic!(
                "{name}: {differing} pixels differ from OpenCV's, the first at x = {}, y = {}",
                first % w as usize,
                first / w as usize
            );
        }
        drawn += 1;
    }
    (drawn, refusals)
}

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/boards")
}

#[test]
fn boards_equal_the_images_opencv_drew() {
    let cases: Vec<Value> =
        serde_json::from_str(&std::fs::read_to_string(data_dir().join("cases.json")).unwrap()).unwrap();
    let (drawn, refused) = compare_with(&cases, &data_dir());
    assert_eq!((drawn, refused), (5, 1));
}

#[test]
#[ignore = "slow: asks OpenCV (Python) to draw 60 boards (a second: slow only for needing Python and OpenCV)"]
fn boards_equal_opencvs_for_many_specs() {
    let mut rng = geom::SplitMix64::new(67);
    let dictionaries = [
        "DICT_4X4_50",
        "DICT_4X4_1000",
        "DICT_5X5_250",
        "DICT_5X5_1000",
        "DICT_6X6_100",
        "DICT_6X6_1000",
        "DICT_7X7_50",
        "DICT_ARUCO_ORIGINAL",
        "DICT_APRILTAG_36h11",
        "DICT_APRILTAG_25h9",
    ];
    let mut cases = Vec::new();
    for i in 0..60 {
        let dictionary = dictionaries[i % dictionaries.len()];
        let charuco = i % 2 == 1;
        let cols = 2 + (rng.next_u64() % 7) as u32;
        let rows = 2 + (rng.next_u64() % 7) as u32;
        let marker_length = rng.range(0.01, 0.08);
        let width = 200 + (rng.next_u64() % 900) as u32;
        let height = 200 + (rng.next_u64() % 900) as u32;
        let margin = (rng.next_u64() % 30) as u32;
        let mut case = json!({
            "name": format!("case{i:02}"), "dictionary": dictionary, "size": [cols, rows],
            "marker_length": marker_length, "first_id": 0, "width": width, "height": height, "margin": margin,
        });
        if charuco {
            case["kind"] = json!("charuco");
            case["square_length"] = json!(marker_length * rng.range(1.15, 1.8));
            case["legacy"] = json!(rng.next_u64().is_multiple_of(3));
        } else {
            case["kind"] = json!("aruco_grid");
            case["marker_separation"] = json!(marker_length * rng.range(0.1, 0.5));
        }
        // Boards of more markers than the dictionary holds are not boards.
        let Ok(board) = Board::new(spec_of(&case)) else {
            continue;
        };
        if !i.is_multiple_of(3) {
            // Most at the board's own proportions (as `pganeus board` draws), a third at any size.
            let (w, m) = (width as f64, margin as f64);
            case["height"] = json!(((w - 2.0 * m) * board.extent[1] / board.extent[0] + 2.0 * m)
                .round()
                .max(3.0 * m + 20.0) as u64);
        }
        cases.push(case);
    }
    let dir = testkit::scratch_dir("calib", "opencv_boards");
    std::fs::write(dir.join("cases.json"), serde_json::to_string(&cases).unwrap()).unwrap();
    let version = opencv_reference("boards", &dir.join("cases.json"), &dir);
    let (drawn, refused) = compare_with(&cases, &dir);
    eprintln!("OpenCV {version}: {drawn} boards equal, {refused} refused by both");
    assert!(
        drawn >= 35 && drawn + refused == cases.len(),
        "only {drawn} of {} cases drawn",
        cases.len()
    );
}
