//! The master's motion application (the [`Motion`] trait of `ringsync-proto`) built on the
//! control library: encoder counts and ns to rad and s, the desired motion, supervision
//! (following error, faults, blind axes), the control law, and the group stop (docs/safety.md):
//! every axis ramps down from where it is; an axis that cannot follow its ramp gets torque
//! off, one without feedback is told to brake on its own, the others get torque off when
//! their ramp has ended and they stand still, and every axis at the stop timeout.

use ringsync_control::{
    AxisTrajectory, ControlInput, ControlLaw, ControlOutput, Controller, Feedback,
    GroupTrajectories, State, VelocitySource,
};
use ringsync_proto::Duration;
use ringsync_proto::node::motion::{Motion, MotionInput, MotionOutput, Setpoint};
use ringsync_proto::node::{OffReason, SlaveLaw, StopOrder, StopReason};
use ringsync_wire::{FeedbackSlot, Status};

use crate::monitor::{Monitor, MonitorSettings};

/// The group stop's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopSettings {
    /// Following-error limit \[rad\]: beyond it the group stops, and during the stop an axis
    /// this far off its ramp gets torque off.
    pub following_error_limit: f64,
    /// Deceleration of the stop ramp [rad/s²].
    pub deceleration: f64,
    /// How long an axis holds still at the end of its ramp before its torque goes off.
    pub hold: Duration,
    /// The longest any axis keeps its torque during a stop.
    pub timeout: Duration,
    /// An axis counts as standing still below this speed [rad/s].
    pub standstill: f64,
}

impl Default for StopSettings {
    /// 1 rad, 200 rad/s², 100 ms, 2 s, 0.2 rad/s.
    fn default() -> Self {
        StopSettings {
            following_error_limit: 1.0,
            deceleration: 200.0,
            hold: Duration::from_ms(100),
            timeout: Duration::from_ms(2_000),
            standstill: 0.2,
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct StopRamp {
    t0: f64,
    x0: f64,
    v0: f64,
    decel: f64,
}

impl StopRamp {
    fn at(&self, t: f64) -> State {
        let tau = (t - self.t0).max(0.0);
        let t_stop = self.v0.abs() / self.decel;
        let s = self.v0.signum();
        if tau >= t_stop {
            State {
                x: self.x0 + self.v0 * t_stop - 0.5 * s * self.decel * t_stop * t_stop,
                v: 0.0,
                a: 0.0,
            }
        } else {
            State {
                x: self.x0 + self.v0 * tau - 0.5 * s * self.decel * tau * tau,
                v: self.v0 - s * self.decel * tau,
                a: -s * self.decel,
            }
        }
    }
}

/// The motion application of a master: a control law on the desired motion of every axis.
pub struct ControlMotion {
    controller: Controller<Box<dyn ControlLaw>>,
    trajectories: GroupTrajectories,
    /// Encoder resolution of each axis [rad per count].
    resolution: Vec<f64>,
    stop_settings: StopSettings,
    stop: Option<Vec<StopRamp>>,
    /// The order given to each axis during the stop (latched).
    orders: Vec<Option<StopOrder>>,
    fb: Feedback,
    input: ControlInput,
    output: ControlOutput,
    monitor: Monitor,
    /// The following errors the monitors take [rad].
    errors: Vec<f64>,
}

impl std::fmt::Debug for ControlMotion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControlMotion")
            .field("law", &self.controller.law.name())
            .field("stopping", &self.stop.is_some())
            .finish_non_exhaustive()
    }
}

impl ControlMotion {
    /// The motion of `law` on `trajectories` (one per axis), with encoders of `resolution`
    /// [rad per count] per axis, a cycle of `cycle`, and the stop's settings.
    pub fn new(
        law: Box<dyn ControlLaw>,
        velocity: VelocitySource,
        trajectories: Vec<AxisTrajectory>,
        resolution: Vec<f64>,
        cycle: Duration,
        stop: StopSettings,
    ) -> Self {
        let n = trajectories.len();
        let t_cyc = cycle.as_ns() as f64 * 1e-9;
        ControlMotion {
            controller: Controller::new(law, velocity),
            trajectories: GroupTrajectories::new(trajectories),
            resolution,
            stop_settings: stop,
            stop: None,
            orders: vec![None; n],
            fb: Feedback::new(n),
            input: ControlInput::new(n, t_cyc),
            output: ControlOutput::new(n),
            monitor: Monitor::new(MonitorSettings::off(n)),
            errors: vec![0.0; n],
        }
    }

