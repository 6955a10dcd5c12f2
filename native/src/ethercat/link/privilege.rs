//! Least privilege for raw Ethernet: CAP_NET_RAW is needed to open an AF_PACKET socket and
//! never after, so once one is open the process gives up every capability (effective,
//! permitted, inheritable and ambient) but the two the cycle thread may still use when it
//! starts, which is after the socket is open: CAP_SYS_NICE for a SCHED_FIFO priority and
//! CAP_IPC_LOCK for locked memory, each kept only where the process holds it.
//!
//! Linux keeps capabilities per thread and capset(2) changes only the caller's, so the other
//! threads of the process (Python's, the middleware's) drop theirs in a signal handler, as
//! libcap's psx does; /proc/self/task/*/status then tells whether every thread did.
//!
//! A process whose effective user is root is left as it is: the kernel gives root its full
//! capability set back on any execve, so dropping would protect nothing (the tools and the
//! node warn at start that root is not needed).

use std::io;
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

use crate::error::{Error, Result};

/// Capability number of CAP_NET_RAW (linux/capability.h).
pub const CAP_NET_RAW: u32 = 13;
/// Capability number of CAP_IPC_LOCK: mlockall beyond RLIMIT_MEMLOCK.
pub const CAP_IPC_LOCK: u32 = 14;
/// Capability number of CAP_SYS_NICE: a SCHED_FIFO priority beyond RLIMIT_RTPRIO.
pub const CAP_SYS_NICE: u32 = 23;
/// The capabilities kept after the drop, where held: what the cycle thread's real-time
/// settings use (see `cycle::rt`).
pub const KEPT: u64 = 1 << CAP_IPC_LOCK | 1 << CAP_SYS_NICE;

/// How long the other threads get to run the signal handler that drops their capabilities.
const THREADS_DEADLINE: Duration = Duration::from_secs(1);
const CAPABILITY_VERSION_3: u32 = 0x2008_0522;

/// The interface whose socket this process opened before it gave up CAP_NET_RAW.
static DROPPED_AFTER: OnceLock<String> = OnceLock::new();
/// One drop at a time: two masters opening at once must not interleave their rounds.
static DROPPING: Mutex<()> = Mutex::new(());

#[repr(C)]
struct CapHeader {
    version: u32,
    pid: libc::c_int,
}

#[repr(C)]
#[derive(Clone, Copy, Default)]
struct CapData {
    effective: u32,
    permitted: u32,
    inheritable: u32,
}

/// The interface after whose socket this process gave up CAP_NET_RAW, if it did.
pub fn dropped_after() -> Option<&'static str> {
    DROPPED_AFTER.get().map(String::as_str)
}

/// Drops the capabilities of every thread of the process but [`KEPT`], after the raw socket on
/// `iface` was opened. Nothing happens for root (see the module's documentation). Threads that
/// cannot be reached (they block every signal, as the two that loading rclpy starts do) keep
/// theirs: the sentence returned names them, for the master's warnings.
pub fn drop_after_open(iface: &str) -> Result<Option<String>> {
    // SAFETY: geteuid cannot fail.
    if unsafe { libc::geteuid() } == 0 {
        return Ok(None);
    }
    let _one_at_a_time = DROPPING.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    if !drop_in_this_thread() {
        return Err(Error::last_os("giving up capabilities after opening the raw socket (capset)"));
    }
    let _ = DROPPED_AFTER.set(iface.to_owned());
    let (holding, why) = match install_handler() {
        Ok(signal) => (
            reach_other_threads(signal),
            format!("they block signal {signal}, by which the other threads gave theirs up"),
        ),
        Err(why) => (
            others_holding_capabilities().into_iter().map(|(tid, _)| tid).collect(),
            format!("the signal to reach them could not be used ({why})"),
        ),
    };
    if holding.is_empty() {
        return Ok(None);
    }
    Ok(Some(format!(
        "after the raw socket on {iface:?} was open, {} kept their capabilities: {why}",
        threads(&holding)
    )))
}

