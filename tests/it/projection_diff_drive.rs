//! Velocity projection on the differential drive (params/diff_drive.yaml): closed forms from the
//! URDF's numbers (a sideways twist, wheel and acceleration limits, twist requests), infeasible
//! requests named, bad input refused. Conventions as in `projection.rs`:
//! `M (v* − v_des) = Jᵀλ + ν`, λ = impulse ON the robot.

use crate::common;
use common::*;
use constraint_dynamics::projection::*;
use constraint_dynamics::{Error, Scene, System};
use nalgebra::DMatrix;
use serde_json::{Value, json};

// ---------------------------------------------------------------------------------------------
// Differential drive (params/diff_drive.yaml): closed forms.

fn project_named(sys: &mut System, q: &[f64], v: &[f64], req: Value) -> Result<Projection, Error> {
    let req = ProjectionRequest::from_json(&req.to_string())?;
    let mut proj = VelocityProjector::new(sys.model(), sys.constraints());
    project_system(&mut proj, sys, q, v, &req)
}

// Closed forms on the differential drive (achieved figures printed by `assert_close`, tolerance
// about 50× the achieved one, relative to max(1, |expected|)):
/// sideways request, mass metric: twist 4.6e-16.
const TOL_SIDEWAYS: f64 = 2e-14;
/// sideways request, mass metric: wheel speeds 1.8e-16.
const TOL_SIDEWAYS_WHEELS: f64 = 1e-14;
/// COM over the axle: zero velocity to 2.1e-16.
const TOL_CENTRED: f64 = 1e-14;
/// multipliers of the two wheel limits 5.8e-16.
const TOL_MU_BOTH: f64 = 2e-14;
/// multiplier of the URDF wheel limit 9.4e-17.
const TOL_MU_URDF: f64 = 5e-15;
/// multiplier of the acceleration limit 4.1e-16.
const TOL_MU_ACCEL: f64 = 2e-14;

/// The diff drive's numbers, from the URDF (docs/robots.md), not from CRBA:
/// wheel radius r, half track c, total mass m, COM x (behind the axle), wheel spin inertia,
/// and the yaw inertia about the axle midpoint.
struct DiffDrive {
    r: f64,
    c: f64,
    m: f64,
    x_c: f64,
    i_spin: f64,
    i_o: f64,
}

fn diff_drive_numbers(chassis_x: f64, caster_x: f64) -> DiffDrive {
    let (r, c) = (0.05, 0.17);
    let (m_ch, m_ca, m_w) = (8.0, 0.2, 0.5);
    let m = m_ch + m_ca + 2.0 * m_w;
    let x_c = (m_ch * chassis_x + m_ca * caster_x) / m;
    let i_o = 0.166666666666667
        + m_ch * chassis_x * chassis_x
        + 5e-5
        + m_ca * caster_x * caster_x
        + 2.0 * (0.00035 + m_w * c * c);
    DiffDrive {
        r,
        c,
        m,
        x_c,
        i_spin: 0.000625,
        i_o,
    }
}

impl DiffDrive {
    /// The reduced metric in s = (vx, wz) on the constraint manifold v = N s,
    /// N = [1 0; 0 0; 0 1; 1/r −c/r; 1/r c/r]: A = NᵀMN = diag(a1, a2) because the COM lies on
    /// the x axis (M[vx, wz] = −m y_c = 0) and the wheel terms ±c/r² cancel.
    fn a1(&self) -> f64 {
        self.m + 2.0 * self.i_spin / (self.r * self.r)
    }
    fn a2(&self) -> f64 {
        self.i_o + 2.0 * self.i_spin * self.c * self.c / (self.r * self.r)
    }
}

