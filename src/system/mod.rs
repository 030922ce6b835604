//! A constrained system ready to evaluate: what a scene declares (the shared robot model, the
//! constraint set, the scene's gains and formulation) and the workspaces its evaluations write,
//! built once from a scene. The CLI, the predictor and the ROS nodes go through here; each call
//! says how it evaluates ([`DynamicsOptions`]) and nothing is set on the system around it.

mod forward;
mod metric;

pub use forward::DynamicsOptions;
pub use metric::TreeMetric;

use crate::algorithm::{
    Data, bias_forces_after_kinematics, center_of_mass, crba_after_kinematics, crba_full,
    crba_full_after_kinematics, forward_kinematics, forward_kinematics_bias,
    forward_kinematics_pos, kinetic_energy, potential_energy,
};
use crate::constraints::{ConstraintData, ConstraintForce, ConstraintSet, constraint_forces};
use crate::derivatives::{
    DerivativeData, aba_derivatives, constrained_dynamics_derivatives, rnea_derivatives,
};
use crate::dynamics::{
    Baumgarte, EmbeddedWorkspace, Formulation, KktOptions, KktWorkspace, TreeKktWorkspace,
    takes_linear_path,
};
use crate::error::{Result, check_len};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

/// [`System::parts`]: the immutable model and constraints beside the workspaces one call writes.
pub struct Parts<'a> {
    /// The robot model.
    pub model: &'a Model,
    /// The validated constraints.
    pub constraints: &'a ConstraintSet,
    /// Kinematics and dynamics workspace.
    pub data: &'a mut Data,
    /// Constraint rows.
    pub rows: &'a mut ConstraintData,
    /// The multiplier form's workspace.
    pub multipliers: &'a mut KktWorkspace,
}

/// A constrained system: the immutable part a scene declares (the robot model, shared; the
/// validated constraints; the scene's Baumgarte gains and formulation) and the workspaces its
/// evaluations write. Outside the crate it is read through accessors and changed only by
/// evaluations; what one evaluation does is its arguments ([`DynamicsOptions`]).
#[derive(Clone, Debug)]
pub struct System {
    model: Arc<Model>,
    constraints: ConstraintSet,
    /// The scene's Baumgarte gains (`dynamics:`), used where an evaluation names none.
    baumgarte: Baumgarte,
    /// The formulation the scene asks for.
    formulation: Formulation,
    /// Kinematics and dynamics workspace.
    data: Data,
    /// Constraint rows (J, φ, γ, J v) at the last evaluation.
    cdata: ConstraintData,
    /// Multiplier-form workspace; λ of the last multiplier solve.
    kkt: KktWorkspace,
    /// Embedded-form workspace.
    embedded: EmbeddedWorkspace,
    /// Whether the forward dynamics go by ABA (`dynamics::takes_linear_path`): in O(n)
    /// without constraint rows, in O(n·m + m³) in the multiplier form with m rows; and that
    /// path's workspace.
    linear: bool,
    tree: TreeKktWorkspace,
    /// Which formulation produced the last result.
    last_formulation: Formulation,
}

impl System {
    /// Build from a model and its constraint set.
    pub fn new(
        model: impl Into<Arc<Model>>,
        constraints: ConstraintSet,
        baumgarte: Baumgarte,
        formulation: Formulation,
    ) -> Self {
        let model = model.into();
        let data = Data::new(&model);
        let cdata = ConstraintData::new(&model, &constraints);
        let kkt = KktWorkspace::new(&model, &constraints);
        let embedded = EmbeddedWorkspace::new(&model, &constraints);
        let tree = TreeKktWorkspace::new(&model);
        let linear = takes_linear_path(&model);
        Self {
            model,
            constraints,
            baumgarte,
            formulation,
            data,
            cdata,
            kkt,
            embedded,
            linear,
            tree,
            last_formulation: Formulation::Multipliers,
        }
    }

    /// The same system evaluated in `formulation` unless a call names its own.
    pub fn with_formulation(mut self, formulation: Formulation) -> Self {
        self.formulation = formulation;
        self
    }

