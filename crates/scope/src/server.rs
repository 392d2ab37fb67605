//! The server: the page and its assets, the WebSocket stream, and the pump that turns the
//! observer's rows into at most 60 updates per second (crate docs).

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::sync::mpsc::TryRecvError;
use std::time::Duration;

use axum::Router;
use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::json;
use tokio::sync::{broadcast, oneshot};

use crate::frame::{self, Header, NODE_FIELDS};
use crate::probe::{Event, Feed, Row};
use crate::{BACKLOG, MAX_CLIENTS, MAX_ROWS, MAX_UPDATES_PER_S, Shared};

/// Send buffer of each client's socket [bytes] (the kernel doubles it): about 0.3 s of a
/// 1 ms ring of 4 axes.
const SEND_BUFFER: usize = 16 * 1024;

/// Longest a page's message (or frame) may be [bytes]: the scope reads nothing from a page
/// but `{"type":"hello"}`, so a client sending more holds no more of the server's memory.
const MAX_CLIENT_MESSAGE: usize = 4096;

/// How long the server waits, once stopped, for open connections to finish: a client that
/// never completes its request must not hold the run's end (and its results) hostage.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(1);

/// Longest time a connection may take to send a request's headers [s]; then it is closed
/// (a client that opens connections and never finishes a request would otherwise hold a
/// descriptor each for the whole run).
const HEADER_TIMEOUT: Duration = Duration::from_secs(5);

/// Longest a write to a client may wait for the client to read [s]; then its connection is
/// closed (a client that sends a request and never reads the answer, or a page that stops
/// reading its stream, would otherwise hold its connection, and its place among the
/// [`MAX_CLIENTS`] pages, until the run ends).
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);

const INDEX: &str = include_str!("../assets/index.html");
const SCRIPT: &str = include_str!("../assets/scope.js");
const UPLOT_JS: &str = include_str!("../assets/uPlot.iife.min.js");
const UPLOT_CSS: &str = include_str!("../assets/uPlot.min.css");
const UPLOT_LICENSE: &str = include_str!("../assets/uPlot-LICENSE");

/// What goes out to every client.
#[derive(Debug)]
pub(crate) enum Update {
    Frame(Vec<u8>),
    Text(String),
}

/// The updates a late page gets first (see `Shared::history`).
#[derive(Debug, Default)]
pub(crate) struct History {
    updates: std::collections::VecDeque<Arc<Update>>,
    frames: usize,
    events: usize,
}

impl History {
    fn push(&mut self, u: Arc<Update>) {
        match *u {
            Update::Frame(_) => self.frames += 1,
            Update::Text(_) => self.events += 1,
        }
        self.updates.push_back(u);
        let frames = self.frames > crate::HISTORY_FRAMES;
        let events = self.events > crate::HISTORY_EVENTS;
        if frames || events {
            let drop_frame = frames;
            if let Some(i) = self
                .updates
                .iter()
                .position(|u| matches!(**u, Update::Frame(_)) == drop_frame)
            {
                self.updates.remove(i);
                if drop_frame {
                    self.frames -= 1;
                } else {
                    self.events -= 1;
                }
            }
        }
    }
}

/// Adds `u` to the history and sends it to every client, under the history's lock.
fn publish(shared: &Shared, tx: &broadcast::Sender<Arc<Update>>, u: Update) {
    let u = Arc::new(u);
    if let Ok(mut h) = shared.history.lock() {
        h.push(u.clone());
        let _ = tx.send(u);
    }
}

#[derive(Clone)]
struct App {
    shared: Arc<Shared>,
    /// Weak, so that the pump's drop of the sender at the end closes every stream.
    tx: broadcast::WeakSender<Arc<Update>>,
}

fn asset(kind: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, kind),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

