//! Where P is brought onto the constraints, and what a sample reads.
//!
//! The linearized steps keep P on the constraints only to their accuracy (the noise terms
//! enter on them: mod.rs), so how often the running P is projected could change it, and a
//! node would publish another covariance when its monitor reads the intermediate horizons. The
//! running P is therefore projected at a cadence of its own — every [`PROJECTION_STEPS`]
//! recorded steps from the start — and a read takes a projected copy: P at a time is the same
//! whichever other times are read (tests/it/live_prediction.rs).

use super::CovariancePropagator;
use super::chunks::{CHUNK_CAPACITY, StepRecord};
use super::{congruence, symmetrize};
use crate::error::Result;
use crate::system::System;
use nalgebra::DMatrix;

/// Recorded steps between two projections of the running P: a full record's, where a
/// prediction read only at its horizon has always projected it.
pub(crate) const PROJECTION_STEPS: usize = CHUNK_CAPACITY;

/// The last read, and where the running P stands.
#[derive(Clone, Debug)]
pub(in crate::predict) struct Reading {
    /// P at the last read, on the constraints (2nv × 2nv).
    pub(in crate::predict) p: DMatrix<f64>,
    /// Steps applied to the running P since it was last projected.
    since_projection: usize,
    /// The state the running P stands at: the last flushed step's end (time [s], q, v).
    t: f64,
    q: Vec<f64>,
    v: Vec<f64>,
}

impl Reading {
    pub fn new(sys: &System) -> Self {
        let (nq, nv) = (sys.model().nq, sys.model().nv);
        Self {
            p: DMatrix::zeros(2 * nv, 2 * nv),
            since_projection: 0,
            t: 0.0,
            q: vec![0.0; nq],
            v: vec![0.0; nv],
        }
    }
}

impl CovariancePropagator {
    /// The start: P, already projected at (t, q, v), is what a read there gives.
    pub(super) fn start_reading(&mut self, (t, q, v): (f64, &[f64], &[f64])) {
        let r = &mut self.reading;
        r.p.copy_from(&self.p);
        r.since_projection = 0;
        r.t = t;
        r.q.copy_from_slice(q);
        r.v.copy_from_slice(v);
    }

    /// `m` more recorded steps applied to P, ending at the record's state `hi`: P is
    /// projected there when [`PROJECTION_STEPS`] have been since it last was.
    pub(super) fn applied(
        &mut self,
        sys: &mut System,
        rec: &StepRecord,
        hi: usize,
        m: usize,
    ) -> Result<()> {
        self.reading.since_projection += m;
        if self.reading.since_projection >= PROJECTION_STEPS {
            self.project(sys, rec.time(hi), &rec.q[hi], &rec.v[hi])?;
            self.reading.since_projection = 0;
        }
        Ok(())
    }

    /// After a flush of `rec`: the state P stands at, and with `read` the read, P projected
    /// there (P itself where it was just projected).
    pub(super) fn after_flush(
        &mut self,
        sys: &mut System,
        rec: &StepRecord,
        read: bool,
    ) -> Result<()> {
        let n = rec.len();
        if n > 0 {
            let r = &mut self.reading;
            r.t = rec.time(n);
            r.q.copy_from_slice(&rec.q[n]);
            r.v.copy_from_slice(&rec.v[n]);
        }
        if !read {
            return Ok(());
        }
        self.reading.p.copy_from(&self.p);
        if self.reading.since_projection == 0 {
            return Ok(());
        }
        // The state leaves the reading while T is formed there (disjoint borrows).
        let (q, v) = (
            std::mem::take(&mut self.reading.q),
            std::mem::take(&mut self.reading.v),
        );
        let projected = self.projector(sys, self.reading.t, &q, &v);
        (self.reading.q, self.reading.v) = (q, v);
        if projected? {
            congruence(&mut self.reading.p, &self.proj, &mut self.tmp);
            symmetrize(&mut self.reading.p);
        }
        Ok(())
    }
}
