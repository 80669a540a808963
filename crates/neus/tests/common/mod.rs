//! Helpers shared by the neus integration tests.
use std::path::Path;

/// A preset rendered small (96×72, 16 views, one video frame) into `dir`: the dataset's root.
pub fn tiny_synth(preset: &str, dir: &Path) {
    let mut scene = synth::preset(preset, synth::Scale::Small).unwrap();
    scene.cameras.width = 96;
    scene.cameras.height = 72;
    scene.cameras.views = 16;
    scene.videos.truncate(1);
    scene.videos[0].frames = 1;
    synth::generate(&scene, Path::new("."), dir, &mut |_, _, _| {}).unwrap();
}
