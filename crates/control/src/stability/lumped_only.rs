//! The discrete-time check of the lumped-only plan of ref. [3] (docs/system.md, "The
//! lumped-only plan of ref. [3]"): no master law, one lumped frame a cycle, and each slave
//! running the law itself when the frame passes it.
//!
//! Slave i (1-based) takes the frame `passes[i − 1]` after the cycle's sampling instant and
//! applies its own axis's command at once. The frame then holds this cycle's samples of
//! slaves 1..=i (written as the frame passed them, slave i's own included) and last cycle's
//! of slaves i + 1..=n (written a cycle ago): slave i's history of an upstream axis ends
//! with e[k], of a downstream one with e[k − 1], sampled one cycle earlier, which the law's
//! estimator bridges over D = pass + T_cyc. Each slave keeps its own history of every axis,
//! so the loop carries the four newest samples of e and ė per axis (e[k − 1..k − 4]): 11
//! states per axis, [`LUMPED_ONLY_STATE_NAMES`].

use nalgebra::DMatrix;

use super::{DiscreteLoop, Measurement, discretised, reported_velocity};
use crate::error::ControlError;
use crate::estimator::{DEPTH, ErrorHistory};
use crate::law::{ControlInput, ControlLaw, ControlOutput, VelocitySource};

/// The names of an axis's states in [`lumped_only_loop`], in their order: x \[rad\], ẋ
/// [rad/s], the command still held u[k−1] \[V\], e[k−1..k−4] \[rad\], ė[k−1..k−4] [rad/s].
pub const LUMPED_ONLY_STATE_NAMES: [&str; 11] = [
    "x", "v", "u_prev", "e1", "e2", "e3", "e4", "de1", "de2", "de3", "de4",
];

/// The sampled closed loop of the lumped-only plan: `law` run by every slave on its view
/// of the ring (see the module's docs), on linear axes `(a, g)`, period `t_cyc` \[s\], slave
/// i's frame pass (its command's effect) `passes[i]` \[s\] after the sampling instant
/// (0 ≤ pass ≤ T_cyc), ė as `m` says (the reported velocity, exact or over its window, or
/// differenced samples). The matrix's states are [`LUMPED_ONLY_STATE_NAMES`] per axis,
/// axis-major; regulation to x^d = 0 as in [`super::discrete_loop`]. Refused
/// ([`ControlError::NotApplicable`]) for an estimator that is not linear in the history,
/// and for the error observer and the disturbance observer (each slave would run its own
/// on its own view: not modelled).
pub fn lumped_only_loop(
    law: &dyn ControlLaw,
    axes: &[(f64, f64)],
    t_cyc: f64,
    passes: &[f64],
    m: &Measurement,
) -> Result<DiscreteLoop, ControlError> {
    let velocity = m.velocity;
    if matches!(velocity, VelocitySource::Observer(_)) || m.dob.is_some() {
        return Err(ControlError::NotApplicable {
            what: "the lumped-only plan's discrete-time check",
            why: "each slave would run its own error or disturbance observer on its view of the ring, which the check does not model".into(),
        });
    }
    let disc = discretised(law, axes, t_cyc, passes)?;
    let reported = reported_velocity(m, axes, t_cyc, passes)?;
    let n = law.axes();
    let per = LUMPED_ONLY_STATE_NAMES.len();
    // ė of axis j's sample this cycle from its states s (e[k] = −x).
    let rate = |j: usize, s: &[f64]| -> f64 {
        match velocity {
            VelocitySource::Differenced => (-s[0] - s[3]) / t_cyc,
            _ => -(reported[j][0] * s[1] + reported[j][1] * s[2]),
        }
    };
    let dim = per * n;
    let mut mat = DMatrix::<f64>::zeros(dim, dim);
    let mut hist = ErrorHistory::new(n);
    let mut input = ControlInput::new(n, t_cyc);
    let mut out = ControlOutput::new(n);
    let mut u = vec![0.0; n];
    let mut z = vec![0.0; dim];
    for col in 0..dim {
        z.fill(0.0);
        z[col] = 1.0;
        // Slave i's command, from its own view of every axis.
        for (i, ui) in u.iter_mut().enumerate() {
            for j in 0..n {
                let s = &z[j * per..(j + 1) * per];
                if j <= i {
                    hist.e[j] = [-s[0], s[3], s[4], s[5]];
                    hist.de[j] = [rate(j, s), s[7], s[8], s[9]];
                    hist.t[j] = 0.0;
                } else {
                    hist.e[j] = [s[3], s[4], s[5], s[6]];
                    hist.de[j] = [s[7], s[8], s[9], s[10]];
                    hist.t[j] = -t_cyc;
                }
                hist.count[j] = DEPTH;
            }
            input.apply_time.fill(passes[i]);
            law.compute(&hist, &input, &mut out)?;
            *ui = out.u_raw[i];
        }
        for i in 0..n {
            let s = &z[i * per..(i + 1) * per];
            let d = &disc[i];
            let (x, v, u_prev) = (s[0], s[1], s[2]);
            let next = [
                d.phi[0][0] * x + d.phi[0][1] * v + d.gamma1[0] * u_prev + d.gamma0[0] * u[i],
                d.phi[1][0] * x + d.phi[1][1] * v + d.gamma1[1] * u_prev + d.gamma0[1] * u[i],
                u[i],
                -x,
                s[3],
                s[4],
                s[5],
                rate(i, s),
                s[7],
                s[8],
                s[9],
            ];
            for (r, val) in next.into_iter().enumerate() {
                mat[(i * per + r, col)] = val;
            }
        }
    }
    DiscreteLoop::of(mat, LUMPED_ONLY_STATE_NAMES.to_vec())
}