/// `mode: mass` (the M-metric QP): a pure sideways twist (0, V, 0) with the wheels
/// completed from the constraints (ω = 0).
///
/// On the manifold, v* = N s* with A s* = Nᵀ M v_des. M v_des = V · M[:, vy], and the only
/// entries of that column N sees are M[vx, vy] = 0 and M[wz, vy] = m x_c (the lateral momentum
/// of a COM that sits x_c ahead of the axle has a moment about it; the wheels' spin does not
/// couple to vy). So vx* = 0, vy* = 0 (the constraint), and
///     wz* = m x_c V / (I_O + 2 I_spin c²/r²),
/// which is zero only when the COM is over the axle. The bundled robot has its COM 4.7 cm
/// behind the axle (x_c < 0): the M-metric projection of a sideways request is a turn,
/// wz* ≈ −1.83 V rad/s. With the chassis and caster moved over the axle (x_c = 0) the same
/// request projects to zero base velocity exactly.
#[test]
fn diff_drive_sideways_twist_projects_to_the_closed_form() {
    let (scene, mut sys) = scene_system("diff_drive.yaml");
    let (q, v0) = (scene.q0.clone(), scene.v0.clone());
    let vy = 0.8;
    let out = project_named(
        &mut sys,
        &q,
        &v0,
        json!({"base_twist": [0.0, vy, 0.0], "mode": "mass"}),
    )
    .unwrap();
    assert_eq!(out.status, Status::Optimal);
    assert_eq!(
        out.method,
        SolvePath::KktBoundsInactive,
        "the URDF limits do not bind"
    );
    let dd = diff_drive_numbers(-0.05, -0.15);
    let wz = dd.m * dd.x_c * vy / dd.a2();
    let tw = out.base_twist.clone().unwrap();
    assert_close(
        "sideways twist (mass metric)",
        &tw,
        &[0.0, 0.0, wz],
        TOL_SIDEWAYS,
    );
    let w = out.joint_velocities.clone().unwrap();
    assert_close(
        "sideways wheels (mass metric)",
        &w,
        &[-dd.c * wz / dd.r, dd.c * wz / dd.r],
        TOL_SIDEWAYS_WHEELS,
    );
    // The lateral rows of the two wheels are identical: one redundant row, min-norm split.
    assert_eq!(out.rank_deficiency, 1);
    assert!(!out.multipliers_unique);

    // The same robot with its COM over the axle: zero base velocity.
    let urdf = std::fs::read_to_string(repo_dir().join("urdf/diff_drive.urdf"))
        .unwrap()
        .replace("<origin xyz=\"-0.05 0 0.03\"", "<origin xyz=\"0 0 0.03\"")
        .replace("xyz=\"-0.15 0 -0.025\"", "xyz=\"0 0 -0.025\"");
    let scene2 = Scene::from_parts(&scene.path, scene.file.clone(), &urdf, "centred.urdf").unwrap();
    let mut sys2 = System::from_scene(&scene2).unwrap();
    let out = project_named(
        &mut sys2,
        &q,
        &v0,
        json!({"base_twist": [0.0, vy, 0.0], "mode": "mass"}),
    )
    .unwrap();
    assert_close(
        "COM over the axle: zero velocity",
        &out.v.unwrap(),
        &[0.0; 5],
        TOL_CENTRED,
    );
    let dd0 = diff_drive_numbers(0.0, 0.0);
    assert_eq!(dd0.x_c, 0.0);
}

