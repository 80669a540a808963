//! A board's printable image: a raster exactly as OpenCV's `Board::generateImage` draws it (OpenCV 4.7 and
//! later; checked against 4.12 and 5.1), so a board printed from either is the same board; and an SVG at the
//! board's true size.
//!
//! The raster follows OpenCV's arithmetic step by step, in its precision: board coordinates in `f32` (OpenCV's
//! `Point3f`), rounding half to even (`cvRound`), and each marker drawn one pixel per bit and enlarged by
//! nearest neighbour (`resize` with `INTER_NEAREST`).

use pganeus_io::Image;

use crate::board::{Board, BoardKind};

pub use crate::dictionary::BORDER_BITS;

/// The board drawn into a `width` × `height` gray image with `margin` white pixels on every side, as
/// `board.generateImage((width, height), marginSize=margin, borderBits=1)` in OpenCV; `None` where OpenCV
/// refuses too (it asserts when a marker's rounded square would run past the drawing region, which some sizes
/// cause: [`board_image_near`] finds a size that draws).
pub fn board_image(board: &Board, width: u32, height: u32, margin: u32) -> Option<Image> {
    let mut image = Image::new(width, height, 1);
    image.data.fill(255);
    let region = Region {
        x0: margin as i64,
        y0: margin as i64,
        cols: width as i64 - 2 * margin as i64,
        rows: height as i64 - 2 * margin as i64,
    };
    if region.cols <= 0 || region.rows <= 0 {
        return None;
    }
    let drawn = match board.spec.kind {
        BoardKind::ArucoGrid => {
            let spec = &board.spec;
            let (ml, sep) = (spec.marker_length as f32, spec.marker_separation.expect("grid") as f32);
            let [cols, rows] = spec.size;
            let mut markers = Vec::new();
            for y in 0..rows {
                for x in 0..cols {
                    let c0 = [x as f32 * (ml + sep), y as f32 * (ml + sep)];
                    markers.push((spec.first_id + markers.len(), square_f32(c0, ml)));
                }
            }
            draw_markers(board, &mut image, region, &markers)
        }
        BoardKind::Charuco => draw_charuco(board, &mut image, region),
    };
    drawn.then_some(image)
}

/// The board drawn as by [`board_image`] at the first size that draws, trying `width` × `height` and then
/// sizes up to `reach` pixels larger in each direction (the pattern keeps its scale to within that).
pub fn board_image_near(board: &Board, width: u32, height: u32, margin: u32, reach: u32) -> Option<Image> {
    (0..=reach).find_map(|d| {
        (0..=d).find_map(|e| {
            board_image(board, width + d, height + e, margin)
                .or_else(|| board_image(board, width + e, height + d, margin))
        })
    })
}

/// A rectangle of the image: the part OpenCV's `Mat` ROI would be.
#[derive(Clone, Copy, Debug)]
struct Region {
    x0: i64,
    y0: i64,
    cols: i64,
    rows: i64,
}

/// A marker's corners in OpenCV's order, computed as OpenCV computes them in `f32`.
fn square_f32(c0: [f32; 2], ml: f32) -> [[f32; 2]; 4] {
    [c0, [c0[0] + ml, c0[1]], [c0[0] + ml, c0[1] + ml], [c0[0], c0[1] + ml]]
}

