//! Which port of which slave connects to which, from the slaves' DL statuses in the order the
//! scan found them (their positions).
//!
//! A frame enters a slave at port 0, leaves through its next open port in the processing order
//! (0 → 3 → 1 → 2 → 0), comes back in there from the slaves behind it, and goes on to the next
//! open port; the positions count the slaves in the order the frame meets them. So the slave
//! after slave `s` hangs on `s`'s first open port after port 0, the slaves behind it follow, and
//! the next slave after those on `s`'s next open port: a line where each slave has port 1
//! open, a branch where a junction (an EK1100's port 2, an EK1122) has more. Every slave is taken
//! to be entered at port 0, as EtherCAT wiring has it (IN, port 0; OUT, the others).

use super::registers::{DlStatus, PROCESSING_ORDER};

/// One end of a connection.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum End {
    /// The master.
    Master,
    /// Port `port` of the slave at `slave`.
    Port {
        /// The slave's position.
        slave: usize,
        /// Its port.
        port: usize,
    },
}

/// The line's connections: what each slave's port 0 hangs on.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Topology {
    /// By position: where its port 0 connects; `None` for a slave the DL statuses leave no open
    /// port for (its link, or one in front of it, down).
    pub upstream: Vec<Option<End>>,
}

impl Topology {
    /// The connections the DL statuses `status` of the slaves in position order say (`None`
    /// for one that never answered: taken as open at port 1 only, a slave of a line).
    pub fn of(status: &[Option<DlStatus>]) -> Self {
        let mut upstream = vec![None; status.len()];
        if let Some(first) = upstream.first_mut() {
            *first = Some(End::Master);
            let mut next = 1;
            place(status, 0, &mut next, &mut upstream);
        }
        Topology { upstream }
    }

    /// What is at the other end of `slave`'s `port`: for port 0 what it hangs on, for another
    /// the slave hanging there (at its port 0); `None` where nothing is.
    pub fn peer(&self, slave: usize, port: usize) -> Option<End> {
        if port == 0 {
            return self.upstream.get(slave).copied().flatten();
        }
        let this = End::Port { slave, port };
        let child = self.upstream.iter().position(|u| *u == Some(this))?;
        Some(End::Port { slave: child, port: 0 })
    }

    /// The ports in the order a frame enters them: a slave's port 0 on the way out, its other
    /// ports on the way back from the slaves hanging there.
    pub fn path(&self) -> Vec<(usize, usize)> {
        let mut path = Vec::new();
        if !self.upstream.is_empty() {
            self.enter(0, &mut path);
        }
        path
    }

    fn enter(&self, slave: usize, path: &mut Vec<(usize, usize)>) {
        path.push((slave, 0));
        for port in PROCESSING_ORDER.into_iter().skip(1) {
            if let Some(End::Port { slave: child, .. }) = self.peer(slave, port) {
                self.enter(child, path);
                path.push((slave, port));
            }
        }
    }

    /// The slaves at and behind `slave`: those a frame reaches through it.
    pub fn behind(&self, slave: usize) -> Vec<usize> {
        let mut found = vec![slave];
        let mut i = 0;
        while let Some(&s) = found.get(i) {
            for (child, up) in self.upstream.iter().enumerate() {
                if matches!(up, Some(End::Port { slave: parent, .. }) if *parent == s) {
                    found.push(child);
                }
            }
            i += 1;
        }
        found.sort_unstable();
        found
    }
}

/// Places the slaves from `next` on behind `slave`'s open ports, depth first, as the frame meets
/// them.
fn place(status: &[Option<DlStatus>], slave: usize, next: &mut usize, upstream: &mut [Option<End>]) {
    for port in PROCESSING_ORDER.into_iter().skip(1) {
        let open = match status[slave] {
            Some(s) => s.open(port),
            None => port == 1,
        };
        if open && *next < status.len() {
            let child = *next;
            *next += 1;
            upstream[child] = Some(End::Port { slave, port });
            place(status, child, next, upstream);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A DL status with links at `ports`.
    fn links(ports: &[usize]) -> Option<DlStatus> {
        Some(DlStatus::with_links(3, std::array::from_fn(|p| ports.contains(&p))))
    }

    #[test]
    fn a_line_hangs_each_slave_on_the_port_1_of_the_one_before() {
        let topology = Topology::of(&[links(&[0, 1]), links(&[0, 1]), links(&[0])]);
        let port = |slave, port| Some(End::Port { slave, port });
        assert_eq!(topology.upstream, [Some(End::Master), port(0, 1), port(1, 1)]);
        assert_eq!(topology.peer(1, 1), port(2, 0));
        assert_eq!(topology.peer(2, 1), None);
        assert_eq!(topology.behind(1), [1, 2]);
        assert_eq!(topology.path(), [(0, 0), (1, 0), (2, 0), (1, 1), (0, 1)]);
    }

    #[test]
    fn a_junction_branches_after_the_slaves_behind_its_first_open_port() {
        // An EK1100 (0) with two terminals on its E-bus port 1 and an AKD on its port 2 (X2 OUT),
        // then an AKD behind that one.
        let status = [links(&[0, 1, 2]), links(&[0, 1]), links(&[0]), links(&[0, 1]), links(&[0])];
        let topology = Topology::of(&status);
        let port = |slave, port| Some(End::Port { slave, port });
        assert_eq!(topology.upstream, [Some(End::Master), port(0, 1), port(1, 1), port(0, 2), port(3, 1)]);
        assert_eq!(topology.behind(0), [0, 1, 2, 3, 4]);
        assert_eq!(topology.behind(1), [1, 2]);
        assert_eq!(topology.path(), [(0, 0), (1, 0), (2, 0), (1, 1), (0, 1), (3, 0), (4, 0), (3, 1), (0, 2)]);
        // A port 3 comes before port 1.
        let topology = Topology::of(&[links(&[0, 1, 3]), links(&[0]), links(&[0])]);
        assert_eq!(topology.upstream, [Some(End::Master), port(0, 3), port(0, 1)]);
    }

    #[test]
    fn a_link_down_leaves_the_slaves_behind_it_unplaced() {
        let topology = Topology::of(&[links(&[0]), links(&[0, 1]), links(&[0])]);
        assert_eq!(topology.upstream, [Some(End::Master), None, None]);
        // A slave that never answered is taken as one of a line.
        let topology = Topology::of(&[links(&[0, 1]), None, links(&[0])]);
        assert_eq!(topology.peer(1, 1), Some(End::Port { slave: 2, port: 0 }));
    }
}
