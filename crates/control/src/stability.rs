//! Stability analysis (docs/system.md, "Stability").
//!
//! **Continuous-time conditions of the paper**, evaluated numerically along a trajectory
//! (x = x^d, ẋ = ẋ^d) in the controller's units (H in V·s²/rad, C in V·s/rad):
//!
//! 1. λ_min(K_E) ≥ ‖α·T·(½Ḣ − C)‖: the paper bounds the right side by c₁‖x‖ + c₂‖ẋ‖; here
//!    it is evaluated at each point, and the margin is λ_min(K_E) minus its largest value;
//! 2. Δ_H ≥ ‖K_H − H(x)‖ and Δ_C ≥ ‖K_C − C(x, ẋ)‖.
//!
//! Norms are spectral norms (largest singular value). The continuous argument says nothing
//! about a given T_cyc, so beside it stands:
//!
//! **The discrete-time check**: the spectral radius of the sampled closed loop of linear
//! axes (ẍ = g·u − a·ẋ; Coulomb friction and saturation left out) with each axis's
//! sample-to-actuation delay, regulating to a final position (x^d = 0, ẋ^d = 0, so K_N = 0
//! and the loop is linear; a caller models a boundary layer's robust term, linear inside the
//! layer with slope K_N/φ on Ė, by adding K_N/φ to K_D). The state per axis is x, ẋ, the command still held, and the three
//! previous samples of e and ė that the estimators read: 9n states. The loop matrix is built
//! column by column by running the law's own `compute` on unit states, so what is checked is
//! exactly the code that runs. Velocity feedback is the reported (exact) velocity.
//!
//! The lumped-only plan of ref. \[3\], where each slave runs the law itself on samples of
//! mixed age, has a loop of its own: [`lumped_only_loop`].
//!
//! What the discrete-time check assumes of the law: its command is a function of the
//! history and the inputs alone ([`ControlLaw::compute`] is pure), linear in the history
//! once the robust term is off, and its estimator, if any, is linear and time-invariant in
//! the samples the history holds ([`crate::Estimator::is_linear_in_history`]): the check
//! sets the history directly and never calls [`crate::Estimator::observe`]. A law whose
//! estimator keeps state of its own (a Kalman filter) is refused with
//! [`ControlError::NotApplicable`]: the loop would need the estimator's state too.

use nalgebra::DMatrix;
use nalgebra::linalg::{SVD, Schur};
use ringsync_plant::{Discretised, Dynamics};

use crate::error::{ControlError, check, check_len};
use crate::estimator::{DEPTH, ErrorHistory};
use crate::law::{ControlInput, ControlLaw, ControlOutput, ErrorObserver, Gains, VelocitySource};
use crate::trajectory::Trajectory;

/// What the continuous-time conditions give along a trajectory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContinuousReport {
    /// Points evaluated.
    pub points: usize,
    /// λ_min(K_E) [V·s/rad].
    pub lambda_min_ke: f64,
    /// Largest ‖α·T·(½Ḣ − C)‖ along the trajectory [V·s/rad].
    pub cond1_bound: f64,
    /// Time of that largest value \[s\].
    pub cond1_worst_time: f64,
    /// λ_min(K_E) − the largest bound; ≥ 0 when condition 1 holds.
    pub cond1_margin: f64,
    /// Largest ‖K_H − H(x)‖ [V·s²/rad].
    pub cond2_h_norm: f64,
    /// Δ_H minus it; ≥ 0 when the H part of condition 2 holds.
    pub cond2_h_margin: f64,
    /// Largest ‖K_C − C(x, ẋ)‖ [V·s/rad].
    pub cond2_c_norm: f64,
    /// Δ_C minus it; ≥ 0 when the C part of condition 2 holds.
    pub cond2_c_margin: f64,
}

