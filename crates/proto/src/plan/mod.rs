//! The cycle plan (docs/system.md, "The cycle plan", paper Fig. 1, eq. 1-2): where the time of one cycle
//! goes, by the paper's formula and by the event-level ring path side by side.
//!
//! Eq. 1 and 2:
//!
//! ```text
//! T_cyc     = T_syn + (⌊n/4⌋ + 1)·T_slot(n) + Σ_{i=1..n} T_slot(i) + T_idle
//! T_syn     = T_lmf + D_ms(n) + D_snm + T_rest
//! T_slot(i) = T_cmf + 2·D_ci + T_ti
//! ```
//!
//! With L the first-bit latency of a hop (PHY tx + cable + PHY rx) and T_t the residence of a
//! forwarding slave (cut-through, first bit in to first bit out):
//! `D_ci = i·L + (i−1)·T_t`, `D_ms(n) = D_cn`, `D_snm = T_t + L`.
//!
//! Eq. 2 assumes the response returns over the command's path and leaves out the response's
//! own wire time. On the physical ring the response travels on through slaves i+1..n; the
//! [event-level](EventLevel) figures follow that path frame by frame ([`Timeline`]).

mod broken;
mod link;
mod params;
mod timeline;

pub use broken::{BrokenRing, RingModel};
pub use link::{Link, parse_bit_rate};
pub use params::{PlanError, RingParams, short_number};
pub use timeline::{FrameRef, Node, Passage, Phase, PhaseKind, Timeline};

use ringsync_wire::ethernet::frame_len;
use ringsync_wire::lumped::lumped_pdu_len;
use ringsync_wire::{COMMAND_PDU_LEN, RESPONSE_PDU_LEN};
use serde::Serialize;

use crate::time::Duration;

/// Assumptions the plan makes that the paper does not state; every output of the planner
/// lists them.
pub const ASSUMPTIONS: &[&str] = &[
    "reserve slices: the paper's \"n/4 + 1\" is read as floor(n/4) + 1",
    "slaves forward every frame cut-through with the same fixed residence T_t, first bit in to first bit out",
    "T_ti runs from the last bit of the command received to the first bit of the response sent",
    "eq. 2 counts the response's return as D_ci over the command's path and omits its wire time; the event-level figures use the physical ring path (response on through slaves i+1..n) and include it",
    "frame sizes are ringsync's wire format (docs/wire.md); the paper does not give its own",
    "the master sends command i+1 as soon as it has response i, unless a link would then carry two frames less than an inter-frame gap apart; then (event level only) it waits out the difference",
    "wire times are rounded up to whole ns, cable delays to the nearest ns",
    "more slots than one MTU holds are split over several lumped frames sent back to back with the inter-frame gap",
];

/// The lumped frames that carry n slots: one frame, or several back to back when n slots do
/// not fit one MTU.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LumpedTrain {
    /// Bytes per slot \[B\].
    pub slot_bytes: usize,
    /// Most slots per frame.
    pub slots_per_frame: usize,
    /// Slots in each frame.
    pub frame_slots: Vec<usize>,
    /// Length of each frame, MAC header to FCS \[B\].
    pub frame_bytes: Vec<usize>,
    /// Wire time of each frame, preamble to FCS \[ns\].
    pub frame_time: Vec<Duration>,
    /// Time for the master to finish sending all of them, gaps between them included \[ns\].
    pub t_lmf: Duration,
}

impl LumpedTrain {
    fn new(params: &RingParams, link: &Link, slot_bytes: usize) -> Self {
        let n = params.slaves as usize;
        let slots_per_frame = (params.slot_room() / slot_bytes).max(1);
        let mut frame_slots = Vec::with_capacity(n.div_ceil(slots_per_frame));
        let mut left = n;
        while left > 0 {
            let m = left.min(slots_per_frame);
            frame_slots.push(m);
            left -= m;
        }
        let pdu: Vec<usize> = frame_slots
            .iter()
            .map(|&m| lumped_pdu_len(m, slot_bytes))
            .collect();
        let frame_time: Vec<Duration> = pdu.iter().map(|&p| link.frame_time(p)).collect();
        let gaps = link.gap() * (frame_time.len() as i64 - 1);
        LumpedTrain {
            slot_bytes,
            slots_per_frame,
            frame_bytes: pdu.iter().map(|&p| frame_len(p)).collect(),
            t_lmf: frame_time.iter().copied().sum::<Duration>() + gaps,
            frame_slots,
            frame_time,
        }
    }

