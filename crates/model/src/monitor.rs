//! Drive-style supervision of the motion (docs/safety.md, "The sync monitor"): per axis a
//! sync-error (ε) monitor and a following-error monitor, each with a warning and a trip
//! limit, a filter time and a reaction, as gantry and following-error monitoring in
//! drives (TwinCAT's position-lag and gantry monitoring) have them.
//!
//! The filter is a time qualification: a limit counts as exceeded when the value has been
//! beyond it in every law run for at least the filter time (from the first run beyond it
//! to this one). Unlike a first-order filter, this makes the trip instant exact and
//! independent of how far the value is beyond the limit (the first run beyond the limit
//! plus the filter time, rounded up to the next law run), never trips on a spike shorter
//! than the filter, and reports the true value, not a smoothed one.
//!
//! The monitors run in the master's motion ([`ControlMotion`](crate::motion::ControlMotion))
//! on what the master measured (e = x^d(t_s) − x at each sample's instant t_s, ε = T·e in
//! O(n)), so the simulator and the runtime run the same code on the same figures.

use ringsync_proto::Duration;
use ringsync_proto::node::{MonitorKind, MonitorNews, StopReason};

/// A monitor's news at a time, as a run records it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MonitorEvent {
    /// When the master's law run saw it [s, true time].
    pub t: f64,
    /// The axis (1-based, as in summary.json).
    pub axis: usize,
    /// Which monitor and limit.
    pub kind: MonitorKind,
    /// Raised (true) or cleared (false; only a warning clears, a trip latches).
    pub raised: bool,
    /// The monitored value then (ε or the following error) \[rad\].
    pub value: f64,
}

/// What a monitor's trip does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Reaction {
    /// Report it (summary.json, the scope, the report); the motion goes on.
    Warn,
    /// Report it and stop the group (its own stop reason).
    #[default]
    GroupStop,
}

impl Reaction {
    /// As written in scenarios and outputs: `warn`, `group-stop`.
    pub fn name(self) -> &'static str {
        match self {
            Reaction::Warn => "warn",
            Reaction::GroupStop => "group-stop",
        }
    }
}

impl std::str::FromStr for Reaction {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "warn" => Ok(Reaction::Warn),
            "group-stop" => Ok(Reaction::GroupStop),
            other => Err(format!(
                "unknown reaction \"{other}\": expected \"warn\" or \"group-stop\""
            )),
        }
    }
}

/// One monitor's settings (sync error or following error).
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// Warning limit per axis \[rad\] (0: no warning).
    pub warn: Vec<f64>,
    /// Trip limit per axis \[rad\] (0: no trip).
    pub trip: Vec<f64>,
    /// How long a limit must be exceeded without a break before it counts.
    pub filter: Duration,
    /// What a trip does.
    pub reaction: Reaction,
}

impl Limits {
    /// No limits on `n` axes.
    pub fn off(n: usize) -> Self {
        Limits {
            warn: vec![0.0; n],
            trip: vec![0.0; n],
            filter: Duration::ZERO,
            reaction: Reaction::GroupStop,
        }
    }
    /// Whether any limit is set.
    pub fn enabled(&self) -> bool {
        self.warn.iter().chain(&self.trip).any(|l| *l > 0.0)
    }
}

/// Both monitors' settings.
#[derive(Debug, Clone, PartialEq)]
pub struct MonitorSettings {
    /// The sync-error (ε) monitor.
    pub sync: Limits,
    /// The following-error monitor (the hard following-error limit of the group stop stays
    /// beside it).
    pub following: Limits,
}

impl MonitorSettings {
    /// Both off, on `n` axes.
    pub fn off(n: usize) -> Self {
        MonitorSettings {
            sync: Limits::off(n),
            following: Limits::off(n),
        }
    }
    /// Whether any limit is set.
    pub fn enabled(&self) -> bool {
        self.sync.enabled() || self.following.enabled()
    }
}

/// One limit of one axis: since when it has been exceeded, and whether it is raised.
#[derive(Debug, Clone, Copy, Default)]
struct Level {
    since: Option<i64>,
    raised: bool,
}

impl Level {
    /// Takes the value `v` at `now` [ns] against `limit`; returns the news, if any.
    fn check(&mut self, v: f64, limit: f64, filter: i64, now: i64, latch: bool) -> Option<bool> {
        if limit <= 0.0 {
            return None;
        }
        if v.abs() > limit {
            let since = *self.since.get_or_insert(now);
            if !self.raised && now - since >= filter {
                self.raised = true;
                return Some(true);
            }
        } else {
            self.since = None;
            if self.raised && !latch {
                self.raised = false;
                return Some(false);
            }
        }
        None
    }
}

/// The monitors' state over a run.
#[derive(Debug, Clone)]
pub struct Monitor {
    settings: MonitorSettings,
    /// Per axis: sync warning, sync trip, following warning, following trip.
    levels: Vec<[Level; 4]>,
    eps: Vec<f64>,
}

