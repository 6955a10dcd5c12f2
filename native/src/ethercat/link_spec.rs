//! The link spec: the one text that names a bus, as the node's `link` parameter, the command
//! line and `Master(link)` take it. It is parsed here once, with no I/O, so every layer that
//! checks a spec accepts and refuses the same ones; opening it is left to a layer that may see
//! both the links and the simulator. The virtual AKDs' options are the spec's words too
//! ([`MissedFrames`], [`Pace`]), so akd-sim, the bindings and the virtual AKD take them from here,
//! and so is a virtual line's list of slaves ([`SimLine`] of [`SimProduct`]s), which `sim:SPEC`
//! and `akd-sim --line SPEC` both name.

use std::fmt;
use std::str::FromStr;

/// Why a text is not a link spec; its text names the allowed forms.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LinkSpecError {
    /// `sim:N` with N not a number in 1..=`max`.
    #[error("link {spec:?}: the number of virtual AKDs must be 1..={max} (or name the slaves, sim:P1,P2,...)")]
    SimCount {
        /// The spec as given.
        spec: String,
        /// The most virtual AKDs a bus may hold (the link spec's `MAX_SIM_COUNT`).
        max: usize,
    },
    /// `sim:SPEC` whose SPEC is no line of slaves the simulator makes.
    #[error("link {spec:?}: {error}")]
    SimLine {
        /// The spec as given.
        spec: String,
        /// What is wrong with the line.
        error: SimLineError,
    },
    /// `sim...?` with an option other than `missed=late|lost|warn` or `pace=real|immediate`,
    /// or one given twice.
    #[error(
        "link {spec:?}: the virtual AKDs take options after '?', joined by '&', each once: \
     missed=late (the default: a frame that comes late is missed and more than seven \
     raise F125, as the real drive judges), missed=lost (only frames lost on the line \
     are missed) or missed=warn (judged as the real drive, but a would-be F125 is \
     counted and warned of instead of raised, for a host whose master thread is not \
     real-time); pace=real (the default: AL requests and mailbox answered as slowly as \
     the real drive answers them) or pace=immediate (at once, for tests that need speed)"
    )]
    SimOption {
        /// The spec as given.
        spec: String,
    },
    /// An interface name followed by an option other than `busy_poll=US` with US in 0..=`max`.
    #[error(
        "link {spec:?}: a network interface takes one option, ?busy_poll=US with US in 0..={max}: \
     how many µs the master busy-polls for the returning frame before it sleeps (0, the \
     default: it sleeps at once)"
    )]
    InterfaceOption {
        /// The spec as given.
        spec: String,
        /// The longest busy poll (the link spec's `MAX_BUSY_POLL_US`).
        max: u32,
    },
    /// `udp://` without `HOST:PORT`, or with a port outside 1..=65535.
    // The port range as the node's parameter check has always named it.
    #[error("link {spec:?} is no udp://HOST:PORT with a port in 1..65535")]
    UdpAddress {
        /// The spec as given.
        spec: String,
    },
    /// None of the forms (empty, or a path or an address without `udp://`).
    #[error("link {spec:?} is none of {}", LinkSpecError::allowed_forms(*.max_sim_count))]
    Unknown {
        /// The spec as given.
        spec: String,
        /// As for [`SimCount`](LinkSpecError::SimCount), to name the allowed N.
        max_sim_count: usize,
    },
}

impl LinkSpecError {
    /// The forms a link spec takes, with N's range up to `max_sim_count`: what a spec that is
    /// none of them is told, and what the node's parameter check names as allowed.
    pub fn allowed_forms(max_sim_count: usize) -> String {
        format!(
            "'sim', 'sim:N' (N 1..={max_sim_count} AKDs), 'sim:P1,P2,...' (the slaves in order, each one of {}; \
             any of them with options '?missed=late|lost|warn', '?pace=real|immediate', joined by '&'), \
             'udp://HOST:PORT' or a network interface name (with '?busy_poll=US' to busy-poll for the returning \
             frame)",
            SimProduct::allowed()
        )
    }
}

/// The most virtual AKDs one in-process bus may hold: far more drives than one node moves, and
/// few enough that a mistyped count does not build a bus that takes seconds per frame.
pub const MAX_SIM_COUNT: usize = 64;

/// The longest a raw link busy-polls for a frame to come back, in µs (`IFACE?busy_poll=US`):
/// a round trip on a real line of many drives takes tens of µs, and a 1 kHz cycle has 1000.
pub const MAX_BUSY_POLL_US: u32 = 1000;

