//! The acceleration envelope: how hard the base can accelerate, brake and turn at one state
//! under the robot's limits — actuator efforts, friction cones and contacts that push but never
//! pull.
//!
//! ```text
//! max  ± a_fwd            (a_yaw = 0)        forward acceleration / deceleration
//! max  ± a_yaw            (a_fwd = 0)        yaw acceleration left (+z) / right
//! over a (nv), τ (na), λ (nc) subject to
//!   M(q) a + h(q, v) = Q + Sᵀ τ + Jᵀ λ       dynamics; S selects the actuated coordinates
//!   J(q) a = −γ(q, v)                        every constraint row at acceleration level
//!   a_i = 0                                  joints that do not drive the base (an arm)
//!   |τ_k| ≤ e_k                              URDF <limit effort> of each actuated joint
//!   λ_n ≥ 0                                  normal rows: rolling contacts, unilateral points
//!   ‖λ_t‖ ≤ μ λ_n                            friction cones (second-order cones)
//! ```
//!
//! Sizes: nv velocity coordinates, na actuated coordinates (every joint coordinate but the
//! base's and the scene's `passive_joints:`), nc constraint rows. a_fwd and a_yaw are the
//! accelerations of the base's `vx_local` and yaw-rate coordinates, the time derivatives of the
//! base twist in the base frame [m/s², rad/s²]; h is the bias force (Coriolis, centrifugal,
//! gravity) and Q the force elements' generalized force at (q, v) (the caller's; zero when the
//! scene has none). The wheels (the joints between the base and a rolling wheel) and the base's
//! other directions are left to the constraints.
//!
//! Each limit is signed: a negative forward deceleration means that even holding still is out
//! of reach — the robot must accelerate to keep every contact (it would tip over). An
//! unbounded direction has no maximum ([`Reach::Unbounded`]); with the other direction held,
//! an empty feasible set is [`Reach::Infeasible`]. Each limit names what binds it
//! ([`LimitKind`](crate::robot_limits::LimitKind)): the actuators at their effort, the contacts at their friction cone, the
//! contacts whose normal force vanishes (`lift_off`).
//!
//! A wheel on a planar base has no normal row: the envelope cannot tell lift-off nor, therefore,
//! friction there, and lists both under [`EnvelopeModel::unchecked`] rather than guess a
//! normal force; so are the friction of a contact declared without μ and the effort of a joint
//! whose URDF gives none.
//!
//! Model / Data: [`EnvelopeModel`] (built once from the model, the constraint set and the
//! scene) and [`EnvelopeData`] (the Clarabel solver, built at the first call and updated in
//! place, and the results). See `docs/projection.md`, "The acceleration envelope".

mod model;
mod report;
mod socp;

pub use crate::constraints::Contact;
/// The kind of a binding (or unchecked) limit.
pub use crate::robot_limits::LimitKind as BindingKind;
pub use crate::robot_limits::{ACTIVE_TOLERANCE, Actuator, Binding, NamedLimit};
pub use model::EnvelopeModel;
pub(crate) use report::unchecked_limits;
pub use report::{EnvelopeReport, LimitReport};

use crate::error::{Result, check_len};
use crate::robot_limits::{active_limits, max_active_limits};
use crate::system::System;
use nalgebra::DVector;
use serde::Serialize;
use socp::{Direction, Outcome, Socp};

/// Whether a direction has a maximum.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reach {
    /// A finite maximum, in [`Limit::max`].
    Bounded,
    /// No limit holds the acceleration in this direction.
    Unbounded,
    /// No accelerations satisfy every limit with the other direction held.
    Infeasible,
}

/// One of the four limits, with the optimum that attains it.
#[derive(Clone, Debug)]
pub struct Limit {
    /// Bounded, unbounded or infeasible.
    pub reach: Reach,
    /// The signed maximum [m/s² or rad/s²] when bounded (NaN otherwise).
    pub max: f64,
    /// What binds it (empty unless bounded).
    pub binding: Vec<Binding>,
    /// Accelerations at the optimum (nv) [m/s², rad/s²].
    pub qdd: DVector<f64>,
    /// Actuator torques at the optimum (na) [N·m or N].
    pub tau: DVector<f64>,
    /// Constraint forces at the optimum (nc), the rows' convention (force on the robot).
    pub lambda: DVector<f64>,
    /// Clarabel's interior-point iterations for this limit.
    pub iterations: u32,
}

impl Limit {
    fn new(em: &EnvelopeModel) -> Self {
        Self {
            reach: Reach::Infeasible,
            max: f64::NAN,
            binding: Vec::with_capacity(max_active_limits(&em.actuators, &em.contacts)),
            qdd: DVector::zeros(em.nv),
            tau: DVector::zeros(em.na()),
            lambda: DVector::zeros(em.nc),
            iterations: 0,
        }
    }
}

