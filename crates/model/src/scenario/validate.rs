//! Checking a scenario's values: every key against its range, the cross-key rules (the
//! cycle holds the ring, the encoder resolution fits the wire, the brake's loop is stable),
//! with errors that name the first bad key.

use ringsync_proto::PlanKind;

use super::error::{ScenarioError, control_error, out_of_range, plant_error};
use super::schema::{AxisKind, Dur, PerAxis, Scenario, TrajectorySpec, VelocityKind};

/// Fewest encoder bits: the plant's encoder needs at least 4 counts per revolution.
pub const MIN_ENCODER_BITS: u32 = 2;

/// Velocities on the wire must hold this multiple of the trajectory's peak speed (room for
/// overshoot and the stop ramp) when the encoder resolution is checked.
pub const VELOCITY_MARGIN: f64 = 2.0;

/// The encoder resolutions a scenario's trajectory allows, and why not more.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EncoderBits {
    /// Allowed `encoder_bits` (empty when the motion is too large for any resolution).
    pub range: std::ops::RangeInclusive<u32>,
    /// The wire limit that bounds it from above, in words.
    pub reason: String,
}

impl EncoderBits {
    /// The allowed range in words, for an error about `value`.
    pub fn allowed(&self, value: u32) -> String {
        let (lo, hi) = (self.range.start(), self.range.end());
        if self.range.is_empty() {
            format!("none for this trajectory: {}", self.reason)
        } else if value < *lo {
            format!("{lo} ..= {hi}: an encoder needs at least 4 counts per revolution ({lo} bits)")
        } else {
            format!("{lo} ..= {hi} for this trajectory: {}", self.reason)
        }
    }
}

impl Scenario {
    /// `[monitor]`: limits ≥ 0 (0 is off), a warning below its trip, filters 0 ..= 10 s, a
    /// known reaction, and a sync monitor only on a ring of at least 2 axes.
    fn validate_monitor(&self) -> Result<(), ScenarioError> {
        let m = &self.monitor;
        let n = self.axes_count();
        for (name, warn, trip, filter, reaction) in [
            (
                "sync",
                &m.sync_warn,
                &m.sync_trip,
                m.sync_filter,
                &m.sync_reaction,
            ),
            (
                "following",
                &m.following_warn,
                &m.following_trip,
                m.following_filter,
                &m.following_reaction,
            ),
        ] {
            for (key, v) in [("warn", warn), ("trip", trip)] {
                if let PerAxis::Each(list) = v
                    && list.is_empty()
                {
                    return Err(out_of_range(
                        format!("monitor.{name}_{key}"),
                        v,
                        "a number or a non-empty list of numbers [rad]",
                    ));
                }
                for i in 0..n {
                    let x = v.get(i);
                    if !(x.is_finite() && x >= 0.0) {
                        return Err(out_of_range(
                            format!("monitor.{name}_{key}"),
                            v,
                            "≥ 0 rad on every axis (0: off)",
                        ));
                    }
                }
            }
            for i in 0..n {
                let (w, t) = (warn.get(i), trip.get(i));
                if w > 0.0 && t > 0.0 && w > t {
                    return Err(out_of_range(
                        format!("monitor.{name}_warn"),
                        warn,
                        format!("≤ monitor.{name}_trip ({trip}) on every axis where both are set"),
                    ));
                }
            }
            if filter.0.as_ns() < 0 || filter.0.as_ns() > 10_000_000_000 {
                return Err(out_of_range(
                    format!("monitor.{name}_filter"),
                    filter,
                    "0 ..= 10 s",
                ));
            }
            if reaction.parse::<crate::monitor::Reaction>().is_err() {
                return Err(out_of_range(
                    format!("monitor.{name}_reaction"),
                    format!("\"{}\"", super::error::clip(reaction, 40)),
                    "\"warn\" or \"group-stop\"",
                ));
            }
        }
        let sync_on = (0..n).any(|i| m.sync_warn.get(i) > 0.0 || m.sync_trip.get(i) > 0.0);
        if sync_on && n < 2 {
            return Err(out_of_range(
                "monitor.sync_warn",
                &m.sync_warn,
                "0 on a ring of one axis (ε needs at least 2 axes)",
            ));
        }
        Ok(())
    }

