//! The scenario's schema: every table and key of a scenario file with its default (the
//! reference scenario `paper-2015`), as plain data. Checking the values is
//! [`validate`](super::validate)'s job; making the run's objects from them is
//! [`build`](super::build)'s.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use ringsync_control::EstimatorKind;
use ringsync_proto::node::{Port, SafeState};
use ringsync_proto::plan::parse_bit_rate;
use ringsync_proto::{Duration, PlanKind, RingParams};
use serde::{Deserialize, Deserializer};

/// A duration written with a unit, e.g. `"1ms"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dur(pub Duration);

impl Dur {
    /// In seconds.
    pub fn secs(self) -> f64 {
        self.0.as_ns() as f64 * 1e-9
    }
}

impl fmt::Display for Dur {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "\"{}\"", self.0)
    }
}

impl<'de> Deserialize<'de> for Dur {
    /// A string with a unit; a bare number is an error that says a unit is needed (not
    /// serde's "expected a string").
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl serde::de::Visitor<'_> for Visit {
            type Value = Dur;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a duration with a unit, e.g. \"4s\", \"1ms\", \"125us\"")
            }
            fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<Dur, E> {
                Duration::from_str(s).map(Dur).map_err(E::custom)
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Dur, E> {
                Err(E::custom(format!(
                    "{v} has no unit: a duration is a string with its unit, e.g. \"{v}s\" or \"{v}ms\" (units s, ms, us, ns)"
                )))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Dur, E> {
                Err(E::custom(format!(
                    "{v} has no unit: a duration is a string with its unit, e.g. \"{v}s\" or \"{v}ms\" (units s, ms, us, ns)"
                )))
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Dur, E> {
                let v = super::error::short_number(v);
                Err(E::custom(format!(
                    "{v} has no unit: a duration is a string with its unit, e.g. \"{v}s\" or \"{v}ms\" (units s, ms, us, ns)"
                )))
            }
        }
        d.deserialize_any(Visit)
    }
}

/// A link of the ring that breaks at `at` and heals at `heal` (or never), written
/// `"I@T"` or `"I@T..T2"`, e.g. `"2@2s"`, `"2@2s..3s"`. Link I (1..=n+1) joins node I−1 to
/// node I, node 0 and node n+1 being the master's ports A and B (docs/planner.md, "A
/// broken link").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinkBreak {
    /// The link, 1..=n+1.
    pub link: u32,
    /// When it breaks (from the run's start).
    pub at: Duration,
    /// When it heals, if it does.
    pub heal: Option<Duration>,
}

impl LinkBreak {
    /// Whether the link is broken at true time `t` \[ns\].
    pub fn broken_at(&self, t: i64) -> bool {
        t >= self.at.as_ns() && self.heal.is_none_or(|h| t < h.as_ns())
    }

    /// When the master's own links go down and come up on a ring of `n` slaves with
    /// `breaks` (link 1 at port A, link n + 1 at port B), as its PHYs would tell it:
    /// (true time \[ns\], port, up), in time order.
    pub fn port_changes(breaks: &[LinkBreak], n: usize) -> Vec<(i64, Port, bool)> {
        let mut v = Vec::new();
        for b in breaks {
            let port = match b.link as usize {
                1 => Port::A,
                l if l == n + 1 => Port::B,
                _ => continue,
            };
            v.push((b.at.as_ns(), port, false));
            if let Some(h) = b.heal {
                v.push((h.as_ns(), port, true));
            }
        }
        v.sort_by_key(|c| c.0);
        v
    }
}

impl FromStr for LinkBreak {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = |why: &str| {
            format!(
                "'{s}' is not a link break: {why} (write I@T or I@T..T2, e.g. \"2@2s\" or \"2@2s..3s\")"
            )
        };
        let (link, when) = s.split_once('@').ok_or_else(|| bad("no '@'"))?;
        let link: u32 = link
            .trim()
            .parse()
            .map_err(|_| bad("the link is not a whole number"))?;
        let (at, heal) = match when.split_once("..") {
            Some((a, h)) => (a, Some(h)),
            None => (when, None),
        };
        let time = |t: &str| Duration::from_str(t.trim()).map_err(|e| bad(&e.to_string()));
        let at = time(at)?;
        let heal = heal.map(time).transpose()?;
        if at.is_negative() {
            return Err(bad("the time is negative"));
        }
        if let Some(h) = heal
            && h <= at
        {
            return Err(bad("it heals before it breaks"));
        }
        Ok(LinkBreak { link, at, heal })
    }
}