    /// Start of frame `j` relative to the start of the first \[ns\].
    pub fn frame_offset(&self, j: usize, gap: Duration) -> Duration {
        self.frame_time[..j].iter().map(|&t| t + gap).sum()
    }
}

/// The figures of the physical ring path, frame by frame (the simulator reproduces them).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EventLevel {
    /// Start of the P2P phase: T_syn, or later if the master's link needs its gap \[ns\].
    pub p2p_start: Duration,
    /// Wait of the master after each response so that every link keeps the inter-frame
    /// gap: max(0, gap − ((n+1)·L + n·T_t)) \[ns\]; zero on any realistic 100 Mbit/s ring.
    pub turnaround: Duration,
    /// Length of each slice: command sent → whole response back at the master \[ns\].
    pub slot: Vec<Duration>,
    /// Length of one reserve slice: the longest slice \[ns\].
    pub reserve_slice: Duration,
    /// Idle time left in the cycle \[ns\]; negative when the cycle is too short.
    pub t_idle: Duration,
    /// Shortest cycle that fits \[ns\].
    pub min_t_cyc: Duration,
}

/// Which communication plan a cycle is planned for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum PlanKind {
    /// The paper's proposed plan: sync lumped frame, then point-to-point slices.
    #[serde(rename = "p2p-lumped")]
    P2pLumped,
    /// The lumped-only plan of ref. \[3\]: one lumped frame, controllers in the slaves.
    #[serde(rename = "lumped-only")]
    LumpedOnly,
}

impl PlanKind {
    /// The name used in options, scenarios and outputs.
    pub fn name(self) -> &'static str {
        match self {
            PlanKind::P2pLumped => "p2p-lumped",
            PlanKind::LumpedOnly => "lumped-only",
        }
    }
}

impl core::str::FromStr for PlanKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "p2p-lumped" => Ok(PlanKind::P2pLumped),
            "lumped-only" => Ok(PlanKind::LumpedOnly),
            other => Err(format!(
                "unknown plan '{other}': expected p2p-lumped or lumped-only"
            )),
        }
    }
}

/// The cycle of the lumped-only plan of ref. \[3\] on the same ring (docs/system.md, "The lumped-only plan"):
/// `T_cyc = T_lmf + D_ms(n) + D_snm + T_rest + T_idle`, the sync phase of eq. 2 with this
/// plan's larger slots and no P2P phase.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LumpedOnlyPlan {
    /// Its lumped frames.
    pub lumped: LumpedTrain,
    /// Shortest cycle: T_lmf + D_ms(n) + D_snm + T_rest \[ns\].
    pub min_t_cyc: Duration,
    /// Idle time left in T_cyc \[ns\]; negative when the cycle is too short.
    pub t_idle: Duration,
}

