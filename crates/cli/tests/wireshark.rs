//! The Wireshark dissector `tools/wireshark/ringsync.lua` under tshark (docs/wireshark.md):
//! captures from `ringsync sim --pcap` and `ringsync rt --pcap`, and frames built here with
//! known contents, on Ethernet and on UDP. tshark's field values must equal what the wire
//! crate reads from the same bytes, its Info column the frame's text form (`Frame`'s
//! Display), frame by frame; no frame may show a Malformed Packet or a Lua error.
//!
//! tshark must be installed (Debian: `apt-get install tshark`; `.ci/run` installs it): these
//! tests fail, with that message, when it is not. As root tshark warns on stderr; that is no
//! failure.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::ringsync;
use ringsync::layers::model::result::Captured;
use ringsync::layers::report::pcap;
use ringsync::layers::wire::{
    CommandRepr, Common, DelayMarker, DelaySlot, FeedbackSlot, Flags, Frame, FrameKind,
    LumpedOnlySlot, LumpedRepr, Pdu, ResponseRepr, Status, crc32,
};
use serde_json::Value;

/// The dissector, in the workspace.
fn lua() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/wireshark/ringsync.lua")
}

/// A fresh temporary directory for one test.
fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ringsync-ws-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// Runs tshark with the dissector loaded; fails the test when tshark is missing, exits with
/// an error, or reports a Lua error on stderr (the root warning is allowed). Its stdout.
fn tshark(cap: &Path, args: &[&str]) -> String {
    let lua = format!("lua_script:{}", lua().display());
    let out = Command::new("tshark")
        .args(["-n", "-X", &lua, "-r"])
        .arg(cap)
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "tshark is not installed ({e}): the Wireshark dissector's tests need it. \
                 Install it: `DEBIAN_FRONTEND=noninteractive apt-get install -y tshark` \
                 (.ci/run does)"
            )
        });
    let stderr = String::from_utf8_lossy(&out.stderr);
    let complaints: Vec<&str> = stderr
        .lines()
        .filter(|l| !l.starts_with("Running as user \"root\""))
        .filter(|l| !l.trim().is_empty())
        .collect();
    assert!(
        out.status.success() && complaints.is_empty(),
        "tshark {args:?} on {}: {}\n{stderr}",
        cap.display(),
        out.status
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

/// The frame numbers tshark shows with display filter `filter`.
fn matching(cap: &Path, args: &[&str], filter: &str) -> Vec<usize> {
    let args = [args, &["-Y", filter, "-T", "fields", "-e", "frame.number"]].concat();
    tshark(cap, &args)
        .lines()
        .map(|l| l.trim().parse().expect("frame number"))
        .collect()
}

/// Fields compared as numbers within tshark's 6 significant digits (binary32 in volts).
const FLOAT_FIELDS: [&str; 3] = [
    "ringsync.slot.command",
    "ringsync.command.value",
    "ringsync.response.applied",
];

/// Every field the dissector shows for a valid frame, compared frame by frame.
const FIELDS: [&str; 38] = [
    "ringsync.version",
    "ringsync.kind",
    "ringsync.flags",
    "ringsync.retry",
    "ringsync.cycle",
    "ringsync.seq",
    "ringsync.length",
    "ringsync.crc",
    "ringsync.crc.status",
    "ringsync.slave",
    "ringsync.master_time",
    "ringsync.first_slot",
    "ringsync.slot_count",
    "ringsync.slot.index",
    "ringsync.slot.position",
    "ringsync.slot.velocity",
    "ringsync.slot.sample_time",
    "ringsync.slot.status",
    "ringsync.slot.written",
    "ringsync.slot.desired_position",
    "ringsync.slot.desired_velocity",
    "ringsync.slot.command",
    "ringsync.slot.residence",
    "ringsync.slot.path_delay",
    "ringsync.slot.residence_of",
    "ringsync.slot.marker",
    "ringsync.command.target",
    "ringsync.command.link",
    "ringsync.command.value",
    "ringsync.command.sample_time",
    "ringsync.response.source",
    "ringsync.response.status",
    "ringsync.response.echo_cycle",
    "ringsync.response.position",
    "ringsync.response.velocity",
    "ringsync.response.sample_time",
    "ringsync.response.applied",
    "ringsync.padding",
];

/// One frame as tshark decoded it: field name → values (as tshark prints them).
type Fields = BTreeMap<String, Vec<String>>;

/// tshark's fields for every frame of `cap`, in order.
fn decode(cap: &Path, args: &[&str]) -> Vec<Fields> {
    let mut a: Vec<&str> = args.to_vec();
    a.extend(["-T", "json"]);
    let extra = ["frame.number", "_ws.col.Info", "_ws.expert.message"];
    let extra = extra.iter().chain(
        [
            "_ws.expert.severity",
            "_ws.malformed",
            "_ws.malformed.expert",
            "_ws.lua.error",
            "frame.protocols",
        ]
        .iter(),
    );
    for f in FIELDS.iter().chain(extra) {
        a.extend(["-e", f]);
    }
    let json: Value = serde_json::from_str(&tshark(cap, &a)).expect("tshark's JSON");
    json.as_array()
        .expect("array")
        .iter()
        .map(|p| {
            p["_source"]["layers"]
                .as_object()
                .expect("layers")
                .iter()
                .map(|(k, v)| {
                    let vals = v.as_array().expect("values");
                    let vals = vals.iter().map(|s| s.as_str().expect("str").to_string());
                    (k.clone(), vals.collect())
                })
                .collect()
        })
        .collect()
}

/// Severity "error" of `_ws.expert.severity` (PI_ERROR).
const PI_ERROR: &str = "8388608";

/// What the dissector must show for the PDU in `buf` (a valid one), from the wire crate.
fn expected(buf: &[u8]) -> Fields {
    let f = Frame::new_checked(buf).expect("frame");
    f.validate().expect("a valid frame");
    let mut e = Fields::new();
    let mut put = |k: &str, v: String| e.entry(k.to_string()).or_default().push(v);
    put("ringsync.version", f.version().to_string());
    put("ringsync.kind", f.kind_byte().to_string());
    put("ringsync.flags", format!("0x{:02x}", f.flags_byte()));
    put("ringsync.retry", f.retry().to_string());
    put("ringsync.cycle", f.cycle().to_string());
    put("ringsync.seq", f.seq().to_string());
    put("ringsync.length", f.payload_len().to_string());
    put("ringsync.crc", format!("0x{:08x}", f.crc()));
    put("ringsync.crc.status", "1".into());
    match f.kind().expect("kind") {
        FrameKind::Delay => {
            let p = f.lumped().expect("delay");
            put("ringsync.master_time", p.master_time_ns().to_string());
            put("ringsync.first_slot", p.first_slot().to_string());
            put("ringsync.slot_count", p.slot_count().to_string());
            for k in 0..usize::from(p.slot_count()) {
                let index = usize::from(p.first_slot()) + k;
                put("ringsync.slot.index", index.to_string());
                put("ringsync.slave", (index + 1).to_string());
                let s = p.delay_slot(k).expect("delay slot");
                put("ringsync.slot.residence", s.residence_ns().to_string());
                put("ringsync.slot.path_delay", s.path_delay_ns().to_string());
                put("ringsync.slot.residence_of", s.residence_of().to_string());
                let marker = match s.marker().expect("marker") {
                    DelayMarker::Empty => 0,
                    DelayMarker::Written => 1,
                    DelayMarker::Residence => 2,
                };
                put("ringsync.slot.marker", marker.to_string());
            }
        }
        kind @ (FrameKind::Lumped | FrameKind::LumpedOnly) => {
            let p = f.lumped().expect("lumped");
            put("ringsync.master_time", p.master_time_ns().to_string());
            put("ringsync.first_slot", p.first_slot().to_string());
            put("ringsync.slot_count", p.slot_count().to_string());
            for k in 0..usize::from(p.slot_count()) {
                let index = usize::from(p.first_slot()) + k;
                put("ringsync.slot.index", index.to_string());
                put("ringsync.slave", (index + 1).to_string());
                let s = p.feedback_slot(k).expect("slot");
                put("ringsync.slot.position", s.position().to_string());
                put("ringsync.slot.velocity", s.velocity().to_string());
                put("ringsync.slot.sample_time", s.sample_time_ns().to_string());
                put("ringsync.slot.status", format!("0x{:04x}", s.status_bits()));
                put("ringsync.slot.written", u8::from(s.written()).to_string());
                if kind == FrameKind::LumpedOnly {
                    let o = p.lumped_only_slot(k).expect("lumped-only slot");
                    put(
                        "ringsync.slot.desired_position",
                        o.desired_position().to_string(),
                    );
                    put(
                        "ringsync.slot.desired_velocity",
                        o.desired_velocity().to_string(),
                    );
                    put("ringsync.slot.command", o.command_v().to_string());
                }
            }
        }
        FrameKind::Command => {
            let c = f.command().expect("command");
            put("ringsync.command.target", c.target().to_string());
            put("ringsync.slave", c.target().to_string());
            put("ringsync.command.link", c.link_ns().to_string());
            put("ringsync.command.value", c.command_v().to_string());
            put(
                "ringsync.command.sample_time",
                c.sample_time_ns().to_string(),
            );
        }
        FrameKind::Response => {
            let r = f.response().expect("response");
            put("ringsync.response.source", r.source().to_string());
            put("ringsync.slave", r.source().to_string());
            put(
                "ringsync.response.status",
                format!("0x{:04x}", r.status_bits()),
            );
            put("ringsync.response.echo_cycle", r.echo_cycle().to_string());
            put("ringsync.response.position", r.position().to_string());
            put("ringsync.response.velocity", r.velocity().to_string());
            put(
                "ringsync.response.sample_time",
                r.sample_time_ns().to_string(),
            );
            put("ringsync.response.applied", r.applied_v().to_string());
        }
    }
    let padding = &buf[f.pdu_len()..];
    if !padding.is_empty() {
        let hex: String = padding.iter().map(|b| format!("{b:02x}")).collect();
        put("ringsync.padding", hex);
    }
    e
}

/// Asserts that tshark's fields of frame `n` equal the expected ones, every field of
/// [`FIELDS`] (floats to tshark's precision).
fn assert_fields(n: usize, got: &Fields, want: &Fields) {
    let none = Vec::new();
    for key in FIELDS {
        let (g, w) = (
            got.get(key).unwrap_or(&none),
            want.get(key).unwrap_or(&none),
        );
        if FLOAT_FIELDS.contains(&key) {
            assert_eq!(g.len(), w.len(), "frame {n}: {key}: {g:?} vs {w:?}");
            for (a, b) in g.iter().zip(w) {
                let (a, b): (f64, f64) = (a.parse().expect("float"), b.parse().expect("float"));
                assert!(
                    (a - b).abs() <= 1e-5 * b.abs().max(1e-30),
                    "frame {n}: {key}: tshark {a}, wire crate {b}"
                );
            }
        } else {
            assert_eq!(g, w, "frame {n}: {key}");
        }
    }
}

/// The first value of `key`, or "".
fn one<'a>(f: &'a Fields, key: &str) -> &'a str {
    f.get(key)
        .and_then(|v| v.first())
        .map_or("", String::as_str)
}