named_variants! {
    /// How a virtual AKD judges that it missed frames (F125, "Synchronization lost", after more
    /// than seven): the link spec names it (`sim:N?missed=warn`), akd-sim takes it (`--missed`),
    /// and the virtual AKD applies it. A real AKD always judges [`Late`](MissedFrames::Late).
    #[derive(Default)]
    pub enum MissedFrames {
        /// By time, as the real AKD does: a frame is missed once half a cycle passed after it was
        /// due, so a master thread the host runs late faults the drive.
        #[default]
        Late => "late",
        /// By the frames the line lost before they reached the drive (a lost burst, a pulled
        /// cable): a late frame is not a missed one. It cannot see a master that stopped sending.
        Lost => "lost",
        /// By time, as the real AKD does, but where the real drive would raise F125 the virtual
        /// one counts it as a would-be F125 (and akd-sim warns) and goes on: for a robot developed
        /// on a host that stalls the master thread now and then. Frames lost on the line still
        /// count as [`Lost`](MissedFrames::Lost) counts them, so a pulled cable still faults.
        Warn => "warn",
    }
    /// The option's value as the link spec writes it: "late", "lost" or "warn".
    fn name;
}

impl MissedFrames {
    /// The judgement named `name` ("late", "lost" or "warn").
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }
}

named_variants! {
    /// How fast virtual AKDs' firmware answers AL requests and the mailbox (`sim?pace=...`,
    /// akd-sim `--pace`): as the real drive (the default), or at once, for tests that open many
    /// buses and are not about the drive's pace.
    #[derive(Default)]
    pub enum Pace {
        /// The real drive's delays ([`crate::sim::Timing::REAL_DRIVE`]): Init→PreOp 17.5 ms the
        /// first time after power-up and 4.5 ms later, the other AL requests 4.5 ms, the first
        /// mailbox reply 30 ms after the request and later ones 1 ms.
        #[default]
        Real => "real",
        /// Every request handled before the next frame.
        Immediate => "immediate",
    }
    /// The option's value as the link spec writes it: "real" or "immediate".
    fn name;
}

impl Pace {
    /// The pace named `name`.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }
}

named_variants! {
    /// A slave the built-in simulator makes, as a line's spec names it (`sim:ek1100,el1004,akd`,
    /// `akd-sim --line ...`): the virtual AKD, and Beckhoff terminals built from their SII images
    /// (docs/howto/simulator.md says what each is made from and where the evidence is thin).
    pub enum SimProduct {
        /// A Kollmorgen AKD, the virtual AKD.
        Akd => "akd",
        /// A Beckhoff EK1100 EtherCAT coupler: the head of a station of E-bus terminals, no
        /// process data.
        Ek1100 => "ek1100",
        /// A Beckhoff EL1004: 4 digital inputs, 24 V, 3 ms filter.
        El1004 => "el1004",
        /// A Beckhoff EL1008: 8 digital inputs, 24 V, 3 ms filter.
        El1008 => "el1008",
        /// A Beckhoff EL2004: 4 digital outputs, 24 V, 0.5 A.
        El2004 => "el2004",
        /// A Beckhoff EL2008: 8 digital outputs, 24 V, 0.5 A.
        El2008 => "el2008",
        /// A Beckhoff EL3102: 2 analog inputs, ±10 V differential, 16 bit, with a mailbox (CoE).
        El3102 => "el3102",
    }
    /// The product's name as a line spec writes it, e.g. "el1004".
    fn name;
}

impl SimProduct {
    /// The product named `name`, in any case ("EL1004" or "el1004").
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name().eq_ignore_ascii_case(name))
    }

    /// Whether it sits on the E-bus of a coupler: an EL terminal, which needs an EK1100 or
    /// another terminal in front of it.
    pub fn is_ebus_terminal(self) -> bool {
        !matches!(self, SimProduct::Akd | SimProduct::Ek1100)
    }

    /// Every product's name, as an error names the allowed ones: "akd, ek1100, el1004, ...".
    pub fn allowed() -> String {
        Self::ALL.map(Self::name).join(", ")
    }
}

