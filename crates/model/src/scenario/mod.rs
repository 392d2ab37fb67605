//! Scenario files: every parameter of a run, in TOML, validated with errors that name the key,
//! the value and the allowed range.
//!
//! Every key is optional and defaults to the reference scenario `paper-2015`
//! (`scenarios/paper-2015.toml`, which a test keeps equal to [`Scenario::default`]). Unknown
//! keys are errors.

use std::fmt;
use std::str::FromStr;

use ringsync_control::{
    AxisTrajectory, ControlError, ControlLaw, Cosine, EstimatorKind, Gains, Pd, RingCoupled,
    Sequence, Sign, SyncController, SyncParams, Trapezoid, VelocitySource,
};
use ringsync_plant::{AxisModel, Friction, PlantError, SignModel, TorqueAxis, VelocityAxis};
use ringsync_proto::node::SafeState;
use ringsync_proto::plan::parse_bit_rate;
use ringsync_proto::{Duration, PlanKind, RingParams};
use serde::{Deserialize, Deserializer};

/// The built-in scenarios: (name, TOML text).
const BUILTIN: &[(&str, &str)] = &[(
    "paper-2015",
    include_str!("../../../../scenarios/paper-2015.toml"),
)];

/// Names of the built-in scenarios.
pub fn builtin_names() -> impl Iterator<Item = &'static str> {
    BUILTIN.iter().map(|(n, _)| *n)
}

/// The commented TOML text of a built-in scenario.
pub fn builtin(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// What is wrong with a scenario.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScenarioError {
    /// The text is not valid TOML, or a value has the wrong type, or a key is unknown.
    #[error("{origin}: {message}")]
    Syntax {
        /// File name or scenario name.
        origin: String,
        /// One line: where and what.
        message: String,
    },
    /// A value out of its range.
    #[error("{key} = {value} is out of range: allowed {allowed}")]
    OutOfRange {
        /// Dotted key, e.g. `ring.slaves` or `axis[2].viscous`.
        key: String,
        /// The value given.
        value: String,
        /// The allowed range, with units.
        allowed: String,
    },
    /// A name that is not a built-in scenario or a readable file.
    #[error("unknown scenario '{0}': not a built-in scenario ({1}) and no such file")]
    Unknown(String, String),
    /// The file could not be read.
    #[error("cannot read {path}: {reason}")]
    Io {
        /// Path given.
        path: String,
        /// The operating system's reason.
        reason: String,
    },
}

fn out_of_range(
    key: impl Into<String>,
    value: impl fmt::Display,
    allowed: impl Into<String>,
) -> ScenarioError {
    ScenarioError::OutOfRange {
        key: key.into(),
        value: value.to_string(),
        allowed: allowed.into(),
    }
}

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

/// `text` cut to at most `max_chars` characters, with an ellipsis where it was cut: values
/// and source lines echoed in error messages stay readable.
pub fn clip(text: &str, max_chars: usize) -> std::borrow::Cow<'_, str> {
    match text.char_indices().nth(max_chars) {
        None => text.into(),
        Some((at, _)) => format!("{}…", &text[..at]).into(),
    }
}

/// `text` cut in the middle to at most about `max_chars` characters: the start and the last
/// 60 characters stay, so a message that echoes a long value still ends with what was
/// expected.
pub fn clip_middle(text: &str, max_chars: usize) -> std::borrow::Cow<'_, str> {
    const TAIL: usize = 60;
    let n = text.chars().count();
    if n <= max_chars {
        return text.into();
    }
    let head: String = text.chars().take(max_chars.saturating_sub(TAIL)).collect();
    let tail: String = text.chars().skip(n - TAIL.min(max_chars)).collect();
    format!("{head}…{tail}").into()
}

/// Longest echo of a source line or value in a [`ScenarioError`] [characters].
pub const ECHO_CHARS: usize = 120;

/// Largest scenario file read [bytes]: 1 MiB.
pub const MAX_SCENARIO_BYTES: u64 = 1 << 20;

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
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        Duration::from_str(&s)
            .map(Dur)
            .map_err(serde::de::Error::custom)
    }
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
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum PerAxis {
    /// The same on every axis.
    One(f64),
    /// One per axis (used in turn if shorter than the ring).
    Each(Vec<f64>),
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
    /// Cable per hop [m].
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
    /// Largest oscillator error [ppm]; each slave draws uniformly in ±drift_ppm.
    pub drift_ppm: f64,
    /// Largest initial clock offset; each slave draws uniformly in ±initial_offset.
    pub initial_offset: Dur,
    /// Hardware timestamp resolution.
    pub timestamp_resolution: Dur,
    /// Sampling lead: slaves latch their encoders this long before each cycle start
    /// (EtherCAT's "input shift"); 0 samples at the cycle start, as in the paper.
    pub sample_lead: Dur,
}