/// The enhanced packet blocks of a pcapng file: (interface, raw 64-bit timestamp,
/// link-layer bytes).
fn blocks(file: &[u8]) -> Vec<(u32, u64, Vec<u8>)> {
    let word = |at: usize| u32::from_le_bytes(file[at..at + 4].try_into().expect("4 bytes"));
    let (mut at, mut out) = (0, Vec::new());
    while at < file.len() {
        let (kind, len) = (word(at), word(at + 4) as usize);
        if kind == 6 {
            let caplen = word(at + 20) as usize;
            let t = (u64::from(word(at + 12)) << 32) | u64::from(word(at + 16));
            out.push((word(at + 8), t, file[at + 28..at + 28 + caplen].to_vec()));
        }
        at += len;
    }
    out
}

/// The packets of a pcapng file: (interface, link-layer bytes).
fn packets(file: &[u8]) -> Vec<(u32, Vec<u8>)> {
    blocks(file).into_iter().map(|(i, _, b)| (i, b)).collect()
}

/// A capture of a ring: tshark's fields per frame and the frames' senders (the pcapng
/// interface: 0 the master, i slave i).
struct RingCapture {
    decoded: Vec<Fields>,
    senders: Vec<u32>,
}

/// The checks every capture of a ring must pass under tshark: every frame is claimed by the
/// dissector (display filter `ringsync`), none shows a Malformed Packet, a Lua error or an
/// expert error, and each frame's fields and Info column are what the wire crate reads from
/// its bytes.
fn check_ring_capture(cap: &Path) -> RingCapture {
    let file = std::fs::read(cap).expect("capture");
    let (senders, pdus): (Vec<u32>, Vec<Vec<u8>>) = packets(&file)
        .into_iter()
        .map(|(node, b)| (node, b[14..].to_vec()))
        .unzip();
    assert!(pdus.len() > 25, "{} frames", pdus.len());
    assert_eq!(
        matching(cap, &[], "ringsync").len(),
        pdus.len(),
        "the display filter `ringsync` matches every frame"
    );
    assert_eq!(
        matching(
            cap,
            &[],
            "_ws.malformed || _ws.lua.error || ringsync.internal"
        ),
        Vec::<usize>::new(),
        "frames with a Malformed Packet or a Lua error"
    );
    let decoded = decode(cap, &[]);
    assert_eq!(decoded.len(), pdus.len());
    for (n, (got, pdu)) in decoded.iter().zip(&pdus).enumerate() {
        let n = n + 1;
        assert_eq!(
            one(got, "_ws.col.Info"),
            Frame::new_unchecked(&pdu[..]).to_string(),
            "frame {n}: Info is the frame's text form"
        );
        assert!(
            one(got, "frame.protocols").ends_with(":ringsync"),
            "frame {n}: {got:?}"
        );
        let severities = got.get("_ws.expert.severity").cloned().unwrap_or_default();
        assert!(
            !severities.iter().any(|s| s == PI_ERROR),
            "frame {n}: {:?}",
            got.get("_ws.expert.message")
        );
        assert_fields(n, got, &expected(pdu));
    }
    RingCapture { decoded, senders }
}

