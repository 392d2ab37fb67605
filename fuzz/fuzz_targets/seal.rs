//! Shared by the targets: a copy of the input with a correct CRC written where the header's
//! payload length puts it, so that the fuzzer reaches the payload checks behind the CRC.
//! A declared length longer than the input is cut to fit, which keeps buffers small.

pub fn sealed(data: &[u8]) -> Option<Vec<u8>> {
    if data.len() < 16 {
        return None;
    }
    let mut b = data.to_vec();
    let declared = usize::from(u16::from_le_bytes([b[10], b[11]]));
    let len = declared.min(b.len() - 16);
    b[10..12].copy_from_slice(&(len as u16).to_le_bytes());
    let end = 12 + len;
    let crc = ringsync_wire::crc32(&b[..end]);
    b[end..end + 4].copy_from_slice(&crc.to_le_bytes());
    Some(b)
}

/// Defines the fuzz target: `$check` runs on the raw input, then on its sealed copy.
#[allow(unused_macros)] // the ethernet target seals its payload its own way
macro_rules! fuzz_raw_and_sealed {
    ($check:ident) => {
        libfuzzer_sys::fuzz_target!(|raw: &[u8]| {
            $check(raw);
            if let Some(b) = seal::sealed(raw) {
                $check(&b);
            }
        });
    };
}
