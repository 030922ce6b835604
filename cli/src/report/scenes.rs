//! The benchmark scenes of the report: what runs, over which horizon, against which reference,
//! and which sweep each integrator gets.

use super::closed_forms::{Modes, a01_position, chain_mass, parallelogram_angle, wrap};
use constraint_dynamics::predict::{DriftControl, Method, Sample};
use nalgebra::{DMatrix, DVector};

/// What the report calls the constraint drift of a scene.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum DriftMeasure {
    /// No constraints: no drift plot.
    None,
    /// max |φ| over the holonomic rows [m].
    Position,
    /// max |J v| [m/s].
    Velocity,
}

/// How the error of a run is measured.
pub enum Reference {
    /// Error of a sample against a closed form (max over the samples is reported).
    ClosedForm(Box<dyn Fn(&Sample) -> f64>),
    /// A tighter solution by another method: dopri5 (rtol = atol = 1e-13, projection) for the
    /// fixed-step rows and RK4 at `rk4_dt` (projection) for the dopri5 rows.
    Numerical { rk4_dt: f64 },
}

/// One line of a work-precision diagram: a method, its drift control and its sweep.
#[derive(Clone)]
pub struct Line {
    pub method: Method,
    pub drift: DriftControl,
    /// Fixed-step methods: the steps [s]; dopri5: the tolerances rtol (= atol).
    pub sweep: Vec<f64>,
}

impl Line {
    pub fn label(&self) -> String {
        let m = match self.method {
            Method::SemiImplicitEuler => "sie",
            Method::Rk4 => "rk4",
            Method::Dopri5 => "dopri5",
            Method::Sdirk2 => "sdirk2",
            Method::Radau5 => "radau5",
        };
        match self.drift {
            DriftControl::None => format!("{m}/none"),
            DriftControl::Baumgarte => format!("{m}/baumgarte"),
            DriftControl::Projection => format!("{m}/projection"),
        }
    }
}

pub struct Bench {
    pub key: &'static str,
    pub title: &'static str,
    /// Scene file relative to the repository.
    pub scene: &'static str,
    pub horizon: f64,
    pub reference: Reference,
    /// What the error column measures, with units.
    pub error_metric: &'static str,
    pub reference_text: String,
    pub drift: DriftMeasure,
    pub lines: Vec<Line>,
}

/// Steps dt0, dt0/2, … (`n` of them).
fn halvings(dt0: f64, n: usize) -> Vec<f64> {
    (0..n).map(|j| dt0 / 2f64.powi(j as i32)).collect()
}

