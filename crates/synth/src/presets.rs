//! Built-in scenes. `tabletop`: a box slides into a wall and bounces back, and
//! is dropped with spin in a second video. `two-body`: a box slides into a
//! resting block. `backdrop`: the tabletop's motion on a board with more and
//! larger obstacles, another board texture and light, and no table: beyond
//! the board a plain grey backdrop (as a studio capture, or another renderer's
//! empty world).

use crate::desc::*;
use crate::render::Light;
use crate::texture::{Pattern, Texture};
use sim::ContactParams;

pub const PRESETS: [&str; 3] = ["tabletop", "two-body", "backdrop"];

/// The motion-only scenes that exercise contact (`contact_scenes`): what a contact model must reproduce.
pub const CONTACT_SCENES: [&str; 4] = ["tipping-slide", "ramp-drop", "rocking", "push"];

/// Image size, view and frame counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    /// 160×120, 24 views, 30 frames: a preset renders in seconds.
    Small,
    /// 320×240, 48 views, 48 frames.
    Large,
}

fn board() -> Board {
    Board {
        half: [0.3, 0.3],
        thickness: 0.01,
        texture: Texture {
            detail: 0.45,
            ..Texture::new(Pattern::Checker, 0.03, vec![[0.92, 0.9, 0.85], [0.18, 0.2, 0.24]], 11)
        },
        table: Some(Texture {
            direction: [0.2, 1.0, 0.0],
            ..Texture::new(
                Pattern::Marble,
                0.05,
                vec![[0.42, 0.27, 0.15], [0.62, 0.43, 0.26], [0.35, 0.22, 0.12]],
                12,
            )
        }),
        print: None,
    }
}

/// A plain grey world beyond a noise-textured board, lit from the other side.
fn backdrop_board_and_light() -> (Board, Light) {
    let board = Board {
        half: [0.3, 0.3],
        thickness: 0.012,
        texture: Texture {
            detail: 0.35,
            ..Texture::new(
                Pattern::Noise,
                0.02,
                vec![[0.85, 0.82, 0.7], [0.35, 0.4, 0.45], [0.6, 0.3, 0.25]],
                13,
            )
        },
        table: None,
        print: None,
    };
    let grey = [0.55, 0.55, 0.55];
    let light = Light {
        ambient: 0.4,
        direction: [-0.5, 0.45, 1.0],
        intensity: 0.7,
        softness: 8.0,
        sky_horizon: grey,
        sky_zenith: grey,
    };
    (board, light)
}

fn obstacle(name: &str, shape: ShapeDesc, t: [f64; 3], texture: Texture) -> ObstacleDesc {
    ObstacleDesc {
        name: name.into(),
        shape,
        t,
        q: [1.0, 0.0, 0.0, 0.0],
        texture,
    }
}

fn rig(scale: Scale) -> CameraRig {
    let (width, height, views) = match scale {
        Scale::Small => (160, 120, 24),
        Scale::Large => (320, 240, 48),
    };
    CameraRig {
        width,
        height,
        fov_deg: 45.0,
        views,
        spp: 4,
        background_elevation: [20.0, 70.0],
        object_elevation: [25.0, 75.0],
    }
}

fn frames(scale: Scale) -> usize {
    match scale {
        Scale::Small => 30,
        Scale::Large => 48,
    }
}

fn toy() -> BodyDesc {
    BodyDesc {
        name: "toy".into(),
        shape: ShapeDesc::RoundedBox {
            half: [0.03, 0.022, 0.018],
            radius: 0.005,
        },
        mass: 0.08,
        texture: Texture {
            detail: 0.5,
            ..Texture::new(
                Pattern::Noise,
                0.012,
                vec![[0.85, 0.2, 0.15], [0.95, 0.75, 0.2], [0.15, 0.45, 0.8]],
                21,
            )
        },
        contact_points: 1000,
        static_orientations: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]],
    }
}

fn camera() -> VideoCamera {
    VideoCamera {
        elevation_deg: 42.0,
        azimuth_deg: -65.0,
        distance: 0.42,
        look_at: [0.07, 0.0, 0.0],
    }
}

/// A video of the preset camera at 30 fps with 20 substeps.
fn video(name: &str, frames: usize, restitution: f64, bodies: Vec<VideoBodyDesc>) -> VideoDesc {
    VideoDesc {
        name: name.into(),
        fps: 30.0,
        frames,
        substeps: 20,
        camera: camera(),
        contact: ContactParams {
            restitution,
            friction: 0.25,
        },
        pair_contact: None,
        bodies,
    }
}

/// A body's initial state in a video.
fn start(name: &str, t: [f64; 3], q: [f64; 4], v: [f64; 3], omega: [f64; 3]) -> VideoBodyDesc {
    VideoBodyDesc {
        name: name.into(),
        t,
        q,
        v,
        omega,
    }
}

const UPRIGHT: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

/// Upright, turned 30° about z (cos 15°, sin 15°).
const YAW_30: [f64; 4] = [0.965_925_826_289_068_3, 0.0, 0.0, 0.258_819_045_102_520_7];

