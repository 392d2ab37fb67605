//! Raw Ethernet frames as AF_PACKET hands them over: MAC header, then maybe a PDU.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ringsync_wire::{EthernetFrame, Pdu};

#[path = "seal.rs"]
mod seal;

fuzz_target!(|raw: &[u8]| {
    check(raw);
    if raw.len() > 14 {
        if let Some(pdu) = seal::sealed(&raw[14..]) {
            let mut b = raw[..14].to_vec();
            b.extend_from_slice(&pdu);
            check(&b);
        }
    }
});

fn check(data: &[u8]) {
    if let Ok(eth) = EthernetFrame::new_checked(data) {
        // `let _`: read on any bytes only to show that no accessor or parser panics.
        let _ = (eth.dst(), eth.src(), eth.ethertype());
        if let Ok(payload) = eth.ringsync_payload() {
            let _ = Pdu::parse(payload);
        }
        if let Ok(pdu) = eth.ringsync_pdu() {
            // Padding stripped, the PDU parses as it did with the padding.
            let padded = eth.ringsync_payload().map(Pdu::parse).ok();
            assert_eq!(Some(Pdu::parse(pdu)), padded);
        }
    }
}
