//! Control laws behind one trait (docs/system.md, "Plant and controller" and "The motion message estimator").
//!
//! A law is a pure function of the error history and the cycle's inputs: it reads the
//! latest samples (and their history, for its estimator), the desired states at the command
//! application times (feed-forward) and those times, and writes one command per axis in
//! volts, clipped to the drive's range. [`Controller`] owns the history and turns raw
//! feedback into error samples.
//!
//! All laws are O(n) per cycle and allocate nothing after construction.
//!
//! Every law is in the [registry]: one file in this folder with its `ENTRY`, and one line in
//! the list below.

pub mod registry;

registry::laws! {
    pd,
    sync,
    ring,
    adjacent,
    ccc,
}

pub use ccc::ContourCoupled;
pub use pd::Pd;
pub use registry::{LawEntry, LawParams, ParamSpec};
pub use ring::RingCoupled;
pub use sync::{Sign, SyncController, SyncParams};

use crate::error::{ControlError, check, check_gain, check_len};
use crate::estimator::{ErrorHistory, Estimator};
use crate::trajectory::State;

/// v_F of the Coulomb feed-forward by default [rad/s]: about 1 % of the reference
/// trajectory's peak speed.
pub const DEFAULT_KF_VELOCITY: f64 = 0.1;

/// Per-axis gains (diagonal matrices as vectors) and drive limits. Gains are in volts:
/// K_P [V/rad], K_D and K_E [V·s/rad], K_C [V·s/rad], K_H [V·s²/rad].
#[derive(Debug, Clone, PartialEq)]
pub struct Gains {
    /// Proportional gain K_P [V/rad], > 0.
    pub kp: Vec<f64>,
    /// Derivative gain K_D [V·s/rad], > 0.
    pub kd: Vec<f64>,
    /// Velocity-error gain K_E of the sync controller [V·s/rad], ≥ 0.
    pub ke: Vec<f64>,
    /// Acceleration feed-forward K_H [V·s²/rad].
    pub kh: Vec<f64>,
    /// Velocity feed-forward K_C [V·s/rad].
    pub kc: Vec<f64>,
    /// Coulomb friction feed-forward K_F \[V\], ≥ 0: K_F·sat(ẋ^d / v_F) is added, so the
    /// term follows the desired velocity's sign without chattering at standstill.
    pub kf: Vec<f64>,
    /// v_F of the Coulomb feed-forward's sat(ẋ^d / v_F) [rad/s], > 0.
    pub kf_velocity: f64,
    /// Drive range ±u_max \[V\], > 0.
    pub u_max: Vec<f64>,
}

impl Gains {
    /// The same gains on every one of `n` axes, no feed-forward, ±10 V drives.
    pub fn uniform(n: usize, kp: f64, kd: f64, ke: f64) -> Self {
        Gains {
            kp: vec![kp; n],
            kd: vec![kd; n],
            ke: vec![ke; n],
            kh: vec![0.0; n],
            kc: vec![0.0; n],
            kf: vec![0.0; n],
            kf_velocity: DEFAULT_KF_VELOCITY,
            u_max: vec![10.0; n],
        }
    }

    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.kp.len()
    }

    /// Checks lengths and ranges; the error names the gain and axis, e.g. `kd[2]`.
    pub fn validate(&self) -> Result<(), ControlError> {
        let n = self.kp.len();
        for (what, v) in [
            ("kd", &self.kd),
            ("ke", &self.ke),
            ("kh", &self.kh),
            ("kc", &self.kc),
            ("kf", &self.kf),
            ("u_max", &self.u_max),
        ] {
            check_len(what, n, v.len())?;
        }
        for i in 0..n {
            check_gain(
                &format!("kp[{i}]"),
                self.kp[i],
                0.0,
                true,
                "> 0 ..= 1e12 V/rad",
            )?;
            check_gain(
                &format!("kd[{i}]"),
                self.kd[i],
                0.0,
                true,
                "> 0 ..= 1e12 V·s/rad",
            )?;
            check_gain(
                &format!("ke[{i}]"),
                self.ke[i],
                0.0,
                false,
                ">= 0 ..= 1e12 V·s/rad",
            )?;
            check_gain(
                &format!("kh[{i}]"),
                self.kh[i],
                f64::MIN,
                false,
                "-1e12 ..= 1e12 V·s²/rad",
            )?;
            check_gain(
                &format!("kc[{i}]"),
                self.kc[i],
                f64::MIN,
                false,
                "-1e12 ..= 1e12 V·s/rad",
            )?;
            check_gain(
                &format!("kf[{i}]"),
                self.kf[i],
                0.0,
                false,
                ">= 0 ..= 1e12 V",
            )?;
            check(&format!("u_max[{i}]"), self.u_max[i], 0.0, true, "> 0 V")?;
        }
        check("kf_velocity", self.kf_velocity, 0.0, true, "> 0 rad/s")?;
        Ok(())
    }

    /// Whether any feed-forward gain (K_H, K_C, K_F) is not zero.
    pub fn has_feed_forward(&self) -> bool {
        self.kh
            .iter()
            .chain(&self.kc)
            .chain(&self.kf)
            .any(|g| *g != 0.0)
    }

    /// Feed-forward K_H·ẍ^d + K_C·ẋ^d (eq. 9) + K_F·sat(ẋ^d/v_F) of axis `i` [V]. The
    /// Coulomb term is not in the paper: it cancels the axes' Coulomb friction from the
    /// desired velocity (a function of the trajectory alone, so it leaves the loop's
    /// stability unchanged).
    #[inline]
    pub(crate) fn feed_forward(&self, i: usize, d: &State) -> f64 {
        let coulomb = if self.kf[i] == 0.0 {
            0.0
        } else {
            self.kf[i] * (d.v / self.kf_velocity).clamp(-1.0, 1.0)
        };
        self.kh[i] * d.a + self.kc[i] * d.v + coulomb
    }
}

