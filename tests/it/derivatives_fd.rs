//! Analytic derivatives against finite differences on every bundled scene: the planar and
//! floating bases, revolute and prismatic joints, and each scene's constraints (point, coupling
//! and rolling contacts), at random states off the scene's initial one.
//!
//! Differences: central, steps h and h/2 combined by Richardson extrapolation
//! (4 D(h/2) − D(h))/3, q perturbed on the Lie group (q ⊕ δ, `Model::integrate`), h = 5e-4 for
//! q; for v and τ, where q̈ and λ are quadratic and linear, h = 1 (the quotient is exact up to
//! rounding). Error: max |X − X_fd| / max(1, max |X_fd|) per matrix.

use crate::common;
use common::*;
use constraint_dynamics::algorithm::{Data, aba, crba_full, nonlinear_effects, rnea};
use constraint_dynamics::constraints::ConstraintKind;
use constraint_dynamics::derivatives::*;
use constraint_dynamics::dynamics::Baumgarte;
use constraint_dynamics::{Model, Scene, System};
use nalgebra::{DMatrix, DVector};

/// Unconstrained: achieved ≤ 3.4e-10 — the differences' own error (it falls as h⁴ from
/// h = 2e-3 to 5e-4 and rises again below from rounding); the analytic values meet
/// Pinocchio's to 1e-14 (tests/it/derivatives.rs).
const TOL_FREE: f64 = 1e-8;
/// Constrained: achieved ≤ 8.9e-10 (the floating mobile manipulator's ∂q̈/∂q, again the
/// differences' error: 1.7e-7 at h = 2e-3, 1.1e-8 at 1e-3, 8.9e-10 at 5e-4).
const TOL_CONSTRAINED: f64 = 1e-8;
/// Difference steps: on q [rad or m] and on v [rad/s or m/s]. q̈ is a quadratic in v, which the
/// extrapolated differences take exactly at any step, unless a turn gain makes the rows depend
/// on v: then 1e-2.
const STEP_Q: f64 = 5e-4;
const STEP_V: f64 = 1.0;
const STEP_V_TURN_GAIN: f64 = 1e-2;

/// A small deterministic generator (xorshift), uniform in [−1, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
    fn vec(&mut self, n: usize, scale: f64) -> Vec<f64> {
        (0..n).map(|_| scale * self.next()).collect()
    }
}

/// Richardson-extrapolated central differences of `f` along each unit direction of the input
/// `x` (q when `on_q`, else a vector space), columns of the returned matrix.
fn fd(
    model: &Model,
    x: &[f64],
    (nv, nout): (usize, usize),
    (on_q, h): (bool, f64),
    mut f: impl FnMut(&[f64]) -> DVector<f64>,
) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(nout, nv);
    for j in 0..nv {
        let mut e = vec![0.0; nv];
        e[j] = 1.0;
        let mut at = |t: f64| {
            if on_q {
                f(&perturbed(model, x, &e, t))
            } else {
                let mut y = x.to_vec();
                y[j] += t;
                f(&y)
            }
        };
        let d = |a: DVector<f64>, b: DVector<f64>, t: f64| (a - b) / (2.0 * t);
        let d1 = d(at(h), at(-h), h);
        let d2 = d(at(h / 2.0), at(-h / 2.0), h / 2.0);
        out.set_column(j, &((d2 * 4.0 - d1) / 3.0));
    }
    out
}

fn err(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).amax() / b.amax().max(1.0)
}

fn check(what: &str, ours: &DMatrix<f64>, fd: &DMatrix<f64>, tol: f64) -> f64 {
    let e = err(ours, fd);
    eprintln!("achieved {what}: {e:.2e} (tol {tol:.0e})");
    assert!(
        e <= tol,
        "{what}: {e:.3e} > {tol:.0e}\n ours {ours:.6}\n fd {fd:.6}"
    );
    e
}

