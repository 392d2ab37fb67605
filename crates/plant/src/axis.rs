//! Single-axis drive models and a plant made of independent axes.

use crate::error::{PlantError, check};
use crate::integrate::rk4;
use crate::{Dynamics, Plant, saturate};

/// How the Coulomb friction's sgn(ẋ) is modelled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SignModel {
    /// The discontinuous sign with stiction: an axis at rest stays at rest while the drive
    /// torque does not exceed T_c. Stepped exactly, piecewise between velocity zero-crossings.
    Exact,
    /// tanh(ẋ / v_s) with v_s [rad/s] (docs/system.md, "The reference scenario": v_s = 1 mrad/s); stepped by RK4.
    Smooth {
        /// Velocity scale v_s [rad/s], > 0.
        v_s: f64,
    },
}

/// Friction of one axis: viscous b·ẋ plus Coulomb T_c·sgn(ẋ).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Friction {
    /// Viscous coefficient b [N·m·s/rad], ≥ 0.
    pub viscous: f64,
    /// Coulomb friction torque T_c [N·m], ≥ 0.
    pub coulomb: f64,
    /// Model of sgn(ẋ).
    pub sign: SignModel,
}

impl Friction {
    /// Viscous friction only.
    pub fn viscous(b: f64) -> Self {
        Friction {
            viscous: b,
            coulomb: 0.0,
            sign: SignModel::Exact,
        }
    }
}

/// A voltage-commanded torque-mode axis (docs/system.md, "The reference scenario"):
/// J ẍ = K_a·sat_{±u_max}(u) − b·ẋ − T_c·sgn(ẋ).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorqueAxis {
    /// Rotor plus load inertia J [kg·m²], > 0.
    pub inertia: f64,
    /// Torque per volt of command K_a [N·m/V], > 0 (rated torque / 10 V).
    pub torque_constant: f64,
    /// Friction.
    pub friction: Friction,
    /// Command range ±u_max \[V\], > 0.
    pub u_max: f64,
    /// Largest RK4 step \[s\] (smooth Coulomb friction only).
    pub max_step: f64,
}

/// Default largest RK4 step [s]: 10 µs, well below J·v_s/T_c ≈ 78 µs of the reference axes.
pub const DEFAULT_MAX_STEP: f64 = 10e-6;

impl TorqueAxis {
    /// A checked torque axis; every parameter is validated and named in the error.
    pub fn new(
        inertia: f64,
        torque_constant: f64,
        friction: Friction,
        u_max: f64,
    ) -> Result<Self, PlantError> {
        let a = TorqueAxis {
            inertia,
            torque_constant,
            friction,
            u_max,
            max_step: DEFAULT_MAX_STEP,
        };
        a.validate()?;
        Ok(a)
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), PlantError> {
        check("inertia", self.inertia, 0.0, true, "> 0 kg·m²")?;
        check(
            "torque_constant",
            self.torque_constant,
            0.0,
            true,
            "> 0 N·m/V",
        )?;
        check(
            "viscous_friction",
            self.friction.viscous,
            0.0,
            false,
            ">= 0 N·m·s/rad",
        )?;
        check(
            "coulomb_friction",
            self.friction.coulomb,
            0.0,
            false,
            ">= 0 N·m",
        )?;
        check("u_max", self.u_max, 0.0, true, "> 0 V")?;
        check("max_step", self.max_step, 0.0, true, "> 0 s")?;
        if let SignModel::Smooth { v_s } = self.friction.sign {
            check("coulomb_velocity_scale", v_s, 0.0, true, "> 0 rad/s")?;
        }
        Ok(())
    }

    /// Advances (x, v) by `dt` with the command `u` held (`u` is clipped to ±u_max).
    pub fn step(&self, x: &mut f64, v: &mut f64, u: f64, dt: f64) {
        let drive = self.torque_constant * saturate(u, self.u_max).0;
        let (j, b, tc) = (self.inertia, self.friction.viscous, self.friction.coulomb);
        match self.friction.sign {
            _ if tc == 0.0 => linear_step(x, v, b / j, drive / j, dt),
            SignModel::Exact => coulomb_exact_step(x, v, j, b, tc, drive, dt),
            SignModel::Smooth { v_s } => {
                let mut y = [*x, *v];
                let mut scratch = [0.0; 10];
                rk4(&mut y, dt, self.max_step, &mut scratch, |y, d| {
                    d[0] = y[1];
                    d[1] = (drive - b * y[1] - tc * (y[1] / v_s).tanh()) / j;
                });
                *x = y[0];
                *v = y[1];
            }
        }
    }

