//! Closed forms taken from the seed texts in `/work/shared/seeds/`, checked against the crate.
//!
//! Every expected number here is computed in the test from the seed's own equations (the seed's
//! coordinates, constraints and Lagrange equations written out by hand), never from the crate's
//! algorithms. The crate is only asked for q̈, λ, constraint forces and J v.
//!
//! Crate convention: `M q̈ + h = τ + Jᵀλ`, h includes gravity, λ is the force the constraint exerts
//! ON the robot.

use crate::common;
use common::*;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::{Scene, System};
use nalgebra::{DMatrix, DVector};

const G: f64 = 9.81;

// Tolerances, relative to max(1, |expected|), from the achieved figures printed by
// `assert_close` (`-- --nocapture`).
/// Masses summed from the URDF: exactly the seed's m (achieved 0; floor 1e-15).
const T_MASS0: f64 = 1e-15;
const T_MASS1: f64 = 1e-15;
/// The scene's v0 satisfies the seed's (33): achieved 0; floor 1e-15.
const T_V0: f64 = 1e-15;
/// Seed 001: J v on the consistent states, achieved ≤ 5.6e-17.
const T_DISK_JV: f64 = 5e-15;
/// Seed 001: q̈ = 0 by (41), (42), achieved ≤ 1.6e-15; the embedded q̈ ≤ 5.4e-16.
const T_DISK_QDD: f64 = 1e-13;
/// Seed 001: contact force = m × centripetal acceleration, achieved ≤ 1.1e-16.
const T_DISK_FORCE: f64 = 1e-14;
/// No-side-slip row: J v against the seed's ẏ cos θ − ẋ sin θ, achieved ≤ 5.6e-17.
const T_NSS: f64 = 5e-15;
/// Seed 000 (rod and body): q̈, λ, Jᵀλ, pin force against the seed's 6×6 Lagrange system,
/// achieved ≤ 8.3e-16; the embedded q̈ ≤ 5.1e-16.
const T_ROD: f64 = 5e-14;

/// Rank of a matrix by SVD (singular values above 1e-10 of the largest).
fn rank(a: &DMatrix<f64>) -> usize {
    if a.nrows() == 0 || a.ncols() == 0 {
        return 0;
    }
    let sv = a.clone().svd(false, false).singular_values;
    let smax = sv.iter().cloned().fold(0.0, f64::max);
    sv.iter()
        .filter(|&&s| s > 1e-10 * smax.max(f64::MIN_POSITIVE))
        .count()
}

