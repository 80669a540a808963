//! A printed board: its file (`board.toml`, FORMATS.md "Boards") and its geometry in metres.
//!
//! Two frames. OpenCV's board frame (what `GridBoard`/`CharucoBoard` use): origin at the pattern's top-left,
//! x to the right, y down the printed image. The world frame of every capture: origin at the centre of the
//! pattern, x to the right, y toward the printed image's top, z out of the printed face.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::dictionary::{self, Dictionary};
use crate::error::{CalibError, Result};

/// Which of OpenCV's boards.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BoardKind {
    /// `cv::aruco::GridBoard`: markers in a grid, `marker_separation` apart.
    ArucoGrid,
    /// `cv::aruco::CharucoBoard`: a chessboard with a marker in each white square.
    Charuco,
}

/// A board file as written (see FORMATS.md "Boards").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardSpec {
    /// Grid of markers or ChArUco.
    pub kind: BoardKind,
    /// OpenCV's name of the dictionary, e.g. `DICT_5X5_1000`.
    pub dictionary: String,
    /// Markers (aruco_grid) or squares (charuco): columns, rows.
    pub size: [u32; 2],
    /// Metres, the printed black square of one marker.
    pub marker_length: f64,
    /// Metres between markers (aruco_grid).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub marker_separation: Option<f64>,
    /// Metres, one chessboard square (charuco).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub square_length: Option<f64>,
    /// ChArUco as OpenCV drew it before 4.6 (boards with an even number of rows start with a white square).
    #[serde(default)]
    pub legacy: bool,
    /// The id of the first marker; the ids run row by row from the printed image's top-left.
    #[serde(default)]
    pub first_id: usize,
}

/// One marker of a board.
#[derive(Clone, Debug)]
pub struct BoardMarker {
    /// The marker's id in the dictionary.
    pub id: usize,
    /// Its corners in OpenCV's board frame (metres): top-left, top-right, bottom-right, bottom-left as printed.
    pub corners: [[f64; 2]; 4],
}

/// A board, resolved: its dictionary, its markers and (ChArUco) chessboard corners.
#[derive(Clone, Debug)]
pub struct Board {
    /// The spec it came from.
    pub spec: BoardSpec,
    /// The dictionary its markers come from.
    pub dictionary: &'static Dictionary,
    /// Its markers, row by row from the top-left.
    pub markers: Vec<BoardMarker>,
    /// ChArUco only: the inner chessboard corners in OpenCV's board frame, row by row (OpenCV's ChArUco ids).
    pub chessboard_corners: Vec<[f64; 2]>,
    /// The pattern's extent in OpenCV's board frame (metres): width and height.
    pub extent: [f64; 2],
    /// For each grid place (marker of a grid, square of a ChArUco board), row by row: its marker's index.
    places: Vec<Option<usize>>,
}

