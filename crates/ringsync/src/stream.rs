//! A real-time run's bulk results written while it runs: `trace.csv` and the pcapng capture
//! go to their files as the run makes them, so that a run of any length takes the same
//! memory (issue 12: an rt run's memory does not grow with its duration).
//!
//! The loop hands each trace row and each frame to a bounded queue and never waits on it
//! (a `try_send`); a writer thread per file, at normal priority, formats the items with the
//! same code as the in-memory writers ([`push_trace_row`], [`push_pcapng_frame`]) and
//! writes them through a buffer. The files are byte-identical to what [`crate::rt::write_rt`]
//! writes from a kept result. A queue that is full (a disk that stalls for seconds) drops
//! the item and counts it: the run is never held up, and [`ringsync_rt::Streamed`] reports
//! the loss. A write that fails ends its writer; [`Streams::finish`] returns the error.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use ringsync_model::result::{Captured, TraceRow};
use ringsync_model::stream::{CaptureSink, TraceSink};
use ringsync_report::pcap::{pcapng_header, push_pcapng_frame};
use ringsync_report::sim::{TRACE_CSV_HEADER, push_trace_row};
use ringsync_rt::Sinks;

use crate::error::{Error, Result};
use crate::output::OutDir;

/// Trace rows a queue holds: 16 s of a 4-axis ring at 1 ms (80 B a row, 5.2 MB, allocated
/// once).
pub const TRACE_QUEUE_ROWS: usize = 1 << 16;
/// Frames a capture queue holds: 2.6 s of the 4-axis reference ring's 25 frames a cycle
/// (40 B each, 2.6 MB, allocated once; the bytes of the frames in it besides).
pub const CAPTURE_QUEUE_FRAMES: usize = 1 << 16;

/// One bounded queue into a writer thread; what does not fit is dropped and counted.
struct Queue<T> {
    tx: SyncSender<T>,
    dropped: u64,
}

impl<T> std::fmt::Debug for Queue<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Queue")
            .field("dropped", &self.dropped)
            .finish_non_exhaustive()
    }
}

impl<T> Queue<T> {
    fn put(&mut self, item: T) {
        if self.tx.try_send(item).is_err() {
            self.dropped += 1;
        }
    }
}

impl TraceSink for Queue<TraceRow> {
    fn row(&mut self, row: TraceRow) {
        self.put(row);
    }
    fn dropped(&self) -> u64 {
        self.dropped
    }
}

impl CaptureSink for Queue<Captured> {
    fn frame(&mut self, frame: Captured) {
        self.put(frame);
    }
    fn dropped(&self) -> u64 {
        self.dropped
    }
}

/// A file being written by its thread.
#[derive(Debug)]
struct Writer {
    /// The file as the user named it (for errors).
    shown: String,
    handle: JoinHandle<std::io::Result<()>>,
}

/// The writer threads of a run's streamed files; [`Streams::finish`] waits for them once the
/// run is over.
#[derive(Debug, Default)]
pub struct Streams {
    writers: Vec<Writer>,
}

impl Streams {
    /// Waits for every file to be written whole (the run must be over: its sinks dropped).
    /// The first write that failed is the error.
    pub fn finish(self) -> Result<()> {
        let mut first = None;
        for w in self.writers {
            let what = format!("cannot write {}", w.shown);
            let r = match w.handle.join() {
                Ok(r) => r,
                Err(_) => Err(std::io::Error::other("its writer thread panicked")),
            };
            if let Err(e) = r {
                first.get_or_insert(Error::io(what, e));
            }
        }
        first.map_or(Ok(()), Err)
    }
}

