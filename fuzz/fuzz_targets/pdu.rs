//! Any bytes into the PDU dispatcher; whatever parses must re-emit to the same PDU.
#![no_main]

#[path = "seal.rs"]
#[macro_use]
mod seal;
use ringsync_wire::Pdu;

fuzz_raw_and_sealed!(check);

fn check(data: &[u8]) {
    if let Ok(pdu) = Pdu::parse(data) {
        let mut buf = vec![0u8; pdu.buffer_len()];
        let n = pdu.emit(&mut buf).expect("a parsed PDU re-emits");
        assert_eq!(Pdu::parse(&buf[..n]).as_ref(), Ok(&pdu));
        // The re-emitted bytes are the input's, up to the PDU length (padding dropped).
        assert_eq!(&buf[..n], &data[..n]);
    }
}