/// A preset scene by name (`tabletop`, `two-body`).
pub fn preset(name: &str, scale: Scale) -> Option<SynthScene> {
    let n = frames(scale);
    Some(match name {
        "tabletop" => SynthScene {
            raw: None,
            camera_like: None,
            physics: Physics::default(),
            name: "tabletop".into(),
            board: board(),
            obstacles: vec![ObstacleDesc {
                name: "wall".into(),
                shape: ShapeDesc::Box {
                    half: [0.02, 0.12, 0.035],
                },
                t: [0.22, 0.0, 0.035],
                q: [1.0, 0.0, 0.0, 0.0],
                texture: Texture {
                    direction: [0.0, 0.3, 1.0],
                    ..Texture::new(Pattern::Stripes, 0.012, vec![[0.2, 0.55, 0.3], [0.9, 0.9, 0.8]], 31)
                },
            }],
            bodies: vec![toy()],
            light: Light::default(),
            cameras: rig(scale),
            videos: vec![
                video(
                    "slide",
                    n,
                    0.5,
                    vec![start(
                        "toy",
                        [-0.12, -0.02, 0.018],
                        UPRIGHT,
                        [1.3, 0.08, 0.0],
                        [0.0, 0.0, 1.5],
                    )],
                ),
                video(
                    "drop",
                    n,
                    0.5,
                    vec![start(
                        "toy",
                        [-0.02, 0.03, 0.1],
                        [0.92, 0.2, 0.3, 0.1],
                        [0.25, -0.05, 0.0],
                        [4.0, 2.0, 1.0],
                    )],
                ),
            ],
        },
        "two-body" => SynthScene {
            raw: None,
            camera_like: None,
            physics: Physics::default(),
            name: "two-body".into(),
            board: board(),
            obstacles: vec![ObstacleDesc {
                name: "ramp".into(),
                shape: ShapeDesc::Wedge {
                    half: [0.06, 0.05, 0.02],
                },
                t: [0.0, 0.2, 0.02],
                q: [1.0, 0.0, 0.0, 0.0],
                texture: Texture::new(Pattern::Stripes, 0.01, vec![[0.3, 0.3, 0.75], [0.85, 0.85, 0.9]], 41),
            }],
            bodies: vec![
                toy(),
                BodyDesc {
                    name: "block".into(),
                    shape: ShapeDesc::Box {
                        half: [0.025, 0.025, 0.02],
                    },
                    mass: 0.1,
                    texture: Texture::new(Pattern::Checker, 0.01, vec![[0.95, 0.95, 0.95], [0.6, 0.1, 0.5]], 51),
                    contact_points: 1000,
                    static_orientations: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]],
                },
            ],
            light: Light::default(),
            cameras: rig(scale),
            videos: vec![VideoDesc {
                // Bouncier and more slippery between the bodies than on the board: a fit that mixes the two
                // up misses both. The block stands 2 cm off the toy's line, turned 30° about z: the toy's
                // face meets the block's corner, and the bodies slip against each other, so their friction
                // shows (0.15 against 0.3 turns the toy 24–31° apart). Face to face (the block square to
                // the toy's line) they stick and it does not; and which of the face's contact points touch
                // first decides the outcome: another sample of the block's points alone moved the bodies
                // 7–14 mm apart, more than any fit can follow.
                pair_contact: Some(ContactParams {
                    restitution: 0.7,
                    friction: 0.15,
                }),
                ..video(
                    "collide",
                    n,
                    0.4,
                    vec![
                        start("toy", [-0.15, 0.0, 0.018], UPRIGHT, [1.3, 0.0, 0.0], [0.0; 3]),
                        start("block", [0.05, 0.02, 0.02], YAW_30, [0.0; 3], [0.0; 3]),
                    ],
                )
            }],
        },
        "backdrop" => {
            let (board, light) = backdrop_board_and_light();
            let mut scene = preset("tabletop", scale).expect("a preset");
            scene.name = "backdrop".into();
            scene.board = board;
            scene.light = light;
            scene.obstacles.extend([
                obstacle(
                    "crate",
                    ShapeDesc::Box {
                        half: [0.05, 0.05, 0.05],
                    },
                    [-0.08, 0.19, 0.05],
                    Texture::new(Pattern::Checker, 0.02, vec![[0.8, 0.6, 0.3], [0.3, 0.2, 0.15]], 61),
                ),
                obstacle(
                    "ramp",
                    ShapeDesc::Wedge {
                        half: [0.08, 0.06, 0.03],
                    },
                    [0.02, -0.19, 0.03],
                    Texture {
                        direction: [1.0, 0.0, 0.3],
                        ..Texture::new(Pattern::Stripes, 0.015, vec![[0.3, 0.3, 0.75], [0.85, 0.85, 0.9]], 62)
                    },
                ),
            ]);
            scene
        }
        _ => return None,
    })
}

