//! pcapng files of simulated frames (opened by Wireshark): one interface per node, each frame
//! as an Ethernet II frame (EtherType 0x88B5, padded to the 60-byte minimum) with its simulated
//! send time at nanosecond resolution.

use ringsync_model::result::Captured;

fn block(out: &mut Vec<u8>, kind: u32, body: &[u8]) {
    let len = 12 + body.len().div_ceil(4) * 4;
    out.extend_from_slice(&kind.to_le_bytes());
    out.extend_from_slice(&(len as u32).to_le_bytes());
    out.extend_from_slice(body);
    out.resize(out.len() + (4 - body.len() % 4) % 4, 0);
    out.extend_from_slice(&(len as u32).to_le_bytes());
}

fn option(body: &mut Vec<u8>, code: u16, value: &[u8]) {
    body.extend_from_slice(&code.to_le_bytes());
    body.extend_from_slice(&(value.len() as u16).to_le_bytes());
    body.extend_from_slice(value);
    body.resize(body.len() + (4 - value.len() % 4) % 4, 0);
}

/// The MAC address of node `i` (0 = master): 02:72:73:00:00:i, locally administered.
pub fn mac(i: usize) -> [u8; 6] {
    [0x02, 0x72, 0x73, 0x00, (i >> 8) as u8, i as u8]
}

/// What a capture says about itself in its section header: the program that wrote it
/// (`shb_userappl`), a comment naming the run (`opt_comment`: scenario, seed, the scenario's
/// hash, ringsync's version, the clock of the timestamps), and for a real-time run the Unix
/// time its frames are dated from (`if_tsoffset`, whole seconds).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CaptureInfo {
    /// The program: `ringsync 0.1.0 co-simulator`, `ringsync 0.1.0 real-time runtime (udp)`.
    pub application: String,
    /// The run, in words.
    pub comment: String,
    /// Seconds added to every frame's time by the reader (`None`: the frames' times are
    /// simulated time from 0, which a reader shows as 1970-01-01).
    pub tsoffset_s: Option<i64>,
}

impl CaptureInfo {
    /// A simulation's capture of scenario `s` (text hash `hash`): simulated time from 0.
    pub fn simulated(s: &ringsync_model::Scenario, hash: u64) -> Self {
        let v = crate::provenance::RINGSYNC_VERSION;
        CaptureInfo {
            application: format!("ringsync {v} co-simulator"),
            comment: format!(
                "ringsync {v} co-simulator: scenario {}, seed {}, scenario hash {hash:016x}; frames timed in simulated time from 0 (shown as 1970-01-01 00:00:00 UTC)",
                s.name, s.seed
            ),
            tsoffset_s: None,
        }
    }

    /// A real-time run's capture of scenario `s` over `transport`, opened now: its frames,
    /// timed by the ring's clock from the run's start, are dated from the wall clock now
    /// (to the second; the start-up phase lies between).
    pub fn real_time(s: &ringsync_model::Scenario, hash: u64, transport: &str) -> Self {
        let v = crate::provenance::RINGSYNC_VERSION;
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| i64::try_from(d.as_secs()).unwrap_or(0));
        CaptureInfo {
            application: format!("ringsync {v} real-time runtime ({transport})"),
            comment: format!(
                "ringsync {v} real-time runtime over {transport}: scenario {}, seed {}, scenario hash {hash:016x}; frames timed by the ring's clock from the run's start, dated from the wall clock when the capture opened (whole seconds)",
                s.name, s.seed
            ),
            tsoffset_s: Some(now),
        }
    }
}

/// A pcapng file of `frames` on a ring of `n` slaves.
pub fn pcapng(frames: &[Captured], n: usize, info: &CaptureInfo) -> Vec<u8> {
    let mut out = pcapng_header(n, info);
    for f in frames {
        push_pcapng_frame(&mut out, f, n);
    }
    out
}

/// The start of a pcapng file on a ring of `n` slaves: the section header and one interface
/// per node; the frames follow ([`push_pcapng_frame`]), for a writer that streams them.
pub fn pcapng_header(n: usize, info: &CaptureInfo) -> Vec<u8> {
    let mut out = Vec::new();
    // Section header: byte-order magic, version 1.0, section length unknown.
    let mut shb = Vec::new();
    shb.extend_from_slice(&0x1A2B_3C4Du32.to_le_bytes());
    shb.extend_from_slice(&1u16.to_le_bytes());
    shb.extend_from_slice(&0u16.to_le_bytes());
    shb.extend_from_slice(&u64::MAX.to_le_bytes());
    option(&mut shb, 1, info.comment.as_bytes()); // opt_comment
    option(&mut shb, 4, info.application.as_bytes()); // shb_userappl
    shb.extend_from_slice(&[0, 0, 0, 0]);
    block(&mut out, 0x0A0D_0D0A, &shb);
    for i in 0..=n {
        let mut idb = Vec::new();
        idb.extend_from_slice(&1u16.to_le_bytes()); // LINKTYPE_ETHERNET
        idb.extend_from_slice(&0u16.to_le_bytes());
        idb.extend_from_slice(&0u32.to_le_bytes()); // no snap length
        let name = if i == 0 {
            "master".to_string()
        } else {
            format!("slave {i}")
        };
        option(&mut idb, 2, name.as_bytes()); // if_name
        option(&mut idb, 9, &[9]); // if_tsresol: 10^-9 s
        if let Some(s) = info.tsoffset_s {
            option(&mut idb, 14, &s.to_le_bytes()); // if_tsoffset [s]
        }
        idb.extend_from_slice(&[0, 0, 0, 0]);
        block(&mut out, 1, &idb);
    }
    out
}

