//! A constrained system ready to evaluate: model, constraint set, stabilisation and every
//! workspace, built once from a scene. The CLI, the predictor and the ROS nodes go through here.

use crate::algorithm::{
    Data, center_of_mass, forward_kinematics, kinetic_energy, potential_energy,
};
use crate::constraints::{ConstraintData, ConstraintForce, ConstraintSet, constraint_forces};
use crate::dynamics::{
    Baumgarte, EmbeddedWorkspace, Formulation, KktOptions, KktWorkspace,
    constrained_forward_dynamics, embedded_forward_dynamics,
};
use crate::error::{Result, check_len};
use crate::model::Model;
use nalgebra::DVector;
use std::sync::Arc;

/// How one dynamics evaluation is done (passed in, never toggled on the system around a call).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DynamicsOptions {
    /// Multipliers (λ and the constraint forces) or the embedded, multiplier-free form;
    /// `Auto` means multipliers here.
    pub formulation: Formulation,
    /// Multiplier form: accept acceleration rows that cannot all be met (redundant rows that
    /// disagree by drift, at or next to a singular configuration) with the least-squares
    /// λ = S⁺ r, instead of an error. The predictor's stages ask for it.
    pub allow_inconsistent: bool,
    /// Multiplier form: the kinematics in `data` and the rows in `cdata` are those of this
    /// (q, v) at `cdata.t` — `ConstraintSet::evaluate` ran there and nothing has written them
    /// since — so that pass is skipped. The predictor sets it for a step's first stage when its
    /// drift projection evaluated the rows at that state and left it unchanged. Default false.
    pub rows_evaluated: bool,
}

impl DynamicsOptions {
    /// An integration stage of a prediction, and each stage of its linearization (the
    /// covariance's, an implicit method's Jacobian): the multiplier form unless the scene asks
    /// for the embedded one, with the least-squares λ = S⁺ r where the rows disagree
    /// ([`crate::dynamics::disagree_beyond_rounding`]). A stage lies off the constraint manifold
    /// by the step's own error, where redundant rows (consistent on it) disagree by as much;
    /// the same formula on both sides of any threshold keeps q̈ and its derivatives smooth, and
    /// a linearization that refused what its prediction took would fail where the prediction
    /// did not.
    pub fn stage(formulation: Formulation) -> Self {
        DynamicsOptions {
            formulation: match formulation {
                Formulation::Embedded => Formulation::Embedded,
                _ => Formulation::Multipliers,
            },
            allow_inconsistent: true,
            rows_evaluated: false,
        }
    }
}

impl Default for DynamicsOptions {
    fn default() -> Self {
        DynamicsOptions {
            formulation: Formulation::Multipliers,
            allow_inconsistent: false,
            rows_evaluated: false,
        }
    }
}

/// Model + constraints + workspaces.
#[derive(Clone, Debug)]
pub struct System {
    /// The robot model, shared with the scene and every other system built from it.
    pub model: Arc<Model>,
    /// The validated constraints.
    pub constraints: ConstraintSet,
    /// Baumgarte stabilisation gains.
    pub baumgarte: Baumgarte,
    /// Formulation asked for by the scene.
    pub formulation: Formulation,
    /// Kinematics and dynamics workspace.
    pub data: Data,
    /// Constraint rows (J, φ, γ, J v) at the last evaluation.
    pub cdata: ConstraintData,
    /// Multiplier-form workspace; λ of the last multiplier solve.
    pub kkt: KktWorkspace,
    /// Embedded-form workspace.
    pub embedded: EmbeddedWorkspace,
    /// Which formulation produced the last result.
    pub last_formulation: Formulation,
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
        Self {
            model,
            constraints,
            baumgarte,
            formulation,
            data,
            cdata,
            kkt,
            embedded,
            last_formulation: Formulation::Multipliers,
        }
    }

    /// Constrained forward dynamics at (q, v, τ); `want_forces` forces the multiplier form under
    /// `Formulation::Auto`. Returns q̈ (nv); λ is in `self.kkt.lambda` when multipliers were used.
    pub fn forward_dynamics(
        &mut self,
        q: &[f64],
        v: &[f64],
        tau: &[f64],
        want_forces: bool,
    ) -> Result<&DVector<f64>> {
        let formulation = match self.formulation {
            Formulation::Auto if want_forces || self.constraints.is_empty() => {
                Formulation::Multipliers
            }
            Formulation::Auto => Formulation::Embedded,
            f => f,
        };
        self.forward_dynamics_with(
            q,
            v,
            tau,
            DynamicsOptions {
                formulation,
                ..Default::default()
            },
        )
    }

    /// Constrained forward dynamics at (q, v, τ) with the options of this one call (the
    /// system's own `formulation` is not consulted). Returns q̈ (nv); λ is in `self.kkt.lambda`
    /// when multipliers were used.
    pub fn forward_dynamics_with(
        &mut self,
        q: &[f64],
        v: &[f64],
        tau: &[f64],
        opts: DynamicsOptions,
    ) -> Result<&DVector<f64>> {
        self.model.check_state(q, v)?;
        check_len("tau", tau, self.model.nv)?;
        crate::error::check_finite("tau", tau)?;
        let use_multipliers = match opts.formulation {
            Formulation::Multipliers | Formulation::Auto => true,
            Formulation::Embedded => false,
        };
        if use_multipliers {
            constrained_forward_dynamics(
                &self.model,
                &mut self.data,
                &self.constraints,
                &mut self.cdata,
                &mut self.kkt,
                q,
                v,
                tau,
                KktOptions {
                    gains: self.baumgarte,
                    allow_inconsistent: opts.allow_inconsistent,
                    rows_evaluated: opts.rows_evaluated,
                },
            )?;
            self.last_formulation = Formulation::Multipliers;
            Ok(&self.kkt.qdd)
        } else {
            embedded_forward_dynamics(
                &self.model,
                &mut self.data,
                &self.constraints,
                &mut self.cdata,
                &mut self.embedded,
                q,
                v,
                tau,
                self.baumgarte,
            )?;
            self.last_formulation = Formulation::Embedded;
            Ok(&self.embedded.qdd)
        }
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
