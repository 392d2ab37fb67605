//! Error transforms (eq. 3-7), all O(n) without forming matrices.
//!
//! - synchronisation error ε = T·e, T = (n/(n−1))·I − (1/(n−1))·1·1ᵀ (eq. 5):
//!   ε_i = e_i − (S − e_i)/(n−1) with S = Σ_j e_j;
//! - coupled error E = (I + αT)·e = e + α·ε (eq. 7);
//! - (I + αT)⁻¹·v = mean(v)·1 + (v − mean(v)·1)/(1 + α·n/(n−1)), since T has eigenvalue 0
//!   on 1 and n/(n−1) on its orthogonal complement;
//! - the split I + αT = P − Q with P = (1+α)·I and Q = (α/(n−1))·(1·1ᵀ − I);
//! - for the ring-coupled baseline, E = (I + αL)·e with the ring Laplacian L.

use crate::error::{ControlError, check_gain, check_len};

/// The peer coupling of n ≥ 2 axes with weight α ≥ 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coupling {
    n: usize,
    alpha: f64,
}

impl Coupling {
    /// Checks n ≥ 2 and α finite and ≥ 0.
    pub fn new(n: usize, alpha: f64) -> Result<Self, ControlError> {
        if n < 2 {
            return Err(ControlError::TooFewAxes {
                what: "synchronisation coupling",
                n,
                min: 2,
            });
        }
        check_gain("alpha", alpha, 0.0, false, ">= 0 ..= 1e12 (dimensionless)")?;
        Ok(Coupling { n, alpha })
    }

    /// Number of axes n.
    pub fn n(&self) -> usize {
        self.n
    }
    /// Coupling weight α.
    pub fn alpha(&self) -> f64 {
        self.alpha
    }
    /// The two eigenvalues of I + αT: 1 (on 1) and 1 + α·n/(n−1).
    pub fn eigenvalues(&self) -> (f64, f64) {
        (1.0, self.denominator())
    }
    /// 1 + α·n/(n−1).
    pub fn denominator(&self) -> f64 {
        1.0 + self.alpha * self.n as f64 / (self.n - 1) as f64
    }
    /// P = p·I and Q = q·(1·1ᵀ − I) with I + αT = P − Q: returns (p, q) = (1+α, α/(n−1)).
    pub fn split(&self) -> (f64, f64) {
        (1.0 + self.alpha, self.alpha / (self.n - 1) as f64)
    }

    fn lens(&self, a: usize, b: usize) -> Result<(), ControlError> {
        check_len("input", self.n, a)?;
        check_len("output", self.n, b)
    }

    /// ε = T·e (eq. 5).
    pub fn sync_errors(&self, e: &[f64], eps: &mut [f64]) -> Result<(), ControlError> {
        self.lens(e.len(), eps.len())?;
        let s: f64 = e.iter().sum();
        let k = 1.0 / (self.n - 1) as f64;
        for (o, &ei) in eps.iter_mut().zip(e) {
            *o = ei - (s - ei) * k;
        }
        Ok(())
    }

    /// E = (I + αT)·e = e + α·ε (eq. 7).
    pub fn coupled(&self, e: &[f64], out: &mut [f64]) -> Result<(), ControlError> {
        self.lens(e.len(), out.len())?;
        let s: f64 = e.iter().sum();
        let k = 1.0 / (self.n - 1) as f64;
        for (o, &ei) in out.iter_mut().zip(e) {
            *o = ei + self.alpha * (ei - (s - ei) * k);
        }
        Ok(())
    }

    /// (I + αT)⁻¹·v.
    pub fn inverse(&self, v: &[f64], out: &mut [f64]) -> Result<(), ControlError> {
        self.lens(v.len(), out.len())?;
        let mean = v.iter().sum::<f64>() / self.n as f64;
        let d = self.denominator();
        for (o, &vi) in out.iter_mut().zip(v) {
            *o = mean + (vi - mean) / d;
        }
        Ok(())
    }
}

