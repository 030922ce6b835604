//! The four example-robot-data robots that `../shared/tools/anchors/cpp/bench_pin.cpp` times in
//! compiled Pinocchio, set up the same way: the same URDF files (read from the pinned venv of
//! `tools/robots/setup_venv.sh`, never copied here), the same locked joints and the same
//! constraint sets, at a random state drawn from the same distributions (q uniform within the
//! limits, ±3.14 where a limit is infinite or beyond 1e3; a uniform random unit quaternion for a
//! free-flyer; v, a, τ uniform in [−1, 1]). The draws are not Pinocchio's own numbers (its
//! generator is C's `rand`), so the states are comparable, not identical: none of the timed
//! algorithms branches on the state.

use constraint_dynamics::algorithm::{Data, forward_kinematics_pos, frame_placement};
use constraint_dynamics::constraints::{Axes, ConstraintSet, ConstraintSpec, Row};
use constraint_dynamics::{BaseType, Model, ModelOptions};
use std::path::PathBuf;

/// How a robot is held, as in bench_pin.cpp: a point (3 rows, world axes) or a 6D weld per frame.
#[derive(Clone, Copy)]
pub enum Contact {
    Point,
    Weld,
}

pub struct Robot {
    pub name: &'static str,
    pub model: Model,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    pub tau: Vec<f64>,
    pub set: ConstraintSet,
}

/// example-robot-data's `robots/` folder: `$CD_ROBOTS_DIR`, else found in the venv
/// (`$CD_ANCHORS_VENV`, else the repository's `.venv-anchors`).
fn robots_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("CD_ROBOTS_DIR") {
        return PathBuf::from(d);
    }
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let venv = std::env::var_os("CD_ANCHORS_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo.join(".venv-anchors"));
    let lib = venv.join("lib");
    let found = std::fs::read_dir(&lib).ok().and_then(|entries| {
        entries
            .flatten()
            .map(|e| {
                e.path()
                    .join("site-packages/cmeel.prefix/share/example-robot-data/robots")
            })
            .find(|d| d.is_dir())
    });
    found.unwrap_or_else(|| {
        panic!(
            "example-robot-data not found under {}: run tools/robots/setup_venv.sh (or \
             tools/bench.py) or set CD_ROBOTS_DIR",
            lib.display()
        )
    })
}

/// xorshift64*: a fixed, dependency-free generator so every run times the same states.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let u = (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * u
    }
}

/// bench_pin.cpp's stand-in for an infinite limit: 3.14, written as in the C++ (not π).
#[allow(clippy::approx_constant)]
const BOUND: f64 = 3.14;

fn clip(x: f64, default: f64) -> f64 {
    if x.is_finite() && x.abs() <= 1e3 {
        x
    } else {
        default
    }
}

/// A random configuration like Pinocchio's `randomConfiguration(model, lo, hi)` with the
/// clipped limits of bench_pin.cpp.
fn random_q(model: &Model, rng: &mut Rng) -> Vec<f64> {
    let mut q = model.neutral();
    let limits = model.limits.q_lower.iter().zip(&model.limits.q_upper);
    for (x, (&lo, &hi)) in q.iter_mut().zip(limits) {
        *x = rng.uniform(clip(lo, -BOUND), clip(hi, BOUND));
    }
    // A free-flyer's quaternion: uniform on the unit sphere (Shoemake), x y z w.
    for b in model.bodies.iter().skip(1) {
        if b.joint.kind.nq() == 7 {
            let (u1, u2, u3) = (
                rng.uniform(0.0, 1.0),
                rng.uniform(0.0, std::f64::consts::TAU),
                rng.uniform(0.0, std::f64::consts::TAU),
            );
            let (s1, s2) = ((1.0 - u1).sqrt(), u1.sqrt());
            let quat = [s1 * u2.sin(), s1 * u2.cos(), s2 * u3.sin(), s2 * u3.cos()];
            q[b.joint.idx_q + 3..b.joint.idx_q + 7].copy_from_slice(&quat);
        }
    }
    q
}