    /// The linear part as ẍ = g·u − a·ẋ: (a, g) = (b/J [1/s], K_a/J [rad/(s²·V)]); `None`
    /// when Coulomb friction makes the axis nonlinear.
    pub fn linear(&self) -> Option<(f64, f64)> {
        (self.friction.coulomb == 0.0).then(|| self.linear_part())
    }

    /// (a, g) of the axis without its Coulomb friction (and saturation).
    pub fn linear_part(&self) -> (f64, f64) {
        (
            self.friction.viscous / self.inertia,
            self.torque_constant / self.inertia,
        )
    }
}

/// Exact step of ẍ = g_u − a·ẋ (constant g_u) over `t`.
fn linear_step(x: &mut f64, v: &mut f64, a: f64, accel: f64, t: f64) {
    if t <= 0.0 {
        return;
    }
    let (phi, psi) = phi_psi(a, t);
    // x(t) = x + φ(t)·v + accel·ψ(t);  v(t) = e^{−at}·v + accel·φ(t)
    let decay = (-a * t).exp();
    *x += phi * *v + accel * psi;
    *v = decay * *v + accel * phi;
}

/// φ(t) = (1 − e^{−at})/a and ψ(t) = (t − φ(t))/a, with their limits for a·t → 0.
fn phi_psi(a: f64, t: f64) -> (f64, f64) {
    let at = a * t;
    if at.abs() < 1e-4 {
        // Series to third order: exact to double precision at this size.
        let phi = t * (1.0 - at / 2.0 + at * at / 6.0);
        let psi = t * t * (0.5 - at / 6.0 + at * at / 24.0);
        (phi, psi)
    } else {
        let phi = -(-at).exp_m1() / a;
        (phi, (t - phi) / a)
    }
}

/// Exact step of J·v̇ = drive − b·v − T_c·sgn(v) with stiction, piecewise between velocity
/// zero-crossings (the dynamics are linear while the sign is fixed).
fn coulomb_exact_step(x: &mut f64, v: &mut f64, j: f64, b: f64, tc: f64, drive: f64, dt: f64) {
    let mut left = dt;
    // At most: move to a stop, start again the other way: three pieces suffice.
    for _ in 0..4 {
        if left <= 0.0 {
            return;
        }
        let s = if *v != 0.0 {
            v.signum()
        } else if drive.abs() > tc {
            drive.signum()
        } else {
            return; // stuck: static friction holds the axis for the rest of the interval
        };
        let force = drive - tc * s;
        // Time until v reaches 0, if the net force decelerates the motion. The deceleration
        // is at most (|force| + b·|v|)/J, so v cannot reach 0 before |v|·J/(|force| + b·|v|):
        // when that is clearly beyond the interval the crossing (and its logarithm) is not
        // needed. (The margin keeps the decision exactly the one the logarithm would make.)
        let t_zero = if *v != 0.0
            && force * s < 0.0
            && v.abs() * j <= left * (force.abs() + b * v.abs()) * (1.0 + 1e-6)
        {
            if b > 0.0 {
                let v_inf = force / b;
                Some(((*v - v_inf) / -v_inf).ln() * j / b)
            } else {
                Some(-*v * j / force)
            }
        } else {
            None
        };
        match t_zero {
            Some(tz) if tz < left => {
                linear_step(x, v, b / j, force / j, tz);
                *v = 0.0;
                left -= tz;
            }
            _ => {
                linear_step(x, v, b / j, force / j, left);
                return;
            }
        }
    }
}

