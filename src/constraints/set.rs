//! The constraints of a scene, stacked: their row ranges and evaluation (each declaration is
//! checked and built in [`super::build`]).

use super::build::{build_one, coupling};
use super::{
    ConstraintKind, ConstraintRows, ConstraintSpec, CouplingConstraint, DistanceConstraint,
    NoSideSlipConstraint, PointConstraint, RollingConstraint, RowSink, VelocityConstraint,
    WeldConstraint,
};
use crate::algorithm::{Data, forward_kinematics_bias, forward_kinematics_pos};
use crate::error::{Error, Result};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};
use std::ops::Range;

/// A constraint of one of the supported kinds (static dispatch).
#[derive(Clone, Debug)]
pub enum Constraint {
    /// Point of one frame held at a point of another (or the world).
    Point(PointConstraint),
    /// Relative pose of two frames fixed.
    Weld(WeldConstraint),
    /// Distance between two frame points fixed.
    Distance(DistanceConstraint),
    /// Linear relation `a·q_i + b·q_j = c` between two 1-DOF joints.
    Coupling(CouplingConstraint),
    /// Wheel rolling without slipping on a plane.
    Rolling(RollingConstraint),
    /// Knife edge: no velocity of a frame origin along an axis.
    NoSideSlip(NoSideSlipConstraint),
    /// f(q, v, t) = 0 written as an expression.
    Velocity(VelocityConstraint),
}

impl Constraint {
    pub(super) fn rows(&self) -> &dyn ConstraintRows {
        match self {
            Constraint::Point(c) => c,
            Constraint::Weld(c) => c,
            Constraint::Distance(c) => c,
            Constraint::Coupling(c) => c,
            Constraint::Rolling(c) => c,
            Constraint::NoSideSlip(c) => c,
            Constraint::Velocity(c) => c,
        }
    }

    /// The constraint's kind (its name is the scene file's `kind:`).
    pub fn kind(&self) -> ConstraintKind {
        match self {
            Constraint::Point(_) => ConstraintKind::Point,
            Constraint::Weld(_) => ConstraintKind::Weld,
            Constraint::Distance(_) => ConstraintKind::Distance,
            Constraint::Coupling(_) => ConstraintKind::Coupling,
            Constraint::Rolling(_) => ConstraintKind::Rolling,
            Constraint::NoSideSlip(_) => ConstraintKind::NoSideSlip,
            Constraint::Velocity(_) => ConstraintKind::Velocity,
        }
    }
}

/// The scene's constraints with their row ranges.
#[derive(Clone, Debug, Default)]
pub struct ConstraintSet {
    /// Constraint names (scene `name:`, or `mimic:<joint>`), in stacking order.
    pub names: Vec<String>,
    /// The constraints, in the same order as `names`.
    pub items: Vec<Constraint>,
    /// Rows of constraint k in the stacked J, φ, γ, λ.
    pub ranges: Vec<Range<usize>>,
    /// Total number of rows (nc).
    pub nrows: usize,
}

/// Workspace and results of `ConstraintSet::evaluate` (allocated once).
#[derive(Clone, Debug)]
pub struct ConstraintData {
    /// nc × nv Jacobian: J v is the constraint velocity.
    pub j: DMatrix<f64>,
    /// Position residual φ(q), nc (0 on nonholonomic rows).
    pub phi: DVector<f64>,
    /// γ = J̇ v, nc.
    pub gamma: DVector<f64>,
    /// Velocity residual, nc: J v, or f(q, v, t) on `velocity` rows (nonlinear in v).
    pub jv: DVector<f64>,
    /// Time [s] of the last evaluation, recorded by [`ConstraintSet::evaluate`] and
    /// [`ConstraintSet::residuals`] from their argument (0 before any).
    pub t: f64,
    /// Rows whose kind wrote its own velocity residual.
    pub(crate) residual_given: Vec<bool>,
    /// The given residuals of those rows while J v is summed by columns (nc).
    jv_given: Vec<f64>,
    /// Row is holonomic (has a position-level residual).
    pub holonomic: Vec<bool>,
    pub(crate) j3: DMatrix<f64>,
    pub(crate) jtmp: DMatrix<f64>,
    pub(crate) j6: DMatrix<f64>,
}

impl ConstraintData {
    /// Size the workspace for the model (nv) and constraint set (nc).
    pub fn new(model: &Model, set: &ConstraintSet) -> Self {
        let (nc, nv) = (set.nrows, model.nv);
        Self {
            j: DMatrix::zeros(nc, nv),
            phi: DVector::zeros(nc),
            gamma: DVector::zeros(nc),
            jv: DVector::zeros(nc),
            t: 0.0,
            residual_given: vec![false; nc],
            jv_given: vec![0.0; nc],
            holonomic: vec![true; nc],
            j3: DMatrix::zeros(3, nv),
            jtmp: DMatrix::zeros(3, nv),
            j6: DMatrix::zeros(6, nv),
        }
    }
}