/// The schedule of one cycle of the proposed plan with every term of eq. 1-2.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CyclePlan {
    /// The inputs.
    pub params: RingParams,
    /// The link of every hop.
    pub link: Link,
    /// First-bit latency L of one hop \[ns\].
    pub hop: Duration,
    /// The sync lumped frame(s).
    pub lumped: LumpedTrain,
    /// Length of a command frame, MAC header to FCS \[B\].
    pub command_frame_bytes: usize,
    /// Length of a response frame, MAC header to FCS \[B\].
    pub response_frame_bytes: usize,
    /// T_lmf: time for the master to finish sending the lumped frame(s) \[ns\].
    pub t_lmf: Duration,
    /// D_ms(n): first-bit delay from the master to slave n \[ns\].
    pub d_ms: Duration,
    /// D_snm: first-bit delay from slave n back to the master \[ns\].
    pub d_snm: Duration,
    /// T_syn = T_lmf + D_ms(n) + D_snm + T_rest (eq. 2) \[ns\].
    pub t_syn: Duration,
    /// T_cmf: wire time of a command frame \[ns\].
    pub t_cmf: Duration,
    /// Wire time of a response frame (not in eq. 2) \[ns\].
    pub t_rmf: Duration,
    /// D_ci for i = 1..n: first-bit delay from the master to slave i \[ns\].
    pub d_c: Vec<Duration>,
    /// T_slot(i) = T_cmf + 2·D_ci + T_ti for i = 1..n (eq. 2) \[ns\].
    pub slot: Vec<Duration>,
    /// Number of reserve slices, ⌊n/4⌋ + 1.
    pub reserve_slices: u32,
    /// Length of one reserve slice, T_slot(n) \[ns\].
    pub reserve_slice: Duration,
    /// T_idle from eq. 1 \[ns\]; negative when the cycle is too short.
    pub t_idle: Duration,
    /// Shortest T_cyc by eq. 1 (T_idle = 0) \[ns\].
    pub min_t_cyc: Duration,
    /// The same cycle on the physical ring path.
    pub event: EventLevel,
    /// The lumped-only plan of ref. \[3\] on the same ring.
    pub lumped_only: LumpedOnlyPlan,
}

impl CyclePlan {
    /// Computes the plan. Fails only on parameters out of range; a cycle that is too short
    /// gives a negative idle time (see [`CyclePlan::check_fits`]).
    pub fn new(params: &RingParams) -> Result<Self, PlanError> {
        params.validate()?;
        let n = params.slaves as i64;
        let link = params.link();
        let hop = link.hop();
        let t_t = params.residence;
        let lumped = LumpedTrain::new(params, &link, params.slot_bytes);
        let t_lmf = lumped.t_lmf;
        let d_c: Vec<Duration> = (1..=n).map(|i| hop * i + t_t * (i - 1)).collect();
        let d_ms = d_c[d_c.len() - 1];
        let d_snm = t_t + hop;
        let t_syn = t_lmf + d_ms + d_snm + params.t_rest;
        let t_cmf = link.frame_time(COMMAND_PDU_LEN);
        let t_rmf = link.frame_time(RESPONSE_PDU_LEN);
        let slot: Vec<Duration> = d_c
            .iter()
            .map(|&d| t_cmf + d * 2 + params.response_delay)
            .collect();
        let reserve_slices = params.slaves / 4 + 1;
        let reserve_slice = slot.iter().copied().max().unwrap_or(Duration::ZERO);
        let min_t_cyc =
            t_syn + reserve_slice * i64::from(reserve_slices) + slot.iter().copied().sum();
        // Physical path: command through slaves 1..i, response on through i+1..n to the
        // master: (n + 1) hops and n − 1 residences in all, whatever i is.
        let ring = hop * (n + 1) + t_t * (n - 1);
        // Slave i sends response i and later forwards command i + 1 on the same link; between
        // the two the frames go once round the ring: (n + 1)·L + n·T_t. The master's own link
        // carries the last lumped frame, then command 1, (n + 1)·L + n·T_t + T_rest apart.
        let round = hop * (n + 1) + t_t * n;
        let gap = link.gap();
        let turnaround = (gap - round).max(Duration::ZERO);
        let p2p_start = t_syn + (gap - round - params.t_rest).max(Duration::ZERO);
        let event_slot =
            vec![t_cmf + params.response_delay + t_rmf + ring + turnaround; n as usize];
        let event_reserve = event_slot[0];
        let event_min = p2p_start
            + event_reserve * i64::from(reserve_slices)
            + event_slot.iter().copied().sum();
        let lo = LumpedTrain::new(params, &link, params.lumped_only_slot_bytes);
        let lo_min = lo.t_lmf + d_ms + d_snm + params.t_rest;
        let lumped_only = LumpedOnlyPlan {
            min_t_cyc: lo_min,
            t_idle: params.t_cyc - lo_min,
            lumped: lo,
        };
        Ok(CyclePlan {
            params: params.clone(),
            link,
            hop,
            command_frame_bytes: frame_len(COMMAND_PDU_LEN),
            response_frame_bytes: frame_len(RESPONSE_PDU_LEN),
            lumped,
            t_lmf,
            d_ms,
            d_snm,
            t_syn,
            t_cmf,
            t_rmf,
            d_c,
            slot,
            reserve_slices,
            reserve_slice,
            t_idle: params.t_cyc - min_t_cyc,
            min_t_cyc,
            event: EventLevel {
                p2p_start,
                turnaround,
                slot: event_slot,
                reserve_slice: event_reserve,
                t_idle: params.t_cyc - event_min,
                min_t_cyc: event_min,
            },
            lumped_only,
        })
    }

