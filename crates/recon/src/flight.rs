//! The launch from the flight: does a physics fit's launch explain the frames before the first contact as
//! well as a launch fitted to those frames alone? If not, that launch is held and the contact values are
//! fitted around it.
//!
//! Before the first contact the simulator is exact (gravity and inertia): the flight tells the launch to the
//! observations' own precision. After it the motion also depends on the contact model, and where the model
//! cannot make the observed motion (a reconstructed body tumbling off the board, another engine's
//! contacts), a fit over every frame bends the launch to explain the later frames a little better: in a
//! least-absolute-error fit every frame pulls alike, and the contact frames outnumber the flight's. (The
//! tabletop drop from a rough first pose: v0 10 % off, the simulation 1.3 mm across the line of sight from
//! GA's pose by frame 3, where GA's poses are 0.1–0.2 mm from the true ones across it.) Where the model is
//! right, the later frames tell the launch too, and better than a short flight seen from one camera: so
//! the launch over every frame is kept unless the flight refutes it.
//!
//! The test: `S_joint` and `S_flight`, the weighed squared errors over the flight of the joint launch and of
//! the flight's own; with `n` degrees of freedom of the errors and `p` values the flight fit moves,
//! `σ² = S_flight / (n − p)` and `(S_joint − S_flight) / σ²` is χ² with `p` degrees of freedom when the
//! joint launch is the true one up to the noise. Above its 1 % point, the launch may have been bent. Only
//! may: `σ²` comes from a few frames whose errors are not independent (GA's depth drifts over a flight), so
//! the test also flags launches the contacts did not bend, and `fit` keeps the flight's launch only where
//! its simulation explains the video's images better than the joint one's.

use crate::fit_physics::{fit_multi_start_bodies, FitError, MultiStart, Observed, PhysicsFit, PhysicsFitConfig};
use crate::{StartResult, StartsOn};
use sim::World;

/// A flight shorter than this tells too little (two frames of an unknown initial pose and launch) to overrule
/// the frames after it.
pub const MIN_FLIGHT_FRAMES: usize = 3;

/// The standard normal's one-sided 1 % point: the test's level.
const LEVEL_Z: f64 = 2.326;

/// What the flight says of a fitted launch.
#[derive(Clone, Debug)]
pub struct FlightCheck {
    /// The frames tested (frame 0 counted): before the first contact in the fitted world's simulation
    /// ([`check_flight`]), or the window given ([`check_window`]).
    pub frames: usize,
    /// The weighed squared errors over the flight: of the fitted launch, and of the flight's own.
    pub joint_squares: f64,
    pub flight_squares: f64,
    /// The errors' degrees of freedom over the flight, and the values the flight fit moves.
    pub dof: usize,
    pub unknowns: usize,
    /// `(S_joint − S_flight) / σ²`, and its 1 % point.
    pub statistic: f64,
    pub critical: f64,
    /// The fitted world with the flight's launch (initial poses, v0, ω0 of the observed bodies) in place.
    pub flight_world: World,
}

impl FlightCheck {
    /// The fitted launch misses the flight by more than its noise: the contacts may have bent it.
    pub fn bent(&self) -> bool {
        self.statistic > self.critical
    }
}

