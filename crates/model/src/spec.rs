//! The ring a scenario describes, built once: the cycle plan and every node's configuration
//! (the typed, validated form both drivers take). A driver may adjust the timing to what it
//! measured (the runtime's calibrated path delays and slices) before it builds its
//! [`Devices`](crate::devices::Devices).

use ringsync_plant::Encoder;
use ringsync_proto::node::{Master, MasterConfig, Slave, SlaveConfig};
use ringsync_proto::{CyclePlan, Duration, PlanKind};

use crate::axes::{ArmAxes, Axes, ServoAxes};
use crate::motion::{ControlMotion, SlaveControl, StopSettings};
use crate::scenario::{Scenario, ScenarioError};

pub(crate) fn scenario_err(key: &str, e: impl ToString) -> ScenarioError {
    ScenarioError::OutOfRange {
        key: key.into(),
        value: "?".into(),
        allowed: e.to_string(),
    }
}

/// A scenario's ring, built: what every driver needs to run it.
#[derive(Debug, Clone)]
pub struct Spec {
    /// The scenario (validated).
    pub scenario: Scenario,
    /// The cycle plan of its ring (eq. 1-2 and the event level).
    pub plan: CyclePlan,
    /// The master's schedule and limits.
    pub master: MasterConfig,
    /// Slave i's configuration at index i − 1.
    pub slaves: Vec<SlaveConfig>,
    /// Encoder resolution of each axis [rad per count].
    pub resolution: Vec<f64>,
}

impl Scenario {
    /// Validates the scenario once and builds its ring: the plan, the master's and every
    /// slave's configuration. The error names the first bad key.
    pub fn build(&self) -> Result<Spec, ScenarioError> {
        let plan = self.validated_plan()?;
        Spec::of(self, plan)
    }
}

impl Scenario {
    /// The `[monitor]` table as the motion takes it (validated: reactions parse).
    pub fn monitor_settings(&self) -> crate::monitor::MonitorSettings {
        use crate::monitor::{Limits, MonitorSettings};
        let n = self.axes_count();
        let m = &self.monitor;
        let limits = |w: &crate::scenario::schema::PerAxis,
                      t: &crate::scenario::schema::PerAxis,
                      f: crate::scenario::schema::Dur,
                      r: &str| Limits {
            warn: w.expand(n),
            trip: t.expand(n),
            filter: f.0,
            reaction: r.parse().unwrap_or_default(),
        };
        MonitorSettings {
            sync: limits(&m.sync_warn, &m.sync_trip, m.sync_filter, &m.sync_reaction),
            following: limits(
                &m.following_warn,
                &m.following_trip,
                m.following_filter,
                &m.following_reaction,
            ),
        }
    }
}

impl Spec {
    /// The configurations a validated scenario describes, with the path delays of its plan.
    fn of(s: &Scenario, plan: CyclePlan) -> Result<Self, ScenarioError> {
        let n = s.axes_count();
        let resolution = encoders(s)?
            .iter()
            .map(|e| e.resolution())
            .collect::<Vec<_>>();
        let mut master = if s.ring.plan == PlanKind::LumpedOnly {
            MasterConfig::lumped_only(&plan, resolution.clone())
        } else {
            MasterConfig::from_plan(&plan, s.ring.jitter.0, resolution.clone())
        };
        master.watchdog_cycles = s.faults.watchdog_cycles;
        let tolerance = timestamp_tolerance(s);
        master.timestamp_tolerance = tolerance;
        let t_cyc = s.ring.cycle.0;
        // A lumped frame may reach a slave up to (n + 1) hops of jitter late.
        let clock_window = tolerance + s.ring.jitter.0 * (n as i64 + 1);
        let p2p_start = match s.ring.plan {
            PlanKind::P2pLumped => master.p2p_start,
            PlanKind::LumpedOnly => Duration::ZERO,
        };
        let slaves = (0..n)
            .map(|i| {
                let a = &s.axis[i % s.axis.len()];
                SlaveConfig {
                    response_delay: s.ring.response_delay.0,
                    velocity_window: a.velocity_window.0,
                    sample_lead: s.clock.sample_lead.0,
                    watchdog_cycles: s.faults.watchdog_cycles,
                    clock_sync: s.clock.sync,
                    u_max: a.u_max,
                    resolution: resolution[i],
                    clock_window,
                    p2p_start,
                    safe_state: s.faults.safe_state,
                    brake_gain: s.faults.brake_gain,
                    ..SlaveConfig::new((i + 1) as u16, t_cyc, plan.d_c[i])
                }
            })
            .collect();
        Ok(Spec {
            scenario: s.clone(),
            plan,
            master,
            slaves,
            resolution,
        })
    }

