//! Where a training step's time goes: wall-clock seconds per phase, summed over a run's steps, so a profile
//! of training can be read without `perf` (`pganeus bench-train` prints them; issue 73's profile).

use serde::Serialize;
use std::time::Instant;

/// Seconds spent in each phase of [`crate::NeusTrainer::step`], summed over the steps taken.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StepPhases {
    /// Drawing the batch's pixels and their rays.
    pub rays: f64,
    /// Marching the occupancy grid for the samples (and keeping those near the surface).
    pub march: f64,
    /// The field at the samples and a step away: SDF, gradients, colours.
    pub field_forward: f64,
    /// The background field behind each ray, forward.
    pub background_forward: f64,
    /// Compositing each ray, its losses and their gradients with respect to the samples.
    pub render: f64,
    /// The background field's backward pass.
    pub background_backward: f64,
    /// Back through the colour and SDF networks and the grid to the parameters.
    pub field_backward: f64,
    /// The eikonal and no-overhang terms at the regulariser points set aside among the dropped samples.
    pub regulariser: f64,
    /// Finding the multi-view stereo points (once, at the first step that uses them).
    pub stereo_start: f64,
    /// The stereo points' term (forward and backward).
    pub stereo: f64,
    /// The optimiser's steps.
    pub adam: f64,
    /// The parameters' running mean over the last steps.
    pub average: f64,
    /// The occupancy grid's refresh.
    pub occupancy: f64,
}

impl StepPhases {
    /// The sum of every phase.
    pub fn total(&self) -> f64 {
        self.rays
            + self.march
            + self.field_forward
            + self.background_forward
            + self.render
            + self.background_backward
            + self.field_backward
            + self.regulariser
            + self.stereo_start
            + self.stereo
            + self.adam
            + self.average
            + self.occupancy
    }
}

/// A stopwatch that charges the time since its last lap to a phase.
pub(crate) struct Lap(Instant);

impl Lap {
    pub(crate) fn start() -> Self {
        Self(Instant::now())
    }

    /// Add the seconds since the last lap (or the start) to `phase`.
    pub(crate) fn charge(&mut self, phase: &mut f64) {
        let now = Instant::now();
        *phase += (now - self.0).as_secs_f64();
        self.0 = now;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laps_charge_each_phase_its_own_time_and_the_total_sums_them() {
        let mut p = StepPhases::default();
        let mut lap = Lap::start();
        std::thread::sleep(std::time::Duration::from_millis(20));
        lap.charge(&mut p.march);
        lap.charge(&mut p.adam);
        assert!(p.march >= 0.02, "{}", p.march);
        assert!(p.adam < 0.01, "the second lap starts where the first ended: {}", p.adam);
        p.rays = 1.0;
        assert!((p.total() - (1.0 + p.march + p.adam)).abs() < 1e-12);
    }
}
