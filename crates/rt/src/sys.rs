//! Thin wrappers over the Linux system calls the runtime needs. The only module of ringsync
//! with `unsafe` code; every block says why it is sound.
#![allow(unsafe_code)]

use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::sync::atomic::{AtomicBool, Ordering};

/// `CLOCK_MONOTONIC` now [ns].
pub fn now_ns() -> i64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec * 1_000_000_000 + ts.tv_nsec
}

fn timespec(ns: i64) -> libc::timespec {
    let ns = ns.max(0);
    libc::timespec {
        tv_sec: ns / 1_000_000_000,
        tv_nsec: ns % 1_000_000_000,
    }
}

/// Sleeps until `CLOCK_MONOTONIC` reads `deadline` [ns] (an absolute deadline:
/// `clock_nanosleep` with `TIMER_ABSTIME`, so no drift accumulates). Returns early on a
/// signal.
pub fn sleep_until(deadline: i64) {
    let ts = timespec(deadline);
    // SAFETY: `ts` is a valid timespec; the remainder pointer may be null with TIMER_ABSTIME.
    unsafe {
        libc::clock_nanosleep(
            libc::CLOCK_MONOTONIC,
            libc::TIMER_ABSTIME,
            &ts,
            std::ptr::null_mut(),
        )
    };
}

/// Waits until one of `fds` is readable or `timeout` [ns] passes (`ppoll`). Returns whether
/// a descriptor is readable.
pub fn wait_readable(fds: &mut [libc::pollfd], timeout: i64) -> io::Result<bool> {
    let ts = timespec(timeout);
    // SAFETY: `fds` is a valid slice of pollfd for its length; `ts` is valid; no sigmask.
    let r = unsafe {
        libc::ppoll(
            fds.as_mut_ptr(),
            fds.len() as libc::nfds_t,
            &ts,
            std::ptr::null(),
        )
    };
    if r < 0 {
        let e = io::Error::last_os_error();
        if e.kind() == io::ErrorKind::Interrupted {
            return Ok(false);
        }
        return Err(e);
    }
    Ok(r > 0)
}

/// A pollfd waiting for input on `fd`.
pub fn pollfd(fd: RawFd) -> libc::pollfd {
    libc::pollfd {
        fd,
        events: libc::POLLIN,
        revents: 0,
    }
}

/// Makes the calling thread SCHED_FIFO at `priority` (1-99).
pub fn set_fifo(priority: i32) -> io::Result<()> {
    let p = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: `p` is a valid sched_param; pid 0 is the calling thread.
    if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &p) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// Returns the calling thread to the normal scheduler and lets it run on every CPU (for
/// helper threads, which inherit the loop's real-time settings otherwise).
pub fn set_normal() {
    let p = libc::sched_param { sched_priority: 0 };
    // SAFETY: `p` is a valid sched_param; `set` is plain data filled by CPU_SET within
    // CPU_SETSIZE; pid 0 is the calling thread. Failures leave the settings as they were.
    unsafe {
        libc::sched_setscheduler(0, libc::SCHED_OTHER, &p);
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        for cpu in 0..cpus().min(libc::CPU_SETSIZE as usize) {
            libc::CPU_SET(cpu, &mut set);
        }
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
    }
}

/// Locks the process's current and future pages in memory (`mlockall`). On failure nothing
/// stays locked and later allocations are not held to the limit (`munlockall`: a failed
/// `mlockall` can leave `MCL_FUTURE` set).
pub fn lock_memory() -> io::Result<()> {
    // SAFETY: plain system calls with flag arguments.
    unsafe {
        if libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) != 0 {
            let e = io::Error::last_os_error();
            libc::munlockall();
            return Err(e);
        }
    }
    Ok(())
}

