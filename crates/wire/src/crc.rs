//! CRC-32 of the ringsync PDU (docs/wire.md, "Integrity check").
//!
//! The IEEE 802.3 polynomial, reflected (0xEDB88320), initial value and final XOR
//! 0xFFFF_FFFF: the same CRC as the Ethernet FCS and zlib's `crc32`. veth links and UDP
//! sockets hand the receiver no FCS, so every PDU carries its own.

const POLY: u32 = 0xEDB8_8320;

const fn make_table() -> [u32; 256] {
    let mut table = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { POLY ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
}

static TABLE: [u32; 256] = make_table();

/// CRC-32 (IEEE 802.3, reflected) of `data`.
pub fn crc32(data: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in data {
        c = TABLE[((c ^ b as u32) & 0xFF) as usize] ^ (c >> 8);
    }
    c ^ 0xFFFF_FFFF
}

#[cfg(test)]
mod tests {
    use super::crc32;

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
}