/// Starts the writer of `path` (shown as `shown`): `head`, then each item received, put
/// into bytes by `line`, until every sender is gone.
fn spawn<T: Send + 'static>(
    path: PathBuf,
    shown: String,
    capacity: usize,
    head: Vec<u8>,
    mut line: impl FnMut(&mut Vec<u8>, &T) + Send + 'static,
) -> Result<(Queue<T>, Writer)> {
    let file =
        std::fs::File::create(&path).map_err(|e| Error::io(format!("cannot write {shown}"), e))?;
    let (tx, rx): (SyncSender<T>, Receiver<T>) = sync_channel(capacity);
    let handle = std::thread::Builder::new()
        .name("ringsync-writer".into())
        .spawn(move || {
            let mut w = std::io::BufWriter::with_capacity(1 << 16, file);
            w.write_all(&head)?;
            let mut buf = Vec::with_capacity(256);
            for item in rx {
                buf.clear();
                line(&mut buf, &item);
                w.write_all(&buf)?;
            }
            w.flush()
        })
        .map_err(|e| Error::io(format!("cannot start the writer of {shown}"), e))?;
    let queue = Queue { tx, dropped: 0 };
    Ok((queue, Writer { shown, handle }))
}

/// Opens the streamed files of a real-time run of `axes` axes into `dir`: `trace.csv` when
/// `trace`, and the capture at `pcap` (inside `dir` or beside it) when given. Hand the sinks
/// to [`ringsync_rt::run_streamed`] (or [`crate::rt::run_rt_streamed`]), then call
/// [`Streams::finish`].
pub fn open(
    dir: &mut OutDir,
    axes: usize,
    trace: bool,
    pcap: Option<&Path>,
    info: &ringsync_report::pcap::CaptureInfo,
) -> Result<(Streams, Sinks)> {
    let mut streams = Streams::default();
    let mut sinks = Sinks::default();
    if trace {
        let (q, w) = spawn(
            dir.stream_path("trace.csv")?,
            "trace.csv".into(),
            TRACE_QUEUE_ROWS,
            TRACE_CSV_HEADER.as_bytes().to_vec(),
            |o, row: &TraceRow| push_trace_row(o, row),
        )?;
        sinks.trace = Some(Box::new(q));
        streams.writers.push(w);
    }
    if let Some(p) = pcap {
        let (q, w) = spawn(
            dir.stream_file(p)?,
            p.display().to_string(),
            CAPTURE_QUEUE_FRAMES,
            pcapng_header(axes, info),
            move |o, f: &Captured| push_pcapng_frame(o, f, axes),
        )?;
        sinks.capture = Some(Box::new(q));
        streams.writers.push(w);
    }
    Ok((streams, sinks))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(k: usize) -> TraceRow {
        TraceRow {
            t: k as f64 * 1e-3,
            axis: k % 4 + 1,
            x_d: 0.25 * k as f64,
            x: 0.125,
            e: 0.25 * k as f64 - 0.125,
            eps: -1e-7,
            u: 0.5,
            sample_time: 1e-4,
            apply_time: f64::NAN,
            clock_error_ns: -3.0,
        }
    }

    /// What a streamed writer puts in trace.csv is what the in-memory writer writes, and
    /// a full queue drops and counts instead of waiting.
    #[test]
    fn a_streamed_trace_is_the_written_one_and_a_full_queue_counts() {
        let dir = std::env::temp_dir().join(format!("ringsync-stream-{}", std::process::id()));
        let mut out = OutDir::create("--out", &dir).expect("out");
        let (streams, mut sinks) = open(
            &mut out,
            4,
            true,
            None,
            &ringsync_report::pcap::CaptureInfo::simulated(&ringsync_model::Scenario::default(), 0),
        )
        .expect("open");
        let mut sink = sinks.trace.take().expect("trace sink");
        let mut want = TRACE_CSV_HEADER.as_bytes().to_vec();
        for k in 0..1_000 {
            sink.row(row(k));
            push_trace_row(&mut want, &row(k));
        }
        assert_eq!(sink.dropped(), 0);
        drop(sink);
        streams.finish().expect("written");
        out.write("summary.json", "{}").expect("marker");
        out.commit().expect("commit");
        let got = std::fs::read(dir.join("trace.csv")).expect("read");
        assert!(got == want, "streamed trace.csv differs");
        let _ = std::fs::remove_dir_all(&dir);

        // A queue of two with nobody reading: the third row is dropped, counted, and the
        // call returns at once.
        let (tx, _rx) = sync_channel::<TraceRow>(2);
        let mut q = Queue { tx, dropped: 0 };
        for k in 0..3 {
            q.row(row(k));
        }
        assert_eq!(TraceSink::dropped(&q), 1);
    }
}
