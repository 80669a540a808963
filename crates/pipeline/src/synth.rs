//! `synth`: a synthetic tabletop dataset with exact ground truth, in the NeuS layout (a preset or a scene
//! description; the motion made by the project's simulator or by Rapier).

use crate::error::{err, fail, Context};
use crate::Result;
use crate::{note, Observer, Task};
use std::path::{Path, PathBuf};
use synth::{preset, Scale, SynthScene, PRESETS};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum PhysicsArg {
    Pganeus,
    Rapier,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ScaleArg {
    Small,
    Large,
}

impl PhysicsArg {
    /// The engine's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            PhysicsArg::Pganeus => "pganeus",
            PhysicsArg::Rapier => "rapier",
        }
    }
}

impl ScaleArg {
    /// The size's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ScaleArg::Small => "small",
            ScaleArg::Large => "large",
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus synth --preset tabletop --out data/tabletop --contact-sheet
  pganeus synth --print-preset tabletop > my_scene.toml && pganeus synth --scene my_scene.toml --out data/mine")
)]
pub struct SynthArgs {
    /// A built-in scene: tabletop, two-body or backdrop.
    #[cfg_attr(feature = "clap", arg(long, conflicts_with = "scene"))]
    pub preset: Option<String>,
    /// A scene description (TOML); see `--print-preset`.
    #[cfg_attr(feature = "clap", arg(long))]
    pub scene: Option<PathBuf>,
    /// Image size, views and frames of a preset: small (160×120, 24 views, 30 frames) or large (320×240, 48, 48).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value = "small"))]
    pub scale: ScaleArg,
    /// The dataset folder to write.
    #[cfg_attr(feature = "clap", arg(long, required_unless_present = "print_preset"))]
    pub out: Option<PathBuf>,
    /// Replace `--out` if it exists (the old folder is kept until the new one is complete).
    #[cfg_attr(feature = "clap", arg(long))]
    pub force: bool,
    /// Also write contact_sheet.png: a few frames of every capture.
    #[cfg_attr(feature = "clap", arg(long))]
    pub contact_sheet: bool,
    /// The engine that makes the videos' motion: the project's simulator, or Rapier (a trusted engine the
    /// project did not write; truth.json then says `model: "rapier"`). Overrides the scene's `physics`.
    #[cfg_attr(feature = "clap", arg(long, value_enum))]
    pub physics: Option<PhysicsArg>,
    /// Print a preset's scene description as TOML and exit.
    #[cfg_attr(feature = "clap", arg(long, value_name = "PRESET"))]
    pub print_preset: Option<String>,
    /// Also write the footage as a camera makes it (`raw/`: a printed board of this kind on the table,
    /// handheld photos at three times the size through a lens with distortion, exposure and white balance
    /// per photo, noise, JPEG, motion blur in the videos; no cameras, no masks) and `camera_truth.json`.
    #[cfg_attr(feature = "clap", arg(long, value_enum))]
    pub raw: Option<RawBoardArg>,
    /// Render the captures themselves as a camera makes them, their true cameras and masks kept: exposure
    /// and white balance per photo, a video's exposure drifting, noise, JPEG, motion blur over a 1/60 s
    /// shutter (the scene file's `[camera_like]` sets each).
    #[cfg_attr(feature = "clap", arg(long))]
    pub camera_like: bool,
    /// The seed of the raw footage's jitter and noise.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 1))]
    pub raw_seed: u64,
    /// The raw footage's sensor size, `WIDTHxHEIGHT` (default three times the captures' size): e.g. 960x720
    /// beside the small scale's 160 x 120 captures, a sensor six times the training's size at a third of
    /// the large scale's rendering.
    #[cfg_attr(feature = "clap", arg(long, value_name = "WxH", value_parser = parse_size, requires = "raw"))]
    pub raw_size: Option<[u32; 2]>,
}

/// `960x720` → `[960, 720]`.
#[cfg(feature = "clap")]
fn parse_size(text: &str) -> std::result::Result<[u32; 2], String> {
    let bad = || format!("\"{text}\": give the size as WIDTHxHEIGHT, e.g. 960x720");
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if w < 16 || h < 16 {
        return Err(format!("\"{text}\": a sensor smaller than 16 x 16 pixels"));
    }
    Ok([w, h])
}

/// The printed board of `synth --raw`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum RawBoardArg {
    /// 6 x 4 DICT_5X5_1000 markers of 40 mm.
    ArucoGrid,
    /// 7 x 5 squares of 40 mm, DICT_4X4_50 markers of 30 mm.
    Charuco,
}