/// `mode: mass`: asked for (vx, wz) = (1 m/s, 0.5 rad/s) — wheel speeds (vx ∓ c wz)/r = 18.3, 21.7 rad/s —
/// with both wheels limited to W = 21.7/2 = 10.85 rad/s, which a uniform scaling by ½ would meet
/// (0.5 m/s, 0.25 rad/s; wheels 9.15, 10.85).
///
/// The M-metric QP on the manifold is min (s − s_d)ᵀ A (s − s_d), A = diag(a1, a2), subject to
/// (vx ∓ c wz)/r ≤ W. With only the right wheel's bound held, s = s_d − μ A⁻¹ n_R (n_R = (1, c)/r)
/// leaves the left wheel at ≈ 19.3 rad/s > W, so both bounds bind: vx = r W, wz = 0 — the
/// turn is dropped entirely, because turning is cheap in this metric (a2 ≈ 0.235 kg m² against
/// a1 = 9.7 kg) and a symmetric pair of wheel limits can only be met at full speed by going
/// straight. The multipliers follow from A (s − s_d) = −(μ_R n_R + μ_L n_L):
///     μ_R + μ_L = r a1 (vx_d − r W),  μ_R − μ_L = r a2 wz_d / c,
/// both positive here (so this is the optimum), and the bound multipliers are ν = −μ ≤ 0.
/// The uniform scaling is feasible but costs more (asserted).
///
/// The URDF's own limit, W = 20 rad/s, binds only the right wheel:
/// μ = (n_R·s_d − W)/(n_Rᵀ A⁻¹ n_R), s = s_d − μ A⁻¹ n_R (left wheel then ≈ 18.4 rad/s < W).
#[test]
fn diff_drive_wheel_limits_give_the_closed_form_twist() {
    let (scene, mut sys) = scene_system("diff_drive.yaml");
    let (q, v0) = (scene.q0.clone(), scene.v0.clone());
    let dd = diff_drive_numbers(-0.05, -0.15);
    let (r, c, a1, a2) = (dd.r, dd.c, dd.a1(), dd.a2());
    let (vx_d, wz_d) = (1.0, 0.5);
    let w_half = (vx_d + c * wz_d) / r / 2.0;
    let req = |w: f64| {
        json!({"base_twist": [vx_d, 0.0, wz_d], "mode": "mass",
               "upper": {"left_wheel_joint": w, "right_wheel_joint": w}})
    };

    let out = project_named(&mut sys, &q, &v0, req(w_half)).unwrap();
    assert_eq!(out.status, Status::Optimal);
    assert_eq!(out.method, SolvePath::ClarabelPolished);
    let v = out.v.clone().unwrap();
    let expect = [r * w_half, 0.0, 0.0, w_half, w_half];
    // achieved 2.8e-15
    assert_close("v (both wheel limits)", &v, &expect, 1e-13);
    // v_des itself is the full feasible request (wheels filled from the constraints).
    // achieved 1.6e-16
    assert_close(
        "v_des",
        &out.v_des,
        &[
            vx_d,
            0.0,
            wz_d,
            (vx_d - c * wz_d) / r,
            (vx_d + c * wz_d) / r,
        ],
        1e-14,
    );
    let mu_sum = r * a1 * (vx_d - r * w_half);
    let mu_diff = r * a2 * wz_d / c;
    let (mu_r, mu_l) = ((mu_sum + mu_diff) / 2.0, (mu_sum - mu_diff) / 2.0);
    assert!(mu_r > 0.0 && mu_l > 0.0);
    let mut ab = out.active_bounds.clone();
    ab.sort_by_key(|b| b.index);
    assert_eq!(ab.len(), 2);
    assert_eq!(
        (ab[0].coordinate.as_str(), ab[0].side),
        ("left_wheel_joint", Side::Upper)
    );
    assert_eq!(
        (ab[1].coordinate.as_str(), ab[1].side),
        ("right_wheel_joint", Side::Upper)
    );
    assert_eq!(ab[0].source, BoundSource::Request);
    assert_close(
        "wheel-limit multipliers",
        &[ab[0].multiplier, ab[1].multiplier],
        &[-mu_l, -mu_r],
        TOL_MU_BOTH,
    );
    let cost = |vx: f64, wz: f64| a1 * (vx - vx_d).powi(2) + a2 * (wz - wz_d).powi(2);
    assert!(cost(r * w_half, 0.0) < cost(vx_d / 2.0, wz_d / 2.0));

    // Without the request's bounds the URDF's 20 rad/s binds, on the right wheel only.
    let w = 20.0;
    let out = project_named(
        &mut sys,
        &q,
        &v0,
        json!({"base_twist": [vx_d, 0.0, wz_d], "mode": "mass"}),
    )
    .unwrap();
    let n_r = [1.0 / r, c / r];
    let mu = ((vx_d * n_r[0] + wz_d * n_r[1]) - w) / (n_r[0] * n_r[0] / a1 + n_r[1] * n_r[1] / a2);
    let (vx, wz) = (vx_d - mu * n_r[0] / a1, wz_d - mu * n_r[1] / a2);
    let v = out.v.clone().unwrap();
    // achieved 7.2e-17
    assert_close(
        "v (right wheel limit)",
        &v,
        &[vx, 0.0, wz, (vx - c * wz) / r, w],
        5e-15,
    );
    assert_eq!(out.active_bounds.len(), 1);
    assert_eq!(out.active_bounds[0].coordinate, "right_wheel_joint");
    assert_eq!(out.active_bounds[0].source, BoundSource::UrdfVelocityLimit);
    assert_close(
        "URDF wheel-limit multiplier",
        &[out.active_bounds[0].multiplier],
        &[-mu],
        TOL_MU_URDF,
    );
}

