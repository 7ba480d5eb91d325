//! A simulated beacon board whose replies go unread (a host that writes and never reads, a
//! terminal left open) drops them, as a UART would, and keeps answering: it does not stop
//! when its pseudo-terminal's buffer is full (fault audit, issue 32, item 4).

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use cta_core::wire::beacon::{Beacon, BeaconRequest};
use cta_core::wire::{encode_frame, BoardKind, Header, Request, MAX_FRAME};
use cta_firmware_beacon::sim::SimBoard;
use cta_lab::boards::link::{open_serial, Link, LinkConfig};

/// Requests written at a time.
const BATCH: usize = 100;

#[test]
fn unread_replies_are_dropped_and_the_board_keeps_answering() {
    let sim = SimBoard::spawn().unwrap();
    let mut port = open_serial(sim.path()).expect("open the pty");
    port.set_timeout(Duration::from_secs(1)).unwrap();
    let mut buf = [0u8; MAX_FRAME];
    let mut frames = Vec::new();
    for seq in 0..BATCH as u16 {
        frames.extend_from_slice(
            encode_frame(
                Header::new(seq),
                &Request::Board(BeaconRequest::GetTable),
                &mut buf,
            )
            .unwrap(),
        );
    }
    // Requests, never a read, until more replies were asked for than the pty's buffer holds
    // (about 1,700 of these tables fill it; a write of ours that times out while the board
    // waits on its own is tried again with the next batch).
    let mut asked = 0usize;
    let deadline = Instant::now() + Duration::from_secs(60);
    while asked < 2_200 && Instant::now() < deadline {
        let _ = port.write_all(&frames);
        asked += BATCH;
    }
    // Drain what is waiting, then the board must still answer a new link.
    let mut sink = [0u8; 4096];
    while matches!(port.read(&mut sink), Ok(n) if n > 0) {}
    drop(port);
    let mut l: Link<Beacon, _> = Link::new(
        open_serial(sim.path()).expect("reopen the pty"),
        LinkConfig {
            timeout: Duration::from_millis(1000),
            retries: 3,
        },
    );
    let id = l
        .check_board()
        .expect("the board answers after its replies went unread");
    assert_eq!(id.board, BoardKind::Beacon);
    sim.stop().expect("the board's loop ended without an error");
}
