//! `pganeus report`: a fit folder as the stages leave it (the truth's motion with its stage files, logs and
//! animation) scored by `eval`, then reported: one self-contained page, every chart as PNG and SVG, a
//! novel-view animation; and headless Chromium opens the page, decodes every picture and takes a
//! screenshot. Chromium is Debian's `chromium` (`.ci/run` installs it and sets PGANEUS_REQUIRE_CHROMIUM, so
//! CI fails without it; elsewhere its part is skipped with a message).

use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common;
use common::{bin, flight_3_cm_s_fast, tabletop, text};

/// The tabletop preset at 64×48 with six frames per video, and its contact sheet.
fn dataset(d: &Path) -> PathBuf {
    tabletop(d, (64, 48), 3, 6, &["--contact-sheet"])
}

/// Per-frame image terms as `fit` writes them.
fn rows(n: usize, iou: f64, psnr: f64) -> Value {
    json!((0..n)
        .map(|k| json!({"frame": k, "loss": 0.01, "iou": iou - 0.01 * k as f64, "psnr_window": psnr, "seen": true}))
        .collect::<Vec<_>>())
}

/// `video` with every pose moved by `dz` metres.
fn shifted(video: &Value, dz: f64) -> Value {
    let mut v = video.clone();
    for p in v["bodies"][0]["poses"].as_array_mut().unwrap() {
        p["t"][2] = json!(p["t"][2].as_f64().unwrap() + dz);
    }
    v
}

/// A fit folder for the drop video: the truth's motion as the result, the stages a little off it.
fn fit_folder(d: &Path, data: &Path) -> PathBuf {
    let truth: Value = serde_json::from_str(&std::fs::read_to_string(data.join("truth.json")).unwrap()).unwrap();
    let video = truth["videos"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["capture"] == "drop")
        .unwrap()
        .clone();
    let n = video["bodies"][0]["poses"].as_array().unwrap().len();
    let fit = d.join("fits").join("drop");
    std::fs::create_dir_all(&fit).unwrap();
    std::fs::copy(data.join("toy.ply"), fit.join("object.ply")).unwrap();
    let reference = &truth["bodies"][0]["static_captures"][1];
    let object = json!({"mesh": "object.ply", "source": "merged/toy",
        "reference": {"capture": reference["capture"], "pose": reference["pose"]}});
    let mut result = video.clone();
    result["bodies"][0]["object"] = object.clone();
    result["video"] = json!(data.join("drop"));
    result["stages"] = json!({"ga": rows(n, 0.97, 24.0), "simulated": rows(n, 0.98, 25.0)});
    result["bodies"][0]["flight"] = flight_3_cm_s_fast(&video);
    std::fs::write(fit.join("trajectory.json"), result.to_string()).unwrap();
    for (stage, dz) in [("pa", 0.004), ("ga", -0.002), ("pga", 0.001)] {
        let mut t = shifted(&video, dz);
        t["bodies"][0]["object"] = object.clone();
        t["frames"] = rows(n, 0.9, 20.0);
        std::fs::write(fit.join(format!("{stage}.json")), t.to_string()).unwrap();
    }
    std::fs::write(
        fit.join("config.toml"),
        format!(
            "[inputs]\nscene = {:?}\n",
            data.join("background.ply").display().to_string()
        ),
    )
    .unwrap();
    let mut log = String::new();
    for i in 0..5 {
        log += &format!(
            "{{\"frame\":0,\"iteration\":{},\"loss\":{},\"stage\":\"first_pose\"}}\n",
            i * 10,
            0.05 / (1.0 + i as f64)
        );
        log += &format!(
            "{{\"iteration\":{i},\"loss\":{},\"stage\":\"pa\",\"window\":4}}\n",
            0.07 / (1.0 + i as f64)
        );
        log += &format!("{{\"frame\":{i},\"loss\":0.005,\"stage\":\"ga\",\"start\":\"physics\"}}\n");
    }
    log += "{\"friction\":0.26,\"loss\":0.06,\"restitution\":0.34,\"round\":0,\"stage\":\"pga\",\"start\":0}\n";
    log += "{\"stage\":\"pa\",\"loss\":0.0"; // a line cut by a kill
    std::fs::write(fit.join("log.jsonl"), log).unwrap();
    // The animation: the video's frames side by side with themselves.
    let frames: Vec<pganeus_io::Image> = (0..n)
        .map(|k| pganeus_io::read_png(&data.join("drop").join("image").join(format!("{k:03}.png"))).unwrap())
        .collect();
    pganeus_io::write_apng(&fit.join("animation.png"), &frames, 30.0).unwrap();
    // A training run's log and the demo's record.
    let run = d.join("runs").join("scene");
    std::fs::create_dir_all(&run).unwrap();
    let train: String = (1..=4)
        .map(|i| {
            format!(
                "{{\"step\":{},\"loss\":{{\"rgb\":{}}},\"psnr\":{}}}\n",
                i * 50,
                0.1 / i as f64,
                17 + i
            )
        })
        .collect();
    std::fs::write(run.join("log.jsonl"), train).unwrap();
    std::fs::write(
        d.join("demo.json"),
        json!({"done": {"fit drop": {"argv": ["fit", "data/drop"], "seconds": 12.5}}}).to_string(),
    )
    .unwrap();
    fit
}

/// Debian's Chromium (or another Chrome) on the PATH.
fn chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .flat_map(|name| std::env::split_paths(&path).map(move |d| d.join(name)))
        .find(|p| p.is_file())
}