/// Runs the server on this thread until `stop` fires.
pub(crate) fn run(
    listener: std::net::TcpListener,
    shared: Arc<Shared>,
    feed: Feed,
    n: usize,
    columns: usize,
    stop: oneshot::Receiver<()>,
) {
    let Ok(rt) = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    else {
        return;
    };
    rt.block_on(async move {
        let Ok(listener) = tokio::net::TcpListener::from_std(listener) else {
            return;
        };
        let (tx, _) = broadcast::channel(BACKLOG);
        let app = App {
            shared: shared.clone(),
            tx: tx.downgrade(),
        };
        tokio::spawn(pump(feed, tx, shared, n, columns));
        let router = Router::new()
            .route(
                "/",
                get(|| async { asset("text/html; charset=utf-8", INDEX) }),
            )
            .route(
                "/scope.js",
                get(|| async { asset("text/javascript; charset=utf-8", SCRIPT) }),
            )
            .route(
                "/uPlot.iife.min.js",
                get(|| async { asset("text/javascript; charset=utf-8", UPLOT_JS) }),
            )
            .route(
                "/uPlot.min.css",
                get(|| async { asset("text/css; charset=utf-8", UPLOT_CSS) }),
            )
            .route(
                "/uPlot-LICENSE",
                get(|| async { asset("text/plain; charset=utf-8", UPLOT_LICENSE) }),
            )
            .route("/ws", get(ws))
            .with_state(app);
        serve(listener, router, stop).await;
    });
}

/// Serves `router` on `listener` until `stop`: HTTP/1.1 with upgrades (the WebSocket), a
/// request's headers within [`HEADER_TIMEOUT`]. Once stopped, connections get
/// [`SHUTDOWN_GRACE`] to finish; then the runtime, dropped, closes what is left.
async fn serve(listener: tokio::net::TcpListener, router: Router, stop: oneshot::Receiver<()>) {
    use hyper::server::conn::http1;
    use hyper_util::rt::{TokioIo, TokioTimer};
    use hyper_util::service::TowerToHyperService;

    let (closing_tx, closing) = tokio::sync::watch::channel(false);
    let mut conns = tokio::task::JoinSet::new();
    let mut stop = std::pin::pin!(stop);
    loop {
        let tcp = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((tcp, _)) => tcp,
                // Out of descriptors, say: wait a little rather than spin.
                Err(_) => {
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            Some(_) = conns.join_next(), if !conns.is_empty() => continue,
            _ = &mut stop => break,
        };
        // A small send buffer per client: a client that stops reading blocks its own task
        // after ~SEND_BUFFER bytes and then skips updates, rather than the kernel holding
        // seconds of stale frames for it.
        let _ = tcp.set_nodelay(true);
        let _ = socket2::SockRef::from(&tcp).set_send_buffer_size(SEND_BUFFER);
        let service = TowerToHyperService::new(router.clone());
        let mut closing = closing.clone();
        conns.spawn(async move {
            let conn = http1::Builder::new()
                .timer(TokioTimer::new())
                .header_read_timeout(HEADER_TIMEOUT)
                .serve_connection(TokioIo::new(WriteLimit::new(tcp, WRITE_TIMEOUT)), service)
                .with_upgrades();
            let mut conn = std::pin::pin!(conn);
            tokio::select! {
                _ = conn.as_mut() => return,
                _ = closing.wait_for(|c| *c) => conn.as_mut().graceful_shutdown(),
            }
            let _ = conn.await;
        });
    }
    let _ = closing_tx.send(true);
    let _ = tokio::time::timeout(SHUTDOWN_GRACE, async {
        while conns.join_next().await.is_some() {}
    })
    .await;
}

/// A connection whose writes fail ([`std::io::ErrorKind::TimedOut`]) once one has waited
/// `limit` for the peer to read: HTTP answers and, after the upgrade, the WebSocket stream
/// alike (hyper hands the upgraded stream this same connection).
struct WriteLimit<T> {
    io: T,
    limit: Duration,
    /// Since when a write has been waiting, as the timer that ends the wait.
    waiting: Option<std::pin::Pin<Box<tokio::time::Sleep>>>,
}

impl<T> WriteLimit<T> {
    fn new(io: T, limit: Duration) -> Self {
        WriteLimit {
            io,
            limit,
            waiting: None,
        }
    }

    /// What a write that made progress (`Ready`) or must wait (`Pending`) returns.
    fn after<R>(
        &mut self,
        cx: &mut std::task::Context<'_>,
        done: std::task::Poll<std::io::Result<R>>,
    ) -> std::task::Poll<std::io::Result<R>> {
        use std::future::Future as _;
        use std::task::Poll;
        if done.is_ready() {
            self.waiting = None;
            return done;
        }
        let limit = self.limit;
        let timer = self
            .waiting
            .get_or_insert_with(|| Box::pin(tokio::time::sleep(limit)));
        match timer.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                "the client has not read for the write time limit",
            ))),
            Poll::Pending => Poll::Pending,
        }
    }
}

