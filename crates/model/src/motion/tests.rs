//! The group stop of [`ControlMotion`] on a hand-driven ring (the protocol's `Testbed`):
//! ramps from where the axes are, torque off for an axis that cannot follow, brake orders for
//! axes the master can reach but no longer sees.

use ringsync_control::{AxisTrajectory, Cosine, Gains, Pd, VelocitySource};
use ringsync_proto::Duration;
use ringsync_proto::node::testbed::{RESOLUTION, Testbed, TestbedConfig};
use ringsync_proto::node::{
    MasterEvent, OffReason, SlaveEvent, StopOrder, StopReason, TorqueOffCause,
};

use super::{ControlMotion, StopSettings};

const MS: i64 = 1_000_000;

/// The default testbed ring, its master running standard PD on the reference gains.
fn ring() -> Testbed {
    let c = TestbedConfig::default();
    let n = c.slaves as usize;
    let law = Pd::new(Gains::uniform(n, 3.182, 1.591, 0.0), false).expect("pd");
    let traj = Cosine::with_peak_speed(c.peak_speed, 2.0).expect("cosine");
    let motion = ControlMotion::new(
        Box::new(law),
        VelocitySource::Reported,
        vec![AxisTrajectory::Cosine(traj); n],
        vec![RESOLUTION; n],
        Duration::from_ms(1),
        StopSettings {
            following_error_limit: c.following_error_limit,
            ..StopSettings::default()
        },
    );
    Testbed::with_motion(c, Box::new(motion))
}

fn stops(r: &Testbed) -> Vec<(i64, StopReason)> {
    r.master_events
        .iter()
        .filter_map(|(t, e)| match e {
            MasterEvent::GroupStop { reason, .. } => Some((*t, *reason)),
            _ => None,
        })
        .collect()
}

/// Axis 2 seizes at full speed (its drive can no longer move it): the following error
/// stops the group; axis 2 cannot follow its stop ramp and gets torque off at once; the
/// others ramp down from where they are and get torque off when they have held still.
/// Everything is off within a bounded time, and each step is an event with its axis.
#[test]
fn a_group_stop_ramps_down_then_cuts_torque() {
    let mut r = ring();
    r.run_until(500 * MS);
    // At 0.5 s every axis moves at its peak speed (15 rad/s): axis 2 keeps that speed.
    r.gains[1] = 0.0;
    r.run_until(2_000 * MS);
    let s = stops(&r);
    assert_eq!(s.len(), 1);
    let (t_stop, reason) = s[0];
    assert!(
        matches!(reason, StopReason::FollowingError { axis: 1, .. }),
        "{reason:?}"
    );
    let offs: Vec<(i64, usize, OffReason)> = r
        .master_events
        .iter()
        .filter_map(|(t, e)| match e {
            MasterEvent::Order {
                axis,
                order: StopOrder::TorqueOff,
                why,
                ..
            } => Some((*t, *axis, *why)),
            _ => None,
        })
        .collect();
    assert_eq!(offs.len(), 4, "{offs:?}");
    let seized = offs.iter().find(|o| o.1 == 1).expect("axis 2 off");
    assert!(
        matches!(seized.2, OffReason::FollowingError { .. }),
        "{seized:?}"
    );
    assert!(
        seized.0 - t_stop < 120 * MS,
        "axis 2 off {} ms after the stop",
        (seized.0 - t_stop) / MS
    );
    for o in offs.iter().filter(|o| o.1 != 1) {
        assert_eq!(o.2, OffReason::StopComplete, "{o:?}");
        // A ramp from ≤ 15.2 rad/s at 200 rad/s² lasts ≤ 76 ms, then 100 ms of hold.
        assert!(
            o.0 - t_stop <= 190 * MS,
            "axis {} off {} ms after the stop",
            o.1 + 1,
            (o.0 - t_stop) / MS
        );
    }
    // Every slave applied the order, and the ramping axes ended at standstill near where
    // the ramp put them.
    for i in 1..=4 {
        assert!(r.slaves[i - 1].torque_off(), "slave {i}");
        assert!(r.slave_events.iter().any(|(_, s, e)| *s == i
            && *e
                == SlaveEvent::TorqueOff {
                    cause: TorqueOffCause::Commanded
                }));
    }
    // The ramping axes were at standstill (below 0.2 rad/s) when their torque went off
    // (the testbed's frictionless axes keep that speed after: they coast).
    for i in [0, 2, 3] {
        assert!(
            r.axes[i].v.abs() < 0.2,
            "axis {} at {} rad/s",
            i + 1,
            r.axes[i].v
        );
    }
}

/// The ring breaks at slave 3 at full speed. The master has no feedback from any axis; it
/// can still reach slaves 1 and 2, and orders them to brake on their own; 3 and 4, which
/// it cannot reach, brake after their watchdogs. Every axis ends at standstill, none coasts.
/// Before the fix the master ordered torque off to the axes it could reach, and they coasted.
#[test]
fn a_broken_ring_brakes_every_axis_it_can_reach_and_the_rest_brake_alone() {
    let mut r = ring();
    r.run_until(500 * MS);
    r.dead[3] = true;
    r.run_until(1_500 * MS);
    let s = stops(&r);
    assert!(
        matches!(s.first(), Some((_, StopReason::NoFeedback { .. }))),
        "{s:?}"
    );
    for i in [1, 2] {
        assert!(
            r.slave_events
                .iter()
                .any(|(_, s, e)| *s == i && *e == SlaveEvent::Braking { ordered: true }),
            "slave {i} was not ordered to brake"
        );
    }
    assert!(
        r.slave_events
            .iter()
            .any(|(_, s, e)| *s == 4 && *e == SlaveEvent::Braking { ordered: false })
    );
    for i in [1, 2, 4] {
        let v = r.axes[i - 1].v;
        assert!(v.abs() < 0.1, "axis {i} at {v} rad/s");
        assert!(r.slaves[i - 1].torque_off(), "slave {i}");
    }
}
