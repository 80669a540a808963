//! Run folders: where a stage finds a run's checkpoint, and settings files laid over a stage's defaults.

use crate::error::{err, Context};
use crate::Result;

/// A run folder's checkpoint, or the checkpoint file itself.
pub fn checkpoint_of(run: &std::path::Path) -> std::path::PathBuf {
    if run.is_dir() {
        run.join("checkpoint.safetensors")
    } else {
        run.to_path_buf()
    }
}

/// Lay `over` on `base` key by key: a nested table (`[field.grid]`, `[ga.pose]`) changes only the keys it
/// names, so a config file keeps the rest of the defaults it starts from.
fn merge_tables(base: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// `base` with a TOML config file's keys laid over it (errors name the file).
pub fn config_over<T: serde::Serialize + serde::de::DeserializeOwned>(base: &T, file: &std::path::Path) -> Result<T> {
    let text = std::fs::read_to_string(file).with_context(|| format!("cannot read {}", file.display()))?;
    settings_over(base, &text, &file.display().to_string())
}

/// `base` with the keys of the TOML text `text` laid over it, as [`config_over`] lays a file's (errors name
/// `source`).
pub fn settings_over<T: serde::Serialize + serde::de::DeserializeOwned>(
    base: &T,
    text: &str,
    source: &str,
) -> Result<T> {
    let over: toml::Table = toml::from_str(text).map_err(|e| err!(Input, "{source}: {e}"))?;
    let mut merged = toml::Table::try_from(base)?;
    merge_tables(&mut merged, over);
    toml::Value::Table(merged)
        .try_into()
        .map_err(|e| err!(Input, "{source}: {e}"))
}

/// A JSON file of a run, read whole.
pub fn read_json(p: &std::path::Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}", p.display()))
}

#[cfg(test)]
mod tests {
    use super::config_over;
    use recon::video_fit::VideoFitConfig;

    #[test]
    fn a_config_file_changes_only_the_keys_it_names() {
        let dir = std::env::temp_dir().join(format!("pganeus-config-over-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("fit.toml");
        std::fs::write(&file, "rounds = 3\n[ga.pose]\niterations = 7\n").unwrap();
        let base = VideoFitConfig::default();
        let cfg = config_over(&base, &file).unwrap();
        assert_eq!(cfg.rounds, 3);
        assert_eq!(cfg.ga.pose.iterations, 7);
        // The nested table's other keys keep fit's defaults, not the library type's.
        assert_eq!(cfg.ga.pose.rays_per_step, base.ga.pose.rays_per_step);
        assert_eq!(cfg.ga.pose.lr_rotation, base.ga.pose.lr_rotation);
        assert_eq!(cfg.pa, base.pa);
        std::fs::write(&file, "[ga.pose]\niteration = 7\n").unwrap();
        let e = config_over(&base, &file).unwrap_err().to_string();
        assert!(e.contains("fit.toml") && e.contains("iteration"), "{e}");
        // Training configs too, nested tables included: a typo is named, not dropped.
        let train = neus::TrainConfig::preset("fast", neus::CaptureSubject::Object).unwrap();
        let file = dir.join("train.toml");
        std::fs::write(&file, "[field.grid]\nlevels = 8\n").unwrap();
        assert_eq!(config_over(&train, &file).unwrap().field.grid.levels, 8);
        for typo in [
            "[field.grid]\nlevelz = 8\n",
            "[stereo]\nhypotheses = 64\nstrid = 2\n",
            "[adam]\nlr = 0.1\n",
        ] {
            std::fs::write(&file, typo).unwrap();
            let e = config_over(&train, &file).unwrap_err().to_string();
            let key = typo
                .lines()
                .nth(typo.lines().count() - 1)
                .unwrap()
                .split(' ')
                .next()
                .unwrap();
            let key = if typo.starts_with("[adam]") { "adam" } else { key };
            assert!(e.contains("train.toml") && e.contains(key), "{typo}: {e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