impl fmt::Display for LinkBreak {
    /// As written: `I@Ts` or `I@Ts..T2s`, times in seconds.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let secs = |d: Duration| d.as_ns() as f64 * 1e-9;
        write!(f, "{}@{}s", self.link, secs(self.at))?;
        if let Some(h) = self.heal {
            write!(f, "..{}s", secs(h))?;
        }
        Ok(())
    }
}

/// `faults.break_link`: one break or a list of them.
fn link_breaks<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<LinkBreak>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Raw {
        One(String),
        Many(Vec<String>),
    }
    let list = match Raw::deserialize(d).map_err(|_| {
        serde::de::Error::custom("expected a link break \"I@T\" or \"I@T..T2\", or a list of them")
    })? {
        Raw::One(s) => vec![s],
        Raw::Many(v) => v,
    };
    list.iter()
        .map(|s| s.parse().map_err(serde::de::Error::custom))
        .collect()
}

/// A bit rate written as `"100M"` or a number of bit/s.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BitRate(pub u64);

impl<'de> Deserialize<'de> for BitRate {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(u64),
            Text(String),
        }
        match Raw::deserialize(d)? {
            Raw::Number(n) => Ok(BitRate(n)),
            Raw::Text(s) => parse_bit_rate(&s)
                .map(BitRate)
                .map_err(serde::de::Error::custom),
        }
    }
}

/// One value for every axis, or one per axis.
#[derive(Debug, Clone, PartialEq)]
pub enum PerAxis {
    /// The same on every axis.
    One(f64),
    /// One per axis (used in turn if shorter than the ring).
    Each(Vec<f64>),
}