/// What a law needs besides the error history, for one cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlInput {
    /// Desired state of each axis at its command's application time (for feed-forward).
    pub desired: Vec<State>,
    /// When each axis's command takes effect \[s\], on the clock of the sample times.
    pub apply_time: Vec<f64>,
    /// Cycle time T_cyc \[s\]: the spacing of the samples in the history.
    pub t_cyc: f64,
}

impl ControlInput {
    /// Inputs for `n` axes: at rest, applied at t = 0, cycle `t_cyc` \[s\].
    pub fn new(n: usize, t_cyc: f64) -> Self {
        ControlInput {
            desired: vec![State::default(); n],
            apply_time: vec![0.0; n],
            t_cyc,
        }
    }

    pub(crate) fn check(&self, n: usize) -> Result<(), ControlError> {
        check_len("desired states", n, self.desired.len())?;
        check_len("apply times", n, self.apply_time.len())?;
        check("t_cyc", self.t_cyc, 0.0, true, "> 0 s")?;
        Ok(())
    }
}

/// The commands of one cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlOutput {
    /// Command per axis after clipping to ±u_max \[V\].
    pub u: Vec<f64>,
    /// The command before clipping \[V\].
    pub u_raw: Vec<f64>,
    /// Whether the command was clipped.
    pub saturated: Vec<bool>,
    /// Per-axis scratch of the laws (estimated slopes, sample instants): lets a law keep
    /// pass-one results for pass two without allocating.
    pub(crate) work: Vec<[f64; 3]>,
}

impl ControlOutput {
    /// Zero commands for `n` axes.
    pub fn new(n: usize) -> Self {
        ControlOutput {
            u: vec![0.0; n],
            u_raw: vec![0.0; n],
            saturated: vec![false; n],
            work: vec![[0.0; 3]; n],
        }
    }

    /// Stores the raw command of axis `i` and its clipped value.
    #[inline]
    pub(crate) fn set(&mut self, i: usize, raw: f64, u_max: f64) {
        let (u, sat) = ringsync_plant::saturate(raw, u_max);
        self.u_raw[i] = raw;
        self.u[i] = u;
        self.saturated[i] = sat;
    }

    pub(crate) fn check(&self, n: usize) -> Result<(), ControlError> {
        check_len("commands", n, self.u.len())?;
        check_len("raw commands", n, self.u_raw.len())?;
        check_len("saturation flags", n, self.saturated.len())?;
        check_len("scratch", n, self.work.len())
    }
}

