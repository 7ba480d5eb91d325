//! The host's `Link` over a pseudo-terminal that already holds input when it is opened: the
//! late replies of an earlier process or connection (a command that timed out while the board
//! was busy, a sweep's link before it reconnected) must not answer a new link's requests.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use cta_core::wire::beacon::{Beacon, BeaconError, BeaconRequest, BeaconResponse};
use cta_core::wire::{
    encode_frame, BoardKind, FrameDecoder, Header, Identity, Reply, Request, Response, MAX_FRAME,
    PROTOCOL_VERSION,
};
use cta_lab::boards::link::{open_serial, Link, LinkConfig};
use serialport::{SerialPort, TTYPort};

fn identity(board: BoardKind) -> Identity {
    Identity {
        board,
        protocol: PROTOCOL_VERSION,
        firmware: heapless::String::try_from("0.1.0").unwrap(),
        simulated: true,
        max_frame: MAX_FRAME as u16,
    }
}

fn frame(seq: u16, reply: &Reply<BeaconResponse, BeaconError>) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    encode_frame(Header::new(seq), reply, &mut buf)
        .unwrap()
        .to_vec()
}

/// A beacon board on the master end that answers `Identify` (and nothing else) until `stop`.
fn answer_identify(mut master: TTYPort, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<u32> {
    std::thread::spawn(move || {
        master.set_timeout(Duration::from_millis(5)).unwrap();
        let mut rx = FrameDecoder::<MAX_FRAME>::new();
        let mut buf = [0u8; 256];
        let mut answered = 0;
        while !stop.load(Ordering::Relaxed) {
            let n = master.read(&mut buf).unwrap_or(0);
            for &b in &buf[..n] {
                if let Some(Ok((h, Request::<BeaconRequest>::Identify))) = rx.push(b) {
                    let reply = frame(h.seq, &Ok(Response::Identity(identity(BoardKind::Beacon))));
                    master.write_all(&reply).unwrap();
                    answered += 1;
                }
            }
        }
        answered
    })
}

#[test]
fn input_waiting_on_a_port_when_it_is_opened_is_discarded() {
    let (mut master, slave) = TTYPort::pair().unwrap();
    let path = slave.name().unwrap();
    // Late answers to an earlier link's first requests: a sensor board's identity (as if the
    // boards had been on the other ports then) numbered 1 and up, the numbers every link used
    // to start from. The slave end stays open (as a simulated board keeps it, and as a real
    // port's driver holds what arrived), so they wait there for the next open.
    let mut stale = Vec::new();
    for seq in 1..=8 {
        stale.extend(frame(
            seq,
            &Ok(Response::Identity(identity(BoardKind::Sensor))),
        ));
    }
    master.write_all(&stale).unwrap();
    master.flush().unwrap();
    let t0 = Instant::now();
    while (slave.bytes_to_read().unwrap() as usize) < stale.len() {
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "the stale replies did not reach the slave end"
        );
        std::thread::sleep(Duration::from_millis(5));
    }

    let port = open_serial(&path).unwrap();
    assert_eq!(
        port.bytes_to_read().unwrap(),
        0,
        "open_serial left the earlier input waiting"
    );
    let stop = Arc::new(AtomicBool::new(false));
    let board = answer_identify(master, stop.clone());
    let mut l: Link<Beacon, _> = Link::new(
        port,
        LinkConfig {
            timeout: Duration::from_millis(1000),
            retries: 0,
        },
    );
    let id = l.check_board();
    stop.store(true, Ordering::Relaxed);
    let answered = board.join().unwrap();
    assert_eq!(id.unwrap().board, BoardKind::Beacon);
    assert_eq!(answered, 1);
    assert_eq!(l.stats().stale, 0, "{:?}", l.stats());
    drop(slave);
}
