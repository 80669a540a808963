//! Shared test helpers. [`check_jacobian`] compares an analytic Jacobian with
//! central finite differences and names every entry that disagrees; [`fuzz`]
//! hands mutated files to parsers and catches their panics.

pub mod fuzz;

/// Tolerances of a finite-difference check: an entry passes when
/// `|analytic − fd| ≤ abs_tol + rel_tol · max(|analytic|, |fd|)`.
#[derive(Clone, Copy, Debug)]
pub struct GradTolerance {
    /// Step of the central difference.
    pub eps: f64,
    pub abs_tol: f64,
    pub rel_tol: f64,
    /// Fraction of entries that must pass (1.0 = all). Below 1 only where a
    /// function has known kinks (cell boundaries of a grid, say).
    pub pass_fraction: f64,
}

impl Default for GradTolerance {
    fn default() -> Self {
        Self {
            eps: 1e-6,
            abs_tol: 1e-8,
            rel_tol: 1e-4,
            pass_fraction: 1.0,
        }
    }
}

/// Central finite-difference Jacobian of `f` at `x`: `jac[out][in]`.
pub fn finite_difference_jacobian(f: &dyn Fn(&[f64]) -> Vec<f64>, x: &[f64], eps: f64) -> Vec<Vec<f64>> {
    let n_out = f(x).len();
    let mut jac = vec![vec![0.0; x.len()]; n_out];
    let mut xp = x.to_vec();
    for j in 0..x.len() {
        xp[j] = x[j] + eps;
        let fp = f(&xp);
        xp[j] = x[j] - eps;
        let fm = f(&xp);
        xp[j] = x[j];
        for i in 0..n_out {
            jac[i][j] = (fp[i] - fm[i]) / (2.0 * eps);
        }
    }
    jac
}

/// Check `analytic[out][in]` against central differences of `f` at `x`.
/// `input_names` label the columns in the report. Returns the worst relative
/// error seen, or an error listing the failing entries.
pub fn check_jacobian(
    name: &str,
    f: &dyn Fn(&[f64]) -> Vec<f64>,
    x: &[f64],
    analytic: &[Vec<f64>],
    input_names: &[String],
    tol: GradTolerance,
) -> Result<f64, String> {
    let fd = finite_difference_jacobian(f, x, tol.eps);
    assert_eq!(fd.len(), analytic.len(), "{name}: output count differs");
    let mut failures = Vec::new();
    let mut total = 0usize;
    let mut worst = 0.0f64;
    for (i, (row_fd, row_an)) in fd.iter().zip(analytic).enumerate() {
        assert_eq!(row_fd.len(), row_an.len(), "{name}: input count differs in row {i}");
        for (j, (&n, &a)) in row_fd.iter().zip(row_an).enumerate() {
            total += 1;
            let scale = a.abs().max(n.abs());
            let err = (a - n).abs();
            if scale > tol.abs_tol {
                worst = worst.max(err / scale);
            }
            if err.is_nan() || err > tol.abs_tol + tol.rel_tol * scale {
                let col = input_names.get(j).cloned().unwrap_or_else(|| format!("x{j}"));
                failures.push(format!(
                    "  out[{i}] / {col}: analytic {a:.9e}, finite difference {n:.9e}"
                ));
            }
        }
    }
    let passed = total - failures.len();
    if (passed as f64) < tol.pass_fraction * total as f64 {
        let shown: Vec<_> = failures.iter().take(40).cloned().collect();
        return Err(format!(
            "{name}: {} of {total} Jacobian entries disagree with finite differences:\n{}",
            failures.len(),
            shown.join("\n")
        ));
    }
    Ok(worst)
}

/// The names of the entries of `dir`, sorted.
pub fn sorted_file_names(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A fresh, empty folder for one test under the system temp dir, unique to
/// this process, `prefix` and `name` (removed first if a run left it behind).
pub fn scratch_dir(prefix: &str, name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("pganeus-{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir is writable");
    d
}

/// An OBJ's text with every vertex moved by `f` (faces and other lines as they are).
///
/// # Panics
/// On a `v` line whose coordinates are not numbers (test data is valid).
pub fn moved_obj(obj: &str, f: impl Fn([f64; 3]) -> [f64; 3]) -> String {
    obj.lines()
        .map(|l| match l.strip_prefix("v ") {
            Some(rest) => {
                let v: Vec<f64> = rest
                    .split_whitespace()
                    .map(|x| x.parse().expect("a vertex coordinate"))
                    .collect();
                let p = f([v[0], v[1], v[2]]);
                format!("v {} {} {}", p[0], p[1], p[2])
            }
            None => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// `width × height` 8-bit samples (gray with 1 channel, RGB with 3) as a JPEG file's bytes, for tests of
/// the JPEG readers (the project itself only decodes JPEG).
///
/// # Panics
/// On a size or channel count the encoder refuses.
pub fn jpeg_bytes(data: &[u8], width: u32, height: u32, channels: u8, quality: u8) -> Vec<u8> {
    let color = match channels {
        1 => jpeg_encoder::ColorType::Luma,
        3 => jpeg_encoder::ColorType::Rgb,
        c => panic!("jpeg_bytes: {c} channels (1 or 3)"),
    };
    let mut out = Vec::new();
    jpeg_encoder::Encoder::new(&mut out, quality)
        .encode(data, width as u16, height as u16, color)
        .expect("a JPEG the encoder accepts");
    out
}

/// A scene field's surface over the synth tabletop layout (board and wall shared by the `tabletop` and
/// `backdrop` presets), from `height(x, y)`: the world height of the zero level on the vertical line at
/// `(x, y)`, `None` when it has none.
#[derive(Debug)]
pub struct TabletopHeights {
    /// The board's top (true height 0) at five spots away from the obstacles; a missing surface is infinite.
    pub board: Vec<f64>,
    /// The wall's top (true height 0.07 m, at x = 0.22 m) at three spots; a missing surface is NaN.
    pub wall: Vec<f64>,
}

impl TabletopHeights {
    pub fn measure(height: impl Fn(f64, f64) -> Option<f64>) -> Self {
        let spots = [(-0.15, -0.05), (-0.05, 0.05), (0.1, -0.05), (0.05, 0.1), (-0.2, -0.15)];
        Self {
            board: spots
                .iter()
                .map(|&(x, y)| height(x, y).unwrap_or(f64::INFINITY))
                .collect(),
            wall: [-0.06, 0.0, 0.06]
                .iter()
                .map(|&y| height(0.22, y).unwrap_or(f64::NAN))
                .collect(),
        }
    }

    /// The median and the largest |board height|.
    pub fn board_error(&self) -> (f64, f64) {
        let mut abs: Vec<f64> = self.board.iter().map(|h| h.abs()).collect();
        abs.sort_by(f64::total_cmp);
        (abs[abs.len() / 2], abs[abs.len() - 1])
    }

    /// Both lists in millimetres, for the test's log.
    pub fn in_mm(&self) -> String {
        let mm = |v: &[f64]| v.iter().map(|h| (h * 1e4).round() / 10.0).collect::<Vec<_>>();
        format!(
            "board heights (mm) {:?}, wall top (mm) {:?}",
            mm(&self.board),
            mm(&self.wall)
        )
    }
}

/// `from` copied into `to`, folders included.
pub fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}
