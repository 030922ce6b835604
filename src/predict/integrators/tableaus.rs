//! Butcher tableaus of the explicit Runge–Kutta methods — RK4, Dormand–Prince 5(4) and
//! Dormand–Prince 8(5,3) ("DOP853": Hairer, Nørsett & Wanner, Solving ODEs I, II.10; the
//! coefficients of Hairer's dop853.f) — checked against the order conditions in the tests below.
//! Also the Rosenbrock method ROS2's γ, which its step and its linearization
//! (covariance/linearize/ros2.rs) share.

// DOP853's coefficients are written as published (30 digits), beyond f64's 17.
#![allow(clippy::excessive_precision)]

/// How a tableau estimates its local error.
#[derive(Clone, Copy, Debug)]
pub enum ErrorWeights {
    None,
    /// An embedded solution b̂: err = h Σ (b_i − b̂_i) k_i.
    Embedded(&'static [f64]),
    /// DOP853: err5 = h Σ e5_i k_i (vs a 5th-order solution) and err3 = h Σ e3_i k_i (3rd),
    /// combined as |err5|² / √(|err5|² + 0.01 |err3|²).
    Dop853 {
        e5: &'static [f64],
        e3: &'static [f64],
    },
}

/// Butcher tableau of an explicit method.
pub struct Tableau {
    pub a: &'static [&'static [f64]],
    pub b: &'static [f64],
    pub error: ErrorWeights,
    pub c: &'static [f64],
}

/// γ of ROS2 (L-stable choice, 1 − 1/√2).
pub(in crate::predict) const ROS2_GAMMA: f64 = 1.0 - std::f64::consts::FRAC_1_SQRT_2;

/// The most stages of any tableau here (DOP853).
pub const MAX_STAGES: usize = 12;

pub const RK4: Tableau = Tableau {
    a: &[&[], &[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]],
    b: &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0],
    error: ErrorWeights::None,
    c: &[0.0, 0.5, 0.5, 1.0],
};

pub const DOPRI5: Tableau = Tableau {
    a: &[
        &[],
        &[1.0 / 5.0],
        &[3.0 / 40.0, 9.0 / 40.0],
        &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
        &[
            19372.0 / 6561.0,
            -25360.0 / 2187.0,
            64448.0 / 6561.0,
            -212.0 / 729.0,
        ],
        &[
            9017.0 / 3168.0,
            -355.0 / 33.0,
            46732.0 / 5247.0,
            49.0 / 176.0,
            -5103.0 / 18656.0,
        ],
        &[
            35.0 / 384.0,
            0.0,
            500.0 / 1113.0,
            125.0 / 192.0,
            -2187.0 / 6784.0,
            11.0 / 84.0,
        ],
    ],
    b: &[
        35.0 / 384.0,
        0.0,
        500.0 / 1113.0,
        125.0 / 192.0,
        -2187.0 / 6784.0,
        11.0 / 84.0,
        0.0,
    ],
    error: ErrorWeights::Embedded(&[
        5179.0 / 57600.0,
        0.0,
        7571.0 / 16695.0,
        393.0 / 640.0,
        -92097.0 / 339200.0,
        187.0 / 2100.0,
        1.0 / 40.0,
    ]),
    c: &[0.0, 0.2, 0.3, 0.8, 8.0 / 9.0, 1.0, 1.0],
};

/// DOP853's weights b (the 8th-order solution).
const DOP853_B: [f64; 12] = [
    5.42937341165687622380535766363e-2,
    0.0,
    0.0,
    0.0,
    0.0,
    4.45031289275240888144113950566,
    1.89151789931450038304281599044,
    -5.8012039600105847814672114227,
    3.1116436695781989440891606237e-1,
    -1.52160949662516078556178806805e-1,
    2.01365400804030348374776537501e-1,
    4.47106157277725905176885569043e-2,
];

