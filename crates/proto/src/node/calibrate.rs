//! The start-up phase: the nodes measure the ring's delays before the first cycle, as
//! EtherCAT's master measures the propagation delays of its distributed clocks and writes
//! each slave's delay into it (docs/planner.md, "Delays measured by the nodes").
//!
//! The paper's slaves synchronise from the master's send time alone, because "every
//! residence and link delay is fixed and measured once at configuration" (docs/system.md,
//! "The cycle plan"): slave i takes the master's stamp plus its path delay D_i as the master
//! time at which the frame's first bit reached it. This phase measures D_i with real frames:
//!
//! 1. **Probes.** The [`Calibrator`] (the master in its start-up phase) sends a delay frame
//!    (kind 5) round the ring once per interval, first bit out at a time it keeps. Each
//!    slave ([`Slave::calibrating`](super::Slave::calibrating)) writes into its slot how long
//!    it held the *previous* probe, first bit in to first bit out on its own clock, and that
//!    probe's sequence number (a two-step report: a slave knows when a frame left only once
//!    it left). The master stamps each probe's first bit back at port B: the round trip R.
//! 2. **The figures.** For a probe whose round trip and every residence are known,
//!    R = (n + 1)·L + Σ r_i, with L one link (PHY out, cable, PHY in) and r_i slave i's
//!    residence; so L = (R − Σ r_i)/(n + 1). The medians over the probes give L and each
//!    r_i, and D_i = i·L + Σ_{j<i} r_j.
//! 3. **Closing.** The master sends each slave its D_i in a closing frame, once per
//!    interval until every slave has acknowledged it (marked its slot written); a slave
//!    takes its delay only in its start-up phase and then runs.
//!
//! **Assumption** (named in the outputs that use the figures): every link of the ring has
//! the same delay L. A one-directional ring gives the master the sum of the links and the
//! slaves their residences, not each link on its own; links of the same cable type and
//! length, as on a machine's ring, meet it. A link longer by δ shifts the path delays of
//! the slaves after it by up to δ·n/(n + 1).
//!
//! Nothing from the wire is trusted: a returning frame counts only as the echo of a probe
//! the master sent (its sequence number and send stamp, ns since the phase began), once; a residence only for a
//! probe the master sent, at most one cycle long; every refusal is counted.

use ringsync_wire::{Common, DelayMarker, DelaySlot, Frame, FrameKind, LumpedRepr, Pdu, SlotCodec};

use super::reject::{Reject, Rejections};
use super::{Outbox, Port, Transmit, WireFrame};
use crate::time::{Duration, Instant};

/// What the start-up phase does.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CalibrationConfig {
    /// Slaves on the ring, n.
    pub slaves: usize,
    /// Probes to send.
    pub probes: u32,
    /// One probe (or closing frame) per interval; a frame not back within it is lost.
    pub interval: Duration,
    /// Closing frames to send at most, until every slave has acknowledged its delay.
    pub closing_tries: u32,
    /// The cycle the ring will run: no delay may reach it.
    pub cycle: Duration,
    /// The relays are transparent: each slave adds to a sync lumped frame's stamp the time
    /// it held the frame (a ring of node processes with kernel stamps, whose relays are
    /// processes that must wake), so each slave is sent its links alone, i·L, as its path
    /// delay ([`Calibrator::clock_path`]); otherwise D_i, residences included.
    pub transparent: bool,
}

impl CalibrationConfig {
    /// `probes` probes (at least 2: a probe's residences come with the next one) and up to
    /// 8 closing frames on a ring of `slaves` slaves, one frame per cycle.
    pub fn new(slaves: usize, cycle: Duration, probes: u32) -> Self {
        CalibrationConfig {
            slaves,
            probes: probes.max(2),
            interval: cycle,
            closing_tries: 8,
            cycle,
            transparent: false,
        }
    }
}

/// The ring's delays as the nodes measured them.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DelayMeasurement {
    /// Probes sent.
    pub probes: u32,
    /// Probes that came back.
    pub probes_back: u32,
    /// Probes whose round trip and every residence were known: the figures come from these.
    pub complete: u32,
    /// Round trip of every probe back, first bit out to first bit back at port B, in the
    /// order sent.
    pub round_trips: Vec<Duration>,
    /// One link L (PHY out, cable, PHY in), the median over the complete probes, every
    /// link taken equal.
    pub link: Duration,
    /// Each slave's residence, first bit in to first bit out (median).
    pub residence: Vec<Duration>,
    /// Each slave's path delay D_i = i·L + Σ_{j<i} r_j: master send to its first bit in.
    pub path: Vec<Duration>,
    /// Closing frames sent.
    pub closing_sent: u32,
}

