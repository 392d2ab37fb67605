//! What a real-time loop asks of the operating system: a CPU of its own, the FIFO
//! scheduler, memory that never pages, and busy-waiting for the last part of each wait.
//! Each request that is not granted falls back with one warning; the loop runs anyway.
//!
//! **A CPU of its own.** A loop claims its CPU with an advisory lock (`flock`) on
//! `/run/lock/ringsync-cpu-<N>.lock` (`/tmp/ringsync-cpu-<N>.lock` where `/run/lock` cannot
//! be used), holding its process id, for as long as it runs: two runs on this host never
//! pin the same CPU without saying so. The lock dies with its process, so a killed run
//! leaves nothing held.

use std::fs::{File, OpenOptions};
use std::io::{self, Read as _, Write as _};
use std::os::unix::fs::{OpenOptionsExt as _, PermissionsExt as _};
use std::path::{Path, PathBuf};

use ringsync_proto::Duration;

use crate::sys;

/// Which CPU the loop is pinned to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pin {
    /// Not pinned: the loop runs wherever the kernel puts it.
    Off,
    /// The last CPU the process may run on that no other run has claimed (the last CPU
    /// when all are free, which on a small machine leaves CPU 0 to the system).
    Auto,
    /// This CPU. When another run has claimed it, the loop runs unpinned, with a warning.
    Cpu(usize),
    /// This CPU, shared with the other node processes of one ring, whose launcher holds
    /// the claim ([`claim_cpu`]): pinned without claiming.
    Shared(usize),
}

/// Real-time settings of a loop thread.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Realtime {
    /// Busy-wait this long before each deadline instead of sleeping.
    pub spin: Duration,
    /// SCHED_FIFO priority (1-99); 0 keeps the normal scheduler.
    pub priority: i32,
    /// Which CPU to pin the loop to (claimed against other runs: [`Pin`]).
    pub cpu: Pin,
    /// Lock memory (`mlockall`), when `RLIMIT_MEMLOCK` allows it ([`MEMORY_HEADROOM`]).
    pub lock_memory: bool,
}

impl Default for Realtime {
    /// Spin 150 µs, SCHED_FIFO 80, pinned to the last free CPU, memory locked (measured on
    /// this kind of machine: DEPENDENCIES.md, docs/runtime.md).
    fn default() -> Self {
        Realtime {
            spin: Duration::from_us(150),
            priority: 80,
            cpu: Pin::Auto,
            lock_memory: true,
        }
    }
}

/// What [`Realtime::apply`] did: a line per setting, and the CPU claim to keep until the
/// loop ends.
#[derive(Debug)]
#[must_use = "dropping the claim frees the CPU for another run while this one is pinned to it"]
pub struct Applied {
    /// One line per setting: what was done, or a warning (`warning: …`) with the reason
    /// when it was not allowed.
    pub lines: Vec<String>,
    /// The CPU the loop is pinned to, claimed against other runs (None: unpinned).
    pub cpu: Option<CpuClaim>,
}

impl Realtime {
    /// Applies the settings to the calling thread (and, for memory, the process): one line
    /// per setting, what was done or a warning with the reason when it was not allowed.
    /// Keep the returned claim until the loop ends.
    pub fn apply(&self) -> Applied {
        let mut lines = Vec::new();
        let cannot_pin = |cpu: usize, e: io::Error| {
            format!("warning: cannot pin to CPU {cpu} ({e}); running unpinned")
        };
        if let Pin::Shared(cpu) = self.cpu {
            lines.push(match sys::pin_to_cpu(cpu) {
                Ok(()) => format!("pinned to CPU {cpu} with the ring's other nodes"),
                Err(e) => cannot_pin(cpu, e),
            });
        }
        let (claim, line) = choose_cpu(self.cpu, &sys::allowed_cpus(), &lock_dirs());
        let claim = match claim.map(|c| (sys::pin_to_cpu(c.cpu), c)) {
            Some((Err(e), c)) => {
                lines.push(cannot_pin(c.cpu, e));
                None
            }
            claimed => {
                lines.extend(line);
                claimed.map(|(_, c)| c)
            }
        };
        if self.priority > 0 {
            match sys::set_fifo(self.priority) {
                Ok(()) => lines.push(format!("SCHED_FIFO priority {}", self.priority)),
                Err(e) => lines.push(format!(
                    "warning: cannot use SCHED_FIFO ({e}); running with the normal scheduler (`ulimit -r {}` or running as root allows it)",
                    self.priority
                )),
            }
        }
        if self.lock_memory {
            lines.push(lock_memory());
        }
        lines.push(format!(
            "busy-wait the last {:.0} µs before each deadline",
            self.spin.as_ns() as f64 * 1e-3
        ));
        Applied { lines, cpu: claim }
    }
}

