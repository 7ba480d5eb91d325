//! End-to-end: the host's `Link` and the simulated beacon board (same `Board` and
//! `Modulator` as the firmware) over a pseudo-terminal, exactly as over RS-232.

use std::io::Write;
use std::time::{Duration, Instant};

use cta_core::wire::beacon::{
    Beacon, BeaconError, BeaconRequest, BeaconResponse, BeaconStatus, FreqSet, LedMode, LedSetting,
    Limits,
};
use cta_core::wire::{encode_frame, BoardKind, Header, Request, MAX_FRAME};
use cta_firmware_beacon::pins::BEACON_PINS;
use cta_firmware_beacon::sim::SimBoard;
use cta_lab::boards::link::{open_serial, Link, LinkConfig, LinkError};

type BeaconLink = Link<Beacon, Box<dyn serialport::SerialPort>>;

/// How long to wait for something the simulated board must do: generous, so a loaded
/// machine cannot fail the test; nothing is assumed done after a fixed time.
const PATIENCE: Duration = Duration::from_secs(60);

fn connect(sim: &SimBoard) -> BeaconLink {
    let port = open_serial(sim.path()).expect("open the pty");
    Link::new(
        port,
        LinkConfig {
            timeout: Duration::from_millis(1000),
            retries: 1,
        },
    )
}

fn status(l: &mut BeaconLink) -> BeaconStatus {
    match l.call(BeaconRequest::Status).unwrap() {
        Some(BeaconResponse::Status(s)) => s,
        other => panic!("{other:?}"),
    }
}

fn refused(r: Result<Option<BeaconResponse>, LinkError<BeaconError>>) -> BeaconError {
    match r {
        Err(LinkError::Refused { error, .. }) => error,
        other => panic!("expected a refusal, got {other:?}"),
    }
}

fn set(led: u8, mode: LedMode) -> BeaconRequest {
    BeaconRequest::Set(LedSetting { led, mode })
}

fn lit(sim: &SimBoard, led: usize) -> bool {
    let p = BEACON_PINS[led];
    sim.snapshot().levels[p.port as usize] & (1 << p.bit) != 0
}

