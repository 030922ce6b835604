//! Centre of mass and energies.

use super::Data;
use crate::model::Model;
use nalgebra::Vector3;

/// World position of the centre of mass [m] (after a kinematics pass).
pub fn center_of_mass(model: &Model, data: &Data) -> Vector3<f64> {
    let mut m = 0.0;
    let mut c = Vector3::zeros();
    for i in 1..model.nbodies() {
        let y = &model.bodies[i].inertia;
        m += y.mass;
        c += data.o_m_i[i].act_point(&y.com) * y.mass;
    }
    if m > 0.0 { c / m } else { c }
}

/// Kinetic energy `½ Σ v_iᵀ I_i v_i` [J] (after `forward_kinematics` with velocities).
pub fn kinetic_energy(model: &Model, data: &Data) -> f64 {
    (1..model.nbodies())
        .map(|i| model.bodies[i].inertia.kinetic_energy(&data.v[i]))
        .sum()
}

/// Potential energy of gravity `−Σ m_i g · c_i` [J], zero at the world origin.
pub fn potential_energy(model: &Model, data: &Data) -> f64 {
    (1..model.nbodies())
        .map(|i| {
            let y = &model.bodies[i].inertia;
            -y.mass * model.gravity.dot(&data.o_m_i[i].act_point(&y.com))
        })
        .sum()
}