/// The soft `RLIMIT_MEMLOCK` [bytes]: how much memory the process may lock without
/// `CAP_IPC_LOCK`; `None` when unlimited.
pub fn memlock_limit() -> io::Result<Option<u64>> {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: `r` is a valid, writable rlimit.
    if unsafe { libc::getrlimit(libc::RLIMIT_MEMLOCK, &mut r) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok((r.rlim_cur != libc::RLIM_INFINITY).then_some(r.rlim_cur))
}

/// Takes an exclusive `flock` on `file` without waiting: `Ok(false)` when another open
/// file description holds it (another process, or another open of the same file). The lock
/// goes with the descriptor: closing the file, or the process's end, releases it.
pub fn try_lock_exclusive(file: &std::fs::File) -> io::Result<bool> {
    // SAFETY: `file` is an open descriptor for the duration of the call.
    if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
        let e = io::Error::last_os_error();
        if e.kind() == io::ErrorKind::WouldBlock {
            return Ok(false);
        }
        return Err(e);
    }
    Ok(true)
}

/// Pins the calling thread to CPU `cpu`.
pub fn pin_to_cpu(cpu: usize) -> io::Result<()> {
    if cpu >= libc::CPU_SETSIZE as usize {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "CPU out of range",
        ));
    }
    // SAFETY: cpu_set_t is plain data; zeroed is the empty set; CPU_SET stays in bounds
    // (checked above); pid 0 is the calling thread.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0 {
            return Err(io::Error::last_os_error());
        }
    }
    Ok(())
}

/// Number of CPUs this process may run on.
pub fn cpus() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The CPUs the calling thread may run on, in increasing order (`sched_getaffinity`);
/// `0..cpus()` when the mask cannot be read.
pub fn allowed_cpus() -> Vec<usize> {
    // SAFETY: cpu_set_t is plain data; zeroed is the empty set; the kernel writes at most
    // its size; CPU_ISSET stays within CPU_SETSIZE.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return (0..cpus()).collect();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect()
    }
}

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

/// A second signal once the flag is up: the signal's default action (the process ends, as
/// it would have without a handler).
extern "C" fn on_signal_twice(sig: libc::c_int) {
    if STOP.swap(true, Ordering::SeqCst) {
        // SAFETY: signal and raise are async-signal-safe; SIG_DFL is a valid action.
        unsafe {
            libc::signal(sig, libc::SIG_DFL);
            libc::raise(sig);
        }
    }
}

/// Installs SIGINT, SIGTERM and SIGHUP handlers that only raise a flag, so that a run ends
/// cleanly (and removes what it created) on Ctrl-C, on `kill`, and when its terminal closes.
/// A SIGHUP the process was started ignoring (`nohup`) stays ignored. Returns the flag.
pub fn stop_flag() -> &'static AtomicBool {
    install(on_signal)
}

/// [`stop_flag`] for work with nothing outside the process to clean up (a simulation, a
/// sweep): the first signal raises the flag, a second one ends the process at once, as a
/// user who presses Ctrl-C twice expects.
pub fn stop_flag_or_twice_exit() -> &'static AtomicBool {
    install(on_signal_twice)
}

fn install(handler: extern "C" fn(libc::c_int)) -> &'static AtomicBool {
    // SAFETY: the handlers only store to an atomic, or take the default action again and
    // raise the signal (async-signal-safe); `sa` and `old` are zeroed plain data, `sa` with
    // the handler set; a null new action only reads the old.
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = handler as *const () as libc::sighandler_t;
        libc::sigemptyset(&mut sa.sa_mask);
        libc::sigaction(libc::SIGINT, &sa, std::ptr::null_mut());
        libc::sigaction(libc::SIGTERM, &sa, std::ptr::null_mut());
        let mut old: libc::sigaction = std::mem::zeroed();
        let read = libc::sigaction(libc::SIGHUP, std::ptr::null(), &mut old);
        if read != 0 || old.sa_sigaction != libc::SIG_IGN {
            libc::sigaction(libc::SIGHUP, &sa, std::ptr::null_mut());
        }
    }
    &STOP
}

