//! Any bytes into the PDU dispatcher; whatever parses must re-emit to the same PDU. The frame
//! view's routing, validation and text form run on every input and agree with the parser.
#![no_main]

#[path = "seal.rs"]
#[macro_use]
mod seal;
use ringsync_wire::{Frame, Pdu};

fuzz_raw_and_sealed!(check);

fn check(data: &[u8]) {
    let parsed = Pdu::parse(data);
    if let Ok(frame) = Frame::new_checked(data) {
        let _ = (frame.route(), frame.kind(), frame.common());
        assert_eq!(
            frame.validate(),
            parsed.as_ref().map(Pdu::kind).map_err(|e| *e)
        );
        let line = frame.to_string();
        if let Ok(pdu) = &parsed {
            assert_eq!(line, pdu.to_string());
            assert_eq!(frame.route().map(|r| r.kind()), Ok(pdu.kind()));
        }
    }
    if let Ok(pdu) = parsed {
        let mut buf = vec![0u8; pdu.buffer_len()];
        let n = pdu.emit(&mut buf).expect("a parsed PDU re-emits");
        assert_eq!(Pdu::parse(&buf[..n]).as_ref(), Ok(&pdu));
        // The re-emitted bytes are the input's, up to the PDU length (padding dropped).
        assert_eq!(&buf[..n], &data[..n]);
    }
}