// ---------------------------------------------------------------------------------------
// Memory.

/// How much a run's memory may grow after its settings are applied \[bytes\]: a finite
/// `RLIMIT_MEMLOCK` must leave this much beyond what is mapped then, or memory is not
/// locked. With `MCL_FUTURE`, an allocation past the limit fails and aborts the process;
/// a run that keeps its trace in memory grows about 0.23 MB per second of run at 1 ms with
/// 4 axes (70 minutes of 1 GiB), about 7 MB with the capture kept too (2.5 minutes); a
/// streamed run does not grow (docs/runtime.md).
pub const MEMORY_HEADROOM: u64 = 1 << 30;

/// Whether memory may be locked: `Ok` when the process is privileged (`CAP_IPC_LOCK`), the
/// limit is unlimited (`None`), or the limit \[bytes\] leaves [`MEMORY_HEADROOM`] beyond
/// `mapped` \[bytes\]; otherwise the warning line, naming the limit found.
pub fn memory_lock_allowed(
    limit: Option<u64>,
    privileged: bool,
    mapped: u64,
) -> Result<(), String> {
    let need = mapped.saturating_add(MEMORY_HEADROOM);
    match limit {
        _ if privileged => Ok(()),
        None => Ok(()),
        Some(l) if l >= need => Ok(()),
        Some(l) => Err(format!(
            "warning: not locking memory: RLIMIT_MEMLOCK is {}, a run needs about {} (`ulimit -l unlimited` or running as root enables it)",
            mib(l),
            mib(need)
        )),
    }
}

fn mib(bytes: u64) -> String {
    format!("{:.0} MiB", bytes as f64 / f64::from(1u32 << 20))
}

/// A field of `/proc/self/status` (`name:\tvalue …`): the first word of its value.
fn status_field<'a>(status: &'a str, name: &str) -> Option<&'a str> {
    status
        .lines()
        .find_map(|l| l.strip_prefix(name)?.strip_prefix(':'))
        .and_then(|v| v.split_whitespace().next())
}

/// Whether `CAP_IPC_LOCK` (capability 14) is in the effective set of `/proc/self/status`.
fn can_lock_any(status: &str) -> bool {
    const CAP_IPC_LOCK: u32 = 14;
    status_field(status, "CapEff")
        .and_then(|h| u64::from_str_radix(h, 16).ok())
        .is_some_and(|caps| caps & (1 << CAP_IPC_LOCK) != 0)
}

/// The process's mapped memory from `/proc/self/status` (`VmSize`, in kB) [bytes].
fn mapped_bytes(status: &str) -> Option<u64> {
    status_field(status, "VmSize")?
        .parse::<u64>()
        .ok()
        .map(|kb| kb * 1024)
}

/// Locks memory when the limit allows it; the line saying what was done.
fn lock_memory() -> String {
    let limit = match sys::memlock_limit() {
        Ok(l) => l,
        Err(e) => return format!("warning: not locking memory: cannot read RLIMIT_MEMLOCK ({e})"),
    };
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    // Unknown mapped size: count only the headroom (the limit check then errs generous,
    // and a failing mlockall still gives a warning).
    let mapped = mapped_bytes(&status).unwrap_or(0);
    if let Err(w) = memory_lock_allowed(limit, can_lock_any(&status), mapped) {
        return w;
    }
    match sys::lock_memory() {
        Ok(()) => "memory locked".into(),
        Err(e) => format!("warning: cannot lock memory ({e}); running with memory unlocked"),
    }
}

// ---------------------------------------------------------------------------------------
// CPU claims.

/// A CPU claimed for a loop: an exclusive `flock` on its lock file, released when this is
/// dropped or the process ends.
#[derive(Debug)]
pub struct CpuClaim {
    cpu: usize,
    /// None when no lock file could be opened (pinned, but not claimed).
    _lock: Option<File>,
}

impl CpuClaim {
    /// The CPU claimed.
    pub fn cpu(&self) -> usize {
        self.cpu
    }
}

/// The outcome of trying to claim one CPU.
#[derive(Debug)]
enum Claim {
    /// Ours until dropped.
    Held(CpuClaim),
    /// Another run holds it: its process id, when its lock file says.
    Taken(Option<u32>),
}

/// Where lock files go, in order of preference.
fn lock_dirs() -> [PathBuf; 2] {
    [PathBuf::from("/run/lock"), std::env::temp_dir()]
}

fn lock_path(dir: &Path, cpu: usize) -> PathBuf {
    dir.join(format!("ringsync-cpu-{cpu}.lock"))
}