/// The lines of a scene: SIE, RK4, SDIRK2 from their largest steps, DOPRI5 over tolerances; with
/// constraints, RK4 and SIE also without drift control and with Baumgarte, DOPRI5 also without.
fn lines(constrained: bool, sie: f64, rk4: f64, sdirk2: f64, quick: bool) -> Vec<Line> {
    let n = if quick { 3 } else { 5 };
    let tols = if quick {
        vec![1e-5, 1e-8, 1e-11]
    } else {
        vec![1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
    };
    let line = |method, drift, sweep| Line {
        method,
        drift,
        sweep,
    };
    let p = if constrained {
        DriftControl::Projection
    } else {
        DriftControl::None
    };
    let mut out = vec![
        line(Method::SemiImplicitEuler, p, halvings(sie, n)),
        line(Method::Rk4, p, halvings(rk4, n)),
        line(Method::Sdirk2, p, halvings(sdirk2, n)),
        line(Method::Dopri5, p, tols.clone()),
    ];
    if constrained {
        for d in [DriftControl::None, DriftControl::Baumgarte] {
            out.push(line(Method::Rk4, d, halvings(rk4, n)));
            out.push(line(Method::SemiImplicitEuler, d, halvings(sie, n)));
        }
        out.push(line(Method::Dopri5, DriftControl::None, tols));
    }
    out
}

const NUMERICAL: &str = "tighter solution by another method: dopri5 rtol = atol = 1e-13 with \
                         projection for the fixed-step rows, RK4 at a small step with projection \
                         for the dopri5 rows";

/// Every benchmark scene, full or quick.
pub fn benches(quick: bool) -> Vec<Bench> {
    let h = |full: f64, short: f64| if quick { short } else { full };
    let mut out = vec![];
    out.push(Bench {
        key: "a01_pendulum",
        title: "IFToMM A01 simple pendulum (1 kg point mass, 1 m, released horizontal)",
        scene: "params/pendulum_a01.yaml",
        horizon: h(2000.0, 20.0),
        reference: Reference::ClosedForm(Box::new(|s: &Sample| {
            let (x, z) = a01_position(s.t);
            (s.q[0].cos() - x).hypot(-s.q[0].sin() - z)
        })),
        error_metric: "max over the samples of |P − P_ref|, the mass position [m]",
        reference_text: "closed form sin(θ/2) = k sn(K(k) − ω₀t; k), k = sin(π/4), ω₀ = √(g/L) \
                         (sn and K by the arithmetic-geometric mean)"
            .into(),
        drift: DriftMeasure::None,
        lines: {
            let mut l = lines(false, 0.01, 0.1, 0.05, quick);
            if !quick {
                // Over 2000 s the phase error needs small steps: sweep RK4 and SDIRK2 further.
                l[1].sweep = halvings(0.05, 7);
                l[2].sweep = halvings(0.02, 6);
            }
            l
        },
    });
    out.push(Bench {
        key: "double_fourbar",
        title: "Double four-bar passing its singular position (A02-like, N = 2)",
        scene: "params/double_fourbar.yaml",
        horizon: h(10.0, 2.0),
        reference: Reference::ClosedForm(Box::new(|s: &Sample| {
            let th = parallelogram_angle(s.t);
            (0..5)
                .map(|i| wrap(s.q[i] - if i % 2 == 0 { th } else { -th }).abs())
                .fold(0.0, f64::max)
        })),
        error_metric: "max over the samples and joints of the wrapped angle error [rad]",
        reference_text: "closed form of the parallelogram mode: 3θ̈ = −3.5 g cos θ, a circulating \
                         pendulum, cos θ = 2 sn cn, sin θ = 2 sn² − 1 (Jacobi functions by the AGM)"
            .into(),
        drift: DriftMeasure::Position,
        lines: lines(true, 1e-3, 1e-2, 1e-2, quick),
    });
    out.push(Bench {
        key: "rod_body",
        title: "Rigid body on a massless rod (seed 000)",
        scene: "params/rod_body.yaml",
        horizon: h(10.0, 2.0),
        reference: Reference::Numerical { rk4_dt: 1e-4 },
        error_metric: "max over the samples of |q ⊖ q_ref|∞ [m, rad]",
        reference_text: NUMERICAL.into(),
        drift: DriftMeasure::Position,
        lines: lines(true, 1e-3, 1e-2, 1e-2, quick),
    });
    out.push(Bench {
        key: "vertical_disk",
        title: "Vertical rolling disk (seed 001, constant rates)",
        scene: "params/vertical_disk.yaml",
        horizon: h(10.0, 2.0),
        reference: Reference::ClosedForm(Box::new(|s: &Sample| {
            let t = s.t;
            let exact = [
                2.0 * (0.5 * t).sin(),
                2.0 * (1.0 - (0.5 * t).cos()),
                0.5 * t,
                10.0 * t,
            ];
            s.q.iter()
                .zip(exact)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        })),
        error_metric: "max over the samples of |q − q_exact|∞ [m, rad]",
        reference_text: "closed form: constant rates, x = 2 sin(t/2), y = 2(1 − cos(t/2)), \
                         yaw = t/2, spin = 10 t"
            .into(),
        drift: DriftMeasure::Velocity,
        lines: lines(true, 1e-3, 1e-2, 1e-2, quick),
    });
    out.push(Bench {
        key: "rolling_disk",
        title: "Rolling disk on a floating base (reference disk.urdf, state 1)",
        scene: "params/report/rolling_disk.yaml",
        horizon: h(5.0, 1.0),
        reference: Reference::Numerical { rk4_dt: 1e-4 },
        error_metric: "max over the samples of |q ⊖ q_ref|∞ (SE(3) log) [m, rad]",
        reference_text: NUMERICAL.into(),
        drift: DriftMeasure::Velocity,
        lines: lines(true, 1e-3, 1e-2, 1e-2, quick),
    });
    out.push(Bench {
        key: "diff_drive",
        title: "Differential-drive base coasting on a curve",
        scene: "params/report/diff_drive_coasting.yaml",
        horizon: h(10.0, 2.0),
        reference: Reference::Numerical { rk4_dt: 1e-4 },
        error_metric: "max over the samples of |q ⊖ q_ref|∞ (SE(2) log, wheel angles) [m, rad]",
        reference_text: NUMERICAL.into(),
        drift: DriftMeasure::Velocity,
        lines: lines(true, 1e-3, 1e-2, 1e-2, quick),
    });
    let masses = [0.1; 5];
    let k = [1e4, 1e5, 1e6, 1e5, 1e4];
    let q0 = [0.002, -0.001, 0.0005, 0.0, 0.001];
    let modes = Modes::new(
        &chain_mass(&masses),
        &DMatrix::from_diagonal(&DVector::from_row_slice(&k)),
        &q0,
    );
    out.push(Bench {
        key: "spring_chain_stiff",
        title: "Stiff spring chain (k = 1e4 … 1e6 N/m on 0.1 kg)",
        scene: "params/report/spring_chain_stiff.yaml",
        horizon: h(0.5, 0.1),
        reference: Reference::ClosedForm(Box::new(move |s: &Sample| {
            let q = modes.at(s.t);
            s.q.iter()
                .zip(&q)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        })),
        error_metric: "max over the samples of |q − q_modal|∞ [m]",
        reference_text: "closed form: modal solution of M q̈ + K q = 0, M_jk = 0.1 (6 − max(j, k)) \
                         kg, K = diag(1e4, 1e5, 1e6, 1e5, 1e4) N/m"
            .into(),
        drift: DriftMeasure::None,
        lines: {
            let n = if quick { 4 } else { 6 };
            let mut l = lines(false, 4e-4, 1e-3, 1e-3, quick);
            l[0].sweep = halvings(4e-4, n);
            l[1].sweep = halvings(1e-3, n);
            l[2].sweep = halvings(1e-3, n);
            l
        },
    });
    out
}
