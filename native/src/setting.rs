//! A value given for a setting outside what it allows, from any layer: the configuration error
//! the Python package raises as `ConfigError`.

/// A value given for a setting outside what the setting allows.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SettingError {
    /// A simulator asked to busy-poll from a thread under a real-time policy.
    #[error(
        "a busy-polling simulator must run under the normal scheduler, not SCHED_FIFO or SCHED_RR: \
         the kernel stops a real-time thread that never sleeps for 50 ms of every second \
         (sched_rt_runtime_us), and it would take its CPU from every other thread meanwhile"
    )]
    BusyPollRealTime,
    /// A cycle period outside 250 µs (the AKD's minimum) ..= 10 ms.
    #[error(
        "cycle period {period_us} µs is outside the allowed range 250 µs ..= 10000 µs (the AKD's minimum to \
         10 ms)"
    )]
    CyclePeriod {
        /// The period asked for, µs.
        period_us: f64,
    },
    /// A cycle period given in seconds outside 0.00025 ..= 0.01 s.
    #[error("cycle period {seconds} s is outside the allowed range 0.00025 ..= 0.01 s")]
    CyclePeriodSeconds {
        /// The period asked for, s.
        seconds: f64,
    },
    /// A SCHED_FIFO priority outside the scheduler's range.
    #[error("SCHED_FIFO priority {priority} is outside {low}..={high}")]
    Priority {
        /// The priority asked for.
        priority: i32,
        /// The lowest.
        low: i32,
        /// The highest.
        high: i32,
    },
    /// A CPU this machine does not have.
    #[error("CPU {cpu} does not exist: this machine has CPUs 0..={}", .cpus - 1)]
    Cpu {
        /// The CPU asked for.
        cpu: usize,
        /// CPUs of this machine.
        cpus: usize,
    },
    /// A CPU wake-up latency outside what a cycle may hold.
    #[error("CPU wake-up latency {us} µs is outside the allowed range 0..={max} µs")]
    CpuLatency {
        /// The latency asked for, µs.
        us: i64,
        /// The longest allowed, µs.
        max: u32,
    },
    /// A drive cycle time below the AKD's minimum.
    #[error("cycle time {cycle_ns} ns is below the AKD's minimum of {min_ns} ns (4 kHz)")]
    CycleTimeBelowMinimum {
        /// The cycle time, ns.
        cycle_ns: u32,
        /// The AKD's minimum, ns.
        min_ns: u32,
    },
    /// A drive cycle time that 0x60C2 (units times a power of ten) cannot encode exactly.
    #[error("cycle time {cycle_ns} ns has no exact encoding as units (0..=255) times a power of ten for 0x60C2")]
    CycleTimeNotEncodable {
        /// The cycle time, ns.
        cycle_ns: u32,
    },
    /// A SYNC0 shift of a whole cycle or more.
    #[error(
        "SYNC0 shift {shift_ns} ns is not within the {cycle_ns} ns cycle: allowed are -{max} to {max} ns",
        max = i64::from(*.cycle_ns) - 1
    )]
    Sync0Shift {
        /// The shift asked for, ns.
        shift_ns: i64,
        /// The cycle time, ns.
        cycle_ns: u32,
    },
    /// A virtual line that is none (an unknown product, a terminal without a coupler in front).
    #[error("line {line:?}: {error}")]
    SimLine {
        /// The line as given.
        line: String,
        /// What is wrong with it.
        error: crate::ethercat::link_spec::SimLineError,
    },
    /// A virtual AKD's mailbox size outside what the simulator builds.
    #[error("a virtual AKD's mailbox of {size} bytes: allowed are {min} to {max}")]
    MailboxSize {
        /// The size asked for.
        size: u16,
        /// The smallest.
        min: u16,
        /// The largest (the real drive's).
        max: u16,
    },
    /// A latch channel the AKD does not have.
    #[error("latch channel {channel}: the AKD has latches 1 and 2")]
    LatchChannel {
        /// The channel asked for.
        channel: u8,
    },
    /// A digital input the AKD does not have.
    #[error("digital input {input}: the AKD has inputs 1 to {count}")]
    DigitalInput {
        /// The input asked for, from 1.
        input: usize,
        /// Inputs the AKD has.
        count: usize,
    },
    /// A digital input's toggle position that is not a finite number of counts.
    #[error("toggle position {position} of digital input {input} is not a finite number of counts")]
    TogglePosition {
        /// The input, from 1.
        input: usize,
        /// The position given.
        position: f64,
    },
    /// A switch of 0x60FD by a name CiA 402 does not give one.
    #[error("switch {name:?} is not one of {}", .allowed.join(", "))]
    Switch {
        /// The name given.
        name: String,
        /// The switches' names.
        allowed: Vec<&'static str>,
    },
    /// An analog voltage that is not a finite number within the range its 16-bit object holds.
    #[error("{what} {volts} V: allowed a finite voltage within ±{max:.4} V")]
    AnalogVoltage {
        /// What it is, e.g. "analog input".
        what: &'static str,
        /// The voltage given.
        volts: f64,
        /// The largest magnitude the object holds, V.
        max: f64,
    },
    /// An SDO write with no data.
    #[error("SDO write of 0x{index:04X}:{subindex:02X} with no data")]
    EmptySdoWrite {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// An SDO write through the cycle thread of more bytes than one mailbox message carries.
    #[error(
        "SDO write of {len} bytes to 0x{index:04X}:{subindex:02X} of slave {slave}: 1 ..= {max} bytes while \
         cycling"
    )]
    SdoWriteLength {
        /// Slave position.
        slave: u16,
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// Bytes given.
        len: usize,
        /// The most allowed.
        max: usize,
    },
    /// Outputs of another length than the slave's.
    #[error("slave {slave} has {expected} bytes of outputs, {given} given")]
    OutputsLength {
        /// Slave position.
        slave: u16,
        /// The slave's output bytes.
        expected: usize,
        /// Bytes given.
        given: usize,
    },
    /// A value of another length than its mapped entry's.
    #[error("0x{index:04X}:{subindex:02X} takes {expected} bytes, {given} given")]
    EntryLength {
        /// Object index.
        index: u16,
        /// Subindex.
        subindex: u8,
        /// The entry's bytes.
        expected: usize,
        /// Bytes given.
        given: usize,
    },
    /// A mapping given in a form that is neither a fixed index nor a list of PDOs.
    #[error("a mapping is a fixed mapping index (e.g. 0x1701) or a list of PDOs, each a list of entries 0xIIIISSBB")]
    MappingForm,
    /// A process image larger than one frame carries.
    #[error(
        "process image of {bytes} bytes (outputs and inputs of every drive) does not fit one frame ({limit} \
         bytes at most): map fewer objects per drive, e.g. a flexible mapping of what the mode needs"
    )]
    ImageTooLarge {
        /// Output and input bytes.
        bytes: usize,
        /// The most one frame carries beside the clock's datagrams.
        limit: usize,
    },
    /// A process image and the supervision reads that together exceed one frame.
    #[error(
        "the process image ({image} bytes) leaves no room in one frame for the status reads of {slaves} \
         slaves ({watch} bytes)"
    )]
    SupervisionTooLarge {
        /// Output and input bytes.
        image: usize,
        /// Slaves supervised.
        slaves: usize,
        /// Bytes of the broadcast status reads.
        watch: usize,
    },
    /// A host name that resolves to no address.
    #[error(
        "{}",
        match *.role {
            "bind" => format!("cannot resolve {:?} as a host to bind", .host),
            _ => format!("UDP address {:?} resolves to nothing", .host),
        }
    )]
    UnresolvedHost {
        /// The host, as given.
        host: String,
        /// "bind" for a server, "connect" for a link.
        role: &'static str,
    },
    /// A duration that is not a finite number of seconds in the setting's range.
    #[error("{what} {seconds} s: allowed {allowed}")]
    Duration {
        /// The setting, e.g. "command timeout".
        what: &'static str,
        /// The value given, s.
        seconds: f64,
        /// What the setting allows.
        allowed: &'static str,
    },
    /// Set-point handshake bits outside those the AKD's profile position and homing take.
    #[error(
        "set-point handshake bits 0x{bits:04X}: allowed are bit 4 (0x0010, new set-point or start homing) \
         with bit 5 (0x0020, change set immediately) and bit 6 (0x0040, relative), e.g. 0x0030 or 0x0010"
    )]
    HandshakeBits {
        /// The bits given.
        bits: u16,
    },
    /// A virtual drive's position beyond any bus position (above 65535).
    #[error("no slave at position {position}: the bus has {count} slave(s)")]
    DrivePosition {
        /// The position asked for.
        position: usize,
        /// Drives on the bus.
        count: usize,
    },
    /// A virtual slave asked for what another kind of slave does (a fault of a terminal, the
    /// I/O of a terminal of an AKD).
    #[error("{what} needs {needs}: the slave at position {position} is an {product}")]
    WrongSlave {
        /// Its position.
        position: usize,
        /// The product it is, as a line spec names it.
        product: &'static str,
        /// What was asked, e.g. "fault".
        what: &'static str,
        /// The kind of slave that does it, e.g. "an AKD".
        needs: &'static str,
    },
    /// A virtual terminal's input it does not have.
    #[error(
        "{kind} input {input}: the {product} at position {position} has {}",
        if *.count == 0 { format!("no {} inputs", .kind) } else { format!("{} inputs 1 to {}", .kind, .count) }
    )]
    TerminalInput {
        /// Its position.
        position: usize,
        /// The product it is, as a line spec names it.
        product: &'static str,
        /// The input asked for, from 1.
        input: usize,
        /// Its inputs of that kind (0: none).
        count: usize,
        /// "digital" or "analog".
        kind: &'static str,
    },
    /// A virtual analog input terminal's input set beyond its range.
    #[error("analog input of {volts} V: allowed are -{limit} to {limit} V")]
    AnalogInputVolts {
        /// The voltage asked for.
        volts: f64,
        /// The range's bound (±).
        limit: f64,
    },
    /// A virtual terminal whose SII image cannot be read.
    #[error("the virtual {product}'s SII image cannot be read: {error}")]
    TerminalImage {
        /// The product, as a line spec names it.
        product: &'static str,
        /// What is wrong with the image.
        error: crate::ethercat::sii::SiiError,
    },
    /// A virtual slave's port its ESC does not have.
    #[error("port {port}: the {product} at position {position} has ports {ports}")]
    NoSuchPort {
        /// Its position.
        position: usize,
        /// The product it is, as a line spec names it.
        product: &'static str,
        /// The port asked for.
        port: usize,
        /// The ports it has, e.g. "0, 1".
        ports: String,
    },
    /// A port of a virtual slave that no cable of the virtual line reaches.
    #[error("no cable at port {port} of the {product} at position {position}: {why}")]
    NoCable {
        /// Its position.
        position: usize,
        /// The product it is, as a line spec names it.
        product: &'static str,
        /// The port asked for.
        port: usize,
        /// Why none does.
        why: &'static str,
    },
    /// A cable fault spoiling one frame in every 0, or in a negative number of frames.
    #[error("one frame in every {every}: allowed are 1 (each frame) or more")]
    FrameSpacing {
        /// The spacing given.
        every: i64,
    },
    /// A burst of simulated line faults of a negative number of frames.
    #[error("{frames} frames: allowed are 0 (ends the burst) or more")]
    FrameCount {
        /// The number asked for.
        frames: i64,
    },
    /// An interface name with a NUL byte, which the OS cannot take.
    #[error("interface name {name:?} contains a NUL byte")]
    InterfaceName {
        /// The name.
        name: String,
    },
    /// An address for EoE that is not in its form.
    #[error("{what} {value:?} is not of the form {form}")]
    Address {
        /// The field ("IP address", "MAC address", ...).
        what: &'static str,
        /// The text given.
        value: String,
        /// The form it must have.
        form: &'static str,
    },
}
