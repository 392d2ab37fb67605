//! The frames a node process sends, kept for the run's capture (`ringsync rt --processes
//! --pcap`): each node writes its own file while it runs, and the launcher merges the
//! files in time order once the nodes are done.
//!
//! **In the node.** [`CapturingPort`] wraps the node's port: every frame sent at the run's
//! time 0 or later goes, with its send instant on the run's clock, to a bounded queue into
//! a writer thread at the normal priority ([`FrameWriter`]). The loop never waits on the
//! queue: a frame that does not fit (a disk that stalls for seconds) is dropped and counted,
//! as the in-process runtime's capture does.
//!
//! **The file.** One record per frame: the send instant [ns, i64], the frame's length
//! [u32] and its bytes, little-endian; records in the order sent, so in time order.
//!
//! **The merge.** [`merge`] reads every node's file at once and hands the frames on in
//! time order (ties in node order), holding one frame per node: its memory does not grow
//! with the run. A file that ends inside a record (its node was killed while writing) ends
//! there.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Write as _};
use std::os::unix::io::RawFd;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{SyncSender, sync_channel};
use std::thread::JoinHandle;

use ringsync_model::result::Captured;

use crate::sys;
use crate::transport::{MAX_PDU, Port};

/// Frames a node's queue holds: 1.6 s of one node's frames on the reference ring at 1 ms
/// (each node sends 5 a cycle; the bytes besides, allocated as they come).
pub const QUEUE_FRAMES: usize = 1 << 13;

/// The name of node `node`'s frame file in a plan's capture directory.
pub fn file_name(node: usize) -> String {
    format!("node-{node}.frames")
}

/// The sending end of a node's frame file (see the module docs): what the port keeps.
#[derive(Debug)]
pub struct FrameTx {
    tx: SyncSender<(i64, Vec<u8>)>,
    dropped: Arc<AtomicU64>,
}

/// The writing end of a node's frame file: its thread.
#[derive(Debug)]
pub struct FrameWriter {
    handle: JoinHandle<io::Result<u64>>,
    dropped: Arc<AtomicU64>,
}

/// Creates `path` and starts its writer: the end to keep frames with, and the writer to
/// finish once every [`FrameTx`] is gone.
pub fn frame_file(path: &Path) -> io::Result<(FrameTx, FrameWriter)> {
    let file = File::create(path)?;
    let (tx, rx) = sync_channel::<(i64, Vec<u8>)>(QUEUE_FRAMES);
    let handle = std::thread::Builder::new()
        .name("ringsync-frames".into())
        .spawn(move || {
            let mut w = BufWriter::with_capacity(1 << 16, file);
            let mut written = 0u64;
            for (t, bytes) in rx {
                let len = u32::try_from(bytes.len()).unwrap_or(u32::MAX);
                w.write_all(&t.to_le_bytes())?;
                w.write_all(&len.to_le_bytes())?;
                w.write_all(&bytes[..len as usize])?;
                written += 1;
            }
            w.flush()?;
            Ok(written)
        })?;
    let dropped = Arc::new(AtomicU64::new(0));
    Ok((
        FrameTx {
            tx,
            dropped: dropped.clone(),
        },
        FrameWriter { handle, dropped },
    ))
}