/// E = (I + αL)·e with L the Laplacian of the ring 1 − 2 − … − n − 1:
/// E_i = e_i + α·(2·e_i − e_{i−1} − e_{i+1}), indices modulo n (n ≥ 2; for n = 2 both
/// neighbours are the other axis).
pub fn ring_coupled(e: &[f64], alpha: f64, out: &mut [f64]) -> Result<(), ControlError> {
    let n = e.len();
    if n < 2 {
        return Err(ControlError::TooFewAxes {
            what: "ring coupling",
            n,
            min: 2,
        });
    }
    check_len("output", n, out.len())?;
    for i in 0..n {
        let prev = e[(i + n - 1) % n];
        let next = e[(i + 1) % n];
        out[i] = e[i] + alpha * (2.0 * e[i] - prev - next);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// The matrix T, formed explicitly, only for checking.
    fn t_matrix(n: usize) -> Vec<Vec<f64>> {
        let k = 1.0 / (n - 1) as f64;
        (0..n)
            .map(|i| (0..n).map(|j| if i == j { 1.0 } else { -k }).collect())
            .collect()
    }

    fn errors() -> impl Strategy<Value = (Vec<f64>, f64)> {
        (2usize..40).prop_flat_map(|n| (prop::collection::vec(-10.0f64..10.0, n), 0.0f64..50.0))
    }

    proptest! {
        #[test]
        fn sync_errors_sum_to_zero_and_match_t((e, _a) in errors()) {
            let c = Coupling::new(e.len(), 0.0).expect("coupling");
            let mut eps = vec![0.0; e.len()];
            c.sync_errors(&e, &mut eps).expect("eps");
            let sum: f64 = eps.iter().sum();
            prop_assert!(sum.abs() < 1e-10, "Σε = {sum}");
            let t = t_matrix(e.len());
            for i in 0..e.len() {
                let ti: f64 = t[i].iter().zip(&e).map(|(a, b)| a * b).sum();
                prop_assert!((ti - eps[i]).abs() < 1e-10);
            }
        }

        #[test]
        fn inverse_undoes_coupling((e, alpha) in errors()) {
            let c = Coupling::new(e.len(), alpha).expect("coupling");
            let (mut big_e, mut back) = (vec![0.0; e.len()], vec![0.0; e.len()]);
            c.coupled(&e, &mut big_e).expect("E");
            c.inverse(&big_e, &mut back).expect("inverse");
            for (a, b) in e.iter().zip(&back) {
                prop_assert!((a - b).abs() < 1e-9 * (1.0 + a.abs()), "{a} vs {b}");
            }
        }

        #[test]
        fn split_is_p_minus_q((e, alpha) in errors()) {
            let n = e.len();
            let c = Coupling::new(n, alpha).expect("coupling");
            let (p, q) = c.split();
            let s: f64 = e.iter().sum();
            let mut big_e = vec![0.0; n];
            c.coupled(&e, &mut big_e).expect("E");
            for i in 0..n {
                // (P − Q)e = p·e_i − q·(S − e_i)
                prop_assert!((p * e[i] - q * (s - e[i]) - big_e[i]).abs() < 1e-9 * (1.0 + s.abs()));
            }
        }
    }

    #[test]
    fn eigenvalues_of_i_plus_alpha_t() {
        let (n, alpha) = (5, 0.5);
        let c = Coupling::new(n, alpha).expect("coupling");
        let mut out = vec![0.0; n];
        // On 1: eigenvalue 1.
        c.coupled(&[1.0; 5], &mut out).expect("E");
        assert!(out.iter().all(|v| (v - 1.0).abs() < 1e-12));
        // On a vector orthogonal to 1: 1 + α·n/(n−1) = 1.625.
        let w = [1.0, -1.0, 2.0, 0.0, -2.0];
        c.coupled(&w, &mut out).expect("E");
        for (o, wi) in out.iter().zip(w) {
            assert!((o - 1.625 * wi).abs() < 1e-12);
        }
        assert_eq!(c.eigenvalues(), (1.0, 1.625));
    }

    #[test]
    fn coupling_needs_two_axes_and_a_real_alpha() {
        assert!(matches!(
            Coupling::new(1, 0.5),
            Err(ControlError::TooFewAxes { n: 1, min: 2, .. })
        ));
        assert!(matches!(
            Coupling::new(4, f64::NAN),
            Err(ControlError::InvalidParameter { .. })
        ));
        assert!(Coupling::new(4, -0.1).is_err());
        let c = Coupling::new(4, 0.5).expect("ok");
        assert!(matches!(
            c.sync_errors(&[0.0; 3], &mut [0.0; 4]),
            Err(ControlError::LengthMismatch { .. })
        ));
    }

    #[test]
    fn ring_laplacian() {
        let mut out = [0.0; 4];
        ring_coupled(&[1.0, 0.0, 0.0, 0.0], 0.5, &mut out).expect("ring");
        assert_eq!(out, [2.0, -0.5, 0.0, -0.5]);
        // Equal errors are not coupled.
        ring_coupled(&[3.0; 4], 0.5, &mut out).expect("ring");
        assert_eq!(out, [3.0; 4]);
        assert!(ring_coupled(&[1.0], 0.5, &mut [0.0]).is_err());
    }
}