impl<'de> Deserialize<'de> for PerAxis {
    /// A number (integer or float) or a list of numbers; anything else is an error that
    /// says so.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = PerAxis;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number (the same on every axis) or a list of numbers (one per axis)")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<PerAxis, E> {
                Ok(PerAxis::One(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<PerAxis, E> {
                Ok(PerAxis::One(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<PerAxis, E> {
                Ok(PerAxis::One(v as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut a: A,
            ) -> Result<PerAxis, A::Error> {
                let mut v = Vec::with_capacity(a.size_hint().unwrap_or(0));
                while let Some(x) = a.next_element::<f64>()? {
                    v.push(x);
                }
                Ok(PerAxis::Each(v))
            }
        }
        d.deserialize_any(Visit)
    }
}

impl PerAxis {
    /// The value for axis `i`.
    pub fn get(&self, i: usize) -> f64 {
        match self {
            PerAxis::One(v) => *v,
            PerAxis::Each(v) if v.is_empty() => f64::NAN,
            PerAxis::Each(v) => v[i % v.len()],
        }
    }
    /// The values for `n` axes.
    pub fn expand(&self, n: usize) -> Vec<f64> {
        (0..n).map(|i| self.get(i)).collect()
    }
}

impl fmt::Display for PerAxis {
    /// As written: `3.5` or `[1, 2.5]`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PerAxis::One(v) => write!(f, "{v}"),
            PerAxis::Each(v) => {
                let items: Vec<String> = v.iter().map(f64::to_string).collect();
                write!(f, "[{}]", items.join(", "))
            }
        }
    }
}

/// `[ring]`: the network and the cycle plan.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ring {
    /// Number of slaves n.
    pub slaves: u32,
    /// Cycle time T_cyc.
    pub cycle: Dur,
    /// Communication plan.
    #[serde(deserialize_with = "plan_kind")]
    pub plan: PlanKind,
    /// Link bit rate [bit/s].
    pub bit_rate: BitRate,
    /// PHY receive latency.
    pub phy_rx: Dur,
    /// PHY transmit latency.
    pub phy_tx: Dur,
    /// Cable per hop \[m\].
    pub cable_m: f64,
    /// Propagation [ns/m].
    pub propagation_ns_per_m: f64,
    /// Residence T_t.
    pub residence: Dur,
    /// Response delay T_ti.
    pub response_delay: Dur,
    /// T_rest.
    pub t_rest: Dur,
    /// Extra random delay per hop, uniform in [0, jitter].
    pub jitter: Dur,
}

fn plan_kind<'de, D: Deserializer<'de>>(d: D) -> Result<PlanKind, D::Error> {
    let s = String::deserialize(d)?;
    s.parse().map_err(serde::de::Error::custom)
}

impl Default for Ring {
    fn default() -> Self {
        let p = RingParams::default();
        Ring {
            slaves: p.slaves,
            cycle: Dur(p.t_cyc),
            plan: PlanKind::P2pLumped,
            bit_rate: BitRate(p.bit_rate_bps),
            phy_rx: Dur(p.phy_rx),
            phy_tx: Dur(p.phy_tx),
            cable_m: p.cable_m,
            propagation_ns_per_m: p.propagation_ns_per_m,
            residence: Dur(p.residence),
            response_delay: Dur(p.response_delay),
            t_rest: Dur(p.t_rest),
            jitter: Dur(Duration::ZERO),
        }
    }
}

/// `[clock]`: the slaves' oscillators and clock synchronisation.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClockSpec {
    /// Whether slaves synchronise to the master.
    pub sync: bool,
    /// Largest oscillator error \[ppm\]; each slave draws uniformly in ±drift_ppm.
    pub drift_ppm: f64,
    /// Largest initial clock offset; each slave draws uniformly in ±initial_offset.
    pub initial_offset: Dur,
    /// Hardware timestamp resolution.
    pub timestamp_resolution: Dur,
    /// Sampling lead: slaves latch their encoders this long before each cycle start
    /// (EtherCAT's "input shift"); 0 samples at the cycle start, as in the paper.
    pub sample_lead: Dur,
    /// Where each slave's path delay D_i comes from: "plan" (the planner's event-level
    /// figure, as configured) or "measured" (the nodes' start-up phase measures it before
    /// the run, docs/planner.md "Delays measured by the nodes").
    #[serde(deserialize_with = "path_delays")]
    pub path_delays: PathDelays,
}

/// Where the slaves' path delays come from (`clock.path_delays`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PathDelays {
    /// The planner's event-level figures, configured in each slave.
    #[default]
    Plan,
    /// Measured by the nodes in a start-up phase before the run.
    Measured,
}

impl PathDelays {
    /// The name used in scenarios and outputs.
    pub fn name(self) -> &'static str {
        match self {
            PathDelays::Plan => "plan",
            PathDelays::Measured => "measured",
        }
    }
}

impl std::str::FromStr for PathDelays {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "plan" => Ok(PathDelays::Plan),
            "measured" => Ok(PathDelays::Measured),
            other => Err(format!(
                "unknown path delay source '{other}': use \"plan\" or \"measured\""
            )),
        }
    }
}

fn path_delays<'de, D: Deserializer<'de>>(d: D) -> Result<PathDelays, D::Error> {
    let s = String::deserialize(d)?;
    s.parse().map_err(serde::de::Error::custom)
}

impl Default for ClockSpec {
    fn default() -> Self {
        ClockSpec {
            sync: true,
            drift_ppm: 50.0,
            initial_offset: Dur(Duration::from_us(10)),
            timestamp_resolution: Dur(Duration::from_ns(8)),
            sample_lead: Dur(Duration::ZERO),
            path_delays: PathDelays::Plan,
        }
    }
}