impl Default for ClockSpec {
    fn default() -> Self {
        ClockSpec {
            sync: true,
            drift_ppm: 50.0,
            initial_offset: Dur(Duration::from_us(10)),
            timestamp_resolution: Dur(Duration::from_ns(8)),
            sample_lead: Dur(Duration::ZERO),
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
    /// Following-error limit [rad].
    pub following_error_limit: f64,
    /// A slave (1-based) that stops answering at `silent_from`; 0 for none.
    pub silent_slave: u32,
    /// When the silent slave goes silent.
    pub silent_from: Dur,
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
            safe_state: SafeState::Brake,
            brake_gain: 1.591,
        }
    }
}

/// Which control law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LawKind {
    /// Standard PD.
    Pd,
    /// The paper's sync controller.
    Sync,
    /// The ring-coupled baseline.
    RingCoupled,
}

impl LawKind {
    /// The name used in outputs.
    pub fn name(self) -> &'static str {
        match self {
            LawKind::Pd => "pd",
            LawKind::Sync => "sync",
            LawKind::RingCoupled => "ring-coupled",
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
}

/// `[control]`: law, estimator and gains.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlSpec {
    /// The law.
    pub law: LawKind,
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
}

fn estimator_kind<'de, D: Deserializer<'de>>(d: D) -> Result<EstimatorKind, D::Error> {
    let s = String::deserialize(d)?;
    s.parse().map_err(serde::de::Error::custom)
}

impl Default for ControlSpec {
    fn default() -> Self {
        ControlSpec {
            law: LawKind::Sync,
            estimator: EstimatorKind::Paper,
            velocity: VelocityKind::Reported,
            kp: PerAxis::One(3.182),
            kd: PerAxis::One(1.591),
            ke: PerAxis::One(0.75),
            kh: PerAxis::One(0.0),
            kc: PerAxis::One(0.0),
            alpha: 0.5,
            delta_h: 0.0,
            delta_c: 0.0,
            boundary_layer: 0.01,
            extrapolate_own: false,
        }
    }
}

/// `[trajectory]`: the desired motion of every axis.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
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
        /// Signed distance [rad].
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
    /// Drive range [V].
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
}

impl Default for Scenario {
    /// The reference scenario `paper-2015` (docs/system.md, "The reference scenario").
    fn default() -> Self {
        let r = ringsync_plant::reference::RATED_TORQUE;
        let j = ringsync_plant::reference::J_OVER_KA;
        let b = ringsync_plant::reference::VISCOUS;
        Scenario {
            name: "paper-2015".into(),
            description: "4 servo axes on a 100 Mbit/s ring, 1 ms cycle, cosine command, PD vs sync controller".into(),
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
        }
    }
}

