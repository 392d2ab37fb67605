//! The simulator's links: every hop adds the PHY tx + cable + PHY rx time of the cycle plan
//! (L), a uniform random jitter in [0, jitter], and may lose or corrupt the frame; forwarding
//! slaves are cut-through (first bit out T_t after first bit in). A frame that slaves only
//! forward costs no event per hop: its arrival at the node that processes it next is
//! computed at once, every hop's draws included.
//!
//! `loss` and `corruption` are probabilities per full trip round the ring (n + 1 hops): a
//! hop loses a frame with 1 − (1 − loss)^(1/(n+1)), or flips one of its bits (its CRC then
//! fails where it is checked) likewise.
//!
//! When capturing (`--pcap`), every hop is recorded as the runtime records it: the sender's
//! transmission and each forwarding slave's, at its first bit out (T_t after its first bit
//! in, the jitter of the hops before included), with the bytes it relays. With jitter the
//! draws say on which hop a frame was lost or corrupted; without, one draw covers the whole
//! path and the capture puts the loss or the flipped bit on the first hop. A frame lost after
//! it was corrupted is relayed unchanged up to the loss (the simulator flips a bit only in a
//! frame that arrives). Recording changes no draw and no delivery.
//!
//! Frames travel as bytes or decoded ([`WireFrame`]); the draws and deliveries are the
//! same. A decoded frame that a hop corrupts becomes bytes (the flipped bit is in them),
//! and a captured one is emitted for the record.

use ringsync_model::Spec;
use ringsync_model::result::{Captured, LinkCounters};
use ringsync_model::rng::Rng;
use ringsync_model::scenario::LinkBreak;
use ringsync_proto::node::{Port, WireFrame};
use ringsync_wire::{Frame, Pdu, Route};

/// The bytes of `frame`: its own, or (decoded) `record`, its emitted bytes (empty without).
fn bytes_of<'a>(frame: &'a WireFrame, record: &'a Option<Vec<u8>>) -> &'a [u8] {
    match (frame, record) {
        (WireFrame::Bytes(b), _) => b,
        (WireFrame::Pdu(_), Some(r)) => r,
        (WireFrame::Pdu(_), None) => &[],
    }
}

/// A frame's cycle counter and where it goes (`None` for bytes that are no frame).
pub(crate) fn cycle_route(frame: &WireFrame) -> Option<(u32, Option<Route>)> {
    match frame {
        WireFrame::Bytes(b) => Frame::new_checked(&b[..])
            .ok()
            .map(|f| (f.cycle(), f.route().ok())),
        WireFrame::Pdu(p) => Some((p.common().cycle, Some(p.route()))),
    }
}

/// The slots a lumped frame of either plan carries: (first slot, count).
fn slots_of(route: Option<Route>) -> Option<(usize, usize)> {
    match route {
        Some(
            Route::Lumped {
                first_slot,
                slot_count,
            }
            | Route::LumpedOnly {
                first_slot,
                slot_count,
            }
            | Route::Delay {
                first_slot,
                slot_count,
            },
        ) => Some((usize::from(first_slot), usize::from(slot_count))),
        _ => None,
    }
}

