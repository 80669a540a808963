//! From a blob's boundary to a quadrilateral: Douglas–Peucker to four vertices, the shape checks a marker's
//! outline must pass, and corners from lines fitted to each side.

/// The vertices Douglas–Peucker keeps of the closed polygon `points` at tolerance `epsilon` (indices, in order).
pub fn simplify_closed(points: &[[i64; 2]], epsilon: f64) -> Vec<usize> {
    let n = points.len();
    if n < 3 {
        return (0..n).collect();
    }
    let d2 = |a: usize, b: usize| {
        let (dx, dy) = (
            (points[a][0] - points[b][0]) as f64,
            (points[a][1] - points[b][1]) as f64,
        );
        dx * dx + dy * dy
    };
    // Split the loop at the point farthest from the first, and at the point farthest from that one.
    let a = (0..n).max_by(|&i, &j| d2(0, i).total_cmp(&d2(0, j))).unwrap_or(0);
    let b = (0..n).max_by(|&i, &j| d2(a, i).total_cmp(&d2(a, j))).unwrap_or(0);
    let (a, b) = (a.min(b), a.max(b));
    if a == b {
        return vec![a];
    }
    let mut keep = vec![a];
    simplify_open(points, a, b, epsilon, &mut keep);
    keep.push(b);
    simplify_open(points, b, a + n, epsilon, &mut keep);
    keep
}

/// Douglas–Peucker between `from` and `to` (indices modulo the loop), pushing the kept inner vertices in order.
fn simplify_open(points: &[[i64; 2]], from: usize, to: usize, epsilon: f64, keep: &mut Vec<usize>) {
    let n = points.len();
    if to <= from + 1 {
        return;
    }
    let p = |i: usize| [points[i % n][0] as f64, points[i % n][1] as f64];
    let (s, e) = (p(from), p(to));
    let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
    let len = (dx * dx + dy * dy).sqrt();
    let mut worst = (0.0, from);
    for i in from + 1..to {
        let q = p(i);
        let d = if len > 0.0 {
            ((q[0] - s[0]) * dy - (q[1] - s[1]) * dx).abs() / len
        } else {
            ((q[0] - s[0]).powi(2) + (q[1] - s[1]).powi(2)).sqrt()
        };
        if d > worst.0 {
            worst = (d, i);
        }
    }
    if worst.0 > epsilon {
        simplify_open(points, from, worst.1, epsilon, keep);
        keep.push(worst.1 % n);
        simplify_open(points, worst.1, to, epsilon, keep);
    }
}

/// The length of the closed polygon.
pub fn perimeter(points: &[[i64; 2]]) -> f64 {
    let n = points.len();
    (0..n)
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % n]);
            (((a[0] - b[0]).pow(2) + (a[1] - b[1]).pow(2)) as f64).sqrt()
        })
        .sum()
}

/// Whether the quadrilateral is convex (either orientation).
pub fn is_convex(q: &[[f64; 2]; 4]) -> bool {
    let mut sign = 0.0;
    for i in 0..4 {
        let (a, b, c) = (q[i], q[(i + 1) % 4], q[(i + 2) % 4]);
        let cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
        if cross == 0.0 || (sign != 0.0 && cross.signum() != sign) {
            return false;
        }
        sign = cross.signum();
    }
    true
}

/// The corners ordered clockwise as seen (image y down), as a marker's corners are printed.
pub fn clockwise(mut q: [[f64; 2]; 4]) -> [[f64; 2]; 4] {
    let (a, b, c) = (q[0], q[1], q[2]);
    let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if cross < 0.0 {
        q.swap(1, 3);
    }
    q
}

/// Corners from the boundary: a line fitted (total least squares) to each side's points between the vertices
/// `corners` (indices into `points`, in order), leaving out the points near the vertices, and neighbouring
/// lines intersected. `None` where a side has too few points or two sides are parallel.
pub fn corners_from_sides(points: &[[i64; 2]], corners: &[usize; 4]) -> Option<[[f64; 2]; 4]> {
    let n = points.len();
    let mut lines = [[0.0f64; 3]; 4];
    for side in 0..4 {
        let (from, to) = (corners[side], corners[(side + 1) % 4]);
        let len = (to + n - from) % n;
        if len < 4 {
            return None;
        }
        let skip = (len / 8).max(1);
        let pts: Vec<[f64; 2]> = (skip..=len - skip)
            .map(|k| {
                let p = points[(from + k) % n];
                [p[0] as f64, p[1] as f64]
            })
            .collect();
        lines[side] = super::edges::fit_line(&pts)?;
    }
    let mut out = [[0.0; 2]; 4];
    for (i, corner) in out.iter_mut().enumerate() {
        // Corner i is where the side ending at it (i - 1) meets the side starting at it (i).
        *corner = super::edges::intersect(&lines[(i + 3) % 4], &lines[i])?;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_outline_simplifies_to_its_four_corners() {
        let mut pts = Vec::new();
        for x in 0..10 {
            pts.push([x, 0]);
        }
        for y in 0..10 {
            pts.push([10, y]);
        }
        for x in (1..=10).rev() {
            pts.push([x, 10]);
        }
        for y in (1..=10).rev() {
            pts.push([0, y]);
        }
        let keep = simplify_closed(&pts, 0.03 * perimeter(&pts));
        let mut corners: Vec<[i64; 2]> = keep.iter().map(|&i| pts[i]).collect();
        corners.sort();
        assert_eq!(corners, vec![[0, 0], [0, 10], [10, 0], [10, 10]]);
        let mut idx = keep.clone();
        idx.sort();
        let q = corners_from_sides(&pts, &[idx[0], idx[1], idx[2], idx[3]]).unwrap();
        assert!(
            q.iter()
                .any(|c| (c[0] - 10.0).abs() < 1e-9 && (c[1] - 10.0).abs() < 1e-9),
            "{q:?}"
        );
        assert!(is_convex(&q));
    }
}