/// The χ² distribution's upper point at the standard normal's `z` (Wilson–Hilferty: within 1 % of the
/// exact point from 3 degrees of freedom up).
fn chi_square_point(dof: usize, z: f64) -> f64 {
    let k = dof as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// The first frame (from 1) in which the world's simulation touches anything with one of `bodies`; `None`
/// if it never does.
pub fn first_contact_frame(world: &World, bodies: &[usize]) -> Option<usize> {
    let traj = world.simulate(&world.params());
    let pairs = world.pairs();
    traj.contacts.iter().enumerate().skip(1).find_map(|(k, c)| {
        let scene = bodies.iter().any(|&b| c.scene.get(b).copied().unwrap_or(false));
        let pair = pairs
            .iter()
            .zip(&c.pairs)
            .any(|(&(i, j), &on)| on && (bodies.contains(&i) || bodies.contains(&j)));
        (scene || pair).then_some(k)
    })
}

/// `observed` cut to its first `frames` frames.
fn first_frames(observed: &[Observed], frames: usize) -> Vec<Observed> {
    observed
        .iter()
        .map(|o| Observed {
            poses: o.poses[..frames].to_vec(),
            weights: o.weights.as_ref().map(|w| w[..frames].to_vec()),
            depth_held: o.depth_held.iter().take(frames).copied().collect(),
            ..o.clone()
        })
        .collect()
}

/// The flight test of `fitted` (a world fitted to `observed` with `cfg`, its initial states as fitted):
/// `None` when the simulation flies fewer than [`MIN_FLIGHT_FRAMES`] frames before its first contact, never
/// touches anything within the observed frames, `cfg` fits no part of the launch, or the flight has no more
/// degrees of freedom than values.
pub fn check_flight(
    cfg: &PhysicsFitConfig,
    fitted: &World,
    observed: &[Observed],
) -> Result<Option<FlightCheck>, FitError> {
    let total = observed.first().map_or(0, |o| o.poses.len());
    let bodies: Vec<usize> = observed.iter().map(|o| o.body).collect();
    let mut world = fitted.clone();
    world.config.frames = total;
    let Some(frames) = first_contact_frame(&world, &bodies) else {
        return Ok(None);
    };
    // In flight no contact value matters.
    let flight_cfg = PhysicsFitConfig {
        fit_restitution: false,
        fit_friction: false,
        fit_pair_restitution: false,
        fit_pair_friction: false,
        ..cfg.clone()
    };
    check_window(&flight_cfg, &world, observed, frames, None)
}

/// The same test over an explicit window, `observed`'s first `frames` frames, before whatever the model may
/// not make (the several-body schedule's frames before the first collision, where the bodies may slide on
/// the scene): the window's own fit moves what `cfg` fits (the launch, and the scene's values where it fits
/// them), and the fitted world's values are `fitted`'s. `None` when the window is shorter than
/// [`MIN_FLIGHT_FRAMES`], `cfg` fits nothing, or the window has no more degrees of freedom than values.
///
/// `precision`: the images' own precision on each error's component (m, one standard deviation; e.g. an
/// edge's precision across the line of sight at the bodies' depth), a floor under the noise the window's
/// own fit measures. It applies to the rotation's components as to the translation's: a fit weighs a turn
/// in metres at the bodies' radius, where an edge's precision over the radius is the image's precision on
/// the turn. A window of four frames leaves its fit of a dozen values a dozen degrees of freedom,
/// and a model a little off the data (a body that starts half a millimetre over the board, launched along
/// it) leaves errors that a fit of so many values absorbs better than noise: on poses jittered by a
/// fifth of a millimetre, the true launch's statistic came out at twice the 1 % point without the floor.
pub fn check_window(
    cfg: &PhysicsFitConfig,
    fitted: &World,
    observed: &[Observed],
    frames: usize,
    precision: Option<f64>,
) -> Result<Option<FlightCheck>, FitError> {
    let total = observed.first().map_or(0, |o| o.poses.len());
    if frames < MIN_FLIGHT_FRAMES || frames > total {
        return Ok(None);
    }
    let mut world = fitted.clone();
    world.config.frames = total;
    let window_cfg = PhysicsFitConfig {
        initial_window: 0,
        ..cfg.clone()
    };
    let joint = match PhysicsFit::new_bodies(window_cfg, world.clone(), first_frames(observed, frames)) {
        Ok(fit) => fit.with_params_of(&world),
        // The settings hold the whole launch: nothing to test.
        Err(FitError::NothingToFit) => return Ok(None),
        Err(e) => return Err(e),
    };
    let (joint_squares, dof) = joint.squares();
    let unknowns = joint.unknown_count();
    if dof <= unknowns {
        return Ok(None);
    }
    let mut own = joint.clone();
    own.run();
    let (flight_squares, _) = own.squares();
    let mut flight_world = own.fitted_world();
    flight_world.config.frames = total;
    // The errors are weighed: the floor's share is the mean weight over the window.
    let (weight_sum, weight_count) = observed
        .iter()
        .flat_map(|o| (0..frames).map(move |k| o.weights.as_ref().map_or(1.0, |w| w[k])))
        .fold((0.0, 0usize), |(s, n), w| (s + w, n + 1));
    let floor = precision.map_or(0.0, |p| p * p * weight_sum / weight_count.max(1) as f64);
    let sigma2 = (flight_squares / (dof - unknowns) as f64).max(floor).max(1e-300);
    Ok(Some(FlightCheck {
        frames,
        joint_squares,
        flight_squares,
        dof,
        unknowns,
        statistic: (joint_squares - flight_squares).max(0.0) / sigma2,
        critical: chi_square_point(unknowns, LEVEL_Z),
        flight_world,
    }))
}

/// The contact values fitted to `observed` with the launch (initial poses, v0, ω0) held at `world`'s, from
/// `world`'s own values and each of `starts` (the scene's values; as [`fit_multi_start_bodies`]).
/// [`FitError::NothingToFit`] where `cfg` fits no contact value.
pub fn fit_holding_launch(
    cfg: &PhysicsFitConfig,
    world: World,
    observed: Vec<Observed>,
    starts: &[(f64, f64)],
    on_start: &mut dyn FnMut(usize, &StartResult),
) -> Result<MultiStart, FitError> {
    let cfg = PhysicsFitConfig {
        fit_velocity: false,
        fit_angular_velocity: false,
        fit_initial_pose: false,
        ..cfg.clone()
    };
    // A fit takes each body's initial pose from its first observation: the held one.
    let observed = observed
        .into_iter()
        .map(|mut o| {
            if let Some(p) = o.poses.first_mut() {
                *p = world.initial[o.body].pose;
            }
            o
        })
        .collect();
    fit_multi_start_bodies(cfg, world, observed, starts, StartsOn::Scene, on_start)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chi_square_points_are_the_tables() {
        // The 1 % points of χ² with 3, 12 and 30 degrees of freedom: 11.34, 26.22, 50.89.
        for (k, table) in [(3, 11.34), (12, 26.22), (30, 50.89)] {
            let p = chi_square_point(k, LEVEL_Z);
            assert!((p - table).abs() < 0.01 * table, "{k}: {p} against {table}");
        }
    }
}
