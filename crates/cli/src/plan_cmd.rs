//! `ringsync plan`: the cycle-time planner.

use std::path::PathBuf;

use clap::Args;
use ringsync::layers::proto::PlanError;
use ringsync::layers::proto::plan::parse_bit_rate;
use ringsync::layers::report::{MAX_SVG_SLAVES, plan_json, plan_table, timing_svg};
use ringsync::{Duration, PlanKind, RingParams};

use crate::{CliError, Outcome};

fn duration(s: &str) -> Result<Duration, String> {
    s.parse::<Duration>().map_err(|e| e.to_string())
}

/// Options of `ringsync plan`; defaults are the reference scenario `paper-2015`.
#[derive(Args, Debug)]
#[command(
    after_help = "Durations take a unit: ns, us (or µs), ms, s. Example:\n  ringsync plan --slaves 8 --cycle 500us --json"
)]
pub struct PlanArgs {
    /// Number of slaves n on the ring [1..=65535].
    #[arg(long, default_value_t = 4, allow_negative_numbers = true)]
    slaves: i64,
    /// Cycle time T_cyc.
    #[arg(long, default_value = "1ms", value_parser = duration, allow_hyphen_values = true)]
    cycle: Duration,
    /// Link bit rate, e.g. 100M, 1G, 100000000.
    #[arg(long, default_value = "100M", allow_hyphen_values = true)]
    bit_rate: String,
    /// PHY receive latency (MII, DP83848: 240ns).
    #[arg(long, default_value = "240ns", value_parser = duration, allow_hyphen_values = true)]
    phy_rx: Duration,
    /// PHY transmit latency (MII: about 60ns).
    #[arg(long, default_value = "60ns", value_parser = duration, allow_hyphen_values = true)]
    phy_tx: Duration,
    /// Cable length of each hop [m].
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    cable_m: f64,
    /// Signal propagation in the cable [ns/m].
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    propagation_ns_per_m: f64,
    /// Residence time T_t of a forwarding slave, first bit in to first bit out.
    #[arg(long, default_value = "1us", value_parser = duration, allow_hyphen_values = true)]
    residence: Duration,
    /// Response delay T_ti of a slave, end of its command to start of its response.
    #[arg(long, default_value = "2us", value_parser = duration, allow_hyphen_values = true)]
    response_delay: Duration,
    /// Reserve T_rest between the sync and P2P phases (master computes).
    #[arg(long, default_value = "100us", value_parser = duration, allow_hyphen_values = true)]
    t_rest: Duration,
    /// Bytes per slave in the lumped frame (wire format: 20) [B].
    #[arg(long, default_value_t = 20, allow_negative_numbers = true)]
    slot_bytes: i64,
    /// Bytes per slave in the lumped-only plan's frame (wire format: 32) [B].
    #[arg(long, default_value_t = 32, allow_negative_numbers = true)]
    lumped_only_slot_bytes: i64,
    /// Largest Ethernet payload [B].
    #[arg(long, default_value_t = 1500, allow_negative_numbers = true)]
    mtu: i64,
    /// Plan whose cycle is checked and shown: p2p-lumped (the paper's) or lumped-only (ref. [3]).
    #[arg(long, default_value = "p2p-lumped", value_parser = |s: &str| s.parse::<PlanKind>())]
    plan: PlanKind,
    /// Print one JSON object in integer nanoseconds instead of the table.
    #[arg(long)]
    json: bool,
    /// With --json: include the frame-by-frame timeline of the cycle (at most 256 slaves).
    #[arg(long)]
    events: bool,
    /// Also draw the cycle as an SVG timing diagram (like the paper's Fig. 1) into FILE.
    #[arg(long, value_name = "FILE")]
    svg: Option<PathBuf>,
    /// Also plan the cycle with link J broken (1..=n+1; link J joins node J-1 to node J, 0
    /// and n+1 being the master's two ports): the master reaches every slave from one end
    /// of the ring or the other (docs/planner.md, "A broken link").
    #[arg(long, value_name = "J", allow_negative_numbers = true)]
    break_link: Option<i64>,
}

/// The cycle with link `j` broken, as a table (times in µs).
fn broken_table(b: &ringsync::layers::proto::plan::BrokenRing) -> String {
    let us = |d: ringsync::layers::proto::Duration| format!("{:.3} µs", d.as_us_f64());
    let opt = |d: Option<ringsync::layers::proto::Duration>| d.map_or("-".to_string(), us);
    let side = |from: u32, count: u32| match count {
        0 => "none".to_string(),
        1 => format!("slave {from}"),
        _ => format!("slaves {from}..{}", from + count - 1),
    };
    let mut t = format!(
        "\nWith link {} broken (port A reaches {}, port B {}):\n",
        b.link,
        side(1, b.side_a),
        side(b.side_a + 1, b.side_b)
    );
    for (name, v) in [
        ("lumped frame back at port A", opt(b.lumped_back_a)),
        ("lumped frame back at port B", opt(b.lumped_back_b)),
        ("P2P start", us(b.p2p_start)),
        ("slice, side A", opt(b.slice_a)),
        ("slice, side B", opt(b.slice_b)),
        ("stamp shift of the copy on port B", us(b.stamp_shift)),
        ("shortest cycle", us(b.min_t_cyc)),
        ("T_idle", us(b.t_idle)),
    ] {
        t.push_str(&format!("  {name:<36} {v:>14}\n"));
    }
    if b.t_idle.is_negative() {
        t.push_str("  The broken ring's plan does not fit this cycle.\n");
    }
    t
}

