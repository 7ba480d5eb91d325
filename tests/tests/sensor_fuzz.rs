//! Fuzz both decoders of the sensor board with random and mutated input: the NorthStar link
//! (`northstar::NsDecoder`) and the PC link (the shared frame decoder inside `Board`).
//! Neither may panic, and each must resynchronise: a valid frame after garbage is decoded.

use cta_core::pose::{cta_constellation, Calibration, Spot};
use cta_core::wire::sensor::{SensorError, SensorRequest, SensorResponse};
use cta_core::wire::{
    encode_frame, FrameDecoder, Header, Reply, Request, ResetCause, Response, MAX_FRAME,
};
use cta_lab::boards::sensor::firmware::board::{Board, Io};
use cta_lab::boards::sensor::firmware::northstar::{self, NsDecoder, NsEvent, SpotFrame};
use cta_lab::boards::sensor::firmware::storage::RamFlash;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

fn report(rng: &mut StdRng, seq: u8) -> Vec<u8> {
    let n = rng.random_range(0..=northstar::MAX_SPOTS);
    let mut spots = heapless::Vec::new();
    for i in 0..n {
        spots
            .push(Spot {
                id: i as u8,
                x: rng.random(),
                y: rng.random(),
                magnitude: rng.random(),
            })
            .unwrap();
    }
    let f = SpotFrame {
        seq,
        sensitivity: rng.random_range(1..=4),
        spots,
    };
    let mut buf = [0u8; northstar::MAX_FRAME];
    let len = northstar::encode_report(&f, &mut buf);
    buf[..len].to_vec()
}

fn mutate(rng: &mut StdRng, mut v: Vec<u8>) -> Vec<u8> {
    for _ in 0..rng.random_range(1..4) {
        if v.is_empty() {
            break;
        }
        let i = rng.random_range(0..v.len());
        match rng.random_range(0..4) {
            0 => v[i] ^= 1 << rng.random_range(0..8),
            1 => {
                v.remove(i);
            }
            2 => v.insert(i, rng.random()),
            _ => v.truncate(i),
        }
    }
    v
}

#[test]
fn northstar_decoder_survives_anything_and_resyncs() {
    let mut rng = StdRng::seed_from_u64(1);
    for round in 0..3000 {
        let mut d = NsDecoder::new();
        let mut junk = Vec::new();
        for _ in 0..rng.random_range(0..4) {
            if rng.random::<bool>() {
                let n = rng.random_range(0..200);
                junk.extend((0..n).map(|_| rng.random::<u8>()));
            } else {
                let f = report(&mut rng, 0);
                junk.extend(mutate(&mut rng, f));
            }
        }
        d.feed(&junk, |_| {});
        // Then two valid frames: both must come out (the decoder keeps scanning what it
        // holds after a false start).
        let a = report(&mut rng, 200);
        let b = report(&mut rng, 201);
        let mut seqs = Vec::new();
        d.feed(&a, |e| {
            if let NsEvent::Report(f) = e {
                seqs.push(f.seq)
            }
        });
        d.feed(&b, |e| {
            if let NsEvent::Report(f) = e {
                seqs.push(f.seq)
            }
        });
        assert!(
            seqs.ends_with(&[200, 201]),
            "round {round}: got {seqs:?} after {} junk bytes",
            junk.len()
        );
    }
}

#[derive(Default)]
struct Capture {
    t: u64,
    pc: Vec<u8>,
}

impl Io for Capture {
    fn now_us(&mut self) -> u64 {
        self.t += 100;
        self.t
    }
    fn send_pc(&mut self, bytes: &[u8]) -> bool {
        self.pc.extend_from_slice(bytes);
        true
    }
    fn send_ns(&mut self, _: &[u8]) {}
}

fn request(seq: u16, r: &Request<SensorRequest>) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    encode_frame(Header::new(seq), r, &mut buf)
        .unwrap()
        .to_vec()
}

#[test]
fn pc_link_survives_anything_and_resyncs() {
    let mut rng = StdRng::seed_from_u64(2);
    let mut board = Board::new(RamFlash::default(), true, ResetCause::PowerOn);
    let mut io = Capture::default();
    let valid = [
        Request::Identify,
        Request::Heartbeat,
        Request::Board(SensorRequest::Status),
        Request::Board(SensorRequest::LoadCalibration(Calibration::table3())),
        Request::Board(SensorRequest::LoadConstellation(cta_constellation())),
        Request::Board(SensorRequest::SetSensitivity(2)),
        Request::Board(SensorRequest::GetConfig),
    ];
    for round in 0..2000u16 {
        let mut junk = Vec::new();
        for _ in 0..rng.random_range(0..4) {
            if rng.random::<bool>() {
                let n = rng.random_range(0..300);
                junk.extend((0..n).map(|_| rng.random::<u8>()));
            } else {
                let r = &valid[rng.random_range(0..valid.len())];
                junk.extend(mutate(&mut rng, request(0x7000, r)));
            }
        }
        // Also random NorthStar bytes (idle mode: counted and dropped).
        let ns: Vec<u8> = (0..rng.random_range(0..64)).map(|_| rng.random()).collect();
        board.on_ns_bytes(&ns, &mut io);
        board.on_pc_bytes(&junk, &mut io);
        io.pc.clear();
        // A valid request after the garbage is answered with its own sequence number.
        let seq = 1 + round;
        board.on_pc_bytes(
            &request(seq, &Request::Board(SensorRequest::Status)),
            &mut io,
        );
        let mut d = FrameDecoder::<MAX_FRAME>::new();
        let answered = io.pc.iter().filter_map(|&b| d.push::<Reply<SensorResponse, SensorError>>(b)).any(|r| {
            matches!(r, Ok((h, Ok(Response::Board(SensorResponse::Status(_))))) if h.seq == seq)
        });
        assert!(
            answered,
            "round {round}: no status reply after {} junk bytes",
            junk.len()
        );
        io.pc.clear();
    }
}