#[cfg(test)]
thread_local! {
    /// Tests: links built on this thread take the general path for every frame.
    pub(crate) static GENERAL_PATH_ONLY: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Whether the links must take the general path (tests comparing it with the plain one).
fn general_path_only() -> bool {
    #[cfg(test)]
    return GENERAL_PATH_ONLY.with(std::cell::Cell::get);
    #[cfg(not(test))]
    false
}

/// What became of a frame sent.
pub(crate) enum Delivery {
    /// Its last bit reaches `node` (0 = the master, on `port`) at true time `at` [ns], its
    /// first at `rx_start`.
    Arrive {
        node: usize,
        port: Port,
        rx_start: i64,
        at: i64,
        frame: WireFrame,
    },
    /// A hop lost it: the buffer goes back to the sender.
    Lost(WireFrame),
    /// It went nowhere (not a frame, or a dead slave on its way).
    Gone,
}

/// The ring's links (see the module docs).
pub(crate) struct Link {
    n: usize,
    hop: i64,
    residence: i64,
    jitter: i64,
    /// Wire time of a lumped, command, response, lumped-only and delay frame [ns].
    frame_ns: [i64; 5],
    hop_loss: f64,
    hop_corruption: f64,
    /// Loss and corruption probabilities over h hops (index h, 0 ..= n + 1).
    over_hops: Vec<(f64, f64)>,
    /// One random stream per sending node.
    rng: Vec<Rng>,
    /// The slave (1-based) that goes silent, and from when [ns].
    silent: Option<(usize, i64)>,
    /// Links that break (and heal).
    breaks: Vec<LinkBreak>,
    /// Link counters (loss, corruption; the driver counts events).
    pub counters: LinkCounters,
    /// Frames sent before `end`, when capturing.
    pub captured: Option<Vec<Captured>>,
    end: i64,
    /// Nothing captured, no jitter, loss, corruption, silent slave or broken link: every
    /// frame takes its closed-form path without a draw.
    plain: bool,
}

impl Link {
    /// The links of `spec`'s ring over a run ending at true time `end` [ns].
    pub fn new(spec: &Spec, end: i64, capture: bool) -> Self {
        let s = &spec.scenario;
        let plan = &spec.plan;
        let n = spec.axes();
        let per_hop = |p: f64| 1.0 - (1.0 - p).powf(1.0 / (n + 1) as f64);
        let (hop_loss, hop_corruption) = (per_hop(s.faults.loss), per_hop(s.faults.corruption));
        let over = |p: f64, h: usize| 1.0 - (1.0 - p).powi(h as i32);
        let mut link = Link {
            n,
            hop: plan.hop.as_ns(),
            residence: s.ring.residence.0.as_ns(),
            jitter: s.ring.jitter.0.as_ns(),
            frame_ns: [
                plan.lumped.frame_time[0].as_ns(),
                plan.t_cmf.as_ns(),
                plan.t_rmf.as_ns(),
                plan.lumped_only.lumped.frame_time[0].as_ns(),
                plan.link
                    .frame_time(ringsync_wire::lumped::lumped_pdu_len(
                        n,
                        <ringsync_wire::DelaySlot as ringsync_wire::SlotCodec>::LEN,
                    ))
                    .as_ns(),
            ],
            hop_loss,
            hop_corruption,
            over_hops: (0..=n + 1)
                .map(|h| (over(hop_loss, h), over(hop_corruption, h)))
                .collect(),
            rng: (0..=n).map(|h| Rng::stream(s.seed, h as u64)).collect(),
            silent: (s.faults.silent_slave != 0).then(|| {
                (
                    s.faults.silent_slave as usize,
                    s.faults.silent_from.0.as_ns(),
                )
            }),
            breaks: s.faults.break_link.clone(),
            counters: LinkCounters::default(),
            captured: capture.then(Vec::new),
            end,
            plain: false,
        };
        link.plain = !capture
            && !general_path_only()
            && link.jitter == 0
            && link.hop_loss == 0.0
            && link.hop_corruption == 0.0
            && link.silent.is_none()
            && link.breaks.is_empty();
        link
    }

    /// Wire time of a frame going `route` [ns].
    fn wire_ns(&self, route: Option<Route>) -> i64 {
        self.frame_ns[match route {
            Some(Route::Lumped { .. }) => 0,
            Some(Route::Command { .. }) => 1,
            Some(Route::LumpedOnly { .. }) => 3,
            Some(Route::Delay { .. }) => 4,
            _ => 2,
        }]
    }

    /// Slave residence time T_t: first bit in to first bit out [ns].
    pub fn residence(&self) -> i64 {
        self.residence
    }

    /// Whether `node` (1-based slave) has gone silent by true time `t` [ns]: it neither
    /// forwards nor answers.
    pub fn is_silent(&self, node: usize, t: i64) -> bool {
        self.silent.is_some_and(|(s, from)| node == s && t >= from)
    }

    /// Whether link `link` (1..=n+1) is broken at true time `t` [ns].
    fn is_broken(&self, link: usize, t: i64) -> bool {
        self.breaks
            .iter()
            .any(|b| b.link as usize == link && b.broken_at(t))
    }

    /// The changes of the master's own links (see [`LinkBreak::port_changes`]).
    pub fn port_changes(&self) -> Vec<(i64, Port, bool)> {
        LinkBreak::port_changes(&self.breaks, self.n)
    }

    /// The path of a frame sent at `t` on a ring with broken links (docs/planner.md, "A
    /// broken link"), walked node by node: positions 0..=n+1, 0 and n+1 the master's ports
    /// A and B, link k joining k−1 and k. A frame moves forward from a slave or port A,
    /// backward from port B; a node whose next link is broken turns it back; a slave takes
    /// only frames moving forward. Returns (the node that takes it, its hops, the relays
    /// on the way, the master's port it reaches), or `None` when it cannot go on (a dead
    /// port, a slave cut off, a silent relay).
    fn walk(
        &self,
        from: usize,
        route: Option<Route>,
        t: i64,
    ) -> Option<(usize, i64, Vec<usize>, Port)> {
        let ring = self.n + 1;
        let takes = |pos: usize| match (route, slots_of(route)) {
            (Some(Route::Command { target }), _) => {
                (from == 0 || from == ring) && usize::from(target) == pos
            }
            (_, Some((f, c))) => pos > f && pos <= f + c,
            _ => false,
        };
        let (mut pos, mut dir): (usize, i64) = if from == ring { (ring, -1) } else { (from, 1) };
        let next_link = |pos: usize, dir: i64| if dir > 0 { pos + 1 } else { pos };
        let mut relays = Vec::new();
        let mut hops = 0i64;
        // The sender: a master's dead port loses the frame; a slave turns it back.
        if self.is_broken(next_link(pos, dir), t) {
            if from == 0 || from == ring || self.is_broken(next_link(pos, -dir), t) {
                return None;
            }
            dir = -dir;
        }
        loop {
            pos = if dir > 0 { pos + 1 } else { pos - 1 };
            hops += 1;
            if pos == 0 || pos == ring {
                return Some((0, hops, relays, if pos == 0 { Port::A } else { Port::B }));
            }
            if dir > 0 && takes(pos) {
                return Some((pos, hops, relays, Port::B));
            }
            if self.is_broken(next_link(pos, dir), t) {
                if self.is_broken(next_link(pos, -dir), t) {
                    return None;
                }
                dir = -dir;
                if dir > 0 && takes(pos) {
                    return Some((pos, hops, relays, Port::B));
                }
            }
            let at = t + hops * (self.hop + self.residence);
            if self.is_silent(pos, at) || hops > 2 * ring as i64 {
                return None;
            }
            relays.push(pos);
        }
    }

    /// On an unbroken ring, the node (0 = master) that processes a frame going `route` from
    /// node `from` next, and the hops to it (at least 1).
    fn next_stop(&self, from: usize, route: Option<Route>) -> (usize, i64) {
        let target = match route {
            Some(Route::Command { target }) => Some(usize::from(target)),
            _ => None,
        };
        self.stop_of(from, target, slots_of(route))
    }

    /// [`Link::next_stop`] of a frame that is a command to `target` or carries `slots`
    /// (first, count), or neither.
    #[inline]
    fn stop_of(
        &self,
        from: usize,
        target: Option<usize>,
        slots: Option<(usize, usize)>,
    ) -> (usize, i64) {
        let ring = self.n + 1;
        // (No `%`: every value reduced here is below 3·ring, and a division by the ring's
        // length is the slowest step of a frame's hop.)
        let wrap = |x: usize| if x >= ring { x - ring } else { x };
        let stop = match (target, slots) {
            (Some(target), _) if from == 0 => target.min(self.n),
            (_, Some((first, count))) => {
                // Slots f..f+m belong to slaves f+1..=f+m.
                let next = from + 1;
                if next <= first {
                    wrap((first + 1).min(ring))
                } else if next <= first + count && next <= self.n {
                    next
                } else {
                    0
                }
            }
            _ => 0,
        };
        let stop = if stop == 0 && from == 0 { ring } else { stop };
        // from ≤ ring (the master's port B), stop ≤ ring.
        let hops = wrap(wrap(stop + ring - from)).max(1) as i64;
        (wrap(stop), hops)
    }

    /// Where and when a frame sent as [`Link::send`] takes it arrives, on a plain ring
    /// (nothing to capture, draw, break or silence: the closed-form time): `Some(Some((node,
    /// rx_start, at)))` as [`Delivery::Arrive`] on port B, `Some(None)` if it goes nowhere;
    /// `None` when the ring is not plain (then [`Link::send`] decides). The frame stays
    /// where it is: the driver moves it once, into its event.
    #[inline]
    pub fn plain_path(
        &self,
        from: usize,
        t_tx: i64,
        frame: &WireFrame,
    ) -> Option<Option<(usize, i64, i64)>> {
        if !self.plain || from > self.n {
            return None;
        }
        // A decoded frame's way straight from its PDU, as `next_stop` and `wire_ns` read it
        // from its route (without building the route).
        let count = |n: usize| n.min(usize::from(u16::MAX));
        let (stop, hops, wire) = match frame {
            WireFrame::Pdu(Pdu::Lumped(r)) => {
                let (stop, hops) = self.stop_of(
                    from,
                    None,
                    Some((usize::from(r.first_slot), count(r.slots.len()))),
                );
                (stop, hops, self.frame_ns[0])
            }
            WireFrame::Pdu(Pdu::Command(r)) => {
                let (stop, hops) = self.stop_of(from, Some(usize::from(r.target)), None);
                (stop, hops, self.frame_ns[1])
            }
            WireFrame::Pdu(Pdu::Response(_)) => {
                let (stop, hops) = self.stop_of(from, None, None);
                (stop, hops, self.frame_ns[2])
            }
            WireFrame::Pdu(p) => {
                let route = Some(p.route());
                let (stop, hops) = self.next_stop(from, route);
                (stop, hops, self.wire_ns(route))
            }
            WireFrame::Bytes(_) => {
                let Some((_, route)) = cycle_route(frame) else {
                    return Some(None);
                };
                let (stop, hops) = self.next_stop(from, route);
                (stop, hops, self.wire_ns(route))
            }
        };
        let rx = t_tx + hops * self.hop + (hops - 1) * self.residence;
        Some(Some((stop, rx, rx + wire)))
    }

    /// Sends `frame` from node `from` (0 = master, n + 1 = the master's port B), first bit
    /// out at true `t_tx` [ns], along the ring to the first node that processes it: a
    /// command's target, each slave whose slot a lumped frame carries, and the master for
    /// everything that comes back round.
    pub fn send(&mut self, from: usize, t_tx: i64, mut frame: WireFrame) -> Delivery {
        if let Some(path) = self.plain_path(from, t_tx, &frame) {
            return match path {
                Some((node, rx_start, at)) => Delivery::Arrive {
                    node,
                    port: Port::B,
                    rx_start,
                    at,
                    frame,
                },
                None => Delivery::Gone,
            };
        }
        let capturing = self.captured.is_some();
        // A decoded frame's bytes, emitted once for the capture.
        let record = match &frame {
            WireFrame::Pdu(_) if capturing => Some(frame.clone().into_bytes()),
            _ => None,
        };
        if let Some(c) = &mut self.captured
            && t_tx < self.end
        {
            c.push(Captured {
                t: t_tx,
                node: from % (self.n + 1),
                bytes: bytes_of(&frame, &record).to_vec(),
            });
        }
        let Some((_, route)) = cycle_route(&frame) else {
            return Delivery::Gone;
        };
        let ring = self.n + 1;
        if from == ring || self.breaks.iter().any(|b| b.broken_at(t_tx)) {
            return self.send_broken(from, t_tx, route, frame, record);
        }
        let dur = self.wire_ns(route);
        let (stop, hops) = self.next_stop(from, route);
        // The slaves between sender and receiver relay the frame; a dead one forwards nothing
        // (the frame is gone unless a hop before loses it).
        let mut relays = hops - 1;
        let mut gone = false;
        if let Some((silent, _)) = self.silent
            && silent != stop
        {
            let d = (silent + ring - from) % ring;
            if d > 0 && (d as i64) < hops {
                let at = t_tx + d as i64 * self.hop + (d as i64 - 1) * self.residence;
                if self.is_silent(silent, at) {
                    relays = d as i64 - 1;
                    gone = true;
                }
            }
        }
        let rng = &mut self.rng[from];
        let mut rx = t_tx + hops * self.hop + (hops - 1) * self.residence;
        // For the capture: the jitter of hops 1..=d at index d - 1.
        let mut jitter_sums = Vec::new();
        // The first hop (1-based) that corrupted the frame.
        let mut corrupted_on = None;
        if self.jitter > 0 {
            // Per hop: jitter, loss and corruption draws hop by hop.
            for h in 1..=hops {
                let j = (rng.unit() * (self.jitter + 1) as f64) as i64;
                rx += j;
                if capturing {
                    jitter_sums.push(jitter_sums.last().copied().unwrap_or(0) + j);
                }
                if rng.chance(self.hop_loss) {
                    self.counters.lost += 1;
                    // Lost on hop h: the slaves before it relayed the frame.
                    let count = relays.min(h - 1);
                    let sent = bytes_of(&frame, &record);
                    self.capture_relays(from, t_tx, count, &jitter_sums, sent, None);
                    return Delivery::Lost(frame);
                }
                if rng.chance(self.hop_corruption) {
                    corrupted_on.get_or_insert(h);
                }
            }
        } else {
            // No jitter: one draw each with the probability over all hops (same distribution).
            let (loss, corruption) = self.over_hops[hops as usize];
            if rng.chance(loss) {
                self.counters.lost += 1;
                return Delivery::Lost(frame);
            }
            if rng.chance(corruption) {
                corrupted_on = Some(1);
            }
        }
        // The bytes as sent, when a hop corrupts them and the hops before relay them.
        let mut as_sent = None;
        if corrupted_on.is_some() {
            // The flipped bit is in the bytes: a decoded frame travels on as bytes.
            let mut bytes = match frame {
                WireFrame::Bytes(b) => b,
                pdu => pdu.into_bytes(),
            };
            if capturing {
                as_sent = Some(bytes.clone());
            }
            let bit = (rng.next_u64() % (bytes.len() as u64 * 8)) as usize;
            bytes[bit / 8] ^= 1 << (bit % 8);
            self.counters.corrupted += 1;
            frame = WireFrame::Bytes(bytes);
        }
        if capturing {
            let now = bytes_of(&frame, &record);
            let (first, corrupted) = match (&as_sent, corrupted_on) {
                (Some(sent), Some(h)) => (&sent[..], Some((h, now))),
                _ => (now, None),
            };
            self.capture_relays(from, t_tx, relays, &jitter_sums, first, corrupted);
        }
        if gone {
            return Delivery::Gone;
        }
        Delivery::Arrive {
            node: stop,
            port: Port::B,
            rx_start: rx,
            at: rx + dur,
            frame,
        }
    }

    /// [`Link::send`] on a ring with a broken link: the path walked node by node
    /// ([`Link::walk`]), with the same draws per hop.
    fn send_broken(
        &mut self,
        from: usize,
        t_tx: i64,
        route: Option<Route>,
        mut frame: WireFrame,
        record: Option<Vec<u8>>,
    ) -> Delivery {
        let capturing = self.captured.is_some();
        let dur = self.wire_ns(route);
        let walked = self.walk(from, route, t_tx);
        let gone = walked.is_none();
        let (stop, hops, relays, port) = walked.unwrap_or((0, 0, Vec::new(), Port::A));
        let rng_ix = from % (self.n + 1);
        let rng = &mut self.rng[rng_ix];
        let mut rx = t_tx + hops * self.hop + (hops - 1).max(0) * self.residence;
        let mut jitter_sums = Vec::new();
        let mut corrupted = false;
        for _ in 1..=hops {
            if self.jitter > 0 {
                let j = (rng.unit() * (self.jitter + 1) as f64) as i64;
                rx += j;
                jitter_sums.push(jitter_sums.last().copied().unwrap_or(0) + j);
            }
            if rng.chance(self.hop_loss) {
                self.counters.lost += 1;
                return Delivery::Lost(frame);
            }
            if rng.chance(self.hop_corruption) {
                corrupted = true;
            }
        }
        if capturing {
            let sent = bytes_of(&frame, &record).to_vec();
            let (hop, residence, end) = (self.hop, self.residence, self.end);
            if let Some(c) = &mut self.captured {
                for (d, &node) in relays.iter().enumerate() {
                    let d = d as i64 + 1;
                    let t = t_tx
                        + d * (hop + residence)
                        + jitter_sums.get(d as usize - 1).copied().unwrap_or(0);
                    if t < end {
                        c.push(Captured {
                            t,
                            node,
                            bytes: sent.clone(),
                        });
                    }
                }
            }
        }
        if gone {
            return Delivery::Gone;
        }
        if corrupted {
            let mut bytes = match frame {
                WireFrame::Bytes(b) => b,
                pdu => pdu.into_bytes(),
            };
            let bit = (rng.next_u64() % (bytes.len() as u64 * 8)) as usize;
            bytes[bit / 8] ^= 1 << (bit % 8);
            self.counters.corrupted += 1;
            frame = WireFrame::Bytes(bytes);
        }
        Delivery::Arrive {
            node: stop,
            port,
            rx_start: rx,
            at: rx + dur,
            frame,
        }
    }

    /// Records the first `count` relays of a frame that node `from` sent at `t_tx`: the slave
    /// d hops on forwards it with its first bit out at t_tx + d·(L + T_t) plus the jitter of
    /// hops 1..=d (`jitter_sums`, empty without jitter); from hop h of `corrupted` = (h,
    /// relayed) on, the slaves relay `relayed` in place of `bytes`.
    fn capture_relays(
        &mut self,
        from: usize,
        t_tx: i64,
        count: i64,
        jitter_sums: &[i64],
        bytes: &[u8],
        corrupted: Option<(i64, &[u8])>,
    ) {
        let (ring, hop, residence, end) = (self.n + 1, self.hop, self.residence, self.end);
        let Some(c) = &mut self.captured else {
            return;
        };
        for d in 1..=count {
            let jitter = jitter_sums.get(d as usize - 1).copied().unwrap_or(0);
            let t = t_tx + d * (hop + residence) + jitter;
            if t >= end {
                break;
            }
            let relayed = match corrupted {
                Some((h, relayed)) if d >= h => relayed,
                _ => bytes,
            };
            c.push(Captured {
                t,
                node: (from + d as usize) % ring,
                bytes: relayed.to_vec(),
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `next_stop` (no division) against the same rule written with `%`, for every sender
    /// (the master's port B too) and every route on rings of 2 to 9 slaves.
    #[test]
    fn next_stop_is_the_modular_rule() {
        let reference = |n: usize, from: usize, route: Option<Route>| {
            let ring = n + 1;
            let stop = match (route, slots_of(route)) {
                (Some(Route::Command { target }), _) if from == 0 => usize::from(target).min(n),
                (_, Some((first, count))) => {
                    let next = from + 1;
                    if next <= first {
                        (first + 1).min(ring) % ring
                    } else if next <= first + count && next <= n {
                        next
                    } else {
                        0
                    }
                }
                _ => 0,
            };
            let stop = if stop == 0 && from == 0 { ring } else { stop };
            let hops = ((stop + ring - from) % ring).max(1) as i64;
            (stop % ring, hops)
        };
        for n in 2..=9u16 {
            let mut s = ringsync_model::Scenario::default();
            s.ring.slaves = u32::from(n);
            let spec = s.build().expect("a valid ring");
            let link = Link::new(&spec, 1_000_000, false);
            let mut routes = vec![None];
            for a in 0..=n + 2 {
                routes.push(Some(Route::Command { target: a }));
                routes.push(Some(Route::Response { source: a }));
                for m in 0..=n + 2 {
                    routes.push(Some(Route::Lumped {
                        first_slot: a,
                        slot_count: m,
                    }));
                    routes.push(Some(Route::Delay {
                        first_slot: a,
                        slot_count: m,
                    }));
                }
            }
            let n = usize::from(n);
            for from in 0..=n + 1 {
                for &r in &routes {
                    assert_eq!(
                        link.next_stop(from, r),
                        reference(n, from, r),
                        "n = {n}, from {from}, {r:?}"
                    );
                }
            }
        }
    }
}