    /// Number of slaves n.
    pub fn slaves(&self) -> u32 {
        self.params.slaves
    }

    /// The terms of eq. 1 in order, as (symbol, duration); they add up to T_cyc exactly.
    pub fn budget(&self) -> Vec<(String, Duration)> {
        let mut rows = vec![
            ("T_lmf".to_string(), self.t_lmf),
            ("D_ms(n)".to_string(), self.d_ms),
            ("D_snm".to_string(), self.d_snm),
            ("T_rest".to_string(), self.params.t_rest),
        ];
        for (i, &s) in self.slot.iter().enumerate() {
            rows.push((format!("T_slot({})", i + 1), s));
        }
        rows.push((
            format!("reserve {}×T_slot(n)", self.reserve_slices),
            self.reserve_slice * i64::from(self.reserve_slices),
        ));
        rows.push(("T_idle".to_string(), self.t_idle));
        rows
    }

    /// The terms of the lumped-only plan's cycle in order; they add up to T_cyc exactly.
    pub fn lumped_only_budget(&self) -> Vec<(String, Duration)> {
        vec![
            ("T_lmf".to_string(), self.lumped_only.lumped.t_lmf),
            ("D_ms(n)".to_string(), self.d_ms),
            ("D_snm".to_string(), self.d_snm),
            ("T_rest".to_string(), self.params.t_rest),
            ("T_idle".to_string(), self.lumped_only.t_idle),
        ]
    }

    /// `Ok` when the cycle holds the proposed plan both by eq. 1 and on the event-level
    /// ring path; otherwise the shortfall of the tighter of the two.
    pub fn check_fits(&self) -> Result<(), PlanError> {
        self.check_fits_for(PlanKind::P2pLumped)
    }

    /// `Ok` when the cycle holds the given plan; otherwise its shortfall. For the proposed
    /// plan both eq. 1 and the event-level path must fit.
    pub fn check_fits_for(&self, kind: PlanKind) -> Result<(), PlanError> {
        let (needed, basis) = match kind {
            PlanKind::LumpedOnly => (self.lumped_only.min_t_cyc, "lumped-only plan"),
            PlanKind::P2pLumped if self.event.min_t_cyc > self.min_t_cyc => {
                (self.event.min_t_cyc, "event level")
            }
            PlanKind::P2pLumped => (self.min_t_cyc, "eq. 1"),
        };
        if needed > self.params.t_cyc {
            Err(PlanError::CycleTooShort {
                slaves: self.params.slaves,
                t_cyc: self.params.t_cyc,
                needed,
                short: needed - self.params.t_cyc,
                basis,
            })
        } else {
            Ok(())
        }
    }

    /// The frame-by-frame timeline of this cycle on the physical ring path.
    pub fn timeline(&self) -> Timeline {
        Timeline::build(self)
    }
}

/// Largest number of slaves whose plan of kind `kind` fits `params.t_cyc` (the proposed
/// plan: by eq. 1 and at event level), all other parameters as given; 0 when not even one
/// slave fits.
pub fn max_slaves(params: &RingParams, kind: PlanKind) -> Result<u32, PlanError> {
    params.validate()?;
    let fits = |n: u32| -> Result<bool, PlanError> {
        let p = RingParams {
            slaves: n,
            ..params.clone()
        };
        Ok(CyclePlan::new(&p)?.check_fits_for(kind).is_ok())
    };
    if !fits(1)? {
        return Ok(0);
    }
    // Every term grows with n, so "fits" is monotone: binary search on [lo fits, hi fails).
    let (mut lo, mut hi) = (1u32, 65_536u32);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(mid)? {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(lo)
}

#[cfg(test)]
mod tests;