/// The ring neighbours of axis `k` (k − 1 and k + 1, modulo n): their newest (e, ė) samples
/// extrapolated by `est` to axis k's application time, D = a_k − s_j (eq. 13). Shared by the
/// laws that couple each axis to its neighbours only.
#[inline]
pub(crate) fn ring_neighbours(
    est: &dyn Estimator,
    h: &ErrorHistory,
    input: &ControlInput,
    k: usize,
) -> [(f64, f64); 2] {
    let n = h.axes();
    [(k + n - 1) % n, (k + 1) % n].map(|j| {
        let d = (input.apply_time[k] - h.t[j]) / input.t_cyc;
        (
            est.estimate(h, j, crate::estimator::Signal::Position, d),
            est.estimate(h, j, crate::estimator::Signal::Velocity, d),
        )
    })
}

/// A control law: commands from the error history (newest sample first) and the cycle's
/// inputs.
pub trait ControlLaw: Send {
    /// Short name used in outputs: the registry's name (`pd`, `sync`, `ring-coupled`, …), or a
    /// variant of it (`pd+ff` for PD with feed-forward).
    fn name(&self) -> &'static str;
    /// Number of axes.
    fn axes(&self) -> usize;
    /// The motion message estimator the law owns, if it uses one (the stability check asks
    /// it whether it is linear in the history).
    fn estimator(&self) -> Option<&dyn Estimator> {
        None
    }
    /// The same, to tell it of new samples ([`Controller::update`] does).
    fn estimator_mut(&mut self) -> Option<&mut dyn Estimator> {
        None
    }
    /// The law itself, on inputs whose lengths [`ControlLaw::compute`] has checked.
    fn evaluate(&self, history: &ErrorHistory, input: &ControlInput, out: &mut ControlOutput);
    /// Computes this cycle's commands after checking that history, input and output all
    /// have [`ControlLaw::axes`] axes. Pure: the same history and input give the same output.
    fn compute(
        &self,
        history: &ErrorHistory,
        input: &ControlInput,
        out: &mut ControlOutput,
    ) -> Result<(), ControlError> {
        let n = self.axes();
        check_len("error history", n, history.axes())?;
        input.check(n)?;
        out.check(n)?;
        self.evaluate(history, input, out);
        Ok(())
    }
}

/// Where the velocity error ė comes from (the paper's: the slave's velocity).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum VelocitySource {
    /// ė = ẋ^d − v with the velocity the slave reports.
    #[default]
    Reported,
    /// ė = (e\[m\] − e[m−1]) / (t_m − t_{m−1}) from successive position samples (0 for the
    /// first sample).
    Differenced,
    /// ė from a tracking observer on the error samples ([`ErrorObserver`]): smooths the
    /// encoder's quantisation instead of dividing it by a short time.
    Observer(ErrorObserver),
}

/// A tracking observer of the error e and its rate ė (an α-β filter, critically damped):
/// at each sample, spaced h, the prediction ê + h·ė̂ is corrected by the residual
/// r = e − (ê + h·ė̂): ê ← ê + h·ė̂ + α·r, ė̂ ← ė̂ + (β/h)·r, with α = 1 − λ², β = (1 − λ)²,
/// λ = exp(−2π·f_b·T_cyc) (both poles at λ). It runs in the master on e = x^d − x, not on
/// x: the error moves slowly even when the axis accelerates hard, so the observer's lag
/// (about (α − β/2)/β cycles times ë) stays small. Not in the paper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorObserver {
    /// Bandwidth f_b \[Hz\], > 0.
    pub bandwidth_hz: f64,
}

impl ErrorObserver {
    /// The gains (α, β) for cycle `t_cyc` \[s\].
    pub fn gains(&self, t_cyc: f64) -> (f64, f64) {
        let lambda = (-std::f64::consts::TAU * self.bandwidth_hz * t_cyc).exp();
        (1.0 - lambda * lambda, (1.0 - lambda) * (1.0 - lambda))
    }

    /// One step over `h` \[s\] from the estimate `(e, ė)` with the new sample `e_new` \[rad\]:
    /// the corrected `(ê, ė̂)`. `alpha_beta` from [`ErrorObserver::gains`].
    #[inline]
    pub fn step(state: (f64, f64), e_new: f64, h: f64, alpha_beta: (f64, f64)) -> (f64, f64) {
        let (a, b) = alpha_beta;
        let pred = state.0 + h * state.1;
        let r = e_new - pred;
        (pred + a * r, state.1 + b / h * r)
    }
}