/// Signals the threads that still hold capabilities until every one that can be reached gave
/// them up or [`THREADS_DEADLINE`] passed; the threads still holding some then. A thread that
/// blocks the signal is not waited for: it would run the handler only once it unblocks it.
fn reach_other_threads(signal: libc::c_int) -> Vec<libc::pid_t> {
    // SAFETY: getpid cannot fail.
    let pid = unsafe { libc::getpid() };
    let deadline = Instant::now() + THREADS_DEADLINE;
    loop {
        let holding = others_holding_capabilities();
        let reachable: Vec<libc::pid_t> =
            holding.iter().filter(|(_, thread)| !thread.blocks(signal)).map(|&(tid, _)| tid).collect();
        if reachable.is_empty() || Instant::now() > deadline {
            return holding.into_iter().map(|(tid, _)| tid).collect();
        }
        for tid in reachable {
            // SAFETY: plain tgkill(2); a thread that has ended meanwhile gives ESRCH, ignored.
            unsafe { libc::syscall(libc::SYS_tgkill, pid, tid, signal) };
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// "threads 12 (python) and 13 (dds.ev.0) of this process".
fn threads(tids: &[libc::pid_t]) -> String {
    let named: Vec<String> = tids
        .iter()
        .map(|tid| {
            let comm = std::fs::read_to_string(format!("/proc/self/task/{tid}/comm")).unwrap_or_default();
            format!("{tid} ({})", comm.trim())
        })
        .collect();
    let list = match named.split_last() {
        Some((last, [])) => return format!("thread {last} of this process"),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
        None => String::new(),
    };
    format!("threads {list} of this process")
}

/// Clears the ambient set and lowers the effective, permitted and inheritable sets of the
/// calling thread to [`KEPT`]; async-signal-safe (two system calls, no allocation).
fn drop_in_this_thread() -> bool {
    let mut header = CapHeader { version: CAPABILITY_VERSION_3, pid: 0 };
    let mut data = [CapData::default(); 2];
    // SAFETY: prctl and capget/capset with a version-3 header and the two data words it takes.
    unsafe {
        // Before the kernel had ambient capabilities (4.3) there are none to clear: EINVAL, ignored.
        libc::prctl(libc::PR_CAP_AMBIENT, libc::PR_CAP_AMBIENT_CLEAR_ALL, 0, 0, 0);
        if libc::syscall(libc::SYS_capget, &mut header as *mut CapHeader, data.as_mut_ptr()) != 0 {
            return false;
        }
        for (word, d) in data.iter_mut().enumerate() {
            let kept = (KEPT >> (32 * word)) as u32 & d.permitted;
            *d = CapData { effective: kept, permitted: kept, inheritable: 0 };
        }
        libc::syscall(libc::SYS_capset, &mut header as *mut CapHeader, data.as_ptr()) == 0
    }
}

extern "C" fn on_drop_signal(_: libc::c_int) {
    // SAFETY: errno of this thread, restored so the interrupted code sees its own.
    unsafe {
        let saved = *libc::__errno_location();
        drop_in_this_thread();
        *libc::__errno_location() = saved;
    }
}

/// Installs the handler on the highest real-time signal, once, and gives the signal. It stays
/// installed: a thread that had it blocked runs it when it unblocks, where the default action
/// would end the process.
fn install_handler() -> std::result::Result<libc::c_int, String> {
    static INSTALLED: OnceLock<std::result::Result<libc::c_int, String>> = OnceLock::new();
    let installed = INSTALLED.get_or_init(|| {
        let signal = libc::SIGRTMAX();
        // SAFETY: sigaction with a zeroed, then filled, struct; the handler is async-signal-safe.
        unsafe {
            let mut old: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(signal, std::ptr::null(), &mut old) != 0 {
                return Err(io::Error::last_os_error().to_string());
            }
            if old.sa_sigaction != libc::SIG_DFL {
                return Err(format!("signal {signal} has a handler of another library"));
            }
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_drop_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            action.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut action.sa_mask);
            if libc::sigaction(signal, &action, std::ptr::null_mut()) != 0 {
                return Err(io::Error::last_os_error().to_string());
            }
        }
        Ok(signal)
    });
    installed.clone()
}

/// The threads of this process but the calling one that hold a capability beyond [`KEPT`],
/// from /proc.
fn others_holding_capabilities() -> Vec<(libc::pid_t, ThreadStatus)> {
    // SAFETY: gettid cannot fail.
    let me = unsafe { libc::gettid() };
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return Vec::new();
    };
    tasks
        .filter_map(|task| {
            let task = task.ok()?;
            let tid = task.file_name().to_str()?.parse().ok().filter(|&tid| tid != me)?;
            // A thread that ended since the listing has no status any more.
            let thread = ThreadStatus::parse(&std::fs::read_to_string(task.path().join("status")).ok()?);
            thread.holds_more_than_kept().then_some((tid, thread))
        })
        .collect()
}

/// A thread's capability sets and blocked signals, as /proc/<pid>/task/<tid>/status gives them.
#[derive(Debug, Default, PartialEq)]
struct ThreadStatus {
    inheritable: u64,
    permitted: u64,
    effective: u64,
    ambient: u64,
    blocked: u64,
}

impl ThreadStatus {
    fn parse(status: &str) -> Self {
        let mut thread = ThreadStatus::default();
        for line in status.lines() {
            let Some((name, value)) = line.split_once(':') else { continue };
            let field = match name {
                "CapInh" => &mut thread.inheritable,
                "CapPrm" => &mut thread.permitted,
                "CapEff" => &mut thread.effective,
                "CapAmb" => &mut thread.ambient,
                "SigBlk" => &mut thread.blocked,
                _ => continue,
            };
            *field = u64::from_str_radix(value.trim(), 16).unwrap_or(0);
        }
        thread
    }

    /// A capability beyond [`KEPT`] in any of the four sets (the bounding set is not the
    /// process's to change without CAP_SETPCAP).
    fn holds_more_than_kept(&self) -> bool {
        self.inheritable != 0 || self.ambient != 0 || (self.permitted | self.effective) & !KEPT != 0
    }

    fn blocks(&self, signal: libc::c_int) -> bool {
        self.blocked & 1 << (signal - 1) != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STATUS: &str = "Name:\tpython3\nCapInh:\t0000000000000000\nCapPrm:\t0000000000802000\n\
                          CapEff:\t0000000000802000\nCapBnd:\t000001ffffffffff\nCapAmb:\t0000000000000000\n";

    #[test]
    fn status_with_net_raw_holds_more_than_kept() {
        assert!(ThreadStatus::parse(STATUS).holds_more_than_kept());
        let dropped = STATUS.replace("0000000000802000", "0000000000800000");
        assert!(!ThreadStatus::parse(&dropped).holds_more_than_kept(), "CAP_SYS_NICE alone is kept");
        let ambient = dropped.replace("CapAmb:\t0000000000000000", "CapAmb:\t0000000000800000");
        assert!(ThreadStatus::parse(&ambient).holds_more_than_kept());
        assert!(!ThreadStatus::parse("CapBnd:\t000001ffffffffff\n").holds_more_than_kept());
    }

    #[test]
    fn a_thread_blocking_every_signal_is_told_apart() {
        // What the two threads that loading rclpy starts show: all blocked but what glibc keeps.
        let thread = ThreadStatus::parse("SigBlk:\tfffffffe7ffbfeff\nCapEff:\t0000000000002000\n");
        assert_eq!(thread.effective, 1 << CAP_NET_RAW);
        assert!(thread.blocks(libc::SIGRTMAX()) && thread.blocks(libc::SIGINT));
        assert!(!thread.blocks(libc::SIGKILL) && !ThreadStatus::parse(STATUS).blocks(libc::SIGRTMAX()));
    }

    #[test]
    fn kept_are_the_real_time_ones() {
        assert_eq!(KEPT, 0x0080_4000);
        assert_eq!(KEPT & 1 << CAP_NET_RAW, 0);
    }
}
