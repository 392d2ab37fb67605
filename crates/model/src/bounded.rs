//! Reading files a user names without trusting their size: `/dev/zero`, an endless pipe or
//! a link to either must end in a clear error, not in all of the machine's memory.

use std::io::{self, Read};
use std::path::Path;

/// Reads the regular file at `path` (a link to one too) as UTF-8 text, at most `max`
/// bytes; a longer file, or a device, FIFO or directory, is an
/// [`io::ErrorKind::InvalidData`] error saying so (`what` names the file's role, as in
/// "larger than 64 MiB, the limit for a node plan").
pub fn read_text(path: &Path, max: u64, what: &str) -> io::Result<String> {
    let file = std::fs::File::open(path)?;
    if !file.metadata()?.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("not a regular file, as {what} must be"),
        ));
    }
    let mut bytes = Vec::new();
    file.take(max.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("larger than {}, the limit for {what}", size_text(max)),
        ));
    }
    String::from_utf8(bytes)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "not UTF-8 text"))
}

/// `n` bytes as MiB or GiB when it is a whole number of them.
fn size_text(n: u64) -> String {
    match n {
        n if n >= 1 << 30 && n % (1 << 30) == 0 => format!("{} GiB", n >> 30),
        n if n >= 1 << 20 && n % (1 << 20) == 0 => format!("{} MiB", n >> 20),
        n => format!("{n} bytes"),
    }
}

/// A reader that fails ([`io::ErrorKind::InvalidData`]) once a line grows beyond a limit:
/// for line-based files of any length (a trace), whose lines are short.
#[derive(Debug)]
pub struct LineLimit<R> {
    inner: R,
    max: usize,
    line: usize,
}

impl<R: Read> LineLimit<R> {
    /// `inner`, with lines of at most `max` bytes (the newline not counted).
    pub fn new(inner: R, max: usize) -> Self {
        LineLimit {
            inner,
            max,
            line: 0,
        }
    }
}

impl<R: Read> Read for LineLimit<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        for &b in &buf[..n] {
            if b == b'\n' {
                self.line = 0;
            } else {
                self.line += 1;
                if self.line > self.max {
                    return Err(io::Error::new(
                        io::ErrorKind::InvalidData,
                        format!("a line longer than {} bytes", self.max),
                    ));
                }
            }
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endless_inputs_end_in_an_error() {
        let e = read_text(Path::new("/dev/zero"), 1 << 20, "a test file").expect_err("endless");
        assert_eq!(e.to_string(), "not a regular file, as a test file must be");
        let big = std::env::temp_dir().join(format!("ringsync-bounded-{}", std::process::id()));
        std::fs::write(&big, vec![b'a'; (1 << 20) + 1]).expect("write");
        let e = read_text(&big, 1 << 20, "a test file").expect_err("too long");
        let _ = std::fs::remove_file(&big);
        assert_eq!(
            e.to_string(),
            "larger than 1 MiB, the limit for a test file"
        );
        let mut r = LineLimit::new(io::repeat(b'x'), 1000);
        let e = io::copy(&mut r, &mut io::sink()).expect_err("one endless line");
        assert_eq!(e.to_string(), "a line longer than 1000 bytes");
        // Many short lines pass, however many.
        let lines = io::repeat(b'\n').take(1 << 16).chain(&b"abc\n"[..]);
        let mut text = String::new();
        LineLimit::new(lines, 3)
            .read_to_string(&mut text)
            .expect("short lines");
        assert!(text.ends_with("abc\n"));
    }
}
