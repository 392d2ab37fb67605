//! ringsync's live web scope (docs/scope.md): while a ring runs (`ringsync rt --scope
//! ADDR`) or a simulation is replayed (`ringsync sim --scope ADDR --speed X`), a page at
//! `/` plots every axis's position error, sync error and command, the clock errors, the
//! cycle-start lateness with its histogram, each node's counters and state on a drawing of
//! the ring and the monitors' status per axis; it pauses, zooms and exports what it holds.
//!
//! Three parts, so that nothing the scope does can hold up the ring:
//!
//! 1. the [`ScopeObserver`] runs in the ring's driver (the real-time
//!    loop) and hands one fixed-size row per cycle to a bounded channel with `try_send`:
//!    a full channel drops the row and counts it, the loop never waits;
//! 2. a pump task drains the channel at most 60 times a second, keeps at most
//!    [`MAX_ROWS`] rows per update (every `stride`-th), encodes one
//!    [binary frame](frame) and hands it to a broadcast channel;
//! 3. one task per WebSocket client (`/ws`) sends what the broadcast channel holds; a
//!    client that reads too slowly falls behind the channel's [`BACKLOG`] updates and
//!    skips them (counted in its frames' header), without slowing anyone else.
//!
//! The server (axum 0.8 + tokio, current-thread runtime) runs on a thread of its own.
//! Control messages (the `hello` at connection, monitor and fault `event`s, the `end` of
//! the run) are JSON text frames; samples only travel in binary frames.

#![forbid(unsafe_code)]

pub mod ab;
pub mod frame;
pub mod probe;
mod server;

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ringsync::Scenario;
use serde_json::{Value, json};

pub use probe::ScopeObserver;

/// Most updates per second a client gets.
pub const MAX_UPDATES_PER_S: u32 = 60;
/// Most rows per update (a faster replay is thinned to every `stride`-th cycle).
pub const MAX_ROWS: usize = 64;
/// Most pages streamed at once; one more is answered 503 rather than each costing the
/// server memory and a share of its one thread.
pub const MAX_CLIENTS: usize = 64;
/// Updates the broadcast channel holds for a slow client before it skips.
pub const BACKLOG: usize = 16;
/// Frames a page that connects late gets first: 10 s of updates.
pub const HISTORY_FRAMES: usize = 600;
/// Events (monitor, fault) a page that connects late gets first, at most.
pub const HISTORY_EVENTS: usize = 2000;

/// What can stop the scope from starting.
#[derive(Debug, thiserror::Error)]
pub enum ScopeError {
    /// The address could not be bound.
    #[error("--scope {addr}: cannot listen there: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The server's runtime or thread could not start.
    #[error("the scope's server could not start: {0}")]
    Start(std::io::Error),
}

/// Where the samples come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Source {
    /// A real-time run (`ringsync rt`).
    Realtime,
    /// A replay of the simulator at this multiple of real speed.
    Replay {
        /// Multiple of real speed.
        speed: f64,
    },
}

/// State the server's tasks share with the [`Scope`] handle.
#[derive(Debug, Default)]
pub(crate) struct Shared {
    /// The `hello` JSON.
    pub hello: String,
    /// Clients connected now.
    pub clients: AtomicUsize,
    /// Clients that ever connected.
    pub connected: AtomicU64,
    /// Updates sent out.
    pub updates: AtomicU64,
    /// The `end` JSON, once the run ended.
    pub end: std::sync::Mutex<Option<String>>,
    /// Raised by the pump once it sent the last rows and the `end`.
    pub done: AtomicBool,
    /// What a page that connects late gets first: the last [`HISTORY_FRAMES`] frames and
    /// every event (up to [`HISTORY_EVENTS`]), in the order they went out. The pump adds to
    /// it and broadcasts under its lock, and a client subscribes under it, so a new page
    /// misses nothing and gets nothing twice.
    pub history: std::sync::Mutex<server::History>,
}

/// A running scope server (see the crate docs). Dropping it stops the server.
#[derive(Debug)]
pub struct Scope {
    addr: SocketAddr,
    shared: Arc<Shared>,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
    drops: Arc<AtomicU64>,
}

/// The `hello` message: what the page needs to read the frames.
pub fn hello(s: &Scenario, source: Source, columns: usize) -> Value {
    let n = s.axes_count().min(probe::MAX_AXES);
    let mut names = vec!["t_s".to_string(), "lateness_us".to_string()];
    for i in 1..=n {
        for c in [
            "e_rad",
            "eps_rad",
            "xd_rad",
            "u_V",
            "clock_error_ns",
            "status",
        ] {
            names.push(format!("axis{i}.{c}"));
        }
    }
    debug_assert_eq!(names.len(), columns);
    let m = s.monitor_settings();
    let limits = |l: &ringsync::layers::model::monitor::Limits| {
        json!({"warn_rad": &l.warn[..n], "trip_rad": &l.trip[..n],
               "filter_s": l.filter.as_ns() as f64 * 1e-9, "reaction": l.reaction.name()})
    };
    json!({
        "type": "hello",
        "version": 1,
        "source": match source { Source::Realtime => "rt", Source::Replay { .. } => "sim" },
        "speed": match source { Source::Realtime => 1.0, Source::Replay { speed } => speed },
        "scenario": s.name,
        "axes": s.axes_count(),
        "shown_axes": n,
        "cycle_s": s.ring.cycle.secs(),
        "duration_s": s.duration.secs(),
        "controller": s.law_name(),
        "following_error_limit_rad": s.faults.following_error_limit,
        "columns": names,
        "node_fields": ["frames", "rejected", "retries", "outages", "state"],
        "node_states": probe::node_state::NAMES,
        "status_bits": {"in_sync": probe::status::IN_SYNC, "sync_warning": probe::status::SYNC_WARNING,
            "sync_trip": probe::status::SYNC_TRIP, "following_warning": probe::status::FOLLOWING_WARNING,
            "following_trip": probe::status::FOLLOWING_TRIP, "stopping": probe::status::STOPPING,
            "torque_off": probe::status::TORQUE_OFF, "braking": probe::status::BRAKING,
            "watchdog": probe::status::WATCHDOG},
        "monitor": {"sync": limits(&m.sync), "following": limits(&m.following)},
        "max_updates_per_s": MAX_UPDATES_PER_S,
        "machine": machine_json(s, n),
    })
}