/// A drive in velocity mode: it closes its own velocity loop, so the commanded velocity
/// k_v·sat(u) reaches the axis through a first-order lag, v̇ = (k_v·sat(u) − v)/τ_v.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityAxis {
    /// Velocity per volt of command k_v [rad/(s·V)], > 0.
    pub gain: f64,
    /// Time constant of the velocity loop τ_v \[s\], > 0.
    pub time_constant: f64,
    /// Command range ±u_max \[V\], > 0.
    pub u_max: f64,
}

impl VelocityAxis {
    /// A checked velocity-mode axis.
    pub fn new(gain: f64, time_constant: f64, u_max: f64) -> Result<Self, PlantError> {
        check("velocity_gain", gain, 0.0, true, "> 0 rad/(s·V)")?;
        check("time_constant", time_constant, 0.0, true, "> 0 s")?;
        check("u_max", u_max, 0.0, true, "> 0 V")?;
        Ok(VelocityAxis {
            gain,
            time_constant,
            u_max,
        })
    }

    /// Advances (x, v) by `dt` with `u` held, exactly.
    pub fn step(&self, x: &mut f64, v: &mut f64, u: f64, dt: f64) {
        let a = 1.0 / self.time_constant;
        linear_step(x, v, a, self.gain * saturate(u, self.u_max).0 * a, dt);
    }

    /// The axis as ẍ = g·u − a·ẋ: (a, g) = (1/τ_v, k_v/τ_v).
    pub fn linear(&self) -> (f64, f64) {
        (1.0 / self.time_constant, self.gain / self.time_constant)
    }
}

/// The exact zero-order-hold discretisation of a linear axis ẍ = g·u − a·ẋ sampled every T,
/// with the command computed from the sample at t_m taking effect at t_m + τ (0 ≤ τ ≤ T):
/// `[x, v](m+1) = Φ·[x, v](m) + Γ1·u(m−1) + Γ0·u(m)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Discretised {
    /// Φ(T), row-major.
    pub phi: [[f64; 2]; 2],
    /// Γ0 = Ψ(T − τ): effect of this cycle's command.
    pub gamma0: [f64; 2],
    /// Γ1 = Φ(T − τ)·Ψ(τ): effect of the previous command, still held for τ.
    pub gamma1: [f64; 2],
}

impl Discretised {
    /// Discretises ẍ = g·u − a·ẋ with period `t` \[s\] and sample-to-actuation delay `delay`
    /// \[s\]; `None` unless 0 ≤ delay ≤ t.
    pub fn new(a: f64, g: f64, t: f64, delay: f64) -> Option<Self> {
        if !(0.0..=t).contains(&delay) || t.is_nan() || t <= 0.0 {
            return None;
        }
        let phi_m = |s: f64| {
            let (ph, _) = phi_psi(a, s);
            [[1.0, ph], [0.0, (-a * s).exp()]]
        };
        let psi = |s: f64| {
            let (ph, ps) = phi_psi(a, s);
            [g * ps, g * ph]
        };
        let p = phi_m(t - delay);
        let q = psi(delay);
        Some(Discretised {
            phi: phi_m(t),
            gamma0: psi(t - delay),
            gamma1: [
                p[0][0] * q[0] + p[0][1] * q[1],
                p[1][0] * q[0] + p[1][1] * q[1],
            ],
        })
    }

    /// The mean velocity over the window of `w` \[s\] that ends at a sample, (x(t) −
    /// x(t − w))/w, of ẍ = g·u − a·ẋ with the command u held over the window: the
    /// coefficients [c_v, c_u] of v(t) [rad/s] and u \[V\], so that the mean is c_v·v(t) +
    /// c_u·u (what a drive reports as its velocity from two encoder readings; for a small
    /// window about the velocity w/2 earlier). `None` unless w > 0.
    pub fn window_velocity(a: f64, g: f64, w: f64) -> Option<[f64; 2]> {
        if w.is_nan() || w <= 0.0 {
            return None;
        }
        // Back from t by w: x(t − w) = x(t) + φ(−w)·v(t) + g·ψ(−w)·u.
        let (ph, ps) = phi_psi(a, -w);
        Some([-ph / w, -g * ps / w])
    }
}

/// The model of one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AxisModel {
    /// Torque mode.
    Torque(TorqueAxis),
    /// Velocity mode.
    Velocity(VelocityAxis),
}

