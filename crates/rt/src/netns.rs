//! The veth ring: one network namespace per node (master = node 0) and one veth pair per
//! hop, node i's `out` end to node i+1's `in` end, the last slave's back to the master. Built
//! with iproute2's `ip`; names carry the process id so that concurrent runs never collide,
//! and leftovers of runs that died (SIGKILL) are removed by the next run.

use std::io;
use std::process::Command;

/// Prefix of every namespace the runtime creates: `ringsync-<pid>-<node>`.
pub const NETNS_PREFIX: &str = "ringsync-";

/// What can go wrong building the ring.
#[derive(Debug, thiserror::Error)]
pub enum NetnsError {
    /// `ip` is missing or cannot run.
    #[error("cannot run `ip` (iproute2): {0}")]
    NoIp(io::Error),
    /// An `ip` command failed.
    #[error(
        "`ip {args}` failed: {stderr} (creating network namespaces needs root or CAP_SYS_ADMIN and CAP_NET_ADMIN)"
    )]
    Failed {
        /// The arguments.
        args: String,
        /// What `ip` said.
        stderr: String,
    },
}

fn ip(args: &[&str]) -> Result<(), NetnsError> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(NetnsError::NoIp)?;
    if out.status.success() {
        Ok(())
    } else {
        Err(NetnsError::Failed {
            args: args.join(" "),
            stderr: String::from_utf8_lossy(&out.stderr).trim().to_string(),
        })
    }
}

/// The namespaces and links of one run; removed on drop.
#[derive(Debug)]
pub struct VethRing {
    pid: u32,
    nodes: usize,
    created: Vec<String>,
}

impl VethRing {
    /// Builds a ring of `nodes` namespaces (master and slaves) and `nodes` veth pairs, all
    /// links up. On failure, whatever was created is removed again.
    pub fn create(nodes: usize) -> Result<VethRing, NetnsError> {
        remove_stale();
        let mut ring = VethRing {
            pid: std::process::id(),
            nodes,
            created: Vec::new(),
        };
        for i in 0..nodes {
            let ns = ring.netns(i);
            ip(&["netns", "add", &ns])?;
            ring.created.push(ns);
        }
        for i in 0..nodes {
            let j = (i + 1) % nodes;
            let (a, b) = (ring.out_if(i), ring.in_if(j));
            let (na, nb) = (ring.netns(i), ring.netns(j));
            ip(&[
                "link", "add", &a, "netns", &na, "type", "veth", "peer", "name", &b, "netns", &nb,
            ])?;
        }
        for i in 0..nodes {
            let ns = ring.netns(i);
            for dev in [ring.in_if(i), ring.out_if(i)] {
                ip(&["-n", &ns, "link", "set", "dev", &dev, "up"])?;
            }
        }
        Ok(ring)
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.nodes
    }

    /// Node i's namespace.
    pub fn netns(&self, i: usize) -> String {
        format!("{NETNS_PREFIX}{}-{i}", self.pid)
    }

    /// Node i's interface towards the next node (at most 15 characters).
    pub fn out_if(&self, i: usize) -> String {
        format!("rs{}o{i}", self.pid)
    }

    /// Node i's interface from the previous node.
    pub fn in_if(&self, i: usize) -> String {
        format!("rs{}i{i}", self.pid)
    }

    /// Where the link out of node `from` (to the next node) is switched, as when its cable
    /// is pulled and plugged in again: the receiving end, (namespace, interface). Its node's
    /// socket sees the link go, as a NIC reports a lost carrier, and a veth pair whose one
    /// end is down carries nothing either way; one end, where two would double the time
    /// the switch takes. Switch it with `sys::set_interface_up` from a thread in
    /// that namespace.
    pub fn link_end(&self, from: usize) -> (String, String) {
        let to = (from + 1) % self.nodes;
        (self.netns(to), self.in_if(to))
    }

    /// Takes node i's links down (both ends of both its veth pairs), as when its cable is
    /// pulled. Runs `ip`; call it off the real-time thread.
    pub fn take_down(&self, i: usize) -> Result<(), NetnsError> {
        let prev = (i + self.nodes - 1) % self.nodes;
        let next = (i + 1) % self.nodes;
        ip(&[
            "-n",
            &self.netns(i),
            "link",
            "set",
            "dev",
            &self.in_if(i),
            "down",
        ])?;
        ip(&[
            "-n",
            &self.netns(i),
            "link",
            "set",
            "dev",
            &self.out_if(i),
            "down",
        ])?;
        ip(&[
            "-n",
            &self.netns(prev),
            "link",
            "set",
            "dev",
            &self.out_if(prev),
            "down",
        ])?;
        ip(&[
            "-n",
            &self.netns(next),
            "link",
            "set",
            "dev",
            &self.in_if(next),
            "down",
        ])?;
        Ok(())
    }
}

impl Drop for VethRing {
    fn drop(&mut self) {
        // Deleting a namespace destroys its veth ends, and a veth pair dies with either end.
        for ns in self.created.drain(..).rev() {
            let _ = ip(&["netns", "del", &ns]);
        }
    }
}

/// The namespaces named like ours now present (`ip netns list`).
pub fn ringsync_namespaces() -> Vec<String> {
    let Ok(out) = Command::new("ip").args(["netns", "list"]).output() else {
        return Vec::new();
    };
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|n| n.starts_with(NETNS_PREFIX))
        .map(str::to_string)
        .collect()
}

/// Removes the namespaces of runs whose process no longer exists.
fn remove_stale() {
    for ns in ringsync_namespaces() {
        let pid = ns
            .strip_prefix(NETNS_PREFIX)
            .and_then(|r| r.split('-').next())
            .and_then(|p| p.parse::<u32>().ok());
        if let Some(pid) = pid
            && !std::path::Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = ip(&["netns", "del", &ns]);
        }
    }
}