#[test]
fn host_drives_the_simulated_board_over_a_pty() {
    let sim = SimBoard::spawn().unwrap();
    let mut l = connect(&sim);

    let id = l.check_board().unwrap();
    assert_eq!(id.board, BoardKind::Beacon);
    assert!(id.simulated);

    // Boots dark with the NorthStar table.
    let s = status(&mut l);
    assert_eq!((s.lit, s.table_len, s.limits), (0, 20, Limits::default()));
    match l.call(BeaconRequest::GetTable).unwrap() {
        Some(BeaconResponse::Table(t)) => assert_eq!(t[0..2], [3_040_000, 2_010_000]),
        other => panic!("{other:?}"),
    }

    // One LED steady, one modulated at 2010 Hz, one at two frequencies at once.
    assert_eq!(l.call(set(5, LedMode::On)).unwrap(), None);
    assert_eq!(
        l.call(set(45, LedMode::Modulated(FreqSet::single(1))))
            .unwrap(),
        None
    );
    assert_eq!(
        l.call(set(46, LedMode::Modulated(FreqSet(0b101)))).unwrap(),
        None
    );
    match l.call(BeaconRequest::GetLeds).unwrap() {
        Some(BeaconResponse::Leds(m)) => {
            assert_eq!(m[5], LedMode::On);
            assert_eq!(m[45], LedMode::Modulated(FreqSet(2)));
            assert_eq!(m[46], LedMode::Modulated(FreqSet(5)));
            assert_eq!(m.iter().filter(|m| m.is_lit()).count(), 3);
        }
        other => panic!("{other:?}"),
    }
    // The simulated modulator runs: LED 45 is seen both lit and dark, LED 5 always lit
    // (sampled until both are seen, however slowly the board's thread runs).
    let (mut on, mut off) = (0, 0);
    let t0 = sim.snapshot().ticks;
    let deadline = Instant::now() + PATIENCE;
    while on == 0 || off == 0 || sim.snapshot().ticks == t0 {
        assert!(
            Instant::now() < deadline,
            "LED 45 never toggled (on {on}, off {off}) or the modulator does not advance"
        );
        std::thread::sleep(Duration::from_millis(2));
        assert!(lit(&sim, 5));
        if lit(&sim, 45) {
            on += 1
        } else {
            off += 1
        }
    }

    // Bad requests: named refusals, nothing changes.
    assert_eq!(
        refused(l.call(set(100, LedMode::On))),
        BeaconError::UnknownBeacon { id: 100 }
    );
    assert_eq!(
        refused(l.call(set(7, LedMode::Modulated(FreqSet::single(25))))),
        BeaconError::FrequencyNotInTable {
            id: 7,
            index: 25,
            table_len: 20
        }
    );
    let mut many = heapless::Vec::new();
    for led in 10..30 {
        many.push(LedSetting {
            led,
            mode: LedMode::On,
        })
        .unwrap();
    }
    assert_eq!(
        refused(l.call(BeaconRequest::SetMany(many))),
        BeaconError::TooManyLit {
            requested: 23,
            cap: 20
        }
    );
    let msg = l.call(set(100, LedMode::On)).unwrap_err().to_string();
    assert!(msg.contains("unknown beacon 100"), "{msg}");
    assert_eq!(status(&mut l).lit, 3);

    // Line garbage, a corrupted frame and an oversized frame: counted, answered, and the
    // next request goes through.
    let before = status(&mut l).decoder;
    let port = l.port_mut();
    port.write_all(&[0x42, 0x17, 0x99, 0x00]).unwrap();
    let mut buf = [0u8; MAX_FRAME];
    let good = encode_frame(
        Header::new(999),
        &Request::Board(BeaconRequest::AllOff),
        &mut buf,
    )
    .unwrap()
    .to_vec();
    let mut bad = good.clone();
    bad[4] ^= 0x21;
    if bad[4] == 0 {
        bad[4] = 0x21;
    }
    port.write_all(&bad).unwrap();
    port.write_all(&[0x55; MAX_FRAME + 10]).unwrap();
    port.write_all(&[0]).unwrap();
    port.flush().unwrap();
    let after = status(&mut l).decoder;
    assert!(after.bad() >= before.bad() + 3, "{before:?} -> {after:?}");
    assert_eq!(after.oversized, before.oversized + 1);
    assert!(l.stats().garbage_answers >= 3, "{:?}", l.stats());
    assert_eq!(
        status(&mut l).lit,
        3,
        "the corrupted AllOff must not have been obeyed"
    );

    // A request the board cannot parse is answered with the request's sequence number.
    let frame = encode_frame(Header::new(4242), &(2u8, 77u8), &mut buf)
        .unwrap()
        .to_vec();
    l.port_mut().write_all(&frame).unwrap();
    let s = status(&mut l);
    assert!(s.decoder.malformed >= 1);

    // Dead-man: with a 200 ms timeout, heartbeats keep the LEDs lit, and without them
    // everything goes dark. Timed on the host's clock, which the simulated board shares: the
    // board restarts its timer at each frame somewhere between the frame's sending and its
    // answer, so a round of heartbeats over three timeouts, each answered within 200 ms of the
    // previous frame's sending, must leave the LEDs lit. A round in which the machine stalled
    // past that proves nothing either way and is run again (relit if it tripped).
    let deadman = Duration::from_millis(200);
    l.call(BeaconRequest::SetLimits(Limits {
        max_lit: 20,
        deadman_ms: 200,
    }))
    .unwrap();
    let mut rounds = 0;
    let (trips, quiet_from) = loop {
        rounds += 1;
        assert!(
            rounds <= 50,
            "every round of heartbeats stalled past the dead-man"
        );
        // `prev`: when the latest frame was sent; `kept`: every frame so far answered within
        // the timeout (less 5 ms for the board's whole-millisecond clock) of the one before.
        let mut prev = Instant::now();
        let trips = status(&mut l).deadman_trips;
        let mut kept = true;
        for (led, mode) in [
            (5, LedMode::On),
            (45, LedMode::Modulated(FreqSet::single(1))),
            (46, LedMode::Modulated(FreqSet(0b101))),
        ] {
            let sent = Instant::now();
            l.call(set(led, mode)).unwrap();
            kept &= prev.elapsed() + Duration::from_millis(5) < deadman;
            prev = sent;
        }
        let start = Instant::now();
        while start.elapsed() < 3 * deadman {
            // Paced, not waited on: any interval under the timeout would do.
            std::thread::sleep(Duration::from_millis(20));
            let sent = Instant::now();
            l.heartbeat().unwrap();
            kept &= prev.elapsed() + Duration::from_millis(5) < deadman;
            prev = sent;
        }
        let quiet_from = Instant::now();
        let s = status(&mut l);
        kept &= prev.elapsed() + Duration::from_millis(5) < deadman;
        if kept {
            assert!(lit(&sim, 5), "heartbeats keep the LEDs lit");
            assert_eq!(
                (s.lit, s.deadman_trips),
                (3, trips),
                "heartbeats keep the LEDs lit"
            );
            break (trips, quiet_from);
        }
    };
    // Silence from the last request on: dark, and not before 200 ms have passed.
    let deadline = Instant::now() + PATIENCE;
    while lit(&sim, 5) {
        assert!(
            Instant::now() < deadline,
            "dead-man did not switch the LEDs off"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    let dark_after = quiet_from.elapsed();
    assert!(
        dark_after > deadman,
        "dark {dark_after:?} after the last request, before the 200 ms dead-man"
    );
    let s = status(&mut l);
    assert_eq!((s.lit, s.deadman_trips), (0, trips + 1));

    // All off.
    l.call(set(9, LedMode::On)).unwrap();
    l.call(BeaconRequest::AllOff).unwrap();
    assert_eq!(status(&mut l).lit, 0);
    drop(l);
    sim.stop().unwrap();
}

#[test]
fn any_board_can_be_identified() {
    // The identify request and reply do not depend on the board's message types.
    let sim = SimBoard::spawn().unwrap();
    let mut l: Link<cta_lab::boards::link::AnyBoard, _> = Link::new(
        open_serial(sim.path()).unwrap(),
        LinkConfig {
            timeout: Duration::from_millis(1000),
            retries: 0,
        },
    );
    let id = l.identify().unwrap();
    assert_eq!((id.board, id.simulated), (BoardKind::Beacon, true));
    sim.stop().unwrap();
}