/// Sends signal `sig` to every process of the process group `pgid` (`kill(-pgid, sig)`).
/// Group ids 0 and 1 are refused: `kill(0, ..)` would signal the caller's own group and
/// `kill(-1, ..)` every process the caller may signal.
pub fn signal_group(pgid: u32, sig: libc::c_int) -> io::Result<()> {
    let group = libc::pid_t::try_from(pgid)
        .ok()
        .filter(|&g| g > 1)
        .ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("no process group {pgid}"),
            )
        })?;
    // SAFETY: kill reads no memory; `-group` is below -1, so it names exactly one group.
    if unsafe { libc::kill(-group, sig) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// Sends signal `sig` to the process `pid` (`kill(pid, sig)`); signal 0 only checks that
/// the process exists (`ESRCH` when it does not). Pid 0 is refused.
#[cfg(test)]
pub fn signal_process(pid: u32, sig: libc::c_int) -> io::Result<()> {
    let pid = libc::pid_t::try_from(pid)
        .ok()
        .filter(|&p| p > 0)
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, format!("no process {pid}")))?;
    // SAFETY: kill reads no memory; a positive pid names exactly one process.
    if unsafe { libc::kill(pid, sig) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// Makes the process that `cmd` starts get SIGKILL when the thread that started it ends
/// (`PR_SET_PDEATHSIG`), so that a launcher that dies without cleaning up (SIGKILL, abort)
/// leaves no child running. A child whose launcher is already gone when it gets there
/// kills itself. The thread must outlive the child: the kernel ties the signal to the
/// thread, not the process.
pub fn die_with_parent(cmd: &mut std::process::Command) {
    use std::os::unix::process::CommandExt;
    let parent = std::process::id();
    // SAFETY: the closure runs in the child between fork and exec, where only
    // async-signal-safe calls are allowed: it calls prctl, getppid and raise and allocates
    // nothing (`io::Error::last_os_error` is the errno, not a heap value). The prctl
    // argument is passed as the unsigned long the kernel reads.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong) != 0 {
                return Err(io::Error::last_os_error());
            }
            if u32::try_from(libc::getppid()).ok() != Some(parent) {
                libc::raise(libc::SIGKILL);
            }
            Ok(())
        })
    };
}

/// Moves the calling thread into the network namespace `name` (`/run/netns/NAME`).
pub fn enter_netns(name: &str) -> io::Result<()> {
    let f = std::fs::File::open(format!("/run/netns/{name}"))?;
    // SAFETY: `f` is an open namespace file; setns only affects the calling thread.
    if unsafe { libc::setns(f.as_raw_fd(), libc::CLONE_NEWNET) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// An AF_PACKET raw socket for EtherType `ethertype` bound to interface `ifname` (in the
/// calling thread's network namespace), non-blocking, not reading its own transmissions.
pub fn packet_socket(ifname: &str, ethertype: u16) -> io::Result<OwnedFd> {
    let proto = ethertype.to_be();
    // SAFETY: plain system call; the result is checked before use.
    let fd = unsafe {
        libc::socket(
            libc::AF_PACKET,
            libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
            i32::from(proto),
        )
    };
    if fd < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: `fd` is a fresh descriptor that nothing else owns.
    let fd = unsafe { OwnedFd::from_raw_fd(fd) };
    let name = CString::new(ifname)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "interface name has a NUL"))?;
    // SAFETY: `name` is a valid C string.
    let index = unsafe { libc::if_nametoindex(name.as_ptr()) };
    if index == 0 {
        return Err(io::Error::new(
            io::ErrorKind::NotFound,
            format!("no interface {ifname}"),
        ));
    }
    // SAFETY: sockaddr_ll is plain data; zeroed then filled.
    let mut sll: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
    sll.sll_family = libc::AF_PACKET as u16;
    sll.sll_protocol = proto;
    sll.sll_ifindex = index as i32;
    // SAFETY: `sll` is a valid sockaddr_ll and its size is passed.
    let r = unsafe {
        libc::bind(
            fd.as_raw_fd(),
            (&sll as *const libc::sockaddr_ll).cast(),
            std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
        )
    };
    if r != 0 {
        return Err(io::Error::last_os_error());
    }
    // PACKET_IGNORE_OUTGOING (Linux 4.20): without it the socket also reads what it sends.
    const PACKET_IGNORE_OUTGOING: libc::c_int = 23;
    set_flag(fd.as_raw_fd(), libc::SOL_PACKET, PACKET_IGNORE_OUTGOING)?;
    Ok(fd)
}

