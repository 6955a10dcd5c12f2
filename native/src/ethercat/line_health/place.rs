//! Where on the line things go wrong, from the counters' pattern, said in the cable's words.
//!
//! An ESC that finds a frame invalid (a CRC error, a physical-layer error inside it) counts it at
//! the port it came in by, spoils the frame's CRC and marks it; every ESC after it counts a
//! forwarded error instead (Section I, "Errors and forwarded errors"). So an error first counted
//! at a port, with forwarded errors after it, lies on the segment in front of that port: the
//! cable into it, from the port at its other end, or the sending side there (the application
//! note's error counter interpretation guide). Frames enter a port 0 on their way out and the
//! other ports on their way back, so errors at a port 1 come from the slave behind it, on the
//! cable's return pair. A lost link is counted at both ends of its cable, once each; a link
//! that is down now shows in the DL status of the slave in front of it, the slaves behind being
//! out of reach.
//!
//! [`findings`] lists what the counters over the window and the DL statuses show, the worst
//! first: a link down, then errors (most first), links lost, errors only ever seen forwarded,
//! and slaves that did not answer.

use super::tally::LineHealth;
use super::topology::{End, Topology};

/// One thing the line's counters show.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Finding {
    /// A link the line had when found is down now: `into`'s port has no link from `from`, and
    /// `unreachable` (the slaves behind) cannot be read.
    LinkDown {
        /// The port whose link is gone, at the far end from the master.
        into: (usize, usize),
        /// Its other end.
        from: End,
        /// The slaves behind it.
        unreachable: Vec<usize>,
    },
    /// Errors first counted at `into`: on the cable into it from `from`.
    Errors {
        /// The port that counted them.
        into: (usize, usize),
        /// The other end of its cable.
        from: End,
        /// Counted over the window.
        count: u64,
    },
    /// Links lost on the cable into `into` (a slave's port 0) from `from`, at either end.
    LinksLost {
        /// The slave's port 0.
        into: (usize, usize),
        /// The other end.
        from: End,
        /// Counted over the window, the more of the two ends' counts.
        count: u64,
    },
    /// Errors counted forwarded, first at `into`, with no ESC counting where they began: the
    /// frames were spoiled in front of it, by the cable from `from` or by the sender there.
    Forwarded {
        /// The first port in the frame's path to count them.
        into: (usize, usize),
        /// The other end of its cable.
        from: End,
        /// Counted there over the window.
        count: u64,
    },
    /// Slaves that did not answer the last read of their counters, though others did.
    Unanswered {
        /// Their positions.
        slaves: Vec<usize>,
    },
}

impl Finding {
    /// Whether it means part of the line is out of reach, not only that it errs.
    pub fn is_down(&self) -> bool {
        matches!(self, Finding::LinkDown { .. })
    }

    /// The port it names, where it names one.
    pub fn port(&self) -> Option<(usize, usize)> {
        match self {
            Finding::LinkDown { into, .. }
            | Finding::Errors { into, .. }
            | Finding::LinksLost { into, .. }
            | Finding::Forwarded { into, .. } => Some(*into),
            Finding::Unanswered { .. } => None,
        }
    }

