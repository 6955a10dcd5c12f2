//! The line's links and error counters for Python: `Cycle.line_health()` and
//! `Master.line_health()` as dicts, `Cycle.line_diagnostics()` as /diagnostics statuses
//! ([`crate::ros::line_diagnostics`]), and the views a simulator's `esc_state()` shares.

use std::collections::HashMap;

use pyo3::prelude::*;

use crate::ethercat::line_health::place::Finding;
use crate::ethercat::line_health::registers::{ErrorCounts, PortCounts};
use crate::ethercat::line_health::LineReading;
use crate::ros::line_diagnostics::{self, counts_words, level_of, link_words, peer_words, slave_words};

/// A slave's counters that are not a port's: "processing_unit_errors", "pdi_errors".
#[derive(IntoPyObject)]
pub(super) struct EscCountsView {
    processing_unit_errors: u64,
    pdi_errors: u64,
}

impl<T: Into<u64>> From<ErrorCounts<T>> for EscCountsView {
    fn from(counts: ErrorCounts<T>) -> Self {
        EscCountsView { processing_unit_errors: counts.processing_unit.into(), pdi_errors: counts.pdi.into() }
    }
}

/// One port of `line_health()["slaves"][n]["ports"]`: "port", "kind" ("MII", "E-bus", ...),
/// "link" (its link as the DL status shows it: "link, open", "link, closed", "no link" or
/// "unknown"), "peer" (what is at its other end: "the master", "slave 2 (joint_3) port 1",
/// "nothing"), "total" and "window" (its counters since the first read and over the window),
/// "counted" (the window's in words: "37 invalid frames, 1 lost link", or "no errors").
#[derive(IntoPyObject)]
struct PortView {
    port: usize,
    kind: &'static str,
    link: &'static str,
    peer: String,
    total: PortCounts<u64>,
    window: PortCounts<u64>,
    counted: String,
}

/// One slave of `line_health()["slaves"]`: "position", "name", "answered" (the last read),
/// "dl_status" (None before it answered), "ports", "total" and "window" (its processing unit's
/// and PDI's counters), and the reads' own counts: "reads", "unanswered", "saturated" (reads
/// that found a counter stopped at 0xFF), "found_lower" (reads that found a counter lower than
/// before without a clear of ours: what it counted in between is missing) and "cleared".
#[derive(IntoPyObject)]
struct SlaveView {
    position: usize,
    name: String,
    answered: bool,
    dl_status: Option<u16>,
    ports: Vec<PortView>,
    total: EscCountsView,
    window: EscCountsView,
    reads: u64,
    unanswered: u64,
    saturated: u64,
    found_lower: u64,
    cleared: u64,
}

/// One of `line_health()["findings"]`: "text", "level" ("warn" or "error"), "slave" and
/// "port" (the port it names, None where it names none).
#[derive(IntoPyObject)]
struct FindingView {
    text: String,
    level: &'static str,
    slave: Option<usize>,
    port: Option<usize>,
}

/// `line_health()`: "interval_s" (None: read once), "window_s", "reads", "frames" and
/// "frames_lost" (the reads' frames), "summary" (the worst finding's words, or that there is
/// none), "findings" (the worst first) and "slaves".
#[derive(IntoPyObject)]
pub(super) struct LineHealthView {
    interval_s: Option<f64>,
    window_s: f64,
    reads: u64,
    frames: u64,
    frames_lost: u64,
    summary: String,
    findings: Vec<FindingView>,
    slaves: Vec<SlaveView>,
}

/// Each slave's label: its joint's name where `names` (position to name) gives one, else its
/// product.
pub(super) fn labels(products: &[String], names: Option<HashMap<usize, String>>) -> Vec<String> {
    let names = names.unwrap_or_default();
    products.iter().enumerate().map(|(s, product)| names.get(&s).cloned().unwrap_or_else(|| product.clone())).collect()
}

impl LineHealthView {
    /// The view of `reading`, slaves named by `labels`.
    pub(super) fn new(reading: &LineReading, labels: &[String]) -> Self {
        let health = &reading.health;
        let topology = reading.topology();
        let findings = reading.findings();
        let period = reading.period();
        let words = |f: &Finding| f.words(|s| slave_words(labels, s), &period);
        let summary = findings.first().map(words).unwrap_or_else(|| format!("no errors on the line {period}"));
        let slaves = health
            .slaves
            .iter()
            .enumerate()
            .map(|(s, slave)| {
                let descriptor = reading.ports.get(s).copied().unwrap_or_default();
                SlaveView {
                    position: s,
                    name: labels.get(s).cloned().unwrap_or_default(),
                    answered: slave.answered,
                    dl_status: slave.dl_status.map(|d| d.0),
                    ports: descriptor
                        .ports()
                        .map(|port| PortView {
                            port,
                            kind: descriptor.kind(port).name(),
                            link: link_words(slave.dl_status, port),
                            peer: peer_words(topology.peer(s, port), labels),
                            total: slave.totals.ports[port],
                            window: slave.window.ports[port],
                            counted: counts_words(&slave.window.ports[port]),
                        })
                        .collect(),
                    total: slave.totals.into(),
                    window: slave.window.into(),
                    reads: slave.reads,
                    unanswered: slave.unanswered,
                    saturated: slave.saturated,
                    found_lower: slave.found_lower,
                    cleared: slave.cleared,
                }
            })
            .collect();
        LineHealthView {
            interval_s: reading.interval.map(|i| i.as_secs_f64()),
            window_s: health.window_ns as f64 * 1e-9,
            reads: health.reads,
            frames: reading.frames,
            frames_lost: reading.frames_lost,
            summary,
            findings: findings
                .iter()
                .map(|f| FindingView {
                    text: words(f),
                    level: if level_of(f) == line_diagnostics::ERROR { "error" } else { "warn" },
                    slave: f.port().map(|p| p.0),
                    port: f.port().map(|p| p.1),
                })
                .collect(),
            slaves,
        }
    }
}