/// The default for a twist request (`mode: twist`, planner semantics). The diff drive's feasible
/// velocities are (vx, 0, wz) with wheel speeds ω_{L,R} = (vx ∓ c wz)/r, so
/// - a pure sideways request (0, V, 0) is nearest to (0, 0, 0) in the twist components: zero base
///   velocity and zero wheel speeds;
/// - (1 m/s, 0.5 rad/s) needs ω_R = (1 + 0.5 c)/r = 21.7 rad/s; with both wheels limited to half
///   of that the largest uniform scale is s = ½: (0.5 m/s, 0.25 rad/s), wheels (9.15, 10.85) with
///   the right one at its limit; with the URDF's own 20 rad/s, s = 20 r/(1 + 0.5 c).
#[test]
fn diff_drive_twist_requests_drop_sideways_motion_and_scale_to_wheel_limits() {
    let (scene, mut sys) = scene_system("diff_drive.yaml");
    let (q, v0) = (scene.q0.clone(), scene.v0.clone());
    let dd = diff_drive_numbers(-0.05, -0.15);
    let (r, c) = (dd.r, dd.c);
    let out = project_named(&mut sys, &q, &v0, json!({"base_twist": [0.0, 0.8, 0.0]})).unwrap();
    assert_eq!(
        (out.status, out.method),
        (Status::Optimal, SolvePath::TwistScaled)
    );
    // achieved 7.2e-15
    assert_close("sideways → zero", &out.v.clone().unwrap(), &[0.0; 5], 2e-13);

    let (vx_d, wz_d) = (1.0, 0.5);
    let w_r = (vx_d + c * wz_d) / r;
    let w_half = w_r / 2.0;
    let req = json!({"base_twist": [vx_d, 0.0, wz_d], "upper": {"left_wheel_joint": w_half, "right_wheel_joint": w_half}});
    let out = project_named(&mut sys, &q, &v0, req).unwrap();
    assert_eq!(
        (out.status, out.method),
        (Status::Optimal, SolvePath::TwistScaled)
    );
    let (vx, wz) = (vx_d / 2.0, wz_d / 2.0);
    // achieved 3.3e-16
    assert_close(
        "scaled twist",
        &out.v.clone().unwrap(),
        &[vx, 0.0, wz, (vx - c * wz) / r, (vx + c * wz) / r],
        2e-14,
    );
    assert_eq!(out.active_bounds.len(), 1);
    assert_eq!(
        (
            out.active_bounds[0].coordinate.as_str(),
            out.active_bounds[0].side
        ),
        ("right_wheel_joint", Side::Upper)
    );

    let out = project_named(&mut sys, &q, &v0, json!({"base_twist": [vx_d, 0.0, wz_d]})).unwrap();
    let s = 20.0 / w_r;
    let (vx, wz) = (s * vx_d, s * wz_d);
    // achieved 1.8e-16
    assert_close(
        "URDF wheel limit",
        &out.v.clone().unwrap(),
        &[vx, 0.0, wz, (vx - c * wz) / r, 20.0],
        1e-14,
    );
}

/// The left wheel forced forward (ω_L ≥ 1 rad/s) while the base must stand still: rolling of the
/// left wheel gives vx − c wz = r ω_L ≥ r, which vx ≤ 0 and wz ≥ 0 forbid. The answer names
/// exactly that minimal set, and no vector.
#[test]
fn infeasible_request_names_the_conflict() {
    let (scene, mut sys) = scene_system("diff_drive.yaml");
    let (q, v0) = (scene.q0.clone(), scene.v0.clone());
    let req = json!({"base_twist": [0.3, 0.0, 0.0],
                     "lower": {"left_wheel_joint": 1.0, "vx": 0.0, "wz": 0.0},
                     "upper": {"vx": 0.0, "wz": 0.0}});
    let out = project_named(&mut sys, &q, &v0, req).unwrap();
    assert_eq!(out.status, Status::Infeasible);
    assert!(out.v.is_none() && out.impulses.is_none());
    let mut labels: Vec<String> = out.conflicts.iter().map(|c| c.label.clone()).collect();
    labels.sort();
    assert_eq!(
        labels,
        [
            "left_wheel_contact/t1 = 0 (constraint rolling)",
            "left_wheel_joint >= 1 (request)",
            "root_joint:vx_local <= 0 (request)",
            "root_joint:wz >= 0 (request)",
        ],
        "{}",
        out.message
    );
    let json = serde_json::to_value(&out).unwrap();
    assert_eq!(json["status"], "infeasible");
    assert!(json["v"].is_null());

    // A lower bound above an upper bound is caught before any solve.
    let req = json!({"base_twist": [0.3, 0.0, 0.0],
                     "lower": {"right_wheel_joint": 25.0}});
    let out = project_named(&mut sys, &q, &v0, req).unwrap();
    assert_eq!(
        (out.status, out.method),
        (Status::Infeasible, SolvePath::BoundCheck)
    );
    let labels: Vec<&str> = out.conflicts.iter().map(|c| c.label.as_str()).collect();
    assert_eq!(
        labels,
        [
            "right_wheel_joint >= 25 (request)",
            "right_wheel_joint <= 20 (URDF velocity limit)"
        ]
    );
}