/// Scenes whose motion exercises contact the way real footage does, for comparing contact models with
/// Rapier (`bench-contact`): a tall box whose friction tips it over as it slides into the wall, the toy
/// dropped with spin onto a ramp so it tumbles down, a well-rounded body released on its edge so it rocks
/// to rest, and a resting block pushed into a sliding spin. One video each, 30 frames at 30 fps.
pub fn contact_scenes() -> Vec<SynthScene> {
    let base = preset("tabletop", Scale::Small).expect("the tabletop preset");
    let n = frames(Scale::Small);
    let with = |name: &str, obstacles: Vec<ObstacleDesc>, body: BodyDesc, v: VideoDesc| SynthScene {
        raw: None,
        camera_like: None,
        name: name.into(),
        obstacles,
        bodies: vec![body],
        videos: vec![v],
        ..base.clone()
    };
    let contact = |mut v: VideoDesc, restitution: f64, friction: f64| {
        v.contact = ContactParams { restitution, friction };
        v
    };
    let wall = base.obstacles.clone();
    // Standing on its end (its 6 cm side upright): friction above 0.6 tips it forward while it slides.
    let standing = [
        std::f64::consts::FRAC_1_SQRT_2,
        0.0,
        std::f64::consts::FRAC_1_SQRT_2,
        0.0,
    ];
    let ramp = obstacle(
        "ramp",
        ShapeDesc::Wedge {
            half: [0.08, 0.1, 0.03],
        },
        [0.0, 0.0, 0.03],
        Texture {
            direction: [1.0, 0.2, 0.0],
            ..Texture::new(Pattern::Stripes, 0.015, vec![[0.3, 0.35, 0.7], [0.85, 0.85, 0.9]], 41)
        },
    );
    let rocker = BodyDesc {
        name: "rocker".into(),
        shape: ShapeDesc::RoundedBox {
            half: [0.035, 0.025, 0.02],
            radius: 0.015,
        },
        mass: 0.1,
        ..toy()
    };
    let block = BodyDesc {
        name: "block".into(),
        shape: ShapeDesc::Box {
            half: [0.03, 0.03, 0.02],
        },
        mass: 0.15,
        ..toy()
    };
    // Tilted 25° about x: its lowest point (support 23.8 mm) 2 mm above the board.
    let tilt = [0.9763, 0.2164, 0.0, 0.0];
    vec![
        with(
            "tipping-slide",
            wall,
            toy(),
            contact(
                video(
                    "tipping-slide",
                    n,
                    0.3,
                    vec![start("toy", [-0.15, 0.0, 0.0301], standing, [1.1, 0.0, 0.0], [0.0; 3])],
                ),
                0.3,
                0.7,
            ),
        ),
        with(
            "ramp-drop",
            vec![ramp],
            toy(),
            contact(
                video(
                    "ramp-drop",
                    n,
                    0.4,
                    vec![start(
                        "toy",
                        [-0.01, 0.0, 0.16],
                        [0.92, 0.2, 0.3, 0.1],
                        [0.1, 0.0, 0.0],
                        [4.0, 2.0, 1.0],
                    )],
                ),
                0.4,
                0.3,
            ),
        ),
        with(
            "rocking",
            vec![],
            rocker,
            contact(
                video(
                    "rocking",
                    n,
                    0.2,
                    vec![start("rocker", [0.0, 0.0, 0.0258], tilt, [0.0; 3], [0.0; 3])],
                ),
                0.2,
                0.5,
            ),
        ),
        with(
            "push",
            vec![],
            block,
            contact(
                video(
                    "push",
                    n,
                    0.3,
                    vec![start(
                        "block",
                        [-0.1, 0.0, 0.02],
                        UPRIGHT,
                        [0.9, 0.15, 0.0],
                        [0.0, 0.0, 4.0],
                    )],
                ),
                0.3,
                0.3,
            ),
        ),
    ]
}

/// `scene` as raw footage of a printed board of `kind` (`aruco_grid`: 6 × 4 `DICT_5X5_1000` markers of
/// 40 mm, 290 × 190 mm; `charuco`: 7 × 5 squares of 40 mm with `DICT_4X4_50` markers of 30 mm, 280 × 200
/// mm) lying at the board's centre, shot at three times the captures' size through a lens with distortion
/// (the `[raw]` defaults), jittered from `seed`.
pub fn with_raw(mut scene: SynthScene, kind: calib::BoardKind, seed: u64) -> SynthScene {
    let spec = match kind {
        calib::BoardKind::ArucoGrid => calib::BoardSpec {
            kind,
            dictionary: "DICT_5X5_1000".into(),
            size: [6, 4],
            marker_length: 0.04,
            marker_separation: Some(0.01),
            square_length: None,
            legacy: false,
            first_id: 0,
        },
        calib::BoardKind::Charuco => calib::BoardSpec {
            kind,
            dictionary: "DICT_4X4_50".into(),
            size: [7, 5],
            marker_length: 0.03,
            marker_separation: None,
            square_length: Some(0.04),
            legacy: false,
            first_id: 0,
        },
    };
    scene.board.print = Some(spec);
    scene.raw = Some(crate::desc::RawDesc {
        width: 3 * scene.cameras.width,
        height: 3 * scene.cameras.height,
        seed,
        ..Default::default()
    });
    scene
}
