//! The pieces of a ring that the simulator and the real-time runtime build alike from a
//! scenario: the master's and the slaves' configurations, the nodes themselves, the slaves'
//! oscillators and the servo axes with their held commands.

use ringsync_plant::{AxisModel, Encoder};
use ringsync_proto::node::{Master, MasterConfig, SafeState, Slave, SlaveConfig, SlaveEvent};
use ringsync_proto::{CyclePlan, Duration, Instant, PlanKind};

use crate::motion::{ControlMotion, SlaveControl, StopSettings};
use crate::record::{FaultStep, Recorder};
use crate::rng::Rng;
use crate::scenario::{Scenario, ScenarioError};

fn scenario_err(key: &str, e: impl ToString) -> ScenarioError {
    ScenarioError::OutOfRange {
        key: key.into(),
        value: "?".into(),
        allowed: e.to_string(),
    }
}

/// The configurations of a scenario's nodes, before the nodes are built (a runtime adjusts
/// the timing to its measured links first).
#[derive(Debug, Clone)]
pub struct RingConfig {
    /// The cycle plan of the scenario's ring (eq. 1-2 and the event level).
    pub plan: CyclePlan,
    /// The master's schedule and limits.
    pub master: MasterConfig,
    /// Slave i's configuration at index i − 1.
    pub slaves: Vec<SlaveConfig>,
    /// Encoder resolution of each axis [rad per count].
    pub resolution: Vec<f64>,
}

impl RingConfig {
    /// The configurations that the scenario describes, with the path delays of its plan.
    pub fn new(s: &Scenario) -> Result<Self, ScenarioError> {
        let n = s.axes_count();
        let plan = CyclePlan::new(&s.ring_params()).map_err(|e| scenario_err("ring", e))?;
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
        Ok(RingConfig {
            plan,
            master,
            slaves,
            resolution,
        })
    }

