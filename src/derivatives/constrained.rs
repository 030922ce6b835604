//! Derivatives of the constrained forward dynamics (multiplier form); the method is in the
//! module doc of [`crate::derivatives`], each kind's part in rows.rs, the solve in kkt.rs.
//!
//! Every constraint kind has derivatives: point, weld (world and local axes), distance,
//! coupling/mimic, rolling and no-side-slip.

use super::rnea::rnea_derivatives_after_bias;
use super::{DerivativeData, kkt, rows};
use crate::algorithm::Data;
use crate::constraints::{ConstraintData, ConstraintSet};
use crate::dynamics::{KktOptions, KktWorkspace, constrained_forward_dynamics};
use crate::error::{Error, Result};
use crate::linalg::ltl_inverse;
use crate::model::Model;

/// Solves the constrained dynamics at (q, v, τ) (q̈ in `ws.qdd` and `dd.qdd`, λ in
/// `ws.lambda`) and writes ∂q̈/∂(q, v, τ) into `dd.dqdd_dq`, `dd.dqdd_dv`, `dd.dqdd_dtau` and
/// ∂λ/∂(q, v, τ) into `dd.dlambda_dq`, `dd.dlambda_dv`, `dd.dlambda_dtau`. `dd` must be sized
/// for `set.nrows` rows.
#[allow(clippy::too_many_arguments)]
pub fn constrained_dynamics_derivatives(
    model: &Model,
    data: &mut Data,
    set: &ConstraintSet,
    cd: &mut ConstraintData,
    ws: &mut KktWorkspace,
    dd: &mut DerivativeData,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    opts: impl Into<KktOptions>,
) -> Result<()> {
    let opts = opts.into();
    let stab = opts.gains;
    let nc = set.nrows;
    if dd.dlambda_dq.nrows() != nc {
        return Err(Error::Dimension {
            what: "DerivativeData constraint rows".into(),
            expected: nc,
            got: dd.dlambda_dq.nrows(),
        });
    }
    for (k, c) in set.items.iter().enumerate() {
        if !rows::supported(c) {
            return Err(Error::Unsupported {
                what: format!("derivatives of constraint '{}'", set.names[k]),
                why: format!("kind {} has no analytic derivatives yet", c.kind()),
            });
        }
    }
    constrained_forward_dynamics(model, data, set, cd, ws, q, v, tau, opts)?;
    dd.qdd.copy_from(&ws.qdd);

    // λ as forces on the bodies (the kinematics of the solve are still in `data`).
    rows::register_constraint_forces(model, data, set, ws.lambda.as_slice(), dd);
    // The forward dynamics left its bias pass in `data` (kinematics at (q, v, q̈ = 0), h).
    let qdd = std::mem::take(&mut dd.qdd);
    rnea_derivatives_after_bias(model, data, dd, qdd.as_slice());
    dd.qdd = qdd;
    rows::force_corrections(model, data, set, ws.lambda.as_slice(), dd);
    // M⁻¹ from the forward dynamics' LTL factor of M where it took one (M is still in `data`
    // for the augmented case: nothing since wrote it).
    if ws.augmented {
        kkt::invert_mass_or_augmented(model, data, cd, dd)?;
    } else {
        dd.rho = 0.0;
        ltl_inverse(
            &ws.l,
            ws.l_inv_diag.as_slice(),
            &model.v_parent,
            &model.v_subtree_end,
            &mut dd.chol,
            &mut dd.minv,
        );
    }
    rows::row_derivatives(model, data, set, cd, dd, stab);
    kkt::solve_kkt_derivatives(cd, dd);
    Ok(())
}