pub fn scale(a: ScaleArg) -> Scale {
    match a {
        ScaleArg::Small => Scale::Small,
        ScaleArg::Large => Scale::Large,
    }
}

pub fn named_preset(name: &str, s: Scale) -> Result<SynthScene> {
    preset(name, s).ok_or_else(|| err!(Stage, "unknown preset \"{name}\" (presets: {})", PRESETS.join(", ")))
}

pub fn run(a: &SynthArgs, observer: &dyn Observer) -> Result<()> {
    if let Some(name) = &a.print_preset {
        let text = toml::to_string(&named_preset(name, scale(a.scale))?)?;
        note(observer, text.trim_end());
        return Ok(());
    }
    let out = a
        .out
        .clone()
        .ok_or_else(|| err!(Settings, "synth: give --out, or --print-preset"))?;
    let (scene, base, label) = match (&a.preset, &a.scene) {
        (Some(p), None) => (
            named_preset(p, scale(a.scale))?,
            PathBuf::from("."),
            format!("preset {p}"),
        ),
        (None, Some(f)) => {
            let text = std::fs::read_to_string(f).with_context(|| format!("cannot read {}", f.display()))?;
            let scene: SynthScene = toml::from_str(&text).with_context(|| format!("{}", f.display()))?;
            (
                scene,
                f.parent().unwrap_or(Path::new(".")).to_path_buf(),
                f.display().to_string(),
            )
        }
        _ => fail!(Stage, "give --preset NAME or --scene FILE"),
    };
    let mut scene = match a.raw {
        Some(RawBoardArg::ArucoGrid) => synth::with_raw(scene, calib::BoardKind::ArucoGrid, a.raw_seed),
        Some(RawBoardArg::Charuco) => synth::with_raw(scene, calib::BoardKind::Charuco, a.raw_seed),
        None => scene,
    };
    if a.camera_like && scene.camera_like.is_none() {
        scene.camera_like = Some(synth::CameraLike::default());
    }
    if let (Some(raw), Some([w, h])) = (&mut scene.raw, a.raw_size) {
        raw.width = w;
        raw.height = h;
    }
    if let Some(p) = a.physics {
        scene.physics = match p {
            PhysicsArg::Pganeus => synth::Physics::Pganeus,
            PhysicsArg::Rapier => synth::Physics::Rapier,
        };
    }
    if out.exists() && std::fs::read_dir(&out).map(|mut d| d.next().is_some()).unwrap_or(true) && !a.force {
        fail!(
            OutputTaken,
            "{} exists and is not empty; use --force to replace it",
            out.display()
        );
    }
    // Written beside the target and swapped in whole, so a failure leaves the old dataset as it was.
    let staged = pganeus_io::StagedDir::new(&out)?;
    let partial = staged.path().to_path_buf();
    let t0 = std::time::Instant::now();
    let pb = Task::start(observer, "render", 0);
    let result = synth::generate(&scene, &base, &partial, &mut |name, done, total| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
        pb.set_status(name);
    });
    pb.finish();
    let summary = match result {
        Ok(s) => s,
        Err(e) => return Err(err!(Input, "{label}: {e}")),
    };
    if a.contact_sheet {
        let (sheet, rows) = synth::contact_sheet::contact_sheet(&partial)?;
        pganeus_io::write_png(&partial.join("contact_sheet.png"), &sheet)?;
        note(observer, format!("contact sheet rows: {}", rows.join(", ")));
    }
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    staged
        .commit()
        .with_context(|| format!("cannot move the new dataset to {}", out.display()))?;
    for (name, n) in &summary.captures {
        note(observer, format!("  {name}: {n} images"));
    }
    note(
        observer,
        format!(
            "rendered {} images in {:.1} s into {}",
            summary.images,
            t0.elapsed().as_secs_f64(),
            out.display()
        ),
    );
    Ok(())
}

#[cfg(all(test, feature = "clap"))]
mod tests {
    use super::parse_size;

    #[test]
    fn sizes_read_as_width_by_height_and_bad_ones_say_how_to_write_them() {
        assert_eq!(parse_size("960x720"), Ok([960, 720]));
        assert_eq!(parse_size("640X480"), Ok([640, 480]));
        assert!(parse_size("960").unwrap_err().contains("WIDTHxHEIGHT"));
        assert!(parse_size("960x-1").unwrap_err().contains("WIDTHxHEIGHT"));
        assert!(parse_size("8x8").unwrap_err().contains("smaller than 16"));
    }
}
