//! A calibration board printed on paper and lying on the board's top face: black ink where the board is
//! black, white paper over the pattern and a margin around it. The pattern's centre is the world's origin,
//! as FORMATS.md's "Boards" fixes the world frame of real footage.

use calib::Board;

/// The ink's and the paper's albedo (linear): toner is not pure black, paper not pure white.
const INK: [f64; 3] = [0.035, 0.035, 0.04];
const PAPER: [f64; 3] = [0.80, 0.80, 0.78];

/// A printed board on the plane z = 0.
#[derive(Clone, Debug)]
pub struct Print {
    pub board: Board,
    /// Paper beyond the pattern on every side, metres.
    pub margin: f64,
}

impl Print {
    /// The albedo at world `(x, y)` on the top face, or `None` off the paper.
    pub fn albedo(&self, x: f64, y: f64) -> Option<[f64; 3]> {
        let [w, h] = self.board.extent;
        // OpenCV's board frame: from the pattern's top-left, y down the print.
        let (u, v) = (x + w / 2.0, h / 2.0 - y);
        if u < -self.margin || v < -self.margin || u > w + self.margin || v > h + self.margin {
            return None;
        }
        Some(if self.board.is_black([u, v]) { INK } else { PAPER })
    }

    /// Half the paper's size, metres.
    pub fn half_paper(&self) -> [f64; 2] {
        [
            self.board.extent[0] / 2.0 + self.margin,
            self.board.extent[1] / 2.0 + self.margin,
        ]
    }
}