    /// The same system with other Baumgarte gains in place of the scene's.
    pub fn with_baumgarte(mut self, gains: Baumgarte) -> Self {
        self.baumgarte = gains;
        self
    }

    /// The constraint rows (J, φ, γ, J v) at (t, q, v), kept as [`System::rows`] until the next
    /// evaluation.
    pub fn evaluate_rows(&mut self, t: f64, q: &[f64], v: &[f64]) -> &ConstraintData {
        self.constraints
            .evaluate(&self.model, &mut self.data, &mut self.cdata, t, q, v);
        &self.cdata
    }

    /// M(q)'s lower triangle [kg, kg·m, kg·m²] at the configuration of the last
    /// [`System::evaluate_rows`] (a CRBA on its kinematics, no second pass), kept in
    /// [`System::data`]: what a Cholesky factor reads; the strict upper triangle is not written.
    pub fn mass_matrix_after_rows(&mut self) -> &DMatrix<f64> {
        crba_after_kinematics(&self.model, &mut self.data)
    }

    /// h(q, v) = C(q, v) v + g(q) [N, N·m] at the state of the last [`System::evaluate_rows`],
    /// kept in [`System::data`] (`tau`).
    pub fn bias_after_rows(&mut self) -> &DVector<f64> {
        bias_forces_after_kinematics(&self.model, &mut self.data);
        &self.data.tau
    }

    /// The rows at (t, q, v) with M (both triangles) and h of the same kinematics pass, their
    /// entries checked finite: what a solve in the mass metric reads (through [`System::data`]
    /// and [`System::rows`]).
    pub fn evaluate_rows_and_dynamics(&mut self, t: f64, q: &[f64], v: &[f64]) -> Result<()> {
        self.evaluate_rows(t, q, v);
        self.constraints.check_finite(&self.cdata)?;
        crba_full_after_kinematics(&self.model, &mut self.data);
        bias_forces_after_kinematics(&self.model, &mut self.data);
        Ok(())
    }

    /// Placements, twists and bias accelerations at (q, v, q̈ = 0), kept in [`System::data`]
    /// (what force elements read).
    pub fn kinematics_at(&mut self, q: &[f64], v: &[f64]) -> &Data {
        forward_kinematics_bias(&self.model, &mut self.data, q, v);
        &self.data
    }

    /// M(q), both triangles, kept in [`System::data`].
    pub fn mass_matrix_at(&mut self, q: &[f64]) -> &DMatrix<f64> {
        crba_full(&self.model, &mut self.data, q)
    }

    /// (max |φ| over holonomic rows [m or rad], max |J v| [m/s or rad/s]) at (t, q, v), each
    /// row's φ and J v kept as [`System::rows`], and the placements and twists of (q, v) in
    /// [`System::data`] (`ConstraintSet::residuals`).
    pub fn residuals(&mut self, t: f64, q: &[f64], v: &[f64]) -> (f64, f64) {
        self.constraints
            .residuals(&self.model, &mut self.data, &mut self.cdata, t, q, v)
    }