impl<T: tokio::io::AsyncRead + Unpin> tokio::io::AsyncRead for WriteLimit<T> {
    fn poll_read(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &mut tokio::io::ReadBuf<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        std::pin::Pin::new(&mut self.io).poll_read(cx, buf)
    }
}

impl<T: tokio::io::AsyncWrite + Unpin> tokio::io::AsyncWrite for WriteLimit<T> {
    fn poll_write(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &[u8],
    ) -> std::task::Poll<std::io::Result<usize>> {
        let done = std::pin::Pin::new(&mut self.io).poll_write(cx, buf);
        self.after(cx, done)
    }

    fn poll_write_vectored(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> std::task::Poll<std::io::Result<usize>> {
        let done = std::pin::Pin::new(&mut self.io).poll_write_vectored(cx, bufs);
        self.after(cx, done)
    }

    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }

    fn poll_flush(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        let done = std::pin::Pin::new(&mut self.io).poll_flush(cx);
        self.after(cx, done)
    }

    fn poll_shutdown(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        let done = std::pin::Pin::new(&mut self.io).poll_shutdown(cx);
        self.after(cx, done)
    }
}

async fn ws(State(app): State<App>, upgrade: WebSocketUpgrade) -> Response {
    if app.shared.clients.load(Ordering::SeqCst) >= MAX_CLIENTS {
        return (
            axum::http::StatusCode::SERVICE_UNAVAILABLE,
            format!("the scope streams to at most {MAX_CLIENTS} pages at once\n"),
        )
            .into_response();
    }
    upgrade
        .max_message_size(MAX_CLIENT_MESSAGE)
        .max_frame_size(MAX_CLIENT_MESSAGE)
        .on_upgrade(move |socket| client(socket, app))
}

/// One client: the `hello`, then every update it keeps up with; updates it fell behind on
/// are skipped and counted in its frames' header.
async fn client(mut socket: WebSocket, app: App) {
    // The history and the subscription under one lock: nothing missed, nothing twice.
    let subscribed = app.tx.upgrade().and_then(|t| {
        let h = app.shared.history.lock().ok()?;
        Some((h.updates.iter().cloned().collect::<Vec<_>>(), t.subscribe()))
    });
    let Some((backlog, mut rx)) = subscribed else {
        // The run has ended: the hello and what the history holds (the end last).
        let backlog: Vec<Arc<Update>> = match app.shared.history.lock() {
            Ok(h) => h.updates.iter().cloned().collect(),
            Err(_) => Vec::new(),
        };
        let _ = socket
            .send(Message::Text(app.shared.hello.clone().into()))
            .await;
        for u in backlog {
            if socket.send(message(&u, 0)).await.is_err() {
                break;
            }
        }
        let _ = socket.send(Message::Close(None)).await;
        return;
    };
    app.shared.clients.fetch_add(1, Ordering::SeqCst);
    app.shared.connected.fetch_add(1, Ordering::SeqCst);
    let mut skipped: u32 = 0;
    let hello = app.shared.hello.clone();
    let mut ok = socket.send(Message::Text(hello.into())).await.is_ok();
    for u in backlog {
        if !ok {
            break;
        }
        ok = socket.send(message(&u, 0)).await.is_ok();
    }
    if ok {
        loop {
            tokio::select! {
                u = rx.recv() => match u {
                    Ok(u) => {
                        if socket.send(message(&u, skipped)).await.is_err() {
                            break;
                        }
                    }
                    Err(broadcast::error::RecvError::Lagged(k)) => {
                        skipped = skipped.saturating_add(u32::try_from(k).unwrap_or(u32::MAX));
                    }
                    Err(broadcast::error::RecvError::Closed) => {
                        let _ = socket.send(Message::Close(None)).await;
                        break;
                    }
                },
                m = socket.recv() => match m {
                    None | Some(Err(_)) | Some(Ok(Message::Close(_))) => break,
                    Some(Ok(Message::Text(t))) if t.as_str().contains("\"hello\"") => {
                        let hello = app.shared.hello.clone();
                        if socket.send(Message::Text(hello.into())).await.is_err() {
                            break;
                        }
                    }
                    _ => {}
                },
            }
        }
    }
    app.shared.clients.fetch_sub(1, Ordering::SeqCst);
}