    /// With a disturbance observer (`None`: without), [`ringsync_control::dob`].
    pub fn with_dob(
        mut self,
        dob: Option<ringsync_control::dob::DobParams>,
    ) -> Result<Self, ringsync_control::ControlError> {
        self.controller = attach_dob(self.controller, dob)?;
        Ok(self)
    }

    /// With the sync-error and following-error monitors of `settings` (one entry per axis).
    pub fn with_monitor(mut self, settings: MonitorSettings) -> Self {
        self.monitor = Monitor::new(settings);
        self
    }

    /// The monitors (their settings, each axis's in-sync status).
    pub fn monitor(&self) -> &Monitor {
        &self.monitor
    }

    /// The law's name.
    pub fn law_name(&self) -> &'static str {
        self.controller.law.name()
    }

    fn state(&self, i: usize, t: f64) -> State {
        match &self.stop {
            Some(r) => r[i].at(t),
            None => self.trajectories.at(i, t),
        }
    }

    /// The latest measured position [rad], velocity [rad/s] and sampling instant [s] of
    /// axis `i`, if it ever reported one.
    fn measured(&self, input: &MotionInput<'_>, i: usize) -> Option<(f64, f64, f64)> {
        let res = self.resolution[i];
        let f = input.samples[i]?;
        Some((
            f64::from(f.position) * res,
            f64::from(f.velocity) * res,
            f.sample_time_ns as f64 * 1e-9,
        ))
    }

    /// The group stop begins at `t` [s]: every axis ramps down from where it is (its
    /// measured position, moved on by its measured velocity to `t`, and that velocity),
    /// like a drive's quick stop.
    fn begin_stop(&mut self, input: &MotionInput<'_>, t: f64) {
        let n = self.trajectories.len();
        let decel = self.stop_settings.deceleration;
        self.stop = Some(
            (0..n)
                .map(|i| {
                    let (x0, v0) = match self.measured(input, i) {
                        Some((x, v, ts)) => (x + v * (t - ts), v),
                        None => {
                            let d = self.trajectories.at(i, t);
                            (d.x, d.v)
                        }
                    };
                    StopRamp {
                        t0: t,
                        x0,
                        v0,
                        decel,
                    }
                })
                .collect(),
        );
        for i in 0..n {
            self.fb.desired[i] = self.state(i, self.fb.sample_time[i]);
        }
    }

    /// During the stop: brake for an axis without feedback (the master can reach it but no
    /// longer sees it); torque off for one that cannot follow its ramp, has ended its ramp
    /// and stands still, or has run out of time.
    fn supervise_stop(&mut self, input: &MotionInput<'_>, t: f64, out: &mut MotionOutput) {
        let Some(ramps) = &self.stop else { return };
        let s = self.stop_settings;
        let hold = s.hold.as_ns() as f64 * 1e-9;
        let timeout = s.timeout.as_ns() as f64 * 1e-9;
        for (i, r) in ramps.iter().enumerate() {
            if self.orders[i] == Some(StopOrder::TorqueOff) {
                continue;
            }
            let measured = self.measured(input, i).filter(|_| !input.blind[i]);
            let order = match (self.orders[i], measured) {
                _ if t >= r.t0 + timeout => Some((StopOrder::TorqueOff, OffReason::StopTimeout)),
                // Braking on its own already: the drive ends it.
                (Some(_), _) => None,
                (None, None) => Some((StopOrder::Brake, OffReason::NoFeedback)),
                (_, Some((x, v, ts))) => {
                    let error = r.at(ts).x - x;
                    if error.abs() > s.following_error_limit {
                        Some((StopOrder::TorqueOff, OffReason::FollowingError { error }))
                    } else if t >= r.t0 + r.v0.abs() / r.decel + hold && v.abs() <= s.standstill {
                        Some((StopOrder::TorqueOff, OffReason::StopComplete))
                    } else {
                        None
                    }
                }
            };
            if let Some((order, why)) = order {
                out.orders.push((i, order, why));
            }
        }
        for &(i, order, _) in &out.orders {
            self.orders[i] = Some(order);
        }
    }
}