/// Feedback of one cycle: the latest sample of every axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Feedback {
    /// Measured position \[rad\].
    pub position: Vec<f64>,
    /// Measured velocity [rad/s] (used with [`VelocitySource::Reported`]).
    pub velocity: Vec<f64>,
    /// Sampling instant \[s\].
    pub sample_time: Vec<f64>,
    /// Desired state at the sampling instant.
    pub desired: Vec<State>,
    /// Whether this cycle brought a new sample of the axis (false: keep the old one).
    pub fresh: Vec<bool>,
}

impl Feedback {
    /// Feedback for `n` axes, all zero and fresh.
    pub fn new(n: usize) -> Self {
        Feedback {
            position: vec![0.0; n],
            velocity: vec![0.0; n],
            sample_time: vec![0.0; n],
            desired: vec![State::default(); n],
            fresh: vec![true; n],
        }
    }
}

/// A law with its error history: feed it each cycle's feedback, get the commands.
#[derive(Debug, Clone)]
pub struct Controller<L> {
    /// The law.
    pub law: L,
    /// Error samples so far.
    pub history: ErrorHistory,
    /// Where ė comes from.
    pub velocity: VelocitySource,
    /// The observer's (ê, ė̂) per axis, with [`VelocitySource::Observer`].
    observed: Vec<(f64, f64)>,
    /// Per axis, how many times the law ran on its newest sample since it was taken.
    held: Vec<u32>,
    /// The disturbance observer, if any ([`Controller::with_dob`]).
    dob: Option<crate::dob::DisturbanceObserver>,
}

impl<L: ControlLaw> Controller<L> {
    /// A controller with an empty history.
    pub fn new(law: L, velocity: VelocitySource) -> Self {
        let n = law.axes();
        Controller {
            law,
            history: ErrorHistory::new(n),
            velocity,
            observed: vec![(0.0, 0.0); n],
            held: vec![0; n],
            dob: None,
        }
    }

    /// With a disturbance observer of as many axes: every command gets the observer's d̂
    /// taken off ([`crate::dob`]).
    pub fn with_dob(mut self, dob: crate::dob::DisturbanceObserver) -> Result<Self, ControlError> {
        check_len(
            "disturbance observer axes",
            self.law.axes(),
            dob.params().h.len(),
        )?;
        self.dob = Some(dob);
        Ok(self)
    }

    /// The disturbance observer, if any.
    pub fn dob(&self) -> Option<&crate::dob::DisturbanceObserver> {
        self.dob.as_ref()
    }

