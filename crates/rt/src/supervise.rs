//! Runs a ring's node processes (`ringsync node master …`, `ringsync node slave …`) and
//! leaves none of them behind, whichever way the run ends.
//!
//! [`supervise`] starts the children in order, each in a process group of its own (so a
//! terminal's Ctrl-C reaches only the launcher, which then decides), and looks at them
//! every [`POLL`] until one of these happens:
//!
//! - every child has exited with status 0: the run is done;
//! - a child ends badly (a non-zero status, or a signal it was not sent by the launcher):
//!   the first such child is [`Supervision::first_failure`];
//! - the caller's stop flag rises (the CLI raises it on SIGINT, SIGTERM and SIGHUP):
//!   [`Supervision::stopped`];
//! - the deadline passes: [`Supervision::timed_out`].
//!
//! In the last three cases the launcher ends the children still running: SIGTERM to each
//! one's process group, up to `grace` for them to exit, then SIGKILL to the groups of those
//! left. A child that ends by the launcher's signal is [`Ended::Killed`]; one that catches
//! the SIGTERM and exits keeps its status ([`Ended::Exited`]) but is no failure: failures
//! are only counted before the launcher begins ending the ring.
//!
//! Every child is reaped (no zombies) before [`supervise`] returns, on every path: also
//! when starting child k fails (the children already started are ended as above, then the
//! start's error is returned), when waiting for a child fails, and when `supervise` itself
//! unwinds (a guard SIGKILLs the process groups still running and reaps them). A launcher
//! that dies outright (SIGKILL, abort) takes its children with it: each child gets SIGKILL
//! from the kernel when the thread that started it ends (`PR_SET_PDEATHSIG`).
//!
//! Children read nothing (standard input is `/dev/null`) and share the launcher's standard
//! output. Their standard error goes through a pipe to a thread per child, which forwards
//! each line to the launcher's standard error prefixed `ringsync rt: [NAME] ` and keeps the
//! last [`TAIL_LINES`] lines for [`Outcome::stderr_tail`].

use std::collections::VecDeque;
use std::ffi::OsString;
use std::fmt;
use std::io::{self, BufRead, BufReader, Read, Write};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::PathBuf;
use std::process::{Child, ChildStderr, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread;
use std::time::{Duration, Instant};

use crate::sys;

/// How often the children, the stop flag and the deadline are looked at.
pub const POLL: Duration = Duration::from_millis(5);

/// Lines of a child's standard error kept for [`Outcome::stderr_tail`].
pub const TAIL_LINES: usize = 20;

/// Longest line of a child's standard error [bytes]; a longer one is cut into pieces of
/// this length, each forwarded and kept as a line.
const MAX_LINE: usize = 4096;

/// How long, once every child is reaped, their standard error may take to reach its end
/// (the reader threads to drain the pipes). Only a process that outlived its child (one
/// that left its process group) holds a pipe longer; its tail is then what arrived.
const DRAIN: Duration = Duration::from_secs(1);

/// Where a child's standard output goes, line by line, when not to the launcher's:
/// each line with the child's index.
pub type LineSink = std::sync::mpsc::Sender<(usize, String)>;

/// One child to start: the program, its arguments, and a name for messages.
#[derive(Debug, Clone)]
pub struct ChildSpec {
    /// The name in messages and in the prefix of its standard error's lines ("master",
    /// "slave 3").
    pub name: String,
    /// The program (a path, or a name looked up in `PATH`).
    pub program: PathBuf,
    /// Its arguments.
    pub args: Vec<OsString>,
    /// Variables added to (or replacing some of) the launcher's environment.
    pub env: Vec<(OsString, OsString)>,
    /// Its standard output, line by line, to this sink with this index (a node's live
    /// feed); `None`: the launcher's own standard output.
    pub stdout: Option<(usize, LineSink)>,
}

impl ChildSpec {
    /// `program` with `args`, named `name`, in the launcher's environment.
    pub fn new(
        name: impl Into<String>,
        program: impl Into<PathBuf>,
        args: impl IntoIterator<Item = impl Into<OsString>>,
    ) -> ChildSpec {
        ChildSpec {
            name: name.into(),
            program: program.into(),
            args: args.into_iter().map(Into::into).collect(),
            env: Vec::new(),
            stdout: None,
        }
    }
}

/// How a child ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ended {
    /// It exited with this status.
    Exited(i32),
    /// A signal it was not sent by the launcher ended it (signal number).
    Signalled(i32),
    /// The launcher's SIGTERM or SIGKILL ended it: it was still running when another child
    /// failed, the stop flag rose or the deadline passed.
    Killed,
}