impl ContinuousReport {
    /// Condition 1 holds along the trajectory.
    pub fn condition1_holds(&self) -> bool {
        self.cond1_margin >= 0.0
    }
    /// Condition 2 holds along the trajectory.
    pub fn condition2_holds(&self) -> bool {
        self.cond2_h_margin >= 0.0 && self.cond2_c_margin >= 0.0
    }
}

fn spectral_norm(m: DMatrix<f64>) -> Result<f64, ControlError> {
    let svd = SVD::try_new(m, false, false, 1e-14, 10_000).ok_or(ControlError::NoConvergence {
        what: "singular value decomposition",
    })?;
    Ok(svd.singular_values.iter().copied().fold(0.0, f64::max))
}

/// Evaluates conditions 1 and 2 at `points` evenly spaced instants of [0, `t_end`] s along
/// the axes' desired trajectories. `gains` gives K_E, K_H, K_C; `alpha`, `delta_h`,
/// `delta_c` as in [`crate::law::SyncParams`].
pub fn continuous_conditions<D: Dynamics + ?Sized, T: Trajectory>(
    dynamics: &D,
    trajectories: &[T],
    gains: &Gains,
    (alpha, delta_h, delta_c): (f64, f64, f64),
    t_end: f64,
    points: usize,
) -> Result<ContinuousReport, ControlError> {
    let n = dynamics.dof();
    if n < 2 {
        return Err(ControlError::TooFewAxes {
            what: "the stability conditions",
            n,
            min: 2,
        });
    }
    check_len("trajectories", n, trajectories.len())?;
    check_len("gains", n, gains.axes())?;
    gains.validate()?;
    check("alpha", alpha, 0.0, false, ">= 0")?;
    check("t_end", t_end, 0.0, false, ">= 0 s")?;
    let points = points.max(1);
    let k = 1.0 / (n - 1) as f64;
    let t_mat = DMatrix::from_fn(n, n, |i, j| if i == j { 1.0 } else { -k });
    let (mut x, mut v) = (vec![0.0; n], vec![0.0; n]);
    let (mut h, mut c, mut hd) = (vec![0.0; n * n], vec![0.0; n * n], vec![0.0; n * n]);
    let mut r = ContinuousReport {
        points,
        lambda_min_ke: gains.ke.iter().copied().fold(f64::INFINITY, f64::min),
        cond1_bound: 0.0,
        cond1_worst_time: 0.0,
        cond1_margin: 0.0,
        cond2_h_norm: 0.0,
        cond2_h_margin: 0.0,
        cond2_c_norm: 0.0,
        cond2_c_margin: 0.0,
    };
    for p in 0..points {
        let t = if points == 1 {
            0.0
        } else {
            t_end * p as f64 / (points - 1) as f64
        };
        for (i, tr) in trajectories.iter().enumerate() {
            let s = tr.at(t);
            x[i] = s.x;
            v[i] = s.v;
        }
        dynamics.inertia(&x, &mut h);
        dynamics.coriolis(&x, &v, &mut c);
        dynamics.inertia_rate(&x, &v, &mut hd);
        let inner = DMatrix::from_fn(n, n, |i, j| 0.5 * hd[i * n + j] - c[i * n + j]);
        let bound = spectral_norm(&t_mat * inner * alpha)?;
        if bound > r.cond1_bound {
            r.cond1_bound = bound;
            r.cond1_worst_time = t;
        }
        let kh_h = DMatrix::from_fn(
            n,
            n,
            |i, j| if i == j { gains.kh[i] } else { 0.0 } - h[i * n + j],
        );
        let kc_c = DMatrix::from_fn(
            n,
            n,
            |i, j| if i == j { gains.kc[i] } else { 0.0 } - c[i * n + j],
        );
        r.cond2_h_norm = r.cond2_h_norm.max(spectral_norm(kh_h)?);
        r.cond2_c_norm = r.cond2_c_norm.max(spectral_norm(kc_c)?);
    }
    r.cond1_margin = r.lambda_min_ke - r.cond1_bound;
    r.cond2_h_margin = delta_h - r.cond2_h_norm;
    r.cond2_c_margin = delta_c - r.cond2_c_norm;
    Ok(r)
}