/// `[faults]`: loss, corruption and the safety limits.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Faults {
    /// Probability that a frame is lost on one trip round the ring (spread over its n + 1
    /// hops).
    pub loss: f64,
    /// Probability that a frame is corrupted on one trip round the ring.
    pub corruption: f64,
    /// W: cycles without a valid command before a slave goes to its safe state.
    pub watchdog_cycles: u32,
    /// Following-error limit \[rad\].
    pub following_error_limit: f64,
    /// A slave (1-based) that stops answering at `silent_from`; 0 for none.
    pub silent_slave: u32,
    /// When the silent slave goes silent.
    pub silent_from: Dur,
    /// Links of the ring that break (and heal): `"I@T"` or `"I@T..T2"`, one or a list
    /// ([`LinkBreak`]). The master reaches every slave from both ends of a ring broken
    /// once; a second break cuts slaves off and stops the group.
    #[serde(deserialize_with = "link_breaks")]
    pub break_link: Vec<LinkBreak>,
    /// What a slave does with its axis when it loses the master (no valid command for W
    /// cycles): "brake" damps the axis to standstill, then cuts torque; "torque-off" cuts
    /// torque at once.
    #[serde(deserialize_with = "safe_state")]
    pub safe_state: SafeState,
    /// K_b of the brake reaction u = −K_b·v (the safe state "brake", or a brake the master
    /// orders) [V·s/rad].
    pub brake_gain: f64,
}

fn safe_state<'de, D: Deserializer<'de>>(d: D) -> Result<SafeState, D::Error> {
    let s = String::deserialize(d)?;
    s.parse().map_err(serde::de::Error::custom)
}

impl Default for Faults {
    fn default() -> Self {
        Faults {
            loss: 0.0,
            corruption: 0.0,
            watchdog_cycles: 5,
            following_error_limit: 1.0,
            silent_slave: 0,
            silent_from: Dur(Duration::ZERO),
            break_link: Vec::new(),
            safe_state: SafeState::Brake,
            brake_gain: 1.591,
        }
    }
}

/// `[monitor]`: drive-style supervision per axis (docs/safety.md, "The sync monitor"):
/// warning and trip limits on the sync error ε and on the following error e, each limit
/// counting once it has been exceeded without a break for the filter time. Every limit is
/// 0 (off) by default.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MonitorSpec {
    /// |ε| warning limit per axis \[rad\] (0: off).
    pub sync_warn: PerAxis,
    /// |ε| trip limit per axis \[rad\] (0: off).
    pub sync_trip: PerAxis,
    /// How long |ε| must stay beyond a limit before it counts.
    pub sync_filter: Dur,
    /// What a sync trip does: "warn" or "group-stop".
    pub sync_reaction: String,
    /// |e| warning limit per axis \[rad\] (0: off).
    pub following_warn: PerAxis,
    /// |e| trip limit per axis \[rad\] (0: off; `faults.following_error_limit` stays the
    /// instantaneous hard limit).
    pub following_trip: PerAxis,
    /// How long |e| must stay beyond a limit before it counts.
    pub following_filter: Dur,
    /// What a following-error trip does: "warn" or "group-stop".
    pub following_reaction: String,
}

impl Default for MonitorSpec {
    fn default() -> Self {
        MonitorSpec {
            sync_warn: PerAxis::One(0.0),
            sync_trip: PerAxis::One(0.0),
            sync_filter: Dur(Duration::from_ms(10)),
            sync_reaction: "group-stop".into(),
            following_warn: PerAxis::One(0.0),
            following_trip: PerAxis::One(0.0),
            following_filter: Dur(Duration::from_ms(10)),
            following_reaction: "group-stop".into(),
        }
    }
}

/// Where ė comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum VelocityKind {
    /// From the slave's reported velocity.
    Reported,
    /// From successive position samples.
    Differenced,
    /// From a tracking observer on the error samples (`control.observer_bandwidth`).
    Observer,
}