impl Ended {
    /// It exited with status 0.
    pub fn succeeded(self) -> bool {
        self == Ended::Exited(0)
    }

    fn of(status: ExitStatus, signalled: bool) -> Ended {
        match (status.code(), status.signal()) {
            (Some(code), _) => Ended::Exited(code),
            (None, Some(sig)) if signalled && (sig == libc::SIGTERM || sig == libc::SIGKILL) => {
                Ended::Killed
            }
            (None, Some(sig)) => Ended::Signalled(sig),
            // Not reachable on Linux: a terminated process has a status or a signal.
            (None, None) => Ended::Signalled(0),
        }
    }
}

impl fmt::Display for Ended {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Ended::Exited(code) => write!(f, "exited with status {code}"),
            Ended::Signalled(sig) => match signal_name(sig) {
                Some(name) => write!(f, "killed by signal {sig} ({name})"),
                None => write!(f, "killed by signal {sig}"),
            },
            Ended::Killed => f.write_str("ended by the launcher"),
        }
    }
}

fn signal_name(sig: i32) -> Option<&'static str> {
    Some(match sig {
        libc::SIGHUP => "SIGHUP",
        libc::SIGINT => "SIGINT",
        libc::SIGQUIT => "SIGQUIT",
        libc::SIGILL => "SIGILL",
        libc::SIGTRAP => "SIGTRAP",
        libc::SIGABRT => "SIGABRT",
        libc::SIGBUS => "SIGBUS",
        libc::SIGFPE => "SIGFPE",
        libc::SIGKILL => "SIGKILL",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGPIPE => "SIGPIPE",
        libc::SIGALRM => "SIGALRM",
        libc::SIGTERM => "SIGTERM",
        _ => return None,
    })
}

/// What became of one child.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outcome {
    /// Its [`ChildSpec::name`].
    pub name: String,
    /// How it ended.
    pub ended: Ended,
    /// The last [`TAIL_LINES`] lines of its standard error, joined by `\n` (no trailing
    /// newline), for messages.
    pub stderr_tail: String,
    /// Its process id (and process group id), now free.
    pub pid: u32,
}

/// How a supervised run ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Supervision {
    /// Every child, in the order of the specs.
    pub children: Vec<Outcome>,
    /// The stop flag rose before the children had ended.
    pub stopped: bool,
    /// The deadline passed before the children had ended.
    pub timed_out: bool,
    /// The index of the first child that ended badly (non-zero status, or a signal not
    /// the launcher's) before the launcher began ending the others.
    pub first_failure: Option<usize>,
}

/// Starts every child in order, each in its own process group, and waits until all have
/// exited 0, one ends badly, `stop` rises or `deadline` passes; in the last three cases
/// the rest get SIGTERM, up to `grace` to exit, then SIGKILL. See the [module](self) for
/// the exit paths. Every child is reaped before this returns.
///
/// Errors: a child that cannot be started (the message names it and its program; the ones
/// started before it are ended and reaped first), or a child that cannot be waited for
/// (the others are ended and reaped first).
pub fn supervise(
    children: Vec<ChildSpec>,
    stop: &AtomicBool,
    deadline: Instant,
    grace: Duration,
) -> io::Result<Supervision> {
    supervise_with(children, stop, deadline, grace, to_stderr(), &mut |_| {})
}

/// Where a reader thread sends each prefixed line of a child's standard error.
type Echo = Arc<dyn Fn(&str) + Send + Sync>;

fn to_stderr() -> Echo {
    Arc::new(|line: &str| {
        // One write per line under the lock, so that the children's lines do not mix; an
        // error (standard error closed) loses the line, not the reader.
        let _ = writeln!(io::stderr().lock(), "{line}");
    })
}

