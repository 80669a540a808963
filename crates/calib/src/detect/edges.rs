//! Corners from the marker's edges: each side's edge found to a fraction of a pixel at many places along it
//! (where the intensity across the edge crosses halfway between the black border and the white paper), a
//! line fitted through those places, and neighbouring lines intersected.
//!
//! `cornerSubPix` at the outer corner of a black square is biased toward the square's inside (about 0.3 px at
//! a 6-pixel cell: the gradients near the tip point along the diagonal), which shrinks every marker and with
//! it the world's scale; a symmetric blur moves no halfway crossing, so the edges' lines meet at the corner.

use crate::gray::Gray;
use crate::lens::Lens;

/// Refines the corners (clockwise as seen) of a marker whose cells are `cell` pixels wide, in `linear` (the
/// image in linear light, [`Gray::to_linear`]); `None` where a side has too few clear edge crossings (the
/// candidate keeps its corners).
///
/// In linear light because a pixel half on the ink is halfway between ink and paper only before the camera's
/// gamma: in sRGB values the halfway crossing sits on the ink's side and every marker looks smaller (0.2 px
/// of its edge under a lens's blur of σ = 0.7 px).
///
/// With `lens`, the edge crossings are undistorted before the lines are fitted and the corners distorted
/// back: a lens bends a marker's sides, and the chord of a bent side misses the corner (at k1 = -0.26 the
/// straight-line corners make a calibration's focal length 0.06 % short).
pub fn refine_by_edges(
    linear: &Gray,
    corners: &[[f64; 2]; 4],
    cell: f64,
    lens: Option<&Lens>,
) -> Option<[[f64; 2]; 4]> {
    let mut c = *corners;
    for _ in 0..2 {
        let mut lines = [[0.0f64; 3]; 4];
        for side in 0..4 {
            let mut points = side_points(linear, c[side], c[(side + 1) % 4], cell)?;
            if let Some(l) = lens {
                for p in &mut points {
                    *p = l.undistort(p[0], p[1]);
                }
            }
            lines[side] = robust_line(&points, lens.map_or(1.0, |l| 1.0 / l.fx))?;
        }
        let mut next = [[0.0; 2]; 4];
        for (i, corner) in next.iter_mut().enumerate() {
            let p = intersect(&lines[(i + 3) % 4], &lines[i])?;
            *corner = match lens {
                Some(l) => l.distort(p[0], p[1]),
                None => p,
            };
        }
        // A refinement that moves a corner by more than a cell has locked onto something else.
        if next
            .iter()
            .zip(&c)
            .any(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt() > cell.max(1.5))
        {
            return None;
        }
        c = next;
    }
    Some(c)
}

/// Places on the edge between `a` and `b`: halfway crossings of the intensity along the side's normal.
fn side_points(gray: &Gray, a: [f64; 2], b: [f64; 2], cell: f64) -> Option<Vec<[f64; 2]>> {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len = (dx * dx + dy * dy).sqrt();
    if len < 4.0 {
        return None;
    }
    let dir = [dx / len, dy / len];
    // Clockwise as seen (y down): the outside of the marker is to the left of the direction of travel.
    let outward = [dir[1], -dir[0]];
    let reach = (0.45 * cell).clamp(1.5, 6.0);
    let step = 0.25;
    let count = (len / 1.0).clamp(8.0, 200.0) as usize;
    let mut points = Vec::with_capacity(count);
    for k in 0..count {
        // Away from the corners, where the other side's edge and the neighbouring squares are.
        let t = 0.2 + 0.6 * (k as f64 + 0.5) / count as f64;
        let base = [a[0] + dx * t, a[1] + dy * t];
        let samples = (2.0 * reach / step) as usize + 1;
        let profile: Vec<f64> = (0..samples)
            .map(|i| {
                let s = -reach + i as f64 * step;
                gray.bilinear(base[0] + outward[0] * s, base[1] + outward[1] * s) as f64
            })
            .collect();
        let inside = profile[..samples / 4].iter().sum::<f64>() / (samples / 4) as f64;
        let outside = profile[samples - samples / 4..].iter().sum::<f64>() / (samples / 4) as f64;
        if outside - inside < 5.0 {
            continue; // no clear dark-to-light edge here (occluded, or glare)
        }
        let half = 0.5 * (inside + outside);
        // The crossing nearest the profile's middle.
        let mut best: Option<(f64, f64)> = None;
        for i in 0..samples - 1 {
            let (p, q) = (profile[i], profile[i + 1]);
            if (p - half) * (q - half) <= 0.0 && p != q {
                let s = -reach + (i as f64 + (half - p) / (q - p)) * step;
                if best.is_none_or(|(bs, _)| s.abs() < bs.abs()) {
                    best = Some((s, 0.0));
                }
            }
        }
        if let Some((s, _)) = best {
            points.push([base[0] + outward[0] * s, base[1] + outward[1] * s]);
        }
    }
    (points.len() >= 4).then_some(points)
}

/// A line through `points`, fitted again without those more than half a pixel (`pixel` in the points' units)
/// off the first fit.
fn robust_line(points: &[[f64; 2]], pixel: f64) -> Option<[f64; 3]> {
    let mut line = fit_line(points)?;
    let kept: Vec<[f64; 2]> = points
        .iter()
        .copied()
        .filter(|p| (line[0] * p[0] + line[1] * p[1] - line[2]).abs() < 0.5 * pixel)
        .collect();
    if kept.len() >= 4 && kept.len() < points.len() {
        line = fit_line(&kept)?;
    }
    Some(line)
}

/// The line `a x + b y = c` (unit normal) through points, by total least squares.
pub(crate) fn fit_line(pts: &[[f64; 2]]) -> Option<[f64; 3]> {
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p[0]).sum::<f64>() / n,
        pts.iter().map(|p| p[1]).sum::<f64>() / n,
    );
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let (dx, dy) = (p[0] - mx, p[1] - my);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    // The direction is the scatter's principal axis; the normal is across it.
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (a, b) = (-theta.sin(), theta.cos());
    Some([a, b, a * mx + b * my])
}

/// Where two lines `a x + b y = c` meet.
pub(crate) fn intersect(l1: &[f64; 3], l2: &[f64; 3]) -> Option<[f64; 2]> {
    let det = l1[0] * l2[1] - l1[1] * l2[0];
    if det.abs() < 1e-9 {
        return None;
    }
    Some([
        (l1[2] * l2[1] - l1[1] * l2[2]) / det,
        (l1[0] * l2[2] - l1[2] * l2[0]) / det,
    ])
}
