//! What acts on the robot at one state, and the constraint forces that answer it.
//!
//! The generalized force that joins the dynamics is τ = τ_act + Q(t, q, v): the actuators'
//! torques (held over a control period) plus the scene's force elements (springs, dampers,
//! scheduled torques, frame forces). The constraint forces at (t, q, v) are the multipliers λ of
//! `M q̈ + h = τ + Jᵀλ, J q̈ = −γ − K_d J v − K_p φ` under that τ. One function computes them for
//! the predictor's samples, the forces service, the CLI and the tests.

use crate::constraints::ConstraintForce;
use crate::dynamics::Formulation;
use crate::error::Result;
use crate::forces::ForceElements;
use crate::system::{DynamicsOptions, System};
use nalgebra::DMatrix;

/// Writes τ = τ_act + Q(t, q, v) into `tau` (nv). Allocates nothing.
pub fn applied_generalized_force(
    sys: &mut System,
    elements: &mut ForceElements,
    (t, q, v): (f64, &[f64], &[f64]),
    tau_act: &[f64],
    tau: &mut [f64],
) {
    if elements.needs_kinematics() {
        sys.kinematics_at(q, v);
    }
    applied_generalized_force_after_kinematics(sys, elements, (t, q, v), tau_act, tau);
}

/// [`applied_generalized_force`] where [`System::data`] already holds the kinematics at (q, v)
/// and q̈ = 0 (a [`System::kinematics_at`] or [`System::evaluate_rows`] there, nothing written
/// since): the force elements read them instead of a second pass.
pub fn applied_generalized_force_after_kinematics(
    sys: &System,
    elements: &mut ForceElements,
    (t, q, v): (f64, &[f64], &[f64]),
    tau_act: &[f64],
    tau: &mut [f64],
) {
    tau.copy_from_slice(tau_act);
    if !elements.is_empty() {
        elements.add_generalized_force(sys.model(), sys.data(), t, q, v, tau);
    }
}

/// The constraint forces at one state (multiplier form, whatever the system integrates with).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ForcesAtState {
    /// q̈ (nv) [m/s², rad/s²].
    pub qdd: Vec<f64>,
    /// λ (nc), in the rows' units: the force ON the robot.
    pub lambda: Vec<f64>,
    /// Each constraint's force or wrench at its frame, named.
    pub forces: Vec<ConstraintForce>,
    /// Jᵀλ per velocity coordinate (nv) [N or N·m].
    pub generalized_force: Vec<f64>,
    /// nc − rank(J M⁻¹ Jᵀ): > 0 at a singular configuration or with redundant rows, where λ is
    /// the minimum-norm solution.
    pub rank_deficiency: usize,
}

/// Constraint forces at (t, q, v) under actuator torques `tau_act` (nv) plus the force
/// elements. Uses the multiplier form; `allow_inconsistent` as in [`DynamicsOptions`].
pub fn constraint_forces_at(
    sys: &mut System,
    elements: &mut ForceElements,
    (t, q, v): (f64, &[f64], &[f64]),
    tau_act: &[f64],
) -> Result<ForcesAtState> {
    let nv = sys.model().nv;
    crate::error::check_len("tau", tau_act, nv)?;
    sys.model().check_state(q, v)?;
    let mut tau = vec![0.0; nv];
    applied_generalized_force(sys, elements, (t, q, v), tau_act, &mut tau);
    let opts = DynamicsOptions {
        formulation: Formulation::Multipliers,
        t,
        ..Default::default()
    };
    let qdd = sys
        .forward_dynamics_with(q, v, &tau, opts)?
        .as_slice()
        .to_vec();
    let out = ForcesAtState {
        qdd,
        lambda: sys.lambda().as_slice().to_vec(),
        forces: sys.constraint_forces(),
        generalized_force: sys.multipliers().generalized_force.as_slice().to_vec(),
        rank_deficiency: sys.multipliers().rank_deficiency,
    };
    // Nothing non-finite leaves: finite inputs can still overflow (v = 1e308 squared).
    let cause = || {
        let amax = |x: &[f64]| x.iter().fold(0.0f64, |m, y| m.max(y.abs()));
        format!(
            "the state or torques overflow the arithmetic at t = {t} s (max |v| = {:e}, max |τ| \
             = {:e}); see the input ranges in README.md",
            amax(v),
            amax(&tau)
        )
    };
    let outputs = [
        ("q̈", &out.qdd),
        ("λ", &out.lambda),
        ("Jᵀλ", &out.generalized_force),
    ];
    if let Some((what, x)) = outputs
        .into_iter()
        .find(|(_, x)| x.iter().any(|y| !y.is_finite()))
    {
        crate::error::check_output(what, x, &cause())?;
    }
    for f in &out.forces {
        let numbers: Vec<f64> = [&f.force[..], &f.torque, &f.point_world, &f.lambda]
            .into_iter()
            .flatten()
            .chain(&f.position_residual)
            .chain(&f.velocity_residual)
            .chain(f.normal_force.iter())
            .chain(f.tangential_force.iter())
            .copied()
            .collect();
        crate::error::check_output(
            &format!("constraint force '{}'", f.name),
            &numbers,
            &cause(),
        )?;
    }
    Ok(out)
}