/// The discrete-time check's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscreteReport {
    /// Spectral radius of the closed-loop matrix.
    pub spectral_radius: f64,
    /// Size of the closed-loop state (9 per axis).
    pub states: usize,
}

impl DiscreteReport {
    /// Asymptotically stable: spectral radius < 1.
    pub fn is_stable(&self) -> bool {
        self.spectral_radius < 1.0
    }
}

/// States per axis in the discrete-time check (11 with the error observer, see
/// [`discrete_loop_with`]).
pub const PER_AXIS: usize = 9;

/// The spectral radius of the sampled closed loop of `law` on linear axes `(a, g)`
/// (ẍ = g·u − a·ẋ, see [`ringsync_plant::AxisModel::linear_part`]), period `t_cyc` \[s\], and
/// per-axis sample-to-actuation delays `delays` \[s\] (0 ≤ delay ≤ T_cyc). All axes sample at
/// the same instant. Refused ([`ControlError::NotApplicable`]) when the law's estimator is
/// not linear in the history (see the module's docs). [`discrete_loop`] gives the loop
/// matrix too.
pub fn discrete_check(
    law: &dyn ControlLaw,
    axes: &[(f64, f64)],
    t_cyc: f64,
    delays: &[f64],
) -> Result<DiscreteReport, ControlError> {
    discrete_loop(law, axes, t_cyc, delays).map(|l| l.report)
}

/// The sampled closed loop of the discrete-time check: its matrix and what
/// [`discrete_check`] reports of it.
#[derive(Debug, Clone, PartialEq)]
pub struct DiscreteLoop {
    /// The closed-loop matrix M, z[k+1] = M·z\[k\] over one cycle T_cyc, `states` × `states`
    /// ([`PER_AXIS`] states per axis, axis-major; see [`discrete_loop`] for their order).
    pub matrix: DMatrix<f64>,
    /// The spectral radius of [`DiscreteLoop::matrix`] (its Schur eigenvalues) and the
    /// number of states.
    pub report: DiscreteReport,
    /// States per axis: [`PER_AXIS`], 2 more with the error observer, 3 more with the
    /// disturbance observer ([`lumped_only_loop`]: 11).
    pub states_per_axis: usize,
    /// The names of an axis's states, in their order ([`STATE_NAMES`], then `e_hat`,
    /// `de_hat` with the error observer and `u_prev2`, `u_prev3`, `d_hat` with the
    /// disturbance observer; [`LUMPED_ONLY_STATE_NAMES`] for the lumped-only plan).
    pub state_names: Vec<&'static str>,
}

/// The sampled closed loop of [`discrete_check`] (same arguments) with its matrix M:
/// z[k+1] = M·z\[k\] over one cycle, 9 states per axis i at `9·i ..`, in this order: x \[rad\],
/// ẋ [rad/s], the command still held from the last cycle u[k−1] \[V\], the three previous
/// samples of the error e[k−1], e[k−2], e[k−3] \[rad\], and of its rate ė[k−1], ė[k−2],
/// ė[k−3] [rad/s] (regulation to x^d = 0: e = −x, ė = −ẋ). The report's spectral radius is
/// that of this matrix.
pub fn discrete_loop(
    law: &dyn ControlLaw,
    axes: &[(f64, f64)],
    t_cyc: f64,
    delays: &[f64],
) -> Result<DiscreteLoop, ControlError> {
    discrete_loop_with(law, axes, t_cyc, delays, &Measurement::default())
}

