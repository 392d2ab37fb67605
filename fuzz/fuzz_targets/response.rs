//! Any bytes into the response frame parser and view; whatever parses re-emits to itself and
//! reads the same through the view.
#![no_main]

#[path = "seal.rs"]
#[macro_use]
mod seal;
use ringsync_wire::{Frame, ResponsePayload, ResponseRepr};

fuzz_raw_and_sealed!(check);

fn check(data: &[u8]) {
    let frame = Frame::new_checked(data).ok();
    let view = frame.as_ref().and_then(|f| f.response().ok());
    if let Some(r) = &view {
        let _ = (
            r.source(),
            r.status(),
            r.echo_cycle(),
            r.position(),
            r.check(),
        );
        let _ = (
            r.velocity(),
            r.sample_time_ns(),
            r.applied_v(),
            r.status_bits(),
        );
    }
    if let Ok(r) = ResponsePayload::new_checked(data) {
        let _ = (r.source(), r.status(), r.check());
    }
    if let Ok(r) = ResponseRepr::parse(data) {
        let v = view.expect("a parsed response has a response view");
        assert_eq!(
            (v.source(), v.status(), v.echo_cycle()),
            (r.source, r.status, r.echo_cycle)
        );
        assert_eq!((v.position(), v.velocity()), (r.position, r.velocity));
        assert_eq!(
            (v.sample_time_ns(), v.applied_v()),
            (r.sample_time_ns, r.applied_v)
        );
        let mut buf = vec![0u8; r.buffer_len()];
        let n = r.emit(&mut buf).expect("a parsed frame re-emits");
        assert_eq!(ResponseRepr::parse(&buf[..n]), Ok(r));
    }
}