/// How [`ForceJacobian`] differences Q.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Differences {
    /// (Q(x + ε) − Q(x − ε)) / 2ε, ε = 1e-6: the implicit methods' Jacobian, whose error
    /// enters their Newton iterations.
    Central,
    /// (Q(x + ε) − Q(x)) / ε, ε = 1e-7: half the evaluations, for a covariance, which needs
    /// far less than its ~1e-7 relative error.
    Forward,
}

/// ∂Q/∂δq and ∂Q/∂v of force elements at a state (δq a right perturbation q ⊕ δq), by
/// differences of their generalized force Q(t, q, v): kinematics and the elements only, since
/// the elements (tyres, turning resistances, frame forces, point springs) have no analytic
/// derivatives. The v step is ε·max(|v_c|, 1). Buffers sized once; allocates nothing.
#[derive(Clone, Debug, Default)]
pub struct ForceJacobian {
    /// ∂Q/∂δq (nv × nv) [N/m, N·m/rad].
    pub dq: DMatrix<f64>,
    /// ∂Q/∂v (nv × nv) [N·s/m, N·m·s/rad].
    pub dv: DMatrix<f64>,
    /// Q at the state (with [`Differences::Forward`]), and at the perturbed states.
    pub at: Vec<f64>,
    plus: Vec<f64>,
    minus: Vec<f64>,
    q: Vec<f64>,
    v: Vec<f64>,
    e: Vec<f64>,
}

impl ForceJacobian {
    /// Sized for `model`.
    pub fn new(model: &crate::model::Model) -> Self {
        let (nq, nv) = (model.nq, model.nv);
        Self {
            dq: DMatrix::zeros(nv, nv),
            dv: DMatrix::zeros(nv, nv),
            at: vec![0.0; nv],
            plus: vec![0.0; nv],
            minus: vec![0.0; nv],
            q: vec![0.0; nq],
            v: vec![0.0; nv],
            e: vec![0.0; nv],
        }
    }

    /// Q of `elements` at (t, q, v) into `out` (its kinematics computed here).
    pub fn generalized_force(
        sys: &mut System,
        elements: &mut ForceElements,
        (t, q, v): (f64, &[f64], &[f64]),
        out: &mut [f64],
    ) {
        if elements.needs_kinematics() {
            sys.kinematics_at(q, v);
        }
        out.fill(0.0);
        elements.add_generalized_force(sys.model(), sys.data(), t, q, v, out);
    }

    /// [`Self::dq`] and [`Self::dv`] of `elements` at (t, q, v); with
    /// [`Differences::Forward`], Q there in [`Self::at`]. Leaves the system's kinematics at a
    /// nearby state.
    pub fn differentiate(
        &mut self,
        sys: &mut System,
        elements: &mut ForceElements,
        (t, q, v): (f64, &[f64], &[f64]),
        how: Differences,
    ) {
        let Self {
            dq,
            dv,
            at,
            plus,
            minus,
            q: qp,
            v: vp,
            e,
        } = self;
        let (eps0, central) = match how {
            Differences::Central => (1e-6, true),
            Differences::Forward => (1e-7, false),
        };
        if !central {
            Self::generalized_force(sys, elements, (t, q, v), at);
        }
        let nv = v.len();
        for col in 0..2 * nv {
            let c = col % nv;
            let eps = if col < nv {
                eps0
            } else {
                eps0 * v[c].abs().max(1.0)
            };
            let signs: &[f64] = if central { &[1.0, -1.0] } else { &[1.0] };
            for &sign in signs {
                let out = if sign > 0.0 { &mut *plus } else { &mut *minus };
                if col < nv {
                    e.fill(0.0);
                    e[c] = sign * eps;
                    sys.model().integrate(q, e, 1.0, qp);
                    Self::generalized_force(sys, elements, (t, qp, v), out);
                } else {
                    vp.copy_from_slice(v);
                    vp[c] += sign * eps;
                    Self::generalized_force(sys, elements, (t, q, vp), out);
                }
            }
            let (base, width) = if central {
                (&*minus, 2.0 * eps)
            } else {
                (&*at, eps)
            };
            let m = if col < nv { &mut *dq } else { &mut *dv };
            for r in 0..nv {
                m[(r, c)] = (plus[r] - base[r]) / width;
            }
        }
    }
}