/// Groups frames by the cycle of their exchange (lumped and command: the header's cycle; a
/// response: the cycle it echoes): how many frames each cycle holds.
fn frames_per_cycle(decoded: &[Fields]) -> BTreeMap<u64, usize> {
    let mut per = BTreeMap::new();
    for f in decoded {
        let cycle = match one(f, "ringsync.kind") {
            "3" => one(f, "ringsync.response.echo_cycle"),
            _ => one(f, "ringsync.cycle"),
        };
        *per.entry(cycle.parse::<u64>().expect("cycle")).or_default() += 1;
    }
    per
}

/// The cycle counters of the master's lumped frames (kind 1 from node 0), which must count
/// up by one per cycle, as tshark shows them.
fn master_cycles(c: &RingCapture) -> Vec<u64> {
    let cycles: Vec<u64> = c
        .decoded
        .iter()
        .zip(&c.senders)
        .filter(|(f, node)| **node == 0 && one(f, "ringsync.kind") == "1")
        .map(|(f, _)| one(f, "ringsync.cycle").parse().expect("cycle"))
        .collect();
    assert!(!cycles.is_empty());
    for w in cycles.windows(2) {
        assert_eq!(
            w[1],
            w[0] + 1,
            "the master's lumped frames count the cycles"
        );
    }
    cycles
}