/// Why a text is not a virtual line (`sim:SPEC`, `akd-sim --line SPEC`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SimLineError {
    /// A slave that names no product the simulator makes (or an empty one: two commas in a
    /// row, or one at an end).
    #[error(
        "the slave at position {position}, {name:?}, is no product the simulator makes: allowed are {} \
         (the slaves in order, separated by commas, e.g. ek1100,el1004,el2004,akd)",
        SimProduct::allowed()
    )]
    UnknownProduct {
        /// Its position on the line, from 0.
        position: usize,
        /// What the spec gave there.
        name: String,
    },
    /// More slaves than a line may hold.
    #[error("a line of {count} slaves: the simulator makes lines of 1 to {max}")]
    TooMany {
        /// Slaves given.
        count: usize,
        /// The most a line holds ([`MAX_SIM_COUNT`]).
        max: usize,
    },
    /// An E-bus terminal with neither a coupler nor a terminal in front of it, which a real
    /// line cannot have: the E-bus is the coupler's.
    #[error(
        "the slave at position {position}, {}, is an E-bus terminal: an ek1100 or another terminal goes in \
         front of it, as on a real line",
        .product.name()
    )]
    NoCoupler {
        /// Its position on the line, from 0.
        position: usize,
        /// The terminal.
        product: SimProduct,
    },
}

/// The slaves of a virtual line in the order frames pass them, 1 to [`MAX_SIM_COUNT`] of them,
/// each E-bus terminal behind a coupler or another terminal.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SimLine(Vec<SimProduct>);

impl SimLine {
    /// A line of `count` AKDs (`sim:N`, `akd-sim --count N`).
    pub fn akds(count: usize) -> Result<Self, SimLineError> {
        Self::of(vec![SimProduct::Akd; count])
    }

    /// The line of `products` in order, checked.
    pub fn of(products: Vec<SimProduct>) -> Result<Self, SimLineError> {
        if products.is_empty() || products.len() > MAX_SIM_COUNT {
            return Err(SimLineError::TooMany { count: products.len(), max: MAX_SIM_COUNT });
        }
        for (position, &product) in products.iter().enumerate() {
            let behind_a_coupler = position > 0 && products[position - 1] != SimProduct::Akd;
            if product.is_ebus_terminal() && !behind_a_coupler {
                return Err(SimLineError::NoCoupler { position, product });
            }
        }
        Ok(SimLine(products))
    }

    /// The slaves, in order.
    pub fn products(&self) -> &[SimProduct] {
        &self.0
    }

    /// Number of slaves.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Always false: a line has at least one slave.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Whether every slave is an AKD (a line `sim:N` names).
    pub fn only_akds(&self) -> bool {
        self.0.iter().all(|p| *p == SimProduct::Akd)
    }
}

impl FromStr for SimLine {
    type Err = SimLineError;

    /// The slaves' names in order, separated by commas: `ek1100,el1004,el2004,akd`.
    fn from_str(spec: &str) -> Result<Self, Self::Err> {
        let names: Vec<&str> = spec.split(',').collect();
        if names.len() > MAX_SIM_COUNT {
            return Err(SimLineError::TooMany { count: names.len(), max: MAX_SIM_COUNT });
        }
        let products = names
            .iter()
            .enumerate()
            .map(|(position, name)| {
                SimProduct::parse(name.trim())
                    .ok_or_else(|| SimLineError::UnknownProduct { position, name: (*name).to_owned() })
            })
            .collect::<Result<_, _>>()?;
        Self::of(products)
    }
}

impl fmt::Display for SimLine {
    /// The names in order, separated by commas.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0.iter().map(|p| p.name()).collect::<Vec<_>>().join(","))
    }
}

