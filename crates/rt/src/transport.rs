//! Transports: how a node's frames reach the next node on the ring. One small trait, two
//! implementations: UDP datagrams on loopback, and raw Ethernet frames (AF_PACKET,
//! EtherType 0x88B5) on veth links between network namespaces.

use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::os::fd::{AsRawFd, OwnedFd, RawFd};
use std::sync::Arc;

use ringsync_wire::ethernet::{ETH_HEADER_LEN, ETHERTYPE, EthernetFrame, emit_header};
use ringsync_wire::{CRC_LEN, HEADER_LEN};

use crate::netns::VethRing;
use crate::run::RtError;
use crate::sys;

/// Largest PDU the runtime handles \[bytes\] (an Ethernet payload).
pub const MAX_PDU: usize = 1500;

/// One node's attachment to the ring: it sends to the next node and receives from the
/// previous one.
pub trait Port: Send {
    /// Sends one PDU to the next node.
    fn send(&mut self, pdu: &[u8]) -> io::Result<()>;
    /// Takes one received PDU into `buf` if one is waiting: its length. Frames that are not
    /// ringsync's at the link layer come back as length 0 (counted by the caller as garbage).
    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>>;
    /// The descriptor that becomes readable when a frame is waiting.
    fn rx_fd(&self) -> RawFd;
    /// The UDP address frames for this node go to (UDP transport only).
    fn udp_addr(&self) -> Option<SocketAddr> {
        None
    }
    /// Sends one PDU to the previous node, backward round the ring (a frame turned back
    /// beside a broken link, or the master's port B). Unsupported by default.
    fn send_back(&mut self, _pdu: &[u8]) -> io::Result<()> {
        Err(io::Error::from(io::ErrorKind::Unsupported))
    }
    /// Takes one PDU that came backward from the next node, as [`Port::recv`]. None by
    /// default.
    fn recv_back(&mut self, _buf: &mut [u8]) -> io::Result<Option<usize>> {
        Ok(None)
    }
    /// The descriptor that becomes readable when a frame came backward (None: no such
    /// direction).
    fn back_fd(&self) -> Option<RawFd> {
        None
    }
    /// Asks the kernel to stamp every frame this port receives with the instant it reached
    /// the port's socket (`SO_TIMESTAMPNS`), before the node's process woke to read it.
    /// Unsupported by default.
    fn enable_kernel_stamps(&mut self) -> io::Result<()> {
        Err(io::Error::from(io::ErrorKind::Unsupported))
    }
    /// The kernel's receive stamp of the frame the last [`Port::recv`] or
    /// [`Port::recv_back`] returned [ns of `CLOCK_REALTIME`]; `None` when stamps are off or
    /// the kernel gave none.
    fn kernel_stamp(&self) -> Option<i64> {
        None
    }
    /// Whether the link behind (frames arrive on it) and the link ahead (frames leave on
    /// it) are up with their carrier, as the interfaces' PHYs report; `None`: this
    /// transport cannot tell.
    fn links_up(&self) -> Option<[bool; 2]> {
        None
    }
}

/// Which transport.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TransportKind {
    /// UDP on 127.0.0.1, one socket per node.
    Udp,
    /// Raw Ethernet on a ring of veth pairs, each node in its own network namespace.
    Veth,
    /// Raw Ethernet on the host's own interfaces: a ring of node processes started by hand
    /// from a plan (`ringsync node`, docs/runtime.md "Real interfaces"); not opened by the
    /// runtime itself.
    Raw,
}

