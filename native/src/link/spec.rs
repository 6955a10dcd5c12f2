//! The link spec: the one text that names a bus, as the node's `link` parameter, the command
//! line and `Master(link)` take it. It is parsed here once, with no I/O, so every layer that
//! checks a spec accepts and refuses the same ones; opening it is left to a layer that may see
//! both the links and the simulator.

use std::fmt;
use std::str::FromStr;

pub use crate::akd_fault::MissedFrames;
pub use crate::error::LinkSpecError;

/// The most virtual AKDs one in-process bus may hold: far more drives than one node moves, and
/// few enough that a mistyped count does not build a bus that takes seconds per frame.
pub const MAX_SIM_COUNT: usize = 64;

/// The longest a raw link busy-polls for a frame to come back, in µs (`IFACE?busy_poll=US`):
/// a round trip on a real line of many drives takes tens of µs, and a 1 kHz cycle has 1000.
pub const MAX_BUSY_POLL_US: u32 = 1000;

/// A bus named by a link spec.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LinkSpec {
    /// `sim` (one) or `sim:N`, optionally `?missed=lost`: virtual AKDs in this process.
    Sim {
        /// How many virtual AKDs, 1..=[`MAX_SIM_COUNT`].
        count: usize,
        /// How they judge missed frames: `late` (the default, as the real drive) or `lost`.
        missed: MissedFrames,
    },
    /// `udp://HOST:PORT`: EtherCAT over UDP, e.g. to an akd-sim server.
    Udp {
        /// `HOST:PORT` (an IPv6 address in brackets, the port 1..=65535), resolved when the link
        /// opens.
        address: String,
    },
    /// A network interface name (raw Ethernet, needs CAP_NET_RAW), optionally
    /// `?busy_poll=US`.
    Interface {
        /// The interface, e.g. `eth0`.
        name: String,
        /// How long, in µs (0..=[`MAX_BUSY_POLL_US`]), the master keeps asking the socket for
        /// the returning frame before it sleeps until the frame comes; 0 (the default) sleeps at
        /// once. Spinning spares the thread the wake-up when the frame arrives, at the cost of
        /// the CPU it spins on (see [`RawLink`](crate::link::raw::RawLink)).
        busy_poll_us: u32,
    },
}

impl LinkSpec {
    /// Whether a bus on this link runs distributed clocks unless told otherwise: on a network
    /// interface, as TwinCAT runs the AKD; not in-process nor over UDP, where a frame's timing
    /// is the host's scheduling and the socket's, not the wire's, so SYNC0 would promise a
    /// timing the set-points do not keep.
    pub fn runs_dc_by_default(&self) -> bool {
        matches!(self, LinkSpec::Interface { .. })
    }
}

impl FromStr for LinkSpec {
    type Err = LinkSpecError;

    fn from_str(spec: &str) -> Result<Self, Self::Err> {
        if spec == "sim" || spec.starts_with("sim:") || spec.starts_with("sim?") {
            return parse_sim(spec);
        }
        if let Some(address) = spec.strip_prefix("udp://") {
            if !is_host_and_port(address) {
                return Err(LinkSpecError::UdpAddress { spec: spec.to_owned() });
            }
            return Ok(LinkSpec::Udp { address: address.to_owned() });
        }
        let (name, option) = spec.split_once('?').map_or((spec, None), |(name, option)| (name, Some(option)));
        // Interface names hold neither; anything with them is a mistyped path or address.
        if name.is_empty() || name.contains(['/', ':']) {
            return Err(LinkSpecError::Unknown { spec: spec.to_owned(), max_sim_count: MAX_SIM_COUNT });
        }
        let busy_poll_us = match option {
            None => 0,
            Some(option) => option
                .strip_prefix("busy_poll=")
                .filter(|us| us.bytes().all(|b| b.is_ascii_digit()))
                .and_then(|us| us.parse().ok())
                .filter(|us| *us <= MAX_BUSY_POLL_US)
                .ok_or_else(|| LinkSpecError::InterfaceOption { spec: spec.to_owned(), max: MAX_BUSY_POLL_US })?,
        };
        Ok(LinkSpec::Interface { name: name.to_owned(), busy_poll_us })
    }
}

/// `sim`, `sim:N`, each optionally followed by `?missed=late` or `?missed=lost`.
fn parse_sim(spec: &str) -> Result<LinkSpec, LinkSpecError> {
    let (bus, option) = spec.split_once('?').map_or((spec, None), |(bus, option)| (bus, Some(option)));
    let missed = match option.map(|o| o.strip_prefix("missed=").and_then(MissedFrames::parse)) {
        None => MissedFrames::default(),
        Some(Some(missed)) => missed,
        Some(None) => return Err(LinkSpecError::SimOption { spec: spec.to_owned() }),
    };
    let count = match bus.strip_prefix("sim:") {
        None => 1,
        Some(count) => count
            .parse()
            .ok()
            .filter(|n| (1..=MAX_SIM_COUNT).contains(n))
            .ok_or_else(|| LinkSpecError::SimCount { spec: spec.to_owned(), max: MAX_SIM_COUNT })?,
    };
    Ok(LinkSpec::Sim { count, missed })
}

/// The forms a link spec takes, as [`LinkSpecError`] names them.
pub fn allowed_forms() -> String {
    LinkSpecError::allowed_forms(MAX_SIM_COUNT)
}

