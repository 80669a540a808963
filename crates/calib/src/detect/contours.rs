//! Dark blobs of an adaptive threshold and their outer boundaries: where marker candidates come from.

use crate::gray::{Gray, Integral};
pub use geom::mask::components;

/// Pixels darker than the mean of the `2 * radius + 1` square around them by more than `offset` (0–255): a
/// marker's black border stays dark under any light that changes slowly across the image.
pub fn adaptive_threshold(gray: &Gray, integral: &Integral, radius: usize, offset: f32) -> Vec<bool> {
    let mut dark = vec![false; gray.width * gray.height];
    for y in 0..gray.height {
        for x in 0..gray.width {
            dark[y * gray.width + x] = gray.data[y * gray.width + x] < integral.box_mean(x, y, radius) - offset;
        }
    }
    dark
}

/// The clockwise ring of neighbour offsets, starting east (image y down, so "clockwise" as seen).
const RING: [(i64, i64); 8] = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)];

/// The outer boundary of the component `label` whose first pixel in raster order is `start`, traced by
/// Moore-neighbour following (clockwise as seen), as pixel positions. Stops on returning to `start` about to
/// take the first step again (Jacob's criterion); `max_steps` bounds the walk.
pub fn trace_boundary(
    labels: &[u32],
    width: usize,
    height: usize,
    start: (usize, usize),
    max_steps: usize,
) -> Vec<[i64; 2]> {
    let label = labels[start.1 * width + start.0];
    let inside = |x: i64, y: i64| {
        x >= 0
            && y >= 0
            && (x as usize) < width
            && (y as usize) < height
            && labels[y as usize * width + x as usize] == label
    };
    let s = [start.0 as i64, start.1 as i64];
    let mut boundary = vec![s];
    // The west neighbour of the first pixel in raster order is outside the component.
    let mut backtrack = 4usize;
    let mut current = s;
    let mut first_step: Option<[i64; 2]> = None;
    for _ in 0..max_steps {
        let mut moved = None;
        for k in 1..=8 {
            let dir = (backtrack + k) % 8;
            let (dx, dy) = RING[dir];
            let next = [current[0] + dx, current[1] + dy];
            if inside(next[0], next[1]) {
                // The neighbour examined just before `next` (outside the component), seen from `next`.
                let (bx, by) = RING[(dir + 7) % 8];
                let outside = [current[0] + bx, current[1] + by];
                let rel = (outside[0] - next[0], outside[1] - next[1]);
                let back = RING
                    .iter()
                    .position(|&o| o == rel)
                    .expect("ring neighbours are adjacent");
                moved = Some((next, back));
                break;
            }
        }
        let Some((next, back)) = moved else {
            break; // a single pixel
        };
        if current == s {
            match first_step {
                None => first_step = Some(next),
                Some(f) if f == next => break,
                Some(_) => {}
            }
        }
        boundary.push(next);
        current = next;
        backtrack = back;
    }
    if boundary.len() > 1 && boundary.last() == Some(&s) {
        boundary.pop();
    }
    boundary
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_ring_is_one_component_with_a_square_boundary() {
        let (w, h) = (12, 10);
        let mut mask = vec![false; w * h];
        for y in 2..8 {
            for x in 3..10 {
                if y == 2 || y == 7 || x == 3 || x == 9 {
                    mask[y * w + x] = true;
                }
            }
        }
        mask[0] = true; // another component
        let (labels, sizes) = components(&mask, w, h);
        assert_eq!(sizes.len(), 3);
        let start = (3, 2);
        let b = trace_boundary(&labels, w, h, start, 1000);
        // The outer boundary of a 7 x 6 rectangle of pixels: 2 * (6 + 5) steps.
        assert_eq!(b.len(), 22, "{b:?}");
        assert!(b.contains(&[9, 7]) && b.contains(&[3, 7]) && b.contains(&[9, 2]));
        assert!(!b.contains(&[4, 3]), "the ring's inside is not on the outer boundary");
    }
}
