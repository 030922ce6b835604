//! Rigid-body algorithms as free functions `algo(model, data, …)`, Featherstone's recurrences in
//! the body frames. Results land in the `Data` workspace; nothing allocates after `Data::new`.
//!
//! Sizes: nq configuration coordinates, nv velocity coordinates, nb bodies (world included).

mod aba;
mod crba;
mod data;
mod energy;
mod jacobian;
mod kinematics;
mod rnea;

pub use aba::{aba, aba_from_innovations, aba_innovations, innovations_product};
pub use crba::{crba, crba_full};
pub(crate) use crba::{
    crba_after_kinematics, crba_full_after_kinematics, mass_diagonal_after_kinematics,
};
pub use data::{DENSE_EAGER_NV, Data};
pub use energy::{center_of_mass, kinetic_energy, potential_energy};
pub use jacobian::{
    ReferenceFrame, frame_jacobian, point_jacobian, point_jacobian_rows,
    point_jacobian_rows_subtract, point_jacobian_transpose_add,
};
pub(crate) use kinematics::forward_kinematics_bias_after_placements;
pub use kinematics::{
    forward_kinematics, forward_kinematics_bias, forward_kinematics_pos, forward_kinematics_vel,
    frame_placement, frame_velocity, point_classical_acceleration, point_position, point_velocity,
};
pub(crate) use rnea::bias_forces_after_kinematics;
pub use rnea::{nonlinear_effects, rnea};