#[test]
fn unconstrained_derivatives_match_finite_differences_on_every_bundled_scene() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut worst = 0.0f64;
    let mut skipped = Vec::new();
    for p in bundled_scenes() {
        let scene = Scene::load(&p).unwrap();
        let model = scene.model.clone();
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let nv = model.nv;
        let mut data = Data::new(&model);
        let mut dd = DerivativeData::new(&model, 0);
        for k in 0..2 {
            let q = perturbed(&model, &scene.q0, &rng.vec(nv, 0.4), 1.0);
            let v = rng.vec(nv, 1.0);
            let tau = rng.vec(nv, 2.0);
            let a = rng.vec(nv, 1.5);
            let tag = format!("{name}[{k}]");
            rnea_derivatives(&model, &mut data, &mut dd, &q, &v, &a);
            let mut d2 = Data::new(&model);
            let f_dq = fd(&model, &q, (nv, nv), (true, STEP_Q), |x| {
                rnea(&model, &mut d2, x, &v, &a).clone()
            });
            let f_dv = fd(&model, &v, (nv, nv), (false, STEP_V), |x| {
                rnea(&model, &mut d2, &q, x, &a).clone()
            });
            worst = worst
                .max(check(
                    &format!("{tag} dtau_dq"),
                    &dd.dtau_dq,
                    &f_dq,
                    TOL_FREE,
                ))
                .max(check(
                    &format!("{tag} dtau_dv"),
                    &dd.dtau_dv,
                    &f_dv,
                    TOL_FREE,
                ));
            if let Err(e) = aba_derivatives(&model, &mut data, &mut dd, &q, &v, &tau) {
                // Only constraints give some scenes' coordinates inertia (M singular alone).
                eprintln!("{tag}: no unconstrained forward dynamics ({e})");
                skipped.push(tag);
                continue;
            }
            let mut fwd = |q: &[f64], v: &[f64], t: &[f64]| {
                aba(&model, &mut d2, q, v, t);
                d2.qdd.clone()
            };
            let f_dq = fd(&model, &q, (nv, nv), (true, STEP_Q), |x| fwd(x, &v, &tau));
            let f_dv = fd(&model, &v, (nv, nv), (false, STEP_V), |x| fwd(&q, x, &tau));
            let f_dt = fd(&model, &tau, (nv, nv), (false, STEP_V), |x| fwd(&q, &v, x));
            worst = worst
                .max(check(
                    &format!("{tag} dqdd_dq"),
                    &dd.dqdd_dq,
                    &f_dq,
                    TOL_FREE,
                ))
                .max(check(
                    &format!("{tag} dqdd_dv"),
                    &dd.dqdd_dv,
                    &f_dv,
                    TOL_FREE,
                ))
                .max(check(&format!("{tag} Minv"), &dd.minv, &f_dt, TOL_FREE));
        }
    }
    eprintln!("worst unconstrained: {worst:.2e}; forward dynamics skipped on {skipped:?}");
    assert!(
        skipped.len() <= 4,
        "forward dynamics skipped on {skipped:?}"
    );
}

/// Rows of J kept greedily in order (a row is dropped when it adds no rank), as the
/// multiplier solve's semi-definite factorization does.
fn independent_rows(j: &DMatrix<f64>) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::new();
    for r in 0..j.nrows() {
        let mut trial = kept.clone();
        trial.push(r);
        let sub = j.select_rows(trial.iter());
        if sub
            .clone()
            .svd(false, false)
            .rank(1e-9 * sub.amax().max(1.0))
            == trial.len()
        {
            kept = trial;
        }
    }
    kept
}

/// A basis of null(J): eigenvectors of JᵀJ with a zero eigenvalue.
fn admissible(j: &DMatrix<f64>) -> DMatrix<f64> {
    let eig = (j.transpose() * j).symmetric_eigen();
    let top = eig.eigenvalues.amax();
    let cols: Vec<_> = (0..j.ncols())
        .filter(|&k| eig.eigenvalues[k] <= 1e-14 * top)
        .map(|k| eig.eigenvectors.column(k).into_owned())
        .collect();
    DMatrix::from_columns(&cols)
}