/// [`supervise`], with the lines echoed to `echo` and each child's pid given to `started`
/// as soon as it runs (the tests' view).
fn supervise_with(
    children: Vec<ChildSpec>,
    stop: &AtomicBool,
    deadline: Instant,
    grace: Duration,
    echo: Echo,
    started: &mut dyn FnMut(u32),
) -> io::Result<Supervision> {
    let mut ring = Children::default();
    for spec in children {
        match ring.start(spec, &echo) {
            Ok(pid) => started(pid),
            Err(e) => {
                ring.end(grace);
                return Err(e);
            }
        }
    }
    let mut stopped = false;
    let mut timed_out = false;
    let mut first_failure = None;
    loop {
        for i in ring.poll() {
            if first_failure.is_none() && ring.list[i].ended.is_some_and(|e| !e.succeeded()) {
                first_failure = Some(i);
            }
        }
        if first_failure.is_some() || ring.error.is_some() || !ring.any_running() {
            break;
        }
        if stop.load(Ordering::SeqCst) {
            stopped = true;
            break;
        }
        let now = Instant::now();
        if now >= deadline {
            timed_out = true;
            break;
        }
        thread::sleep(POLL.min(deadline - now));
    }
    ring.end(grace);
    if let Some(e) = ring.error.take() {
        return Err(e);
    }
    Ok(Supervision {
        children: ring.outcomes(),
        stopped,
        timed_out,
        first_failure,
    })
}

/// The last lines of a child's standard error, and whether its reader reached the end.
#[derive(Default)]
struct Tail {
    state: Mutex<TailState>,
    drained: Condvar,
}

#[derive(Default)]
struct TailState {
    lines: VecDeque<String>,
    done: bool,
}

