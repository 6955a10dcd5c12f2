//! What /diagnostics says of the line ([`statuses`]): one status of the whole line naming the
//! worst place, and one per slave with its ports (link, what is at the other end, each counter
//! since the first read and over the window), made from what the reads of the line found
//! ([`LineReading`]). The node and akd-top show the same statuses; every count is a plain
//! integer, so a reader of a bag compares them with a simulator's own.
//!
//! Names, each a status's `what` (the node puts its name in front): `line` for the line,
//! `line slave N` for the slave at position N. Keys of a slave's values: `portP` (its link),
//! `portP_peer`, `portP_invalid_frames`, `portP_rx_errors`, `portP_forwarded_errors`,
//! `portP_lost_links` (totals), `portP_window` (the same over the window, in words),
//! `processing_unit_errors`, `pdi_errors`, and the reads' own counts.

use crate::ethercat::line_health::place::Finding;
use crate::ethercat::line_health::registers::{DlStatus, PortCounts};
use crate::ethercat::line_health::topology::End;
use crate::ethercat::line_health::LineReading;

/// A DiagnosticStatus's level: OK.
pub const OK: u8 = 0;
/// WARN.
pub const WARN: u8 = 1;
/// ERROR.
pub const ERROR: u8 = 2;

/// One status: level, what it is of, message, hardware id and its (key, value) pairs.
pub type Status = (u8, String, String, String, Vec<(String, String)>);

/// How a slave is named: "slave 4 (joint_5)", `labels` giving the part in brackets.
pub fn slave_words(labels: &[String], slave: usize) -> String {
    match labels.get(slave) {
        Some(label) if !label.is_empty() => format!("slave {slave} ({label})"),
        _ => format!("slave {slave}"),
    }
}

/// A port's link as its DL status shows it.
pub fn link_words(status: Option<DlStatus>, port: usize) -> &'static str {
    match status {
        None => "unknown",
        Some(s) if s.open(port) => "link, open",
        Some(s) if s.link(port) => "link, closed",
        Some(_) => "no link",
    }
}

/// What is at the other end of a port.
pub fn peer_words(peer: Option<End>, labels: &[String]) -> String {
    match peer {
        None => "nothing".to_owned(),
        Some(End::Master) => "the master".to_owned(),
        Some(End::Port { slave, port }) => format!("{} port {port}", slave_words(labels, slave)),
    }
}

/// A port's counts in words, those above 0 only: "37 invalid frames, 1 lost link".
pub fn counts_words(counts: &PortCounts<u64>) -> String {
    let parts: Vec<String> = [
        (counts.invalid_frames, "invalid frame"),
        (counts.rx_errors, "RX error"),
        (counts.forwarded_errors, "forwarded error"),
        (counts.lost_links, "lost link"),
    ]
    .into_iter()
    .filter(|&(n, _)| n > 0)
    .map(|(n, what)| format!("{n} {what}{}", if n == 1 { "" } else { "s" }))
    .collect();
    if parts.is_empty() {
        "no errors".to_owned()
    } else {
        parts.join(", ")
    }
}

/// A finding's level: a link down is an error, the rest warnings.
pub fn level_of(finding: &Finding) -> u8 {
    if finding.is_down() {
        ERROR
    } else {
        WARN
    }
}