/// (q̈, λ) from a dense LU solve of the KKT system on the `kept` rows (λ = 0 on the others):
/// an independent solve of `[M Jᵀ; J 0][q̈; −λ] = [τ − h; −(γ + K_d J v + K_p φ)]`.
fn dense_kkt(
    sys: &mut System,
    kept: &[usize],
    q: &[f64],
    v: &[f64],
    t: &[f64],
    stab: Baumgarte,
) -> DVector<f64> {
    let (nv, nc) = (sys.model().nv, sys.constraints().nrows);
    sys.evaluate_rows(sys.rows().t, q, v);
    let (j, gamma, jv, phi) = (
        sys.rows().j.clone(),
        sys.rows().gamma.clone(),
        sys.rows().jv.clone(),
        sys.rows().phi.clone(),
    );
    let (mut data, _, _) = workspaces(sys);
    crba_full(sys.model(), &mut data, q);
    let m = data.mass_matrix.clone();
    let h = nonlinear_effects(sys.model(), &mut data, q, v).clone();
    let nk = kept.len();
    let mut a = DMatrix::zeros(nv + nk, nv + nk);
    let mut b = DVector::zeros(nv + nk);
    a.view_mut((0, 0), (nv, nv)).copy_from(&m);
    for (r, &row) in kept.iter().enumerate() {
        for c in 0..nv {
            a[(nv + r, c)] = j[(row, c)];
            a[(c, nv + r)] = j[(row, c)];
        }
        b[nv + r] = -(gamma[row] + stab.kd * jv[row] + stab.kp * phi[row]);
    }
    for i in 0..nv {
        b[i] = t[i] - h[i];
    }
    let x = a.lu().solve(&b).expect("KKT solvable on independent rows");
    let mut out = DVector::zeros(nv + nc);
    out.rows_mut(0, nv).copy_from(&x.rows(0, nv));
    for (r, &row) in kept.iter().enumerate() {
        out[nv + row] = -x[nv + r];
    }
    out
}