    /// The master and the slaves of the scenario's plan (the law in the master, or in every
    /// slave with the lumped-only plan).
    pub fn build(&self, s: &Scenario) -> Result<(Master, Vec<Slave>), ScenarioError> {
        let law = s.law().map_err(|e| scenario_err("control", e))?;
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
        );
        let master = Master::new(self.master.clone(), Box::new(motion));
        let slaves = self
            .slaves
            .iter()
            .map(|cfg| {
                if s.ring.plan == PlanKind::LumpedOnly {
                    let control = SlaveControl::new(
                        s.law().map_err(|e| scenario_err("control", e))?,
                        s.velocity_source(),
                        s.trajectories()
                            .map_err(|e| scenario_err("trajectory", e))?,
                        self.resolution.clone(),
                        s.ring.cycle.0,
                    );
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

fn encoders(s: &Scenario) -> Result<Vec<Encoder>, ScenarioError> {
    (0..s.axes_count())
        .map(|i| Encoder::new(1u32 << s.axis[i % s.axis.len()].encoder_bits))
        .collect::<Result<_, _>>()
        .map_err(|e| scenario_err("axis", e))
}

/// A slave's oscillator: its local clock reads offset + t·rate, truncated to the timestamp
/// resolution, where t is true (master) time.
#[derive(Debug, Clone, Copy)]
pub struct Oscillator {
    /// Local reading at true time 0 [ns].
    pub offset: f64,
    /// Local nanoseconds per true nanosecond (1 + drift).
    pub rate: f64,
    /// Timestamp resolution [ns], at least 1.
    pub res: i64,
}

impl Oscillator {
    /// The scenario's oscillators: slave i's offset and drift drawn uniformly within the
    /// scenario's bounds from its own seeded stream.
    pub fn for_scenario(s: &Scenario) -> Vec<Oscillator> {
        (0..s.axes_count())
            .map(|i| {
                let mut r = Rng::stream(s.seed, 1_000 + i as u64);
                Oscillator {
                    offset: r.symmetric(s.clock.initial_offset.0.as_ns() as f64),
                    rate: 1.0 + r.symmetric(s.clock.drift_ppm) * 1e-6,
                    res: s.clock.timestamp_resolution.0.as_ns().max(1),
                }
            })
            .collect()
    }

    /// The local clock's reading at true time `t` [ns].
    pub fn local(&self, t: i64) -> Instant {
        let l = floor_i64(self.offset + t as f64 * self.rate);
        if self.res == 1 {
            return Instant::from_ns(l);
        }
        if self.res & (self.res - 1) == 0 {
            // A power of two (8 ns, the reference): clearing the low bits rounds down in
            // two's complement exactly as rem_euclid does, without a division.
            return Instant::from_ns(l & !(self.res - 1));
        }
        Instant::from_ns(l - l.rem_euclid(self.res))
    }

    /// The first true time [ns] at which the local clock reads at least `l`.
    pub fn true_at(&self, l: Instant) -> i64 {
        let mut t = -floor_i64((self.offset - l.as_ns() as f64) / self.rate);
        while self.local(t) < l {
            t += 1;
        }
        t
    }
}

/// ⌊y⌋ as an integer, for |y| < 2⁶³ (simulated times are far below), without a libm call.
pub(crate) fn floor_i64(y: f64) -> i64 {
    let l = y as i64;
    if (l as f64) > y { l - 1 } else { l }
}

/// One servo axis with its encoder and the command it holds until the next one.
#[derive(Debug, Clone)]
pub struct ServoAxis {
    /// The drive and mechanics.
    pub model: AxisModel,
    /// The encoder.
    pub encoder: Encoder,
    /// Position [rad].
    pub x: f64,
    /// Velocity [rad/s].
    pub v: f64,
    /// True time of the state [ns].
    pub t: i64,
    /// Command held [V].
    pub u: f64,
}

impl ServoAxis {
    /// The scenario's axes at rest at position 0, true time 0, 0 V.
    pub fn for_scenario(s: &Scenario) -> Result<Vec<ServoAxis>, ScenarioError> {
        let models = s
            .axis_models()
            .map_err(|(i, e)| scenario_err(&format!("axis[{i}]"), e))?;
        Ok(models
            .into_iter()
            .zip(encoders(s)?)
            .map(|(model, encoder)| ServoAxis {
                model,
                encoder,
                x: 0.0,
                v: 0.0,
                t: 0,
                u: 0.0,
            })
            .collect())
    }

    /// Advances the state to true time `t` [ns] with the command held (no-op if `t` is not
    /// later than the state).
    pub fn advance(&mut self, t: i64) {
        if t > self.t {
            self.model
                .step(&mut self.x, &mut self.v, self.u, (t - self.t) as f64 * 1e-9);
            self.t = t;
        }
    }

    /// The encoder count of the current position.
    pub fn counts(&self) -> i64 {
        self.encoder.counts(self.x)
    }

    /// Acts on what slave `i` (0-based) reported at true time `t` [ns]: a command or the
    /// drive's own brake changes the held command, torque off holds 0 V; the recorder logs
    /// applied commands and every fault step. Both drivers call this.
    pub fn take(&mut self, ev: SlaveEvent, i: usize, t: i64, safe: SafeState, rec: &mut Recorder) {
        self.advance(t);
        let ts = t as f64 * 1e-9;
        match ev {
            SlaveEvent::Apply { u } => {
                self.u = u;
                rec.applied(i, ts);
            }
            SlaveEvent::Brake { u } => self.u = u,
            SlaveEvent::WatchdogExpired => {
                self.u = 0.0;
                rec.watchdog(i + 1, ts);
                rec.fault(ts, i + 1, FaultStep::Watchdog(safe));
            }
            SlaveEvent::TorqueOff { cause } => {
                self.u = 0.0;
                rec.fault(ts, i + 1, FaultStep::TorqueOff(cause));
            }
            SlaveEvent::Relocked { step } => rec.fault(ts, i + 1, FaultStep::Relocked(step)),
            SlaveEvent::Braking { ordered } => rec.fault(ts, i + 1, FaultStep::Braking { ordered }),
        }
    }
}

/// Where a ring broke, told from what each node last received (EtherCAT's working-counter
/// idea: every node keeps a counter of the frames it took, so the first node along the ring
/// whose counter stopped is behind the break, whatever the timing was).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RingBreak {
    /// Every node still received this cycle's frames: the stop did not come from the ring.
    Whole,
    /// Slave `i` (1-based) stopped running: it neither samples nor forwards.
    Node(usize),
    /// The link from node `from` to node `to` (0 = the master, i = slave i) carries
    /// nothing, though the node behind it still runs.
    Link {
        /// Sending node (0 = master).
        from: usize,
        /// Receiving node (0 = master).
        to: usize,
    },
}

impl RingBreak {
    /// One line naming the failed node or link (nodes as "master" and "slave i").
    pub fn describe(&self) -> String {
        let node = |i: usize| {
            if i == 0 {
                "master".to_string()
            } else {
                format!("slave {i}")
            }
        };
        match *self {
            RingBreak::Whole => "none: every node received the cycle's frames".into(),
            RingBreak::Node(i) => format!("slave {i} (it stopped running)"),
            RingBreak::Link { from, to } => {
                format!(
                    "link {} → {} (the node behind it still runs)",
                    node(from),
                    node(to)
                )
            }
        }
    }

    /// The failed slave (1-based), if a node failed.
    pub fn slave(&self) -> Option<usize> {
        match *self {
            RingBreak::Node(i) => Some(i),
            _ => None,
        }
    }
}

/// Where the ring broke at the master's cycle `k`: `slaves_seen[i]` is the last cycle slave
/// i + 1 took a lumped frame of, `master_seen` the last cycle whose lumped frame came back,
/// `running[i]` whether slave i + 1 still runs. A node is behind the break when it took no
/// lumped frame of the last two cycles; the first such node along the ring names it.
pub fn locate_break(
    k: i64,
    slaves_seen: &[Option<i64>],
    master_seen: Option<i64>,
    running: &[bool],
) -> RingBreak {
    let behind = |seen: Option<i64>| seen.is_none_or(|c| c < k - 1);
    for (i, seen) in slaves_seen.iter().enumerate() {
        if behind(*seen) {
            return if running.get(i).copied().unwrap_or(true) {
                RingBreak::Link { from: i, to: i + 1 }
            } else {
                RingBreak::Node(i + 1)
            };
        }
    }
    if behind(master_seen) {
        RingBreak::Link {
            from: slaves_seen.len(),
            to: 0,
        }
    } else {
        RingBreak::Whole
    }
}

/// [`locate_break`] for a ring of nodes at the master's current cycle, each node's
/// "running" told by its own heartbeat: a slave runs while its encoder latches keep up with
/// the cycles (its sample counter is within two of the master's cycle).
pub fn locate_break_of(master: &Master, slaves: &[Slave]) -> RingBreak {
    let k = master.cycle();
    let seen: Vec<Option<i64>> = slaves.iter().map(|s| s.last_lumped_cycle()).collect();
    let running: Vec<bool> = slaves.iter().map(|s| s.samples_taken() >= k - 1).collect();
    locate_break(k, &seen, master.last_lumped_cycle(), &running)
}

#[cfg(test)]
mod break_tests {
    use super::*;

    #[test]
    fn integer_floor_matches_libm_floor() {
        let mut r = crate::rng::Rng::stream(7, 7);
        for _ in 0..100_000 {
            let y = r.symmetric(1e13);
            assert_eq!(super::floor_i64(y), y.floor() as i64, "{y}");
            let z = y.round();
            assert_eq!(super::floor_i64(z), z as i64, "{z}");
        }
        for y in [-1.0, -0.5, -0.0, 0.0, 0.5, 1.0, -1e-300, 4e15 + 0.5] {
            assert_eq!(super::floor_i64(y), y.floor() as i64, "{y}");
        }
    }

    /// The oscillator's truncation to a power-of-two resolution (a mask) against rem_euclid,
    /// for negative readings too.
    #[test]
    fn power_of_two_resolution_truncates_like_rem_euclid() {
        use super::Oscillator;
        let mut r = crate::rng::Rng::stream(5, 9);
        for k in 0..100_000 {
            let res = [2i64, 8, 64, 1024][k % 4];
            let o = Oscillator {
                offset: r.symmetric(1e9),
                rate: 1.0 + r.symmetric(1e-4),
                res,
            };
            let t = r.symmetric(1e12) as i64;
            let l = super::floor_i64(o.offset + t as f64 * o.rate);
            assert_eq!(o.local(t).as_ns(), l - l.rem_euclid(res), "{o:?} t = {t}");
        }
    }

    #[test]
    fn the_first_node_that_stopped_receiving_names_the_break() {
        let k = 100;
        let all = [true; 4];
        let fresh = [Some(100), Some(100), Some(99), Some(100)];
        assert_eq!(locate_break(k, &fresh, Some(100), &all), RingBreak::Whole);
        // Slave 3 stopped receiving at cycle 90, and so did everything after it.
        let broken = [Some(100), Some(100), Some(90), Some(90)];
        assert_eq!(
            locate_break(k, &broken, Some(90), &all),
            RingBreak::Link { from: 2, to: 3 }
        );
        // The same with slave 3 dead: the node, not the link.
        let dead = [true, true, false, true];
        assert_eq!(
            locate_break(k, &broken, Some(90), &dead),
            RingBreak::Node(3)
        );
        // Nothing ever reached slave 1.
        assert_eq!(
            locate_break(k, &[None; 4], None, &all),
            RingBreak::Link { from: 0, to: 1 }
        );
        // Every slave took its frames; the master got none back.
        assert_eq!(
            locate_break(k, &fresh, Some(80), &all),
            RingBreak::Link { from: 4, to: 0 }
        );
        assert_eq!(
            RingBreak::Link { from: 4, to: 0 }.describe(),
            "link slave 4 → master (the node behind it still runs)"
        );
    }
}