/// Whether `address` is `HOST:PORT`: a host name or IPv4 address (no `:`, `/` or white space)
/// or an IPv6 address in brackets, and a port 1..=65535 in decimal digits.
fn is_host_and_port(address: &str) -> bool {
    let Some((host, port)) = address.rsplit_once(':') else {
        return false;
    };
    let host_ok = match host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        Some(v6) => !v6.is_empty() && v6.chars().all(|c| c.is_ascii_hexdigit() || c == ':'),
        None => !host.is_empty() && !host.contains([':', '/']) && !host.chars().any(char::is_whitespace),
    };
    let port_ok = port.bytes().all(|b| b.is_ascii_digit()) && port.parse::<u16>().is_ok_and(|p| p != 0);
    host_ok && port_ok
}

impl fmt::Display for LinkSpec {
    /// The spec in the form it was parsed from (`sim:1` for `sim`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkSpec::Sim { count, missed: MissedFrames::Late } => write!(f, "sim:{count}"),
            LinkSpec::Sim { count, missed } => write!(f, "sim:{count}?missed={}", missed.name()),
            LinkSpec::Udp { address } => write!(f, "udp://{address}"),
            LinkSpec::Interface { name, busy_poll_us: 0 } => f.write_str(name),
            LinkSpec::Interface { name, busy_poll_us } => write!(f, "{name}?busy_poll={busy_poll_us}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_each_form() {
        let late = MissedFrames::Late;
        assert_eq!("sim".parse(), Ok(LinkSpec::Sim { count: 1, missed: late }));
        assert_eq!("sim:64".parse(), Ok(LinkSpec::Sim { count: 64, missed: late }));
        assert_eq!("sim:2?missed=late".parse(), Ok(LinkSpec::Sim { count: 2, missed: late }));
        let lost = MissedFrames::Lost;
        assert_eq!("sim?missed=lost".parse(), Ok(LinkSpec::Sim { count: 1, missed: lost }));
        assert_eq!("sim:6?missed=lost".parse(), Ok(LinkSpec::Sim { count: 6, missed: lost }));
        assert_eq!("udp://127.0.0.1:34980".parse(), Ok(LinkSpec::Udp { address: "127.0.0.1:34980".into() }));
        assert_eq!("eth0".parse(), Ok(LinkSpec::Interface { name: "eth0".into(), busy_poll_us: 0 }));
        assert_eq!("eth0?busy_poll=0".parse(), Ok(LinkSpec::Interface { name: "eth0".into(), busy_poll_us: 0 }));
        assert_eq!("eth0?busy_poll=1000".parse(), Ok(LinkSpec::Interface { name: "eth0".into(), busy_poll_us: 1000 }));
        for spec in ["sim:3", "sim:3?missed=lost", "udp://h:1", "veth0", "veth0?busy_poll=80"] {
            assert_eq!(spec.parse::<LinkSpec>().unwrap().to_string(), spec);
        }
    }

    #[test]
    fn names_the_allowed_forms() {
        for spec in ["sim:0", "sim:65", "sim:x", "sim:"] {
            let err = spec.parse::<LinkSpec>().unwrap_err();
            assert_eq!(err, LinkSpecError::SimCount { spec: spec.into(), max: MAX_SIM_COUNT });
            assert!(err.to_string().contains("1..=64"), "{err}");
        }
        for spec in ["sim?missed", "sim:2?missed=soon", "sim:2?lost", "sim:2?missed=lost?"] {
            let err = spec.parse::<LinkSpec>().unwrap_err();
            assert_eq!(err, LinkSpecError::SimOption { spec: spec.into() });
            assert!(err.to_string().contains("?missed=late") && err.to_string().contains("?missed=lost"), "{err}");
        }
        for spec in ["eth0?busy_poll=1001", "eth0?busy_poll=", "eth0?busy_poll=+5", "eth0?spin=5", "eth0?"] {
            let err = spec.parse::<LinkSpec>().unwrap_err();
            assert_eq!(err, LinkSpecError::InterfaceOption { spec: spec.into(), max: MAX_BUSY_POLL_US });
            assert!(err.to_string().contains("?busy_poll=US") && err.to_string().contains("0..=1000"), "{err}");
        }
        for spec in ["", "/dev/x", "host:1", "?busy_poll=5"] {
            let err = spec.parse::<LinkSpec>().unwrap_err();
            assert!(err.to_string().contains("'udp://HOST:PORT'"), "{err}");
            assert!(err.to_string().contains(&allowed_forms()), "{err}");
        }
        for spec in
            ["udp://127.0.0.1", "udp://:1", "udp://h:0", "udp://h:65536", "udp://h:+1", "udp://a b:1", "udp://[]:1"]
        {
            let err = spec.parse::<LinkSpec>().unwrap_err();
            assert_eq!(err, LinkSpecError::UdpAddress { spec: spec.into() });
            assert!(err.to_string().contains("udp://HOST:PORT with a port in 1..65535"), "{err}");
        }
        for spec in ["udp://localhost:65535", "udp://[::1]:34980", "udp://10.0.0.2:1"] {
            assert!(spec.parse::<LinkSpec>().is_ok(), "{spec}");
        }
    }
}