/// `Board::Impl::generateImage` on a region that is already white: the markers' bounding box stretched over
/// the region (OpenCV 4.7+ keeps no aspect ratio here: the caller sizes the region); false where OpenCV's
/// copy into the region would assert (a marker's square past the region's edge, or too small to draw).
fn draw_markers(board: &Board, image: &mut Image, region: Region, markers: &[(usize, [[f32; 2]; 4])]) -> bool {
    let (mut min_x, mut max_x) = (markers[0].1[0][0], markers[0].1[0][0]);
    let (mut min_y, mut max_y) = (markers[0].1[0][1], markers[0].1[0][1]);
    for (_, corners) in markers {
        for c in corners {
            min_x = min_x.min(c[0]);
            max_x = max_x.max(c[0]);
            min_y = min_y.min(c[1]);
            max_y = max_y.max(c[1]);
        }
    }
    let size_x = max_x - min_x;
    let size_y = max_y - min_y;
    let cells = (board.dictionary.marker_size + 2 * BORDER_BITS) as i64;
    for (id, corners) in markers {
        let to_pixels = |c: [f32; 2]| {
            [
                (c[0] - min_x) / size_x * region.cols as f32,
                (c[1] - min_y) / size_y * region.rows as f32,
            ]
        };
        let [c0, c1, c2] = [to_pixels(corners[0]), to_pixels(corners[1]), to_pixels(corners[2])];
        // cv::norm of a Point2f, in double, then back to float.
        let norm = |a: [f32; 2], b: [f32; 2]| {
            let (dx, dy) = ((b[0] - a[0]) as f64, (b[1] - a[1]) as f64);
            (dx * dx + dy * dy).sqrt() as f32
        };
        let side = (norm(c0, c1).round_ties_even() as i64).min(norm(c0, c2).round_ties_even() as i64);
        let (left, top) = (c0[0].round_ties_even() as i64, c0[1].round_ties_even() as i64);
        if side < cells || left < 0 || top < 0 || left + side > region.cols || top + side > region.rows {
            return false;
        }
        let tile = marker_tile(board, *id, side as usize);
        for ty in 0..side {
            let row = (region.y0 + top + ty) as usize * image.width as usize;
            for tx in 0..side {
                image.data[row + (region.x0 + left + tx) as usize] = tile[(ty * side + tx) as usize];
            }
        }
    }
    true
}

/// `Dictionary::generateImageMarker(id, side)`: one pixel per bit with the black border, enlarged by nearest
/// neighbour to `side` pixels (the source pixel of output pixel `x` is `floor(x / (side / cells))`).
pub fn marker_tile(board: &Board, id: usize, side: usize) -> Vec<u8> {
    let cells_of = cell_values(board, id);
    let cells = board.dictionary.marker_size + 2 * BORDER_BITS;
    assert!(
        side >= cells,
        "a marker of {cells} cells needs at least {cells} pixels, not {side}"
    );
    let inverse_scale = 1.0 / (side as f64 / cells as f64);
    let source = |x: usize| ((x as f64 * inverse_scale).floor() as usize).min(cells - 1);
    let mut tile = vec![0u8; side * side];
    for y in 0..side {
        for x in 0..side {
            tile[y * side + x] = cells_of[source(y) * cells + source(x)];
        }
    }
    tile
}

/// A marker one pixel per cell, border included: 0 black, 255 white.
fn cell_values(board: &Board, id: usize) -> Vec<u8> {
    let n = board.dictionary.marker_size;
    let cells = n + 2 * BORDER_BITS;
    let bits = board.dictionary.bits(id);
    let mut out = vec![0u8; cells * cells];
    for row in 0..n {
        for col in 0..n {
            if bits[row * n + col] {
                out[(row + BORDER_BITS) * cells + col + BORDER_BITS] = 255;
            }
        }
    }
    out
}

