//! How a trainer's held-out views are rendered and scored: PSNR, and for an object capture with masks
//! the rendered silhouette against the masks.

use crate::appearance::psnr_right_half;
use crate::render_view::{psnr, render_view, RenderSettings, STOP_TRANSMITTANCE};
use crate::{CaptureSubject, NeusTrainer};

/// What a trainer's held-out views say.
pub struct Holdout {
    /// Mean PSNR (inside the masks when there are masks); with per-view appearance, of each view's right
    /// half through the colour map fitted on its left half.
    pub psnr: f32,
    /// Mean PSNR of each view's right half through the colour map fitted on its left half, whatever the
    /// setting: runs with and without per-view appearance compared on one footing.
    pub psnr_fitted: f32,
    /// The rendered silhouette against the masks; empty (no area) for a scene or a capture without masks.
    pub silhouette: SilhouetteTally,
}

/// The settings a trainer renders its held-out views with at its current step: twice its training's
/// steps and sample cap, the levels active now.
fn settings(t: &NeusTrainer) -> RenderSettings {
    let levels = t.config.active_levels(t.step);
    RenderSettings {
        steps_per_ray: t.config.steps_per_ray * 2,
        max_samples_per_ray: t.config.max_samples_per_ray * 2,
        active_levels: levels,
        fd_eps: t.fd_eps(levels).min(t.config.field.grid.finest_cell() * 4.0),
        view_independent: t.step < t.config.view_independent_steps,
        stop_transmittance: STOP_TRANSMITTANCE,
    }
}

/// Render the views `views` of a trainer's capture and score them.
pub fn score(t: &NeusTrainer, views: &[usize]) -> Holdout {
    let set = settings(t);
    let object_masks = t.config.kind == CaptureSubject::Object && t.data.has_masks();
    let (mut psnr_sum, mut fitted_sum) = (0.0f32, 0.0f32);
    let mut tally = SilhouetteTally::default();
    for &i in views {
        let v = &t.data.views[i];
        let img = render_view(&t.field, &t.occupancy, &set, &v.camera);
        // The view's exposure is not known: fitted on its left half, the right half scored.
        let fitted = psnr_right_half(&img.rgb, &v.rgb, v.mask.as_deref(), t.data.width as usize);
        fitted_sum += fitted;
        psnr_sum += if t.config.per_view_appearance {
            fitted
        } else {
            psnr(&img.rgb, &v.rgb, v.mask.as_deref())
        };
        if let (true, Some(mask)) = (object_masks, &v.mask) {
            tally.add(&img.opacity, mask);
        }
    }
    Holdout {
        psnr: psnr_sum / views.len().max(1) as f32,
        psnr_fitted: fitted_sum / views.len().max(1) as f32,
        silhouette: tally,
    }
}

/// Render a trainer's held-out views and score them.
pub fn holdout(t: &NeusTrainer) -> Holdout {
    score(t, &t.holdout_views)
}

/// A field's rendered opacity against masks, summed over views: how much larger (or smaller) the drawn
/// silhouette is than what the masks mark. A fit that matches silhouettes turns such an excess into depth:
/// a silhouette 1 % too large in area puts a body 0.5 % too far from the camera.
#[derive(Clone, Copy, Debug, Default)]
pub struct SilhouetteTally {
    opacity: f64,
    marked: f64,
    both: usize,
    either: usize,
}

impl SilhouetteTally {
    pub fn add(&mut self, opacity: &[f32], mask: &[f32]) {
        for (&o, &m) in opacity.iter().zip(mask) {
            self.opacity += o as f64;
            self.marked += m as f64;
            let (a, b) = (o > 0.5, m > 0.5);
            self.both += (a && b) as usize;
            self.either += (a || b) as usize;
        }
    }

    /// Another tally's pixels added to this one.
    pub fn merge(&mut self, other: &Self) {
        self.opacity += other.opacity;
        self.marked += other.marked;
        self.both += other.both;
        self.either += other.either;
    }

    /// Summed opacity over the masks' summed value, minus one, in percent (None without marked pixels).
    pub fn area_excess_percent(&self) -> Option<f64> {
        (self.marked > 0.0).then(|| 100.0 * (self.opacity / self.marked - 1.0))
    }

    /// Intersection over union of opacity > 0.5 and mask > 0.5.
    pub fn iou(&self) -> f64 {
        self.both as f64 / self.either.max(1) as f64
    }
}
