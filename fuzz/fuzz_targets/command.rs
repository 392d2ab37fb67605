//! Any bytes into the command frame parser and view; whatever parses re-emits to itself and
//! reads the same through the view.
#![no_main]

#[path = "seal.rs"]
#[macro_use]
mod seal;
use ringsync_wire::{CommandPayload, CommandRepr, Frame};

fuzz_raw_and_sealed!(check);

fn check(data: &[u8]) {
    let view = Frame::new_checked(data).ok();
    let view = view.as_ref().and_then(|f| f.command().ok());
    // `let _`: every accessor is read on any bytes only to show that none panics; what
    // they return is checked below against the parser, for frames that parse.
    if let Some(c) = &view {
        let _ = (c.target(), c.command_v(), c.sample_time_ns(), c.check());
    }
    if let Ok(c) = CommandPayload::new_checked(data) {
        let _ = (c.target(), c.command_v(), c.check());
    }
    if let Ok(r) = CommandRepr::parse(data) {
        let c = view.expect("a parsed command has a command view");
        assert_eq!(
            (c.target(), c.command_v(), c.sample_time_ns()),
            (r.target, r.command_v, r.sample_time_ns)
        );
        let mut buf = vec![0u8; r.buffer_len()];
        let n = r.emit(&mut buf).expect("a parsed frame re-emits");
        assert_eq!(CommandRepr::parse(&buf[..n]), Ok(r));
    }
}