#[test]
fn a_sim_capture_decodes_frame_by_frame() {
    let d = dir("sim");
    let sc = d.join("short.toml");
    std::fs::write(&sc, "duration = \"20ms\"\n").expect("scenario");
    let cap = d.join("sim.pcapng");
    let o = ringsync(&[
        "sim",
        sc.to_str().expect("utf-8"),
        "--out",
        d.join("out").to_str().expect("utf-8"),
        "--pcap",
        cap.to_str().expect("utf-8"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let c = check_ring_capture(&cap);
    let decoded = &c.decoded;
    // Every hop, as rt records them: 25 frames in each of the 20 cycles of the reference ring.
    assert_eq!(decoded.len(), 20 * 25);
    assert!(frames_per_cycle(decoded).values().all(|&n| n == 25));
    assert_eq!(master_cycles(&c), (0..20).collect::<Vec<u64>>());
    // Per cycle: the lumped frame round the ring (its slots for slaves 1..4), then a command
    // to each slave in turn, relayed by the slaves before it, each answered and the answer
    // relayed by the slaves behind.
    let cycle: Vec<(&str, &str)> = decoded[25 * 7..25 * 8]
        .iter()
        .map(|f| (one(f, "ringsync.kind"), one(f, "ringsync.slave")))
        .collect();
    let mut want = vec![("1", "1"); 5];
    for s in ["1", "2", "3", "4"] {
        let hops = s.parse::<usize>().expect("slave");
        want.extend(std::iter::repeat_n(("2", s), hops));
        want.extend(std::iter::repeat_n(("3", s), 5 - hops));
    }
    assert_eq!(cycle, want);
    for f in &decoded[25 * 7..25 * 7 + 5] {
        assert_eq!(f["ringsync.slave"], ["1", "2", "3", "4"]);
        assert_eq!(f["ringsync.cycle"], ["7"]);
    }
    // The capture names its run and its clock: simulated time from 0.
    let (app, comment, first) = provenance(&cap);
    assert!(app.ends_with("co-simulator"), "{app}");
    assert!(
        comment.contains("scenario short, seed 1, scenario hash")
            && comment.contains("simulated time from 0"),
        "{comment}"
    );
    assert!(first < 1.0, "simulated time: {first}");
    let _ = std::fs::remove_dir_all(&d);
}

/// What tshark reads of a capture's provenance: the section header's application and
/// comment, and the first frame's absolute time [s since 1970].
fn provenance(cap: &Path) -> (String, String, f64) {
    let file = std::fs::read(cap).expect("read capture");
    let shb_len = u32::from_le_bytes(file[4..8].try_into().expect("4 bytes")) as usize;
    let shb = &file[..shb_len];
    // Options after the 24-byte fixed part: (code, length, value padded to 4).
    let (mut at, mut app, mut comment) = (24, String::new(), String::new());
    while at + 4 <= shb_len - 4 {
        let code = u16::from_le_bytes([shb[at], shb[at + 1]]);
        let len = usize::from(u16::from_le_bytes([shb[at + 2], shb[at + 3]]));
        let value = String::from_utf8_lossy(&shb[at + 4..at + 4 + len]).into_owned();
        match code {
            0 => break,
            1 => comment = value,
            4 => app = value,
            _ => {}
        }
        at += 4 + len.div_ceil(4) * 4;
    }
    let first: f64 = tshark(cap, &["-c", "1", "-T", "fields", "-e", "frame.time_epoch"])
        .trim()
        .parse()
        .expect("a time");
    (app, comment, first)
}

#[test]
fn an_rt_capture_decodes_frame_by_frame() {
    let d = dir("rt");
    let cap = d.join("rt.pcapng");
    let before = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .expect("after 1970")
        .as_secs_f64();
    rt_capture(
        &[
            "--transport",
            "udp",
            "--duration",
            "300ms",
            "--out",
            d.join("out").to_str().expect("utf-8"),
        ],
        &cap,
        250,
    );
    // A real-time capture says so and dates its frames from the wall clock (to the second).
    let (app, comment, first) = provenance(&cap);
    assert!(app.ends_with("real-time runtime (udp)"), "{app}");
    assert!(comment.contains("scenario paper-2015, seed 1"), "{comment}");
    assert!(
        first >= before.floor() - 1.0 && first < before + 120.0,
        "first frame at {first}, the run started at {before}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// Runs `ringsync rt paper-2015 ARGS --no-sim-prediction --pcap CAP` (a group stop the host
/// caused is still a run; a start-up phase that measured the ring too slow for its cycle
/// three times, a busy host's doing, is launched again, three times at most), checks the
/// capture under tshark ([`check_ring_capture`]) with at least `cycles` of the master's
/// lumped frames, and returns it. rt records every hop: most cycles hold the 25 frames the
/// simulator records (a late loop may add a retry now and then).
fn rt_capture(args: &[&str], cap: &Path, cycles: usize) -> RingCapture {
    let mut all = vec!["rt", "paper-2015"];
    all.extend_from_slice(args);
    all.extend([
        "--no-sim-prediction",
        "--pcap",
        cap.to_str().expect("utf-8"),
    ]);
    let mut o = ringsync(&all);
    for _ in 1..3 {
        if o.status.code() != Some(2)
            || !String::from_utf8_lossy(&o.stderr).contains("the measured ring needs")
        {
            break;
        }
        o = ringsync(&all);
    }
    assert!(
        matches!(o.status.code(), Some(0 | 3)),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let c = check_ring_capture(cap);
    assert!(
        master_cycles(&c).len() >= cycles,
        "{} cycles",
        master_cycles(&c).len()
    );
    let per = frames_per_cycle(&c.decoded);
    let full = per.values().filter(|&&n| n == 25).count();
    assert!(
        full * 2 > per.len(),
        "{full} of {} cycles hold 25 frames",
        per.len()
    );
    c
}

/// A ring of node processes keeps what each node sends; the launcher merges the nodes'
/// frames into one capture, in time order, each frame on its sender's interface.
#[test]
fn a_capture_of_node_processes_decodes_frame_by_frame() {
    let d = dir("processes");
    let cap = d.join("processes.pcapng");
    let out = d.join("out");
    // A 10 ms cycle, every node on one CPU: the ring of processes fits it on a busy host
    // too (one that held the nodes off their CPUs for milliseconds measured 8.8-14.4 ms
    // needed of 5 ms, unpinned).
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let last = status
        .lines()
        .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
        .and_then(|v| v.trim().rsplit([',', '-']).next())
        .unwrap_or("0")
        .to_string();
    let c = rt_capture(
        &[
            "--processes",
            "--cpu",
            &last,
            "--transport",
            "udp",
            "--cycle",
            "10ms",
            "--duration",
            "2s",
            "--out",
            out.to_str().expect("utf-8"),
        ],
        &cap,
        190,
    );
    // Every node sent frames, each on its own interface.
    for node in 0..=4 {
        assert!(c.senders.contains(&node), "node {node}: {:?}", c.senders);
    }
    // In time order, and nothing the nodes' queues dropped.
    let times = times(&std::fs::read(&cap).expect("capture"));
    assert!(times.windows(2).all(|w| w[0] <= w[1]));
    let summary: Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("summary.json")).expect("summary.json"),
    )
    .expect("json");
    assert_eq!(
        summary["streamed"]["frames_dropped"], 0,
        "{}",
        summary["streamed"]
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// The timestamps of a pcapng file's packets (the raw 64-bit stamps).
fn times(file: &[u8]) -> Vec<u64> {
    blocks(file).into_iter().map(|(_, t, _)| t).collect()
}

/// Writes `frames` as a pcapng of Ethernet frames (one per ms) to `d/<name>.pcapng`; returns
/// its path and each frame's Ethernet payload as the file holds it (padded to 46 bytes).
fn ethernet_capture(
    d: &Path,
    name: &str,
    frames: &[(&'static str, Vec<u8>)],
) -> (PathBuf, Vec<Vec<u8>>) {
    let captured: Vec<Captured> = frames
        .iter()
        .enumerate()
        .map(|(i, (_, b))| Captured {
            t: i as i64 * 1000,
            node: 0,
            bytes: b.clone(),
        })
        .collect();
    let cap = d.join(format!("{name}.pcapng"));
    let info = pcap::CaptureInfo {
        application: "ringsync test".into(),
        comment: name.into(),
        tsoffset_s: None,
    };
    std::fs::write(&cap, pcap::pcapng(&captured, 4, &info)).expect("write");
    let payloads = packets(&std::fs::read(&cap).expect("read"))
        .into_iter()
        .map(|(_, b)| b[14..].to_vec())
        .collect();
    (cap, payloads)
}

/// Frames with known contents, valid, then broken in each way a receiver rejects.
fn known_frames() -> Vec<(&'static str, Vec<u8>)> {
    let common = |cycle, seq| Common {
        cycle,
        seq,
        ..Common::default()
    };
    let emit = |pdu: Pdu| {
        let mut b = vec![0u8; pdu.buffer_len()];
        let n = pdu.emit(&mut b).expect("emit");
        assert_eq!(Pdu::parse(&b[..n]).expect("parses"), pdu);
        b
    };
    let slot = |k: i32| FeedbackSlot {
        position: -1000 * k - 7,
        velocity: 50_000 + k,
        sample_time_ns: 1_000_000_000 + k as u64,
        status: [
            Status::FAULT.with(Status::SATURATED),
            Status::CLOCK_UNLOCKED,
            Status::empty(),
        ][k as usize % 3],
        written: k % 2 == 0,
    };
    let lumped = emit(Pdu::Lumped(LumpedRepr {
        common: common(7, 11),
        master_time_ns: 123_456_789_012,
        first_slot: 2,
        slots: (0..3).map(slot).collect(),
    }));
    let lumped_only = emit(Pdu::LumpedOnly(LumpedRepr {
        common: Common {
            flags: Flags::BRAKE,
            ..common(8, 12)
        },
        master_time_ns: 5,
        first_slot: 0,
        slots: (0..2)
            .map(|k| LumpedOnlySlot {
                feedback: slot(k),
                desired_position: 4000 + k,
                desired_velocity: -300 - k,
                command_v: -0.625 + k as f32,
            })
            .collect(),
    }));
    let command = emit(Pdu::Command(CommandRepr {
        common: Common {
            flags: Flags::STOP.with(Flags::TORQUE_OFF),
            retry: 2,
            cycle: 4_000_000_000,
            seq: 65535,
        },
        target: 3,
        command_v: -1.25,
        sample_time_ns: (1 << 40) + 5,
        link_ns: 1614,
    }));
    let response = emit(Pdu::Response(ResponseRepr {
        common: common(42, 7),
        source: 2,
        status: Status::SATURATED.with(Status::STOPPING),
        echo_cycle: 41,
        position: -2_147_483_000,
        velocity: 123_456,
        sample_time_ns: 2_000_125,
        applied_v: 9.75,
    }));
    // Broken frames; `resealed` gives a frame a correct CRC again after an edit.
    let resealed = |mut b: Vec<u8>| {
        let len = usize::from(u16::from_le_bytes([b[10], b[11]]));
        let crc = crc32(&b[..12 + len]);
        b[12 + len..16 + len].copy_from_slice(&crc.to_le_bytes());
        b
    };
    let edit = |b: &[u8], at: usize, v: &[u8]| {
        let mut b = b.to_vec();
        b[at..at + v.len()].copy_from_slice(v);
        b
    };
    // A probe (slave 2 reports its residence of probe 40, slave 3 has none to report yet,
    // slave 4 did not see it) and a closing frame (path delays; slave 5 has taken its own).
    let probe = emit(Pdu::Delay(LumpedRepr {
        common: common(0, 41),
        master_time_ns: 1_500_000,
        first_slot: 1,
        slots: vec![
            DelaySlot {
                residence_ns: 1012,
                path_delay_ns: 0,
                residence_of: 40,
                marker: DelayMarker::Residence,
            },
            DelaySlot {
                marker: DelayMarker::Written,
                ..DelaySlot::default()
            },
            DelaySlot::default(),
        ],
    }));
    let closing = emit(Pdu::Delay(LumpedRepr {
        common: Common {
            flags: Flags::STOP,
            retry: 1,
            ..common(1, 42)
        },
        master_time_ns: 2_000_000,
        first_slot: 3,
        slots: vec![
            DelaySlot {
                path_delay_ns: 4_240,
                marker: DelayMarker::Written,
                ..DelaySlot::default()
            },
            DelaySlot {
                residence_ns: u32::MAX,
                path_delay_ns: u32::MAX,
                residence_of: u16::MAX,
                marker: DelayMarker::Empty,
            },
        ],
    }));
    let mut bad_crc = command.clone();
    bad_crc[20] ^= 0x10;
    vec![
        ("lumped", lumped.clone()),
        ("lumped-only", lumped_only),
        ("command", command.clone()),
        ("response", response.clone()),
        ("bad CRC", bad_crc),
        ("truncated", lumped[..80].to_vec()),
        ("five bytes", vec![1, 2, 0, 0, 0]),
        ("kind 9", resealed(edit(&command, 1, &[9]))),
        ("version 2", resealed(edit(&command, 0, &[2]))),
        ("reserved flag", resealed(edit(&command, 2, &[0x80]))),
        ("target 0", resealed(edit(&command, 12, &[0, 0]))),
        (
            "NaN command",
            resealed(edit(&command, 16, &f32::NAN.to_le_bytes())),
        ),
        ("short payload", resealed(edit(&lumped, 22, &[4, 0]))),
        ("over capacity", resealed(edit(&lumped, 22, &[100, 0]))),
        ("marker 2", resealed(edit(&lumped, 12 + 12 + 18, &[2]))),
        ("reserved status", resealed(edit(&response, 14, &[0, 1]))),
        ("delay probe", probe.clone()),
        ("delay closing", closing),
        (
            "delay marker 3",
            resealed(edit(&probe, 12 + 12 + 12 + 10, &[3])),
        ),
        ("delay reserved", resealed(edit(&probe, 12 + 12 + 11, &[1]))),
        ("delay short payload", resealed(edit(&probe, 22, &[4, 0]))),
        ("delay over capacity", resealed(edit(&probe, 22, &[123, 0]))),
        ("kind 6", resealed(edit(&probe, 1, &[6]))),
    ]
}

/// Whether the dissector's automatic claim (EtherType 0x88B5, UDP heuristic) takes `buf`:
/// version 1, a known kind, a payload length that fits it, the bytes present, and the CRC
/// (unless `bad_crc_ok`).
fn claimed(buf: &[u8], bad_crc_ok: bool) -> bool {
    let Ok(f) = Frame::new_checked(buf) else {
        return false;
    };
    let fits = match f.kind() {
        Ok(FrameKind::Lumped | FrameKind::LumpedOnly | FrameKind::Delay) => f.lumped().is_ok(),
        Ok(FrameKind::Command) => f.command().is_ok(),
        Ok(FrameKind::Response) => f.response().is_ok(),
        Err(_) => false,
    };
    f.version() == 1 && fits && (bad_crc_ok || f.crc() == f.compute_crc())
}

/// Checks tshark's view of the known frames of `cap` under `args`; frame i carries
/// `frames[i]`, whose bytes as the dissector gets them (Ethernet padding included) are
/// `payloads[i]`. The claimed frames are those `claim` says, each with the Info column of
/// the wire crate's text form; the valid ones with every field and no Malformed mark, the
/// broken ones with their first problem among their expert errors; no Lua error or exception
/// anywhere.
fn check_known(
    cap: &Path,
    args: &[&str],
    frames: &[(&str, Vec<u8>)],
    payloads: &[Vec<u8>],
    claim: &dyn Fn(&[u8]) -> bool,
) {
    let decoded = decode(cap, args);
    assert_eq!(decoded.len(), frames.len());
    for (i, ((name, _), (got, payload))) in
        frames.iter().zip(decoded.iter().zip(payloads)).enumerate()
    {
        let n = i + 1;
        // No Lua error and no exception; a broken frame's structural problems are expert
        // infos of the Malformed group (so `_ws.malformed` marks it), a valid frame has none.
        assert!(
            got.get("_ws.lua.error").is_none() && got.get("_ws.malformed.expert").is_none(),
            "frame {n} ({name}): {got:?}"
        );
        let messages = got.get("_ws.expert.message").cloned().unwrap_or_default();
        assert!(
            !messages.iter().any(|m| m.contains("ringsync.lua")),
            "{messages:?}"
        );
        let is_ours = one(got, "frame.protocols").ends_with(":ringsync");
        assert_eq!(
            is_ours,
            claim(payload),
            "frame {n} ({name}) claimed? {args:?}"
        );
        if !is_ours {
            continue;
        }
        let text = Frame::new_unchecked(&payload[..]).to_string();
        assert_eq!(one(got, "_ws.col.Info"), text, "frame {n} ({name})");
        let errors = got
            .get("_ws.expert.severity")
            .is_some_and(|s| s.iter().any(|s| s == PI_ERROR));
        if text.starts_with("bad frame (") {
            // The first problem, as the Info column names it, is among the expert errors.
            let problem = &text["bad frame (".len()..text.len() - 1];
            assert!(errors, "frame {n} ({name}): {messages:?}");
            assert!(
                messages.iter().any(|m| m == problem),
                "frame {n} ({name}): {problem:?} not in {messages:?}"
            );
        } else {
            assert!(!errors, "frame {n} ({name}): {messages:?}");
            assert!(got.get("_ws.malformed").is_none(), "frame {n} ({name})");
            assert_fields(n, got, &expected(payload));
        }
    }
}

#[test]
fn known_frames_on_ethernet_claimed_checked_or_decoded_as() {
    let d = dir("eth");
    let frames = known_frames();
    let (cap, payloads) = ethernet_capture(&d, "known", &frames);

    // EtherType 0x88B5 as it comes: only what checks as a ringsync PDU is claimed.
    check_known(&cap, &[], &frames, &payloads, &|b| claimed(b, false));
    // The known contents, literally.
    let decoded = decode(&cap, &[]);
    let lumped = &decoded[0];
    assert_eq!(lumped["ringsync.cycle"], ["7"]);
    assert_eq!(lumped["ringsync.slave"], ["3", "4", "5"]);
    assert_eq!(lumped["ringsync.slot.position"], ["-7", "-1007", "-2007"]);
    assert_eq!(
        lumped["ringsync.slot.status"],
        ["0x0003", "0x0008", "0x0000"]
    );
    assert_eq!(lumped["ringsync.slot.written"], ["1", "0", "1"]);
    assert_eq!(lumped["ringsync.master_time"], ["123456789012"]);
    let lumped_only = &decoded[1];
    assert_eq!(
        lumped_only["ringsync.slot.desired_position"],
        ["4000", "4001"]
    );
    assert_eq!(lumped_only["ringsync.slot.command"], ["-0.625", "0.375"]);
    assert_eq!(lumped_only["ringsync.flags"], ["0x04"]);
    let command = &decoded[2];
    assert_eq!(command["ringsync.kind"], ["2"]);
    assert_eq!(command["ringsync.cycle"], ["4000000000"]);
    assert_eq!(command["ringsync.retry"], ["2"]);
    assert_eq!(command["ringsync.slave"], ["3"]);
    assert_eq!(command["ringsync.command.value"], ["-1.25"]);
    assert_eq!(command["ringsync.command.sample_time"], ["1099511627781"]);
    assert_eq!(
        one(command, "_ws.col.Info"),
        "command cycle 4000000000 seq 65535 retry 2 flags STOP|TORQUE_OFF → slave 3: -1.250 V, \
         sampled at 1099511627781 ns, link 1614 ns"
    );
    assert_eq!(command["ringsync.command.link"], ["1614"]);
    let response = &decoded[3];
    assert_eq!(response["ringsync.response.position"], ["-2147483000"]);
    assert_eq!(response["ringsync.response.status"], ["0x0022"]);
    assert_eq!(response["ringsync.response.applied"], ["9.75"]);
    let at = |name: &str| {
        let i = frames.iter().position(|(n, _)| *n == name).expect(name);
        &decoded[i]
    };
    let probe = at("delay probe");
    assert_eq!(probe["ringsync.kind"], ["5"]);
    assert_eq!(probe["ringsync.slave"], ["2", "3", "4"]);
    assert_eq!(probe["ringsync.slot.residence"], ["1012", "0", "0"]);
    assert_eq!(probe["ringsync.slot.residence_of"], ["40", "0", "0"]);
    assert_eq!(probe["ringsync.slot.path_delay"], ["0", "0", "0"]);
    assert_eq!(probe["ringsync.slot.marker"], ["2", "1", "0"]);
    assert!(probe.get("ringsync.slot.position").is_none(), "{probe:?}");
    assert_eq!(
        one(probe, "_ws.col.Info"),
        "delay cycle 0 seq 41, slots 1..4, sent at 1500000 ns"
    );
    let closing = at("delay closing");
    assert_eq!(closing["ringsync.slot.path_delay"], ["4240", "4294967295"]);
    assert_eq!(closing["ringsync.slot.residence_of"], ["0", "65535"]);
    assert_eq!(closing["ringsync.slot.marker"], ["1", "0"]);
    assert_eq!(
        one(closing, "_ws.col.Info"),
        "delay cycle 1 seq 42 retry 1 flags STOP, slots 3..5, sent at 2000000 ns"
    );
    // A delay frame with a bad marker passes the claim (its CRC and length are right) and
    // says what is wrong with it.
    let bad = at("delay marker 3");
    assert_eq!(
        one(bad, "_ws.col.Info"),
        "bad frame (bad delay slot marker 3: expected 0, 1 or 2)"
    );
    assert_eq!(bad["ringsync.slot.marker"], ["2", "3", "0"]);
    // The frame with a flipped bit is not claimed, until the preference says so: then it
    // shows its bad CRC.
    assert_eq!(one(&decoded[4], "frame.protocols"), "eth:ethertype:data");
    check_known(
        &cap,
        &["-o", "ringsync.claim_bad_crc:TRUE"],
        &frames,
        &payloads,
        &|b| claimed(b, true),
    );
    let bad = &decode(&cap, &["-o", "ringsync.claim_bad_crc:TRUE"])[4];
    assert_eq!(bad["ringsync.crc.status"], ["0"]);
    let f = Frame::new_unchecked(&payloads[4][..]);
    let message = format!(
        "bad CRC-32: frame carries 0x{:08x}, contents give 0x{:08x}",
        f.crc(),
        f.compute_crc()
    );
    assert!(bad["_ws.expert.message"].contains(&message), "{bad:?}");
    assert_eq!(
        matching(
            &cap,
            &["-o", "ringsync.claim_bad_crc:TRUE"],
            "ringsync.crc.bad"
        ),
        [5]
    );
    // Decode As: every frame is RingSync, and says what is wrong with it.
    check_known(
        &cap,
        &["-d", "ethertype==0x88b5,ringsync"],
        &frames,
        &payloads,
        &|_| true,
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// A classic pcap file of UDP datagrams on loopback (Ethernet framing, as Linux captures
/// `lo`), each `(source port, destination port, payload)`.
fn udp_pcap(datagrams: &[(u16, u16, Vec<u8>)]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&0xA1B2_C3D4u32.to_le_bytes());
    out.extend_from_slice(&2u16.to_le_bytes());
    out.extend_from_slice(&4u16.to_le_bytes());
    out.extend_from_slice(&[0; 8]);
    out.extend_from_slice(&65535u32.to_le_bytes());
    out.extend_from_slice(&1u32.to_le_bytes()); // LINKTYPE_ETHERNET
    for (i, (sport, dport, payload)) in datagrams.iter().enumerate() {
        let mut p = vec![0u8; 12];
        p.extend_from_slice(&0x0800u16.to_be_bytes());
        let total = (20 + 8 + payload.len()) as u16;
        let mut ip = vec![0x45, 0];
        ip.extend_from_slice(&total.to_be_bytes());
        ip.extend_from_slice(&(i as u16).to_be_bytes());
        ip.extend_from_slice(&[0x40, 0, 64, 17, 0, 0, 127, 0, 0, 1, 127, 0, 0, 1]);
        let sum: u32 = ip
            .chunks(2)
            .map(|c| u32::from(u16::from_be_bytes([c[0], c[1]])))
            .sum();
        let sum = !(((sum & 0xFFFF) + (sum >> 16)) as u16);
        ip[10..12].copy_from_slice(&sum.to_be_bytes());
        p.extend_from_slice(&ip);
        p.extend_from_slice(&sport.to_be_bytes());
        p.extend_from_slice(&dport.to_be_bytes());
        p.extend_from_slice(&(8 + payload.len() as u16).to_be_bytes());
        p.extend_from_slice(&[0, 0]); // no checksum
        p.extend_from_slice(payload);
        out.extend_from_slice(&(i as u32).to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&(p.len() as u32).to_le_bytes());
        out.extend_from_slice(&(p.len() as u32).to_le_bytes());
        out.extend_from_slice(&p);
    }
    out
}

#[test]
fn known_frames_on_udp_found_by_the_heuristic_or_decoded_as() {
    let d = dir("udp");
    let mut frames = known_frames();
    frames.push((
        "not ringsync",
        b"\x12\x34\x01\x00\x00\x01\x00\x00\x00\x00\x00\x00".to_vec(),
    ));
    frames.push(("empty", Vec::new()));
    // The runtime's ring on loopback: ephemeral ports, one socket per node.
    let datagrams: Vec<(u16, u16, Vec<u8>)> = frames
        .iter()
        .map(|(_, b)| (40001, 40002, b.clone()))
        .collect();
    let cap = d.join("udp.pcap");
    std::fs::write(&cap, udp_pcap(&datagrams)).expect("write");
    let payloads: Vec<Vec<u8>> = frames.iter().map(|(_, b)| b.clone()).collect();
    check_known(&cap, &[], &frames, &payloads, &|b| claimed(b, false));
    let valid: Vec<usize> = (1..=payloads.len())
        .filter(|&n| claimed(&payloads[n - 1], false))
        .collect();
    assert_eq!(matching(&cap, &[], "ringsync"), valid);
    assert!(
        valid.starts_with(&[1, 2, 3, 4]) && !valid.contains(&5),
        "{valid:?}"
    );
    // Decode As claims every datagram on the port (UDP hands on no empty payload).
    let any = |b: &[u8]| !b.is_empty();
    check_known(
        &cap,
        &["-d", "udp.port==40002,ringsync"],
        &frames,
        &payloads,
        &any,
    );
    // The ports preference does what Decode As does.
    check_known(
        &cap,
        &["-o", "ringsync.udp_ports:40002"],
        &frames,
        &payloads,
        &any,
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// Frames mutated at random (bits flipped, then the CRC made right again or not, or cut
/// short), 400 of them from the known valid ones, seeded: Decode As claims every one and
/// shows the wire crate's text form, the first problem among the expert errors, and never a
/// Lua error or an exception; the automatic claim takes exactly those that check.
#[test]
fn mutated_frames_never_break_the_dissector() {
    let d = dir("mutated");
    let valid: Vec<Vec<u8>> = known_frames()
        .into_iter()
        .map(|(_, b)| b)
        .filter(|b| {
            Frame::new_checked(&b[..])
                .and_then(|f| f.validate())
                .is_ok()
        })
        .collect();
    assert_eq!(
        valid.len(),
        6,
        "the valid known frames, both delay frames among them"
    );
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut next = |m: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % m as u64) as usize
    };
    let mut frames = Vec::new();
    for i in 0..400 {
        let mut b = valid[i % valid.len()].clone();
        match next(3) {
            0 => b.truncate(next(b.len())),
            way => {
                for _ in 0..1 + next(3) {
                    let bit = next(b.len() * 8);
                    b[bit / 8] ^= 1 << (bit % 8);
                }
                let len = usize::from(u16::from_le_bytes([b[10], b[11]]));
                if way == 2 && 12 + len + 4 <= b.len() {
                    let crc = crc32(&b[..12 + len]);
                    b[12 + len..16 + len].copy_from_slice(&crc.to_le_bytes());
                }
            }
        }
        frames.push(("mutated", b));
    }
    let (cap, payloads) = ethernet_capture(&d, "mutated", &frames);
    // (An Ethernet payload the writer padded from nothing is still 46 bytes: never empty.)
    check_known(
        &cap,
        &["-d", "ethertype==0x88b5,ringsync"],
        &frames,
        &payloads,
        &|_| true,
    );
    check_known(&cap, &[], &frames, &payloads, &|b| claimed(b, false));
    let _ = std::fs::remove_dir_all(&d);
}