impl FrameTx {
    /// Keeps a frame sent at `t` [ns, the run's clock], or counts it dropped when the queue
    /// is full.
    pub fn push(&self, t: i64, bytes: &[u8]) {
        if self.tx.try_send((t, bytes.to_vec())).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl FrameWriter {
    /// Waits for the file to be written whole (every [`FrameTx`] dropped): the frames
    /// written and those dropped, or the write's error.
    pub fn finish(self) -> io::Result<(u64, u64)> {
        let written = match self.handle.join() {
            Ok(r) => r?,
            Err(_) => return Err(io::Error::other("the frame writer panicked")),
        };
        Ok((written, self.dropped.load(Ordering::Relaxed)))
    }
}

/// A node's port that keeps every frame it sends from the run's time 0 on (see the module
/// docs).
pub struct CapturingPort {
    inner: Box<dyn Port>,
    file: FrameTx,
    /// The run's time 0 on the host's `CLOCK_MONOTONIC` [ns].
    epoch_ns: i64,
}

impl CapturingPort {
    /// `inner`, its frames sent kept in `file`, on the run whose time 0 is `epoch_ns`.
    pub fn new(inner: Box<dyn Port>, file: FrameTx, epoch_ns: i64) -> Self {
        CapturingPort {
            inner,
            file,
            epoch_ns,
        }
    }

    /// The run's time now [ns]: a frame's send instant, read before it is sent (first bit
    /// out, as the in-process ring stamps it; after the send, a relayed frame could stamp
    /// before the frame it relays).
    fn now(&self) -> i64 {
        sys::now_ns() - self.epoch_ns
    }

    /// Keeps a frame sent at `t` [ns] from the run's time 0 on.
    fn keep(&self, t: i64, pdu: &[u8]) {
        if t >= 0 {
            self.file.push(t, pdu);
        }
    }
}

impl Port for CapturingPort {
    fn send(&mut self, pdu: &[u8]) -> io::Result<()> {
        let t = self.now();
        self.inner.send(pdu)?;
        self.keep(t, pdu);
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        self.inner.recv(buf)
    }

    fn rx_fd(&self) -> RawFd {
        self.inner.rx_fd()
    }

    fn udp_addr(&self) -> Option<std::net::SocketAddr> {
        self.inner.udp_addr()
    }

    fn send_back(&mut self, pdu: &[u8]) -> io::Result<()> {
        let t = self.now();
        self.inner.send_back(pdu)?;
        self.keep(t, pdu);
        Ok(())
    }

    fn recv_back(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        self.inner.recv_back(buf)
    }

    fn back_fd(&self) -> Option<RawFd> {
        self.inner.back_fd()
    }

    fn enable_kernel_stamps(&mut self) -> io::Result<()> {
        self.inner.enable_kernel_stamps()
    }
    fn kernel_stamp(&self) -> Option<i64> {
        self.inner.kernel_stamp()
    }
    fn links_up(&self) -> Option<[bool; 2]> {
        self.inner.links_up()
    }
}

/// One node's file being read.
struct Reader {
    node: usize,
    file: BufReader<File>,
}

impl Reader {
    /// The next record, or None at the end (or inside a record cut short, or at a length
    /// no frame has: the file is not what a node wrote).
    fn next(&mut self) -> io::Result<Option<(i64, Vec<u8>)>> {
        let mut t = [0u8; 8];
        let mut len = [0u8; 4];
        if !fill(&mut self.file, &mut t)? || !fill(&mut self.file, &mut len)? {
            return Ok(None);
        }
        let len = u32::from_le_bytes(len) as usize;
        if len > MAX_PDU {
            return Ok(None);
        }
        let mut bytes = vec![0u8; len];
        if !fill(&mut self.file, &mut bytes)? {
            return Ok(None);
        }
        Ok(Some((i64::from_le_bytes(t), bytes)))
    }
}

/// Fills `buf`: false when the file ends first.
fn fill(r: &mut impl io::Read, buf: &mut [u8]) -> io::Result<bool> {
    match r.read_exact(buf) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => Ok(false),
        Err(e) => Err(e),
    }
}

/// What takes the merged frames, one at a time ([`merge`]).
pub type FrameSink<'a> = dyn FnMut(&Captured) -> io::Result<()> + 'a;

/// Hands every frame of `files` (node, path) to `each` in time order, ties in node order
/// (see the module docs); returns how many. A missing file is a node that sent nothing.
pub fn merge(files: &[(usize, PathBuf)], each: &mut FrameSink<'_>) -> io::Result<u64> {
    let mut readers = Vec::new();
    for (node, path) in files {
        match File::open(path) {
            Ok(f) => readers.push(Reader {
                node: *node,
                file: BufReader::with_capacity(1 << 16, f),
            }),
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(io::Error::new(e.kind(), format!("{}: {e}", path.display()))),
        }
    }
    // The next frame of each reader, by (time, node).
    let mut heads: Vec<Option<Vec<u8>>> = vec![None; readers.len()];
    let mut order = BinaryHeap::new();
    for (r, reader) in readers.iter_mut().enumerate() {
        if let Some((t, bytes)) = reader.next()? {
            heads[r] = Some(bytes);
            order.push(Reverse((t, reader.node, r)));
        }
    }
    let mut count = 0;
    while let Some(Reverse((t, node, r))) = order.pop() {
        if let Some(bytes) = heads[r].take() {
            let frame = Captured { t, node, bytes };
            each(&frame)?;
            count += 1;
        }
        if let Some((t, bytes)) = readers[r].next()? {
            heads[r] = Some(bytes);
            order.push(Reverse((t, node, r)));
        }
    }
    Ok(count)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames written by three nodes come back merged in time order, ties in node order;
    /// a file cut inside a record ends there; a missing file is a node that sent nothing.
    #[test]
    fn node_files_merge_in_time_order() {
        let dir = std::env::temp_dir().join(format!("ringsync-frames-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let sent: [&[(i64, u8)]; 3] = [
            &[(0, 1), (10, 2), (30, 3)],
            &[(5, 4), (10, 5), (31, 6)],
            &[(7, 7), (8, 8)],
        ];
        let mut files = Vec::new();
        for (node, frames) in sent.iter().enumerate() {
            let path = dir.join(format!("node-{node}.frames"));
            let (tx, writer) = frame_file(&path).expect("create");
            for &(t, b) in *frames {
                tx.push(t, &[b; 3]);
            }
            drop(tx);
            assert_eq!(writer.finish().expect("written"), (frames.len() as u64, 0));
            files.push((node, path));
        }
        // Node 2's last record cut short: its frame at 8 is gone, the rest stays.
        let cut = &files[2].1;
        let len = std::fs::metadata(cut).expect("meta").len();
        std::fs::OpenOptions::new()
            .write(true)
            .open(cut)
            .and_then(|f| f.set_len(len - 2))
            .expect("cut");
        files.push((3, dir.join("node-3.frames")));
        let mut got = Vec::new();
        let n = merge(&files, &mut |c| {
            got.push((c.t, c.node, c.bytes[0]));
            Ok(())
        })
        .expect("merge");
        assert_eq!(n, 7);
        assert_eq!(
            got,
            [
                (0, 0, 1),
                (5, 1, 4),
                (7, 2, 7),
                (10, 0, 2),
                (10, 1, 5),
                (30, 0, 3),
                (31, 1, 6)
            ]
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
