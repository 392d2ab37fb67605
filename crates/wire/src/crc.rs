//! CRC-32 of the ringsync PDU (docs/wire.md, "Integrity check").
//!
//! The IEEE 802.3 polynomial, reflected (0xEDB88320), initial value and final XOR
//! 0xFFFF_FFFF: the same CRC as the Ethernet FCS and zlib's `crc32`. veth links and UDP
//! sockets hand the receiver no FCS, so every PDU carries its own.
//!
//! Frames of 64 bytes and more (lumped frames) go to `crc32fast`, which folds 16 bytes at a
//! time with carry-less multiplication where the CPU has it: 171 instructions for a 96-byte
//! frame against 308 by table. Shorter ones (commands, responses) are computed here
//! slicing-by-8 (eight 256-entry tables, eight bytes per step), which is the faster of the
//! two below 64 bytes (124 against 137 instructions at 32 bytes; callgrind, docs/benchmarks.md).
//! The bitwise definition is kept for the tests.

const POLY: u32 = 0xEDB8_8320;

const fn make_tables() -> [[u32; 256]; 8] {
    let mut t = [[0u32; 256]; 8];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { POLY ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        t[0][i] = c;
        i += 1;
    }
    let mut s = 1;
    while s < 8 {
        let mut i = 0;
        while i < 256 {
            let prev = t[s - 1][i];
            t[s][i] = (prev >> 8) ^ t[0][(prev & 0xFF) as usize];
            i += 1;
        }
        s += 1;
    }
    t
}

static TABLES: [[u32; 256]; 8] = make_tables();

/// Frames at least this long go to `crc32fast` [bytes].
const FOLD_FROM: usize = 64;

/// CRC-32 (IEEE 802.3, reflected) of `data`.
pub fn crc32(data: &[u8]) -> u32 {
    if data.len() >= FOLD_FROM {
        crc32fast::hash(data)
    } else {
        by_table(data)
    }
}

/// CRC-32 slicing-by-8.
fn by_table(data: &[u8]) -> u32 {
    let t = &TABLES;
    let mut c = 0xFFFF_FFFFu32;
    let mut chunks = data.chunks_exact(8);
    for ch in &mut chunks {
        let lo = c ^ u32::from_le_bytes([ch[0], ch[1], ch[2], ch[3]]);
        c = t[7][(lo & 0xFF) as usize]
            ^ t[6][((lo >> 8) & 0xFF) as usize]
            ^ t[5][((lo >> 16) & 0xFF) as usize]
            ^ t[4][(lo >> 24) as usize]
            ^ t[3][ch[4] as usize]
            ^ t[2][ch[5] as usize]
            ^ t[1][ch[6] as usize]
            ^ t[0][ch[7] as usize];
    }
    for &b in chunks.remainder() {
        c = t[0][((c ^ u32::from(b)) & 0xFF) as usize] ^ (c >> 8);
    }
    c ^ 0xFFFF_FFFF
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bitwise CRC-32, straight from the definition: the reference for the fast one.
    fn bitwise(data: &[u8]) -> u32 {
        let mut c = 0xFFFF_FFFFu32;
        for &b in data {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 { POLY ^ (c >> 1) } else { c >> 1 };
            }
        }
        c ^ 0xFFFF_FFFF
    }

    #[test]
    fn standard_check_value() {
        // The catalogued check value of CRC-32/ISO-HDLC.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn empty_and_zeros() {
        assert_eq!(crc32(b""), 0);
        // zlib.crc32(bytes(4)) in Python.
        assert_eq!(crc32(&[0, 0, 0, 0]), 0x2144_DF1C);
    }

    #[test]
    fn both_paths_equal_bitwise_for_every_length() {
        let data: [u8; 300] = core::array::from_fn(|i| (i as u8).wrapping_mul(37).wrapping_add(11));
        for len in 0..=data.len() {
            let want = bitwise(&data[..len]);
            assert_eq!(crc32(&data[..len]), want, "length {len}");
            assert_eq!(by_table(&data[..len]), want, "table, length {len}");
        }
    }
}
