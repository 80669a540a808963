//! Binary images (a `bool` a pixel, `width` pixels a row): connected components, growing and shrinking by
//! a square, holes filled. Shared by the board detector and the masks computed from video.

/// The 8-connected components of `mask`: a label per pixel (0 for pixels off the mask, components from 1)
/// and each component's pixel count.
pub fn components(mask: &[bool], width: usize, height: usize) -> (Vec<u32>, Vec<usize>) {
    let mut parent: Vec<u32> = vec![0];
    fn find(parent: &mut [u32], mut a: u32) -> u32 {
        while parent[a as usize] != a {
            parent[a as usize] = parent[parent[a as usize] as usize];
            a = parent[a as usize];
        }
        a
    }
    let mut labels = vec![0u32; width * height];
    for y in 0..height {
        for x in 0..width {
            if !mask[y * width + x] {
                continue;
            }
            let mut neighbours = [0u32; 4];
            let mut n = 0;
            let mut look = |xx: i64, yy: i64| {
                if xx >= 0 && yy >= 0 && (xx as usize) < width {
                    let l = labels[yy as usize * width + xx as usize];
                    if l != 0 {
                        neighbours[n] = l;
                        n += 1;
                    }
                }
            };
            let (xi, yi) = (x as i64, y as i64);
            look(xi - 1, yi);
            if y > 0 {
                look(xi - 1, yi - 1);
                look(xi, yi - 1);
                look(xi + 1, yi - 1);
            }
            let label = if n == 0 {
                parent.push(parent.len() as u32);
                (parent.len() - 1) as u32
            } else {
                let mut root = find(&mut parent, neighbours[0]);
                for &other in &neighbours[1..n] {
                    let r = find(&mut parent, other);
                    if r != root {
                        let (lo, hi) = (root.min(r), root.max(r));
                        parent[hi as usize] = lo;
                        root = lo;
                    }
                }
                root
            };
            labels[y * width + x] = label;
        }
    }
    // Flatten to consecutive labels.
    let mut remap = vec![0u32; parent.len()];
    let mut next = 0u32;
    for l in 1..parent.len() as u32 {
        let r = find(&mut parent, l);
        if r == l {
            next += 1;
            remap[l as usize] = next;
        }
    }
    let mut sizes = vec![0usize; next as usize + 1];
    for l in labels.iter_mut() {
        if *l != 0 {
            *l = remap[find(&mut parent, *l) as usize];
            sizes[*l as usize] += 1;
        }
    }
    (labels, sizes)
}

/// `mask` grown (dilated) by `r` pixels (a square), `width` pixels a row: rows, then columns, each a running count.
pub fn dilate(mask: &[bool], width: usize, r: usize) -> Vec<bool> {
    let height = mask.len() / width.max(1);
    let pass = |src: &[bool], along_rows: bool| -> Vec<bool> {
        let (lines, len) = if along_rows { (height, width) } else { (width, height) };
        let at = |line: usize, i: usize| if along_rows { line * width + i } else { i * width + line };
        let mut out = vec![false; src.len()];
        for line in 0..lines {
            let mut count = 0usize;
            // The window [i − r, i + r]: count what enters at i + r and leaves at i − r − 1.
            for i in 0..len.min(r) {
                count += src[at(line, i)] as usize;
            }
            for i in 0..len {
                if i + r < len {
                    count += src[at(line, i + r)] as usize;
                }
                if i > r {
                    count -= src[at(line, i - r - 1)] as usize;
                }
                out[at(line, i)] = count > 0;
            }
        }
        out
    };
    pass(&pass(mask, true), false)
}

/// `mask` shrunk (eroded) by `r` pixels (a square): a pixel stays where its whole square is on the mask
/// (pixels past the image's edge count as on it, so a mask touching the edge keeps its edge).
pub fn erode(mask: &[bool], width: usize, r: usize) -> Vec<bool> {
    let off: Vec<bool> = mask.iter().map(|&m| !m).collect();
    dilate(&off, width, r).into_iter().map(|m| !m).collect()
}

/// `mask` with its holes filled: the pixels off the mask that no path of off pixels (4-connected) joins to
/// the image's edge.
pub fn fill_holes(mask: &[bool], width: usize) -> Vec<bool> {
    let height = mask.len() / width.max(1);
    let mut outside = vec![false; mask.len()];
    let mut stack: Vec<usize> = Vec::new();
    for y in 0..height {
        for x in 0..width {
            if (x == 0 || y == 0 || x + 1 == width || y + 1 == height) && !mask[y * width + x] {
                outside[y * width + x] = true;
                stack.push(y * width + x);
            }
        }
    }
    while let Some(p) = stack.pop() {
        let (x, y) = (p % width, p / width);
        let mut visit = |q: usize| {
            if !mask[q] && !outside[q] {
                outside[q] = true;
                stack.push(q);
            }
        };
        if x > 0 {
            visit(p - 1);
        }
        if x + 1 < width {
            visit(p + 1);
        }
        if y > 0 {
            visit(p - width);
        }
        if y + 1 < height {
            visit(p + width);
        }
    }
    outside.into_iter().map(|o| !o).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grown_mask_reaches_r_pixels_every_way() {
        let (w, h) = (9, 7);
        let mut mask = vec![false; w * h];
        mask[3 * w + 4] = true;
        let g = dilate(&mask, w, 2);
        for y in 0..h {
            for x in 0..w {
                let inside = x.abs_diff(4) <= 2 && y.abs_diff(3) <= 2;
                assert_eq!(g[y * w + x], inside, "({x}, {y})");
            }
        }
    }

    #[test]
    fn eroding_undoes_growing_a_square_and_holes_fill_but_bays_do_not() {
        let (w, h) = (12, 10);
        let mut mask = vec![false; w * h];
        for y in 3..7 {
            for x in 4..8 {
                mask[y * w + x] = true;
            }
        }
        assert_eq!(erode(&dilate(&mask, w, 1), w, 1), mask);
        // A ring with a hole, and a bay open to the edge.
        let mut ring = vec![false; w * h];
        for y in 1..6 {
            for x in 1..6 {
                ring[y * w + x] = !(x == 3 && y == 3);
            }
        }
        for y in 0..4 {
            ring[y * w + 9] = true;
            ring[y * w + 11] = true;
        }
        let filled = fill_holes(&ring, w);
        assert!(filled[3 * w + 3], "the hole is filled");
        assert!(!filled[w + 10], "a bay open to the edge stays open");
        assert_eq!(
            filled.iter().filter(|&&m| m).count(),
            ring.iter().filter(|&&m| m).count() + 1
        );
    }

    #[test]
    fn components_are_8_connected_and_counted() {
        let (w, h) = (6, 4);
        let mut mask = vec![false; w * h];
        for p in [(0, 0), (1, 1), (4, 0), (5, 0), (4, 3)] {
            mask[p.1 * w + p.0] = true;
        }
        let (labels, sizes) = components(&mask, w, h);
        assert_eq!(sizes.len(), 4, "three components and the background's 0");
        assert_eq!(labels[0], labels[w + 1], "diagonal neighbours join");
        assert_eq!(sizes[labels[4] as usize], 2);
    }
}
