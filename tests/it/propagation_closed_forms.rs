//! The closed forms themselves (`common/closed_forms.rs`): Jacobi's elliptic functions meet their
//! identities, the A01 and A02 closed forms conserve their energies, and the modal solution solves
//! the spring chain. These check the tests' own reference functions, not the crate.

use crate::closed_forms;

use closed_forms::*;
use nalgebra::{DMatrix, DVector};
use std::f64::consts::PI;

#[test]
fn elliptic_functions_satisfy_their_identities() {
    assert!((elliptic_k(0.0) - PI / 2.0).abs() < 1e-15);
    // K(sin 45°) = 1.854074677301372 (A&S table 17.1)
    assert!((elliptic_k(PI.sin() * 0.0 + (0.5f64).sqrt()) - 1.854074677301372).abs() < 1e-14);
    let k = 0.8;
    for &u in &[0.0, 0.3, 1.7, -2.2, 40.0, 1234.5] {
        let (sn, cn, dn) = jacobi_sn_cn_dn(u, k);
        assert!((sn * sn + cn * cn - 1.0).abs() < 1e-14);
        assert!((dn * dn + k * k * sn * sn - 1.0).abs() < 1e-14);
        // d sn/du = cn dn by central differences
        let h = 1e-5;
        let d = (jacobi_sn_cn_dn(u + h, k).0 - jacobi_sn_cn_dn(u - h, k).0) / (2.0 * h);
        assert!((d - cn * dn).abs() < 1e-9, "u = {u}: {d} vs {}", cn * dn);
    }
    let (sn, cn, _) = jacobi_sn_cn_dn(elliptic_k(k), k);
    assert!((sn - 1.0).abs() < 1e-15 && cn.abs() < 1e-7);
    // k = 0: sn = sin
    assert!((jacobi_sn_cn_dn(0.7, 0.0).0 - 0.7f64.sin()).abs() < 1e-15);
}

#[test]
fn closed_forms_conserve_their_energies() {
    for &t in &[0.0, 0.4, 1.1, 123.4, 1999.9] {
        let (q, qd) = a01_state(t);
        assert!(
            (0.5 * qd * qd - G * q.sin()).abs() < 1e-11,
            "A01 energy at {t}"
        );
        let (x, z) = a01_position(t, 1.0);
        assert!((x - q.cos()).abs() < 1e-12 && (z + q.sin()).abs() < 1e-12);
        let (c, s, w) = parallelogram_crank(t);
        assert!((c * c + s * s - 1.0).abs() < 1e-13);
        assert!(
            (1.5 * w * w + 3.5 * G * s - 35.835).abs() < 1e-9,
            "A02 energy at {t}"
        );
    }
    // period of A01: 4 √(L/g) K(sin π/4)
    let period = 4.0 / G.sqrt() * elliptic_k((0.5f64).sqrt());
    assert!((period - 2.3678419475762373).abs() < 1e-13);
}

#[test]
fn modal_solution_solves_the_chain() {
    let m = relative_chain_mass(&[0.1, 0.2, 0.3]);
    let k = DMatrix::from_diagonal(&DVector::from_vec(vec![1e4, 3e4, 2e4]));
    let (q0, v0) = ([0.01, -0.02, 0.005], [0.0, 1.0, 0.0]);
    let t = 0.0123;
    let h = 1e-6;
    let (q, _) = linear_modes(&m, &k, &q0, &v0, t);
    let (qp, _) = linear_modes(&m, &k, &q0, &v0, t + h);
    let (qm, _) = linear_modes(&m, &k, &q0, &v0, t - h);
    let qdd = DVector::from_iterator(3, (0..3).map(|i| (qp[i] - 2.0 * q[i] + qm[i]) / (h * h)));
    let resid = &m * qdd + &k * DVector::from_column_slice(&q);
    assert!(resid.amax() < 1e-3 * (&k * DVector::from_column_slice(&q)).amax());
}
