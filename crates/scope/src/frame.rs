//! The scope's binary WebSocket frame (docs/scope.md, "The binary frame"): a 32-byte
//! header, then the samples as little-endian `f32` columns (column-major: every row of
//! column 0, then column 1, …), then the nodes' counters as little-endian `u32`.
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | u32 | magic `0x50435352` (`"RSCP"` in memory order) |
//! | 4 | u32 | sequence number of the update (+1 per update the server sends out) |
//! | 8 | u32 | samples dropped so far: the real-time loop found the buffer full |
//! | 12 | u32 | updates this client skipped so far (it read too slowly) |
//! | 16 | u32 | cycle k of the first sample this update covers |
//! | 20 | u32 | cycles this update covers (the next update starts at first + cycles unless samples were dropped) |
//! | 24 | u16 | rows m (samples kept: every `stride`-th of the cycles covered, from the first) |
//! | 26 | u16 | stride (cycles between rows) |
//! | 28 | u16 | columns c |
//! | 30 | u16 | nodes (master first, then slave 1..n) |
//! | 32 | f32 × c·m | the columns |
//! | 32 + 4·c·m | u32 × 5·nodes | per node: frames, rejected, retries, outages, state |

/// The frame's magic number.
pub const MAGIC: u32 = 0x5043_5352;
/// Header length \[bytes\].
pub const HEADER_LEN: usize = 32;
/// Counters per node in the node block: frames, rejected, retries, outages, state.
pub const NODE_FIELDS: usize = 5;

/// A frame's header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Header {
    /// Sequence number of the update.
    pub seq: u32,
    /// Samples dropped so far (the buffer was full).
    pub drops: u32,
    /// Updates this client skipped so far.
    pub skipped: u32,
    /// Cycle of the first sample covered.
    pub first: u32,
    /// Cycles covered.
    pub cycles: u32,
    /// Rows kept.
    pub rows: u16,
    /// Cycles between rows.
    pub stride: u16,
    /// Columns.
    pub columns: u16,
    /// Nodes.
    pub nodes: u16,
}

/// Encodes a frame: `header`, the columns `cols` (`header.columns` × `header.rows` values,
/// column-major) and the node block `nodes` (`NODE_FIELDS` × `header.nodes`).
pub fn encode(header: &Header, cols: &[f32], nodes: &[u32]) -> Vec<u8> {
    let mut o = Vec::with_capacity(HEADER_LEN + 4 * (cols.len() + nodes.len()));
    for v in [
        MAGIC,
        header.seq,
        header.drops,
        header.skipped,
        header.first,
        header.cycles,
    ] {
        o.extend_from_slice(&v.to_le_bytes());
    }
    for v in [header.rows, header.stride, header.columns, header.nodes] {
        o.extend_from_slice(&v.to_le_bytes());
    }
    for v in cols {
        o.extend_from_slice(&v.to_le_bytes());
    }
    for v in nodes {
        o.extend_from_slice(&v.to_le_bytes());
    }
    o
}

/// Writes a client's skip count into an encoded frame.
pub fn set_skipped(frame: &mut [u8], skipped: u32) {
    if let Some(b) = frame.get_mut(12..16) {
        b.copy_from_slice(&skipped.to_le_bytes());
    }
}

/// A decoded frame (for tests and tools).
#[derive(Debug, Clone, PartialEq)]
pub struct Decoded {
    /// The header.
    pub header: Header,
    /// Column j, row r at `cols[j * rows + r]`.
    pub cols: Vec<f32>,
    /// Node i's field f at `nodes[i * NODE_FIELDS + f]`.
    pub nodes: Vec<u32>,
}

/// Decodes a frame; `None` when it is not one (wrong magic or length).
pub fn decode(b: &[u8]) -> Option<Decoded> {
    let u32_at =
        |i: usize| -> Option<u32> { Some(u32::from_le_bytes(b.get(i..i + 4)?.try_into().ok()?)) };
    let u16_at =
        |i: usize| -> Option<u16> { Some(u16::from_le_bytes(b.get(i..i + 2)?.try_into().ok()?)) };
    if u32_at(0)? != MAGIC {
        return None;
    }
    let header = Header {
        seq: u32_at(4)?,
        drops: u32_at(8)?,
        skipped: u32_at(12)?,
        first: u32_at(16)?,
        cycles: u32_at(20)?,
        rows: u16_at(24)?,
        stride: u16_at(26)?,
        columns: u16_at(28)?,
        nodes: u16_at(30)?,
    };
    let nc = usize::from(header.columns) * usize::from(header.rows);
    let nn = usize::from(header.nodes) * NODE_FIELDS;
    if b.len() != HEADER_LEN + 4 * (nc + nn) {
        return None;
    }
    let word = |i: usize| -> [u8; 4] {
        let s = HEADER_LEN + 4 * i;
        [b[s], b[s + 1], b[s + 2], b[s + 3]]
    };
    Some(Decoded {
        header,
        cols: (0..nc).map(|i| f32::from_le_bytes(word(i))).collect(),
        nodes: (nc..nc + nn).map(|i| u32::from_le_bytes(word(i))).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_round_trips_and_its_layout_is_as_documented() {
        let h = Header {
            seq: 7,
            drops: 3,
            skipped: 0,
            first: 1000,
            cycles: 17,
            rows: 2,
            stride: 9,
            columns: 3,
            nodes: 2,
        };
        let cols = [1.0, 2.0, -0.5, 0.25, f32::NAN, 6.0];
        let nodes = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10];
        let mut b = encode(&h, &cols, &nodes);
        assert_eq!(b.len(), 32 + 4 * 6 + 4 * 10);
        assert_eq!(&b[0..4], b"RSCP");
        assert_eq!(&b[32..36], &1.0f32.to_le_bytes());
        set_skipped(&mut b, 11);
        let d = decode(&b).expect("decodes");
        assert_eq!(d.header, Header { skipped: 11, ..h });
        assert_eq!(d.cols[..4], cols[..4]);
        assert!(d.cols[4].is_nan());
        assert_eq!(d.nodes, nodes);
        assert!(decode(&b[..b.len() - 1]).is_none());
        b[0] = 0;
        assert!(decode(&b).is_none());
    }
}
