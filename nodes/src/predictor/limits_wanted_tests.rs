//! The envelope's schedule: every tick while its limits are taken, once per diagnostics period
//! otherwise (for `/diagnostics`).

use super::*;
use crate::msg::constraint_dynamics_msgs::AccelerationLimits;
use crate::params::CommonParams;

fn node() -> PredictorNode {
    let mut common = CommonParams::default();
    common.model.scene_file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../params/suite_diff_drive.yaml"
    )
    .into();
    common.diagnostics.period = 1.0;
    let params = NodeParams::<PredictorParams> {
        common,
        node: PredictorParams::default(),
    };
    let robot = Robot::load(&params.common).unwrap();
    PredictorNode::new(robot, params, NodeLog::new("test")).unwrap()
}

/// `ms` [ms] after `t0`.
fn at(t0: Time, ms: i64) -> Time {
    Time::from_nanos(t0.to_nanos() + ms * 1_000_000)
}

/// The limits the tick at `now` computed, if it did.
fn limits(n: &mut PredictorNode, now: Time) -> Option<AccelerationLimits> {
    let mut out = None;
    n.tick(now, &mut |o| out = Some(o)).unwrap();
    out.expect("a tick publishes").limits
}

#[test]
fn the_envelope_is_computed_every_tick_only_while_its_limits_are_wanted() {
    let mut n = node();
    let t0 = Time::from_nanos(1_000_000_000_000);
    // Wanted from the start (a subscriber may be there before the glue has looked).
    assert!(limits(&mut n, at(t0, 0)).is_some());
    assert!(limits(&mut n, at(t0, 100)).is_some());
    n.handle(PredictorInput::LimitsWanted(false), t0, &mut |_| {});
    // Not wanted: once per diagnostics period (1 s) after the last one, at 0.1 s.
    let ticks: Vec<(i64, Option<AccelerationLimits>)> = (2..=12)
        .map(|k| (k, limits(&mut n, at(t0, 100 * k))))
        .collect();
    let computed: Vec<i64> = (ticks.iter())
        .filter(|(_, l)| l.is_some())
        .map(|(k, _)| *k)
        .collect();
    assert_eq!(computed, [11], "ticks (×0.1 s) that computed the envelope");
    // The envelope of that tick's state: the diff drive at rest, docs/projection.md's closed
    // form a = 2 τ_max / (r (M + 2 I_w/r²)) = 20.61856 m/s² (written to 10 digits, ±5e-10).
    let m = ticks[9].1.as_ref().expect("the tick at 1.1 s");
    assert_eq!(m.header.stamp, at(t0, 1100));
    let a = m.forward_acceleration.max;
    assert!((a - 20.61855670).abs() <= 1e-9 * a, "{a}");
    // `/diagnostics` shows the last envelope's limits in between.
    let values = n.diagnostics();
    let shown = values.iter().filter(|kv| kv.key.ends_with("limit [m/s²]"));
    assert_eq!(shown.count(), 2, "{values:?}");
    n.handle(PredictorInput::LimitsWanted(true), t0, &mut |_| {});
    assert!(limits(&mut n, at(t0, 1300)).is_some());
    assert!(limits(&mut n, at(t0, 1400)).is_some());
}