impl TransportKind {
    /// The name used on the command line and in outputs.
    pub fn name(self) -> &'static str {
        match self {
            TransportKind::Udp => "udp",
            TransportKind::Veth => "veth",
            TransportKind::Raw => "raw",
        }
    }

    /// Opens a ring of `nodes` ports (index 0 the master) on this transport: UDP sockets on
    /// loopback, or a ring of veth pairs between fresh network namespaces (removed when the
    /// last holder of [`OpenRing::veth`] drops it, after the ports are closed).
    pub fn open(self, nodes: usize) -> Result<OpenRing, RtError> {
        let io = |context: &str| {
            let context = context.to_string();
            move |source| RtError::Io { context, source }
        };
        Ok(match self {
            TransportKind::Raw => {
                return Err(RtError::Config(
                    "a ring on the host's own interfaces runs as node processes started from a plan: `ringsync node plan`, then `ringsync node slave|master` (docs/runtime.md, \"Real interfaces\")".into(),
                ));
            }
            TransportKind::Veth => {
                let ring = Arc::new(VethRing::create(nodes)?);
                let ports = (0..nodes)
                    .map(|i| VethPort::open(&ring, i).map(|p| Box::new(p) as Box<dyn Port>))
                    .collect::<io::Result<_>>()
                    .map_err(io("opening raw sockets in the namespaces"))?;
                OpenRing {
                    ports,
                    veth: Some(ring),
                }
            }
            TransportKind::Udp => OpenRing {
                ports: udp_ring(nodes)
                    .map_err(io("opening UDP sockets on 127.0.0.1"))?
                    .into_iter()
                    .map(|p| Box::new(p) as Box<dyn Port>)
                    .collect(),
                veth: None,
            },
        })
    }
}

/// A ring of open ports.
pub struct OpenRing {
    /// Node i's port at index i (0 the master).
    pub ports: Vec<Box<dyn Port>>,
    /// The namespaces and links behind a veth ring.
    pub veth: Option<Arc<VethRing>>,
}

/// A node's two UDP sockets (frames moving forward round the ring, and backward) and
/// where its frames go: the next node's forward socket, the previous node's backward one.
#[derive(Debug)]
pub struct UdpPort {
    sock: UdpSocket,
    next: SocketAddr,
    /// The backward socket and the previous node's (none for a node process's port).
    back: Option<(UdpSocket, SocketAddr)>,
    /// Kernel receive stamps: off (`None`), or the last frame's (`Some`).
    stamp: Option<Option<i64>>,
}

/// `nodes` pairs of UDP sockets on 127.0.0.1 (ephemeral ports): each node sends forward to
/// the next, the last to the first, and backward to the one before.
pub fn udp_ring(nodes: usize) -> io::Result<Vec<UdpPort>> {
    let open = || {
        (0..nodes)
            .map(|_| {
                let s = UdpSocket::bind("127.0.0.1:0")?;
                s.set_nonblocking(true)?;
                Ok(s)
            })
            .collect::<io::Result<Vec<_>>>()
    };
    let (socks, backs) = (open()?, open()?);
    let addrs_of = |v: &[UdpSocket]| {
        v.iter()
            .map(|s| s.local_addr())
            .collect::<io::Result<Vec<_>>>()
    };
    let (addrs, back_addrs) = (addrs_of(&socks)?, addrs_of(&backs)?);
    Ok(socks
        .into_iter()
        .zip(backs)
        .enumerate()
        .map(|(i, (sock, back))| UdpPort {
            sock,
            next: addrs[(i + 1) % nodes],
            back: Some((back, back_addrs[(i + nodes - 1) % nodes])),
            stamp: None,
        })
        .collect())
}

/// One datagram from `sock` if one is waiting (see [`UdpPort`]'s `recv`).
fn udp_recv(
    sock: &UdpSocket,
    buf: &mut [u8],
    stamp: &mut Option<Option<i64>>,
) -> io::Result<Option<usize>> {
    loop {
        let got = match stamp {
            Some(st) => sys::recv_stamped(sock.as_raw_fd(), buf).map(|r| {
                r.map(|(len, t)| {
                    *st = t;
                    len
                })
            }),
            None => sock.recv_from(buf).map(|(len, _)| Some(len)),
        };
        match got {
            Ok(got) => return Ok(got),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(None),
            // A send to a closed port (a killed node) reports ECONNREFUSED on a later
            // call of the sender's socket: not a received frame.
            Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => continue,
            Err(e) => return Err(e),
        }
    }
}

impl UdpPort {
    /// A node's port of its own (one process per node): `sock` bound, non-blocking, sending
    /// to `next`. It has no backward socket (a node process runs a whole ring).
    pub fn single(sock: UdpSocket, next: SocketAddr) -> UdpPort {
        UdpPort {
            sock,
            next,
            back: None,
            stamp: None,
        }
    }

