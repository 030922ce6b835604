//! A diff drive's traction with load transfer: a common-mode wheel torque accelerates the base,
//! which pitches onto its caster or skid and takes weight off the wheels, so both wheels' clamps
//! fall together; a pure turn keeps them.

use super::{Actuators, Pi};

impl Actuators {
    /// The diff drive's wheels (indices into `velocity`) and their common traction limit [N·m]
    /// for the raw torques `raw(k, controller)` gives, where a load transfer is declared.
    pub(super) fn wheel_limits(
        &self,
        raw: impl Fn(usize, &Pi) -> f64,
    ) -> Option<(usize, usize, f64)> {
        let (il, ir, _, _) = self.diff_drive?;
        let (t, kappa) = self.traction;
        if kappa <= 0.0 {
            return None;
        }
        let (ul, ur) = (raw(il, &self.velocity[il]), raw(ir, &self.velocity[ir]));
        Some((il, ir, coupled_limit(ul, ur, t, kappa)))
    }
}

/// Controller `k`'s effort bound under `limits` ([`Actuators::wheel_limits`]).
pub(super) fn effort(limits: Option<(usize, usize, f64)>, k: usize, effort: f64) -> f64 {
    match limits {
        Some((il, ir, l)) if k == il || k == ir => effort.min(l),
        _ => effort,
    }
}

/// The wheels' common traction limit L [N·m] for raw torques (u_l, u_r): the L with
/// L = t − κ |τ_l + τ_r|/2, τ_i = clamp(u_i, ±L). The wheels share the weight the pitch moves,
/// so they share the limit. Solved case by case: both inside, both clamped alike
/// (L = t/(1 + κ)), both clamped opposite (τ_c = 0, L = t), or one clamped at s L beside a free
/// u_j (L = (t − κ σ u_j/2)/(1 + κ σ s/2), σ the sign of τ_c).
pub fn coupled_limit(u_l: f64, u_r: f64, t: f64, kappa: f64) -> f64 {
    if kappa <= 0.0 {
        return t;
    }
    let free = t - kappa * (0.5 * (u_l + u_r)).abs();
    if u_l.abs() <= free && u_r.abs() <= free {
        return free;
    }
    if u_l.signum() == u_r.signum() {
        let l = t / (1.0 + kappa);
        if u_l.abs() >= l && u_r.abs() >= l {
            return l;
        }
    } else if u_l.abs() >= t && u_r.abs() >= t {
        return t;
    }
    for (ui, uj) in [(u_l, u_r), (u_r, u_l)] {
        let s = ui.signum();
        for sigma in [1.0, -1.0] {
            let l = (t - kappa * sigma * uj / 2.0) / (1.0 + kappa * sigma * s / 2.0);
            let c = s * l + uj;
            if l > 0.0 && (c == 0.0 || c.signum() == sigma) && uj.abs() <= l && ui.abs() >= l {
                return l;
            }
        }
    }
    // Every (u_l, u_r) falls in one case above; the least limit is the safe answer regardless.
    t / (1.0 + kappa)
}

#[cfg(test)]
mod tests {
    use super::coupled_limit;

    /// The limit solves its own definition: L = t − κ |clamp(u_l, ±L) + clamp(u_r, ±L)|/2.
    #[test]
    fn the_coupled_limit_solves_its_definition() {
        let (t, kappa) = (2.0, 0.8);
        let mut n = 0;
        for i in -20..=20 {
            for j in -20..=20 {
                let (ul, ur) = (0.37 * i as f64, 0.29 * j as f64);
                let l = coupled_limit(ul, ur, t, kappa);
                let c = 0.5 * (ul.clamp(-l, l) + ur.clamp(-l, l));
                assert!(
                    (l - (t - kappa * c.abs())).abs() < 1e-12,
                    "({ul}, {ur}): L {l}"
                );
                n += 1;
            }
        }
        assert_eq!(n, 41 * 41);
        // Both pushing forward beyond it: t/(1 + κ); a pure turn: t.
        assert_eq!(coupled_limit(9.0, 7.0, t, kappa), t / (1.0 + kappa));
        assert_eq!(coupled_limit(-9.0, 7.0, t, kappa), t);
        assert_eq!(coupled_limit(9.0, 7.0, t, 0.0), t);
    }
}