/// "line L, column C" of byte offset `at` in `text`.
fn line_col(text: &str, at: usize) -> (usize, usize) {
    let before = &text[..at.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

impl Scenario {
    /// Parses and validates a scenario from TOML text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, ScenarioError> {
        let s: Scenario = toml::from_str(text).map_err(|e| {
            let msg = e.message().trim().replace('\n', " ");
            let msg = clip_middle(&msg, 2 * ECHO_CHARS);
            let message = match e.span() {
                Some(span) => {
                    let (l, c) = line_col(text, span.start);
                    let src = text.lines().nth(l - 1).unwrap_or("").trim();
                    format!("line {l}, column {c} ({}): {msg}", clip(src, ECHO_CHARS))
                }
                None => msg.into_owned(),
            };
            ScenarioError::Syntax {
                origin: clip(origin, ECHO_CHARS).into_owned(),
                message,
            }
        })?;
        s.validate()?;
        Ok(s)
    }

    /// A built-in scenario by name, or a scenario file by path.
    pub fn load(name_or_path: &str) -> Result<Self, ScenarioError> {
        Scenario::load_with_hash(name_or_path).map(|(s, _)| s)
    }

    /// [`Scenario::load`], with the FNV-1a 64-bit hash of the scenario's text (it names the
    /// exact input in every output).
    pub fn load_with_hash(name_or_path: &str) -> Result<(Self, u64), ScenarioError> {
        let text = Scenario::text(name_or_path)?;
        let s = Scenario::from_toml(&text, name_or_path)?;
        Ok((s, fnv1a(text.as_bytes())))
    }

    /// The TOML text of a built-in scenario or a scenario file.
    pub fn text(name_or_path: &str) -> Result<String, ScenarioError> {
        if let Some(text) = builtin(name_or_path) {
            return Ok(text.to_string());
        }
        use std::io::Read as _;
        let path = std::path::Path::new(name_or_path);
        let shown = clip(name_or_path, ECHO_CHARS).into_owned();
        if !path.exists() {
            let names: Vec<&str> = builtin_names().collect();
            return Err(ScenarioError::Unknown(shown, names.join(", ")));
        }
        let io = |reason: String| ScenarioError::Io {
            path: shown.clone(),
            reason,
        };
        // At most 1 MiB + 1 byte: /dev/zero or an endless pipe ends here, not in memory.
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|f| f.take(MAX_SCENARIO_BYTES + 1).read_to_end(&mut bytes))
            .map_err(|e| io(e.to_string()))?;
        if bytes.len() as u64 > MAX_SCENARIO_BYTES {
            return Err(io(format!(
                "larger than 1 MiB ({MAX_SCENARIO_BYTES} bytes), the limit for a scenario file"
            )));
        }
        String::from_utf8(bytes).map_err(|e| {
            io(format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ))
        })
    }

    /// Number of axes n (= slaves).
    pub fn axes_count(&self) -> usize {
        self.ring.slaves as usize
    }

    /// The cycle-plan parameters of the ring.
    pub fn ring_params(&self) -> RingParams {
        let r = &self.ring;
        RingParams {
            slaves: r.slaves,
            bit_rate_bps: r.bit_rate.0,
            phy_rx: r.phy_rx.0,
            phy_tx: r.phy_tx.0,
            cable_m: r.cable_m,
            propagation_ns_per_m: r.propagation_ns_per_m,
            residence: r.residence.0,
            response_delay: r.response_delay.0,
            t_rest: r.t_rest.0,
            t_cyc: r.cycle.0,
            ..RingParams::default()
        }
    }

    /// Checks every value; the error names the first bad key.
    pub fn validate(&self) -> Result<(), ScenarioError> {
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
        plan.check_fits_for(self.ring.plan)
            .map_err(|e| out_of_range("ring.cycle", self.ring.cycle, e.to_string()))?;
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
        if !(f.following_error_limit.is_finite() && f.following_error_limit > 0.0) {
            return Err(out_of_range(
                "faults.following_error_limit",
                f.following_error_limit,
                "> 0 rad",
            ));
        }
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
        if self.control.law != LawKind::Pd && n < 2 {
            return Err(out_of_range(
                "ring.slaves",
                n,
                format!(
                    "2 ..= 65535 with control.law = \"{}\" (coupling needs two axes)",
                    self.control.law.name()
                ),
            ));
        }
        for (key, list) in [
            ("control.kp", &self.control.kp),
            ("control.kd", &self.control.kd),
            ("control.ke", &self.control.ke),
            ("control.kh", &self.control.kh),
            ("control.kc", &self.control.kc),
        ] {
            if matches!(list, PerAxis::Each(v) if v.is_empty()) {
                return Err(out_of_range(key, "[]", "a number or a non-empty list"));
            }
        }
        // Before anything that uses the axes in turn (i % axis.len()).
        if self.axis.is_empty() {
            return Err(out_of_range("axis", "[]", "at least one [[axis]] table"));
        }
        self.law().map_err(|e| control_error(&e))?;
        for (i, a) in self.axis.iter().enumerate() {
            if ns(a.velocity_window) <= 0 || a.velocity_window.0 > self.ring.cycle.0 {
                return Err(out_of_range(
                    format!("axis[{i}].velocity_window"),
                    a.velocity_window,
                    "1 ns ..= ring.cycle",
                ));
            }
        }
        self.axis_models().map_err(|(i, e)| plant_error(i, &e))?;
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
        self.check_brake()?;
        Ok(())
    }

    /// A slave brakes its axis with u = −K_b·v, updated once a cycle (docs/safety.md):
    /// that loop must be stable for every axis. For a torque axis,
    /// v ← v·(1 − T·K_b/(J/K_a)), so T·K_b/(J/K_a) < 2; for a velocity axis (time constant
    /// τ, gain k_v), v ← v·(a − (1 − a)·k_v·K_b) with a = e^(−T/τ), so
    /// (1 − a)·k_v·K_b < 1 + a.
    fn check_brake(&self) -> Result<(), ScenarioError> {
        let t = self.ring.cycle.secs();
        let k = self.faults.brake_gain;
        if !(k.is_finite() && k > 0.0) {
            return Err(out_of_range("faults.brake_gain", k, "> 0 V·s/rad"));
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
                        "a gain the slaves' brake (u = −K_b·v once a cycle) can use on axis[{}]: its loop factor is {factor:.3}, it must stay under {bound:.3}",
                        i % self.axis.len().max(1)
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
            format!("positions up to {reach:.1} rad must fit the wire's i32 counts")
        } else {
            format!(
                "velocities up to {speed:.1} rad/s ({VELOCITY_MARGIN} × the peak speed, room for overshoot and the stop) must fit the wire's i32 counts/s"
            )
        };
        EncoderBits {
            range: MIN_ENCODER_BITS..=max.unwrap_or(MIN_ENCODER_BITS - 1),
            reason: binding,
        }
    }

    /// The largest |ẋ^d| the trajectory reaches [rad/s]: the cosine's peak speed, the
    /// profiles' v_max (an upper bound when a move is too short to reach it).
    pub fn trajectory_peak_speed(&self) -> f64 {
        match &self.trajectory {
            TrajectorySpec::Cosine { peak_speed, .. } => peak_speed.abs(),
            TrajectorySpec::Trapezoid { v_max, .. } | TrajectorySpec::Sequence { v_max, .. } => {
                v_max.abs()
            }
        }
    }

    /// The largest |x^d| the trajectory reaches [rad].
    pub fn trajectory_reach(&self) -> f64 {
        match &self.trajectory {
            TrajectorySpec::Cosine { peak_speed, period } => {
                2.0 * peak_speed * period.secs() / std::f64::consts::TAU
            }
            TrajectorySpec::Trapezoid { distance, .. } => distance.abs(),
            TrajectorySpec::Sequence { targets, .. } => {
                targets.iter().fold(0.0, |m, (x, _)| m.max(x.abs()))
            }
        }
    }

    /// The gains of all n axes.
    pub fn gains(&self) -> Gains {
        let n = self.axes_count();
        let c = &self.control;
        Gains {
            kp: c.kp.expand(n),
            kd: c.kd.expand(n),
            ke: c.ke.expand(n),
            kh: c.kh.expand(n),
            kc: c.kc.expand(n),
            // NaN without [[axis]] tables: Gains::validate rejects it.
            u_max: (0..n)
                .map(|i| self.axis_spec(i).map_or(f64::NAN, |a| a.u_max))
                .collect(),
        }
    }

    /// The `[[axis]]` table of axis `i` (0-based): the tables are used in turn; `None`
    /// when there is none.
    pub fn axis_spec(&self, i: usize) -> Option<&AxisSpec> {
        self.axis.get(i % self.axis.len().max(1))
    }

    /// Whether standard PD adds the feed-forward K_H·ẍ^d + K_C·ẋ^d: when any K_H or K_C is
    /// not zero.
    pub fn pd_feed_forward(&self) -> bool {
        let g = |p: &PerAxis| match p {
            PerAxis::One(v) => *v != 0.0,
            PerAxis::Each(v) => v.iter().any(|v| *v != 0.0),
        };
        g(&self.control.kh) || g(&self.control.kc)
    }

    /// The controller's name in outputs: the law's, `pd+ff` for standard PD with
    /// feed-forward.
    pub fn law_name(&self) -> &'static str {
        match self.control.law {
            LawKind::Pd if self.pd_feed_forward() => "pd+ff",
            other => other.name(),
        }
    }

    /// The sync controller's parameters.
    pub fn sync_params(&self) -> SyncParams {
        let c = &self.control;
        SyncParams {
            alpha: c.alpha,
            delta_h: c.delta_h,
            delta_c: c.delta_c,
            sign: if c.boundary_layer == 0.0 {
                Sign::Exact
            } else {
                Sign::BoundaryLayer(c.boundary_layer)
            },
            estimator: c.estimator,
            extrapolate_own: c.extrapolate_own,
        }
    }

    /// The control law, checked.
    pub fn law(&self) -> Result<Box<dyn ControlLaw>, ControlError> {
        let g = self.gains();
        Ok(match self.control.law {
            LawKind::Pd => Box::new(Pd::new(g, self.pd_feed_forward())?),
            LawKind::Sync => Box::new(SyncController::new(g, self.sync_params())?),
            LawKind::RingCoupled => Box::new(RingCoupled::new(
                g,
                self.control.alpha,
                self.control.estimator,
            )?),
        })
    }

    /// Where ė comes from.
    pub fn velocity_source(&self) -> VelocitySource {
        match self.control.velocity {
            VelocityKind::Reported => VelocitySource::Reported,
            VelocityKind::Differenced => VelocitySource::Differenced,
        }
    }

    /// The plant model of every axis; on error, the axis index and the error.
    pub fn axis_models(&self) -> Result<Vec<AxisModel>, (usize, PlantError)> {
        (0..self.axes_count())
            .map(|i| {
                let k = i % self.axis.len().max(1);
                let a = self.axis.get(k).ok_or((
                    k,
                    PlantError::InvalidParameter {
                        name: "axis",
                        value: 0.0,
                        expected: "at least one [[axis]] table",
                    },
                ))?;
                let model = match a.model {
                    AxisKind::Torque => {
                        let ka = a.rated_torque / a.u_max;
                        let friction = Friction {
                            viscous: a.viscous,
                            coulomb: a.coulomb_fraction * a.rated_torque,
                            sign: match a.coulomb_sign {
                                CoulombSign::Exact => SignModel::Exact,
                                CoulombSign::Smooth => SignModel::Smooth {
                                    v_s: a.coulomb_velocity_scale,
                                },
                            },
                        };
                        TorqueAxis::new(a.j_over_ka * ka, ka, friction, a.u_max)
                            .map(AxisModel::Torque)
                    }
                    AxisKind::Velocity => {
                        VelocityAxis::new(a.velocity_gain, a.time_constant.secs(), a.u_max)
                            .map(AxisModel::Velocity)
                    }
                };
                model.map_err(|e| (k, e))
            })
            .collect()
    }

    /// The desired motion of every axis.
    pub fn trajectories(&self) -> Result<Vec<AxisTrajectory>, ControlError> {
        let one = match &self.trajectory {
            TrajectorySpec::Cosine { peak_speed, period } => {
                AxisTrajectory::Cosine(Cosine::with_peak_speed(*peak_speed, period.secs())?)
            }
            TrajectorySpec::Trapezoid {
                distance,
                v_max,
                a_max,
            } => AxisTrajectory::Trapezoid(Trapezoid::new(0.0, *distance, *v_max, *a_max, 0.0)?),
            TrajectorySpec::Sequence {
                targets,
                v_max,
                a_max,
            } => AxisTrajectory::Sequence(Sequence::new(0.0, targets, *v_max, *a_max, 0.0)?),
        };
        Ok(vec![one; self.axes_count()])
    }
}

