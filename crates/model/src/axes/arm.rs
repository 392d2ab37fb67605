//! The coupled plant on the ring: the two joints of a planar two-link arm
//! (`plant.kind = "two-link-arm"`), one slave each.

use ringsync_plant::{ArmParams, Encoder, Plant, PlantError, TwoLinkArm};

use super::Axes;

/// The two-link arm as the drivers move it: both joints share one state time and advance
/// together, whichever joint an event concerns, each with the command its drive holds
/// (M(q)q̈ + C(q, q̇)q̇ + F·q̇ = τ, τ_i = K_a,i·sat(u_i) with the drive range of the joint's
/// `[[axis]]` table; RK4). Asked for a time not later than the arm's, it stays where it is
/// (as an independent axis does): the drivers ask in time order, so that happens only to a
/// driver that gets to an event late.
#[derive(Debug, Clone)]
pub struct ArmAxes {
    arm: TwoLinkArm,
    encoders: [Encoder; 2],
    /// Command each drive holds [V].
    u: [f64; 2],
    /// True time of the state [ns].
    t: i64,
}

impl ArmAxes {
    /// The arm at rest at q = 0, true time 0, 0 V on both drives.
    pub fn new(params: ArmParams, encoders: [Encoder; 2]) -> Result<Self, PlantError> {
        Ok(ArmAxes {
            arm: TwoLinkArm::new(params)?,
            encoders,
            u: [0.0; 2],
            t: 0,
        })
    }

    /// The arm itself (its parameters and state).
    pub fn arm(&self) -> &TwoLinkArm {
        &self.arm
    }
}

impl Axes for ArmAxes {
    fn len(&self) -> usize {
        2
    }
    fn advance(&mut self, _i: usize, t: i64) {
        if t > self.t {
            self.arm.advance_held(self.u, (t - self.t) as f64 * 1e-9);
            self.t = t;
        }
    }
    fn position(&self, i: usize) -> f64 {
        self.arm.position(i)
    }
    fn velocity(&self, i: usize) -> f64 {
        self.arm.velocity(i)
    }
    fn time(&self, _i: usize) -> i64 {
        self.t
    }
    fn counts(&self, i: usize) -> i64 {
        self.encoders[i].counts(self.arm.position(i))
    }
    fn command(&self, i: usize) -> f64 {
        self.u[i]
    }
    fn set_command(&mut self, i: usize, u: f64) {
        self.u[i] = u;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arm() -> ArmAxes {
        let p = ArmParams {
            p1: 0.15,
            p2: 0.02,
            p3: 0.03,
            f1: 0.05,
            f2: 0.02,
            torque_constant: [2.0, 0.5],
            u_max: [10.0; 2],
            max_step: 1e-4,
        };
        let e = Encoder::new(1 << 20).expect("encoder");
        ArmAxes::new(p, [e, e]).expect("arm")
    }

    /// Asking for one joint moves both: the state time is shared, and the positions are
    /// those of the plant stepped over the same interval with both commands held.
    #[test]
    fn one_joint_asked_both_advance() {
        let mut a = arm();
        a.set_command(0, 2.0);
        a.set_command(1, -1.0);
        a.advance(1, 3_000_000);
        assert_eq!((a.time(0), a.time(1)), (3_000_000, 3_000_000));
        let mut plant = TwoLinkArm::new(a.arm().params).expect("arm");
        plant.advance_held([2.0, -1.0], 3e-3);
        for j in 0..2 {
            assert_eq!(a.position(j), plant.position(j));
            assert_eq!(a.velocity(j), plant.velocity(j));
            assert_eq!(a.counts(j), a.encoders[j].counts(plant.position(j)));
        }
        // Not later: nothing moves.
        let before = (a.position(0), a.position(1));
        a.advance(0, 2_000_000);
        assert_eq!((a.position(0), a.position(1)), before);
        assert_eq!(a.time(0), 3_000_000);
    }

    /// The joints are coupled: joint 2 driven alone moves joint 1, whose drive holds 0 V
    /// (the reaction through M's off-diagonal p2 + p3·cos q2). An independent axis at 0 V
    /// would stay at rest. From rest at q = 0, M·q̈ = (0, K_a,2·u_2) gives
    /// q̈1 = −M12·K_a,2·u_2/det M = −0.05·0.5/0.0017 = −14.7 rad/s², so joint 1 turns back by
    /// about ½·q̈1·t² = −0.74 mrad in 10 ms (q2 changes little in that time).
    #[test]
    fn joint_two_alone_moves_joint_one() {
        let mut a = arm();
        a.set_command(1, 1.0);
        a.advance(0, 10_000_000);
        assert_eq!(a.command(0), 0.0);
        assert!(a.position(1) > 0.0, "{}", a.position(1));
        let m = a.arm().mass_matrix(0.0);
        let det = m[0] * m[3] - m[1] * m[2];
        let want = 0.5 * (-m[1] * 0.5 * 1.0 / det) * 0.01f64.powi(2);
        assert!(
            (a.position(0) - want).abs() < 0.05 * want.abs(),
            "joint 1 at {} against {want}",
            a.position(0)
        );
        assert!(a.counts(0) < 0);
    }

    /// Commands beyond a drive's range act as the range (the drive saturates, the held
    /// command is what was applied).
    #[test]
    fn commands_saturate_at_the_drive_range() {
        let (mut a, mut b) = (arm(), arm());
        a.set_command(0, 25.0);
        b.set_command(0, 10.0);
        a.advance(0, 1_000_000);
        b.advance(0, 1_000_000);
        assert_eq!(a.position(0), b.position(0));
        assert_eq!(a.command(0), 25.0);
    }
}