impl Motion for ControlMotion {
    fn axes(&self) -> usize {
        self.trajectories.len()
    }

    fn is_stopping(&self) -> bool {
        self.stop.is_some()
    }

    fn desired(&self, axis: usize, t: f64) -> Setpoint {
        let s = self.state(axis, t);
        Setpoint { x: s.x, v: s.v }
    }

    fn compute(&mut self, input: &MotionInput<'_>, out: &mut MotionOutput) {
        let n = self.trajectories.len();
        out.stop = None;
        out.orders.clear();
        out.monitor.clear();
        let t_start = input.cycle_start.as_ns() as f64 * 1e-9;
        let t_now = input.now.as_ns() as f64 * 1e-9;
        let mut stop_reason = input.pending;
        for i in 0..n {
            let res = self.resolution[i];
            match input.samples[i] {
                Some(s) => {
                    let ts = s.sample_time_ns as f64 * 1e-9;
                    self.fb.position[i] = f64::from(s.position) * res;
                    self.fb.velocity[i] = f64::from(s.velocity) * res;
                    self.fb.sample_time[i] = ts;
                    self.fb.desired[i] = self.state(i, ts);
                    self.fb.fresh[i] = input.fresh[i];
                    if s.status.contains(Status::FAULT) && stop_reason.is_none() {
                        stop_reason = Some(StopReason::AxisFault { axis: i });
                    }
                }
                None => {
                    self.fb.position[i] = 0.0;
                    self.fb.velocity[i] = 0.0;
                    self.fb.sample_time[i] = t_start;
                    self.fb.desired[i] = self.state(i, t_start);
                    self.fb.fresh[i] = false;
                }
            }
            let e = self.fb.desired[i].x - self.fb.position[i];
            if input.samples[i].is_some()
                && e.abs() > self.stop_settings.following_error_limit
                && stop_reason.is_none()
            {
                stop_reason = Some(StopReason::FollowingError { axis: i, error: e });
            }
            // A law run on a sample W cycles old drives the axis blind (with the ring
            // broken behind it, the error it sees never closes and the command winds up
            // to saturation).
            if input.blind[i] && stop_reason.is_none() && self.stop.is_none() {
                stop_reason = Some(StopReason::NoFeedback { axis: i });
            }
        }
        // The monitors, on what the master measured, while the group runs (every axis
        // has reported; none is blind).
        if self.stop.is_none()
            && input.samples.iter().all(Option::is_some)
            && !input.blind.iter().any(|b| *b)
        {
            for i in 0..n {
                self.errors[i] = self.fb.desired[i].x - self.fb.position[i];
            }
            let trip = self
                .monitor
                .check(input.now.as_ns(), &self.errors, &mut out.monitor);
            if stop_reason.is_none() {
                stop_reason = trip;
            }
        }
        if let (Some(reason), None) = (stop_reason, &self.stop) {
            self.begin_stop(input, t_now);
            out.stop = Some(reason);
        }
        if !input.commanded {
            return;
        }
        if self.stop.is_some() {
            self.supervise_stop(input, t_now, out);
        }
        for i in 0..n {
            let a = t_start + input.command_arrival[i].as_ns() as f64 * 1e-9;
            self.input.apply_time[i] = a;
            self.input.desired[i] = self.state(i, a);
        }
        if self
            .controller
            .update(&self.fb, &self.input, &mut self.output)
            .is_err()
        {
            // Lengths are fixed at construction; an error here is a bug. Command 0 V.
            self.output.u.fill(0.0);
        }
        for i in 0..n {
            if input.blind[i] || self.orders[i].is_some() {
                self.output.u[i] = 0.0;
                self.output.saturated[i] = false;
            }
        }
        out.u.copy_from_slice(&self.output.u);
        out.saturated.copy_from_slice(&self.output.saturated);
        let r = &mut out.record;
        r.k = input.k;
        r.sample_time.copy_from_slice(&self.fb.sample_time);
        r.position.copy_from_slice(&self.fb.position);
        r.fresh.copy_from_slice(&self.fb.fresh);
        r.u.copy_from_slice(&self.output.u);
        r.saturated.copy_from_slice(&self.output.saturated);
        r.apply_time.copy_from_slice(&self.input.apply_time);
    }
}

