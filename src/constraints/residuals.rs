//! The residuals a sample reports — max |φ| over holonomic rows and max |J v| — straight from
//! placements and twists where every kind can say its rows' φ and J v without forming J and γ
//! (points, rolling wheels, knife edges), else through the full evaluation.

use super::{ConstraintData, ConstraintSet, RowResiduals};
use crate::algorithm::{Data, forward_kinematics_vel};
use crate::model::Model;

impl ConstraintSet {
    /// (max |φ| over holonomic rows [m or rad], max |J v| [m/s or rad/s]) at (q, v, t),
    /// with each row's φ, J v and holonomic flag in `cd` and the placements and body twists of
    /// (q, v) in `data` (what the energies read). J and γ are left as they were when every kind
    /// has the shortcut; a kind without it costs one more kinematics pass ([`Self::evaluate`]).
    pub fn residuals(
        &self,
        model: &Model,
        data: &mut Data,
        cd: &mut ConstraintData,
        t: f64,
        q: &[f64],
        v: &[f64],
    ) -> (f64, f64) {
        cd.t = t;
        forward_kinematics_vel(model, data, q, v);
        let direct = self.items.iter().zip(&self.ranges).all(|(c, r)| {
            let out = RowResiduals {
                phi: &mut cd.phi.as_mut_slice()[r.clone()],
                jv: &mut cd.jv.as_mut_slice()[r.clone()],
                holonomic: &mut cd.holonomic[r.clone()],
            };
            c.rows().residuals(model, data, out)
        });
        if !direct {
            self.evaluate(model, data, cd, t, q, v);
        }
        let rows = 0..self.nrows;
        let position = (rows.clone().filter(|&k| cd.holonomic[k]))
            .map(|k| cd.phi[k].abs())
            .fold(0.0, f64::max);
        let velocity = rows.map(|k| cd.jv[k].abs()).fold(0.0, f64::max);
        (position, velocity)
    }
}
