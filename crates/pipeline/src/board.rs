//! `board`: a printable board from its file (`board.toml`): an SVG at its true size, or a PNG at a given dpi
//! drawn exactly as OpenCV's `generateImage` draws the same board.

use std::path::PathBuf;

use calib::draw::{board_image_near, board_svg, caption, pixels_at_dpi};
use calib::Board;

use crate::error::{fail, Context};
use crate::{note, Observer, Result};

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus board board.toml --out board.svg
  pganeus board board.toml --out board.png --dpi 600 --margin-mm 5")
)]
pub struct BoardArgs {
    /// The board file (FORMATS.md \"Boards\").
    pub spec: PathBuf,
    /// The page to write: `.svg` (vector, true size) or `.png` (OpenCV's drawing at `--dpi`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// Dots per inch of a PNG (written into the file, so a printer prints it at its true size).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 300.0))]
    pub dpi: f64,
    /// White margin around the pattern, millimetres.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 10.0))]
    pub margin_mm: f64,
}

impl BoardArgs {
    /// The flags' defaults for a board file and the page to write.
    pub fn new(spec: impl Into<PathBuf>, out: impl Into<PathBuf>) -> Self {
        BoardArgs {
            spec: spec.into(),
            out: out.into(),
            dpi: 300.0,
            margin_mm: 10.0,
        }
    }
}

/// What `board` wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardPage {
    /// The file.
    pub path: PathBuf,
    /// The page's size, millimetres.
    pub page_mm: [f64; 2],
    /// A printed marker's side, millimetres (the board file's `marker_length` for an SVG; a PNG's pixels
    /// make it a little off).
    pub marker_mm: f64,
}

/// Writes the board's page (atomically: an earlier file stays whole until the new one is complete).
pub fn run(a: &BoardArgs, observer: &dyn Observer) -> Result<BoardPage> {
    let board = Board::read(&a.spec).map_err(|e| crate::Error::Input(e.to_string()))?;
    if !(a.margin_mm >= 0.0 && a.margin_mm.is_finite()) {
        fail!(
            Settings,
            "--margin-mm {}: must be zero or more millimetres",
            a.margin_mm
        );
    }
    let extension = a.out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let page = match extension.as_deref() {
        Some("svg") => write_svg(&board, a)?,
        Some("png") => write_png(&board, a)?,
        _ => fail!(
            Settings,
            "--out {}: the page is written as .svg or .png",
            a.out.display()
        ),
    };
    note(
        observer,
        format!(
            "wrote {} ({:.1} x {:.1} mm): {}",
            page.path.display(),
            page.page_mm[0],
            page.page_mm[1],
            caption(&board)
        ),
    );
    if extension.as_deref() == Some("png") {
        note(
            observer,
            format!(
                "at {} dpi a marker prints at {:.2} mm ({:+.2} % of marker_length): whole pixels",
                a.dpi,
                page.marker_mm,
                (page.marker_mm / (board.spec.marker_length * 1000.0) - 1.0) * 100.0
            ),
        );
    }
    if page.page_mm[0].min(page.page_mm[1]) > 216.0 || page.page_mm[0].max(page.page_mm[1]) > 297.0 {
        note(
            observer,
            "the page is larger than A4 and Letter: print it on a larger sheet or tile it, never scaled",
        );
    }
    Ok(page)
}

fn write_svg(board: &Board, a: &BoardArgs) -> Result<BoardPage> {
    let svg = board_svg(board, a.margin_mm);
    pganeus_io::write_atomic(&a.out, svg.as_bytes()).with_context(|| format!("cannot write {}", a.out.display()))?;
    Ok(BoardPage {
        path: a.out.clone(),
        page_mm: board.extent.map(|v| v * 1000.0 + 2.0 * a.margin_mm),
        marker_mm: board.spec.marker_length * 1000.0,
    })
}

fn write_png(board: &Board, a: &BoardArgs) -> Result<BoardPage> {
    if !(a.dpi >= 30.0 && a.dpi <= 2400.0) {
        fail!(Settings, "--dpi {}: a printer's resolution, 30 to 2400", a.dpi);
    }
    let margin = pixels_at_dpi(a.margin_mm / 1000.0, a.dpi);
    let [w, h] = board.extent.map(|v| pixels_at_dpi(v, a.dpi));
    // OpenCV stretches the pattern over the size it is given; some sizes round a marker past its region.
    let Some(image) = board_image_near(board, w + 2 * margin, h + 2 * margin, margin, 4) else {
        fail!(
            Settings,
            "{}: at {} dpi the markers are too small to draw (a cell under a pixel); raise --dpi",
            a.spec.display(),
            a.dpi
        );
    };
    pganeus_io::write_png_at_dpi(&a.out, &image, a.dpi)?;
    let mm_per_pixel = 25.4 / a.dpi;
    let pattern_px = (image.width - 2 * margin) as f64;
    Ok(BoardPage {
        path: a.out.clone(),
        page_mm: [image.width as f64 * mm_per_pixel, image.height as f64 * mm_per_pixel],
        marker_mm: board.spec.marker_length * 1000.0 * pattern_px / (board.extent[0] * 1000.0 / mm_per_pixel),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Quiet;
    use std::path::Path;

    fn spec(dir: &Path, text: &str) -> PathBuf {
        let p = dir.join("board.toml");
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn a_png_prints_at_its_true_size_and_says_its_dpi() {
        let dir = testkit::scratch_dir("pipeline", "board_png");
        let s = spec(&dir, "kind = \"aruco_grid\"\ndictionary = \"DICT_5X5_1000\"\nsize = [4, 3]\nmarker_length = 0.04\nmarker_separation = 0.01\n");
        let a = BoardArgs {
            dpi: 200.0,
            ..BoardArgs::new(&s, dir.join("b.png"))
        };
        let page = run(&a, &Quiet).unwrap();
        assert!((page.marker_mm - 40.0).abs() < 0.2, "{page:?}");
        let image = pganeus_io::read_png(&dir.join("b.png")).unwrap();
        assert_eq!(image.width, pixels_at_dpi(0.19, 200.0) + 2 * pixels_at_dpi(0.01, 200.0));
        let bytes = std::fs::read(dir.join("b.png")).unwrap();
        assert!(bytes.windows(4).any(|w| w == b"pHYs"));
    }

    #[test]
    fn bad_requests_name_the_problem_and_write_nothing() {
        let dir = testkit::scratch_dir("pipeline", "board_bad");
        let s = spec(&dir, "kind = \"charuco\"\ndictionary = \"DICT_4X4_50\"\nsize = [5, 7]\nmarker_length = 0.02\nsquare_length = 0.03\n");
        let e = run(&BoardArgs::new(&s, dir.join("b.pdf")), &Quiet)
            .unwrap_err()
            .to_string();
        assert!(e.contains(".svg or .png"), "{e}");
        let e = run(
            &BoardArgs {
                dpi: 10.0,
                ..BoardArgs::new(&s, dir.join("b.png"))
            },
            &Quiet,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--dpi"), "{e}");
        let bad = spec(
            &dir,
            "kind = \"charuco\"\ndictionary = \"DICT_4X4_50\"\nsize = [5, 7]\nmarker_length = 0.02\n",
        );
        let e = run(&BoardArgs::new(&bad, dir.join("b.svg")), &Quiet)
            .unwrap_err()
            .to_string();
        assert!(e.contains("board.toml") && e.contains("square_length"), "{e}");
        assert!(!dir.join("b.png").exists() && !dir.join("b.svg").exists() && !dir.join("b.pdf").exists());
    }
}