/// `[control]`: law, estimator and gains.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlSpec {
    /// The law: a name in the law registry (`ringsync_control::law::LAWS`, docs/control.md).
    #[serde(deserialize_with = "law_name")]
    pub law: String,
    /// The estimator.
    #[serde(deserialize_with = "estimator_kind")]
    pub estimator: EstimatorKind,
    /// Source of ė.
    pub velocity: VelocityKind,
    /// K_P [V/rad].
    pub kp: PerAxis,
    /// K_D [V·s/rad].
    pub kd: PerAxis,
    /// K_E [V·s/rad].
    pub ke: PerAxis,
    /// K_H [V·s²/rad].
    pub kh: PerAxis,
    /// K_C [V·s/rad].
    pub kc: PerAxis,
    /// K_F, Coulomb friction feed-forward \[V\] (not in the paper).
    pub kf: PerAxis,
    /// v_F of the Coulomb feed-forward's sat(ẋ^d/v_F) [rad/s].
    pub kf_velocity: f64,
    /// Bandwidth f_b of the error observer (`velocity = "observer"`) \[Hz\].
    pub observer_bandwidth: f64,
    /// Bandwidth f_Q of the disturbance observer \[Hz\]; 0: none (not in the paper).
    pub dob_bandwidth: f64,
    /// α.
    pub alpha: f64,
    /// Δ_H [V·s²/rad].
    pub delta_h: f64,
    /// Δ_C [V·s/rad].
    pub delta_c: f64,
    /// φ [rad/s]; 0 selects the exact sign.
    pub boundary_layer: f64,
    /// Extrapolate the own sample too.
    pub extrapolate_own: bool,
    /// `[control.params]`: the chosen law's own parameters by key (the keys its registry
    /// entry declares), each one number for every axis or a list of n.
    pub params: BTreeMap<String, PerAxis>,
}

fn law_name<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    let s = String::deserialize(d)?;
    match ringsync_control::law::registry::find(&s) {
        Some(_) => Ok(s),
        None => Err(serde::de::Error::custom(
            ringsync_control::law::registry::unknown_law(&s),
        )),
    }
}

fn estimator_kind<'de, D: Deserializer<'de>>(d: D) -> Result<EstimatorKind, D::Error> {
    let s = String::deserialize(d)?;
    s.parse().map_err(serde::de::Error::custom)
}

impl Default for ControlSpec {
    fn default() -> Self {
        ControlSpec {
            law: ringsync_control::law::sync::ENTRY.name.to_string(),
            estimator: EstimatorKind::Paper,
            velocity: VelocityKind::Reported,
            kp: PerAxis::One(3.182),
            kd: PerAxis::One(1.591),
            ke: PerAxis::One(0.75),
            kh: PerAxis::One(0.0),
            kc: PerAxis::One(0.0),
            kf: PerAxis::One(0.0),
            kf_velocity: ringsync_control::law::DEFAULT_KF_VELOCITY,
            observer_bandwidth: 100.0,
            dob_bandwidth: 0.0,
            alpha: 0.5,
            delta_h: 0.0,
            delta_c: 0.0,
            boundary_layer: 0.01,
            extrapolate_own: false,
            params: BTreeMap::new(),
        }
    }
}

/// `[trajectory]`: the desired motion of every axis. `kind` defaults to `cosine`, and a
/// cosine's missing keys to the reference scenario's (`[trajectory]` with `period = "3s"`
/// alone is the reference cosine at another period); a trapezoid or a sequence needs all
/// of its keys.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(try_from = "RawTrajectory")]
pub enum TrajectorySpec {
    /// x^d = A·(1 − cos(2πt/P)), A = peak_speed·P/(2π).
    Cosine {
        /// Peak speed [rad/s].
        peak_speed: f64,
        /// Period P.
        period: Dur,
    },
    /// One trapezoidal move from 0.
    Trapezoid {
        /// Signed distance \[rad\].
        distance: f64,
        /// v_max [rad/s].
        v_max: f64,
        /// a_max [rad/s²].
        a_max: f64,
    },
    /// Moves through `targets` = [[position rad, dwell s], …] from 0.
    Sequence {
        /// Targets and dwell times.
        targets: Vec<(f64, f64)>,
        /// v_max [rad/s].
        v_max: f64,
        /// a_max [rad/s²].
        a_max: f64,
    },
    /// A part program (G-code) on the scenario's `[machine]` (docs/programs.md).
    Program {
        /// The program file, relative to the scenario file (or a built-in program's name).
        program: String,
    },
}