#[test]
fn bad_input_is_refused_with_a_clear_error() {
    let (scene, mut sys) = scene_system("diff_drive.yaml");
    let (q, v0) = (scene.q0.clone(), scene.v0.clone());
    let mut proj = VelocityProjector::new(sys.model(), sys.constraints());
    let mut p = ProjectionProblem::new(sys.model());
    let (mut data, mut cd, _) = workspaces(&sys);
    let mut run = |p: &ProjectionProblem, q: &[f64]| {
        proj.project(sys.model(), &mut data, sys.constraints(), &mut cd, q, p)
            .map(|_| ())
    };
    p.v_des[1] = f64::NAN;
    let e = run(&p, &q).unwrap_err();
    assert!(
        matches!(e, Error::NonFinite { ref what, index: 1, .. } if what == "v_des"),
        "{e}"
    );
    p.v_des = vec![0.0; 4];
    let e = run(&p, &q).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Dimension {
                expected: 5,
                got: 4,
                ..
            }
        ),
        "{e}"
    );
    p.v_des = vec![0.0; 5];
    p.upper[3] = f64::NAN;
    assert!(matches!(run(&p, &q).unwrap_err(), Error::NonFinite { .. }));
    p.upper[3] = f64::INFINITY;
    p.a = DMatrix::zeros(1, 5);
    assert!(
        matches!(run(&p, &q).unwrap_err(), Error::Dimension { .. }),
        "b missing"
    );
    p.a = DMatrix::zeros(0, 5);
    let mut qn = q.clone();
    qn[0] = f64::NAN;
    assert!(matches!(run(&p, &qn).unwrap_err(), Error::NonFinite { .. }));
    assert!(matches!(
        run(&p, &q[..2]).unwrap_err(),
        Error::Dimension { .. }
    ));
    assert!(run(&p, &q).is_ok());

    // Named requests.
    let mut err = |req: Value| {
        project_named(&mut sys, &q, &v0, req)
            .unwrap_err()
            .to_string()
    };
    assert!(err(json!({"joints": {"no_such_joint": 1.0}})).contains("no_such_joint"));
    assert!(err(json!({"base_twist": [1.0, 0.0]})).contains("base_twist"));
    assert!(err(json!({"v_des": [0.0, 0.0, 0.0]})).contains("v_des"));
    assert!(
        err(json!({"v_des": [0.0, 0.0, 0.0, 0.0, 0.0], "base_twist": [1.0, 0.0, 0.0]}))
            .contains("not both")
    );
    assert!(err(json!({"base_twist": [1.0, 0.0, 0.0], "colour": 1})).contains("colour"));
    assert!(err(json!({})).contains("no desired velocity"));
    assert!(
        err(json!({"base_twist": [1.0, 0.0, 0.0],
                   "accel_limit": {"dt": 0.0, "a_max": {"vx": 1.0}}}))
        .contains("dt")
    );
}

/// `mode: mass`: an acceleration limit from rest: |vx − 0| ≤ a_max dt = 0.1 m/s against a request of 1 m/s
/// straight ahead. On the manifold the metric A = diag(a1, a2) decouples vx from wz, so
/// vx* = 0.1, wz* = 0, wheels 2 rad/s, and A (s − s_d) = Nᵀν gives ν_vx = a1 (0.1 − 1) on the
/// acceleration limit's upper side.
#[test]
fn acceleration_limit_from_rest_gives_the_closed_form() {
    let (scene, mut sys) = scene_system("diff_drive.yaml");
    let (q, v0) = (scene.q0.clone(), scene.v0.clone());
    let dd = diff_drive_numbers(-0.05, -0.15);
    let req = json!({"base_twist": [1.0, 0.0, 0.0], "mode": "mass",
                     "accel_limit": {"dt": 0.1, "a_max": {"vx": 1.0}}});
    let out = project_named(&mut sys, &q, &v0, req).unwrap();
    // achieved 3.6e-15
    assert_close(
        "v",
        out.v.as_ref().unwrap(),
        &[0.1, 0.0, 0.0, 2.0, 2.0],
        1e-13,
    );
    assert_eq!(out.active_bounds.len(), 1);
    let ab = &out.active_bounds[0];
    assert_eq!(
        (ab.coordinate.as_str(), ab.side, ab.source),
        (
            "root_joint:vx_local",
            Side::Upper,
            BoundSource::AccelerationLimit
        )
    );
    assert_close(
        "acceleration-limit multiplier",
        &[ab.multiplier],
        &[dd.a1() * (0.1 - 1.0)],
        TOL_MU_ACCEL,
    );
}