impl Monitor {
    /// Monitors with `settings` (their vectors one entry per axis).
    pub fn new(settings: MonitorSettings) -> Self {
        let n = settings.sync.warn.len();
        Monitor {
            settings,
            levels: vec![[Level::default(); 4]; n],
            eps: vec![0.0; n],
        }
    }

    /// The settings.
    pub fn settings(&self) -> &MonitorSettings {
        &self.settings
    }

    /// Whether axis `i` is in sync: its sync error is neither warning nor tripped.
    pub fn in_sync(&self, i: usize) -> bool {
        self.levels
            .get(i)
            .is_none_or(|l| !l[0].raised && !l[1].raised)
    }

    /// One law run at `now` \[ns\] on the following errors `e` \[rad\] of every axis (all
    /// measured): news into `out`, and the first trip whose reaction is the group stop.
    pub fn check(&mut self, now: i64, e: &[f64], out: &mut Vec<MonitorNews>) -> Option<StopReason> {
        let n = e.len().min(self.levels.len());
        if !self.settings.enabled() || n == 0 {
            return None;
        }
        // ε_i = e_i − (S − e_i)/(n − 1) (docs/system.md eq. 3-5), O(n).
        let sync_on = n >= 2 && self.settings.sync.enabled();
        if sync_on {
            let s: f64 = e[..n].iter().sum();
            let d = (n - 1) as f64;
            for (eps, &ei) in self.eps.iter_mut().zip(&e[..n]) {
                *eps = ei - (s - ei) / d;
            }
        }
        let mut stop = None;
        let kinds = [
            MonitorKind::SyncWarning,
            MonitorKind::SyncTrip,
            MonitorKind::FollowingWarning,
            MonitorKind::FollowingTrip,
        ];
        for (i, &ei) in e[..n].iter().enumerate() {
            for (j, kind) in kinds.iter().enumerate() {
                let (lim, v) = if j < 2 {
                    if !sync_on {
                        continue;
                    }
                    (&self.settings.sync, self.eps[i])
                } else {
                    (&self.settings.following, ei)
                };
                let trip = j % 2 == 1;
                let limit = if trip { lim.trip[i] } else { lim.warn[i] };
                let filter = lim.filter.as_ns();
                if let Some(raised) = self.levels[i][j].check(v, limit, filter, now, trip) {
                    out.push(MonitorNews {
                        axis: i,
                        kind: *kind,
                        raised,
                        value: v,
                    });
                    if raised && trip && lim.reaction == Reaction::GroupStop && stop.is_none() {
                        stop = Some(if j < 2 {
                            StopReason::SyncTrip { axis: i, error: v }
                        } else {
                            StopReason::FollowingTrip { axis: i, error: v }
                        });
                    }
                }
            }
        }
        stop
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(filter_ms: i64, reaction: Reaction) -> MonitorSettings {
        MonitorSettings {
            sync: Limits {
                warn: vec![0.02; 3],
                trip: vec![0.025; 3],
                filter: Duration::from_ms(filter_ms),
                reaction,
            },
            following: Limits::off(3),
        }
    }

    #[test]
    fn trips_after_the_filter_time_and_not_on_a_shorter_spike() {
        let mut m = Monitor::new(settings(5, Reaction::GroupStop));
        let mut out = Vec::new();
        // Axis 0 leads by 0.03 rad: ε_0 = 0.03 − 0 = 0.03 > both limits; the others'
        // ε = −0.015 stays within.
        let big = [0.03, 0.0, 0.0];
        let ms = 1_000_000;
        // A spike of 4 ms (runs at 0..=3 ms), then back: nothing.
        for k in 0..4 {
            assert_eq!(m.check(k * ms, &big, &mut out), None);
        }
        assert_eq!(m.check(4 * ms, &[0.0; 3], &mut out), None);
        assert!(out.is_empty(), "{out:?}");
        // Sustained from 10 ms: the warning and the trip at 15 ms exactly.
        for k in 10..15 {
            assert_eq!(m.check(k * ms, &big, &mut out), None);
        }
        let stop = m.check(15 * ms, &big, &mut out);
        assert!(
            matches!(stop, Some(StopReason::SyncTrip { axis: 0, error }) if (error - 0.03).abs() < 1e-12)
        );
        assert_eq!(out.len(), 2);
        assert!(out.iter().all(|n| n.axis == 0 && n.raised));
        assert!(!m.in_sync(0) && m.in_sync(1));
    }

    #[test]
    fn a_warning_clears_and_a_trip_latches_and_warn_does_not_stop() {
        let mut m = Monitor::new(settings(0, Reaction::Warn));
        let mut out = Vec::new();
        assert_eq!(m.check(0, &[0.03, 0.0, 0.0], &mut out), None);
        assert_eq!(out.len(), 2);
        out.clear();
        m.check(1, &[0.0, 0.0, 0.0], &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].kind, MonitorKind::SyncWarning);
        assert!(!out[0].raised);
        // The trip latched: still not in sync.
        assert!(!m.in_sync(0));
    }
}