/// An update as a WebSocket message, with this client's skip count in a frame's header.
fn message(u: &Update, skipped: u32) -> Message {
    match u {
        Update::Frame(b) => {
            let mut b = b.clone();
            frame::set_skipped(&mut b, skipped);
            Message::Binary(b.into())
        }
        Update::Text(t) => Message::Text(t.clone().into()),
    }
}

fn event_json(e: &Event) -> String {
    match e {
        Event::Monitor(m) => json!({
            "type": "event", "kind": "monitor", "time_s": m.t, "axis": m.axis,
            "monitor": m.kind.monitor(), "level": m.kind.level(),
            "change": if m.raised { "raised" } else { "cleared" }, "value_rad": m.value,
        }),
        Event::Fault(f) => json!({
            "type": "event", "kind": "fault", "time_s": f.t, "axis": f.axis,
            "step": f.step.name(), "detail": f.step.detail(),
        }),
        Event::Ring(c) => json!({
            "type": "event", "kind": "ring", "time_s": c.t, "cycle": c.k,
            "from": c.from.describe(), "to": c.to.describe(),
            "broken_link": match c.to {
                ringsync::layers::proto::node::RingState::Broken { link } => Some(link),
                ringsync::layers::proto::node::RingState::Whole => None,
            },
        }),
    }
    .to_string()
}

/// Drains the observer's rows at most [`MAX_UPDATES_PER_S`] times a second into one
/// frame each, and its events into JSON; at the end, the `end`.
async fn pump(
    feed: Feed,
    tx: broadcast::Sender<Arc<Update>>,
    shared: Arc<Shared>,
    n: usize,
    columns: usize,
) {
    let mut tick = tokio::time::interval(Duration::from_secs(1) / MAX_UPDATES_PER_S);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut rows: Vec<Row> = Vec::with_capacity(crate::probe::CAPACITY);
    let mut seq: u32 = 0;
    let nodes = n + 1;
    loop {
        tick.tick().await;
        let mut ended = false;
        loop {
            match feed.rows.try_recv() {
                Ok(r) => rows.push(r),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    ended = true;
                    break;
                }
            }
        }
        for e in feed.events.try_iter() {
            publish(&shared, &tx, Update::Text(event_json(&e)));
        }
        if !rows.is_empty() {
            let stride = rows.len().div_ceil(MAX_ROWS).max(1);
            let kept: Vec<&Row> = rows.iter().step_by(stride).collect();
            let m = kept.len();
            let mut cols = vec![0f32; columns * m];
            for (r, row) in kept.iter().enumerate() {
                for c in 0..columns {
                    cols[c * m + r] = row.cols[c];
                }
            }
            let last = rows[rows.len() - 1];
            let header = Header {
                seq,
                drops: u32::try_from(feed.drops.load(Ordering::Relaxed)).unwrap_or(u32::MAX),
                skipped: 0,
                first: u32::try_from(rows[0].k).unwrap_or(0),
                cycles: u32::try_from(last.k - rows[0].k + 1).unwrap_or(0),
                rows: u16::try_from(m).unwrap_or(u16::MAX),
                stride: u16::try_from(stride).unwrap_or(u16::MAX),
                columns: u16::try_from(columns).unwrap_or(u16::MAX),
                nodes: u16::try_from(nodes).unwrap_or(u16::MAX),
            };
            let b = frame::encode(&header, &cols, &last.nodes[..nodes * NODE_FIELDS]);
            seq = seq.wrapping_add(1);
            shared.updates.fetch_add(1, Ordering::SeqCst);
            publish(&shared, &tx, Update::Frame(b));
            rows.clear();
        }
        let end = shared.end.lock().ok().and_then(|e| e.clone());
        if ended && let Some(end) = end {
            publish(&shared, &tx, Update::Text(end));
            shared.done.store(true, Ordering::SeqCst);
            // Dropping the sender closes every client's stream after what it holds.
            drop(tx);
            return;
        }
    }
}