impl ConstraintSet {
    /// Validate the declarations against the model (frames and joints must exist) and add one
    /// coupling per URDF `<mimic>` between movable joints. `q_ref` (a configuration of the scene)
    /// decides geometric questions: a wheel axis parallel to the plane normal is refused, and a
    /// rolling contact's normal row is kept only if the model can move the contact along it.
    pub fn new(model: &Model, specs: &[ConstraintSpec], q_ref: &[f64]) -> Result<ConstraintSet> {
        model.check_state(q_ref, &vec![0.0; model.nv])?;
        let mut data = Data::new(model);
        forward_kinematics_pos(model, &mut data, q_ref);
        let mut set = ConstraintSet::default();
        for spec in specs {
            let name = spec.name().to_string();
            if set.names.contains(&name) {
                return Err(Error::Constraint {
                    name,
                    message: "duplicate constraint name".into(),
                });
            }
            let c = build_one(model, &data, spec)?;
            set.push(name, c);
        }
        for m in &model.mimics {
            let (Ok(bi), Ok(bj)) = (model.joint_body(&m.joint), model.joint_body(&m.mimicked))
            else {
                continue; // a locked joint: the reduced model already fixes it
            };
            let c = coupling(model, bi, bj, 1.0, -m.multiplier, m.offset);
            set.push(format!("mimic:{}", m.joint), c);
        }
        Ok(set)
    }

    fn push(&mut self, name: String, c: Constraint) {
        let d = c.rows().dim();
        self.ranges.push(self.nrows..self.nrows + d);
        self.nrows += d;
        self.names.push(name);
        self.items.push(c);
    }

    /// True when there are no constraints.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Index of a constraint by name.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Row names `constraint/row` in stacked order.
    pub fn row_names(&self) -> Vec<String> {
        let mut out = vec![];
        for (k, c) in self.items.iter().enumerate() {
            for r in super::forces::row_labels(c) {
                out.push(format!("{}/{}", self.names[k], r));
            }
        }
        out
    }

    /// Kinematics at (q, v, q̈ = 0), then J, φ, γ and J v of every row at time `t` [s] (what
    /// `velocity` rows f(q, v, t) read) into `cd`, which records `t`.
    pub fn evaluate(
        &self,
        model: &Model,
        data: &mut Data,
        cd: &mut ConstraintData,
        t: f64,
        q: &[f64],
        v: &[f64],
    ) {
        cd.t = t;
        forward_kinematics_bias(model, data, q, v);
        self.fill_rows(model, data, cd, q, v);
        // J v column by column over J's column-major storage (contiguous), each row's sum in
        // the order of its columns; the rows whose kind gave its own residual keep it.
        let (nr, j) = (cd.j.nrows(), cd.j.as_slice());
        if nr == 0 {
            return;
        }
        let jv = &mut cd.jv.as_mut_slice()[..nr];
        let given = &cd.residual_given[..nr];
        let kept = &mut cd.jv_given[..nr];
        for ((k, &g), &x) in kept.iter_mut().zip(given).zip(jv.iter()) {
            if g {
                *k = x;
            }
        }
        jv.fill(0.0);
        for (col, &x) in j.chunks_exact(nr).zip(v) {
            for (s, &a) in jv.iter_mut().zip(col) {
                *s += a * x;
            }
        }
        for ((s, &g), &k) in jv.iter_mut().zip(given).zip(kept.iter()) {
            if g {
                *s = k;
            }
        }
    }

    /// The first row with a non-finite J entry, γ or velocity residual (an expression
    /// evaluated where it is undefined, e.g. √ at 0 in its derivative), as an error naming
    /// the constraint.
    pub fn check_finite(&self, cd: &ConstraintData) -> Result<()> {
        // The hot loop's case in one contiguous pass; the row is located only on failure.
        let finite = |x: &f64| x.is_finite();
        if [cd.j.as_slice(), cd.gamma.as_slice(), cd.jv.as_slice()]
            .iter()
            .all(|s| s.iter().all(finite))
        {
            return Ok(());
        }
        for (k, rg) in self.ranges.iter().enumerate() {
            for r in rg.clone() {
                let bad = !(cd.gamma[r].is_finite() && cd.jv[r].is_finite())
                    || cd.j.row(r).iter().any(|x| !x.is_finite());
                if bad {
                    return Err(Error::Constraint {
                        name: self.names[k].clone(),
                        message: format!(
                            "non-finite row at t = {} s (f = {}, γ = {}): the constraint is \
                             not differentiable at this state",
                            cd.t, cd.jv[r], cd.gamma[r]
                        ),
                    });
                }
            }
        }
        Ok(())
    }

    /// J, φ, γ (and f on `velocity` rows) from an existing kinematics pass (no J v).
    pub(crate) fn fill_rows(
        &self,
        model: &Model,
        data: &Data,
        cd: &mut ConstraintData,
        q: &[f64],
        v: &[f64],
    ) {
        for (k, c) in self.items.iter().enumerate() {
            let mut sink = RowSink {
                q,
                v,
                t: cd.t,
                jv: &mut cd.jv,
                residual_given: &mut cd.residual_given,
                row0: self.ranges[k].start,
                j: &mut cd.j,
                phi: &mut cd.phi,
                gamma: &mut cd.gamma,
                holonomic: &mut cd.holonomic,
                j3: &mut cd.j3,
                jtmp: &mut cd.jtmp,
                j6: &mut cd.j6,
            };
            c.rows().fill(model, data, &mut sink);
        }
    }
}
