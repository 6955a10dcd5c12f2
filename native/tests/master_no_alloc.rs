//! The cyclic exchange allocates nothing: counted by a global allocator, per thread, while the
//! master exchanges with virtual AKDs served over UDP by another thread (whose allocations,
//! the simulator's, are not the master's and are not counted).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use akd_native::drive::akd::AkdLine;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::link::udp::Udp;
use akd_native::ethercat::master::Master;
use akd_native::sim::{server, Timing, VirtualBus};

#[path = "support/counting.rs"]
mod counting;
use counting::allocations;

#[test]
fn exchange_allocates_nothing() {
    let socket = server::bind_udp("127.0.0.1:0".parse().unwrap()).unwrap();
    let address = socket.local_addr().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let serving = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            server::serve_udp_on(socket, VirtualBus::with_timing(2, Timing::IMMEDIATE), &stop, None)
        })
    };
    let mut m = Master::new(Box::new(Udp::connect(&address.to_string()).unwrap()), Duration::from_millis(500));
    // The server may take a moment to bind.
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    while m.scan().is_err() {
        assert!(std::time::Instant::now() < deadline, "no simulator on {address}");
    }
    m.request_state(AlState::PreOp, Duration::from_secs(5)).unwrap();
    m.configure_dc(1_000_000, 0).unwrap();
    m.request_state(AlState::Op, Duration::from_secs(5)).unwrap();
    m.slave_mut(1).unwrap().set_outputs(&[1, 2, 3, 4, 5, 6]).unwrap();
    assert_eq!(m.exchange().unwrap(), 6);
    // The counter sees this thread's allocations.
    let probe = allocations();
    drop(std::hint::black_box(Vec::<u8>::with_capacity(8)));
    assert_eq!(allocations(), probe + 1);
    let before = allocations();
    for _ in 0..1000 {
        assert_eq!(m.exchange().unwrap(), 6);
    }
    let during = allocations() - before;
    stop.store(true, Ordering::SeqCst);
    serving.join().unwrap().unwrap();
    assert_eq!(during, 0, "allocations in 1000 cycles");
}
