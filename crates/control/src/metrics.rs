//! Metrics (eq. 26-27), streaming in constant memory:
//!
//! ```text
//! Track-RMSE = sqrt( (1/N) Σ_j Σ_i e_i(j)² )      Sync-RMSE = sqrt( (1/N) Σ_j Σ_i ε_i(j)² )
//! ```
//!
//! over N samples (one per cycle); the sum over the axes is inside the root, so for n axes
//! these are not per-axis averages. Per axis: RMS and maximum |e| and |ε|, RMS and peak |u|,
//! and how often the command was clipped.

use crate::coupling::Coupling;
use crate::error::{ControlError, check_len};

/// Accumulates one sample per cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct Metrics {
    coupling: Option<Coupling>,
    samples: u64,
    sum_e2: Vec<f64>,
    sum_eps2: Vec<f64>,
    max_e: Vec<f64>,
    max_eps: Vec<f64>,
    sum_u2: Vec<f64>,
    peak_u: Vec<f64>,
    saturations: Vec<u64>,
    eps: Vec<f64>,
}

/// Figures of one axis.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisSummary {
    /// RMS of e \[rad\].
    pub rms_e: f64,
    /// Largest |e| \[rad\].
    pub max_e: f64,
    /// RMS of ε \[rad\].
    pub rms_eps: f64,
    /// Largest |ε| \[rad\].
    pub max_eps: f64,
    /// RMS of the command \[V\].
    pub rms_u: f64,
    /// Largest |command| \[V\].
    pub peak_u: f64,
    /// Cycles in which the command was clipped.
    pub saturations: u64,
}

/// The metrics of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Samples N.
    pub samples: u64,
    /// Track-RMSE (eq. 26) \[rad\].
    pub track_rmse: f64,
    /// Sync-RMSE (eq. 27) \[rad\]; 0 for a single axis.
    pub sync_rmse: f64,
    /// Per axis.
    pub axes: Vec<AxisSummary>,
}

impl Metrics {
    /// Metrics for `n` ≥ 1 axes (ε needs n ≥ 2; it is 0 for one axis).
    pub fn new(n: usize) -> Self {
        Metrics {
            coupling: Coupling::new(n, 0.0).ok(),
            samples: 0,
            sum_e2: vec![0.0; n],
            sum_eps2: vec![0.0; n],
            max_e: vec![0.0; n],
            max_eps: vec![0.0; n],
            sum_u2: vec![0.0; n],
            peak_u: vec![0.0; n],
            saturations: vec![0; n],
            eps: vec![0.0; n],
        }
    }

    /// Adds one cycle: errors e \[rad\], commands u \[V\] and their saturation flags.
    pub fn push(&mut self, e: &[f64], u: &[f64], saturated: &[bool]) -> Result<(), ControlError> {
        let n = self.sum_e2.len();
        check_len("errors", n, e.len())?;
        check_len("commands", n, u.len())?;
        check_len("saturation flags", n, saturated.len())?;
        if let Some(c) = &self.coupling {
            c.sync_errors(e, &mut self.eps)?;
        }
        for i in 0..n {
            let (ei, epsi, ui) = (e[i], self.eps[i], u[i]);
            self.sum_e2[i] += ei * ei;
            self.sum_eps2[i] += epsi * epsi;
            self.max_e[i] = self.max_e[i].max(ei.abs());
            self.max_eps[i] = self.max_eps[i].max(epsi.abs());
            self.sum_u2[i] += ui * ui;
            self.peak_u[i] = self.peak_u[i].max(ui.abs());
            self.saturations[i] += u64::from(saturated[i]);
        }
        self.samples += 1;
        Ok(())
    }

    /// The figures so far (all zero before the first sample).
    pub fn summary(&self) -> Summary {
        let n = self.samples.max(1) as f64;
        let axes = (0..self.sum_e2.len())
            .map(|i| AxisSummary {
                rms_e: (self.sum_e2[i] / n).sqrt(),
                max_e: self.max_e[i],
                rms_eps: (self.sum_eps2[i] / n).sqrt(),
                max_eps: self.max_eps[i],
                rms_u: (self.sum_u2[i] / n).sqrt(),
                peak_u: self.peak_u[i],
                saturations: self.saturations[i],
            })
            .collect();
        Summary {
            samples: self.samples,
            track_rmse: (self.sum_e2.iter().sum::<f64>() / n).sqrt(),
            sync_rmse: (self.sum_eps2.iter().sum::<f64>() / n).sqrt(),
            axes,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rmse_sums_axes_inside_the_root() {
        let mut m = Metrics::new(2);
        // Two samples: e = (1, 3) then (−1, 1).
        m.push(&[1.0, 3.0], &[12.0, 0.0], &[true, false])
            .expect("push");
        m.push(&[-1.0, 1.0], &[-2.0, 0.0], &[false, false])
            .expect("push");
        let s = m.summary();
        // Track: sqrt((1 + 9 + 1 + 1)/2) = sqrt(6).
        assert!((s.track_rmse - 6f64.sqrt()).abs() < 1e-12);
        // n = 2: ε = (e1 − e2, e2 − e1) = (−2, 2), (−2, 2): sqrt((4+4+4+4)/2) = sqrt(8).
        assert!((s.sync_rmse - 8f64.sqrt()).abs() < 1e-12);
        assert_eq!(s.axes[0].max_e, 1.0);
        assert_eq!(s.axes[1].max_eps, 2.0);
        assert_eq!(s.axes[0].peak_u, 12.0);
        assert!((s.axes[0].rms_u - (74.0f64).sqrt()).abs() < 1e-12);
        assert_eq!(s.axes[0].saturations, 1);
        assert!(m.push(&[1.0], &[0.0, 0.0], &[false, false]).is_err());
    }

    #[test]
    fn equal_errors_have_no_sync_error() {
        let mut m = Metrics::new(4);
        for k in 0..100 {
            let e = k as f64 * 0.01;
            m.push(&[e; 4], &[0.0; 4], &[false; 4]).expect("push");
        }
        let s = m.summary();
        assert!(s.sync_rmse < 1e-15 && s.track_rmse > 0.5);
        // One axis: no ε at all.
        let mut one = Metrics::new(1);
        one.push(&[2.0], &[0.0], &[false]).expect("push");
        assert_eq!(one.summary().sync_rmse, 0.0);
    }
}