/// `[trajectory]` as written: every key of every kind optional, checked against the kind
/// by [`TrajectorySpec`]'s `TryFrom`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTrajectory {
    kind: Option<String>,
    peak_speed: Option<f64>,
    period: Option<Dur>,
    distance: Option<f64>,
    v_max: Option<f64>,
    a_max: Option<f64>,
    targets: Option<Vec<(f64, f64)>>,
    program: Option<String>,
}

impl TryFrom<RawTrajectory> for TrajectorySpec {
    type Error = String;
    fn try_from(r: RawTrajectory) -> Result<Self, String> {
        let kind = r.kind.as_deref().unwrap_or("cosine");
        let given = [
            ("peak_speed", r.peak_speed.is_some()),
            ("period", r.period.is_some()),
            ("distance", r.distance.is_some()),
            ("v_max", r.v_max.is_some()),
            ("a_max", r.a_max.is_some()),
            ("targets", r.targets.is_some()),
            ("program", r.program.is_some()),
        ];
        let only = |keys: &[&str]| match given.iter().find(|(k, on)| *on && !keys.contains(k)) {
            Some((k, _)) => Err(format!(
                "unknown field `{k}` for kind = \"{kind}\", expected {}",
                keys.iter()
                    .map(|k| format!("`{k}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
            None => Ok(()),
        };
        let need = |k: &str, v: Option<f64>| {
            v.ok_or_else(|| format!("missing field `{k}` (kind = \"{kind}\" needs it)"))
        };
        match kind {
            "cosine" => {
                only(&["peak_speed", "period"])?;
                let TrajectorySpec::Cosine { peak_speed, period } = TrajectorySpec::default()
                else {
                    return Err("the reference trajectory is a cosine".into());
                };
                Ok(TrajectorySpec::Cosine {
                    peak_speed: r.peak_speed.unwrap_or(peak_speed),
                    period: r.period.unwrap_or(period),
                })
            }
            "trapezoid" => {
                only(&["distance", "v_max", "a_max"])?;
                Ok(TrajectorySpec::Trapezoid {
                    distance: need("distance", r.distance)?,
                    v_max: need("v_max", r.v_max)?,
                    a_max: need("a_max", r.a_max)?,
                })
            }
            "sequence" => {
                only(&["targets", "v_max", "a_max"])?;
                Ok(TrajectorySpec::Sequence {
                    targets: r.targets.ok_or_else(|| {
                        "missing field `targets` (kind = \"sequence\" needs it)".to_string()
                    })?,
                    v_max: need("v_max", r.v_max)?,
                    a_max: need("a_max", r.a_max)?,
                })
            }
            "program" => {
                only(&["program"])?;
                Ok(TrajectorySpec::Program {
                    program: r.program.ok_or_else(|| {
                        "missing field `program` (kind = \"program\" needs the part program's file)"
                            .to_string()
                    })?,
                })
            }
            other => Err(format!(
                "unknown variant `{other}`, expected one of `cosine`, `trapezoid`, `sequence`, `program`"
            )),
        }
    }
}

impl Default for TrajectorySpec {
    fn default() -> Self {
        TrajectorySpec::Cosine {
            peak_speed: 15.12,
            period: Dur(Duration::from_ms(2000)),
        }
    }
}

/// Drive mode of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AxisKind {
    /// Torque mode: J·ẍ = K_a·sat(u) − b·ẋ − T_c·sgn(ẋ).
    Torque,
    /// Velocity mode: ẍ = (k_v·sat(u) − ẋ)/τ_v.
    Velocity,
}

/// Sign model of Coulomb friction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CoulombSign {
    /// Exact sign with stiction.
    Exact,
    /// tanh(ẋ/v_s).
    Smooth,
}

/// One `[[axis]]` table.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AxisSpec {
    /// Drive mode.
    pub model: AxisKind,
    /// Rated torque [N·m] (torque mode): ±u_max = ± rated torque.
    pub rated_torque: f64,
    /// J/K_a [s²·V/rad] (torque mode).
    pub j_over_ka: f64,
    /// Viscous friction b [N·m·s/rad] (torque mode).
    pub viscous: f64,
    /// Coulomb friction as a fraction of rated torque (torque mode).
    pub coulomb_fraction: f64,
    /// Sign model of the Coulomb friction.
    pub coulomb_sign: CoulombSign,
    /// v_s of the smooth sign [rad/s].
    pub coulomb_velocity_scale: f64,
    /// k_v [rad/(s·V)] (velocity mode).
    pub velocity_gain: f64,
    /// τ_v (velocity mode).
    pub time_constant: Dur,
    /// Drive range \[V\].
    pub u_max: f64,
    /// Encoder resolution, 2^bits counts per revolution.
    pub encoder_bits: u32,
    /// Velocity measured by encoder difference over this window.
    pub velocity_window: Dur,
}

impl Default for AxisSpec {
    fn default() -> Self {
        AxisSpec {
            model: AxisKind::Torque,
            rated_torque: ringsync_plant::reference::RATED_TORQUE[0],
            j_over_ka: ringsync_plant::reference::J_OVER_KA[0],
            viscous: ringsync_plant::reference::VISCOUS[0],
            coulomb_fraction: ringsync_plant::reference::COULOMB_FRACTION,
            coulomb_sign: CoulombSign::Exact,
            coulomb_velocity_scale: 1e-3,
            velocity_gain: 1.5,
            time_constant: Dur(Duration::from_ms(5)),
            u_max: ringsync_plant::reference::U_MAX,
            encoder_bits: 20,
            velocity_window: Dur(Duration::from_us(125)),
        }
    }
}

/// A whole scenario.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scenario {
    /// Name, used in outputs.
    pub name: String,
    /// One line on what it is.
    pub description: String,
    /// Simulated time.
    pub duration: Dur,
    /// Seed of every random draw.
    pub seed: u64,
    /// Network and plan.
    pub ring: Ring,
    /// Oscillators and clock sync.
    pub clock: ClockSpec,
    /// Faults and limits.
    pub faults: Faults,
    /// Law and gains.
    pub control: ControlSpec,
    /// Desired motion.
    pub trajectory: TrajectorySpec,
    /// Axes, used in turn.
    pub axis: Vec<AxisSpec>,
    /// What the axes are mechanically: independent, or the joints of a coupled arm.
    pub plant: super::plant::PlantSpec,
    /// Sync-error and following-error monitors (all off by default).
    pub monitor: MonitorSpec,
    /// The machine the axes make, for part programs (none by default).
    pub machine: Option<super::machine::MachineSpec>,
    /// The directory the scenario's relative file names (its part program) are found in:
    /// the scenario file's; `None` for a scenario given as text (the working directory).
    #[serde(skip)]
    pub dir: Option<std::path::PathBuf>,
}

impl Default for Scenario {
    /// The reference scenario `paper-2015` (docs/system.md, "The reference scenario").
    fn default() -> Self {
        let r = ringsync_plant::reference::RATED_TORQUE;
        let j = ringsync_plant::reference::J_OVER_KA;
        let b = ringsync_plant::reference::VISCOUS;
        Scenario {
            name: "paper-2015".into(),
            description: "4 servo axes on a 100 Mbit/s ring, 1 ms cycle, cosine command: the paper's test bench".into(),
            duration: Dur(Duration::from_ms(4000)),
            seed: 1,
            ring: Ring::default(),
            clock: ClockSpec::default(),
            faults: Faults::default(),
            control: ControlSpec::default(),
            trajectory: TrajectorySpec::default(),
            axis: (0..4)
                .map(|i| AxisSpec { rated_torque: r[i], j_over_ka: j[i], viscous: b[i], ..AxisSpec::default() })
                .collect(),
            plant: super::plant::PlantSpec::default(),
            monitor: MonitorSpec::default(),
            machine: None,
            dir: None,
        }
    }
}