/// What the controller adds around the law, for [`discrete_loop_with`]: where ė comes from,
/// and the disturbance observer.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Measurement {
    /// The source of ė (the paper's: the slave's velocity).
    pub velocity: VelocitySource,
    /// The disturbance observer's parameters, if one runs ([`crate::dob`]).
    pub dob: Option<crate::dob::DobParams>,
    /// With [`VelocitySource::Reported`]: over how long before the sample each axis's
    /// drive measures the velocity it reports \[s\], the mean (x(t) − x(t − w))/w with the
    /// command held ([`Discretised::window_velocity`]); empty: the exact velocity at the
    /// sample. A window must end after the command's effect (w ≤ T_cyc − delay).
    pub velocity_window: Vec<f64>,
}

/// The reported velocity's coefficients [c_v, c_u] on each axis's (ẋ, u[k−1]) at the
/// sample: [1, 0] for the exact velocity, else the mean over `m.velocity_window`
/// (see [`Measurement::velocity_window`]).
fn reported_velocity(
    m: &Measurement,
    axes: &[(f64, f64)],
    t_cyc: f64,
    delays: &[f64],
) -> Result<Vec<[f64; 2]>, ControlError> {
    if m.velocity_window.is_empty() || !matches!(m.velocity, VelocitySource::Reported) {
        return Ok(vec![[1.0, 0.0]; axes.len()]);
    }
    check_len("velocity windows", axes.len(), m.velocity_window.len())?;
    axes.iter()
        .zip(delays)
        .zip(&m.velocity_window)
        .enumerate()
        .map(|(i, ((&(a, g), &d), &w))| {
            if w > t_cyc - d {
                return Err(ControlError::NotApplicable {
                    what: "the discrete-time stability check",
                    why: format!(
                        "axis {i}'s velocity window ({:.1} µs) reaches back past its command's effect ({:.1} µs before the next sample): the check holds one command over the window",
                        w * 1e6,
                        (t_cyc - d) * 1e6
                    ),
                });
            }
            Discretised::window_velocity(a, g, w).ok_or_else(|| ControlError::InvalidParameter {
                name: format!("velocity_window[{i}]"),
                value: w,
                expected: "> 0 s".into(),
            })
        })
        .collect()
}