/// A bus named by a link spec.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LinkSpec {
    /// `sim` (one AKD), `sim:N` (N AKDs) or `sim:P1,P2,...` (the slaves in order), optionally
    /// with options after `?`, joined by `&`: `missed=late|lost|warn`, `pace=real|immediate`.
    /// A virtual line in this process.
    Sim {
        /// The slaves, 1..=[`MAX_SIM_COUNT`] of them.
        line: SimLine,
        /// How its AKDs judge missed frames: `late` (the default, as the real drive), `lost` or
        /// `warn`.
        missed: MissedFrames,
        /// How fast its AKDs' firmware answers: `real` (the default) or `immediate`.
        pace: Pace,
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
        /// the CPU it spins on (see [`RawLink`](crate::ethercat::link::raw::RawLink)).
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

/// `sim`, `sim:N`, `sim:P1,P2,...`, each optionally followed by `?` and options joined by `&`,
/// each at most once: `missed=late|lost|warn`, `pace=real|immediate`.
fn parse_sim(spec: &str) -> Result<LinkSpec, LinkSpecError> {
    let (bus, options) = spec.split_once('?').map_or((spec, None), |(bus, options)| (bus, Some(options)));
    let refused = || LinkSpecError::SimOption { spec: spec.to_owned() };
    let (mut missed, mut pace) = (None, None);
    for option in options.map(|o| o.split('&')).into_iter().flatten() {
        let parsed = match option.split_once('=') {
            Some(("missed", value)) if missed.is_none() => MissedFrames::parse(value).map(|m| missed = Some(m)),
            Some(("pace", value)) if pace.is_none() => Pace::parse(value).map(|p| pace = Some(p)),
            _ => None,
        };
        parsed.ok_or_else(refused)?;
    }
    let count_refused = || LinkSpecError::SimCount { spec: spec.to_owned(), max: MAX_SIM_COUNT };
    let line = match bus.strip_prefix("sim:") {
        None => SimLine::akds(1),
        Some(count) if count.is_empty() || count.bytes().all(|b| b.is_ascii_digit()) => {
            let count = count.parse().ok().filter(|n| (1..=MAX_SIM_COUNT).contains(n)).ok_or_else(count_refused)?;
            SimLine::akds(count)
        }
        Some(slaves) => slaves.parse(),
    }
    .map_err(|error| LinkSpecError::SimLine { spec: spec.to_owned(), error })?;
    Ok(LinkSpec::Sim { line, missed: missed.unwrap_or_default(), pace: pace.unwrap_or_default() })
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
    /// The spec in the form it was parsed from (`sim:1` for `sim`, `sim:N` for a line of N AKDs
    /// however named, a line's products in lower case).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkSpec::Sim { line, missed, pace } => {
                if line.only_akds() {
                    write!(f, "sim:{}", line.len())?;
                } else {
                    write!(f, "sim:{line}")?;
                }
                let missed = (*missed != MissedFrames::default()).then(|| format!("missed={}", missed.name()));
                let pace = (*pace != Pace::default()).then(|| format!("pace={}", pace.name()));
                let options: Vec<String> = missed.into_iter().chain(pace).collect();
                if !options.is_empty() {
                    write!(f, "?{}", options.join("&"))?;
                }
                Ok(())
            }
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
        let sim = |count, missed, pace| Ok(LinkSpec::Sim { line: SimLine::akds(count).unwrap(), missed, pace });
        let (late, lost, warn) = (MissedFrames::Late, MissedFrames::Lost, MissedFrames::Warn);
        let (real, immediate) = (Pace::Real, Pace::Immediate);
        assert_eq!("sim".parse(), sim(1, late, real));
        assert_eq!("sim:64".parse(), sim(64, late, real));
        assert_eq!("sim:2?missed=late".parse(), sim(2, late, real));
        assert_eq!("sim?missed=lost".parse(), sim(1, lost, real));
        assert_eq!("sim:6?missed=warn".parse(), sim(6, warn, real));
        assert_eq!("sim:6?pace=immediate".parse(), sim(6, late, immediate));
        assert_eq!("sim:6?pace=immediate&missed=lost".parse(), sim(6, lost, immediate));
        assert_eq!("sim:6?missed=warn&pace=real".parse(), sim(6, warn, real));
        assert_eq!("udp://127.0.0.1:34980".parse(), Ok(LinkSpec::Udp { address: "127.0.0.1:34980".into() }));
        assert_eq!("eth0".parse(), Ok(LinkSpec::Interface { name: "eth0".into(), busy_poll_us: 0 }));
        assert_eq!("eth0?busy_poll=0".parse(), Ok(LinkSpec::Interface { name: "eth0".into(), busy_poll_us: 0 }));
        assert_eq!("eth0?busy_poll=1000".parse(), Ok(LinkSpec::Interface { name: "eth0".into(), busy_poll_us: 1000 }));
        for spec in ["sim:3", "sim:3?missed=lost", "sim:3?missed=warn&pace=immediate", "sim:1?pace=immediate"] {
            assert_eq!(spec.parse::<LinkSpec>().unwrap().to_string(), spec);
        }
        for spec in ["udp://h:1", "veth0", "veth0?busy_poll=80"] {
            assert_eq!(spec.parse::<LinkSpec>().unwrap().to_string(), spec);
        }
        assert_eq!("sim:2?pace=real&missed=late".parse::<LinkSpec>().unwrap().to_string(), "sim:2");
    }

    #[test]
    fn names_the_allowed_forms() {
        for spec in ["sim:0", "sim:65", "sim:"] {
            let err = spec.parse::<LinkSpec>().unwrap_err();
            assert_eq!(err, LinkSpecError::SimCount { spec: spec.into(), max: MAX_SIM_COUNT });
            assert!(err.to_string().contains("1..=64"), "{err}");
        }
        for spec in [
            "sim?missed",
            "sim:2?missed=soon",
            "sim:2?lost",
            "sim:2?missed=lost?",
            "sim:2?missed=lost&missed=warn",
            "sim:2?pace=slow",
            "sim:2?pace=real&",
        ] {
            let err = spec.parse::<LinkSpec>().unwrap_err();
            assert_eq!(err, LinkSpecError::SimOption { spec: spec.into() });
            for named in ["missed=late", "missed=lost", "missed=warn", "pace=real", "pace=immediate"] {
                assert!(err.to_string().contains(named), "{err}");
            }
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

    #[test]
    fn a_line_names_its_slaves_in_order() {
        use SimProduct::*;
        let LinkSpec::Sim { line, .. } = "sim:ek1100,el1004,EL2004,akd,akd?pace=immediate".parse().unwrap() else {
            panic!("not a line")
        };
        assert_eq!(line.products(), [Ek1100, El1004, El2004, Akd, Akd]);
        assert!(!line.only_akds());
        let spec: LinkSpec = "sim:ek1100,el1008,el2008,el3102,akd?missed=lost".parse().unwrap();
        assert_eq!(spec.to_string(), "sim:ek1100,el1008,el2008,el3102,akd?missed=lost");
        // A line of AKDs only is sim:N however it was named.
        assert_eq!("sim:akd,akd".parse::<LinkSpec>().unwrap().to_string(), "sim:2");
        assert_eq!("ek1100, el1004 ,akd".parse::<SimLine>().unwrap().to_string(), "ek1100,el1004,akd");
        // A coupler with nothing behind it, or behind an AKD (a coupler's X2 out), is a line too.
        for spec in ["ek1100", "akd,ek1100,el2004", "ek1100,el1004,ek1100,el2004"] {
            assert!(spec.parse::<SimLine>().is_ok(), "{spec}");
        }
    }

    #[test]
    fn a_bad_line_is_named_in_one_sentence() {
        let err = "sim:ek1100,el9999,akd".parse::<LinkSpec>().unwrap_err();
        assert_eq!(
            err,
            LinkSpecError::SimLine {
                spec: "sim:ek1100,el9999,akd".into(),
                error: SimLineError::UnknownProduct { position: 1, name: "el9999".into() }
            }
        );
        let text = err.to_string();
        assert!(text.starts_with("link \"sim:ek1100,el9999,akd\": the slave at position 1, \"el9999\""), "{text}");
        assert!(text.contains("allowed are akd, ek1100, el1004, el1008, el2004, el2008, el3102"), "{text}");
        assert!(!text.contains('\n'), "{text}");
        for (spec, position, name) in [("sim:x", 0, "x"), ("sim:ek1100,,akd", 1, ""), ("sim:akd,", 1, "")] {
            let Err(LinkSpecError::SimLine { error, .. }) = spec.parse::<LinkSpec>() else { panic!("{spec} accepted") };
            assert_eq!(error, SimLineError::UnknownProduct { position, name: name.into() }, "{spec}");
        }
        for (spec, position, product) in
            [("el1004", 0, SimProduct::El1004), ("ek1100,akd,el2004", 2, SimProduct::El2004)]
        {
            let err = spec.parse::<SimLine>().unwrap_err();
            assert_eq!(err, SimLineError::NoCoupler { position, product }, "{spec}");
            assert!(err.to_string().contains("an ek1100 or another terminal goes in front of it"), "{err}");
        }
        let long = vec!["akd"; MAX_SIM_COUNT + 1].join(",");
        let err = long.parse::<SimLine>().unwrap_err();
        assert_eq!(err, SimLineError::TooMany { count: 65, max: 64 });
        assert_eq!(err.to_string(), "a line of 65 slaves: the simulator makes lines of 1 to 64");
        assert!(allowed_forms().contains("'sim:P1,P2,...'") && allowed_forms().contains("el3102"));
    }
}
