//! A state of one robot model in the coordinates of another model of the same robot (a variant
//! scene: other limits, a planar base where the other floats, a payload), matched by name.

use super::Model;
use crate::error::{Error, Result};

/// Where each joint coordinate of a target model comes from in a source model: the base through
/// its pose and twist, every other coordinate by name. Built once per pair of models.
#[derive(Clone, Debug, PartialEq)]
pub struct StateMap {
    /// (target q index, source q index) of every joint position coordinate.
    q: Vec<(usize, usize)>,
    /// (target v index, source v index) of every joint velocity coordinate.
    v: Vec<(usize, usize)>,
}

impl StateMap {
    /// The map from `source`'s state to `target`'s: every joint coordinate of `target` must be
    /// one of `source`'s, by name (an error names the first that is not).
    pub fn new(source: &Model, target: &Model) -> Result<Self> {
        let pairs = |names: &[String], theirs: &[String], skip: usize, what: &str| {
            names
                .iter()
                .enumerate()
                .skip(skip)
                .map(|(i, n)| match theirs.iter().position(|t| t == n) {
                    Some(j) => Ok((i, j)),
                    None => Err(Error::Invalid(format!(
                        "its {what} coordinate '{n}' is not one of the other model's ({})",
                        theirs.join(", ")
                    ))),
                })
                .collect::<Result<Vec<_>>>()
        };
        Ok(StateMap {
            q: pairs(
                &target.q_names,
                &source.q_names,
                target.base.nq(),
                "position",
            )?,
            v: pairs(
                &target.v_names,
                &source.v_names,
                target.base.nv(),
                "velocity",
            )?,
        })
    }

    /// `source`'s state (q, v) in `target`'s coordinates, into (`q_out`, `v_out`). What the
    /// source cannot say is kept from `q_out` (a floating base's height where the source's base
    /// is planar); velocities it cannot say are zero. Allocates nothing.
    pub fn apply(
        &self,
        (source, target): (&Model, &Model),
        (q, v): (&[f64], &[f64]),
        (q_out, v_out): (&mut [f64], &mut [f64]),
    ) {
        let mut pose = source.base_pose(q);
        let twist = source.base_twist(v);
        if source.base.nq() < target.base.nq() {
            pose.position[2] = target.base_pose(q_out).position[2];
        }
        v_out.iter_mut().for_each(|x| *x = 0.0);
        target.set_base(&pose, &twist, q_out, v_out);
        for &(i, j) in &self.q {
            q_out[i] = q[j];
        }
        for &(i, j) in &self.v {
            v_out[i] = v[j];
        }
    }
}
