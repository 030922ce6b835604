//! The dynamic projection allocates nothing after its first call outside Clarabel's own solve
//! (one solve per call; Clarabel's `solve` makes a fixed number of allocations, counted in
//! `envelope.rs`), as long as the request keeps its structure (the same finite bounds and rows
//! of A); a new structure builds a new cone program once.

use crate::common;
use common::*;
use constraint_dynamics::envelope::EnvelopeModel;
use constraint_dynamics::projection::{DynamicProjector, ProjectionProblem, Status};
use constraint_dynamics::{Scene, System};

use crate::counting_alloc;
use counting_alloc::allocations;

#[test]
fn dynamic_projection_allocates_nothing_outside_clarabels_solve_after_the_first_call() {
    let per_solve = super::envelope::clarabel_solve_allocations();
    for name in [
        "tests/data/cart_tall_mass.yaml",
        "params/mobile_manipulator_floating.yaml",
        "params/diff_drive.yaml",
    ] {
        let scene = Scene::load(repo_dir().join(name)).unwrap();
        let mut sys = System::from_scene(&scene).unwrap();
        let em = EnvelopeModel::from_scene(&scene, &sys).unwrap();
        let nv = sys.model().nv;
        let zero = vec![0.0; nv];
        let mut proj = DynamicProjector::new(sys.model(), sys.constraints());
        let mut p = ProjectionProblem::new(sys.model());
        p.v_des[0] = 5.0;
        p.upper[0] = 0.01;
        let q = scene.q0.clone();
        let o = proj
            .project(&mut sys, Some(&em), &q, &zero, &zero, &p, 0.01)
            .unwrap();
        assert_eq!(o.status, Status::Optimal, "{name}");
        // Another request, state and period with the same structure reuse the program.
        let mut p2 = p.clone();
        p2.v_des[0] = -3.0;
        p2.upper[0] = 0.02;
        let mut q2 = q.clone();
        let last = q2.len() - 1;
        q2[last] += 0.1;
        let n = allocations(|| {
            proj.project(&mut sys, Some(&em), &q2, &zero, &zero, &p2, 0.02)
                .unwrap();
            proj.project(&mut sys, Some(&em), &q, &zero, &zero, &p, 0.01)
                .unwrap();
        });
        assert_eq!(n, 2 * per_solve, "{name}: the dynamic projection allocates");
        assert_eq!(proj.builds(), 1, "{name}: one structure, one cone program");
    }
}