/// Opens (creating it, writable by all, so that any user's run can claim the CPU and
/// write its id) a lock file; read-only when it belongs to another user.
fn open_lock(path: &Path) -> io::Result<File> {
    let created = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .mode(0o666)
        .open(path);
    if let Ok(f) = &created {
        // The umask narrowed the mode; only the owner may widen it (others fail: harmless).
        let _ = f.set_permissions(std::fs::Permissions::from_mode(0o666));
    }
    created
        .or_else(|_| OpenOptions::new().read(true).write(true).open(path))
        .or_else(|_| File::open(path))
}

/// Tries to claim `cpu` with a lock file in the first of `dirs` where one can be opened.
fn claim_in(dirs: &[PathBuf], cpu: usize) -> io::Result<Claim> {
    let mut last = io::Error::new(io::ErrorKind::NotFound, "no lock directory");
    for dir in dirs {
        let path = lock_path(dir, cpu);
        let mut file = match open_lock(&path) {
            Ok(f) => f,
            Err(e) => {
                last = io::Error::new(e.kind(), format!("{}: {e}", path.display()));
                continue;
            }
        };
        if !sys::try_lock_exclusive(&file)? {
            let mut text = String::new();
            let pid = file
                .read_to_string(&mut text)
                .ok()
                .and_then(|_| text.trim().parse().ok());
            return Ok(Claim::Taken(pid));
        }
        // Ours: say whose it is (a read-only lock file stays without).
        let _ = file
            .set_len(0)
            .and_then(|()| writeln!(file, "{}", std::process::id()));
        return Ok(Claim::Held(CpuClaim {
            cpu,
            _lock: Some(file),
        }));
    }
    Err(last)
}

fn by(pid: Option<u32>) -> String {
    pid.map_or("another ringsync run".into(), |p| {
        format!("another ringsync run (PID {p})")
    })
}

/// Chooses and claims a CPU as [`Realtime::apply`] does, without pinning the caller to it:
/// for a launcher whose node processes share the CPU ([`Pin::Shared`]). Returns the claim
/// (None: the nodes run unpinned) and the one line that says so (none when it went as
/// asked).
pub fn claim_cpu(pin: Pin) -> (Option<CpuClaim>, Option<String>) {
    choose_cpu(pin, &sys::allowed_cpus(), &lock_dirs())
}