    /// The finding in words, each slave named by `label` (e.g. "slave 4 (joint_5)"), counts said
    /// over `period` ([`window_words`] or [`LineReading::period`](super::LineReading::period): "in the
    /// last 10 s").
    pub fn words(&self, label: impl Fn(usize) -> String, period: &str) -> String {
        let end = |e: &End| match e {
            End::Master => "the master".to_owned(),
            End::Port { slave, port } => format!("{} port {port}", label(*slave)),
        };
        let window = period;
        let cable = |into: &(usize, usize), from: &End| {
            format!("the cable into {} port {}, from {}", label(into.0), into.1, end(from))
        };
        match self {
            Finding::LinkDown { into, from, unreachable } => {
                let names: Vec<String> = unreachable.iter().map(|&s| label(s)).collect();
                format!("no link on {}: unreachable {}", cable(into, from), names.join(", "))
            }
            Finding::Errors { into, from, count } => format!("errors on {}: {count} {window}", cable(into, from)),
            Finding::LinksLost { into, from, count } => format!("link lost on {}: {count} {window}", cable(into, from)),
            Finding::Forwarded { into, from, count } => format!(
                "errors forwarded into {} port {}, none counted where they began: spoiled by {} or the cable from \
                 it: {count} {window}",
                label(into.0),
                into.1,
                end(from)
            ),
            Finding::Unanswered { slaves } => {
                let names: Vec<String> = slaves.iter().map(|&s| label(s)).collect();
                format!("no answer to the last read of the counters from {}", names.join(", "))
            }
        }
    }
}

/// How counts over a window of `window_ns` are said: "in the last 10 s".
pub fn window_words(window_ns: u64) -> String {
    format!("in the last {:.0} s", window_ns as f64 * 1e-9)
}