/// Why the start-up phase failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CalibrationError {
    /// No probe came back with every slave's residence.
    NoCompleteProbe {
        /// Probes sent.
        sent: u32,
        /// Probes that came back.
        back: u32,
        /// Probes that came back a cycle or more after they were sent (not counted).
        late: u32,
        /// 1-based addresses of the slaves that never reported a residence (empty when no
        /// probe came back).
        silent: Vec<usize>,
    },
    /// A measured path delay is not within (0, cycle).
    Implausible {
        /// The slave (1-based).
        slave: usize,
        /// Its measured path delay.
        path: Duration,
    },
    /// More slaves than one delay frame carries.
    TooManySlaves {
        /// Slaves on the ring.
        slaves: usize,
        /// Slots one delay frame carries.
        capacity: usize,
    },
    /// Slaves did not acknowledge their delay after every closing frame.
    NotAcknowledged {
        /// 1-based addresses.
        slaves: Vec<usize>,
    },
}

impl std::fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let list = |v: &[usize]| {
            v.iter()
                .map(|s| format!("slave {s}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        match self {
            CalibrationError::NoCompleteProbe {
                sent,
                back: 0,
                late,
                ..
            } if *late > 0 => write!(
                f,
                "{late} of {sent} delay probes came back a cycle or more after they were sent: the ring's round trip does not fit the cycle"
            ),
            CalibrationError::NoCompleteProbe { sent, back: 0, .. } => write!(
                f,
                "none of {sent} delay probes came back round the ring (a node does not forward)"
            ),
            CalibrationError::NoCompleteProbe {
                sent, back, silent, ..
            } if silent.is_empty() => {
                write!(
                    f,
                    "no delay probe came back with every slave's residence ({back} of {sent} probes back; a probe's residences come with the next one)"
                )
            }
            CalibrationError::NoCompleteProbe {
                sent, back, silent, ..
            } => write!(
                f,
                "no delay probe came back with every slave's residence ({back} of {sent} probes back): {} never reported one",
                list(silent)
            ),
            CalibrationError::Implausible { slave, path } => write!(
                f,
                "slave {slave}'s measured path delay of {:.3} µs is not between 0 and the cycle",
                path.as_us_f64()
            ),
            CalibrationError::TooManySlaves { slaves, capacity } => write!(
                f,
                "the start-up phase measures at most {capacity} slaves (one delay frame); the ring has {slaves}"
            ),
            CalibrationError::NotAcknowledged { slaves } => {
                write!(f, "{} did not acknowledge its path delay", list(slaves))
            }
        }
    }
}

impl std::error::Error for CalibrationError {}

/// Where the start-up phase stands.
#[derive(Debug, Clone, PartialEq)]
pub enum CalibrationState {
    /// Sending probes.
    Probing,
    /// Sending each slave its path delay until all have acknowledged.
    Closing,
    /// Every slave has its path delay; the ring may run.
    Done,
    /// The phase failed; the ring must not run on these figures.
    Failed(CalibrationError),
}

/// A probe sent: its sequence number, send time, and round trip once back.
#[derive(Debug, Clone, Copy)]
struct Sent {
    seq: u16,
    at: Instant,
    back: Option<Duration>,
}

/// The master in its start-up phase (see the module docs). Sans-IO, driven like
/// [`Master`](super::Master): [`poll_timeout`](Calibrator::poll_timeout) /
/// [`handle_timeout`](Calibrator::handle_timeout), [`handle_frame`](Calibrator::handle_frame)
/// for every frame back at port B with its first bit's time, and
/// [`poll_transmit`](Calibrator::poll_transmit) after either. Once
/// [`state`](Calibrator::state) is `Done`, [`measurement`](Calibrator::measurement) holds the
/// figures the master's configuration takes.
#[derive(Debug)]
pub struct Calibrator {
    cfg: CalibrationConfig,
    state: CalibrationState,
    /// The phase's start: the frames' send stamps count from it.
    start: Instant,
    /// Echoes that came back a cycle or more after their probe.
    late: u32,
    next_at: Instant,
    seq: u16,
    sent: Vec<Sent>,
    /// Residences per slave: (probe sequence number, ns on the slave's clock).
    residences: Vec<Vec<(u16, i64)>>,
    /// Closing frames sent, and which slaves acknowledged.
    closing_sent: u32,
    acked: Vec<bool>,
    /// The closing frame in flight: its sequence number and send time.
    closing: Option<(u16, Instant)>,
    measurement: Option<DelayMeasurement>,
    /// What each slave is sent as its path delay (see [`Calibrator::clock_path`]).
    clock_path: Vec<Duration>,
    out: Outbox,
    rejected: Rejections,
}

