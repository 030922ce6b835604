//! One robot model per node: applying a decoded `/odom` message to the latest state borrows the
//! robot's model and allocates nothing (a message at 50–100 Hz must not copy a model).

use crate::common::repo_root;
use crate::counting_alloc::allocations;
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use constraint_dynamics_nodes::params::CommonParams;
use constraint_dynamics_nodes::robot::Robot;

#[test]
fn applying_odometry_allocates_nothing() {
    let _group = crate::common::exclusive_group(module_path!());
    let mut common = CommonParams::default();
    common.model.scene_file = repo_root()
        .join("params/suite_mobile_manipulator.yaml")
        .display()
        .to_string();
    let mut robot = Robot::load(&common).unwrap();
    let mut od = Odometry::default();
    od.pose.pose.orientation.w = 1.0;
    od.pose.pose.position.x = 0.4;
    od.pose.pose.position.y = -0.2;
    od.twist.twist.linear.x = 0.3;
    od.twist.twist.angular.z = 0.5;
    robot.apply_odometry(&od).unwrap();
    od.pose.pose.position.x = 0.5;
    let n = allocations(|| robot.apply_odometry(&od).unwrap());
    assert_eq!(n, 0, "applying an /odom message allocated {n} times");
    // The state took the message: the planar base's x and its forward rate.
    let (q, v) = (&robot.state().q, &robot.state().v);
    assert_eq!(q[0], 0.5);
    assert_eq!(v[0], 0.3);
}
