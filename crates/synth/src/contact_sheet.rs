//! One PNG with a few frames of every capture of a dataset, so a person can
//! see it at a glance: a row per capture (background, each body's static
//! captures, each video), six images spread over it, then the mask of the
//! last one shown (where the capture has masks).

use pganeus_io::Image;
use std::path::{Path, PathBuf};

const TILE_W: u32 = 160;
const GAP: u32 = 4;
const COLUMNS: usize = 6;

/// Box-filter `img` down (or nearest-neighbour up) to `w`×`h`, as RGB.
pub(crate) fn resize(img: &Image, w: u32, h: u32) -> Image {
    let src = img.to_rgb();
    let mut out = Image::new(w, h, 3);
    let (sx, sy) = (src.width as f64 / w as f64, src.height as f64 / h as f64);
    for y in 0..h {
        for x in 0..w {
            let (x0, y0) = ((x as f64 * sx) as u32, (y as f64 * sy) as u32);
            let (x1, y1) = (
                (((x + 1) as f64 * sx).ceil() as u32).max(x0 + 1),
                (((y + 1) as f64 * sy).ceil() as u32).max(y0 + 1),
            );
            let mut acc = [0u32; 3];
            let mut n = 0;
            for yy in y0..y1.min(src.height) {
                for xx in x0..x1.min(src.width) {
                    let p = src.pixel(xx, yy);
                    for k in 0..3 {
                        acc[k] += p[k] as u32;
                    }
                    n += 1;
                }
            }
            let dst = out.pixel_mut(x, y);
            for k in 0..3 {
                dst[k] = (acc[k] / n.max(1)) as u8;
            }
        }
    }
    out
}

fn pngs(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "png"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// The capture folders of a dataset, in the order of `truth.json` when there
/// is one (background, static captures, videos), else sorted by name.
fn captures(dataset: &Path) -> Vec<String> {
    if let Ok(t) = pganeus_io::read_truth(&dataset.join("truth.json")) {
        let mut names = Vec::new();
        if let Some(b) = &t.background {
            names.push(b.capture.clone());
        }
        for b in &t.bodies {
            names.extend(b.static_captures.iter().map(|s| s.capture.clone()));
        }
        names.extend(t.videos.iter().map(|v| v.capture.clone()));
        return names;
    }
    let mut names: Vec<String> = std::fs::read_dir(dataset)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .filter(|e| e.path().join("image").is_dir())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

/// Build the sheet of `dataset`; also returns the row names, top to bottom.
pub fn contact_sheet(dataset: &Path) -> Result<(Image, Vec<String>), pganeus_io::IoError> {
    let names = captures(dataset);
    let mut rows: Vec<Vec<Image>> = Vec::new();
    let mut tile_h = TILE_W * 3 / 4;
    for name in &names {
        let images = pngs(&dataset.join(name).join("image"));
        if images.is_empty() {
            continue;
        }
        let picks: Vec<usize> = (0..COLUMNS.min(images.len()))
            .map(|i| i * (images.len() - 1) / (COLUMNS - 1).max(1))
            .collect();
        let first = pganeus_io::read_image(&images[picks[0]])?;
        tile_h = (TILE_W as u64 * first.height as u64 / first.width as u64) as u32;
        let mut row = Vec::new();
        for &i in &picks {
            row.push(resize(&pganeus_io::read_image(&images[i])?, TILE_W, tile_h));
        }
        let last = images[*picks.last().expect("at least one pick")].clone();
        let mask = dataset.join(name).join("mask").join(last.file_name().expect("a file"));
        if mask.exists() {
            row.push(resize(&pganeus_io::read_image(&mask)?, TILE_W, tile_h));
        }
        rows.push(row);
    }
    let cols = COLUMNS as u32 + 1;
    let width = cols * TILE_W + (cols + 1) * GAP;
    let height = rows.len().max(1) as u32 * (tile_h + GAP) + GAP;
    let mut sheet = Image::new(width, height, 3);
    sheet.data.fill(40);
    for (r, row) in rows.iter().enumerate() {
        for (c, tile) in row.iter().enumerate() {
            let (ox, oy) = (GAP + c as u32 * (TILE_W + GAP), GAP + r as u32 * (tile_h + GAP));
            for y in 0..tile.height {
                for x in 0..tile.width {
                    sheet.pixel_mut(ox + x, oy + y).copy_from_slice(tile.pixel(x, y));
                }
            }
        }
    }
    Ok((sheet, names))
}