/// URDF roll-pitch-yaw of R = Rz(yaw) Ry(pitch) Rx(roll).
fn rpy(r: &nalgebra::Matrix3<f64>) -> [f64; 3] {
    [
        r[(2, 1)].atan2(r[(2, 2)]),
        (-r[(2, 0)]).clamp(-1.0, 1.0).asin(),
        r[(1, 0)].atan2(r[(0, 0)]),
    ]
}

/// One robot as bench_pin.cpp sets it up; each frame in `frames` is held where it is at q.
fn load(
    name: &'static str,
    urdf: &str,
    floating: bool,
    locked: &[&str],
    frames: &[&str],
    contact: Contact,
    rng: &mut Rng,
) -> Robot {
    let opts = ModelOptions {
        base: if floating {
            BaseType::Floating
        } else {
            BaseType::Fixed
        },
        // Pinocchio's buildReducedModel at neutral(full): the fingers at 0.
        locked_joints: locked.iter().map(|j| (j.to_string(), 0.0)).collect(),
        ..Default::default()
    };
    let model = Model::from_urdf_file(robots_dir().join(urdf), &opts)
        .unwrap_or_else(|e| panic!("{urdf}: {e}"));
    let q = random_q(&model, rng);
    let mut draw = |n: usize| (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect::<Vec<_>>();
    let (v, a, tau) = (draw(model.nv), draw(model.nv), draw(model.nv));
    let mut data = Data::new(&model);
    forward_kinematics_pos(&model, &mut data, &q);
    let specs: Vec<ConstraintSpec> = frames
        .iter()
        .map(|f| {
            let pose = frame_placement(&model, &data, model.frame_id(f).expect("frame"));
            let t = pose.translation;
            match contact {
                Contact::Point => ConstraintSpec::Point {
                    name: f.to_string(),
                    frame_a: f.to_string(),
                    point_a: [0.0; 3],
                    frame_b: "world".into(),
                    point_b: [t.x, t.y, t.z],
                    rows: vec![Row::X, Row::Y, Row::Z],
                    unilateral: false,
                    friction: None,
                },
                Contact::Weld => ConstraintSpec::Weld {
                    name: f.to_string(),
                    frame_a: f.to_string(),
                    frame_b: "world".into(),
                    axes: Axes::World,
                    rows: vec![Row::X, Row::Y, Row::Z, Row::Rx, Row::Ry, Row::Rz],
                    relative_xyz: [t.x, t.y, t.z],
                    relative_rpy: rpy(&pose.rotation),
                },
            }
        })
        .collect();
    let set = ConstraintSet::new(&model, &specs, &q).expect("constraints");
    Robot {
        name,
        model,
        q,
        v,
        a,
        tau,
        set,
    }
}

/// ur5, panda, solo12, talos_reduced (bench_pin.cpp's rows, in its order).
pub fn all() -> Vec<Robot> {
    let mut rng = Rng(42);
    vec![
        load(
            "ur5",
            "ur_description/urdf/ur5_robot.urdf",
            false,
            &[],
            &["tool0"],
            Contact::Point,
            &mut rng,
        ),
        load(
            "panda",
            "panda_description/urdf/panda.urdf",
            false,
            &["panda_finger_joint1", "panda_finger_joint2"],
            &["panda_hand_tcp"],
            Contact::Point,
            &mut rng,
        ),
        load(
            "solo12",
            "solo_description/robots/solo12.urdf",
            true,
            &[],
            &["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"],
            Contact::Point,
            &mut rng,
        ),
        load(
            "talos_reduced",
            "talos_data/robots/talos_reduced.urdf",
            true,
            &[],
            &["left_sole_link", "right_sole_link"],
            Contact::Weld,
            &mut rng,
        ),
    ]
}
