//! Which of several fits to keep: a multi-start's start where its starts fit GA's poses alike (the images
//! choose), and per frame the better of two GA passes. Decisions of the method with no I/O.

use crate::poses_from_video::FramePose;

/// PGA's starts that end within this share of the best one's loss fit GA's poses alike (the drop Rapier
/// made at 320×240: 0.0641 against 0.0680, launches 20 % apart), and the one whose simulation explains the
/// video best (its image loss over every frame) is kept: GA's poses are a proxy for the images. The same
/// share of the image loss is a tie too: the images overrule PGA's own pick only where they tell the starts
/// apart (the Rapier drop: 2.76 against 3.47; the backdrop slide's 0.748 against 0.755 do not, and the pick
/// they would have overruled had the launch spin right).
pub const PGA_TIE: f64 = 0.1;

/// The start to keep of a multi-start whose starts ended at `losses`: PGA's own pick (the lowest; the first
/// of equal ones) unless, of the starts within `tie` of it (`(1 + tie)` times its loss), the one `image_loss`
/// scores lowest beats the pick's score by more than `tie` too (each start scored once, in order). `None`
/// when no start ended with a finite loss.
pub fn among_ties<E>(
    losses: &[f64],
    tie: f64,
    mut image_loss: impl FnMut(usize) -> Result<f64, E>,
) -> Result<Option<usize>, E> {
    let lowest = losses.iter().cloned().fold(f64::INFINITY, f64::min);
    let Some(pick) = losses.iter().position(|&l| l == lowest) else {
        return Ok(None);
    };
    let mut pick_score = None;
    let mut best: Option<(usize, f64)> = None;
    for (i, &l) in losses.iter().enumerate() {
        if !(l <= lowest * (1.0 + tie)) {
            continue;
        }
        let score = image_loss(i)?;
        if i == pick {
            pick_score = Some(score);
        }
        if best.is_none_or(|(_, b)| score < b) {
            best = Some((i, score));
        }
    }
    Ok(Some(match (best, pick_score) {
        (Some((i, b)), Some(p)) if p > b * (1.0 + tie) => i,
        _ => pick,
    }))
}

/// Per body and frame, the GA pose of `a` or `b` with the lower image loss (a fitted one before one that
/// was not: a frame without the body's mask).
pub fn better_per_frame(a: &[Vec<FramePose>], b: &[Vec<FramePose>]) -> Vec<Vec<FramePose>> {
    a.iter()
        .zip(b)
        .map(|(a, b)| {
            a.iter()
                .zip(b)
                .map(|(x, y)| {
                    let better_b = match (x.fitted, y.fitted) {
                        (true, true) => y.image.loss < x.image.loss,
                        (fx, fy) => fy && !fx,
                    };
                    if better_b {
                        y.clone()
                    } else {
                        x.clone()
                    }
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_images_choose_among_starts_that_fit_the_poses_alike() {
        // Starts 1 and 2 tie (within a tenth); start 3 explains the images best but fits the poses worse.
        let pga = [1.0, 0.50, 0.54, 0.9];
        let image = [3.0, 2.5, 2.0, 1.0];
        let mut asked = Vec::new();
        let chosen = among_ties(&pga, 0.1, |i| {
            asked.push(i);
            Ok::<_, ()>(image[i])
        })
        .unwrap()
        .unwrap();
        assert_eq!((chosen, asked), (2, vec![1, 2]));
        // Images that tie too (2.4 against 2.5: within a tenth) leave PGA's own pick.
        let image = [3.0, 2.5, 2.4, 1.0];
        assert_eq!(among_ties(&pga, 0.1, |i| Ok::<_, ()>(image[i])).unwrap().unwrap(), 1);
        // PGA's pick is the first of equal losses.
        assert_eq!(among_ties(&[0.5, 0.5], 0.1, |_| Ok::<_, ()>(1.0)).unwrap().unwrap(), 0);
        // Without a tie the lowest loss wins, scored once.
        assert_eq!(among_ties(&pga, 0.0, |_| Ok::<_, ()>(0.0)).unwrap().unwrap(), 1);
        assert_eq!(among_ties(&[f64::NAN], 0.1, |_| Ok::<_, ()>(0.0)).unwrap(), None);
    }
}