/// Checks the constrained derivatives of `scene` at two random states near its initial one;
/// returns the worst error and the kinds it exercised.
fn check_constrained_scene(name: &str, scene: &Scene, rng: &mut Rng) -> (f64, Vec<&'static str>) {
    let mut worst = 0.0f64;
    {
        let s = System::from_scene(scene).unwrap();
        let (mut data, mut cd, mut kkt) = workspaces(&s);
        if s.constraints().nrows == 0 {
            return (0.0, vec![]);
        }
        // Expression constraints have no analytic derivatives (Unsupported).
        if s.constraints()
            .items
            .iter()
            .any(|c| c.kind() == ConstraintKind::Velocity)
        {
            return (0.0, vec![]);
        }
        let model = s.model().clone();
        let (nv, nc) = (model.nv, s.constraints().nrows);
        let turn_gain = (s.constraints().items.iter()).any(|c| {
            matches!(c, constraint_dynamics::constraints::Constraint::Rolling(rc) if rc.axle_offset_turn_gain != 0.0)
        });
        let step_v = if turn_gain { STEP_V_TURN_GAIN } else { STEP_V };
        let mut s2 = System::from_scene(scene).unwrap();
        let mut dd = DerivativeData::new(&model, nc);
        for k in 0..2 {
            // Near the scene's (consistent) initial state; v with J v = 0 so that dependent
            // rows (two wheels on one axle) stay consistent.
            let q = perturbed(&model, &scene.q0, &rng.vec(nv, 0.05), 1.0);
            s.constraints()
                .evaluate(&model, &mut data, &mut cd, 0.0, &q, &vec![0.0; nv]);
            let mut j = cd.j.clone();
            let kept = independent_rows(&j);
            let full_rank = kept.len() == nc;
            let v0 = DVector::from_vec(rng.vec(nv, 0.5));
            let mut v: Vec<f64> = v0.as_slice().to_vec();
            if !full_rank {
                // Onto J(q, v) v = 0, J taken at v itself: a turn gain's rows depend on v.
                for _ in 0..8 {
                    let pinv = j.clone().svd(true, true).pseudo_inverse(1e-10).unwrap();
                    v = (&v0 - pinv * (&j * &v0)).as_slice().to_vec();
                    s.constraints()
                        .evaluate(&model, &mut data, &mut cd, 0.0, &q, &v);
                    j = cd.j.clone();
                }
            }
            // The tangent of J(q, v) v = 0 at v is the null space of ∂(J v)/∂v, which is J
            // itself unless the rows depend on v (a turn gain): then take it by differences.
            let mut tangent_rows = j.clone();
            if !full_rank {
                let h = 1e-6;
                for i in 0..nv {
                    let mut jv = [DVector::zeros(nc), DVector::zeros(nc)];
                    for (side, sign) in [(0, 1.0), (1, -1.0)] {
                        let mut vp = v.clone();
                        vp[i] += sign * h;
                        s.constraints()
                            .evaluate(&model, &mut data, &mut cd, 0.0, &q, &vp);
                        jv[side] = cd.jv.clone();
                    }
                    tangent_rows.set_column(i, &((&jv[0] - &jv[1]) / (2.0 * h)));
                }
                if (&tangent_rows - &j).amax() <= 1e-9 {
                    tangent_rows = j.clone();
                }
            }
            // Baumgarte on (where the rows are independent), so its terms are checked too.
            let stab = if full_rank {
                Baumgarte { kp: 25.0, kd: 10.0 }
            } else {
                Baumgarte::default()
            };
            let tau = rng.vec(nv, 2.0);
            let tag = format!("{name}[{k}]");
            constrained_dynamics_derivatives(
                s.model(),
                &mut data,
                s.constraints(),
                &mut cd,
                &mut kkt,
                &mut dd,
                &q,
                &v,
                &tau,
                stab,
            )
            .unwrap_or_else(|e| panic!("{tag}: {e}"));
            assert_eq!(dd.lambda_unique, full_rank, "{tag}: rank of J");
            let mut solve =
                |q: &[f64], v: &[f64], t: &[f64]| dense_kkt(&mut s2, &kept, q, v, t, stab);
            let f_dq = fd(&model, &q, (nv, nv + nc), (true, STEP_Q), |x| {
                solve(x, &v, &tau)
            });
            let f_dv = fd(&model, &v, (nv, nv + nc), (false, step_v), |x| {
                solve(&q, x, &tau)
            });
            let f_dt = fd(&model, &tau, (nv, nv + nc), (false, STEP_V), |x| {
                solve(&q, &v, x)
            });
            for (what, fdm, qdd, lam) in [
                ("q", &f_dq, &dd.dqdd_dq, &dd.dlambda_dq),
                ("v", &f_dv, &dd.dqdd_dv, &dd.dlambda_dv),
                ("tau", &f_dt, &dd.dqdd_dtau, &dd.dlambda_dtau),
            ] {
                let fq = fdm.rows(0, nv).into_owned();
                let fl = fdm.rows(nv, nc).into_owned();
                // With dependent rows, q̈ is differentiable in v only along admissible
                // directions (J δv = 0); off them the rows disagree, and the derivative is the
                // least-squares reconciliation's, not the reference's choice of dropped rows.
                let (ours, theirs) = if what == "v" && !full_rank {
                    let n = admissible(&tangent_rows);
                    (qdd * &n, fq * &n)
                } else {
                    (qdd.clone(), fq)
                };
                worst = worst.max(check(
                    &format!("{tag} dqdd_d{what}"),
                    &ours,
                    &theirs,
                    TOL_CONSTRAINED,
                ));
                // With dependent rows λ is not unique and has no derivative (zero, flagged).
                if full_rank {
                    worst = worst.max(check(
                        &format!("{tag} dlambda_d{what}"),
                        lam,
                        &fl,
                        TOL_CONSTRAINED,
                    ));
                } else {
                    assert_eq!(lam.amax(), 0.0, "{tag}: dlambda_d{what} of dependent rows");
                }
            }
        }
        (
            worst,
            s.constraints()
                .items
                .iter()
                .map(|c| c.kind().name())
                .collect(),
        )
    }
}

