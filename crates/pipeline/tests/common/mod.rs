//! A printed board photographed through a distorting lens: the rendered sessions the pipeline's camera
//! tests (calibrate, import) shoot; and `synth` scenes rendered into scratch folders.

#![allow(dead_code)]

use std::path::Path;

use calib::board_views::{render, View};
use calib::{Board, BoardSpec, Lens};

pub const BOARD: &str = "kind = \"aruco_grid\"\ndictionary = \"DICT_4X4_50\"\nsize = [6, 4]\nmarker_length = 0.04\nmarker_separation = 0.008\n";
pub const SIZE: (usize, usize) = (640, 480);

pub fn lens() -> Lens {
    Lens {
        fx: 580.0,
        fy: 582.0,
        cx: 322.0,
        cy: 236.0,
        distortion: [-0.22, 0.07, 0.0005, -0.0003, 0.0],
    }
}

pub fn board() -> Board {
    Board::new(BoardSpec::parse(BOARD, Path::new("board.toml")).unwrap()).unwrap()
}

/// Writes `views` into `dir` (JPEG or PNG), returning them.
pub fn shoot(dir: &Path, views: &[View], jpeg: bool, seed: u64) {
    std::fs::create_dir_all(dir).unwrap();
    let b = board();
    for (k, v) in views.iter().enumerate() {
        let image = render(&b, v, SIZE, 3, 1.5, seed + k as u64).to_image();
        if jpeg {
            let bytes = testkit::jpeg_bytes(&image.data, image.width, image.height, 1, 95);
            std::fs::write(dir.join(format!("IMG_{k:04}.jpg")), bytes).unwrap();
        } else {
            pganeus_io::write_png(&dir.join(format!("frame_{k:03}.png")), &image).unwrap();
        }
    }
}

pub fn around(n: usize, seed: u64) -> Vec<View> {
    let b = board();
    let mut rng = geom::SplitMix64::new(seed);
    (0..n)
        .map(|_| {
            View::looking_at(
                &b,
                580.0,
                SIZE,
                rng.range(0.38, 0.5),
                rng.range(0.25, 0.7),
                rng.range(-3.1, 3.1),
                rng.range(-0.6, 0.6),
            )
            .with_lens(lens())
        })
        .collect()
}

/// `scene` rendered by `synth` into a fresh scratch folder `group/name`; the folder.
pub fn synth_into(scene: &synth::SynthScene, group: &str, name: &str) -> std::path::PathBuf {
    let dir = testkit::scratch_dir(group, name);
    synth::generate(scene, Path::new("."), &dir, &mut |_, _, _| {}).unwrap();
    dir
}