fn load(rel: &str) -> Scene {
    let p = repo_dir().join(rel);
    Scene::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

// ---------------------------------------------------------------------------------------------
// Seed 000: rigid body on a massless rod.
// ---------------------------------------------------------------------------------------------

/// Seed 000 (rigid body C of mass m, inertia I_C, pinned at distance ρ from C to the tip of a
/// massless rod of length L hinged at the origin), in the seed's dependent coordinates
/// (θ, φ, x1C, x2C) with x1 pointing "down" (gravity +g along x1).
///
/// Seed data: T = ½ m (ẋ1C² + ẋ2C²) + ½ I_C φ̇², Q = (0, 0, m g, 0), constraints
///   g1 = x1C − L cos θ − ρ cos φ = 0,   g2 = x2C − L sin θ − ρ sin φ = 0,
/// C = ∂g/∂q (rows g1, g2; columns θ, φ, x1C, x2C)
///   = [ L sin θ,  ρ sin φ, 1, 0 ;
///      −L cos θ, −ρ cos φ, 0, 1 ].
/// Lagrange with multipliers, d/dt ∂T/∂q̇ − ∂T/∂q + Cᵀλ = Q, gives the seed's (3)–(6):
///   (3)  L sin θ λ1 − L cos θ λ2 = 0                  (the rod is massless: T has no θ̇)
///   (4)  I_C φ̈ + ρ sin φ λ1 − ρ cos φ λ2 = 0
///   (5)  m ẍ1C + λ1 = m g
///   (6)  m ẍ2C + λ2 = 0
/// and, to close the six unknowns (θ̈, φ̈, ẍ1C, ẍ2C, λ1, λ2), the constraints twice differentiated:
///   g̈1 = ẍ1C + L sin θ θ̈ + L cos θ θ̇² + ρ sin φ φ̈ + ρ cos φ φ̇² = 0
///   g̈2 = ẍ2C − L cos θ θ̈ + L sin θ θ̇² − ρ cos φ φ̈ + ρ sin φ φ̇² = 0.
/// These six linear equations are solved here by a dense LU (independent of the crate).
///
/// Sign/order mapping of the multipliers: the seed writes M q̈ = Q − Cᵀλ_seed. The crate writes
/// M q̈ = −h + Jᵀλ with −h = Q (gravity is the only term: T has no velocity coupling), and the
/// scene's point residual is rod_tip − body_pin = −(g1, g2), so J = ∂φ/∂q = −C (columns permuted to
/// our order θ, x1C, x2C, φ). Hence Jᵀλ = −Cᵀλ, i.e. **λ_ours = λ_seed, same order**: row x ↔ g1,
/// row y ↔ g2. Physically, λ_seed = (λ1, λ2) is minus the pin force on the body: (5) says
/// m ẍ1C = m g − λ1, and the crate's `force` on frame rod_tip is +λ (force on the rod's chain; the
/// body receives −λ, so the body's equations are m ẍC = m g e_x − λ, matching (5), (6)).
/// Also Jᵀλ = −Cᵀλ_seed is the generalized constraint force M q̈ − Q.
///
/// M is singular (θ has no inertia); the crate handles that, the seed's 6×6 system is regular.
#[test]
fn seed000_rod_body_matches_lagrange_multiplier_equations() {
    let (l, rho, m, ic) = (1.0, 0.3, 2.0, 0.05);
    let scene = load("params/rod_body.yaml");
    let mut sys = System::from_scene(&scene).unwrap();
    let model = sys.model();
    assert_eq!(model.q_names, ["theta", "x1C", "x2C", "phi"]);
    assert_eq!(model.v_names, ["theta", "x1C", "x2C", "phi"]);
    assert_close("body mass", &[model.total_mass()], &[m], T_MASS0);
    assert_close("gravity", model.gravity.as_slice(), &[G, 0.0, 0.0], 1e-15); // achieved 0
    let (it, ix1, ix2, ip) = (0, 1, 2, 3);

    // The seed's own 6×6 system at (θ, φ, θ̇, φ̇): returns (θ̈, φ̈, ẍ1C, ẍ2C, λ1, λ2).
    let seed_solve = |th: f64, ph: f64, thd: f64, phd: f64| -> DVector<f64> {
        let (st, ct, sp, cp) = (th.sin(), th.cos(), ph.sin(), ph.cos());
        #[rustfmt::skip]
        let a = DMatrix::from_row_slice(6, 6, &[
            // θ̈        φ̈          ẍ1C  ẍ2C  λ1        λ2
            0.0,        0.0,        0.0, 0.0, l * st,   -l * ct,   // (3)
            0.0,        ic,         0.0, 0.0, rho * sp, -rho * cp, // (4)
            0.0,        0.0,        m,   0.0, 1.0,      0.0,       // (5)
            0.0,        0.0,        0.0, m,   0.0,      1.0,       // (6)
            l * st,     rho * sp,   1.0, 0.0, 0.0,      0.0,       // g̈1 = 0
            -l * ct,    -rho * cp,  0.0, 1.0, 0.0,      0.0,       // g̈2 = 0
        ]);
        let b = DVector::from_row_slice(&[
            0.0,
            0.0,
            m * G,
            0.0,
            -l * ct * thd * thd - rho * cp * phd * phd,
            -l * st * thd * thd - rho * sp * phd * phd,
        ]);
        a.lu().solve(&b).expect("seed 6x6 system singular")
    };

    // Consistent state from (θ, φ, θ̇, φ̇): g = 0 and ġ = 0 solved for x1C, x2C and their rates.
    let state = |th: f64, ph: f64, thd: f64, phd: f64| -> (Vec<f64>, Vec<f64>) {
        let mut q = vec![0.0; 4];
        let mut v = vec![0.0; 4];
        q[it] = th;
        q[ip] = ph;
        q[ix1] = l * th.cos() + rho * ph.cos();
        q[ix2] = l * th.sin() + rho * ph.sin();
        v[it] = thd;
        v[ip] = phd;
        v[ix1] = -l * th.sin() * thd - rho * ph.sin() * phd;
        v[ix2] = l * th.cos() * thd + rho * ph.cos() * phd;
        (q, v)
    };

    // The scene's initial state is one of these: θ = 0.4, φ = 1.1, θ̇ = 0.7, φ̇ = −0.5.
    let (q_s, v_s) = state(0.4, 1.1, 0.7, -0.5);
    // The scene file holds the seed's consistent state to its printed digits: achieved 0.
    assert_close("scene q0 (consistent)", &scene.q0, &q_s, 1e-15);
    assert_close("scene v0 (consistent)", &scene.v0, &v_s, 1e-15);

    // Sanity of the hand derivation against the numbers quoted in docs/robots.md.
    let s0 = seed_solve(0.4, 1.1, 0.7, -0.5);
    assert_close(
        "seed solve vs docs q̈ (θ, x1C, x2C, φ)",
        &[s0[0], s0[2], s0[3], s0[1]],
        &[
            3.043664872758356,
            6.270989590059195,
            -1.4962696023667346,
            -29.70348043719291,
        ],
        1e-14, // achieved 1.2e-16
    );
    assert_close(
        "seed solve vs docs λ",
        &[s0[4], s0[5]],
        &[7.07802081988161, 2.992539204733469],
        2e-14, // achieved 2.5e-16
    );

    let states = [
        (0.4, 1.1, 0.7, -0.5),
        (-1.3, 2.4, 1.9, -2.2),
        (2.8, -0.6, -0.4, 3.1),
    ];
    for (k, &(th, ph, thd, phd)) in states.iter().enumerate() {
        let (q, v) = state(th, ph, thd, phd);
        let s = seed_solve(th, ph, thd, phd);
        // Seed order (θ, φ, x1C, x2C) → ours (θ, x1C, x2C, φ).
        let qdd_seed = [s[0], s[2], s[3], s[1]];
        let lam_seed = [s[4], s[5]];
        let tau = [0.0; 4];

        let qdd = sys.forward_dynamics(&q, &v, &tau, true).unwrap().clone();
        assert_eq!(sys.last_formulation(), Formulation::Multipliers);
        assert_close(&format!("state {k}: q̈"), qdd.as_slice(), &qdd_seed, T_ROD);
        assert_eq!(sys.multipliers().lambda.len(), 2);
        // λ_ours = λ_seed (J = −C, and M q̈ = Q − Cᵀλ_seed = Q + Jᵀλ_ours).
        assert_close(
            &format!("state {k}: λ"),
            sys.multipliers().lambda.as_slice(),
            &lam_seed,
            T_ROD,
        );
        // Jᵀλ = −Cᵀλ_seed in our order: (−(L sθ λ1 − L cθ λ2), −λ1, −λ2, −(ρ sφ λ1 − ρ cφ λ2)).
        let (l1, l2) = (lam_seed[0], lam_seed[1]);
        let gen_force = [
            -(l * th.sin() * l1 - l * th.cos() * l2),
            -l1,
            -l2,
            -(rho * ph.sin() * l1 - rho * ph.cos() * l2),
        ];
        assert_close(
            &format!("state {k}: Jᵀλ"),
            sys.multipliers().generalized_force.as_slice(),
            &gen_force,
            T_ROD,
        );
        // The per-constraint report carries the same rows as a world-axis force.
        let f = sys.constraint_forces();
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].rows, ["x", "y"]);
        assert_close(
            &format!("state {k}: pin force"),
            &f[0].force,
            &[l1, l2, 0.0],
            T_ROD,
        );

        // The multiplier-free form gives the same q̈.
        let qdd_e = sys.forward_dynamics(&q, &v, &tau, false).unwrap().clone();
        assert_eq!(sys.last_formulation(), Formulation::Embedded);
        assert_close(
            &format!("state {k}: embedded q̈"),
            qdd_e.as_slice(),
            &qdd_seed,
            T_ROD,
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Seed 001 §3: vertical disk rolling without slipping.
// ---------------------------------------------------------------------------------------------

/// Seed 001 §3: a thin vertical disk (radius a, mass m, I_φ = m a²/2, I_θ = m a²/4) rolling
/// without slipping, coordinates (x, y, φ, θ), θ the angle between the disk axis and world x.
///
/// Constraints (31), (32): ẋ sin θ − ẏ cos θ − a φ̇ = 0, ẋ cos θ + ẏ sin θ = 0, so (33), (34)
/// ẋ = a φ̇ sin θ, ẏ = −a φ̇ cos θ, T̃ = ½ (I_φ + m a²) φ̇² + ½ I_θ θ̇² and the Voronets equations
/// (39), (40) reduce to (41) φ̈ = 0, (42) θ̈ = 0.
///
/// Our scene: planar base (x, y, yaw) with v = (vx_local, vy_local, wz) in the base frame, plus the
/// joint `spin` (axis +y). Mapping: φ = spin, θ = yaw + π/2 (so θ̇ = wz, θ̈ = ẇz). With heading
/// ψ = yaw, (ẋ, ẏ) = a φ̇ (sin θ, −cos θ) = a φ̇ (cos ψ, sin ψ): the centre moves along the
/// base's local +x at u = a φ̇, i.e. vx_local = a·spin_rate, vy_local = 0 (the scene's initial
/// state has spin 10, vx_local 1.0 = 0.1·10, which fixes the sign). Because φ̇ and θ̇ stay
/// constant and the local velocities are tied to them, the full q̈ = (v̇x_local, v̇y_local, ẇz,
/// spin̈) = (a φ̈, 0, θ̈, φ̈) = 0.
///
/// Contact force: the centre velocity is u (cos ψ, sin ψ) with u and ψ̇ = wz constant, so its
/// acceleration is u ψ̇ (−sin ψ, cos ψ), a circle of radius u/ψ̇ (centre on the base's local +y
/// side when u ψ̇ > 0). The only horizontal force on the disk+base is the ground contact (the
/// planar joint reacts only along z and about x, y; the base and axle are massless), so
/// F_horizontal = m u ψ̇ (−sin ψ, cos ψ): magnitude m |u ψ̇|, along local +y (toward the centre)
/// when u ψ̇ > 0, and zero along the heading (cos ψ, sin ψ).
///
/// Embedded form: k = 2 constraints on n = 4 velocities, s = n − k = 2 independent velocities
/// (the seed picks φ̇, θ̇), so the partition must hold nv − rank(J) = 2 independent coordinates.
#[test]
fn seed001_vertical_disk_rolls_with_constant_rates() {
    let (a, m) = (0.1, 1.0);
    let scene = load("params/vertical_disk.yaml");
    let mut sys = System::from_scene(&scene).unwrap();
    let nv = sys.model().nv;
    assert_eq!(
        sys.model().v_names,
        [
            "root_joint:vx_local",
            "root_joint:vy_local",
            "root_joint:wz",
            "spin"
        ]
    );
    assert_eq!(
        sys.model().q_names,
        ["root_joint:x", "root_joint:y", "root_joint:yaw", "spin"]
    );
    assert_close("disk mass", &[sys.model().total_mass()], &[m], T_MASS1);
    let (ivx, ivy, iwz, isp) = (0, 1, 2, 3);
    let iyaw = 2;
    // Sign convention fixed by the scene: vx_local = a·spin_rate, vy_local = 0.
    assert_close(
        "scene v0: vx = a·spin",
        &[scene.v0[ivx]],
        &[a * scene.v0[isp]],
        T_V0,
    );
    assert_eq!(scene.v0[ivy], 0.0);

    // (q, v) for position (x, y, yaw, spin angle), spin rate and yaw rate, consistent by (33), (34).
    let state = |x: f64, y: f64, yaw: f64, ang: f64, spin_rate: f64, wz: f64| {
        (
            vec![x, y, yaw, ang],
            vec![a * spin_rate, 0.0, wz, spin_rate],
        )
    };
    let states = [
        (scene.q0.clone(), scene.v0.clone()),
        state(0.3, -0.7, 1.2, 0.4, -6.0, 1.3),
        state(-1.0, 2.0, -2.5, 3.0, 4.0, -0.8),
    ];
    let tau = vec![0.0; nv];
    for (k, (q, v)) in states.iter().enumerate() {
        let qdd = sys.forward_dynamics(q, v, &tau, true).unwrap().clone();
        assert_eq!(sys.last_formulation(), Formulation::Multipliers);
        // The state satisfies the rolling constraints.
        assert_close(
            &format!("state {k}: J v"),
            sys.rows().jv.as_slice(),
            &[0.0, 0.0],
            T_DISK_JV,
        );
        // (41), (42): φ̈ = 0, θ̈ = 0; and the dependent accelerations a φ̈, 0: q̈ = 0.
        assert_close(
            &format!("state {k}: q̈ = 0"),
            qdd.as_slice(),
            &[0.0; 4],
            T_DISK_QDD,
        );

        // Contact force = m × centripetal acceleration of the centre.
        let (u, wz, psi) = (v[ivx], v[iwz], q[iyaw]);
        let f = sys.constraint_forces();
        let rolling: Vec<_> = f.iter().filter(|c| c.kind.name() == "rolling").collect();
        assert_eq!(rolling.len(), 1);
        assert_eq!(rolling[0].name, "disk_contact");
        let fh = [rolling[0].force[0], rolling[0].force[1]];
        let expected = [-m * u * wz * psi.sin(), m * u * wz * psi.cos()];
        assert_close(
            &format!("state {k}: horizontal contact force"),
            &fh,
            &expected,
            T_DISK_FORCE,
        );
        let along_heading = fh[0] * psi.cos() + fh[1] * psi.sin();
        let lateral = -fh[0] * psi.sin() + fh[1] * psi.cos();
        assert_close(
            &format!("state {k}: force (along heading, lateral)"),
            &[along_heading, lateral],
            &[0.0, m * u * wz],
            T_DISK_FORCE,
        );

        // Multiplier-free form: same q̈, fewer equations.
        let qdd_e = sys.forward_dynamics(q, v, &tau, false).unwrap().clone();
        assert_eq!(sys.last_formulation(), Formulation::Embedded);
        assert_close(
            &format!("state {k}: embedded q̈"),
            qdd_e.as_slice(),
            qdd.as_slice(),
            T_DISK_QDD,
        );
        let r = rank(&sys.rows().j);
        assert_eq!(r, 2, "state {k}: rank J (seed: two constraints (31), (32))");
        assert_eq!(sys.embedded().partition.independent.len(), nv - r);
        assert_eq!(sys.embedded().partition.dependent.len(), r);
    }
}

// ---------------------------------------------------------------------------------------------
// Seed 000 text, non-holonomic example: differential drive, no side slip.
// ---------------------------------------------------------------------------------------------

/// Seed 000's differential-drive example: the robot cannot move sideways,
///   ẏ cos θ − ẋ sin θ = 0
/// (θ = heading, (ẋ, ẏ) world velocity). With the planar base our v holds the base-frame velocity
/// (vx_local, vy_local) = Rᵀ(θ) (ẋ, ẏ), so vy_local = −ẋ sin θ + ẏ cos θ: the seed's expression is
/// exactly vy_local. A `no_side_slip` constraint on frame base_link, axis +y, has the row
/// e_yᵀ v_{base_link origin} in base_link axes; base_link sits on the yaw axis (0, 0, 0.05), so
/// ω × r = wz e_z × 0.05 e_z = 0 and J = [0, 1, 0, 0, 0] over (vx_local, vy_local, wz, ω_L, ω_R).
/// Hence J v = 0 for a world velocity on the heading, and J v = vy_local = ẏ cos θ − ẋ sin θ
/// otherwise.
#[test]
fn seed_diff_drive_no_side_slip_is_lateral_velocity() {
    let urdf = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("urdf/diff_drive.urdf");
    let yaml = format!(
        "urdf: {:?}\nbase: planar\nconstraints:\n  - name: no_slip\n    kind: no_side_slip\n    \
         frame: base_link\n    axis: [0.0, 1.0, 0.0]\n",
        urdf.display().to_string()
    );
    let path = std::env::temp_dir().join(format!("seeds_no_side_slip_{}.yaml", std::process::id()));
    std::fs::write(&path, yaml).unwrap();
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let _ = std::fs::remove_file(&path);
    let mut sys = System::from_scene(&scene).unwrap();
    assert_eq!(
        sys.model().v_names,
        [
            "root_joint:vx_local",
            "root_joint:vy_local",
            "root_joint:wz",
            "left_wheel_joint",
            "right_wheel_joint"
        ]
    );
    assert_eq!(sys.constraints().nrows, 1);
    let nv = sys.model().nv;
    let tau = vec![0.0; nv];
    let th: f64 = 0.7;
    let q = vec![0.4, -0.2, th, 0.3, -1.1];
    let to_local = |xd: f64, yd: f64| {
        (
            xd * th.cos() + yd * th.sin(),
            -xd * th.sin() + yd * th.cos(),
        )
    };

    // World velocity along the heading: satisfies ẏ cos θ − ẋ sin θ = 0.
    let s = 0.8;
    let (xd, yd) = (s * th.cos(), s * th.sin());
    assert!((yd * th.cos() - xd * th.sin()).abs() < 1e-15);
    let (vx, vy) = to_local(xd, yd);
    let v = vec![vx, vy, 0.6, 3.0, -2.0];
    sys.forward_dynamics(&q, &v, &tau, true).unwrap();
    assert_close(
        "J row",
        sys.rows().j.row(0).transpose().as_slice(),
        &[0.0, 1.0, 0.0, 0.0, 0.0],
        1e-15, // achieved 0
    );
    assert_close("J v, admissible", &[sys.rows().jv[0]], &[0.0], T_NSS);
    sys.forward_dynamics(&q, &v, &tau, false).unwrap();
    assert_close(
        "J v, admissible (embedded path)",
        &[sys.rows().jv[0]],
        &[0.0],
        T_NSS,
    );

    // A sideways-slipping velocity: J v = vy_local = ẏ cos θ − ẋ sin θ ≠ 0.
    let (xd, yd) = (0.5, 0.9);
    let seed_residual = yd * th.cos() - xd * th.sin();
    let (vx, vy) = to_local(xd, yd);
    assert!(vy.abs() > 0.1);
    let v = vec![vx, vy, -0.3, 1.0, 2.0];
    sys.forward_dynamics(&q, &v, &tau, true).unwrap();
    assert_close("J v = vy_local", &[sys.rows().jv[0]], &[vy], T_NSS);
    assert_close(
        "J v = seed residual",
        &[sys.rows().jv[0]],
        &[seed_residual],
        T_NSS,
    );
    let f = sys.constraint_forces();
    assert_eq!(f[0].kind.name(), "no_side_slip");
    assert_close(
        "reported velocity residual",
        &[f[0].velocity_residual[0]],
        &[vy],
        T_NSS,
    );
}