/// The law a slave of the lumped-only plan runs (the [`SlaveLaw`] of `ringsync-proto`, ref.
/// \[3\]): the control law on what its lumped frame carries, this cycle's samples of the
/// slaves before it and last cycle's of those after it, each slave evaluating the shared
/// trajectory itself.
pub struct SlaveControl {
    trajectories: GroupTrajectories,
    resolution: Vec<f64>,
    controller: Controller<Box<dyn ControlLaw>>,
    fb: Feedback,
    input: ControlInput,
    out: ControlOutput,
    /// Sampling instant of the newest sample taken into the history, per axis [ns].
    seen: Vec<u64>,
}

impl std::fmt::Debug for SlaveControl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlaveControl")
            .field("law", &self.controller.law.name())
            .finish_non_exhaustive()
    }
}

impl SlaveControl {
    /// A slave's `law` (for all n axes) on `trajectories`, with every axis's encoder
    /// `resolution` [rad per count] and the cycle `cycle`.
    pub fn new(
        law: Box<dyn ControlLaw>,
        velocity: VelocitySource,
        trajectories: Vec<AxisTrajectory>,
        resolution: Vec<f64>,
        cycle: Duration,
    ) -> Self {
        let n = law.axes();
        let t_cyc = cycle.as_ns() as f64 * 1e-9;
        SlaveControl {
            trajectories: GroupTrajectories::new(trajectories),
            resolution,
            controller: Controller::new(law, velocity),
            fb: Feedback::new(n),
            input: ControlInput::new(n, t_cyc),
            out: ControlOutput::new(n),
            seen: vec![u64::MAX; n],
        }
    }

    /// With a disturbance observer (`None`: without), [`ringsync_control::dob`].
    pub fn with_dob(
        mut self,
        dob: Option<ringsync_control::dob::DobParams>,
    ) -> Result<Self, ringsync_control::ControlError> {
        self.controller = attach_dob(self.controller, dob)?;
        Ok(self)
    }
}

impl SlaveLaw for SlaveControl {
    fn axes(&self) -> usize {
        self.seen.len()
    }

    fn command(&mut self, me: usize, slots: &[Option<FeedbackSlot>], now: f64) -> f64 {
        let n = self.seen.len();
        for a in 0..n {
            self.fb.fresh[a] = false;
        }
        for (a, slot) in slots.iter().enumerate().take(n) {
            let Some(slot) = slot else { continue };
            // A sample already taken (the frame carries last cycle's again), or an empty
            // slot once the axis has reported.
            if slot.sample_time_ns == self.seen[a]
                || slot.sample_time_ns == 0 && self.seen[a] != u64::MAX
            {
                continue;
            }
            let ts = slot.sample_time_ns as f64 * 1e-9;
            let res = self.resolution[a];
            self.fb.position[a] = f64::from(slot.position) * res;
            self.fb.velocity[a] = f64::from(slot.velocity) * res;
            self.fb.sample_time[a] = ts;
            self.fb.desired[a] = self.trajectories.at(a, ts);
            self.fb.fresh[a] = true;
            self.seen[a] = slot.sample_time_ns;
        }
        for a in 0..n {
            self.input.apply_time[a] = now;
            self.input.desired[a] = self.trajectories.at(a, now);
        }
        if self
            .controller
            .update(&self.fb, &self.input, &mut self.out)
            .is_ok()
        {
            self.out.u.get(me).copied().unwrap_or(0.0)
        } else {
            0.0
        }
    }
}

/// `controller` with a disturbance observer of `dob` (unchanged for `None`).
fn attach_dob<L: ringsync_control::ControlLaw>(
    controller: Controller<L>,
    dob: Option<ringsync_control::dob::DobParams>,
) -> Result<Controller<L>, ringsync_control::ControlError> {
    match dob {
        Some(p) => controller.with_dob(ringsync_control::dob::DisturbanceObserver::new(p)?),
        None => Ok(controller),
    }
}

#[cfg(test)]
mod tests;