/// Appends frame `f` (of a ring of `n` slaves) to a pcapng file's bytes: one enhanced packet
/// block on its sender's interface.
pub fn push_pcapng_frame(out: &mut Vec<u8>, f: &Captured, n: usize) {
    let mut eth = Vec::with_capacity(14 + f.bytes.len());
    eth.extend_from_slice(&mac((f.node + 1) % (n + 1)));
    eth.extend_from_slice(&mac(f.node));
    eth.extend_from_slice(&ringsync_wire::ETHERTYPE.to_be_bytes());
    eth.extend_from_slice(&f.bytes);
    eth.resize(eth.len().max(60), 0);
    let ts = f.t.max(0) as u64;
    let mut epb = Vec::with_capacity(20 + eth.len());
    epb.extend_from_slice(&(f.node as u32).to_le_bytes());
    epb.extend_from_slice(&((ts >> 32) as u32).to_le_bytes());
    epb.extend_from_slice(&(ts as u32).to_le_bytes());
    epb.extend_from_slice(&(eth.len() as u32).to_le_bytes());
    epb.extend_from_slice(&(eth.len() as u32).to_le_bytes());
    epb.extend_from_slice(&eth);
    block(out, 6, &epb);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Walks the blocks: every block's two length fields agree and the file ends exactly.
    fn blocks(b: &[u8]) -> Vec<(u32, usize)> {
        let mut at = 0;
        let mut out = Vec::new();
        while at < b.len() {
            let kind = u32::from_le_bytes(b[at..at + 4].try_into().expect("4"));
            let len = u32::from_le_bytes(b[at + 4..at + 8].try_into().expect("4")) as usize;
            let tail =
                u32::from_le_bytes(b[at + len - 4..at + len].try_into().expect("4")) as usize;
            assert_eq!(len, tail, "block at {at}");
            assert_eq!(len % 4, 0);
            out.push((kind, len));
            at += len;
        }
        assert_eq!(at, b.len());
        out
    }

    #[test]
    fn structure_is_pcapng() {
        let frames = vec![
            Captured {
                t: 0,
                node: 0,
                bytes: vec![1; 32],
            },
            Captured {
                t: 1_234_567_890_123,
                node: 2,
                bytes: vec![2; 108],
            },
        ];
        let info = CaptureInfo {
            application: "ringsync test".into(),
            comment: "scenario x, seed 3".into(),
            tsoffset_s: Some(1_765_160_000),
        };
        let file = pcapng(&frames, 4, &info);
        let b = blocks(&file);
        // The section header carries the comment and the application, each interface the
        // offset of the frames' times.
        let shb = &file[..b[0].1];
        let find = |hay: &[u8], needle: &[u8]| hay.windows(needle.len()).any(|w| w == needle);
        assert!(
            find(shb, b"\x01\x00\x12\x00scenario x, seed 3"),
            "opt_comment"
        );
        assert!(find(shb, b"\x04\x00\x0d\x00ringsync test"), "shb_userappl");
        let idb = &file[b[0].1..b[0].1 + b[1].1];
        let mut off = vec![14u8, 0, 8, 0];
        off.extend_from_slice(&1_765_160_000i64.to_le_bytes());
        assert!(find(idb, &off), "if_tsoffset");
        let sim = CaptureInfo::simulated(&ringsync_model::Scenario::default(), 0xab);
        assert!(
            sim.tsoffset_s.is_none()
                && sim
                    .comment
                    .contains("seed 1, scenario hash 00000000000000ab")
        );
        let rt = CaptureInfo::real_time(&ringsync_model::Scenario::default(), 1, "udp");
        assert!(
            rt.application.ends_with("real-time runtime (udp)")
                && rt.tsoffset_s > Some(1_700_000_000)
        );
        assert_eq!(b[0].0, 0x0A0D_0D0A);
        assert_eq!(
            b.iter().filter(|(k, _)| *k == 1).count(),
            5,
            "one interface per node"
        );
        assert_eq!(b.iter().filter(|(k, _)| *k == 6).count(), 2);
        // The second packet: interface 2, timestamp split in two words, padded Ethernet frame.
        let last = &file[file.len() - b[b.len() - 1].1..];
        assert_eq!(u32::from_le_bytes(last[8..12].try_into().expect("4")), 2);
        let ts = (u64::from(u32::from_le_bytes(last[12..16].try_into().expect("4"))) << 32)
            | u64::from(u32::from_le_bytes(last[16..20].try_into().expect("4")));
        assert_eq!(ts, 1_234_567_890_123);
        assert_eq!(
            u32::from_le_bytes(last[20..24].try_into().expect("4")),
            14 + 108
        );
        assert_eq!(&last[28 + 12..28 + 14], &[0x88, 0xB5]);
    }
}