impl Tail {
    fn lock(&self) -> MutexGuard<'_, TailState> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn push(&self, line: String) {
        let mut s = self.lock();
        if s.lines.len() == TAIL_LINES {
            s.lines.pop_front();
        }
        s.lines.push_back(line);
    }

    fn finish(&self) {
        self.lock().done = true;
        self.drained.notify_all();
    }

    /// The lines, once the reader is done or `until` has passed.
    fn wait(&self, until: Instant) -> String {
        let mut s = self.lock();
        while !s.done {
            let now = Instant::now();
            if now >= until {
                break;
            }
            s = match self.drained.wait_timeout(s, until - now) {
                Ok((s, _)) => s,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
        s.lines
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>()
            .join("\n")
    }
}

/// Marks the tail done when the reader ends, however it ends.
struct Finish(Arc<Tail>);

impl Drop for Finish {
    fn drop(&mut self) {
        self.0.finish();
    }
}

/// Reads a child's standard error to its end: each line to `echo` after `prefix`, and
/// into `tail`. Bytes that are not UTF-8 are replaced.
fn forward(stderr: ChildStderr, prefix: &str, echo: &Echo, tail: Arc<Tail>) {
    let tail = Finish(tail);
    let mut reader = BufReader::new(stderr);
    let mut line = Vec::with_capacity(256);
    loop {
        line.clear();
        match (&mut reader)
            .take(MAX_LINE as u64)
            .read_until(b'\n', &mut line)
        {
            Ok(0) => break,
            Ok(_) => {
                let text = String::from_utf8_lossy(&line);
                let text = text.trim_end_matches(['\n', '\r']);
                echo(&format!("{prefix}{text}"));
                tail.0.push(text.to_owned());
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(_) => break,
        }
    }
}

/// A started child.
struct Running {
    name: String,
    pid: u32,
    child: Child,
    tail: Arc<Tail>,
    /// The launcher has sent its process group SIGTERM or SIGKILL.
    signalled: bool,
    ended: Option<Ended>,
    /// Waiting for it failed: it can be neither waited for nor signalled any more.
    lost: bool,
}

impl Running {
    fn running(&self) -> bool {
        self.ended.is_none() && !self.lost
    }
}

/// The children started so far; dropped with some still running (an unwind), it SIGKILLs
/// their process groups and reaps them.
#[derive(Default)]
struct Children {
    list: Vec<Running>,
    /// The first failure to wait for a child.
    error: Option<io::Error>,
}

impl Children {
    /// Starts `spec`'s child and its standard error's reader; returns its pid.
    fn start(&mut self, spec: ChildSpec, echo: &Echo) -> io::Result<u32> {
        let mut cmd = Command::new(&spec.program);
        cmd.args(&spec.args)
            .envs(spec.env.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::null())
            .stdout(if spec.stdout.is_some() {
                Stdio::piped()
            } else {
                Stdio::inherit()
            })
            .stderr(Stdio::piped())
            .process_group(0);
        sys::die_with_parent(&mut cmd);
        let mut child = cmd.spawn().map_err(|e| {
            io::Error::new(
                e.kind(),
                format!(
                    "cannot start {} ({}): {e}",
                    spec.name,
                    spec.program.display()
                ),
            )
        })?;
        let pid = child.id();
        let tail = Arc::new(Tail::default());
        let stderr = child.stderr.take();
        if let (Some(out), Some((index, sink))) = (child.stdout.take(), spec.stdout.clone()) {
            // Detached as the standard error's reader: it ends with the pipe.
            let lines = move || {
                for line in io::BufRead::lines(io::BufReader::new(out)) {
                    let Ok(line) = line else { break };
                    if sink.send((index, line)).is_err() {
                        break;
                    }
                }
            };
            if let Err(e) = thread::Builder::new()
                .name("rt-child-stdout".into())
                .spawn(lines)
            {
                let _ = child.kill();
                let _ = child.wait();
                return Err(io::Error::new(
                    e.kind(),
                    format!("cannot read the standard output of {}: {e}", spec.name),
                ));
            }
        }
        self.list.push(Running {
            name: spec.name.clone(),
            pid,
            child,
            tail: Arc::clone(&tail),
            signalled: false,
            ended: None,
            lost: false,
        });
        match stderr {
            Some(stderr) => {
                let prefix = format!("ringsync rt: [{}] ", spec.name);
                let echo = Arc::clone(echo);
                let reader = Arc::clone(&tail);
                // Detached: it ends at the pipe's end, which the child's end brings.
                thread::Builder::new()
                    .name("rt-child-stderr".into())
                    .spawn(move || forward(stderr, &prefix, &echo, reader))
                    .map_err(|e| {
                        tail.finish();
                        io::Error::new(
                            e.kind(),
                            format!("cannot read the standard error of {}: {e}", spec.name),
                        )
                    })?;
            }
            None => tail.finish(),
        }
        Ok(pid)
    }

    fn any_running(&self) -> bool {
        self.list.iter().any(Running::running)
    }

    /// Collects the children that have ended since the last look, without waiting; returns
    /// their indices.
    fn poll(&mut self) -> Vec<usize> {
        let mut ended = Vec::new();
        for (i, r) in self.list.iter_mut().enumerate() {
            if !r.running() {
                continue;
            }
            match r.child.try_wait() {
                Ok(Some(status)) => {
                    r.ended = Some(Ended::of(status, r.signalled));
                    ended.push(i);
                }
                Ok(None) => {}
                Err(e) => lose(r, e, &mut self.error),
            }
        }
        ended
    }

    /// Sends `sig` to the process group of every child still running. A child not yet
    /// reaped keeps its pid, and so its group id, from reuse: the signal cannot reach a
    /// stranger.
    fn signal(&mut self, sig: libc::c_int) {
        for r in self.list.iter_mut().filter(|r| r.running()) {
            r.signalled = true;
            // ESRCH only: the group has just emptied; the wait collects the child.
            let _ = sys::signal_group(r.pid, sig);
        }
    }

    /// Waits for every child still running, however long it takes.
    fn reap(&mut self) {
        for r in self.list.iter_mut().filter(|r| r.running()) {
            match r.child.wait() {
                Ok(status) => r.ended = Some(Ended::of(status, r.signalled)),
                Err(e) => lose(r, e, &mut self.error),
            }
        }
    }

    /// Ends the children still running: SIGTERM, up to `grace` for them to exit, SIGKILL
    /// to those left; then reaps them all.
    fn end(&mut self, grace: Duration) {
        if !self.any_running() {
            return;
        }
        self.signal(libc::SIGTERM);
        // A grace too long for the clock waits as long as it takes.
        let until = Instant::now().checked_add(grace);
        loop {
            self.poll();
            if !self.any_running() {
                return;
            }
            let now = Instant::now();
            match until {
                Some(until) if now >= until => break,
                Some(until) => thread::sleep(POLL.min(until - now)),
                None => thread::sleep(POLL),
            }
        }
        self.signal(libc::SIGKILL);
        self.reap();
    }

    /// What became of each child, once their standard error has been read (up to
    /// [`DRAIN`]). Every child must have ended.
    fn outcomes(&mut self) -> Vec<Outcome> {
        let until = Instant::now() + DRAIN;
        self.list
            .iter()
            .map(|r| Outcome {
                name: r.name.clone(),
                // A child without an end is lost, and then `supervise` returns the error.
                ended: r.ended.unwrap_or(Ended::Killed),
                stderr_tail: r.tail.wait(until),
                pid: r.pid,
            })
            .collect()
    }
}

/// Records that waiting for `r` failed (and the first such error).
fn lose(r: &mut Running, e: io::Error, error: &mut Option<io::Error>) {
    r.lost = true;
    error.get_or_insert_with(|| {
        io::Error::new(e.kind(), format!("cannot wait for {}: {e}", r.name))
    });
}

impl Drop for Children {
    fn drop(&mut self) {
        if self.any_running() {
            self.signal(libc::SIGKILL);
            self.reap();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    const LONG: Duration = Duration::from_secs(20);

    fn sh(name: &str, script: &str) -> ChildSpec {
        ChildSpec::new(name, "/bin/sh", ["-c", script])
    }

    fn sleeper(name: &str) -> ChildSpec {
        sh(name, "sleep 30")
    }

    /// An echo that keeps the lines (the tests print nothing), and the lines.
    fn kept() -> (Echo, Arc<Mutex<Vec<String>>>) {
        let lines = Arc::new(Mutex::new(Vec::new()));
        let to = Arc::clone(&lines);
        let echo: Echo = Arc::new(move |l: &str| to.lock().expect("lines").push(l.to_owned()));
        (echo, lines)
    }

    /// Runs `children` quietly; returns the result, the pids started, and how long it took.
    fn run(
        children: Vec<ChildSpec>,
        stop: &AtomicBool,
        deadline: Instant,
        grace: Duration,
        echo: Echo,
    ) -> (io::Result<Supervision>, Vec<u32>, Duration) {
        let t0 = Instant::now();
        let mut pids = Vec::new();
        let r = supervise_with(children, stop, deadline, grace, echo, &mut |p| pids.push(p));
        let took = t0.elapsed();
        assert_nothing_left(&pids);
        (r, pids, took)
    }

    /// The state and process group of process `pid` (`/proc/PID/stat`).
    fn state_and_group(pid: &str) -> Option<(char, u32)> {
        let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
        let mut rest = stat[stat.rfind(')')? + 1..].split_whitespace();
        let state = rest.next()?.chars().next()?;
        let group = rest.nth(1)?.parse().ok()?;
        Some((state, group))
    }

    /// No child is left (`/proc/PID` is gone), nor anything running in the children's
    /// process groups (grandchildren). A SIGKILLed grandchild dies asynchronously, and an
    /// orphan's zombie is its new parent's to reap: waits up to 5 s for the groups to be
    /// empty of anything but zombies.
    fn assert_nothing_left(pids: &[u32]) {
        for p in pids {
            assert!(
                !Path::new(&format!("/proc/{p}")).exists(),
                "child {p} is left"
            );
        }
        let until = Instant::now() + Duration::from_secs(5);
        loop {
            let left: Vec<String> = std::fs::read_dir("/proc")
                .expect("/proc")
                .filter_map(|e| e.ok()?.file_name().into_string().ok())
                .filter(|n| n.bytes().all(|b| b.is_ascii_digit()))
                .filter(|n| state_and_group(n).is_some_and(|(s, g)| s != 'Z' && pids.contains(&g)))
                .collect();
            if left.is_empty() {
                return;
            }
            assert!(Instant::now() < until, "left in the groups: {left:?}");
            thread::sleep(Duration::from_millis(20));
        }
    }

    #[test]
    fn all_exit_zero() {
        let (echo, lines) = kept();
        let children = vec![
            sh("master", "echo hello >&2"),
            sh("slave 1", "exit 0"),
            sh("slave 2", "sleep 0.1"),
        ];
        let stop = AtomicBool::new(false);
        let (r, pids, _) = run(children, &stop, Instant::now() + LONG, LONG, echo);
        let s = r.expect("supervised");
        assert_eq!(s.children.len(), 3);
        assert!(
            s.children.iter().all(|c| c.ended == Ended::Exited(0)),
            "{s:?}"
        );
        assert_eq!(
            (s.stopped, s.timed_out, s.first_failure),
            (false, false, None)
        );
        let got: Vec<u32> = s.children.iter().map(|c| c.pid).collect();
        assert_eq!(got, pids);
        assert_eq!(s.children[0].stderr_tail, "hello");
        assert_eq!(s.children[1].stderr_tail, "");
        assert_eq!(
            *lines.lock().expect("lines"),
            ["ringsync rt: [master] hello"]
        );
    }

    #[test]
    fn a_failure_ends_the_others() {
        let (echo, lines) = kept();
        let children = vec![
            sleeper("master"),
            sh("slave 1", "echo boom >&2; sleep 0.1; exit 3"),
            sleeper("slave 2"),
        ];
        let stop = AtomicBool::new(false);
        let (r, _, took) = run(children, &stop, Instant::now() + LONG, LONG, echo);
        let s = r.expect("supervised");
        let ended: Vec<Ended> = s.children.iter().map(|c| c.ended).collect();
        assert_eq!(ended, [Ended::Killed, Ended::Exited(3), Ended::Killed]);
        assert_eq!(s.first_failure, Some(1));
        assert_eq!((s.stopped, s.timed_out), (false, false));
        assert_eq!(s.children[1].stderr_tail, "boom");
        assert!(
            lines
                .lock()
                .expect("lines")
                .contains(&"ringsync rt: [slave 1] boom".to_owned())
        );
        assert!(took < Duration::from_secs(10), "{took:?}");
    }

    #[test]
    fn a_signal_not_ours_is_a_failure() {
        let (echo, _) = kept();
        let children = vec![sleeper("master"), sh("slave 1", "kill -SEGV $$")];
        let stop = AtomicBool::new(false);
        let (r, _, _) = run(children, &stop, Instant::now() + LONG, LONG, echo);
        let s = r.expect("supervised");
        assert_eq!(s.children[1].ended, Ended::Signalled(libc::SIGSEGV));
        assert_eq!(s.children[0].ended, Ended::Killed);
        assert_eq!(s.first_failure, Some(1));
        assert_eq!(
            s.children[1].ended.to_string(),
            format!("killed by signal {} (SIGSEGV)", libc::SIGSEGV)
        );
    }

    #[test]
    fn the_stop_flag_ends_them() {
        let (echo, _) = kept();
        let stop = Arc::new(AtomicBool::new(false));
        let raise = Arc::clone(&stop);
        let raiser = thread::spawn(move || {
            thread::sleep(Duration::from_millis(100));
            raise.store(true, Ordering::SeqCst);
        });
        let children = vec![sleeper("master"), sleeper("slave 1"), sleeper("slave 2")];
        // A grace too long for the clock: the sleepers end on the SIGTERM.
        let (r, _, took) = run(children, &stop, Instant::now() + LONG, Duration::MAX, echo);
        raiser.join().expect("raiser");
        let s = r.expect("supervised");
        assert!(s.children.iter().all(|c| c.ended == Ended::Killed), "{s:?}");
        assert_eq!(
            (s.stopped, s.timed_out, s.first_failure),
            (true, false, None)
        );
        assert!(took < Duration::from_secs(10), "{took:?}");
    }

    /// The children's first line on standard error raises the stop flag (so the launcher
    /// signals them only once they are ready for it); returns the echo and when it rose.
    fn stop_when_ready(stop: &Arc<AtomicBool>) -> (Echo, Arc<Mutex<Option<Instant>>>) {
        let at = Arc::new(Mutex::new(None));
        let (raise, when) = (Arc::clone(stop), Arc::clone(&at));
        let echo: Echo = Arc::new(move |l: &str| {
            if l.ends_with("ready") {
                when.lock().expect("when").get_or_insert_with(Instant::now);
                raise.store(true, Ordering::SeqCst);
            }
        });
        (echo, at)
    }

    #[test]
    fn sigterm_ignored_means_sigkill_after_the_grace() {
        let stop = Arc::new(AtomicBool::new(false));
        let (echo, at) = stop_when_ready(&stop);
        // Not `exec`: the shell waits for its own child, which the group's SIGKILL ends too.
        let children = vec![sh("master", "trap '' TERM; echo ready >&2; sleep 30")];
        let grace = Duration::from_millis(300);
        let (r, _, _) = run(children, &stop, Instant::now() + LONG, grace, echo);
        let returned = Instant::now();
        let s = r.expect("supervised");
        assert_eq!(s.children[0].ended, Ended::Killed);
        assert!(s.stopped);
        let raised = at.lock().expect("when").expect("the child was ready");
        assert!(returned - raised >= grace, "{:?}", returned - raised);
        assert!(returned - raised < Duration::from_secs(10));
    }

    #[test]
    fn an_exit_after_our_sigterm_is_no_failure() {
        let stop = Arc::new(AtomicBool::new(false));
        let (echo, _) = stop_when_ready(&stop);
        let children = vec![sh(
            "master",
            "trap 'exit 5' TERM; echo ready >&2; while :; do sleep 0.05; done",
        )];
        let (r, _, _) = run(children, &stop, Instant::now() + LONG, LONG, echo);
        let s = r.expect("supervised");
        assert_eq!(s.children[0].ended, Ended::Exited(5));
        assert_eq!((s.stopped, s.first_failure), (true, None));
    }

    #[test]
    fn the_deadline_ends_them() {
        let (echo, _) = kept();
        let children = vec![sleeper("master"), sleeper("slave 1")];
        let stop = AtomicBool::new(false);
        let deadline = Instant::now() + Duration::from_millis(200);
        let (r, _, took) = run(children, &stop, deadline, LONG, echo);
        let s = r.expect("supervised");
        assert!(s.children.iter().all(|c| c.ended == Ended::Killed), "{s:?}");
        assert_eq!(
            (s.stopped, s.timed_out, s.first_failure),
            (false, true, None)
        );
        assert!(took < Duration::from_secs(10), "{took:?}");
    }

    #[test]
    fn a_failed_start_ends_those_started() {
        let (echo, _) = kept();
        let children = vec![
            sleeper("master"),
            ChildSpec::new("slave 1", "/nonexistent/ringsync", ["node"]),
            sleeper("slave 2"),
        ];
        let stop = AtomicBool::new(false);
        let (r, pids, took) = run(children, &stop, Instant::now() + LONG, LONG, echo);
        let e = r.expect_err("no such program");
        assert_eq!(e.kind(), io::ErrorKind::NotFound);
        assert!(e.to_string().contains("slave 1"), "{e}");
        assert_eq!(pids.len(), 1);
        let gone = sys::signal_process(pids[0], 0).expect_err("the master is gone");
        assert_eq!(gone.raw_os_error(), Some(libc::ESRCH));
        assert!(took < Duration::from_secs(10), "{took:?}");
    }

    #[test]
    fn an_unwind_ends_them() {
        let (echo, _) = kept();
        let children = vec![sleeper("master"), sleeper("slave 1"), sleeper("slave 2")];
        let stop = AtomicBool::new(false);
        let mut pids = Vec::new();
        let unwound = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            supervise_with(
                children,
                &stop,
                Instant::now() + LONG,
                LONG,
                echo,
                &mut |p| {
                    pids.push(p);
                    assert!(pids.len() < 2, "a panic with two children running");
                },
            )
        }));
        assert!(unwound.is_err());
        assert_eq!(pids.len(), 2);
        assert_nothing_left(&pids);
    }

    #[test]
    fn the_tail_is_the_last_lines_and_the_environment_reaches_the_child() {
        let (echo, lines) = kept();
        let mut child = sh(
            "master",
            "i=0; while [ $i -lt 30 ]; do echo \"$WORD $i\" >&2; i=$((i+1)); done",
        );
        child.env.push(("WORD".into(), "line".into()));
        let stop = AtomicBool::new(false);
        let (r, _, _) = run(vec![child], &stop, Instant::now() + LONG, LONG, echo);
        let s = r.expect("supervised");
        let want: Vec<String> = (10..30).map(|i| format!("line {i}")).collect();
        assert_eq!(s.children[0].stderr_tail, want.join("\n"));
        assert_eq!(lines.lock().expect("lines").len(), 30);
    }
}