/// The statuses of the line `reading` found, slaves named by `labels` (by position: a joint's
/// name, or the product), on the link `link`.
pub fn statuses(reading: &LineReading, labels: &[String], link: &str) -> Vec<Status> {
    let findings = reading.findings();
    let name = |s: usize| slave_words(labels, s);
    let health = &reading.health;
    let window = reading.period();
    let (level, message) = match (reading.interval, findings.first()) {
        (None, None) if health.reads == 0 => (OK, "the line's links and error counters are not read".to_owned()),
        (_, None) => (OK, format!("no errors on the line {window}")),
        (_, Some(worst)) => (level_of(worst), worst.words(name, &window)),
    };
    let topology = reading.topology();
    let connections: Vec<String> = (1..health.slaves.len())
        .map(|s| format!("{} port 0 - {}", name(s), peer_words(topology.peer(s, 0), labels)))
        .collect();
    let mut values = vec![
        ("reads".to_owned(), health.reads.to_string()),
        ("interval_s".to_owned(), reading.interval.map_or("not read".to_owned(), |i| format!("{}", i.as_secs_f64()))),
        ("window_s".to_owned(), format!("{:.3}", health.window_ns as f64 * 1e-9)),
        ("read_frames".to_owned(), reading.frames.to_string()),
        ("read_frames_lost".to_owned(), reading.frames_lost.to_string()),
        ("topology".to_owned(), connections.join("; ")),
    ];
    values.extend(findings.iter().enumerate().map(|(n, f)| (format!("finding_{n}"), f.words(name, &window))));
    let hardware_id = format!("EtherCAT line {link}");
    let mut all = vec![(level, "line".to_owned(), message, hardware_id, values)];
    for (s, slave) in health.slaves.iter().enumerate() {
        let ports = reading.ports.get(s).copied().unwrap_or_default();
        let mut values = vec![
            ("slave".to_owned(), s.to_string()),
            ("name".to_owned(), labels.get(s).cloned().unwrap_or_default()),
            ("answered".to_owned(), slave.answered.to_string()),
            ("dl_status".to_owned(), slave.dl_status.map_or("unknown".to_owned(), |d| format!("0x{:04X}", d.0))),
        ];
        let mut rising = Vec::new();
        for port in ports.ports() {
            let (total, counted) = (slave.totals.ports[port], slave.window.ports[port]);
            let kind = ports.kind(port).name();
            values.push((format!("port{port}"), format!("{}, {kind}", link_words(slave.dl_status, port))));
            values.push((format!("port{port}_peer"), peer_words(topology.peer(s, port), labels)));
            values.push((format!("port{port}_invalid_frames"), total.invalid_frames.to_string()));
            values.push((format!("port{port}_rx_errors"), total.rx_errors.to_string()));
            values.push((format!("port{port}_forwarded_errors"), total.forwarded_errors.to_string()));
            values.push((format!("port{port}_lost_links"), total.lost_links.to_string()));
            values.push((format!("port{port}_window"), format!("{} {window}", counts_words(&counted))));
            if counted.values().iter().any(|&c| c > 0) {
                rising.push(format!("port {port}: {} {window}", counts_words(&counted)));
            }
        }
        values.extend([
            ("processing_unit_errors".to_owned(), slave.totals.processing_unit.to_string()),
            ("pdi_errors".to_owned(), slave.totals.pdi.to_string()),
            ("reads".to_owned(), slave.reads.to_string()),
            ("unanswered".to_owned(), slave.unanswered.to_string()),
            ("saturated".to_owned(), slave.saturated.to_string()),
            ("found_lower".to_owned(), slave.found_lower.to_string()),
            ("cleared".to_owned(), slave.cleared.to_string()),
        ]);
        let down =
            findings.iter().any(|f| matches!(f, Finding::LinkDown { unreachable, .. } if unreachable.contains(&s)));
        let (level, message) = if down {
            (ERROR, "unreachable: a link in front of it is down".to_owned())
        } else if !slave.answered && slave.reads > 0 {
            (WARN, "did not answer the last read of its counters".to_owned())
        } else if !rising.is_empty() {
            (WARN, rising.join("; "))
        } else {
            (OK, format!("no errors {window}"))
        };
        all.push((level, format!("line slave {s}"), message, format!("{} on {link}", name(s)), values));
    }
    all
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::line_health::registers::PortDescriptor;
    use crate::ethercat::line_health::tally::{LineHealth, SlaveHealth};

    fn reading(n: usize) -> LineReading {
        let slaves = (0..n)
            .map(|s| {
                let status = Some(DlStatus::with_links(3, [true, s + 1 < n, false, false]));
                SlaveHealth { answered: true, dl_status: status, found: status, reads: 4, ..Default::default() }
            })
            .collect();
        LineReading {
            ports: vec![PortDescriptor(0x0F); n],
            health: LineHealth { time_ns: 1, reads: 4, window_ns: 10_000_000_000, slaves },
            interval: Some(std::time::Duration::from_millis(250)),
            frames: 4,
            frames_lost: 0,
        }
    }

    fn value<'a>(status: &'a Status, key: &str) -> &'a str {
        &status.4.iter().find(|(k, _)| k == key).unwrap_or_else(|| panic!("no {key} in {status:?}")).1
    }

    #[test]
    fn a_clean_line_is_ok_everywhere_and_shows_its_connections() {
        let labels: Vec<String> = (1..=3).map(|j| format!("joint_{j}")).collect();
        let all = statuses(&reading(3), &labels, "sim:3");
        assert_eq!(all.len(), 4);
        assert!(all.iter().all(|s| s.0 == OK), "{all:?}");
        assert_eq!(all[0].2, "no errors on the line in the last 10 s");
        assert_eq!(
            value(&all[0], "topology"),
            "slave 1 (joint_2) port 0 - slave 0 (joint_1) port 1; slave 2 (joint_3) port 0 - slave 1 (joint_2) port 1"
        );
        let slave = &all[2];
        assert_eq!((slave.1.as_str(), slave.3.as_str()), ("line slave 1", "slave 1 (joint_2) on sim:3"));
        assert_eq!(value(slave, "port1"), "link, open, MII");
        assert_eq!(value(slave, "port1_peer"), "slave 2 (joint_3) port 0");
        assert_eq!(value(slave, "port0_invalid_frames"), "0");
        assert_eq!(value(&all[3], "port1"), "no link, MII");
    }

    #[test]
    fn errors_name_the_cable_on_the_line_and_rise_on_the_slave() {
        let mut r = reading(6);
        r.health.slaves[3].totals.ports[1].invalid_frames = 40;
        r.health.slaves[3].window.ports[1].invalid_frames = 37;
        let all = statuses(&r, &[], "sim:6");
        assert_eq!(
            (all[0].0, all[0].2.as_str()),
            (WARN, "errors on the cable into slave 3 port 1, from slave 4 port 0: 37 in the last 10 s")
        );
        assert_eq!(value(&all[0], "finding_0"), all[0].2);
        let slave = &all[4];
        assert_eq!(slave.0, WARN);
        assert_eq!(slave.2, "port 1: 37 invalid frames in the last 10 s");
        assert_eq!(value(slave, "port0_window"), "no errors in the last 10 s");
        assert_eq!(value(slave, "port1_invalid_frames"), "40");
    }
}