    /// This port's address.
    pub fn addr(&self) -> io::Result<SocketAddr> {
        self.sock.local_addr()
    }
}

impl Port for UdpPort {
    fn send(&mut self, pdu: &[u8]) -> io::Result<()> {
        self.sock.send_to(pdu, self.next).map(|_| ())
    }
    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        udp_recv(&self.sock, buf, &mut self.stamp)
    }
    fn enable_kernel_stamps(&mut self) -> io::Result<()> {
        sys::enable_rx_stamps(self.sock.as_raw_fd())?;
        if let Some((s, _)) = &self.back {
            sys::enable_rx_stamps(s.as_raw_fd())?;
        }
        self.stamp = Some(None);
        Ok(())
    }
    fn kernel_stamp(&self) -> Option<i64> {
        self.stamp.flatten()
    }
    fn rx_fd(&self) -> RawFd {
        self.sock.as_raw_fd()
    }
    fn udp_addr(&self) -> Option<SocketAddr> {
        self.sock.local_addr().ok()
    }
    fn send_back(&mut self, pdu: &[u8]) -> io::Result<()> {
        match &self.back {
            Some((s, prev)) => s.send_to(pdu, prev).map(|_| ()),
            None => Err(io::Error::from(io::ErrorKind::Unsupported)),
        }
    }
    fn recv_back(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        match &self.back {
            Some((s, _)) => udp_recv(s, buf, &mut self.stamp),
            None => Ok(None),
        }
    }
    fn back_fd(&self) -> Option<RawFd> {
        self.back.as_ref().map(|(s, _)| s.as_raw_fd())
    }
}

/// A send-only UDP socket aimed at one node (for injecting frames).
#[derive(Debug)]
pub struct UdpSender {
    sock: UdpSocket,
    to: SocketAddr,
}

impl UdpSender {
    /// A socket on 127.0.0.1 that sends to `to`.
    pub fn new(to: SocketAddr) -> io::Result<UdpSender> {
        Ok(UdpSender {
            sock: UdpSocket::bind("127.0.0.1:0")?,
            to,
        })
    }
}

impl Port for UdpSender {
    fn send(&mut self, pdu: &[u8]) -> io::Result<()> {
        self.sock.send_to(pdu, self.to).map(|_| ())
    }
    fn recv(&mut self, _: &mut [u8]) -> io::Result<Option<usize>> {
        Ok(None)
    }
    fn rx_fd(&self) -> RawFd {
        self.sock.as_raw_fd()
    }
}

/// A send-only raw socket on one veth link (for injecting frames).
#[derive(Debug)]
pub struct RawSender {
    fd: OwnedFd,
    src: [u8; 6],
    frame: Vec<u8>,
}

impl RawSender {
    /// Sends on `fd` with a source address of its own (node 0xF0 + `i`).
    pub fn new(fd: OwnedFd, i: usize) -> RawSender {
        RawSender {
            fd,
            src: mac(0xF0 + i),
            frame: vec![0; ETH_HEADER_LEN + MAX_PDU],
        }
    }
}

impl Port for RawSender {
    fn send(&mut self, pdu: &[u8]) -> io::Result<()> {
        let len = ethernet_frame(&mut self.frame, self.src, pdu)?;
        sys::send(self.fd.as_raw_fd(), &self.frame[..len]).map(|_| ())
    }
    fn recv(&mut self, _: &mut [u8]) -> io::Result<Option<usize>> {
        Ok(None)
    }
    fn rx_fd(&self) -> RawFd {
        self.fd.as_raw_fd()
    }
}

/// The locally administered MAC address of node `i` (0 = master): 02:72:73:00:00:i.
pub fn mac(i: usize) -> [u8; 6] {
    [0x02, 0x72, 0x73, 0x00, (i >> 8) as u8, i as u8]
}

/// A node's two raw sockets: one on the link from the previous node, one on the link to
/// the next.
#[derive(Debug)]
pub struct VethPort {
    rx: OwnedFd,
    tx: OwnedFd,
    src: [u8; 6],
    frame: Vec<u8>,
    /// A control socket in the interfaces' namespace, and their names: to read their link
    /// state.
    ctl: OwnedFd,
    names: [String; 2],
    /// Kernel receive stamps: off (`None`), or the last frame's (`Some`).
    stamp: Option<Option<i64>>,
}

