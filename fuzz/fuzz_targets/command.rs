//! Any bytes into the command frame parser; whatever parses re-emits to itself.
#![no_main]

#[path = "seal.rs"]
#[macro_use]
mod seal;
use ringsync_wire::CommandRepr;

fuzz_raw_and_sealed!(check);

fn check(data: &[u8]) {
    if let Ok(r) = CommandRepr::parse(data) {
        let mut buf = vec![0u8; r.buffer_len()];
        let n = r.emit(&mut buf).expect("a parsed frame re-emits");
        assert_eq!(CommandRepr::parse(&buf[..n]), Ok(r));
    }
}