impl BoardSpec {
    /// Reads and checks a board file.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|cause| CalibError::Read {
            path: path.to_path_buf(),
            cause,
        })?;
        let spec: BoardSpec = toml::from_str(&text).map_err(|e| CalibError::BoardSpec {
            path: path.to_path_buf(),
            msg: e.to_string(),
        })?;
        spec.check().map_err(|msg| CalibError::BoardSpec {
            path: path.to_path_buf(),
            msg,
        })?;
        Ok(spec)
    }

    /// Parses a board file's text (`origin` names it in errors).
    pub fn parse(text: &str, origin: &Path) -> Result<Self> {
        let spec: BoardSpec = toml::from_str(text).map_err(|e| CalibError::BoardSpec {
            path: origin.to_path_buf(),
            msg: e.to_string(),
        })?;
        spec.check().map_err(|msg| CalibError::BoardSpec {
            path: origin.to_path_buf(),
            msg,
        })?;
        Ok(spec)
    }

    /// What is wrong with the spec, in words a user can act on.
    pub fn check(&self) -> std::result::Result<(), String> {
        let Some(dictionary) = dictionary::by_name(&self.dictionary) else {
            return Err(format!(
                "unknown dictionary `{}`; OpenCV's predefined ones are: {}",
                self.dictionary,
                dictionary::names().join(", ")
            ));
        };
        let [cols, rows] = self.size;
        if cols == 0 || rows == 0 {
            return Err(format!(
                "size = [{cols}, {rows}]: a board needs at least one column and one row"
            ));
        }
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{name} = {v}: must be a positive length in metres"))
            }
        };
        positive("marker_length", self.marker_length)?;
        if self.marker_length > 1.0 {
            return Err(format!(
                "marker_length = {} m: lengths are in metres (a 60 mm marker is 0.060)",
                self.marker_length
            ));
        }
        match self.kind {
            BoardKind::ArucoGrid => {
                let Some(separation) = self.marker_separation else {
                    return Err("kind = \"aruco_grid\" needs marker_separation (metres between markers)".into());
                };
                positive("marker_separation", separation)?;
                if self.square_length.is_some() {
                    return Err("square_length is for kind = \"charuco\"; an aruco_grid has marker_separation".into());
                }
                if self.legacy {
                    return Err("legacy is for kind = \"charuco\" (the chessboard's pre-4.6 colouring)".into());
                }
            }
            BoardKind::Charuco => {
                let Some(square) = self.square_length else {
                    return Err("kind = \"charuco\" needs square_length (metres, one chessboard square)".into());
                };
                positive("square_length", square)?;
                if self.marker_length >= square {
                    return Err(format!(
                        "marker_length = {} must be smaller than square_length = {square}",
                        self.marker_length
                    ));
                }
                if self.marker_separation.is_some() {
                    return Err(
                        "marker_separation is for kind = \"aruco_grid\"; a charuco board has square_length".into(),
                    );
                }
                if cols < 2 || rows < 2 {
                    return Err(format!(
                        "size = [{cols}, {rows}]: a ChArUco board needs at least 2 x 2 squares"
                    ));
                }
            }
        }
        let markers = self.marker_count();
        if self.first_id + markers > dictionary.len() {
            return Err(format!(
                "the board needs ids {}..{} but {} has {} markers",
                self.first_id,
                self.first_id + markers - 1,
                dictionary.name,
                dictionary.len()
            ));
        }
        Ok(())
    }

    /// Markers on the board.
    pub fn marker_count(&self) -> usize {
        let [cols, rows] = self.size.map(|v| v as usize);
        match self.kind {
            BoardKind::ArucoGrid => cols * rows,
            BoardKind::Charuco => (0..rows)
                .map(|y| (0..cols).filter(|&x| self.charuco_has_marker(x, y)).count())
                .sum(),
        }
    }

    /// Whether ChArUco square (column `x`, row `y`) is white and holds a marker.
    pub(crate) fn charuco_has_marker(&self, x: usize, y: usize) -> bool {
        if self.legacy && self.size[1].is_multiple_of(2) {
            (y + 1) % 2 != x % 2
        } else {
            y % 2 != x % 2
        }
    }
}

impl Board {
    /// The board a checked spec describes.
    pub fn new(spec: BoardSpec) -> Result<Self> {
        spec.check().map_err(|msg| CalibError::BoardSpec {
            path: "board spec".into(),
            msg,
        })?;
        let dictionary = dictionary::by_name(&spec.dictionary).expect("checked");
        let [cols, rows] = spec.size.map(|v| v as usize);
        let ml = spec.marker_length;
        let square = |x0: f64, y0: f64| [[x0, y0], [x0 + ml, y0], [x0 + ml, y0 + ml], [x0, y0 + ml]];
        let mut markers = Vec::new();
        let mut chessboard_corners = Vec::new();
        let mut places = Vec::with_capacity(cols * rows);
        let extent = match spec.kind {
            BoardKind::ArucoGrid => {
                let step = ml + spec.marker_separation.expect("checked");
                for y in 0..rows {
                    for x in 0..cols {
                        places.push(Some(markers.len()));
                        markers.push(BoardMarker {
                            id: spec.first_id + markers.len(),
                            corners: square(x as f64 * step, y as f64 * step),
                        });
                    }
                }
                [cols as f64 * step - (step - ml), rows as f64 * step - (step - ml)]
            }
            BoardKind::Charuco => {
                let sq = spec.square_length.expect("checked");
                let inset = (sq - ml) / 2.0;
                for y in 0..rows {
                    for x in 0..cols {
                        places.push(spec.charuco_has_marker(x, y).then_some(markers.len()));
                        if spec.charuco_has_marker(x, y) {
                            markers.push(BoardMarker {
                                id: spec.first_id + markers.len(),
                                corners: square(x as f64 * sq + inset, y as f64 * sq + inset),
                            });
                        }
                    }
                }
                for y in 1..rows {
                    for x in 1..cols {
                        chessboard_corners.push([x as f64 * sq, y as f64 * sq]);
                    }
                }
                [cols as f64 * sq, rows as f64 * sq]
            }
        };
        Ok(Board {
            spec,
            dictionary,
            markers,
            chessboard_corners,
            extent,
            places,
        })
    }

