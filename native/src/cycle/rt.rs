//! Real-time settings of the cycle thread: SCHED_FIFO priority, CPU affinity, locked memory
//! and the CPUs' wake-up latency (PM QoS). Each is optional. A value outside its range is an
//! error; a setting the system does not permit (no CAP_SYS_NICE, a CPU outside the
//! container's set, a memlock limit, no write access to /dev/cpu_dma_latency) is a warning
//! that names what was refused and why, and the cycle runs without it.

use crate::error::{Result, SettingError};

/// How the cycle thread runs on the host: the options of `Axis`, `Bus` and the node's `rt.*`
/// parameters alike (`akd_ros.RealTime` in Python). The default runs it as any thread, each
/// frame awaited.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "python", pyo3::pyclass(name = "RealTime", module = "akd_ros._native", frozen, eq, get_all))]
pub struct RealTime {
    /// SCHED_FIFO priority (1..=99), or the normal scheduler when `None`.
    pub priority: Option<i32>,
    /// The CPU the thread is bound to, or any when `None`.
    pub cpu: Option<usize>,
    /// Whether to lock the process's memory (mlockall).
    pub lock_memory: bool,
    /// The CPUs' wake-up latency to hold while the thread runs, µs (see [`hold_cpu_latency`]),
    /// 0..=[`MAX_CPU_LATENCY_US`]; the system's when `None`.
    pub cpu_latency_us: Option<u32>,
    /// Whether each cycle's frame is sent without waiting for it, its return taken at the next
    /// wake-up (see [the cycle](super)).
    pub pipelined: bool,
}

/// The SCHED_FIFO priorities Linux allows.
pub fn fifo_priorities() -> (i32, i32) {
    unsafe { (libc::sched_get_priority_min(libc::SCHED_FIFO), libc::sched_get_priority_max(libc::SCHED_FIFO)) }
}

/// The longest CPU wake-up latency a cycle may ask for, µs: a second, far past any cycle.
pub const MAX_CPU_LATENCY_US: u32 = 1_000_000;

/// Where a process asks the kernel to keep every CPU's wake-up from idle within a latency
/// (PM QoS), for as long as it keeps the file open.
const CPU_DMA_LATENCY: &str = "/dev/cpu_dma_latency";

/// A CPU wake-up latency as a caller gives it, µs; refused outside 0..=[`MAX_CPU_LATENCY_US`].
pub fn cpu_latency(us: i64) -> Result<u32> {
    u32::try_from(us)
        .ok()
        .filter(|&us| us <= MAX_CPU_LATENCY_US)
        .ok_or(SettingError::CpuLatency { us, max: MAX_CPU_LATENCY_US }.into())
}

/// Checks a SCHED_FIFO priority and a CPU number before anything starts.
pub fn check(priority: Option<i32>, cpu: Option<usize>) -> Result<()> {
    let (low, high) = fifo_priorities();
    if let Some(p) = priority.filter(|p| !(low..=high).contains(p)) {
        return Err(SettingError::Priority { priority: p, low, high }.into());
    }
    let cpus = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_CONF) }.max(1) as usize;
    if let Some(c) = cpu.filter(|&c| c >= cpus.min(libc::CPU_SETSIZE as usize)) {
        return Err(SettingError::Cpu { cpu: c, cpus }.into());
    }
    Ok(())
}

fn os_error(code: i32) -> String {
    std::io::Error::from_raw_os_error(code).to_string()
}

/// Gives the calling thread SCHED_FIFO at `priority`; a warning when not permitted.
pub fn set_fifo_priority(priority: i32) -> Option<String> {
    let param = libc::sched_param { sched_priority: priority };
    match unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) } {
        0 => None,
        code => Some(format!(
            "SCHED_FIFO priority {priority} not set ({}): the cycle runs at normal priority; \
             it needs CAP_SYS_NICE or an RLIMIT_RTPRIO of at least {priority}",
            os_error(code)
        )),
    }
}

/// Binds the calling thread to `cpu`; a warning when not permitted.
pub fn set_affinity(cpu: usize) -> Option<String> {
    let code = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::pthread_setaffinity_np(libc::pthread_self(), std::mem::size_of::<libc::cpu_set_t>(), &set)
    };
    (code != 0).then(|| {
        format!(
            "CPU affinity to CPU {cpu} not set ({}): the cycle runs on any CPU (is it in this process's cpuset?)",
            os_error(code)
        )
    })
}

/// Asks the kernel to wake every CPU from idle within `us` µs for as long as the returned file
/// stays open, as cyclictest does while it runs: an idle CPU then polls or naps lightly
/// instead of halting, and a halted CPU, above all a virtual machine's vCPU, wakes the cycle
/// tens of µs late. A warning when not permitted (it needs write access to
/// `/dev/cpu_dma_latency`, root's by default).
pub fn hold_cpu_latency(us: u32) -> std::result::Result<std::fs::File, String> {
    use std::io::Write;
    let refused = |e: std::io::Error| {
        format!(
            "CPU wake-up latency of {us} µs not held ({CPU_DMA_LATENCY}: {e}): idle CPUs may sleep deeply \
             and wake the cycle late; it needs write access to {CPU_DMA_LATENCY}"
        )
    };
    let mut file = std::fs::OpenOptions::new().write(true).open(CPU_DMA_LATENCY).map_err(refused)?;
    // The kernel takes the latency as a native 32-bit integer.
    file.write_all(&(us as i32).to_ne_bytes()).map_err(refused)?;
    Ok(file)
}

/// Locks the process's memory, now and future, so page faults never stall the cycle; a
/// warning when not permitted.
pub fn lock_memory() -> Option<String> {
    if unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } == 0 {
        return None;
    }
    Some(format!(
        "memory not locked ({}): the cycle may meet page faults; it needs CAP_IPC_LOCK or a larger RLIMIT_MEMLOCK",
        std::io::Error::last_os_error()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_of_range_values_are_refused_with_the_range() {
        let (low, high) = fifo_priorities();
        assert_eq!((low, high), (1, 99));
        let message = check(Some(0), None).unwrap_err().to_string();
        assert!(message.contains("priority 0 is outside 1..=99"), "{message}");
        assert!(check(Some(100), None).is_err());
        let message = check(None, Some(100_000)).unwrap_err().to_string();
        assert!(message.contains("CPU 100000 does not exist"), "{message}");
        assert!(check(Some(50), Some(0)).is_ok());
    }

    #[test]
    fn settings_apply_or_warn_by_name() {
        // On a thread of its own: the test harness's threads keep their normal scheduling.
        std::thread::spawn(|| {
            if let Some(w) = set_fifo_priority(10) {
                assert!(w.contains("SCHED_FIFO priority 10 not set"), "{w}");
            }
            if let Some(w) = set_affinity(0) {
                assert!(w.contains("CPU affinity to CPU 0"), "{w}");
            }
        })
        .join()
        .unwrap();
    }
}