    /// Number of axes n.
    pub fn axes(&self) -> usize {
        self.slaves.len()
    }

    /// The axes of the scenario's plant at rest at position 0, true time 0, 0 V: the
    /// independent servo axes of its `[[axis]]` tables, or the coupled two-link arm
    /// (`[plant] kind = "two-link-arm"`). The one place a driver's axes are made.
    pub fn plant(&self) -> Result<Box<dyn Axes>, ScenarioError> {
        let s = &self.scenario;
        let Some(params) = s.arm_params() else {
            let axes = ServoAxes::for_scenario(s).map_err(|e| scenario_err("axis", e))?;
            return Ok(Box::new(axes));
        };
        let encoders = encoders(s)?;
        let [e1, e2] = encoders[..] else {
            return Err(scenario_err(
                "ring.slaves",
                "2 with plant.kind = \"two-link-arm\"",
            ));
        };
        let arm = ArmAxes::new(params, [e1, e2]).map_err(|e| scenario_err("plant", e))?;
        Ok(Box::new(arm))
    }

    /// The master and the slaves of the plan (the law in the master, or in every slave with
    /// the lumped-only plan).
    pub fn nodes(&self) -> Result<(Master, Vec<Slave>), ScenarioError> {
        let s = &self.scenario;
        let law = s.law()?;
        let trajectories = s
            .trajectories()
            .map_err(|e| scenario_err("trajectory", e))?;
        let stop = StopSettings {
            following_error_limit: s.faults.following_error_limit,
            ..StopSettings::default()
        };
        let motion = ControlMotion::new(
            law,
            s.velocity_source(),
            trajectories,
            self.resolution.clone(),
            s.ring.cycle.0,
            stop,
        )
        .with_monitor(s.monitor_settings())
        .with_dob(s.dob_params())
        .map_err(|e| scenario_err("control.dob_bandwidth", e))?;
        let master = Master::new(self.master.clone(), Box::new(motion));
        let slaves = self
            .slaves
            .iter()
            .map(|cfg| {
                if s.ring.plan == PlanKind::LumpedOnly {
                    let control = SlaveControl::new(
                        s.law()?,
                        s.velocity_source(),
                        s.trajectories()
                            .map_err(|e| scenario_err("trajectory", e))?,
                        self.resolution.clone(),
                        s.ring.cycle.0,
                    )
                    .with_dob(s.dob_params())
                    .map_err(|e| scenario_err("control.dob_bandwidth", e))?;
                    Ok(Slave::with_law(cfg.clone(), Box::new(control)))
                } else {
                    Ok(Slave::new(cfg.clone()))
                }
            })
            .collect::<Result<_, ScenarioError>>()?;
        Ok((master, slaves))
    }
}

/// How far ahead of a node's clock a received timestamp may be: 50 µs (the slaves'
/// clocks follow the master's to nanoseconds in the simulator, to tens of µs over software
/// timestamps), plus, when the slaves do not synchronise, what their free-running clocks can
/// drift apart over the run.
pub fn timestamp_tolerance(s: &Scenario) -> Duration {
    let base = Duration::from_us(50);
    if s.clock.sync {
        return base;
    }
    let drift = s.clock.drift_ppm * 1e-6 * s.duration.0.as_ns() as f64;
    base + s.clock.initial_offset.0 + Duration::from_ns(drift.ceil() as i64)
}

pub(crate) fn encoders(s: &Scenario) -> Result<Vec<Encoder>, ScenarioError> {
    (0..s.axes_count())
        .map(|i| Encoder::new(1u32 << s.axis[i % s.axis.len()].encoder_bits))
        .collect::<Result<_, _>>()
        .map_err(|e| scenario_err("axis", e))
}