    /// Whether the printed board is black at `p` (OpenCV's board frame, metres); white off the pattern.
    pub fn is_black(&self, p: [f64; 2]) -> bool {
        let [cols, rows] = self.spec.size.map(|v| v as usize);
        let ml = self.spec.marker_length;
        let (pitch, inset) = match self.spec.kind {
            BoardKind::ArucoGrid => (ml + self.spec.marker_separation.unwrap_or(0.0), 0.0),
            BoardKind::Charuco => {
                let sq = self.spec.square_length.unwrap_or(1.0);
                (sq, (sq - ml) / 2.0)
            }
        };
        if !(p[0] >= 0.0 && p[1] >= 0.0) {
            return false;
        }
        let (ix, iy) = ((p[0] / pitch).floor() as usize, (p[1] / pitch).floor() as usize);
        if ix >= cols || iy >= rows {
            return false;
        }
        let Some(m) = self.places[iy * cols + ix] else {
            return true; // a black square of a ChArUco board
        };
        let (u, v) = (p[0] - ix as f64 * pitch - inset, p[1] - iy as f64 * pitch - inset);
        if !(u >= 0.0 && v >= 0.0 && u < ml && v < ml) {
            return false;
        }
        let n = self.dictionary.marker_size;
        let cells = n + 2 * crate::dictionary::BORDER_BITS;
        let (col, row) = ((u / ml * cells as f64) as usize, (v / ml * cells as f64) as usize);
        let b = crate::dictionary::BORDER_BITS;
        if col < b || row < b || col >= cells - b || row >= cells - b {
            return true;
        }
        !self.dictionary.bit(self.markers[m].id, (row - b) * n + (col - b))
    }

    /// Reads, checks and resolves a board file.
    pub fn read(path: &Path) -> Result<Self> {
        Board::new(BoardSpec::read(path)?)
    }

    /// A point of OpenCV's board frame in the world frame (z = 0 on the printed face).
    pub fn to_world(&self, p: [f64; 2]) -> [f64; 3] {
        [p[0] - self.extent[0] / 2.0, self.extent[1] / 2.0 - p[1], 0.0]
    }

    /// The index (in [`Board::markers`]) of the marker in grid place (column `x`, row `y`): a grid's marker or
    /// a ChArUco square's; `None` for a black square or a place off the board.
    pub fn marker_in_square(&self, x: usize, y: usize) -> Option<usize> {
        let [cols, rows] = self.spec.size.map(|v| v as usize);
        if x >= cols || y >= rows {
            return None;
        }
        self.places[y * cols + x]
    }

    /// The world-to-camera pose of a camera whose board-to-camera pose is `rotation`, `translation`.
    /// World: `p_world = M p_board + o` with `M = diag(1, -1, -1)` (y up, z out of the face) and `o` moving the
    /// pattern's top-left to `(-w/2, h/2, 0)`.
    pub fn world_to_camera(&self, rotation: geom::Quat<f64>, translation: geom::Vec3<f64>) -> geom::Pose<f64> {
        // p_cam = R p_board + t = R M (p_world - o) + t
        let flip = geom::Quat::new(0.0, 1.0, 0.0, 0.0); // 180 degrees about x: diag(1, -1, -1)
        let r = rotation * flip;
        let o = geom::Vec3::new(-self.extent[0] / 2.0, self.extent[1] / 2.0, 0.0);
        geom::Pose::new(r, translation - r.rotate(o))
    }