/// Sets socket option `name` of `level` on `fd` to 1.
fn set_flag(fd: RawFd, level: libc::c_int, name: libc::c_int) -> io::Result<()> {
    let one: libc::c_int = 1;
    // SAFETY: the option value is a valid c_int and its size is passed.
    let r = unsafe {
        libc::setsockopt(
            fd,
            level,
            name,
            (&one as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    if r != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// Sends `buf` on a bound socket.
pub fn send(fd: RawFd, buf: &[u8]) -> io::Result<usize> {
    // SAFETY: `buf` is valid for reads of its length.
    let r = unsafe { libc::send(fd, buf.as_ptr().cast(), buf.len(), libc::MSG_DONTWAIT) };
    if r < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(r as usize)
}

/// Receives one datagram into `buf` without blocking; `None` when nothing is waiting.
pub fn recv(fd: RawFd, buf: &mut [u8]) -> io::Result<Option<usize>> {
    // SAFETY: `buf` is valid for writes of its length.
    let r = unsafe { libc::recv(fd, buf.as_mut_ptr().cast(), buf.len(), libc::MSG_DONTWAIT) };
    if r < 0 {
        let e = io::Error::last_os_error();
        if e.kind() == io::ErrorKind::WouldBlock {
            return Ok(None);
        }
        return Err(e);
    }
    Ok(Some(r as usize))
}

/// `SO_TIMESTAMPNS` and its control message (`SCM_TIMESTAMPNS`): the value of
/// `asm-generic/socket.rs` (x86-64, arm64, riscv), spelled here because the `libc` crate
/// does not export it for every target.
const SO_TIMESTAMPNS: libc::c_int = 35;

/// Asks the kernel to stamp every datagram `fd` receives with the instant it reached the
/// socket (`SO_TIMESTAMPNS`: `CLOCK_REALTIME`, read by [`recv_stamped`]).
pub fn enable_rx_stamps(fd: RawFd) -> io::Result<()> {
    set_flag(fd, libc::SOL_SOCKET, SO_TIMESTAMPNS)
}

/// Receives one datagram into `buf` without blocking, as [`recv`], with the kernel's
/// receive stamp when [`enable_rx_stamps`] asked for it [ns of `CLOCK_REALTIME`]; `None`
/// when nothing is waiting.
pub fn recv_stamped(fd: RawFd, buf: &mut [u8]) -> io::Result<Option<(usize, Option<i64>)>> {
    let mut iov = libc::iovec {
        iov_base: buf.as_mut_ptr().cast(),
        iov_len: buf.len(),
    };
    // Room for one control message of a timespec (32 bytes on 64-bit Linux) and more,
    // aligned as a cmsghdr.
    let mut control = [0u64; 16];
    // SAFETY: an all-zero msghdr is a valid empty one.
    let mut msg: libc::msghdr = unsafe { std::mem::zeroed() };
    msg.msg_iov = &mut iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control.as_mut_ptr().cast();
    msg.msg_controllen = std::mem::size_of_val(&control) as _;
    // SAFETY: `msg` points at `iov` (valid for writes of `buf`'s length) and `control`,
    // both alive for the call.
    let r = unsafe { libc::recvmsg(fd, &mut msg, libc::MSG_DONTWAIT) };
    if r < 0 {
        let e = io::Error::last_os_error();
        if e.kind() == io::ErrorKind::WouldBlock {
            return Ok(None);
        }
        return Err(e);
    }
    let mut stamp = None;
    // SAFETY: the kernel filled `msg`'s control buffer; the CMSG macros walk it within
    // `msg_controllen`, and a timestamp message's data is one timespec (read unaligned).
    unsafe {
        let mut c = libc::CMSG_FIRSTHDR(&msg);
        while !c.is_null() {
            if (*c).cmsg_level == libc::SOL_SOCKET && (*c).cmsg_type == SO_TIMESTAMPNS {
                let ts: libc::timespec = std::ptr::read_unaligned(libc::CMSG_DATA(c).cast());
                stamp = ts
                    .tv_sec
                    .checked_mul(1_000_000_000)
                    .and_then(|s| s.checked_add(ts.tv_nsec));
            }
            c = libc::CMSG_NXTHDR(&msg, c);
        }
    }
    Ok(Some((r as usize, stamp)))
}

/// `CLOCK_REALTIME` less `CLOCK_MONOTONIC` [ns], read between two readings of the
/// monotonic clock (the closest of three pairs): what turns a kernel receive stamp into
/// the loop's time. It changes only when the system clock is set, not when it is slewed.
pub fn realtime_offset() -> i64 {
    let read = |clock| {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `ts` is a valid, writable timespec; both clocks exist on Linux.
        unsafe { libc::clock_gettime(clock, &mut ts) };
        ts.tv_sec * 1_000_000_000 + ts.tv_nsec
    };
    (0..3)
        .map(|_| {
            let m0 = read(libc::CLOCK_MONOTONIC);
            let r = read(libc::CLOCK_REALTIME);
            let m1 = read(libc::CLOCK_MONOTONIC);
            (m1 - m0, r - m0 - (m1 - m0) / 2)
        })
        .min_by_key(|p| p.0)
        .map_or(0, |p| p.1)
}

/// A socket for interface control requests (ioctl) in the calling thread's network
/// namespace; it stays in that namespace whichever thread uses it later.
pub fn control_socket() -> io::Result<OwnedFd> {
    // SAFETY: plain system call; the result is checked before use.
    let fd = unsafe { libc::socket(libc::AF_INET, libc::SOCK_DGRAM | libc::SOCK_CLOEXEC, 0) };
    if fd < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: `fd` is a fresh descriptor that nothing else owns.
    Ok(unsafe { OwnedFd::from_raw_fd(fd) })
}

/// Whether interface `ifname` (in `ctl`'s namespace) is up and has its carrier (IFF_UP and
/// IFF_RUNNING: `ip link` shows `state UP`), as its PHY reports: a veth end whose peer went
/// down, or a card whose cable was pulled, has no carrier.
pub fn interface_running(ctl: &OwnedFd, ifname: &str) -> io::Result<bool> {
    let (_, flags) = interface_flags(ctl, ifname)?;
    let want = (libc::IFF_UP | libc::IFF_RUNNING) as libc::c_short;
    Ok(flags & want == want)
}

/// An ifreq naming `ifname`, with the interface's flags read into it (SIOCGIFFLAGS on
/// `ctl`), and the flags.
fn interface_flags(ctl: &OwnedFd, ifname: &str) -> io::Result<(libc::ifreq, libc::c_short)> {
    let bytes = ifname.as_bytes();
    // SAFETY: ifreq is plain data; zeroed, then the name is copied in below.
    let mut req: libc::ifreq = unsafe { std::mem::zeroed() };
    if bytes.len() >= req.ifr_name.len() || bytes.contains(&0) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("interface name {ifname:?} is not a valid name"),
        ));
    }
    for (d, s) in req.ifr_name.iter_mut().zip(bytes) {
        *d = *s as libc::c_char;
    }
    // SAFETY: `req` is a valid ifreq with a NUL-terminated name; the kernel fills the flags.
    if unsafe { libc::ioctl(ctl.as_raw_fd(), libc::SIOCGIFFLAGS, &mut req) } != 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: SIOCGIFFLAGS filled the flags member of the union.
    let flags = unsafe { req.ifr_ifru.ifru_flags };
    Ok((req, flags))
}

/// Sets interface `ifname` (in `ctl`'s namespace) administratively up or down, as `ip link
/// set dev IFNAME up|down` does, in two system calls (microseconds, where `ip` takes
/// milliseconds, tens of them on a busy host).
pub fn set_interface_up(ctl: &OwnedFd, ifname: &str, up: bool) -> io::Result<()> {
    let (mut req, flags) = interface_flags(ctl, ifname)?;
    let up_flag = libc::IFF_UP as libc::c_short;
    req.ifr_ifru.ifru_flags = if up {
        flags | up_flag
    } else {
        flags & !up_flag
    };
    // SAFETY: as above; the kernel reads the name and the flags.
    if unsafe { libc::ioctl(ctl.as_raw_fd(), libc::SIOCSIFFLAGS, &req) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}