    /// Takes this cycle's fresh samples into the history, then computes the commands. The
    /// law's estimator, if any, is told of every sample pushed ([`Estimator::observe`]),
    /// interpolated ones included, before the law computes.
    ///
    /// The estimators assume one sample per cycle. When a fresh sample comes after g missed
    /// cycles (its sampling instant g + 1 cycles after the last one), g samples linearly
    /// interpolated between the two are pushed first, so the spacing stays T_cyc; after
    /// more than [`DEPTH`](crate::estimator::DEPTH) − 1 missed cycles the history starts
    /// afresh. A sample that is not at least half a cycle newer than the last one taken
    /// (the same sample delivered again, e.g. when a slave latched after the lumped frame
    /// passed) is ignored, as if not fresh: taking it would put two samples one "cycle"
    /// apart in the history that are really zero apart, and the estimators' slopes with it.
    ///
    /// With [`VelocitySource::Differenced`], the ė a law ran on keeps adding up to the
    /// change of e across a short gap, as it does from cycle to cycle (Σ ė·T = e\[m\] − e\[0\],
    /// T the cycle): a law that ran k more times on its newest sample (no new one came, or
    /// the same one again), 0 < k < [`DEPTH`](crate::estimator::DEPTH), ran on that sample's
    /// ė k more times, so the interpolated samples carry that ė and the next sample's ė is
    /// (e − e₀)/T − k·ė₀, taking back what the repeats added. Without it a missed cycle left
    /// one count of velocity noise in the D term, an offset the slow pole K_P/K_D takes half
    /// a second to remove (docs/control.md). Not in the paper.
    pub fn update(
        &mut self,
        fb: &Feedback,
        input: &ControlInput,
        out: &mut ControlOutput,
    ) -> Result<(), ControlError> {
        let n = self.law.axes();
        for (what, len) in [
            ("positions", fb.position.len()),
            ("velocities", fb.velocity.len()),
            ("sample times", fb.sample_time.len()),
            ("desired states at sampling", fb.desired.len()),
            ("fresh flags", fb.fresh.len()),
        ] {
            check_len(what, n, len)?;
        }
        for i in 0..n {
            // Law runs on axis i's newest sample since it was taken, this one not counted.
            let held = std::mem::take(&mut self.held[i]);
            if !fb.fresh[i] {
                self.held[i] = held.saturating_add(u32::from(self.history.count[i] > 0));
                continue;
            }
            let e = fb.desired[i].x - fb.position[i];
            let t = fb.sample_time[i];
            let h = &mut self.history;
            // The newest sample taken before this one: (e, ė, t).
            let last = (h.e[i][0], h.de[i][0], h.t[i]);
            // Differenced ė across a gap the law ran through (see the docs above).
            let carried = held > 0
                && (held as usize) < crate::estimator::DEPTH
                && matches!(self.velocity, VelocitySource::Differenced);
            if h.count[i] > 0 {
                let steps = ringsync_plant::rounding::round_f64((t - h.t[i]) / input.t_cyc);
                if steps < 1.0 {
                    self.held[i] = held.saturating_add(1);
                    continue;
                }
                if steps > crate::estimator::DEPTH as f64 {
                    h.count[i] = 0;
                } else if steps >= 2.0 {
                    let (e0, de0, t0) = last;
                    let de_new = match self.velocity {
                        VelocitySource::Reported => fb.desired[i].v - fb.velocity[i],
                        VelocitySource::Differenced => (e - e0) / (t - t0),
                        VelocitySource::Observer(o) => {
                            let g = o.gains(input.t_cyc);
                            ErrorObserver::step(self.observed[i], e, t - t0, g).1
                        }
                    };
                    let g = steps as usize - 1;
                    for j in 1..=g {
                        let f = j as f64 / steps;
                        h.push(
                            i,
                            e0 + f * (e - e0),
                            if carried {
                                de0
                            } else {
                                de0 + f * (de_new - de0)
                            },
                            t0 + f * (t - t0),
                        )?;
                        if let Some(est) = self.law.estimator_mut() {
                            est.observe(h, i);
                        }
                    }
                }
            }
            let de = match self.velocity {
                VelocitySource::Reported => fb.desired[i].v - fb.velocity[i],
                VelocitySource::Differenced => {
                    let dt = fb.sample_time[i] - self.history.t[i];
                    let (e0, de0, _) = last;
                    if carried && self.history.count[i] > 0 {
                        (e - e0) / input.t_cyc - f64::from(held) * de0
                    } else if self.history.count[i] > 0 && dt > 0.0 {
                        (e - self.history.e[i][0]) / dt
                    } else {
                        0.0
                    }
                }
                VelocitySource::Observer(o) => {
                    let dt = fb.sample_time[i] - self.history.t[i];
                    self.observed[i] = if self.history.count[i] > 0 && dt > 0.0 {
                        ErrorObserver::step(self.observed[i], e, dt, o.gains(input.t_cyc))
                    } else {
                        // Start from the sample and the slave's velocity.
                        (e, fb.desired[i].v - fb.velocity[i])
                    };
                    self.observed[i].1
                }
            };
            self.history.push(i, e, de, fb.sample_time[i])?;
            if let Some(est) = self.law.estimator_mut() {
                est.observe(&self.history, i);
            }
            if let Some(dob) = &mut self.dob {
                dob.sample(i, fb.position[i], fb.sample_time[i], input.t_cyc);
            }
        }
        self.law.compute(&self.history, input, out)?;
        if let Some(dob) = &mut self.dob {
            dob.compensate(out, &input.apply_time);
        }
        Ok(())
    }
}

/// A boxed law is a law (for choosing the law at run time, e.g. from a scenario).
impl<L: ControlLaw + ?Sized> ControlLaw for Box<L> {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn axes(&self) -> usize {
        (**self).axes()
    }
    fn estimator(&self) -> Option<&dyn Estimator> {
        (**self).estimator()
    }
    fn estimator_mut(&mut self) -> Option<&mut dyn Estimator> {
        (**self).estimator_mut()
    }
    fn evaluate(&self, history: &ErrorHistory, input: &ControlInput, out: &mut ControlOutput) {
        (**self).evaluate(history, input, out)
    }
}

#[cfg(test)]
mod tests;
