//! Rigid-body algorithms: free functions over `(&Model, &mut Data, …)`, one file each. Each checks
//! its inputs once (lengths, finiteness) and then runs without allocating.

mod aba;
mod check;
mod crba;
mod energy;
mod factor;
pub(crate) mod jacobian;
mod kinematics;
mod mass_matrix;
mod momentum;
mod rnea;

pub use aba::aba;
pub(crate) use check::check_v;
pub use crba::crba;
pub(crate) use crba::crba_packed_at_kinematics;
pub use energy::{center_of_mass, kinetic_energy, potential_energy};
pub use factor::{
    factor_mass_matrix, forward_dynamics_crba, mass_matrix_factor, solve_mass_matrix, solve_mass_matrix_slice,
};
pub(crate) use factor::{factor_packed_mass_matrix, pack_mass_matrix, solve_mass_matrix_dofs};
pub use jacobian::{compute_joint_jacobians, frame_jacobian, JacobianFrame};
pub use kinematics::{forward_kinematics, frame_placement};
pub use mass_matrix::mass_matrix;
pub(crate) use momentum::{has_screw_joints_only, momentum_and_lagrangian_force};
pub(crate) use rnea::nonlinear_effects_at_kinematics;
pub use rnea::{generalized_gravity, nonlinear_effects, rnea};