/// `CharucoBoardImpl::generateImage`: the chessboard as large as fits, centred; its markers drawn by the
/// generic board drawing over the zone from the first marker's corner to the last one's; then the black squares.
fn draw_charuco(board: &Board, image: &mut Image, region: Region) -> bool {
    let spec = &board.spec;
    let (sq, ml) = (spec.square_length.expect("charuco") as f32, spec.marker_length as f32);
    let [cols, rows] = spec.size.map(|v| v as i64);
    let per_square_x = region.cols as f32 / cols as f32;
    let per_square_y = region.rows as f32 / rows as f32;
    let mut zone = region;
    let per_square;
    if per_square_x <= per_square_y {
        per_square = per_square_x;
        zone.rows = (per_square * rows as f32).round_ties_even() as i64;
        zone.y0 += (region.rows - zone.rows) / 2;
    } else {
        per_square = per_square_y;
        zone.cols = (per_square * cols as f32).round_ties_even() as i64;
        zone.x0 += (region.cols - zone.cols) / 2;
    }
    if zone.x0 < region.x0
        || zone.y0 < region.y0
        || zone.x0 + zone.cols > region.x0 + region.cols
        || zone.y0 + zone.rows > region.y0 + region.rows
    {
        return false;
    }
    let marker_pixels = ml / sq * per_square;
    let inset = 0.5 * (per_square - marker_pixels);
    let end_x = (per_square * (cols - 1) as f32 + inset + marker_pixels).round_ties_even() as i64;
    let end_y = (per_square * (rows - 1) as f32 + inset + marker_pixels).round_ties_even() as i64;
    let start = inset.round_ties_even() as i64;
    if end_x > zone.cols || end_y > zone.rows || start >= end_x || start >= end_y {
        return false;
    }
    let marker_zone = Region {
        x0: zone.x0 + start,
        y0: zone.y0 + start,
        cols: end_x - start,
        rows: end_y - start,
    };
    let diff = (sq - ml) / 2.0;
    let mut markers = Vec::new();
    for y in 0..rows {
        for x in 0..cols {
            if spec.charuco_has_marker(x as usize, y as usize) {
                let c0 = [x as f32 * sq + diff, y as f32 * sq + diff];
                markers.push((spec.first_id + markers.len(), square_f32(c0, ml)));
            }
        }
    }
    if !draw_markers(board, image, marker_zone, &markers) {
        return false;
    }
    for y in 0..rows {
        for x in 0..cols {
            if spec.charuco_has_marker(x as usize, y as usize) {
                continue;
            }
            let start_x = per_square * x as f32;
            let start_y = per_square * y as f32;
            let (r0, r1) = (
                start_y.round_ties_even() as i64,
                (start_y + per_square).round_ties_even() as i64,
            );
            let (c0, c1) = (
                start_x.round_ties_even() as i64,
                (start_x + per_square).round_ties_even() as i64,
            );
            if r1 > zone.rows || c1 > zone.cols {
                return false;
            }
            for row in r0..r1 {
                let offset = (zone.y0 + row) as usize * image.width as usize;
                for col in c0..c1 {
                    image.data[offset + (zone.x0 + col) as usize] = 0;
                }
            }
        }
    }
    true
}

/// The board as an SVG page at its true size: the pattern (millimetres, exact) with `margin_mm` of white
/// around it, and a line in the bottom margin saying what the board is and how to check the print.
pub fn board_svg(board: &Board, margin_mm: f64) -> String {
    let mm = |metres: f64| metres * 1000.0;
    let [w, h] = board.extent.map(mm);
    let (page_w, page_h) = (w + 2.0 * margin_mm, h + 2.0 * margin_mm);
    let mut svg = String::new();
    svg.push_str(&format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{page_w:.4}mm\" height=\"{page_h:.4}mm\" viewBox=\"0 0 {page_w:.4} {page_h:.4}\" shape-rendering=\"crispEdges\">\n"
    ));
    svg.push_str(&format!(
        "<rect x=\"0\" y=\"0\" width=\"{page_w:.4}\" height=\"{page_h:.4}\" fill=\"#fff\"/>\n"
    ));
    let rect = |svg: &mut String, x: f64, y: f64, w: f64, h: f64, fill: &str| {
        svg.push_str(&format!(
            "<rect x=\"{:.4}\" y=\"{:.4}\" width=\"{w:.4}\" height=\"{h:.4}\" fill=\"{fill}\"/>\n",
            x + margin_mm,
            y + margin_mm
        ));
    };
    if board.spec.kind == BoardKind::Charuco {
        let sq = mm(board.spec.square_length.expect("charuco"));
        let [cols, rows] = board.spec.size.map(|v| v as usize);
        for y in 0..rows {
            for x in 0..cols {
                if !board.spec.charuco_has_marker(x, y) {
                    rect(&mut svg, x as f64 * sq, y as f64 * sq, sq, sq, "#000");
                }
            }
        }
    }
    let n = board.dictionary.marker_size;
    let cells = n + 2 * BORDER_BITS;
    for marker in &board.markers {
        let [x0, y0] = marker.corners[0].map(mm);
        let side = mm(board.spec.marker_length);
        let cell = side / cells as f64;
        rect(&mut svg, x0, y0, side, side, "#000");
        let bits = board.dictionary.bits(marker.id);
        for row in 0..n {
            // Runs of white bits in a row become one rectangle.
            let mut col = 0;
            while col < n {
                if !bits[row * n + col] {
                    col += 1;
                    continue;
                }
                let start = col;
                while col < n && bits[row * n + col] {
                    col += 1;
                }
                let x = x0 + (start + BORDER_BITS) as f64 * cell;
                let y = y0 + (row + BORDER_BITS) as f64 * cell;
                rect(&mut svg, x, y, (col - start) as f64 * cell, cell, "#fff");
            }
        }
    }
    if margin_mm >= 6.0 {
        svg.push_str(&format!(
            "<text x=\"{:.4}\" y=\"{:.4}\" font-family=\"sans-serif\" font-size=\"{:.2}\" fill=\"#777\">{}</text>\n",
            margin_mm,
            page_h - margin_mm / 3.0,
            (margin_mm / 3.0).min(3.5),
            caption(board)
        ));
    }
    svg.push_str("</svg>\n");
    svg
}