impl VethPort {
    /// Sockets on node `i`'s interfaces of `ring`.
    pub fn open(ring: &VethRing, i: usize) -> io::Result<VethPort> {
        let (ns, rx_if, tx_if) = (ring.netns(i), ring.in_if(i), ring.out_if(i));
        VethPort::open_named(Some(&ns), &rx_if, &tx_if, i)
    }

    /// Sockets of node `i` on interfaces `rx_if` (frames from the previous node) and `tx_if`
    /// (to the next), opened in network namespace `netns` when given (a thread enters it,
    /// opens them and ends), on the host's interfaces otherwise.
    pub fn open_named(
        netns: Option<&str>,
        rx_if: &str,
        tx_if: &str,
        i: usize,
    ) -> io::Result<VethPort> {
        let (rx, tx, ctl) = std::thread::scope(|s| {
            s.spawn(|| -> io::Result<(OwnedFd, OwnedFd, OwnedFd)> {
                if let Some(ns) = netns {
                    sys::enter_netns(ns)?;
                }
                Ok((
                    sys::packet_socket(rx_if, ETHERTYPE)?,
                    sys::packet_socket(tx_if, ETHERTYPE)?,
                    sys::control_socket()?,
                ))
            })
            .join()
            .map_err(|_| io::Error::other("socket thread panicked"))?
        })?;
        Ok(VethPort {
            rx,
            tx,
            src: mac(i),
            frame: vec![0; ETH_HEADER_LEN + MAX_PDU],
            ctl,
            names: [rx_if.to_string(), tx_if.to_string()],
            stamp: None,
        })
    }

    /// A socket that sends onto node `i`'s outgoing link (for injecting frames).
    pub fn injector(ring: &VethRing, i: usize) -> io::Result<OwnedFd> {
        let (ns, tx_if) = (ring.netns(i), ring.out_if(i));
        std::thread::scope(|s| {
            s.spawn(|| -> io::Result<OwnedFd> {
                sys::enter_netns(&ns)?;
                sys::packet_socket(&tx_if, ETHERTYPE)
            })
            .join()
            .map_err(|_| io::Error::other("socket thread panicked"))?
        })
    }
}

/// Writes `pdu` into `frame` as an Ethernet frame (broadcast destination, padded to the
/// 60-byte minimum): its length.
pub fn ethernet_frame(frame: &mut [u8], src: [u8; 6], pdu: &[u8]) -> io::Result<usize> {
    if pdu.len() > MAX_PDU || frame.len() < ETH_HEADER_LEN + MAX_PDU {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("PDU of {} bytes exceeds {MAX_PDU}", pdu.len()),
        ));
    }
    emit_header(frame, [0xFF; 6], src).map_err(|e| io::Error::other(e.to_string()))?;
    frame[ETH_HEADER_LEN..ETH_HEADER_LEN + pdu.len()].copy_from_slice(pdu);
    let len = (ETH_HEADER_LEN + pdu.len()).max(60);
    frame[ETH_HEADER_LEN + pdu.len()..len].fill(0);
    Ok(len)
}

impl VethPort {
    /// One ringsync PDU read from `fd` into `buf` if one is waiting (0: not ringsync's).
    fn read(&mut self, fd: RawFd, buf: &mut [u8]) -> io::Result<Option<usize>> {
        let len = match &mut self.stamp {
            Some(st) => match sys::recv_stamped(fd, &mut self.frame)? {
                Some((len, t)) => {
                    *st = t;
                    len
                }
                None => return Ok(None),
            },
            None => match sys::recv(fd, &mut self.frame)? {
                Some(len) => len,
                None => return Ok(None),
            },
        };
        let Ok(eth) = EthernetFrame::new_checked(&self.frame[..len]) else {
            return Ok(Some(0));
        };
        let Ok(payload) = eth.ringsync_payload() else {
            return Ok(Some(0));
        };
        // Drop the Ethernet padding: the PDU's own header gives its length.
        let pdu_len = if payload.len() >= HEADER_LEN {
            let len = usize::from(u16::from_le_bytes([payload[10], payload[11]]));
            (HEADER_LEN + len + CRC_LEN).min(payload.len())
        } else {
            payload.len()
        };
        let n = pdu_len.min(buf.len());
        buf[..n].copy_from_slice(&payload[..n]);
        Ok(Some(n))
    }
}