/// Chromium, headless, on `page`; `args` say what to do. Its own profile folder, and no sandbox (CI runs
/// as root).
fn headless(chrome: &Path, profile: &Path, args: &[&str], page: &Path) -> Output {
    Command::new("timeout")
        .arg("120")
        .arg(chrome)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--hide-scrollbars",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap()
}

#[test]
fn a_report_embeds_everything_and_headless_chromium_shows_it_all() {
    let d = testkit::scratch_dir("cli", "report");
    let data = dataset(&d);
    let fit = fit_folder(&d, &data);
    let o = bin()
        .arg("eval")
        .arg(&fit)
        .arg("--truth")
        .arg(data.join("truth.json"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let o = bin().arg("report").arg(&d).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));

    // One file: every picture a data URI, nothing fetched.
    let page = d.join("report.html");
    let html = std::fs::read_to_string(&page).unwrap();
    for needle in ["<script src", "<link", "url(http"] {
        assert!(!html.contains(needle), "{needle}");
    }
    assert_eq!(
        html.matches("<img src=\"").count(),
        html.matches("<img src=\"data:image/png;base64,").count()
    );
    // The inputs, the mesh's turntable, the animation and the novel view.
    assert_eq!(html.matches("<img ").count(), 4, "{html}");
    for needle in [
        "Fit: drop",
        "Against the truth",
        "PGA",
        "top view",
        "silhouette IoU per frame",
        "training: PSNR",
        "toy: the flight alone (4 frames before the first contact; the kept launch misses it)",
    ] {
        assert!(html.contains(needle), "{needle}");
    }
    // The truth's own motion scores as zero error, along the line of sight and across it too.
    assert!(
        html.contains("<td>reported</td><td>toy</td><td>0.00 / 0.00</td><td>0.00 / 0.00</td>"),
        "{html}"
    );
    assert!(html.contains("along (absolute) / across the line of sight"), "{html}");
    // Every chart as PNG and SVG.
    for chart in [
        "drop_toy_top_view",
        "drop_toy_height",
        "drop_iou",
        "drop_psnr",
        "drop_loss_first_pose",
        "drop_loss_pa",
        "drop_loss_ga_pga",
        "training_psnr",
        "training_loss",
    ] {
        let png = pganeus_io::read_png(&d.join("plots").join(format!("{chart}.png"))).unwrap();
        assert_eq!((png.width, png.height), (480, 320), "{chart}");
        let svg = std::fs::read_to_string(d.join("plots").join(format!("{chart}.svg"))).unwrap();
        assert!(
            svg.contains("<svg") && html.contains(&svg[svg.find("<svg").unwrap()..]),
            "{chart}"
        );
    }
    // The novel view: an animation with a frame per video frame (its acTL chunk says how many).
    let novel = std::fs::read(fit.join("novel_view.png")).unwrap();
    let at = novel.windows(4).position(|w| w == b"acTL").expect("an APNG");
    assert_eq!(u32::from_be_bytes(novel[at + 4..at + 8].try_into().unwrap()), 6);

    // A folder with nothing to report is refused, naming it.
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let o = bin().arg("report").arg(&empty).output().unwrap();
    assert!(
        !o.status.success() && text(&o).contains("nothing to report"),
        "{}",
        text(&o)
    );

    // Headless Chromium: every picture decodes, the charts are there, and the screenshot shows them.
    let Some(chrome) = chromium() else {
        assert!(
            std::env::var_os("PGANEUS_REQUIRE_CHROMIUM").is_none(),
            "PGANEUS_REQUIRE_CHROMIUM is set but no chromium is on the PATH"
        );
        eprintln!("no chromium on the PATH: the browser check is skipped (apt install chromium)");
        let _ = std::fs::remove_dir_all(&d);
        return;
    };
    let profile = d.join("chromium-profile");
    let o = headless(&chrome, &profile, &["--virtual-time-budget=10000", "--dump-dom"], &page);
    assert!(o.status.success(), "{}", text(&o));
    let dom = String::from_utf8_lossy(&o.stdout);
    let body = &dom[dom.find("<body").expect("a body")..];
    let body = &body[..body.find('>').unwrap()];
    let attr = |name: &str| -> usize {
        let key = format!("{name}=\"");
        let at = body
            .find(&key)
            .unwrap_or_else(|| panic!("{name} not set: the check script did not run: {body}"));
        body[at + key.len()..].split('"').next().unwrap().parse().unwrap()
    };
    assert_eq!(attr("data-images"), 4, "{body}");
    assert_eq!(attr("data-images-loaded"), 4, "a picture did not decode: {body}");
    assert_eq!(attr("data-charts"), 9, "{body}");
    let shot = d.join("screenshot.png");
    let o = headless(
        &chrome,
        &profile,
        &["--window-size=1100,1600", &format!("--screenshot={}", shot.display())],
        &page,
    );
    assert!(o.status.success(), "{}", text(&o));
    let img = pganeus_io::read_png(&shot).unwrap();
    assert_eq!((img.width, img.height), (1100, 1600));
    // Not a blank page: many distinct colours (pictures, charts, text).
    let mut colours: Vec<&[u8]> = img.data.chunks(img.channels as usize).collect();
    colours.sort();
    colours.dedup();
    assert!(colours.len() > 500, "{} colours", colours.len());
    let _ = std::fs::remove_dir_all(&d);
}