    /// The marker with this id, if it is on the board.
    pub fn marker(&self, id: usize) -> Option<&BoardMarker> {
        id.checked_sub(self.spec.first_id).and_then(|i| self.markers.get(i))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(text: &str) -> std::result::Result<BoardSpec, String> {
        BoardSpec::parse(text, Path::new("board.toml")).map_err(|e| e.to_string())
    }

    #[test]
    fn the_formats_example_parses_and_centres_the_world() {
        let s = spec(
            "kind = \"aruco_grid\"\ndictionary = \"DICT_5X5_1000\"\nsize = [8, 6]\nmarker_length = 0.060\nmarker_separation = 0.012\n",
        )
        .unwrap();
        let board = Board::new(s).unwrap();
        assert_eq!(board.markers.len(), 48);
        assert!((board.extent[0] - (8.0 * 0.072 - 0.012)).abs() < 1e-12);
        // The top-left corner of the first marker is at the world's top-left (x < 0, y > 0).
        let w = board.to_world(board.markers[0].corners[0]);
        assert!((w[0] + board.extent[0] / 2.0).abs() < 1e-12 && (w[1] - board.extent[1] / 2.0).abs() < 1e-12);
        assert_eq!(board.marker(47).unwrap().id, 47);
    }

    #[test]
    fn the_world_pose_sees_the_board_where_its_board_pose_does() {
        let board = Board::new(spec("kind = \"aruco_grid\"\ndictionary = \"DICT_4X4_50\"\nsize = [3, 2]\nmarker_length = 0.04\nmarker_separation = 0.01\n").unwrap()).unwrap();
        let rotation = geom::Quat::exp(geom::Vec3::new(0.3, -0.2, 0.9));
        let translation = geom::Vec3::new(0.02, -0.05, 0.5);
        let pose = board.world_to_camera(rotation, translation);
        for p in [[0.0, 0.0], [0.04, 0.09], [0.14, 0.01]] {
            let seen = rotation.rotate(geom::Vec3::new(p[0], p[1], 0.0)) + translation;
            let w = board.to_world(p);
            let via_world = pose.transform_point(geom::Vec3::new(w[0], w[1], w[2]));
            assert!((seen - via_world).norm() < 1e-12);
        }
    }

    #[test]
    fn charuco_places_markers_on_the_white_squares() {
        let s = spec(
            "kind = \"charuco\"\ndictionary = \"DICT_4X4_50\"\nsize = [5, 4]\nmarker_length = 0.03\nsquare_length = 0.04\n",
        )
        .unwrap();
        let board = Board::new(s.clone()).unwrap();
        // OpenCV >= 4.6: square (0, 0) is black, so the first marker is in square (1, 0).
        assert_eq!(board.markers.len(), 10);
        assert!((board.markers[0].corners[0][0] - 0.045).abs() < 1e-12);
        assert_eq!(board.chessboard_corners.len(), 4 * 3);
        let legacy = Board::new(BoardSpec { legacy: true, ..s }).unwrap();
        assert!(
            (legacy.markers[0].corners[0][0] - 0.005).abs() < 1e-12,
            "legacy: square (0, 0) is white"
        );
    }

    #[test]
    fn bad_specs_say_what_to_fix() {
        let bad = [
            ("kind = \"aruco_grid\"\ndictionary = \"DICT_9X9\"\nsize = [2, 2]\nmarker_length = 0.05\nmarker_separation = 0.01\n", "unknown dictionary"),
            ("kind = \"aruco_grid\"\ndictionary = \"DICT_4X4_50\"\nsize = [2, 2]\nmarker_length = 0.05\n", "needs marker_separation"),
            ("kind = \"aruco_grid\"\ndictionary = \"DICT_4X4_50\"\nsize = [8, 8]\nmarker_length = 0.05\nmarker_separation = 0.01\n", "has 50 markers"),
            ("kind = \"charuco\"\ndictionary = \"DICT_4X4_50\"\nsize = [5, 5]\nmarker_length = 0.05\nsquare_length = 0.04\n", "smaller than square_length"),
            ("kind = \"aruco_grid\"\ndictionary = \"DICT_4X4_50\"\nsize = [2, 2]\nmarker_length = 60\nmarker_separation = 10\n", "metres"),
            ("kind = \"grid\"\n", "unknown variant"),
            ("kind = \"aruco_grid\"\ndictionary = \"DICT_4X4_50\"\nsize = [2, 2]\nmarker_length = 0.05\nmarker_separation = 0.01\nmarker_size = 3\n", "unknown field"),
        ];
        for (text, want) in bad {
            let err = spec(text).unwrap_err();
            assert!(err.contains(want) && err.contains("board.toml"), "{err}");
        }
    }
}