/// [`discrete_loop`] with the controller's measurement `m`. ė as the controller takes it
/// at each sample: `Reported`, the axis's velocity (−ẋ); `Differenced`, (e\[k\] − e[k−1])/
/// T_cyc; `Observer`, the error observer's ė̂ ([`ErrorObserver`]),
/// whose estimate (ê, ė̂) of the last sample adds two states per axis after the nine. The ė
/// history holds the ė the law was given. A disturbance observer ([`crate::dob`]) adds three
/// more: the commands of two and three cycles back u[k−2], u[k−3] \[V\] and its estimate
/// d̂[k−1] \[V\]; the command is then the law's minus d̂\[k\].
pub fn discrete_loop_with(
    law: &dyn ControlLaw,
    axes: &[(f64, f64)],
    t_cyc: f64,
    delays: &[f64],
    m: &Measurement,
) -> Result<DiscreteLoop, ControlError> {
    let velocity = m.velocity;
    let n = law.axes();
    let disc = discretised(law, axes, t_cyc, delays)?;
    let obs = if matches!(velocity, VelocitySource::Observer(_)) {
        2
    } else {
        0
    };
    let dob_at = PER_AXIS + obs;
    if let Some(d) = &m.dob {
        check_len("disturbance observer axes", n, d.h.len())?;
        check_len("disturbance observer axes", n, d.c.len())?;
    }
    let per = dob_at + if m.dob.is_some() { 3 } else { 0 };
    let reported = reported_velocity(m, axes, t_cyc, delays)?;
    // ė at the sample from axis i's states s (9 or 11): (ė, the observer's new (ê, ė̂)).
    let rate = |i: usize, s: &[f64]| -> (f64, [f64; 2]) {
        match velocity {
            VelocitySource::Reported => {
                (-(reported[i][0] * s[1] + reported[i][1] * s[2]), [0.0; 2])
            }
            VelocitySource::Differenced => ((-s[0] - s[3]) / t_cyc, [0.0; 2]),
            VelocitySource::Observer(o) => {
                let (e, de) = ErrorObserver::step((s[9], s[10]), -s[0], t_cyc, o.gains(t_cyc));
                (de, [e, de])
            }
        }
    };
    let dim = per * n;
    let gamma = m.dob.as_ref().map_or(0.0, |d| d.gain(t_cyc));
    let mut mat = DMatrix::<f64>::zeros(dim, dim);
    let mut hist = ErrorHistory::new(n);
    let mut input = ControlInput::new(n, t_cyc);
    input.apply_time.copy_from_slice(delays);
    let mut out = ControlOutput::new(n);
    let mut z = vec![0.0; dim];
    for col in 0..dim {
        z.fill(0.0);
        z[col] = 1.0;
        for i in 0..n {
            let s = &z[i * per..(i + 1) * per];
            // Regulation to x^d = 0: e = −x, ė from the velocity source.
            hist.e[i] = [-s[0], s[3], s[4], s[5]];
            hist.de[i] = [rate(i, s).0, s[6], s[7], s[8]];
            hist.count[i] = 4;
            hist.t[i] = 0.0;
        }
        law.compute(&hist, &input, &mut out)?;
        for i in 0..n {
            let s = &z[i * per..(i + 1) * per];
            let d = &disc[i];
            let (x, v, u_prev) = (s[0], s[1], s[2]);
            // The disturbance observer at this sample (module `dob`): x_{k−1} = −e_{k−1}.
            let (u, dob_next) = match &m.dob {
                None => (out.u_raw[i], [0.0; 3]),
                Some(p) => {
                    let (x1, x2) = (-s[3], -s[4]);
                    let acc = x - 2.0 * x1 + x2;
                    let vel = t_cyc * (x - x2) / 2.0;
                    let w = crate::dob::DobParams::input_weights(t_cyc, delays[i]);
                    let (u2, u3, d_prev) = (s[dob_at], s[dob_at + 1], s[dob_at + 2]);
                    let y = w[0] * u3 + w[1] * u2 + w[2] * u_prev;
                    let dk = (p.h[i] * acc + p.c[i] * vel - y) / (t_cyc * t_cyc);
                    let d_hat = d_prev + gamma * (dk - d_prev);
                    (out.u_raw[i] - d_hat, [u_prev, u2, d_hat])
                }
            };
            let (de, observed) = rate(i, s);
            let mut next = [0.0; PER_AXIS + 5];
            let base = [
                d.phi[0][0] * x + d.phi[0][1] * v + d.gamma1[0] * u_prev + d.gamma0[0] * u,
                d.phi[1][0] * x + d.phi[1][1] * v + d.gamma1[1] * u_prev + d.gamma0[1] * u,
                u,
                -x,
                s[3],
                s[4],
                de,
                s[6],
                s[7],
            ];
            next[..PER_AXIS].copy_from_slice(&base);
            next[PER_AXIS..dob_at].copy_from_slice(&observed[..obs]);
            if m.dob.is_some() {
                next[dob_at..dob_at + 3].copy_from_slice(&dob_next);
            }
            for (r, val) in next.into_iter().take(per).enumerate() {
                mat[(i * per + r, col)] = val;
            }
        }
    }
    let mut names = STATE_NAMES.to_vec();
    if obs > 0 {
        names.extend(["e_hat", "de_hat"]);
    }
    if m.dob.is_some() {
        names.extend(["u_prev2", "u_prev3", "d_hat"]);
    }
    DiscreteLoop::of(mat, names)
}

/// The names of the check's [`PER_AXIS`] states of an axis, in their order (x, ẋ, u[k−1],
/// e[k−1..k−3], ė[k−1..k−3]).
pub const STATE_NAMES: [&str; PER_AXIS] =
    ["x", "v", "u_prev", "e1", "e2", "e3", "de1", "de2", "de3"];