impl Calibrator {
    /// The start-up phase, its first probe at `start` on the master's clock.
    pub fn new(cfg: CalibrationConfig, start: Instant) -> Self {
        let n = cfg.slaves;
        let capacity = ringsync_wire::lumped::slot_capacity(<DelaySlot as SlotCodec>::LEN);
        let state = if n > capacity {
            CalibrationState::Failed(CalibrationError::TooManySlaves {
                slaves: n,
                capacity,
            })
        } else {
            CalibrationState::Probing
        };
        Calibrator {
            cfg,
            state,
            start,
            late: 0,
            next_at: start,
            seq: 0,
            sent: Vec::new(),
            residences: vec![Vec::new(); n],
            closing_sent: 0,
            acked: vec![false; n],
            closing: None,
            measurement: None,
            clock_path: Vec::new(),
            out: Outbox::default(),
            rejected: Rejections::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &CalibrationConfig {
        &self.cfg
    }
    /// Where the phase stands.
    pub fn state(&self) -> &CalibrationState {
        &self.state
    }
    /// The figures, once the probes are done (also while closing and after a failed
    /// closing).
    pub fn measurement(&self) -> Option<&DelayMeasurement> {
        self.measurement.as_ref()
    }
    /// The path delay each slave is sent and its clock takes, once the probes are done:
    /// the measured D_i (`DelayMeasurement::path`), or with transparent relays
    /// ([`CalibrationConfig::transparent`]) the links alone, i·L (the relays' residences
    /// then come in each frame's stamp).
    pub fn clock_path(&self) -> &[Duration] {
        &self.clock_path
    }
    /// Frames refused, per reason.
    pub fn rejected(&self) -> Rejections {
        self.rejected
    }
    /// Whether the phase has ended (done or failed).
    pub fn is_finished(&self) -> bool {
        matches!(
            self.state,
            CalibrationState::Done | CalibrationState::Failed(_)
        )
    }

    /// When to call [`Calibrator::handle_timeout`] next; `None` once finished.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        (!self.is_finished()).then_some(self.next_at)
    }

    /// The master's clock reached `now`: the next probe or closing frame, or the end of a
    /// phase.
    pub fn handle_timeout(&mut self, now: Instant) {
        if now < self.next_at || self.is_finished() {
            return;
        }
        self.next_at = now + self.cfg.interval;
        match self.state {
            CalibrationState::Probing if (self.sent.len() as u32) < self.cfg.probes => {
                self.send_probe(now);
            }
            CalibrationState::Probing => match self.figures() {
                Ok((m, links)) => {
                    self.clock_path = if self.cfg.transparent {
                        links
                    } else {
                        m.path.clone()
                    };
                    self.measurement = Some(m);
                    self.state = CalibrationState::Closing;
                    self.send_closing(now);
                }
                Err(e) => self.state = CalibrationState::Failed(e),
            },
            CalibrationState::Closing if self.acked.iter().all(|a| *a) => {
                self.state = CalibrationState::Done;
            }
            CalibrationState::Closing if self.closing_sent < self.cfg.closing_tries => {
                self.send_closing(now);
            }
            CalibrationState::Closing => {
                let slaves = (1..=self.cfg.slaves)
                    .filter(|s| !self.acked[s - 1])
                    .collect();
                self.state = CalibrationState::Failed(CalibrationError::NotAcknowledged { slaves });
            }
            CalibrationState::Done | CalibrationState::Failed(_) => {}
        }
    }

    fn frame(&mut self, now: Instant, slots: Vec<DelaySlot>) -> u16 {
        let seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        let pdu = Pdu::Delay(LumpedRepr {
            common: Common {
                seq,
                ..Common::default()
            },
            master_time_ns: self.stamp(now),
            first_slot: 0,
            slots,
        });
        self.out.push_on(now, Port::A, pdu);
        seq
    }

    /// A frame's send stamp: ns since the phase began (the phase may run before the
    /// cycles' time 0, on a time line of its own).
    fn stamp(&self, at: Instant) -> u64 {
        stamp_since(self.start, at)
    }

    fn send_probe(&mut self, now: Instant) {
        let seq = self.frame(now, vec![DelaySlot::default(); self.cfg.slaves]);
        self.sent.push(Sent {
            seq,
            at: now,
            back: None,
        });
    }

    fn send_closing(&mut self, now: Instant) {
        if self.measurement.is_none() {
            return;
        }
        let slots = self
            .clock_path
            .iter()
            .map(|d| DelaySlot {
                path_delay_ns: u32::try_from(d.as_ns()).unwrap_or(u32::MAX),
                ..DelaySlot::default()
            })
            .collect();
        let seq = self.frame(now, slots);
        self.closing = Some((seq, now));
        self.closing_sent += 1;
        if let Some(m) = &mut self.measurement {
            m.closing_sent = self.closing_sent;
        }
    }

    /// A frame whose first bit came back to the master at `rx_start` (its port B).
    pub fn handle_frame(&mut self, rx_start: Instant, bytes: &[u8]) {
        if let Err(r) = self.take(rx_start, bytes) {
            self.rejected.count(r);
        }
    }

    fn take(&mut self, rx_start: Instant, bytes: &[u8]) -> Result<(), Reject> {
        let frame = Frame::new_checked(bytes).map_err(|_| Reject::Malformed)?;
        if frame.check().map_err(|_| Reject::Malformed)? != FrameKind::Delay {
            return Err(Reject::UnexpectedKind);
        }
        let d = LumpedRepr::<DelaySlot>::parse_verified(bytes).map_err(|_| Reject::Malformed)?;
        if d.first_slot != 0 || d.slots.len() != self.cfg.slaves {
            return Err(Reject::Unsolicited);
        }
        let seq = d.common.seq;
        let start = self.start;
        let stamp = |at: Instant| stamp_since(start, at);
        if let Some((cs, at)) = self.closing
            && cs == seq
            && stamp(at) == d.master_time_ns
        {
            for (a, s) in self.acked.iter_mut().zip(&d.slots) {
                *a |= s.marker == DelayMarker::Written;
            }
            if self.state == CalibrationState::Closing && self.acked.iter().all(|a| *a) {
                self.state = CalibrationState::Done;
            }
            return Ok(());
        }
        let cycle = self.cfg.cycle.as_ns();
        let Some(p) = self
            .sent
            .iter_mut()
            .find(|p| p.seq == seq && stamp(p.at) == d.master_time_ns)
        else {
            return Err(Reject::Unsolicited);
        };
        if p.back.is_some() {
            return Err(Reject::Duplicate);
        }
        let rtt = rx_start
            .as_ns()
            .checked_sub(p.at.as_ns())
            .ok_or(Reject::Overflow)?;
        if rtt <= 0 {
            return Err(Reject::Stale);
        }
        if rtt >= cycle {
            self.late += 1;
            return Err(Reject::Stale);
        }
        p.back = Some(Duration::from_ns(rtt));
        for (i, s) in d.slots.iter().enumerate() {
            if s.marker != DelayMarker::Residence {
                continue;
            }
            let r = i64::from(s.residence_ns);
            let known = self.sent.iter().any(|p| p.seq == s.residence_of);
            let again = self.residences[i].iter().any(|(q, _)| *q == s.residence_of);
            if !known || again || r >= cycle {
                self.rejected.count(Reject::Unsolicited);
                continue;
            }
            self.residences[i].push((s.residence_of, r));
        }
        Ok(())
    }

    /// The figures from the probes (see the module docs).
    /// The figures, and each slave's links alone (i·L).
    fn figures(&self) -> Result<(DelayMeasurement, Vec<Duration>), CalibrationError> {
        let n = self.cfg.slaves;
        let mut links = Vec::new();
        for p in &self.sent {
            let Some(rtt) = p.back else { continue };
            let res: Option<i64> = self
                .residences
                .iter()
                .map(|r| r.iter().find(|(q, _)| *q == p.seq).map(|(_, ns)| *ns))
                .sum();
            if let Some(sum) = res {
                links.push((rtt.as_ns() - sum) as f64 / (n + 1) as f64);
            }
        }
        let back = self.sent.iter().filter(|p| p.back.is_some()).count() as u32;
        if links.is_empty() {
            let silent = if back > 0 {
                (1..=n)
                    .filter(|i| self.residences[i - 1].is_empty())
                    .collect()
            } else {
                Vec::new()
            };
            return Err(CalibrationError::NoCompleteProbe {
                sent: self.sent.len() as u32,
                back,
                late: self.late,
                silent,
            });
        }
        let link = median(&mut links);
        let residence: Vec<f64> = self
            .residences
            .iter()
            .map(|r| median(&mut r.iter().map(|(_, ns)| *ns as f64).collect::<Vec<_>>()))
            .collect();
        let mut path = Vec::with_capacity(n);
        // i·L: the path a slave's clock takes behind transparent relays.
        let links_only = (1..=n)
            .map(|i| Duration::from_ns((i as f64 * link).round() as i64))
            .collect();
        let mut before = 0.0;
        for (i, r) in residence.iter().enumerate() {
            let d = Duration::from_ns(((i + 1) as f64 * link + before).round() as i64);
            if d >= self.cfg.cycle || d.as_ns() <= 0 {
                return Err(CalibrationError::Implausible {
                    slave: i + 1,
                    path: d,
                });
            }
            path.push(d);
            before += r;
        }
        let round_trips: Vec<Duration> = self.sent.iter().filter_map(|p| p.back).collect();
        let m = DelayMeasurement {
            probes: self.sent.len() as u32,
            probes_back: round_trips.len() as u32,
            complete: links.len() as u32,
            round_trips,
            link: Duration::from_ns(link.round() as i64),
            residence: residence
                .iter()
                .map(|r| Duration::from_ns(r.round() as i64))
                .collect(),
            path,
            closing_sent: self.closing_sent,
        };
        Ok((m, links_only))
    }

    /// The next frame to send, as bytes.
    pub fn poll_transmit(&mut self) -> Option<Transmit> {
        self.out.pop_bytes().map(|(t, _)| t)
    }

    /// The next frame to send, first bit out at the returned local time: as bytes, or
    /// decoded with `decoded`.
    pub fn poll_frame(&mut self, decoded: bool) -> Option<(Instant, WireFrame)> {
        if decoded {
            return self.out.pop_pdu().map(|t| (t.at, WireFrame::Pdu(t.pdu)));
        }
        self.poll_transmit()
            .map(|t| (t.at, WireFrame::Bytes(t.bytes)))
    }

    /// Hands back the buffer of a frame the driver is done with.
    pub fn recycle(&mut self, buf: Vec<u8>) {
        self.out.recycle(buf);
    }
}

/// The send stamp of a frame sent at `at` in a phase begun at `start` [ns since `start`].
fn stamp_since(start: Instant, at: Instant) -> u64 {
    u64::try_from(at.as_ns().saturating_sub(start.as_ns())).unwrap_or(0)
}

/// The median of `v` (the mean of the middle two for an even count); 0 for none.
fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        (v[m - 1] + v[m]) / 2.0
    }
}