/// What `health` shows of a line whose connections were `found` (the topology of the line as
/// first read), the worst first.
pub fn findings(found: &Topology, health: &LineHealth) -> Vec<Finding> {
    let slaves = &health.slaves;
    let mut down = Vec::new();
    let mut errors = Vec::new();
    let mut lost = Vec::new();
    for (slave, up) in found.upstream.iter().enumerate() {
        let Some(from) = *up else { continue };
        // The link into this slave's port 0, as the other end sees it now.
        if let End::Port { slave: parent, port } = from {
            let parent_health = &slaves[parent];
            let gone = parent_health.answered && parent_health.dl_status.is_some_and(|s| !s.link(port));
            if gone {
                down.push(Finding::LinkDown { into: (slave, 0), from, unreachable: found.behind(slave) });
            }
            let count = slaves[slave].window.ports[0].lost_links.max(parent_health.window.ports[port].lost_links);
            if count > 0 {
                lost.push(Finding::LinksLost { into: (slave, 0), from, count });
            }
        }
    }
    let mut forwarded = None;
    for (slave, port) in found.path() {
        let Some(from) = found.peer(slave, port) else { continue };
        let counts = slaves[slave].window.ports[port];
        if counts.original() > 0 {
            errors.push(Finding::Errors { into: (slave, port), from, count: counts.original() });
        } else if counts.forwarded_errors > 0 && forwarded.is_none() {
            forwarded = Some(Finding::Forwarded { into: (slave, port), from, count: counts.forwarded_errors });
        }
    }
    errors.sort_by_key(|f| match f {
        Finding::Errors { count, .. } => std::cmp::Reverse(*count),
        _ => std::cmp::Reverse(0),
    });
    lost.sort_by_key(|f| match f {
        Finding::LinksLost { count, .. } => std::cmp::Reverse(*count),
        _ => std::cmp::Reverse(0),
    });
    let mut all = down;
    let origin_seen = !errors.is_empty();
    all.extend(errors);
    all.extend(lost);
    all.extend(forwarded.filter(|_| !origin_seen));
    let unreachable: Vec<usize> = all
        .iter()
        .flat_map(|f| match f {
            Finding::LinkDown { unreachable, .. } => unreachable.clone(),
            _ => Vec::new(),
        })
        .collect();
    let silent: Vec<usize> = (0..slaves.len())
        .filter(|&s| !slaves[s].answered && slaves[s].reads > 0 && !unreachable.contains(&s))
        .collect();
    if !silent.is_empty() && slaves.iter().any(|s| s.answered) {
        all.push(Finding::Unanswered { slaves: silent });
    }
    all
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::line_health::registers::{DlStatus, ErrorCounts};
    use crate::ethercat::line_health::tally::SlaveHealth;

    /// A line of `n` slaves, each with its links, having answered.
    fn line(n: usize) -> (Topology, LineHealth) {
        let status: Vec<_> = (0..n).map(|s| Some(DlStatus::with_links(3, [true, s + 1 < n, false, false]))).collect();
        let slaves = status
            .iter()
            .map(|&dl_status| SlaveHealth {
                answered: true,
                dl_status,
                found: dl_status,
                reads: 1,
                ..Default::default()
            })
            .collect();
        (Topology::of(&status), LineHealth { time_ns: 0, reads: 1, window_ns: 10_000_000_000, slaves })
    }

    fn label(slave: usize) -> String {
        format!("slave {slave} (joint_{})", slave + 1)
    }

    #[test]
    fn an_error_first_counted_at_a_port_names_the_cable_in_front_of_it() {
        let (topology, mut health) = line(6);
        // A bad cable from slave 2 into slave 3: slave 3 counts the errors at port 0, the slaves
        // after it forwarded errors on the way out and back.
        health.slaves[3].window.ports[0].invalid_frames = 37;
        for (slave, port) in [(4, 0), (5, 0), (4, 1), (3, 1), (2, 1), (1, 1), (0, 1)] {
            health.slaves[slave].window.ports[port].forwarded_errors = 37;
        }
        let found = findings(&topology, &health);
        assert_eq!(found, [Finding::Errors { into: (3, 0), from: End::Port { slave: 2, port: 1 }, count: 37 }]);
        assert_eq!(
            found[0].words(label, &window_words(health.window_ns)),
            "errors on the cable into slave 3 (joint_4) port 0, from slave 2 (joint_3) port 1: 37 in the last 10 s"
        );
    }

    #[test]
    fn errors_at_a_port_1_are_the_return_path_from_the_slave_behind() {
        let (topology, mut health) = line(6);
        health.slaves[3].window.ports[1].invalid_frames = 12;
        for slave in 0..3 {
            health.slaves[slave].window.ports[1].forwarded_errors = 12;
        }
        let found = findings(&topology, &health);
        assert_eq!(
            found[0].words(label, &window_words(health.window_ns)),
            "errors on the cable into slave 3 (joint_4) port 1, from slave 4 (joint_5) port 0: 12 in the last 10 s"
        );
    }

    #[test]
    fn a_link_down_and_its_lost_links_name_the_same_cable() {
        let (topology, mut health) = line(6);
        health.slaves[3].dl_status = Some(DlStatus::with_links(3, [true, false, false, false]));
        for s in 4..6 {
            health.slaves[s].answered = false;
        }
        health.slaves[3].window.ports[1].lost_links = 1;
        let found = findings(&topology, &health);
        assert_eq!(
            found[0].words(label, &window_words(health.window_ns)),
            "no link on the cable into slave 4 (joint_5) port 0, from slave 3 (joint_4) port 1: unreachable slave 4 \
             (joint_5), slave 5 (joint_6)"
        );
        assert_eq!(
            found[1].words(label, &window_words(health.window_ns)),
            "link lost on the cable into slave 4 (joint_5) port 0, from slave 3 (joint_4) port 1: 1 in the last 10 s"
        );
        assert_eq!(found.len(), 2, "the unreachable slaves are the link's, not unanswered: {found:?}");
    }

    #[test]
    fn forwarded_errors_alone_name_the_first_port_counting_them_and_a_clean_line_nothing() {
        let (topology, mut health) = line(3);
        assert_eq!(findings(&topology, &health), []);
        health.slaves[1].window.ports[0].forwarded_errors = 4;
        health.slaves[2].window.ports[0].forwarded_errors = 4;
        let found = findings(&topology, &health);
        assert_eq!(found, [Finding::Forwarded { into: (1, 0), from: End::Port { slave: 0, port: 1 }, count: 4 }]);
        health.slaves[0].window = ErrorCounts::default();
        health.slaves[2].answered = false;
        assert_eq!(findings(&topology, &health).last(), Some(&Finding::Unanswered { slaves: vec![2] }));
    }
}