/// FNV-1a, 64 bits.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Maps a control-layer error to the scenario key it came from.
fn control_error(e: &ControlError) -> ScenarioError {
    match e {
        ControlError::InvalidParameter {
            name,
            value,
            expected,
        } => {
            // Gains are reported as kp[2]: in the scenario that is control.kp (axis 2).
            let key = match name.split_once('[') {
                Some((g, rest)) => format!("control.{g} (axis {})", rest.trim_end_matches(']')),
                None => format!("control.{name}"),
            };
            out_of_range(key, value, *expected)
        }
        other => out_of_range("control", "?", other.to_string()),
    }
}

fn plant_error(axis: usize, e: &PlantError) -> ScenarioError {
    match e {
        PlantError::InvalidParameter {
            name,
            value,
            expected,
        } => {
            if *name == "axis" {
                return out_of_range("axis", "[]", *expected);
            }
            let key = match *name {
                "inertia" | "torque_constant" => "j_over_ka, rated_torque or u_max",
                "viscous_friction" => "viscous",
                "coulomb_friction" => "coulomb_fraction",
                "velocity_gain" => "velocity_gain",
                other => other,
            };
            out_of_range(format!("axis[{axis}].{key}"), value, *expected)
        }
        other => out_of_range(format!("axis[{axis}]"), "?", other.to_string()),
    }
}

impl ScenarioError {
    fn prefixed(self, section: &str) -> ScenarioError {
        match self {
            ScenarioError::OutOfRange {
                key,
                value,
                allowed,
            } => ScenarioError::OutOfRange {
                key: key.replacen("control.", &format!("{section}."), 1),
                value,
                allowed,
            },
            other => other,
        }
    }
}

#[cfg(test)]
mod tests;
