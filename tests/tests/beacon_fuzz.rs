//! Decoder fuzzing: a million random and mutated frames thrown at the beacon board's frame
//! decoder and at the full board (`Board::feed`, dispatch and reply encoding). Nothing may
//! panic, and a valid frame sent after any garbage must always come through intact.

use cta_core::schedule::{Modulator, NORTHSTAR_TABLE_MHZ};
use cta_core::wire::beacon::{BeaconRequest, FreqSet, LedMode, LedSetting, Limits};
use cta_core::wire::{encode_frame, FrameDecoder, Header, Request, ResetCause, MAX_FRAME};
use cta_firmware_beacon::board::{BeaconReply, Board};
use cta_firmware_beacon::pins::BEACON_LINES;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

type Req = Request<BeaconRequest>;

fn random_mode(rng: &mut StdRng) -> LedMode {
    match rng.random_range(0..3) {
        0 => LedMode::Off,
        1 => LedMode::On,
        _ => LedMode::Modulated(FreqSet(rng.random())),
    }
}

fn random_request(rng: &mut StdRng) -> Req {
    match rng.random_range(0..10) {
        0 => Request::Identify,
        1 => Request::Heartbeat,
        2 => Request::Board(BeaconRequest::Status),
        3 => Request::Board(BeaconRequest::AllOff),
        4 => Request::Board(BeaconRequest::GetLeds),
        5 => Request::Board(BeaconRequest::SetLimits(Limits {
            max_lit: rng.random(),
            deadman_ms: rng.random(),
        })),
        6 => {
            let n = rng.random_range(0..=32);
            let t = (0..n)
                .map(|_| rng.random_range(0..20_000_000))
                .collect::<Vec<u32>>();
            Request::Board(BeaconRequest::SetTable(
                heapless::Vec::from_slice(&t).unwrap(),
            ))
        }
        7 => {
            let n = rng.random_range(0..=100);
            let mut v = heapless::Vec::new();
            for _ in 0..n {
                let led = rng.random_range(0..110);
                v.push(LedSetting {
                    led,
                    mode: random_mode(rng),
                })
                .unwrap();
            }
            Request::Board(BeaconRequest::SetMany(v))
        }
        _ => {
            let led = rng.random_range(0..=255);
            Request::Board(BeaconRequest::Set(LedSetting {
                led,
                mode: random_mode(rng),
            }))
        }
    }
}

fn encode(seq: u16, r: &Req) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    encode_frame(Header::new(seq), r, &mut buf)
        .unwrap()
        .to_vec()
}

/// Garbage: random bytes, or a valid frame mutated (bit flips, truncation, insertions,
/// deletions, splices), or an oversized run.
fn garbage(rng: &mut StdRng, out: &mut Vec<u8>) {
    out.clear();
    match rng.random_range(0..8) {
        0 => {
            let n = rng.random_range(0..64);
            out.extend((0..n).map(|_| rng.random::<u8>()));
        }
        1 => {
            // Random bytes without zeros: one long bogus frame.
            let n = rng.random_range(1..300);
            out.extend((0..n).map(|_| rng.random_range(1..=255u8)));
        }
        2 if rng.random_range(0..50) == 0 => {
            // Oversized.
            out.extend(std::iter::repeat_n(
                0x5a,
                MAX_FRAME + rng.random_range(0..100),
            ));
        }
        _ => {
            let mut f = encode(rng.random(), &random_request(rng));
            let edits = rng.random_range(1..4);
            for _ in 0..edits {
                if f.is_empty() {
                    break;
                }
                let i = rng.random_range(0..f.len());
                match rng.random_range(0..5) {
                    0 => f[i] ^= 1 << rng.random_range(0..8),
                    1 => f.truncate(i),
                    2 => f.insert(i, rng.random()),
                    3 => {
                        f.remove(i);
                    }
                    _ => f[i] = rng.random(),
                }
            }
            // Sometimes drop the trailing delimiter (a frame cut off mid-way).
            if rng.random_range(0..4) == 0 {
                while f.last() == Some(&0) {
                    f.pop();
                }
            }
            out.extend(f);
        }
    }
}

#[test]
fn a_million_garbage_frames_never_hide_the_next_valid_frame() {
    let mut rng = StdRng::seed_from_u64(0xC7A4);
    let mut dec = FrameDecoder::<MAX_FRAME>::new();
    let mut junk = Vec::new();
    let rounds = 1_000_000;
    let mut bytes = 0usize;
    let mut rejected = 0u64;
    for round in 0..rounds {
        garbage(&mut rng, &mut junk);
        bytes += junk.len();
        for &b in &junk {
            if let Some(Err(_)) = dec.push::<Req>(b) {
                rejected += 1;
            }
        }
        let want = random_request(&mut rng);
        let seq = (round % 65_535 + 1) as u16;
        let frame = encode(seq, &want);
        bytes += frame.len();
        let mut last = None;
        for &b in &frame {
            if let Some(r) = dec.push::<Req>(b) {
                if r.is_err() {
                    // Garbage left without a delimiter ends at the frame's leading zero.
                    rejected += 1;
                }
                last = Some(r);
            }
        }
        match last {
            Some(Ok((h, got))) => {
                assert_eq!(h, Header::new(seq), "round {round}");
                assert_eq!(got, want, "round {round}");
            }
            other => panic!("round {round}: valid frame lost after garbage {junk:?}: {other:?}"),
        }
    }
    let s = dec.stats();
    assert!(s.ok >= rounds as u32);
    assert!(rejected > rounds / 2, "{s:?}");
    assert_eq!(
        s.bad() as u64,
        rejected,
        "every rejected frame is counted: {s:?}"
    );
    // (Malformed frames need a valid CRC: random garbage essentially never has one; they are
    // covered by the unit tests of core::wire.)
    assert!(
        s.oversized > 0 && s.crc > 0 && s.encoding > 0 && s.truncated > 0,
        "{s:?}"
    );
    eprintln!("{rounds} rounds, {bytes} bytes: {s:?}");
}

#[test]
fn the_board_answers_every_frame_and_never_panics() {
    let mut rng = StdRng::seed_from_u64(42);
    let mut m = Modulator::new(&NORTHSTAR_TABLE_MHZ, &BEACON_LINES).unwrap();
    let mut board = Board::new(true, ResetCause::PowerOn);
    board.start(&mut m);
    let mut tx = [0u8; MAX_FRAME];
    let mut host = FrameDecoder::<MAX_FRAME>::new();
    let mut junk = Vec::new();
    let (mut frames_in, mut replies) = (0u64, 0u64);
    for round in 0..100_000u64 {
        if round % 2 == 0 {
            garbage(&mut rng, &mut junk);
        } else {
            junk = encode(rng.random(), &random_request(&mut rng));
        }
        for &b in &junk {
            if let Some(frame) = board.feed(b, round, &mut m, &mut tx) {
                replies += 1;
                for &c in frame {
                    if let Some(r) = host.push::<BeaconReply>(c) {
                        // The frame must decode; its reply may be an error reply.
                        let _reply = r.expect("every reply frame decodes");
                    }
                }
            }
        }
        board.poll(round, &mut m);
        assert!(board.lit() <= board.limits().max_lit);
        frames_in = (board.decoder_stats().ok + board.decoder_stats().bad()) as u64;
    }
    assert_eq!(frames_in, replies, "every frame is answered");
    assert_eq!(host.stats().ok as u64, replies);
}