impl Port for VethPort {
    fn links_up(&self) -> Option<[bool; 2]> {
        // An interface that cannot be read (gone) counts as down.
        Some(
            self.names
                .each_ref()
                .map(|n| sys::interface_running(&self.ctl, n).unwrap_or(false)),
        )
    }
    fn send(&mut self, pdu: &[u8]) -> io::Result<()> {
        let len = ethernet_frame(&mut self.frame, self.src, pdu)?;
        sys::send(self.tx.as_raw_fd(), &self.frame[..len]).map(|_| ())
    }
    fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        self.read(self.rx.as_raw_fd(), buf)
    }
    fn enable_kernel_stamps(&mut self) -> io::Result<()> {
        sys::enable_rx_stamps(self.rx.as_raw_fd())?;
        sys::enable_rx_stamps(self.tx.as_raw_fd())?;
        self.stamp = Some(None);
        Ok(())
    }
    fn kernel_stamp(&self) -> Option<i64> {
        self.stamp.flatten()
    }
    fn rx_fd(&self) -> RawFd {
        self.rx.as_raw_fd()
    }
    /// On the link from the previous node, the other way.
    fn send_back(&mut self, pdu: &[u8]) -> io::Result<()> {
        let len = ethernet_frame(&mut self.frame, self.src, pdu)?;
        sys::send(self.rx.as_raw_fd(), &self.frame[..len]).map(|_| ())
    }
    /// From the link to the next node, the other way.
    fn recv_back(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        self.read(self.tx.as_raw_fd(), buf)
    }
    fn back_fd(&self) -> Option<RawFd> {
        Some(self.tx.as_raw_fd())
    }
}

#[cfg(test)]
mod tests {
    use super::{Port, UdpPort};
    use crate::clock::Clock;
    use std::net::UdpSocket;

    /// A kernel receive stamp is when the datagram reached the socket (within the send
    /// call on loopback), not when it was read 50 ms later; without stamps there is none.
    /// (The first socket to ask turns stamping on for the whole kernel a moment later,
    /// meanwhile stamping at the read: a few tries.)
    #[test]
    fn a_kernel_stamp_is_the_arrival_not_the_read() {
        let a = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let b = UdpSocket::bind("127.0.0.1:0").expect("bind");
        b.set_nonblocking(true).expect("non-blocking");
        let to_b = b.local_addr().expect("address");
        let mut rx = UdpPort::single(b, a.local_addr().expect("address"));
        let mut clock = Clock::start_in(0);
        let mut buf = [0u8; 64];
        a.send_to(b"plain", to_b).expect("send");
        std::thread::sleep(std::time::Duration::from_millis(5));
        assert_eq!(rx.recv(&mut buf).expect("recv"), Some(5));
        assert_eq!(rx.kernel_stamp(), None);
        rx.enable_kernel_stamps().expect("SO_TIMESTAMPNS");
        let mut seen = Vec::new();
        for _ in 0..20 {
            let before = clock.now();
            a.send_to(b"stamped", to_b).expect("send");
            let after = clock.now();
            std::thread::sleep(std::time::Duration::from_millis(50));
            let read = clock.now();
            assert_eq!(rx.recv(&mut buf).expect("recv"), Some(7));
            let at = clock.from_realtime(rx.kernel_stamp().expect("a kernel stamp"));
            assert_eq!(rx.recv(&mut buf).expect("recv"), None);
            // The two clocks' offset is measured to well under a µs; 1 ms of margin.
            if (before - 1_000_000..=after + 1_000_000).contains(&at) {
                assert!(read - at >= 49_000_000, "stamped at {at}, read at {read}");
                return;
            }
            seen.push((before, at, read));
        }
        panic!("never stamped within its send call: (sent, stamped, read) {seen:?}");
    }
}