/// A part program's machine, for the page's XY panel: each machine axis's letter and its
/// drives as (0-based axis, transmission [rad/mm]); `null` without a program, or when a
/// drive is beyond the axes the page is sent.
fn machine_json(s: &Scenario, shown: usize) -> Value {
    let Ok(Some(m)) = s.machine_map() else {
        return Value::Null;
    };
    if m.axes
        .iter()
        .flat_map(|a| &a.drives)
        .any(|(i, _)| *i >= shown)
    {
        return Value::Null;
    }
    json!({
        "axes": m.axes.iter().map(|a| json!({
            "name": a.name.to_string(),
            "drives": a.drives.iter().map(|(i, k)| json!([i, k])).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "program": match &s.trajectory {
            ringsync::layers::model::scenario::TrajectorySpec::Program { program } => program.clone(),
            _ => String::new(),
        },
    })
}

impl Scope {
    /// Serves the scope of scenario `s`'s ring at `addr` (port 0: any free port, see
    /// [`Scope::addr`]), and returns the observer to add to the run. `pace` replays at
    /// that multiple of real speed (the simulator); `None` for a real-time run.
    pub fn start(
        addr: SocketAddr,
        s: &Scenario,
        source: Source,
    ) -> Result<(Scope, ScopeObserver), ScopeError> {
        let pace = match source {
            Source::Realtime => None,
            Source::Replay { speed } => Some(speed),
        };
        let (observer, feed) = ScopeObserver::new(s.axes_count(), probe::CAPACITY, pace);
        let listener = std::net::TcpListener::bind(addr)
            .map_err(|source| ScopeError::Bind { addr, source })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| ScopeError::Bind { addr, source })?;
        let bound = listener
            .local_addr()
            .map_err(|source| ScopeError::Bind { addr, source })?;
        let shared = Arc::new(Shared {
            hello: hello(s, source, observer.columns()).to_string(),
            ..Shared::default()
        });
        let (tx, rx) = tokio::sync::oneshot::channel();
        let drops = feed.drops.clone();
        let n = s.axes_count().min(probe::MAX_AXES);
        let sh = shared.clone();
        let columns = observer.columns();
        let thread = std::thread::Builder::new()
            .name("ringsync-scope".into())
            .spawn(move || server::run(listener, sh, feed, n, columns, rx))
            .map_err(ScopeError::Start)?;
        Ok((
            Scope {
                addr: bound,
                shared,
                shutdown: Some(tx),
                thread: Some(thread),
                drops,
            },
            observer,
        ))
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.shared.clients.load(Ordering::SeqCst)
    }

    /// Rows the real-time side dropped so far (the buffer was full).
    pub fn drops(&self) -> u64 {
        self.drops.load(Ordering::Relaxed)
    }

    /// Updates sent out so far.
    pub fn updates(&self) -> u64 {
        self.shared.updates.load(Ordering::SeqCst)
    }

    /// Waits up to `timeout` for a first client; whether one came.
    pub fn wait_for_client(&self, timeout: Duration) -> bool {
        let end = Instant::now() + timeout;
        while self.shared.connected.load(Ordering::SeqCst) == 0 {
            if Instant::now() >= end {
                return false;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        true
    }

    /// The run ended (its observer is gone): sends the last rows and `end` (a JSON object,
    /// sent with `"type": "end"` added), gives the clients up to `linger` to read them,
    /// and stops the server.
    pub fn finish(mut self, end: Value, linger: Duration) {
        let mut end = end;
        if let Value::Object(o) = &mut end {
            o.insert("type".into(), json!("end"));
            o.insert("drops".into(), json!(self.drops()));
        }
        if let Ok(mut e) = self.shared.end.lock() {
            *e = Some(end.to_string());
        }
        let deadline = Instant::now() + linger;
        while Instant::now() < deadline
            && (!self.shared.done.load(Ordering::SeqCst) || self.clients() > 0)
        {
            std::thread::sleep(Duration::from_millis(10));
        }
        self.stop();
    }

    fn stop(&mut self) {
        if let Some(tx) = self.shutdown.take() {
            let _ = tx.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Scope {
    fn drop(&mut self) {
        self.stop();
    }
}

#[cfg(test)]
mod palette_tests {
    /// The page colours axis i as the reports do (issue 41: axes 2 and 4 swapped colours
    /// between the scope and the reports).
    #[test]
    fn the_page_colours_the_axes_as_the_reports_do() {
        let js = include_str!("../assets/scope.js");
        let start = js.find("const COLORS = [").expect("the page's palette") + 16;
        let end = start + js[start..].find(']').expect("its end");
        let page: Vec<&str> = js[start..end]
            .split(',')
            .map(|c| c.trim().trim_matches('"'))
            .filter(|c| !c.is_empty())
            .collect();
        let report = ringsync::layers::report::plot::PALETTE;
        assert_eq!(&page[..report.len()], &report[..]);
    }
}