impl AxisModel {
    /// Advances (x, v) by `dt` with `u` held.
    pub fn step(&self, x: &mut f64, v: &mut f64, u: f64, dt: f64) {
        match self {
            AxisModel::Torque(a) => a.step(x, v, u, dt),
            AxisModel::Velocity(a) => a.step(x, v, u, dt),
        }
    }
    /// Command range ±u_max \[V\].
    pub fn u_max(&self) -> f64 {
        match self {
            AxisModel::Torque(a) => a.u_max,
            AxisModel::Velocity(a) => a.u_max,
        }
    }
    /// (a, g) of ẍ = g·u − a·ẋ, or `None` for a nonlinear axis.
    pub fn linear(&self) -> Option<(f64, f64)> {
        match self {
            AxisModel::Torque(a) => a.linear(),
            AxisModel::Velocity(a) => Some(a.linear()),
        }
    }

    /// (a, g) of the axis with Coulomb friction and saturation left out (the linearisation
    /// used by the discrete-time stability check).
    pub fn linear_part(&self) -> (f64, f64) {
        match self {
            AxisModel::Torque(a) => a.linear_part(),
            AxisModel::Velocity(a) => a.linear(),
        }
    }
    /// H and C of this axis in the theory's units (docs/system.md, "Plant and controller"): torque mode
    /// H = J/K_a [V·s²/rad], C = b/K_a [V·s/rad]; velocity mode H = τ_v/k_v, C = 1/k_v.
    pub fn theory_h_c(&self) -> (f64, f64) {
        match self {
            AxisModel::Torque(a) => (
                a.inertia / a.torque_constant,
                a.friction.viscous / a.torque_constant,
            ),
            AxisModel::Velocity(a) => (a.time_constant / a.gain, 1.0 / a.gain),
        }
    }
}

/// A plant of n mechanically independent axes (the paper's experiment).
#[derive(Debug, Clone, PartialEq)]
pub struct IndependentAxes {
    /// The axis models.
    pub models: Vec<AxisModel>,
    x: Vec<f64>,
    v: Vec<f64>,
}

impl IndependentAxes {
    /// All axes at rest at position 0.
    pub fn new(models: Vec<AxisModel>) -> Self {
        let n = models.len();
        IndependentAxes {
            models,
            x: vec![0.0; n],
            v: vec![0.0; n],
        }
    }
    /// Sets the state of axis `i` [rad, rad/s].
    pub fn set_state(&mut self, i: usize, x: f64, v: f64) {
        self.x[i] = x;
        self.v[i] = v;
    }
}

impl Plant for IndependentAxes {
    fn axes(&self) -> usize {
        self.models.len()
    }
    fn position(&self, i: usize) -> f64 {
        self.x[i]
    }
    fn velocity(&self, i: usize) -> f64 {
        self.v[i]
    }
    fn advance(&mut self, u: &[f64], dt: f64) -> Result<(), PlantError> {
        if u.len() != self.models.len() {
            return Err(PlantError::LengthMismatch {
                what: "commands",
                expected: self.models.len(),
                got: u.len(),
            });
        }
        for (i, m) in self.models.iter().enumerate() {
            m.step(&mut self.x[i], &mut self.v[i], u[i], dt);
        }
        Ok(())
    }
}

impl Dynamics for IndependentAxes {
    fn dof(&self) -> usize {
        self.models.len()
    }
    fn inertia(&self, _x: &[f64], h: &mut [f64]) {
        let n = self.models.len();
        h.fill(0.0);
        for (i, m) in self.models.iter().enumerate() {
            h[i * n + i] = m.theory_h_c().0;
        }
    }
    fn coriolis(&self, _x: &[f64], _v: &[f64], c: &mut [f64]) {
        let n = self.models.len();
        c.fill(0.0);
        for (i, m) in self.models.iter().enumerate() {
            c[i * n + i] = m.theory_h_c().1;
        }
    }
    fn inertia_rate(&self, _x: &[f64], _v: &[f64], hd: &mut [f64]) {
        hd.fill(0.0);
    }
}

#[cfg(test)]
mod tests;
