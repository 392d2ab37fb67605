//! The ring's timing over a run, as the loop measures it: each cycle start's lateness, the
//! P2P phase, the host's stalls, the overruns and outages. The definitions here are the ones
//! `ringsync latency` measures the bare host with ([`crate::clock`]).

use ringsync_proto::node::MasterCounters;

use crate::stats::{Delays, Percentiles};

/// A stall this long or longer is the host holding the loop off its CPU (a pass of the
/// loop takes a few µs; measured in docs/runtime.md) \[ns\].
pub const STALL: i64 = 50_000;

/// The ring's timing over the run.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Timing {
    /// Cycles the master started (fewer than planned when the run was interrupted).
    pub cycles: i64,
    /// Cycles planned: the duration over the cycle time.
    pub cycles_planned: i64,
    /// Cycles that did not finish in time (lumped frame or a command lost).
    pub overruns: u64,
    /// Cycles whose lumped frame was lost or late.
    pub lumped_lost: u64,
    /// Commands not acknowledged within their cycle.
    pub commands_lost: u64,
    /// Lateness of the cycle start (the lumped frame's send) behind k·T_cyc.
    pub lateness: Percentiles,
    /// P2P phase: from the law's run to the last response of the cycle.
    pub p2p: Percentiles,
    /// Timer deadlines run later than 1 ms.
    pub late_timers: u64,
    /// Sends that failed (a node gone, a link down).
    pub send_errors: u64,
    /// Frames a node could not send on because both its links were broken, or the
    /// master's port was (`faults.break_link`: the PHY knows; nothing is sent).
    pub broken_dropped: u64,
    /// Receives that failed (a link went down); the port is read again
    /// [`RX_RETRY`](crate::ring::RX_RETRY) later.
    pub receive_errors: u64,
    /// Frames the runtime dropped on the link of a `--flap` over UDP while it was down
    /// (UDP has no link to take down: the loop drops what the link would carry).
    pub flap_dropped: u64,
    /// Sync lumped frames whose stamp a transparent relay moved on by the time it held them
    /// (kernel stamps, a ring of node processes), summed over the nodes.
    pub relay_corrected: u64,
    /// Frames a transparent relay passed on untouched: relayed unread and failing their
    /// checks, or lumped frames whose stamp would have overflowed.
    pub relay_uncorrected: u64,
    /// How long the flapped link was down \[ns\] (veth): from before the call that took it
    /// down to after the call that brought it up (microseconds more than asked).
    pub flap_down_ns: Option<i64>,
    /// Cycle starts whose true axis states were read after the axis had moved on.
    pub probes_late: u64,
    /// Encoder latches taken after their axis had moved past their instant (0 by design:
    /// latches are taken before any frame moves the axis on).
    pub latches_late: u64,
    /// The longest stall of each cycle \[ns\]: the longest gap between two of the loop's
    /// clock readings beyond what it asked of a sleep, or the cycle's late start. The loop
    /// reads the clock at every frame and timer, so a gap of [`STALL`] or more is the host
    /// holding it off its CPU.
    pub stalls: Percentiles,
    /// Cycles with a stall of [`STALL`] or more.
    pub cycles_stalled: u64,
    /// Overruns in cycles with a stall of [`STALL`] or more.
    pub overruns_stalled: u64,
    /// The longest run of consecutive overruns \[cycles\]: the longest the axes went without
    /// fresh feedback or a command (the master stops the group at W).
    pub longest_outage: u64,
}

/// The loop's running account of [`Timing`]: counters, and histograms its percentiles are
/// taken from at the end (allocated once: a run of any length takes the same memory, and
/// recording never allocates).
#[derive(Debug, Clone, Default)]
pub(crate) struct TimingLog {
    /// The counters so far.
    pub timing: Timing,
    lateness: Delays,
    p2p: Delays,
    stalls: Delays,
    last_losses: u64,
    outage: u64,
    computed_at: Option<i64>,
    last_master_rx: i64,
}

impl TimingLog {
    /// The account of a run of `cycles` cycles.
    pub fn new(cycles: i64) -> Self {
        TimingLog {
            timing: Timing {
                cycles_planned: cycles,
                ..Timing::default()
            },
            ..TimingLog::default()
        }
    }

    /// The master starts cycle `k` (0-based) at `now`, due at `due` [ns]; `losses` are its
    /// lumped frames and commands lost so far, `stall` the longest stall since the last
    /// cycle start [ns]. Closes the account of the cycle that ends. Returns the stall that
    /// counts for the cycle that starts: its late start.
    pub fn cycle_start(&mut self, k: i64, now: i64, due: i64, losses: u64, stall: i64) -> i64 {
        let t = &mut self.timing;
        self.lateness.record(now - due);
        // A stall up to this cycle's start counts for the cycle that ends.
        if k > 0 {
            self.stalls.record(stall);
            if stall >= STALL {
                t.cycles_stalled += 1;
            }
        }
        if losses > self.last_losses {
            t.overruns += 1;
            if stall >= STALL {
                t.overruns_stalled += 1;
            }
            self.outage += 1;
            t.longest_outage = t.longest_outage.max(self.outage);
        } else {
            self.outage = 0;
        }
        self.last_losses = losses;
        if let Some(c) = self.computed_at.take()
            && self.last_master_rx > c
        {
            self.p2p.record(self.last_master_rx - c);
        }
        t.cycles = k + 1;
        // A late start is a stall of the cycle it delays: its lumped frame leaves late
        // against a P2P start that does not move.
        now - due
    }

    /// The law ran at `now` [ns] (the P2P phase begins).
    pub fn computed(&mut self, now: i64) {
        self.computed_at = Some(now);
    }

    /// The master read a frame at `now` [ns].
    pub fn master_rx(&mut self, now: i64) {
        self.last_master_rx = now;
    }

    /// Cycle-start lateness so far (for a progress line).
    pub fn lateness(&self) -> Percentiles {
        self.lateness.percentiles()
    }

    /// The run's timing, with the master's loss counters.
    pub fn finish(self, master: &MasterCounters) -> Timing {
        Timing {
            lateness: self.lateness.percentiles(),
            p2p: self.p2p.percentiles(),
            stalls: self.stalls.percentiles(),
            lumped_lost: master.lumped_lost,
            commands_lost: master.commands_lost,
            ..self.timing
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Overruns, their stalls and the longest outage from a made-up run of five cycles.
    #[test]
    fn cycles_are_accounted() {
        let mut log = TimingLog::new(5);
        // (now, due, losses so far, stall since the last start)
        let starts = [
            (10, 0, 0, 0),
            (1_000, 1_000, 1, 60_000),
            (2_000, 2_000, 2, 0),
            (3_000, 3_000, 2, 0),
            (4_500, 4_000, 3, 0),
        ];
        for (k, &(now, due, losses, stall)) in starts.iter().enumerate() {
            assert_eq!(
                log.cycle_start(k as i64, now, due, losses, stall),
                now - due
            );
            // The cycle's P2P phase: the law runs, the last response comes back.
            log.computed(now + 100);
            log.master_rx(now + 400);
        }
        let t = log.finish(&MasterCounters::default());
        assert_eq!(t.cycles, 5);
        assert_eq!(t.overruns, 3);
        assert_eq!(t.overruns_stalled, 1);
        assert_eq!(t.cycles_stalled, 1);
        assert_eq!(t.longest_outage, 2);
        assert_eq!(t.lateness.max, 500);
        assert_eq!(t.stalls.count, 4);
        assert_eq!(t.p2p.count, 4);
        assert_eq!(t.p2p.max, 300);
    }
}