impl CalibrationState {
    /// "probing", "closing", "done" or "failed".
    pub fn name(&self) -> &'static str {
        match self {
            CalibrationState::Probing => "probing",
            CalibrationState::Closing => "closing",
            CalibrationState::Done => "done",
            CalibrationState::Failed(_) => "failed",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::{FrameOutcome, Slave, SlaveConfig, SlaveEvent};

    const CYCLE: Duration = Duration::from_us(1_000);

    /// A ring in memory: every link takes `link` ns, slave i holds a frame `hold[i]` ns,
    /// slave i's clock reads true time + `offset[i]`. Returns the calibrator and slaves when
    /// the phase ends (or after `max_cycles`). `lose` drops the frame with this sequence
    /// number after slave `lose.1` (1-based).
    struct Ring {
        link: i64,
        hold: Vec<i64>,
        offset: Vec<i64>,
        lose: Option<(u16, usize)>,
        /// A slave (1-based) that forwards nothing.
        dead: Option<usize>,
        /// The master sends each slave its links alone (transparent relays).
        transparent: bool,
    }

    impl Ring {
        fn new(n: usize, link: i64, hold: i64) -> Self {
            Ring {
                link,
                hold: vec![hold; n],
                offset: (0..n).map(|i| 1_000_003 * (i as i64 + 1)).collect(),
                lose: None,
                dead: None,
                transparent: false,
            }
        }

        fn run(&self, probes: u32) -> (Calibrator, Vec<Slave>) {
            let n = self.hold.len();
            let mut cfg = CalibrationConfig::new(n, CYCLE, probes);
            cfg.transparent = self.transparent;
            let mut cal = Calibrator::new(cfg, Instant::ZERO);
            let mut slaves: Vec<Slave> = (1..=n)
                .map(|a| Slave::calibrating(SlaveConfig::new(a as u16, CYCLE, Duration::ZERO)))
                .collect();
            for _ in 0..(probes + 20) {
                let Some(t) = cal.poll_timeout() else { break };
                cal.handle_timeout(t);
                while let Some(tx) = cal.poll_transmit() {
                    let mut bytes = tx.bytes;
                    let seq = Frame::new_checked(&bytes[..]).expect("frame").seq();
                    let mut first = tx.at.as_ns();
                    let mut back = true;
                    for (i, s) in slaves.iter_mut().enumerate() {
                        first += self.link;
                        let local = Instant::from_ns(first + self.offset[i]);
                        let out = s.handle_frame(local, local, &mut bytes);
                        assert_eq!(out, FrameOutcome::Forward);
                        first += self.hold[i];
                        s.handle_forwarded(Instant::from_ns(first + self.offset[i]));
                        if self.lose == Some((seq, i + 1)) || self.dead == Some(i + 1) {
                            back = false;
                            break;
                        }
                    }
                    if back {
                        cal.handle_frame(Instant::from_ns(first + self.link), &bytes);
                    }
                }
            }
            (cal, slaves)
        }
    }

    #[test]
    fn the_nodes_measure_every_path_delay_and_each_slave_takes_its_own() {
        // The reference ring's figures: L = 1.26 µs, T_t = 1 µs; then uneven residences.
        for (n, link, hold) in [(4, 1_260, 1_000), (16, 700, 320), (1, 500, 0)] {
            let mut ring = Ring::new(n, link, hold);
            if n == 4 {
                ring.hold = vec![900, 1_100, 1_700, 300];
            }
            let (cal, slaves) = ring.run(16);
            assert_eq!(cal.state(), &CalibrationState::Done, "n = {n}");
            let m = cal.measurement().expect("figures");
            assert_eq!(m.link.as_ns(), link);
            assert_eq!(m.complete, 15, "the last probe's residences never come");
            let mut d = 0;
            for (i, s) in slaves.iter().enumerate() {
                d += link;
                assert_eq!(m.residence[i].as_ns(), ring.hold[i]);
                assert_eq!(m.path[i].as_ns(), d, "slave {}", i + 1);
                assert_eq!(s.path_delay(), Some(m.path[i]));
                assert_eq!(cal.clock_path()[i], m.path[i]);
                d += ring.hold[i];
            }
        }
    }

    /// Behind transparent relays (each adds its residence to the stamp) a slave is sent its
    /// links alone; the figures, residences included, are the same.
    #[test]
    fn behind_transparent_relays_each_slave_takes_its_links_alone() {
        let mut ring = Ring::new(4, 1_260, 1_000);
        ring.hold = vec![900, 1_100, 1_700, 300];
        ring.transparent = true;
        let (cal, slaves) = ring.run(16);
        assert_eq!(cal.state(), &CalibrationState::Done);
        let m = cal.measurement().expect("figures");
        assert_eq!(m.path[3].as_ns(), 4 * 1_260 + 900 + 1_100 + 1_700);
        for (i, s) in slaves.iter().enumerate() {
            let links = Duration::from_ns(1_260 * (i as i64 + 1));
            assert_eq!(cal.clock_path()[i], links, "slave {}", i + 1);
            assert_eq!(s.path_delay(), Some(links), "slave {}", i + 1);
        }
    }

    #[test]
    fn a_lost_probe_or_acknowledgement_costs_a_retry_not_the_figures() {
        let mut ring = Ring::new(4, 1_000, 1_000);
        // Probe 3 lost after slave 2; the first closing frame (seq 16) lost after slave 3:
        // slaves 1-3 took their delay, slave 4 never saw it; the second closing frame is
        // acknowledged by all (1-3 again, as running slaves).
        ring.lose = Some((3, 2));
        let (cal, _) = ring.run(16);
        let m = cal.measurement().expect("figures");
        assert_eq!((m.probes, m.probes_back), (16, 15));
        assert_eq!(m.path[3].as_ns(), 7_000);
        let mut ring = Ring::new(4, 1_000, 1_000);
        ring.lose = Some((16, 3));
        let (cal, slaves) = ring.run(16);
        assert_eq!(cal.state(), &CalibrationState::Done);
        assert!(slaves.iter().all(|s| s.path_delay().is_some()));
        assert_eq!(cal.measurement().map(|m| m.closing_sent), Some(2));
    }

    fn failure(ring: &Ring, probes: u32) -> CalibrationError {
        let (cal, slaves) = ring.run(probes);
        assert!(slaves.iter().all(|s| s.path_delay().is_none()));
        match cal.state() {
            CalibrationState::Failed(e) => e.clone(),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_ring_that_does_not_forward_fails_naming_why() {
        let mut ring = Ring::new(3, 1_000, 1_000);
        ring.dead = Some(2);
        let e = failure(&ring, 8);
        assert_eq!(
            e,
            CalibrationError::NoCompleteProbe {
                sent: 8,
                back: 0,
                late: 0,
                silent: vec![]
            }
        );
        assert!(
            e.to_string()
                .starts_with("none of 8 delay probes came back"),
            "{e}"
        );
        // Probe 0 lost; probe 1 came back with the residences of probe 0, whose round
        // trip is unknown, and probe 1's residences never come: no complete probe.
        let mut ring = Ring::new(3, 1_000, 1_000);
        ring.lose = Some((0, 3));
        let e = failure(&ring, 2);
        assert!(e.to_string().contains("(1 of 2 probes back;"), "{e}");
    }

    fn closing(path: &[u32]) -> Vec<u8> {
        let pdu = Pdu::Delay(LumpedRepr {
            common: Common::default(),
            master_time_ns: 0,
            first_slot: 0,
            slots: path
                .iter()
                .map(|p| DelaySlot {
                    path_delay_ns: *p,
                    ..DelaySlot::default()
                })
                .collect(),
        });
        let mut b = Vec::new();
        pdu.emit_into(&mut b).expect("emit");
        b
    }

    #[test]
    fn a_slave_takes_a_path_delay_once_and_only_a_plausible_one() {
        let mut s = Slave::calibrating(SlaveConfig::new(1, CYCLE, Duration::from_us(5)));
        assert_eq!(s.path_delay(), None);
        let t = Instant::from_ns(10);
        // Longer than the cycle: refused, still calibrating.
        let _ = s.handle_frame(t, t, &mut closing(&[1_000_000]));
        assert_eq!(s.path_delay(), None);
        assert_eq!(s.counters().rejected.get(Reject::Overflow), 1);
        let mut b = closing(&[2_520]);
        assert_eq!(s.handle_frame(t, t, &mut b), FrameOutcome::Forward);
        assert_eq!(s.path_delay(), Some(Duration::from_ns(2_520)));
        assert_eq!(
            s.poll_event(),
            Some(SlaveEvent::Calibrated {
                path_delay: Duration::from_ns(2_520)
            })
        );
        let d = LumpedRepr::<DelaySlot>::parse(&b).expect("parse");
        assert_eq!(d.slots[0].marker, DelayMarker::Written);
        // Running: another delay is refused and changes nothing; the same one is
        // acknowledged again.
        let _ = s.handle_frame(t, t, &mut closing(&[9_999]));
        assert_eq!(s.path_delay(), Some(Duration::from_ns(2_520)));
        assert_eq!(s.counters().rejected.get(Reject::UnexpectedKind), 1);
        let mut b = closing(&[2_520]);
        let _ = s.handle_frame(t, t, &mut b);
        let d = LumpedRepr::<DelaySlot>::parse(&b).expect("parse");
        assert_eq!(d.slots[0].marker, DelayMarker::Written);
    }

    #[test]
    fn the_master_counts_only_echoes_of_its_own_probes() {
        let mut cal = Calibrator::new(CalibrationConfig::new(2, CYCLE, 4), Instant::ZERO);
        cal.handle_timeout(Instant::ZERO);
        let tx = cal.poll_transmit().expect("probe");
        // A forged probe (another send stamp), then the echo twice, then a frame of
        // another kind.
        let mut forged = tx.bytes.clone();
        let mut f = Frame::new_checked(&mut forged[..]).expect("frame");
        f.payload_mut()[0] ^= 1;
        f.fill_crc();
        cal.handle_frame(Instant::from_ns(5_000), &forged);
        cal.handle_frame(Instant::from_ns(5_000), &tx.bytes);
        cal.handle_frame(Instant::from_ns(5_100), &tx.bytes);
        let r = cal.rejected();
        assert_eq!(r.get(Reject::Unsolicited), 1);
        assert_eq!(r.get(Reject::Duplicate), 1);
        assert_eq!(r.total(), 2);
    }

    #[test]
    fn a_calibrating_slave_takes_no_sync_and_no_command() {
        use ringsync_wire::{CommandRepr, FeedbackSlot, LumpedFrameRepr};
        let mut s = Slave::calibrating(SlaveConfig::new(1, CYCLE, Duration::from_us(5)));
        let t = Instant::from_ns(10);
        let lumped = Pdu::Lumped(LumpedFrameRepr {
            common: Common::default(),
            master_time_ns: 0,
            first_slot: 0,
            slots: vec![FeedbackSlot::default()],
        });
        let cmd = Pdu::Command(CommandRepr {
            common: Common::default(),
            target: 1,
            command_v: 1.0,
            sample_time_ns: 0,
            link_ns: 0,
        });
        let mut b = Vec::new();
        lumped.emit_into(&mut b).expect("emit");
        let unchanged = b.clone();
        assert_eq!(s.handle_frame(t, t, &mut b), FrameOutcome::Forward);
        assert_eq!(b, unchanged);
        cmd.emit_into(&mut b).expect("emit");
        assert_eq!(s.handle_frame(t, t, &mut b), FrameOutcome::Dropped);
        assert_eq!(s.counters().rejected.get(Reject::UnexpectedKind), 2);
        assert_eq!((s.counters().syncs, s.counters().commands), (0, 0));
        assert_eq!(s.poll_event(), None);
    }

    #[test]
    fn a_slave_reports_the_residence_of_its_probe_not_of_a_frame_after_it() {
        let mut s = Slave::calibrating(SlaveConfig::new(1, CYCLE, Duration::ZERO));
        let mut cal = Calibrator::new(CalibrationConfig::new(1, CYCLE, 3), Instant::ZERO);
        let probe = |cal: &mut Calibrator, t: i64| {
            cal.handle_timeout(Instant::from_ns(t));
            cal.poll_transmit().expect("probe").bytes
        };
        let mut p0 = probe(&mut cal, 0);
        let dup = p0.clone();
        let t = Instant::from_ns(1_000);
        assert_eq!(s.handle_frame(t, t, &mut p0), FrameOutcome::Forward);
        s.handle_forwarded(Instant::from_ns(1_700));
        // The same probe again, forwarded much later: refused, and its send is not probe
        // 0's residence.
        let mut again = dup;
        let t2 = Instant::from_ns(500_000);
        let _ = s.handle_frame(t2, t2, &mut again);
        s.handle_forwarded(Instant::from_ns(900_000));
        let mut p1 = probe(&mut cal, 1_000_000);
        let t3 = Instant::from_ns(1_001_000);
        let _ = s.handle_frame(t3, t3, &mut p1);
        let d = LumpedRepr::<DelaySlot>::parse(&p1).expect("parse");
        assert_eq!(d.slots[0].marker, DelayMarker::Residence);
        assert_eq!((d.slots[0].residence_of, d.slots[0].residence_ns), (0, 700));
    }

    #[test]
    fn a_phase_before_time_0_stamps_each_frame_apart_and_names_a_slow_ring() {
        // A process ring's master starts before the cycles' time 0: the stamps still tell
        // its probes apart, so a forged echo with a guessed sequence number is refused.
        let start = Instant::from_ns(-5_000_000);
        let mut cal = Calibrator::new(CalibrationConfig::new(1, CYCLE, 2), start);
        cal.handle_timeout(start);
        let p0 = cal.poll_transmit().expect("probe 0").bytes;
        cal.handle_timeout(start + CYCLE);
        let p1 = cal.poll_transmit().expect("probe 1").bytes;
        let stamp = |b: &[u8]| {
            LumpedRepr::<DelaySlot>::parse(b)
                .expect("parse")
                .master_time_ns
        };
        assert_eq!((stamp(&p0), stamp(&p1)), (0, 1_000_000));
        let mut forged = LumpedRepr::<DelaySlot>::parse(&p1).expect("parse");
        forged.master_time_ns = 0;
        let mut b = Vec::new();
        Pdu::Delay(forged).emit_into(&mut b).expect("emit");
        cal.handle_frame(start + CYCLE + Duration::from_us(10), &b);
        assert_eq!(cal.rejected().get(Reject::Unsolicited), 1);
        // Both probes back a cycle late: the error says the round trip does not fit.
        cal.handle_frame(start + CYCLE + CYCLE, &p0);
        cal.handle_frame(start + CYCLE * 3, &p1);
        cal.handle_timeout(start + CYCLE * 2);
        let CalibrationState::Failed(e) = cal.state() else {
            panic!("{:?}", cal.state())
        };
        assert!(
            e.to_string().contains("round trip does not fit the cycle"),
            "{e}"
        );
    }
}