#[test]
fn constrained_derivatives_match_finite_differences_on_every_bundled_scene() {
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let mut worst = 0.0f64;
    let mut kinds = std::collections::BTreeSet::new(); // kind names
    for p in bundled_scenes() {
        let scene = Scene::load(&p).unwrap();
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let (w, k) = check_constrained_scene(&name, &scene, &mut rng);
        worst = worst.max(w);
        kinds.extend(k);
    }
    eprintln!("worst constrained: {worst:.2e}; kinds covered: {kinds:?}");
    for k in [ConstraintKind::Point, ConstraintKind::Rolling] {
        assert!(kinds.contains(&k.name()), "no bundled scene exercised {k}");
    }
}

/// Scenes for the kinds no bundled scene uses: a distance constraint closing the four-bar
/// (the tip at 0.3 m from a world point), a knife edge instead of the wheels of the diff
/// drive (no side slip of base_link along its y axis), and welds on the UR5 (tool0 to the
/// world in world axes; tool0 to the moving upper arm in its local axes and in world axes).
#[test]
fn distance_knife_edge_and_weld_derivatives_match_finite_differences() {
    let dir = std::env::temp_dir().join(format!("cd_dfd_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let urdf = |f: &str| repo_dir().join("urdf").join(f).display().to_string();
    let ur5 = || {
        reference_dir()
            .join("urdf/ur5_robot.urdf")
            .display()
            .to_string()
    };
    // The UR5 reference case's first state (../shared/reference/cases/ur5_ee_point.json).
    const UR5_Q: &str = "{shoulder_pan_joint: 1.27, shoulder_lift_joint: -4.08, elbow_joint: -1.74, wrist_1_joint: 4.27, wrist_2_joint: 1.75, wrist_3_joint: -3.32}";
    // A bundled mobile-manipulator scene with `keys` added to both wheels' rolling contacts.
    const TURN_GAIN_KEYS: &str = "axle_offset: 0.003\n    axle_offset_turn_gain: 0.004";
    const LATERAL_TYRES: &str = "    - { wheel: left_wheel, axis: [0, 1, 0], radius: 0.05, friction: 0.8, normal_force: 56.0, slip_speed_scale: 0.05 }\n    - { wheel: right_wheel, axis: [0, 1, 0], radius: 0.05, friction: 0.8, normal_force: 56.0, slip_speed_scale: 0.05 }\n";
    let with_wheel_keys = |file: &str, keys: &str| {
        std::fs::read_to_string(repo_dir().join("params").join(file))
            .unwrap()
            .replace(
                "../urdf/mobile_manipulator.urdf",
                &urdf("mobile_manipulator.urdf"),
            )
            .replace(
                "    radius: 0.05\n",
                &format!("    radius: 0.05\n    {keys}\n"),
            )
    };
    let scenes = [
        (
            "fourbar_distance",
            format!(
                "urdf: {}\nbase: fixed\ninitial_state:\n  q: {{crank_joint: 0.5, coupler_joint: 0.04, rocker_joint: -2.4}}\n  v: {{crank_joint: 1.0}}\nconstraints:\n  - {{name: rod, kind: distance, frame_a: tip, frame_b: world, point_b: [0.6, 0.0, 0.3], distance: 0.3}}\n",
                urdf("fourbar.urdf")
            ),
        ),
        (
            "diff_drive_knife_edge",
            format!(
                "urdf: {}\nbase: planar\ninitial_state:\n  q: {{root_joint:yaw: 0.3}}\n  v: {{root_joint:vx_local: 0.5, root_joint:wz: 0.2}}\nconstraints:\n  - {{name: skate, kind: no_side_slip, frame: base_link, axis: [0.0, 1.0, 0.0]}}\n",
                urdf("diff_drive.urdf")
            ),
        ),
        (
            "ur5_weld_world",
            format!(
                "urdf: {}\nbase: fixed\ninitial_state:\n  q: {UR5_Q}\nconstraints:\n  - {{name: w, kind: weld, frame_a: tool0, rows: [x, y, z, rx, rz], relative_xyz: [0.3, 0.2, 0.4], relative_rpy: [0.1, 0.2, 0.3]}}\n",
                ur5()
            ),
        ),
        (
            "ur5_weld_local_moving",
            format!(
                "urdf: {}\nbase: fixed\ninitial_state:\n  q: {UR5_Q}\nconstraints:\n  - {{name: w, kind: weld, frame_a: tool0, frame_b: upper_arm_link, axes: local, rows: [x, ry, rz], relative_xyz: [0.1, 0.0, 0.5]}}\n",
                ur5()
            ),
        ),
        (
            "ur5_weld_world_moving",
            format!(
                "urdf: {}\nbase: fixed\ninitial_state:\n  q: {UR5_Q}\nconstraints:\n  - {{name: w, kind: weld, frame_a: tool0, frame_b: upper_arm_link, rows: [y, rx]}}\n",
                ur5()
            ),
        ),
        (
            // The contact points moved along the axles (an effective track): the sliding
            // contact's ȧ-term on a floating base, where the wheels tilt.
            "mobile_manipulator_floating_axle_offset",
            with_wheel_keys("mobile_manipulator_floating.yaml", "axle_offset: 0.012"),
        ),
        (
            // The suite's planar diff drive with its track widening in turns
            // (axle_offset_turn_gain): the rows depend on the velocity.
            "suite_mobile_manipulator_turn_gain",
            with_wheel_keys("suite_mobile_manipulator.yaml", TURN_GAIN_KEYS),
        ),
        (
            // One wheel on the floating base, so that its rows are independent and λ's
            // derivatives are checked too. With both wheels the reference drops one of their
            // dependent rows where the KKT solve reconciles them: a q-step at fixed v moves the
            // two offsets apart and the rows stop agreeing, to 9.3e-8 of ∂q̈/∂q.
            "mobile_manipulator_floating_one_wheel_turn_gain",
            with_wheel_keys("mobile_manipulator_floating.yaml", TURN_GAIN_KEYS).replace(
                &format!(
                    "  - name: right_wheel_contact\n    kind: rolling\n    wheel: right_wheel\n    \
                     axis: [0.0, 1.0, 0.0]\n    radius: 0.05\n    {TURN_GAIN_KEYS}\n"
                ),
                "",
            ),
        ),
        (
            // The wheels' sideways grip left to tyres (`lateral: tyre`): one rolling row per
            // wheel along a direction that turns with it, v off the lateral rows (slip).
            "suite_mobile_manipulator_lateral_tyre",
            with_wheel_keys("suite_mobile_manipulator.yaml", "lateral: tyre").replace(
                "  urdf_damping: true\n",
                &format!("  urdf_damping: true\n  tyres:\n{LATERAL_TYRES}"),
            ),
        ),
        (
            // The same on the floating base, where the wheels tilt and keep their normal rows.
            "mobile_manipulator_floating_lateral_tyre",
            with_wheel_keys("mobile_manipulator_floating.yaml", "lateral: tyre")
                + &format!("forces:\n  tyres:\n{LATERAL_TYRES}"),
        ),
    ];
    let mut rng = Rng(0x1234_5678_9abc_def1);
    let mut kinds = Vec::new();
    for (name, text) in scenes {
        let path = dir.join(format!("{name}.yaml"));
        std::fs::write(&path, text).unwrap();
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let (w, k) = check_constrained_scene(name, &scene, &mut rng);
        eprintln!("{name}: worst {w:.2e}");
        kinds.extend(k);
    }
    for k in [
        ConstraintKind::Distance,
        ConstraintKind::NoSideSlip,
        ConstraintKind::Weld,
    ] {
        assert!(kinds.contains(&k.name()), "{k} not exercised");
    }
}