/// The CLI option that sets a [`RingParams`] field.
fn option_of(field: &str) -> &'static str {
    match field {
        "slaves" => "--slaves",
        "bit_rate" => "--bit-rate",
        "phy_rx" => "--phy-rx",
        "phy_tx" => "--phy-tx",
        "cable_m" => "--cable-m",
        "propagation_ns_per_m" => "--propagation-ns-per-m",
        "residence" => "--residence",
        "response_delay" => "--response-delay",
        "t_rest" => "--t-rest",
        "t_cyc" => "--cycle",
        "slot_bytes" => "--slot-bytes",
        "lumped_only_slot_bytes" => "--lumped-only-slot-bytes",
        "mtu" => "--mtu",
        _ => "an option",
    }
}

fn usage(e: ringsync::Error) -> CliError {
    let ringsync::Error::Plan(e) = e else {
        return e.into();
    };
    CliError::Usage(match e {
        PlanError::OutOfRange {
            field,
            value,
            allowed,
        } => {
            format!(
                "{} {value} is out of range: allowed {allowed}",
                option_of(field)
            )
        }
        PlanError::CycleTooShort {
            slaves,
            t_cyc,
            needed,
            short,
            basis,
        } => format!(
            "--cycle {t_cyc} is too short for {slaves} slaves: the plan needs {needed} ({basis}), short by {short}"
        ),
    })
}

/// Converts an integer option to its type, or says which range it must be in.
/// Most slaves `--events` lists (its passages grow as n²: 256 slaves make 19 MB of JSON and
/// 200 MB of memory).
const MAX_EVENTS_SLAVES: u32 = 256;

fn int<T: TryFrom<i64>>(option: &str, v: i64, allowed: &str) -> Result<T, CliError> {
    T::try_from(v)
        .map_err(|_| CliError::Usage(format!("{option} {v} is out of range: allowed {allowed}")))
}

impl PlanArgs {
    fn params(&self) -> Result<RingParams, CliError> {
        let bit_rate_bps = parse_bit_rate(&self.bit_rate)
            .map_err(|m| CliError::Usage(format!("--bit-rate {m}")))?;
        Ok(RingParams {
            slaves: int("--slaves", self.slaves, "1..=65535")?,
            bit_rate_bps,
            phy_rx: self.phy_rx,
            phy_tx: self.phy_tx,
            cable_m: self.cable_m,
            propagation_ns_per_m: self.propagation_ns_per_m,
            residence: self.residence,
            response_delay: self.response_delay,
            t_rest: self.t_rest,
            t_cyc: self.cycle,
            slot_bytes: int("--slot-bytes", self.slot_bytes, "1 B ..= MTU - 28 B")?,
            lumped_only_slot_bytes: int(
                "--lumped-only-slot-bytes",
                self.lumped_only_slot_bytes,
                "1 B ..= MTU - 28 B",
            )?,
            mtu: int("--mtu", self.mtu, "46 ..= 9000 B")?,
        })
    }
}

/// Runs `ringsync plan`.
pub(crate) fn run(args: &PlanArgs) -> Result<Outcome, CliError> {
    let params = args.params()?;
    if let Some(path) = &args.svg {
        ringsync::output::writable(path)?;
    }
    let plan = ringsync::plan(&params, args.plan).map_err(usage)?;
    let broken = match args.break_link {
        None => None,
        Some(_) if args.plan != PlanKind::P2pLumped => {
            return Err(CliError::Usage(
                "--break-link plans the p2p-lumped plan only".into(),
            ));
        }
        Some(j) => Some(
            u32::try_from(j)
                .ok()
                .and_then(|j| plan.broken(j))
                .ok_or_else(|| {
                    CliError::Usage(format!(
                        "--break-link {j} is not a link of this ring: allowed 1..={}",
                        params.slaves + 1
                    ))
                })?,
        ),
    };
    if let Some(path) = &args.svg {
        // The cycle the options ask for: the plan `--plan`, with `--break-link`'s link broken.
        let svg = timing_svg(&plan, args.plan, broken.as_ref()).ok_or_else(|| {
            CliError::Usage(format!(
                "--svg draws at most {MAX_SVG_SLAVES} slaves, --slaves is {}",
                params.slaves
            ))
        })?;
        ringsync::output::write_file(path, svg)?;
    }
    if args.events && params.slaves > MAX_EVENTS_SLAVES {
        return Err(CliError::Usage(format!(
            "--events lists every frame's passage at every node, some n² of them: at most {MAX_EVENTS_SLAVES} slaves (about 20 MB of JSON), --slaves is {}",
            params.slaves
        )));
    }
    if args.json {
        let mut v = plan_json(&plan, args.plan, args.events);
        if let (Some(b), serde_json::Value::Object(o)) = (&broken, &mut v) {
            let b = serde_json::to_value(b)
                .map_err(|e| CliError::Failure(format!("cannot format JSON: {e}")))?;
            o.insert("broken_ring".into(), b);
        }
        let text = serde_json::to_string_pretty(&v)
            .map_err(|e| CliError::Failure(format!("cannot format JSON: {e}")))?;
        crate::out(&format!("{text}\n"))?;
    } else {
        if args.events {
            return Err(CliError::Usage("--events goes with --json".into()));
        }
        let mut text = plan_table(&plan, args.plan);
        if let Some(b) = &broken {
            text.push_str(&broken_table(b));
        }
        if let Some(path) = &args.svg {
            text.push_str(&format!(
                "\nTiming diagram written to {}.\n",
                path.display()
            ));
        }
        crate::out(&text)?;
    }
    Ok(Outcome::Done)
}
