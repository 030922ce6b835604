//! Constrained forward dynamics of a [`System`]: q̈ (and λ in the multiplier form) at
//! (q, v, τ), by the path the model and the options choose — ABA on a tree without rows or in
//! the multiplier form where it is linear-time, else the dense multiplier or embedded form.

use super::System;
use crate::dynamics::{
    Baumgarte, Formulation, KktOptions, constrained_forward_dynamics, embedded_forward_dynamics,
    tree_constrained_forward_dynamics, tree_forward_dynamics,
};
use crate::error::{Result, check_len};
use nalgebra::DVector;

/// How one dynamics evaluation is done (passed in, never toggled on the system around a call).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DynamicsOptions {
    /// Time [s] of the evaluation: what `velocity` rows f(q, v, t) read (default 0).
    pub t: f64,
    /// Multipliers (λ and the constraint forces) or the embedded, multiplier-free form;
    /// `Auto` means multipliers here.
    pub formulation: Formulation,
    /// Multiplier form: accept acceleration rows that cannot all be met (redundant rows that
    /// disagree by drift, at or next to a singular configuration) with the least-squares
    /// λ = S⁺ r, instead of an error. The predictor's stages ask for it.
    pub allow_inconsistent: bool,
    /// Multiplier form: the kinematics in `data` and the rows in `cdata` are those of this
    /// (q, v) at `t` — `ConstraintSet::evaluate` ran there and nothing has written them
    /// since — so that pass is skipped. The predictor sets it for a step's first stage when its
    /// drift projection evaluated the rows at that state and left it unchanged. Default false.
    pub rows_evaluated: bool,
    /// Baumgarte gains of this evaluation; `None`: the system's (the scene's `dynamics:`).
    pub gains: Option<Baumgarte>,
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
            gains: None,
            t: 0.0,
        }
    }

    /// The same options at time `t` [s].
    pub fn at(self, t: f64) -> Self {
        DynamicsOptions { t, ..self }
    }
}

impl Default for DynamicsOptions {
    fn default() -> Self {
        DynamicsOptions {
            formulation: Formulation::Multipliers,
            allow_inconsistent: false,
            rows_evaluated: false,
            gains: None,
            t: 0.0,
        }
    }
}

impl System {
    /// Constrained forward dynamics at (q, v, τ); `want_forces`, and a tree that takes the linear
    /// path, choose the multiplier form under `Formulation::Auto`. Returns q̈ (nv); λ is [`System::lambda`] when multipliers were used.
    pub fn forward_dynamics(
        &mut self,
        q: &[f64],
        v: &[f64],
        tau: &[f64],
        want_forces: bool,
    ) -> Result<&DVector<f64>> {
        let formulation = match self.formulation {
            // On a large tree the multiplier form goes without M (O(n)); the embedded form
            // forms and factors the independent block of M.
            Formulation::Auto if want_forces || self.constraints.is_empty() || self.linear => {
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
    /// system's own `formulation` is not consulted). Returns q̈ (nv); λ is [`System::lambda`]
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
        let kkt_options = KktOptions {
            t: opts.t,
            gains: opts.gains.unwrap_or(self.baumgarte),
            allow_inconsistent: opts.allow_inconsistent,
            rows_evaluated: opts.rows_evaluated,
        };
        if self.linear && self.constraints.is_empty() {
            let tree = self.tree.tree();
            if tree_forward_dynamics(&self.model, &mut self.data, tree, q, v, tau) {
                return Ok(self.unconstrained_result(opts.t, use_multipliers));
            }
        } else if self.linear
            && use_multipliers
            && tree_constrained_forward_dynamics(
                &self.model,
                &mut self.data,
                &self.constraints,
                &mut self.cdata,
                &mut self.kkt,
                &mut self.tree,
                q,
                v,
                tau,
                kkt_options,
            )?
        {
            self.last_formulation = Formulation::Multipliers;
            return Ok(&self.kkt.qdd);
        }
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
                kkt_options,
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
                opts.t,
                opts.gains.unwrap_or(self.baumgarte),
            )?;
            self.last_formulation = Formulation::Embedded;
            Ok(&self.embedded.qdd)
        }
    }

    /// The linear-time path's q̈ (in `data.qdd`) as the result of the form asked for: λ empty,
    /// no generalized constraint force, every velocity independent. M and h are not computed
    /// ([`System::terms_at`] computes them).
    fn unconstrained_result(&mut self, t: f64, use_multipliers: bool) -> &DVector<f64> {
        self.cdata.t = t;
        if use_multipliers {
            let ws = &mut self.kkt;
            ws.qdd.copy_from(&self.data.qdd);
            ws.generalized_force.fill(0.0);
            ws.rank_deficiency = 0;
            ws.augmented = false;
            ws.inconsistency = 0.0;
            self.last_formulation = Formulation::Multipliers;
            &self.kkt.qdd
        } else {
            let ws = &mut self.embedded;
            ws.qdd.copy_from(&self.data.qdd);
            ws.partition.independent.clear();
            ws.partition.independent.extend(0..self.model.nv);
            ws.partition.dependent.clear();
            ws.partition.rows.clear();
            self.last_formulation = Formulation::Embedded;
            &self.embedded.qdd
        }
    }
}