/// Chooses and claims the loop's CPU among `allowed` with lock files in `dirs`: the claim
/// (None: run unpinned) and the one line that says so; no line when it went as asked.
fn choose_cpu(pin: Pin, allowed: &[usize], dirs: &[PathBuf]) -> (Option<CpuClaim>, Option<String>) {
    let wanted: Vec<usize> = match pin {
        Pin::Off | Pin::Shared(_) => return (None, None),
        Pin::Cpu(c) => vec![c],
        Pin::Auto => allowed.iter().rev().copied().collect(),
    };
    let mut taken = Vec::new();
    for &cpu in &wanted {
        match claim_in(dirs, cpu) {
            Ok(Claim::Held(c)) => {
                let line = if taken.is_empty() {
                    format!("pinned to CPU {cpu}")
                } else {
                    format!(
                        "pinned to CPU {cpu}: {}",
                        taken
                            .iter()
                            .map(|(c, p)| format!("CPU {c} is taken by {}", by(*p)))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                };
                return (Some(c), Some(line));
            }
            Ok(Claim::Taken(pid)) => taken.push((cpu, pid)),
            Err(e) => {
                // No lock file anywhere: pin as asked, unclaimed.
                return (
                    Some(CpuClaim { cpu, _lock: None }),
                    Some(format!(
                        "warning: pinned to CPU {cpu} without claiming it against other runs (cannot open a lock file: {e})"
                    )),
                );
            }
        }
    }
    let line = match (pin, taken.as_slice()) {
        (Pin::Cpu(c), [(_, pid)]) => format!(
            "warning: CPU {c} is taken by {}; running unpinned (choose a free CPU with --cpu, or leave --cpu out to take one)",
            by(*pid)
        ),
        _ if taken.is_empty() => "warning: no CPU to pin to; running unpinned".into(),
        _ => format!(
            "warning: every CPU is taken by another ringsync run ({}); running unpinned",
            taken
                .iter()
                .map(|(c, p)| format!(
                    "CPU {c}{}",
                    p.map_or(String::new(), |p| format!(": PID {p}"))
                ))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    (None, Some(line))
}

#[cfg(test)]
mod tests {
    use super::*;

    const MIB: u64 = 1 << 20;

    #[test]
    fn memory_is_locked_only_when_the_limit_allows_it() {
        let mapped = 10 * MIB;
        // An ordinary user's default limit (8 MiB): not locked, the limit named, the way
        // out given.
        let w = memory_lock_allowed(Some(8 * MIB), false, mapped).expect_err("8 MiB");
        assert!(w.starts_with("warning: "), "{w}");
        assert!(w.contains("RLIMIT_MEMLOCK is 8 MiB"), "{w}");
        assert!(
            w.contains("ulimit -l unlimited") && w.contains("root"),
            "{w}"
        );
        assert_eq!(w.lines().count(), 1);
        // Unlimited, or enough, or privileged whatever the limit.
        assert!(memory_lock_allowed(None, false, mapped).is_ok());
        assert!(memory_lock_allowed(Some(mapped + MEMORY_HEADROOM), false, mapped).is_ok());
        assert!(memory_lock_allowed(Some(mapped + MEMORY_HEADROOM - 1), false, mapped).is_err());
        assert!(memory_lock_allowed(Some(8 * MIB), true, mapped).is_ok());
        assert!(memory_lock_allowed(Some(0), true, u64::MAX).is_ok());
    }

    #[test]
    fn privilege_and_mapped_size_are_read_from_proc_status() {
        let status = "Name:\tringsync\nVmPeak:\t   9244 kB\nVmSize:\t    9000 kB\nCapEff:\t0000000000004000\n";
        assert_eq!(mapped_bytes(status), Some(9000 * 1024));
        assert!(can_lock_any(status));
        assert!(!can_lock_any("CapEff:\t0000000000000000\n"));
        assert!(!can_lock_any("CapEff:\tnot-hex\n"));
        assert_eq!(mapped_bytes("VmSize:\tlots kB\n"), None);
        assert_eq!(mapped_bytes(""), None);
        // Root here: all capabilities.
        let own = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
        assert!(mapped_bytes(&own).is_some_and(|b| b > 0));
    }

    fn dirs(name: &str) -> Vec<PathBuf> {
        let d = std::env::temp_dir().join(format!("ringsync-claims-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("lock dir");
        vec![d]
    }

    #[test]
    fn a_second_claim_of_a_cpu_takes_another_or_runs_unpinned_with_a_warning() {
        let d = dirs("second");
        let allowed = [0, 1];
        let pid = std::process::id();
        // The first run takes the last CPU, and its lock file names it.
        let (first, line) = choose_cpu(Pin::Auto, &allowed, &d);
        let first = first.expect("CPU 1 is free");
        assert_eq!((first.cpu(), line.as_deref()), (1, Some("pinned to CPU 1")));
        let held = std::fs::read_to_string(lock_path(&d[0], 1)).expect("lock file");
        assert_eq!(held.trim(), pid.to_string());
        // The second is moved to the other CPU, in one line that says why.
        let (second, line) = choose_cpu(Pin::Auto, &allowed, &d);
        let line = line.expect("a line");
        assert_eq!(second.as_ref().map(CpuClaim::cpu), Some(0), "{line}");
        assert_eq!(
            line,
            format!("pinned to CPU 0: CPU 1 is taken by another ringsync run (PID {pid})")
        );
        // Every CPU taken: unpinned, with a warning naming the holders.
        let (third, line) = choose_cpu(Pin::Auto, &allowed, &d);
        let line = line.expect("a line");
        assert!(third.is_none(), "{line}");
        assert_eq!(
            line,
            format!(
                "warning: every CPU is taken by another ringsync run (CPU 1: PID {pid}, CPU 0: PID {pid}); running unpinned"
            )
        );
        // A CPU asked for by number and taken: unpinned, with a warning.
        let (fixed, line) = choose_cpu(Pin::Cpu(1), &allowed, &d);
        let line = line.expect("a line");
        assert!(fixed.is_none(), "{line}");
        assert!(
            line.starts_with(&format!(
                "warning: CPU 1 is taken by another ringsync run (PID {pid}); running unpinned"
            )),
            "{line}"
        );
        // A claim ends with its run: CPU 1 is free again.
        drop(first);
        let (again, line) = choose_cpu(Pin::Cpu(1), &allowed, &d);
        assert_eq!(again.as_ref().map(CpuClaim::cpu), Some(1), "{line:?}");
        drop((second, again));
        let _ = std::fs::remove_dir_all(&d[0]);
    }

    #[test]
    fn a_claim_falls_back_to_the_next_lock_directory() {
        let mut d = dirs("fallback");
        d.insert(0, PathBuf::from("/nonexistent/ringsync-lock-dir"));
        let (c, line) = choose_cpu(Pin::Cpu(0), &[0], &d);
        assert_eq!(c.as_ref().map(CpuClaim::cpu), Some(0), "{line:?}");
        assert!(lock_path(&d[1], 0).exists());
        // Unpinned: nothing claimed, nothing said.
        let (c, line) = choose_cpu(Pin::Off, &[0], &d);
        assert!(c.is_none() && line.is_none());
        drop(c);
        let _ = std::fs::remove_dir_all(&d[1]);
    }
}