    /// The model, the constraints and the kinematics and row workspaces, lent to one call of
    /// an algorithm that takes them apart (`algo(model, data, …)`).
    pub fn parts(&mut self) -> Parts<'_> {
        Parts {
            model: &self.model,
            constraints: &self.constraints,
            data: &mut self.data,
            rows: &mut self.cdata,
            multipliers: &mut self.kkt,
        }
    }

    /// The body placements at q (positions only; frames through `algorithm::frame_placement`),
    /// kept as [`System::data`] until the next evaluation.
    pub fn placements_at(&mut self, q: &[f64]) -> &Data {
        forward_kinematics_pos(&self.model, &mut self.data, q);
        &self.data
    }

    /// The robot model (shared with the scene it was built from).
    pub fn model(&self) -> &Arc<Model> {
        &self.model
    }

    /// The validated constraints.
    pub fn constraints(&self) -> &ConstraintSet {
        &self.constraints
    }

    /// The scene's Baumgarte gains.
    pub fn baumgarte(&self) -> Baumgarte {
        self.baumgarte
    }

    /// The formulation the scene asks for.
    pub fn formulation(&self) -> Formulation {
        self.formulation
    }

    /// Which formulation produced the last result.
    pub fn last_formulation(&self) -> Formulation {
        self.last_formulation
    }

    /// Kinematics, M and h of the last evaluation.
    pub fn data(&self) -> &Data {
        &self.data
    }

    /// The constraint rows (J, φ, γ, J v, at `t`) of the last evaluation.
    pub fn rows(&self) -> &ConstraintData {
        &self.cdata
    }

    /// The multiplier form's results of its last solve: λ (N, N·m, … on the robot), Jᵀλ,
    /// the rank deficiency.
    pub fn multipliers(&self) -> &KktWorkspace {
        &self.kkt
    }

    /// λ of the last multiplier-form evaluation, in the rows' units: force ON the robot.
    pub fn lambda(&self) -> &DVector<f64> {
        &self.kkt.lambda
    }

    /// The embedded form's results of its last evaluation (partition, solved velocities).
    pub fn embedded(&self) -> &EmbeddedWorkspace {
        &self.embedded
    }

    /// M(q) (both triangles) and h(q, v) = C(q, v) v + g(q) at (q, v), kept in
    /// [`System::data`] (`mass_matrix`, `tau`): what a dense evaluation computes on the way,
    /// asked for separately since the linear-time path does not form them.
    pub fn terms_at(&mut self, q: &[f64], v: &[f64]) -> (&DMatrix<f64>, &DVector<f64>) {
        forward_kinematics_bias(&self.model, &mut self.data, q, v);
        crba_full_after_kinematics(&self.model, &mut self.data);
        bias_forces_after_kinematics(&self.model, &mut self.data);
        (&self.data.mass_matrix, &self.data.tau)
    }

    /// q̈ and ∂q̈/∂(q, v, τ) at (q, v, τ) and time `t` [s] into `dd` (and ∂λ/∂(q, v, τ) with
    /// constraints): the multiplier form's with the scene's gains, ABA's without constraints.
    pub fn dynamics_derivatives(
        &mut self,
        dd: &mut DerivativeData,
        t: f64,
        q: &[f64],
        v: &[f64],
        tau: &[f64],
    ) -> Result<()> {
        self.model.check_state(q, v)?;
        check_len("tau", tau, self.model.nv)?;
        if self.constraints.is_empty() {
            aba_derivatives(&self.model, &mut self.data, dd, q, v, tau)
        } else {
            constrained_dynamics_derivatives(
                &self.model,
                &mut self.data,
                &self.constraints,
                &mut self.cdata,
                &mut self.kkt,
                dd,
                q,
                v,
                tau,
                KktOptions {
                    t,
                    ..self.baumgarte.into()
                },
            )
        }
    }

    /// ∂τ/∂(q, v) of inverse dynamics at (q, v, q̈) into `dd.dtau_dq`, `dd.dtau_dv`.
    pub fn inverse_dynamics_derivatives(
        &mut self,
        dd: &mut DerivativeData,
        q: &[f64],
        v: &[f64],
        qdd: &[f64],
    ) {
        rnea_derivatives(&self.model, &mut self.data, dd, q, v, qdd);
    }

    /// Constraint forces of the last multiplier-form evaluation.
    pub fn constraint_forces(&self) -> Vec<ConstraintForce> {
        constraint_forces(
            &self.model,
            &self.data,
            &self.constraints,
            &self.cdata,
            &self.kkt.lambda,
        )
    }

    /// (kinetic, potential) energy [J] and the centre of mass [m] at (q, v).
    pub fn energy(&mut self, q: &[f64], v: &[f64]) -> (f64, f64, [f64; 3]) {
        let zero = vec![0.0; self.model.nv];
        forward_kinematics(&self.model, &mut self.data, q, v, &zero);
        let c = center_of_mass(&self.model, &self.data);
        (
            kinetic_energy(&self.model, &self.data),
            potential_energy(&self.model, &self.data),
            [c.x, c.y, c.z],
        )
    }
}