    /// Checks every value; the error names the first bad key.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        self.validated_plan().map(|_| ())
    }

    /// [`Scenario::validate`], returning the cycle plan it built on the way (so that
    /// building a scenario plans its ring once).
    pub(crate) fn validated_plan(&self) -> Result<ringsync_proto::CyclePlan, ScenarioError> {
        let ns = |d: Dur| d.0.as_ns();
        if ns(self.duration) <= 0 || ns(self.duration) > 3_600_000_000_000 {
            return Err(out_of_range("duration", self.duration, "1 ns ..= 3600 s"));
        }
        // The ring: the planner's own checks, with scenario key names.
        let plan = ringsync_proto::CyclePlan::new(&self.ring_params()).map_err(|e| match e {
            ringsync_proto::PlanError::OutOfRange {
                field,
                value,
                allowed,
            } => {
                let key = match field {
                    "t_cyc" => "cycle",
                    "slot_bytes" | "lumped_only_slot_bytes" | "mtu" => field,
                    other => other,
                };
                out_of_range(format!("ring.{key}"), value, allowed)
            }
            other => out_of_range("ring", "?", other.to_string()),
        })?;
        // A run shorter than a cycle has no cycle: its metrics would be zeros, not results.
        if self.duration.0 < self.ring.cycle.0 {
            return Err(out_of_range(
                "duration",
                self.duration,
                format!(
                    "at least one cycle (ring.cycle = {}) ..= 3600 s",
                    self.ring.cycle
                ),
            ));
        }
        plan.check_fits_for(self.ring.plan).map_err(|e| match e {
            ringsync_proto::PlanError::CycleTooShort {
                slaves,
                needed,
                short,
                basis,
                ..
            } => out_of_range(
                "ring.cycle",
                self.ring.cycle,
                format!(
                    "at least {needed} for {slaves} slaves (the plan's {basis}; short by {short})"
                ),
            ),
            other => out_of_range("ring.cycle", self.ring.cycle, other.to_string()),
        })?;
        // Each link the scenario breaks: the broken ring's cycle must fit too, or the master
        // would drop the last slices and stop the group for the want of a response.
        for b in &self.faults.break_link {
            if let Some(br) = plan.broken(b.link)
                && br.t_idle.is_negative()
            {
                return Err(out_of_range(
                    "faults.break_link",
                    b,
                    format!(
                        "a break whose cycle fits: with link {} broken the ring needs {} (docs/planner.md, \"A broken link\"), ring.cycle is {}",
                        b.link, br.min_t_cyc, self.ring.cycle.0
                    ),
                ));
            }
        }
        if ns(self.ring.jitter) < 0 || self.ring.jitter.0 > self.ring.cycle.0 {
            return Err(out_of_range(
                "ring.jitter",
                self.ring.jitter,
                "0 ..= ring.cycle",
            ));
        }
        let c = &self.clock;
        if !(c.drift_ppm.is_finite() && (0.0..=1000.0).contains(&c.drift_ppm)) {
            return Err(out_of_range(
                "clock.drift_ppm",
                c.drift_ppm,
                "0 ..= 1000 ppm",
            ));
        }
        if ns(c.initial_offset) < 0 || ns(c.initial_offset) > 1_000_000_000 {
            return Err(out_of_range(
                "clock.initial_offset",
                c.initial_offset,
                "0 ..= 1 s",
            ));
        }
        if ns(c.timestamp_resolution) < 1 || ns(c.timestamp_resolution) > 1_000_000 {
            return Err(out_of_range(
                "clock.timestamp_resolution",
                c.timestamp_resolution,
                "1 ns ..= 1 ms",
            ));
        }
        if ns(c.sample_lead) < 0 || c.sample_lead.0 * 2 > self.ring.cycle.0 {
            return Err(out_of_range(
                "clock.sample_lead",
                c.sample_lead,
                "0 ..= ring.cycle / 2",
            ));
        }
        let f = &self.faults;
        for (key, p) in [("faults.loss", f.loss), ("faults.corruption", f.corruption)] {
            if !(p.is_finite() && (0.0..=1.0).contains(&p)) {
                return Err(out_of_range(key, p, "0 ..= 1 (a probability)"));
            }
        }
        if !(1..=100_000).contains(&f.watchdog_cycles) {
            return Err(out_of_range(
                "faults.watchdog_cycles",
                f.watchdog_cycles,
                "1 ..= 100000",
            ));
        }
        if f.silent_slave > self.ring.slaves {
            return Err(out_of_range(
                "faults.silent_slave",
                f.silent_slave,
                "0 (none) ..= ring.slaves",
            ));
        }
        if f.silent_from.0.is_negative() {
            return Err(out_of_range(
                "faults.silent_from",
                f.silent_from,
                ">= 0 s (from the run's start)",
            ));
        }
        for b in &f.break_link {
            if !(1..=self.ring.slaves + 1).contains(&b.link) {
                return Err(out_of_range(
                    "faults.break_link",
                    b,
                    "links 1 ..= ring.slaves + 1 (link I joins node I-1 to node I; 0 and n+1 are the master)",
                ));
            }
        }
        if !f.break_link.is_empty() && self.ring.plan != PlanKind::P2pLumped {
            return Err(out_of_range(
                "faults.break_link",
                f.break_link[0],
                "breaks only with ring.plan = \"p2p-lumped\" (the lumped-only plan has no ring redundancy yet)",
            ));
        }
        if !(f.following_error_limit.is_finite() && f.following_error_limit > 0.0) {
            return Err(out_of_range(
                "faults.following_error_limit",
                f.following_error_limit,
                "> 0 rad",
            ));
        }
        self.validate_monitor()?;
        let n = self.axes_count();
        let cap = ringsync_wire::lumped::slot_capacity(
            <ringsync_wire::LumpedOnlySlot as ringsync_wire::SlotCodec>::LEN,
        );
        if self.ring.plan == PlanKind::LumpedOnly && n > cap {
            return Err(out_of_range(
                "ring.slaves",
                n,
                format!(
                    "1 ..= {cap} with ring.plan = \"lumped-only\": one lumped frame carries at most {cap} slaves"
                ),
            ));
        }
        let law = self.law_entry()?;
        if n < law.min_axes {
            let why = if law.min_axes == 2 {
                "coupling needs two axes".to_string()
            } else {
                format!("the law needs at least {} axes", law.min_axes)
            };
            return Err(out_of_range(
                "ring.slaves",
                n,
                format!(
                    "{} ..= 65535 with control.law = \"{}\" ({why})",
                    law.min_axes, law.name
                ),
            ));
        }
        for (key, list) in [
            ("control.kp", &self.control.kp),
            ("control.kd", &self.control.kd),
            ("control.ke", &self.control.ke),
            ("control.kh", &self.control.kh),
            ("control.kc", &self.control.kc),
            ("control.kf", &self.control.kf),
        ] {
            if matches!(list, PerAxis::Each(v) if v.is_empty()) {
                return Err(out_of_range(key, "[]", "a number or a non-empty list"));
            }
            // A longer list than the ring has axes would leave values unused, unsaid.
            if let PerAxis::Each(v) = list
                && v.len() > n
            {
                return Err(out_of_range(
                    key,
                    list,
                    format!(
                        "a number or a list of at most {n} (one per axis of ring.slaves = {n}; a shorter list is used in turn)"
                    ),
                ));
            }
        }
        // Before anything that uses the axes in turn (i % axis.len()).
        if self.axis.is_empty() {
            return Err(out_of_range("axis", "[]", "at least one [[axis]] table"));
        }
        self.law()?;
        for (i, a) in self.axis.iter().enumerate() {
            // The keys the plant derives its inertia and torque constant from, each named
            // on its own before the plant sees their quotients.
            if a.model == AxisKind::Torque {
                for (key, v, unit) in [
                    ("rated_torque", a.rated_torque, "N·m"),
                    ("j_over_ka", a.j_over_ka, "s²·V/rad"),
                    ("u_max", a.u_max, "V"),
                ] {
                    if !(v.is_finite() && v > 0.0) {
                        return Err(out_of_range(
                            format!("axis[{i}].{key}"),
                            super::error::short_number(v),
                            format!("> 0 {unit}"),
                        ));
                    }
                }
            }
            if ns(a.velocity_window) <= 0 || a.velocity_window.0 > self.ring.cycle.0 {
                return Err(out_of_range(
                    format!("axis[{i}].velocity_window"),
                    a.velocity_window,
                    "1 ns ..= ring.cycle",
                ));
            }
        }
        self.axis_models().map_err(|(i, e)| plant_error(i, &e))?;
        self.validate_machine()?;
        self.trajectories()
            .map_err(|e| control_error(&e).prefixed("trajectory"))?;
        let bits = self.encoder_bits_range();
        for (i, a) in self.axis.iter().enumerate() {
            if !bits.range.contains(&a.encoder_bits) {
                return Err(out_of_range(
                    format!("axis[{i}].encoder_bits"),
                    a.encoder_bits,
                    bits.allowed(a.encoder_bits),
                ));
            }
        }
        // The observer's bandwidth counts only where the observer runs (a ring with a long
        // cycle and another velocity source keeps the default).
        let nyquist = 0.5 / self.ring.cycle.secs();
        let fb = self.control.observer_bandwidth;
        if self.control.velocity == VelocityKind::Observer && !(fb > 0.0 && fb <= nyquist) {
            return Err(out_of_range(
                "control.observer_bandwidth",
                fb,
                format!("> 0 Hz ..= {nyquist} Hz (half the cycle rate)"),
            ));
        }
        if let Some(p) = self.dob_params() {
            let fq = p.bandwidth_hz;
            if !(fq > 0.0 && fq <= nyquist) {
                return Err(out_of_range(
                    "control.dob_bandwidth",
                    fq,
                    format!("0 (none), or > 0 Hz ..= {nyquist} Hz (half the cycle rate)"),
                ));
            }
            if self.pd_kf_set() {
                return Err(out_of_range(
                    "control.kf",
                    &self.control.kf,
                    "0 with control.dob_bandwidth > 0: the disturbance observer cancels the Coulomb friction itself, K_F would count it twice",
                ));
            }
            ringsync_control::dob::DisturbanceObserver::new(p).map_err(|e| control_error(&e))?;
        }
        self.validate_plant()?;
        self.check_brake()?;
        Ok(plan)
    }

    /// A slave brakes its axis with u = −K_b·v, updated once a cycle (docs/safety.md):
    /// that loop must be stable for every axis. For a torque axis,
    /// v ← v·(1 − T·K_b/(J/K_a)), so T·K_b/(J/K_a) < 2; for a velocity axis (time constant
    /// τ, gain k_v), v ← v·(a − (1 − a)·k_v·K_b) with a = e^(−T/τ), so
    /// (1 − a)·k_v·K_b < 1 + a. The two-link arm has its own (`ArmSpec`'s).
    fn check_brake(&self) -> Result<(), ScenarioError> {
        let t = self.ring.cycle.secs();
        let k = self.faults.brake_gain;
        if !(k.is_finite() && k > 0.0) {
            return Err(out_of_range("faults.brake_gain", k, "> 0 V·s/rad"));
        }
        if let Some(arm) = self.plant.arm() {
            return arm.check_brake(t, k);
        }
        for i in 0..self.axes_count() {
            let Some(a) = self.axis_spec(i) else { continue };
            let (factor, bound) = match a.model {
                AxisKind::Torque => (t * k / a.j_over_ka, 2.0),
                AxisKind::Velocity => {
                    let e = (-t / a.time_constant.secs()).exp();
                    ((1.0 - e) * a.velocity_gain * k, 1.0 + e)
                }
            };
            if factor >= bound {
                return Err(out_of_range(
                    "faults.brake_gain",
                    k,
                    format!(
                        "a gain the slaves' brake (u = −K_b·v once a cycle of ring.cycle = {}) can use on axis[{}]: its loop factor is {}, it must stay under {bound:.3}",
                        self.ring.cycle.0,
                        i % self.axis.len().max(1),
                        super::error::fixed(factor, 3)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The encoder resolutions this scenario's trajectory allows. The plant's encoder needs
    /// at least 4 counts per revolution (2 bits). Positions travel as i32 counts and
    /// velocities as i32 counts/s (docs/wire.md): the trajectory's reach plus 1 rad, and
    /// [`VELOCITY_MARGIN`] × its peak speed (room for overshoot and the stop ramp), must fit.
    pub fn encoder_bits_range(&self) -> EncoderBits {
        let reach = self.trajectory_reach() + 1.0;
        let speed = VELOCITY_MARGIN * self.trajectory_peak_speed();
        let limit = f64::from(i32::MAX);
        let counts = |x: f64, bits: u32| x / std::f64::consts::TAU * f64::from(1u32 << bits);
        let fits_x = |b: u32| counts(reach, b) < limit;
        let fits_v = |b: u32| counts(speed, b) < limit;
        let max = (MIN_ENCODER_BITS..=31)
            .rev()
            .find(|&b| fits_x(b) && fits_v(b));
        let next = max.map_or(MIN_ENCODER_BITS, |m| m + 1);
        // The constraint that the next resolution up breaks (velocity first: it binds first
        // for any motion faster than about 1 rad/s).
        let binding = if next <= 31 && fits_v(next) {
            format!(
                "positions up to {} rad must fit the wire's i32 counts",
                super::error::fixed(reach, 1)
            )
        } else {
            format!(
                "velocities up to {} rad/s ({VELOCITY_MARGIN} × the peak speed, room for overshoot and the stop) must fit the wire's i32 counts/s",
                super::error::fixed(speed, 1)
            )
        };
        EncoderBits {
            range: MIN_ENCODER_BITS..=max.unwrap_or(MIN_ENCODER_BITS - 1),
            reason: binding,
        }
    }

    /// `[machine]` and a part program: the machine's keys, then the program found,
    /// interpreted and planned (its errors name the file, line and column); a `[machine]`
    /// table only with a program, which is what it is for.
    fn validate_machine(&self) -> Result<(), ScenarioError> {
        let program = matches!(self.trajectory, TrajectorySpec::Program { .. });
        if self.machine.is_some() && !program {
            return Err(out_of_range(
                "machine",
                "[machine]",
                "a [machine] table with trajectory.kind = \"program\" (it maps a part program's X, Y, Z to the ring's axes)",
            ));
        }
        self.machine_map()?;
        self.planned_path()?;
        Ok(())
    }

    /// The largest |ẋ^d| the trajectory reaches [rad/s]: the cosine's peak speed, the
    /// profiles' v_max (an upper bound when a move is too short to reach it); for a part
    /// program, the fastest drive's speed at its machine axis's v_max.
    pub fn trajectory_peak_speed(&self) -> f64 {
        match &self.trajectory {
            TrajectorySpec::Cosine { peak_speed, .. } => peak_speed.abs(),
            TrajectorySpec::Trapezoid { v_max, .. } | TrajectorySpec::Sequence { v_max, .. } => {
                v_max.abs()
            }
            TrajectorySpec::Program { .. } => match self.machine_map() {
                Ok(Some(m)) => m
                    .axes
                    .iter()
                    .flat_map(|a| a.drives.iter().map(|(_, k)| a.limits.v_max * k.abs()))
                    .fold(0.0, f64::max),
                _ => 0.0,
            },
        }
    }

    /// The largest |x^d| the trajectory reaches \[rad\].
    pub fn trajectory_reach(&self) -> f64 {
        match &self.trajectory {
            TrajectorySpec::Cosine { peak_speed, period } => {
                2.0 * peak_speed * period.secs() / std::f64::consts::TAU
            }
            TrajectorySpec::Trapezoid { distance, .. } => distance.abs(),
            TrajectorySpec::Sequence { targets, .. } => {
                targets.iter().fold(0.0, |m, (x, _)| m.max(x.abs()))
            }
            TrajectorySpec::Program { .. } => {
                let (Ok(Some(m)), Ok(Some(path))) = (self.machine_map(), self.planned_path())
                else {
                    return 0.0;
                };
                // Every piece's end points, and an arc's centre ± radius: a bound on how far
                // each coordinate goes.
                let mut reach = [0.0f64; 3];
                for pc in path.pieces() {
                    let (lo, hi) = pc.curve.extent();
                    for c in 0..3 {
                        reach[c] = reach[c].max(lo[c].abs()).max(hi[c].abs());
                    }
                }
                m.axes
                    .iter()
                    .flat_map(|a| a.drives.iter().map(|(_, k)| reach[a.coord] * k.abs()))
                    .fold(0.0, f64::max)
            }
        }
    }
}
