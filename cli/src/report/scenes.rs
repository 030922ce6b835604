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
    /// fixed-step rows and RK4 at `rk4_dt` (projection) for the tolerance-driven rows (dopri5,
    /// radau5).
    Numerical { rk4_dt: f64 },
    /// The state at the end of the horizon only, against dopri5 at rtol = atol = `rtol`
    /// (projection) for the fixed-step rows and the peers, and RK4 at `rk4_dt` (projection) for
    /// the tolerance-driven rows; both checked against each other and against `published`.
    Final {
        rtol: f64,
        rk4_dt: f64,
        published: Published,
    },
}

/// A published value of q at the end of the horizon, with its own accuracy.
pub struct Published {
    /// Coordinate names, in the order of `q`.
    pub names: &'static [&'static str],
    pub q: &'static [f64],
    pub source: &'static str,
}

/// An external peer solving the same problem (its own process, its own pinned venv).
pub struct Peer {
    pub name: &'static str,
    /// Creates or reuses the venv (repository-relative; may need PyPI on its first run).
    pub setup: &'static str,
    /// The venv (repository-relative, unless the environment variable `venv_env` names another),
    /// given to `setup` as its argument; the peer runs in its `bin/python`.
    pub venv: &'static str,
    pub venv_env: &'static str,
    /// The peer's script: writes its runs as JSON to the path given as its argument.
    pub script: &'static str,
    /// What it is, for the README.
    pub about: &'static str,
}

/// One line of a work-precision diagram: a method, its drift control and its sweep.
#[derive(Clone)]
pub struct Line {
    pub method: Method,
    pub drift: DriftControl,
    /// Whether the sweep is over tolerances (rtol = atol) rather than steps.
    pub tolerances: bool,
    /// Fixed-step methods: the steps [s]; tolerance-driven ones: rtol (= atol).
    pub sweep: Vec<f64>,
}

/// The serde (scene file) name of a method or drift control: "rk4", "projection", ….
pub fn name<T: serde::Serialize>(x: T) -> String {
    serde_json::to_value(x)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default()
}

impl Line {
    pub fn label(&self) -> String {
        format!("{}/{}", name(self.method), name(self.drift))
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
    /// External peers drawn in the same diagrams (not in `--quick`: CI has no PyPI).
    pub peers: Vec<Peer>,
}

/// Steps dt0, dt0/2, … (`n` of them).
fn halvings(dt0: f64, n: usize) -> Vec<f64> {
    (0..n).map(|j| dt0 / 2f64.powi(j as i32)).collect()
}

/// The lines of a scene: SIE, RK4, SDIRK2 from their largest steps, DOPRI5 and Radau IIA over
/// tolerances; with
/// constraints, RK4 and SIE also without drift control and with Baumgarte, DOPRI5 also without.
/// The one list of the report's methods: a new method is added here (a tolerance-driven one
/// with `tolerances: true`).
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
        tolerances: method.is_adaptive(),
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
        line(Method::Dop853, p, tols.clone()),
        line(Method::Radau5, p, tols.clone()),
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

/// The IVP test set's reference q(0.03 s) of Andrews' squeezer (PSIDE at tol 1e-14), in its
/// coordinate order; accurate to ~1.4e-9 rad only (tests/it/andrews.rs).
const ANDREWS_NAMES: [&str; 7] = ["beta", "theta", "gamma", "phi", "delta", "omega", "epsilon"];
const ANDREWS_Q: [f64; 7] = [
    0.1581077119629904e+02,
    -0.1575637105984298e+02,
    0.4082224013073101e-01,
    -0.5347301163226948e+00,
    0.5244099658805304e+00,
    0.5347301163226948e+00,
    0.1048080741042263e+01,
];

const NUMERICAL: &str = "tighter solution by another method: dopri5 rtol = atol = 1e-13 with \
                         projection for the fixed-step rows, RK4 at a small step with projection \
                         for the dopri5, dop853 and radau5 rows";

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
        peers: vec![],
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
        peers: vec![],
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
        peers: vec![],
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
        peers: vec![],
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
        peers: vec![],
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
        peers: vec![],
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
        peers: vec![],
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
    out.push(Bench {
        key: "andrews",
        title: "Andrews' squeezing mechanism (Hairer & Wanner II VII.7; IVP test set), q at 0.03 s",
        scene: "params/andrews.yaml",
        horizon: 0.03,
        reference: Reference::Final {
            rtol: 1e-14,
            rk4_dt: 1e-6,
            published: Published {
                names: &ANDREWS_NAMES,
                q: &ANDREWS_Q,
                source: "the IVP test set's reference q(0.03 s) (PSIDE at tol 1e-14; accurate to \
                         ~1.4e-9 rad, tests/it/andrews.rs)",
            },
        },
        error_metric: "max over the coordinates of |q(0.03 s) − q_ref| [rad]",
        reference_text: "dopri5 at rtol = atol = 1e-14 with projection (for the fixed-step rows \
                         and the peers), RK4 at a small step with projection (for the \
                         tolerance-driven rows)"
            .into(),
        drift: DriftMeasure::Position,
        lines: {
            // Stiff: the spring's ~1.4 kHz and the loop's faster modes bound explicit steps
            // (RK4 ≤ ~2e-4 s); 12 digits need RK4 at ~5e-7 s, dopri5 at rtol ~1e-12.
            let n = if quick { 3 } else { 10 };
            let mut l = lines(true, 4e-6, 1e-4, 1e-4, quick);
            for line in &mut l {
                line.sweep = match (line.method, line.tolerances) {
                    (_, true) if !quick => (4..=14).map(|k| 10f64.powi(-k)).collect(),
                    (_, true) => vec![1e-5, 1e-8, 1e-11],
                    (Method::SemiImplicitEuler, _) => halvings(4e-6, n.min(6)),
                    (Method::Sdirk2, _) => halvings(1e-4, n.min(6)),
                    _ => halvings(1e-4, n),
                };
            }
            l
        },
        peers: if quick {
            vec![]
        } else {
            vec![Peer {
                name: "casadi",
                setup: "tools/peers/setup_casadi_venv.sh",
                venv: ".venv-casadi",
                venv_env: "CD_CASADI_VENV",
                script: "tools/peers/andrews_casadi.py",
                about: "CasADi (PyPI `casadi`, pinned in tools/peers/setup_casadi_venv.sh): \
                        SUNDIALS CVODES (Adams, BDF) on the index-1 ODE and IDAS on the \
                        semi-explicit index-1 DAE, the model generated as C by CasADi and \
                        compiled once (gcc -O3); see docs/propagation.md",
            }]
        },
    });
    out
}