impl DiscreteLoop {
    /// The loop of matrix `matrix` whose axes each have the states `names`, with its
    /// spectral radius (the Schur eigenvalues' largest modulus).
    fn of(matrix: DMatrix<f64>, names: Vec<&'static str>) -> Result<Self, ControlError> {
        let rho = spectral_radius(&matrix)?;
        let states = matrix.nrows();
        Ok(DiscreteLoop {
            matrix,
            report: DiscreteReport {
                spectral_radius: rho,
                states,
            },
            states_per_axis: names.len(),
            state_names: names,
        })
    }
}

/// The largest modulus of `m`'s eigenvalues (its real Schur form's). A loop with large
/// gains can keep the decomposition from converging: it is then balanced (a similarity by
/// powers of two, so the same eigenvalues to the last bit of the arithmetic) and
/// decomposed again, with the tolerance loosened step by step to 10⁻¹⁰.
fn spectral_radius(m: &DMatrix<f64>) -> Result<f64, ControlError> {
    // Gains near f64's range overflow into the matrix: the decomposition (and its balancing)
    // would never end on them.
    if let Some(&x) = m.iter().find(|x| !x.is_finite()) {
        return Err(ControlError::InvalidParameter {
            name: "an entry of the loop matrix".into(),
            value: x,
            expected: "a finite number: the gains are too large for double precision".into(),
        });
    }
    let radius = |s: Schur<f64, nalgebra::Dyn>| {
        s.complex_eigenvalues()
            .iter()
            .map(|l| l.norm())
            .fold(0.0, f64::max)
    };
    if let Some(s) = Schur::try_new(m.clone(), 1e-13, 100_000) {
        return Ok(radius(s));
    }
    let mut balanced = m.clone();
    nalgebra::linalg::balancing::balance_parlett_reinsch(&mut balanced);
    [1e-13, 1e-12, 1e-11, 1e-10]
        .into_iter()
        .find_map(|eps| Schur::try_new(balanced.clone(), eps, 100_000))
        .map(radius)
        .ok_or(ControlError::NoConvergence {
            what: "Schur decomposition of the loop matrix",
        })
}

/// The checks' common inputs, checked: `law` is linear in its history (else
/// [`ControlError::NotApplicable`]), one linear axis `(a, g)` and one delay in
/// [0, `t_cyc`] per axis of the law; each axis discretised over a cycle with its command
/// switching at its delay.
fn discretised(
    law: &dyn ControlLaw,
    axes: &[(f64, f64)],
    t_cyc: f64,
    delays: &[f64],
) -> Result<Vec<Discretised>, ControlError> {
    let n = law.axes();
    check_len("axes", n, axes.len())?;
    check_len("delays", n, delays.len())?;
    check("t_cyc", t_cyc, 0.0, true, "> 0 s")?;
    if let Some(est) = law.estimator().filter(|e| !e.is_linear_in_history()) {
        return Err(ControlError::NotApplicable {
            what: "the discrete-time stability check",
            why: format!(
                "it builds the loop from the last {DEPTH} samples alone, and estimator {} keeps state beyond them (not linear in the history)",
                est.name()
            ),
        });
    }
    let mut disc = Vec::with_capacity(n);
    for (i, (&(a, g), &d)) in axes.iter().zip(delays).enumerate() {
        check(&format!("axes[{i}].a"), a, 0.0, false, ">= 0 1/s")?;
        check(&format!("axes[{i}].g"), g, 0.0, true, "> 0 rad/(s²·V)")?;
        disc.push(Discretised::new(a, g, t_cyc, d).ok_or_else(|| {
            ControlError::InvalidParameter {
                name: format!("delays[{i}]"),
                value: d,
                expected: "0 <= delay <= t_cyc".into(),
            }
        })?);
    }
    Ok(disc)
}

mod lumped_only;
pub use lumped_only::{LUMPED_ONLY_STATE_NAMES, lumped_only_loop};

#[cfg(test)]
mod tests;