pub const DOP853: Tableau = Tableau {
    a: &[
        &[],
        &[5.26001519587677318785587544488e-2],
        &[
            1.97250569845378994544595329183e-2,
            5.91751709536136983633785987549e-2,
        ],
        &[
            2.95875854768068491816892993775e-2,
            0.0,
            8.87627564304205475450678981324e-2,
        ],
        &[
            2.41365134159266685502369798665e-1,
            0.0,
            -8.84549479328286085344864962717e-1,
            9.24834003261792003115737966543e-1,
        ],
        &[
            3.7037037037037037037037037037e-2,
            0.0,
            0.0,
            1.70828608729473871279604482173e-1,
            1.25467687566822425016691814123e-1,
        ],
        &[
            3.7109375e-2,
            0.0,
            0.0,
            1.70252211019544039314978060272e-1,
            6.02165389804559606850219397283e-2,
            -1.7578125e-2,
        ],
        &[
            3.70920001185047927108779319836e-2,
            0.0,
            0.0,
            1.70383925712239993810214054705e-1,
            1.07262030446373284651809199168e-1,
            -1.53194377486244017527936158236e-2,
            8.27378916381402288758473766002e-3,
        ],
        &[
            6.24110958716075717114429577812e-1,
            0.0,
            0.0,
            -3.36089262944694129406857109825,
            -8.68219346841726006818189891453e-1,
            2.75920996994467083049415600797e1,
            2.01540675504778934086186788979e1,
            -4.34898841810699588477366255144e1,
        ],
        &[
            4.77662536438264365890433908527e-1,
            0.0,
            0.0,
            -2.48811461997166764192642586468,
            -5.90290826836842996371446475743e-1,
            2.12300514481811942347288949897e1,
            1.52792336328824235832596922938e1,
            -3.32882109689848629194453265587e1,
            -2.03312017085086261358222928593e-2,
        ],
        &[
            -9.3714243008598732571704021658e-1,
            0.0,
            0.0,
            5.18637242884406370830023853209,
            1.09143734899672957818500254654,
            -8.14978701074692612513997267357,
            -1.85200656599969598641566180701e1,
            2.27394870993505042818970056734e1,
            2.49360555267965238987089396762,
            -3.0467644718982195003823669022,
        ],
        &[
            2.27331014751653820792359768449,
            0.0,
            0.0,
            -1.05344954667372501984066689879e1,
            -2.00087205822486249909675718444,
            -1.79589318631187989172765950534e1,
            2.79488845294199600508499808837e1,
            -2.85899827713502369474065508674,
            -8.87285693353062954433549289258,
            1.23605671757943030647266201528e1,
            6.43392746015763530355970484046e-1,
        ],
    ],
    b: &DOP853_B,
    error: ErrorWeights::Dop853 {
        e5: &[
            0.1312004499419488073250102996e-1,
            0.0,
            0.0,
            0.0,
            0.0,
            -0.1225156446376204440720569753e1,
            -0.4957589496572501915214079952,
            0.1664377182454986536961530415e1,
            -0.3503288487499736816886487290,
            0.3341791187130174790297318841,
            0.8192320648511571246570742613e-1,
            -0.2235530786388629525884427845e-1,
        ],
        // b − b̂₃, b̂₃ nonzero at stages 1, 9 and 12.
        e3: &[
            DOP853_B[0] - 0.244094488188976377952755905512,
            0.0,
            0.0,
            0.0,
            0.0,
            DOP853_B[5],
            DOP853_B[6],
            DOP853_B[7],
            DOP853_B[8] - 0.733846688281611857341361741547,
            DOP853_B[9],
            DOP853_B[10],
            DOP853_B[11] - 0.220588235294117647058823529412e-1,
        ],
    },
    c: &[
        0.0,
        0.526001519587677318785587544488e-1,
        0.789002279381515978178381316732e-1,
        0.118350341907227396726757197510,
        0.281649658092772603273242802490,
        1.0 / 3.0,
        0.25,
        4.0 / 13.0,
        127.0 / 195.0,
        0.6,
        6.0 / 7.0,
        1.0,
    ],
};

#[cfg(test)]
mod tests {
    use super::*;

    /// Σ_j a_ij c_j^k for a row (missing entries are zeros).
    fn row_dot(row: &[f64], c: &[f64], k: i32) -> f64 {
        row.iter().zip(c).map(|(a, cj)| a * cj.powi(k)).sum()
    }

    /// Order conditions of the trees up to order 8 that test every coefficient: quadrature
    /// Σ b c^k = 1/(k+1) (k ≤ 7), row sums a_i· = c_i, Σ b_i c_i^m a_ij c_j^k = 1/((k+1)(k+m+2))
    /// (k + m ≤ 6), Σ b_i a_ij a_jl c_l^m = 1/((m+1)(m+2)(m+3)) (m ≤ 5).
    fn check(tab: &Tableau, p: i32, tol: f64) {
        let (a, b, c) = (tab.a, tab.b, tab.c);
        let s = b.len();
        for i in 0..s {
            assert!((a[i].iter().sum::<f64>() - c[i]).abs() < tol, "row {i}");
        }
        for k in 0..p {
            let q: f64 = (0..s).map(|i| b[i] * c[i].powi(k)).sum();
            assert!((q - 1.0 / (k + 1) as f64).abs() < tol, "quadrature {k}");
        }
        for m in 0..p - 1 {
            for k in 0..p - 1 - m {
                let v: f64 = (0..s)
                    .map(|i| b[i] * c[i].powi(m) * row_dot(a[i], c, k))
                    .sum();
                let want = 1.0 / ((k + 1) * (k + m + 2)) as f64;
                assert!((v - want).abs() < tol, "b c^{m} A c^{k}: {v} vs {want}");
            }
        }
        for m in 0..p - 2 {
            let v: f64 = (0..s)
                .map(|i| {
                    (0..a[i].len())
                        .map(|j| b[i] * a[i][j] * row_dot(a[j], c, m))
                        .sum::<f64>()
                })
                .sum();
            let want = 1.0 / ((m + 1) * (m + 2) * (m + 3)) as f64;
            assert!((v - want).abs() < tol, "b A A c^{m}: {v} vs {want}");
        }
    }

    #[test]
    fn rk4_dopri5_and_dop853_meet_their_order_conditions() {
        check(&RK4, 4, 1e-15);
        check(&DOPRI5, 5, 1e-14);
        check(&DOP853, 8, 1e-13);
    }

    /// The error weights vanish on the orders they estimate: Σ (b − b̂) c^k = 0 for k < 4
    /// (DOPRI5's 4th-order b̂), Σ e5 c^k = 0 for k < 5 and Σ e3 c^k = 0 for k < 3 (DOP853).
    #[test]
    fn error_weights_vanish_on_the_lower_orders() {
        let ErrorWeights::Embedded(bh) = DOPRI5.error else {
            panic!()
        };
        for k in 0..4 {
            let v: f64 = (0..7)
                .map(|i| (DOPRI5.b[i] - bh[i]) * DOPRI5.c[i].powi(k))
                .sum();
            assert!(v.abs() < 1e-15, "DOPRI5 {k}: {v}");
        }
        let ErrorWeights::Dop853 { e5, e3 } = DOP853.error else {
            panic!()
        };
        for (w, p) in [(e5, 5), (e3, 3)] {
            for k in 0..p {
                let v: f64 = (0..12).map(|i| w[i] * DOP853.c[i].powi(k)).sum();
                assert!(v.abs() < 1e-13, "DOP853 order {p}, k = {k}: {v}");
            }
        }
    }
}