/// The four limits of the base at one state.
#[derive(Clone, Debug)]
pub struct Envelope {
    /// Largest forward acceleration, yaw acceleration held at 0 [m/s²].
    pub forward_acceleration: Limit,
    /// Largest forward deceleration (−a_fwd), yaw acceleration held at 0 [m/s²].
    pub forward_deceleration: Limit,
    /// Largest yaw acceleration to the left (+z), forward acceleration held at 0 [rad/s²].
    pub yaw_acceleration_left: Limit,
    /// Largest yaw acceleration to the right (−z), forward acceleration held at 0 [rad/s²].
    pub yaw_acceleration_right: Limit,
}

/// Workspace and results of [`acceleration_envelope`] (the "data" half; allocated once, the
/// solver built at the first call).
pub struct EnvelopeData {
    socp: Socp,
    rhs: DVector<f64>,
    /// The results of the last call.
    pub envelope: Envelope,
}

impl EnvelopeData {
    /// Size the workspace for `em`.
    pub fn new(em: &EnvelopeModel) -> Self {
        Self {
            socp: Socp::new(em),
            rhs: DVector::zeros(em.nv),
            envelope: Envelope {
                forward_acceleration: Limit::new(em),
                forward_deceleration: Limit::new(em),
                yaw_acceleration_left: Limit::new(em),
                yaw_acceleration_right: Limit::new(em),
            },
        }
    }
}

/// The acceleration envelope of `sys` at (q, v) with the force elements' generalized force
/// `applied` (nv; zeros when the scene has none). Results in `ed.envelope`; allocates nothing
/// after the first call outside Clarabel's solve.
pub fn acceleration_envelope<'a>(
    sys: &mut System,
    em: &EnvelopeModel,
    ed: &'a mut EnvelopeData,
    q: &[f64],
    v: &[f64],
    applied: &[f64],
) -> Result<&'a Envelope> {
    let nv = sys.model().nv;
    sys.model().check_state(q, v)?;
    check_len("applied", applied, nv)?;
    crate::error::check_finite("applied", applied)?;
    // One kinematics pass at (q, v, q̈ = 0) serves J, γ, M and h; the envelope is of the
    // present, time-dependent rows at the rows' own last time.
    sys.evaluate_rows_and_dynamics(sys.rows().t, q, v)?;
    let (data, rows) = (sys.data(), sys.rows());
    for i in 0..nv {
        ed.rhs[i] = applied[i] - data.tau[i];
    }
    ed.socp
        .load(em, &data.mass_matrix, &rows.j, &ed.rhs, &rows.gamma)?;
    let env = &mut ed.envelope;
    let cases = [
        (
            Direction::Forward,
            em.forward,
            1.0,
            &mut env.forward_acceleration,
        ),
        (
            Direction::Forward,
            em.forward,
            -1.0,
            &mut env.forward_deceleration,
        ),
        (Direction::Yaw, em.yaw, 1.0, &mut env.yaw_acceleration_left),
        (
            Direction::Yaw,
            em.yaw,
            -1.0,
            &mut env.yaw_acceleration_right,
        ),
    ];
    let (m, j) = (&sys.data().mass_matrix, &sys.rows().j);
    for (direction, coordinate, sign, limit) in cases {
        let outcome = ed.socp.solve(m, j, direction, coordinate, sign)?;
        limit.binding.clear();
        limit.iterations = ed.socp.iterations();
        limit.max = f64::NAN;
        limit.reach = match outcome {
            Outcome::Optimal => Reach::Bounded,
            Outcome::Unbounded => Reach::Unbounded,
            Outcome::Infeasible => Reach::Infeasible,
        };
        if outcome != Outcome::Optimal {
            continue;
        }
        let x = ed.socp.x();
        let (nv, na) = (em.nv, em.na());
        limit.qdd.as_mut_slice().copy_from_slice(&x[..nv]);
        limit.tau.as_mut_slice().copy_from_slice(&x[nv..nv + na]);
        limit.lambda.as_mut_slice().copy_from_slice(&x[nv + na..]);
        limit.max = sign * x[coordinate];
        let (tau, lambda) = (&x[nv..nv + na], &x[nv + na..]);
        let (actuators, contacts) = (&em.actuators, &em.contacts);
        active_limits(
            actuators,
            contacts,
            tau,
            lambda,
            em.force_scale,
            &mut limit.binding,
        );
    }
    Ok(&ed.envelope)
}