/// What the board is and how to check its print, in one line.
pub fn caption(board: &Board) -> String {
    let spec = &board.spec;
    let [c, r] = spec.size;
    let ml = spec.marker_length * 1000.0;
    let layout = match spec.kind {
        BoardKind::ArucoGrid => format!(
            "aruco_grid {c} x {r}, marker {ml:.1} mm, separation {:.1} mm",
            spec.marker_separation.unwrap_or(0.0) * 1000.0
        ),
        BoardKind::Charuco => format!(
            "charuco {c} x {r}{}, square {:.1} mm, marker {ml:.1} mm",
            if spec.legacy { " (legacy)" } else { "" },
            spec.square_length.unwrap_or(0.0) * 1000.0
        ),
    };
    format!(
        "{} {layout}, first id {}. Print at 100 % (no fit to page); a marker's black square must measure {ml:.1} mm.",
        board.dictionary.name, spec.first_id
    )
}

/// Pixels of a `metres` length at `dpi` dots per inch.
pub fn pixels_at_dpi(metres: f64, dpi: f64) -> u32 {
    (metres / 0.0254 * dpi).round() as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::BoardSpec;
    use std::path::Path;

    fn board(text: &str) -> Board {
        Board::new(BoardSpec::parse(text, Path::new("t.toml")).unwrap()).unwrap()
    }

    #[test]
    fn a_tile_is_the_marker_bits_enlarged() {
        let b = board("kind = \"aruco_grid\"\ndictionary = \"DICT_4X4_50\"\nsize = [1, 1]\nmarker_length = 0.05\nmarker_separation = 0.01\n");
        let tile = marker_tile(&b, 0, 12);
        // 6 cells of 2 pixels: the border is black, the first inner bit of marker 0 is white.
        assert!(tile[..12].iter().all(|&v| v == 0));
        assert_eq!(tile[2 * 12 + 2], 255);
        assert_eq!(tile[2 * 12 + 4], 0);
    }

    #[test]
    fn the_svg_has_one_black_square_per_marker_and_the_true_size() {
        let b = board("kind = \"aruco_grid\"\ndictionary = \"DICT_5X5_1000\"\nsize = [3, 2]\nmarker_length = 0.04\nmarker_separation = 0.01\n");
        let svg = board_svg(&b, 10.0);
        assert!(
            svg.contains("width=\"160.0000mm\" height=\"110.0000mm\""),
            "{}",
            &svg[..200]
        );
        assert_eq!(svg.matches("fill=\"#000\"").count(), 6);
    }
}
