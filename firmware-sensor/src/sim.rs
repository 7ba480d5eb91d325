//! The simulated sensor board (feature `sim`): the firmware's [`Board`] behind a
//! pseudo-terminal, fed by a simulated NorthStar that emits frames of the assumed format
//! ([`crate::northstar`]) from the core emulator (eqs 60-63) for a given target pose and
//! beacon set. The host (`cta sensor --sim`) and the end-to-end tests talk to it exactly as
//! to the real board, over the pty's path.

// The board behind a pseudo-terminal ([`SimBoard`]) is Unix only; the simulated NorthStar,
// [`physics`] and [`answer_commands`] are portable.
#[cfg(unix)]
use std::io::{Read, Write};
#[cfg(unix)]
use std::sync::atomic::{AtomicBool, Ordering};
#[cfg(unix)]
use std::sync::{Arc, Mutex};
#[cfg(unix)]
use std::thread::JoinHandle;
#[cfg(unix)]
use std::time::{Duration, Instant};

use cta_core::emulator::{Effects, Emulator, Head, Pose as HeadPose};
use cta_core::magnitude_law;
use cta_core::pose::{simulate_spots_scaled, Calibration, Constellation};
#[cfg(unix)]
use cta_core::wire::ResetCause;
use nalgebra::Vector3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
#[cfg(unix)]
use serialport::{SerialPort, TTYPort};

#[cfg(unix)]
use crate::board::{Board, Io};
use crate::northstar::{self, NsCommand, SpotFrame, MAX_FRAME};
#[cfg(unix)]
use crate::storage::RamFlash;

/// The simulated NorthStar: true physics, true beacon positions, the target's true pose.
#[derive(Debug, Clone)]
pub struct SimNorthStar {
    /// The head on the board with the eq 63 physics (the truth).
    pub physics: Emulator<f64>,
    /// True constellation (beacon positions in the target frame, channels).
    pub constellation: Constellation,
    /// True target position in N, inches.
    pub t: Vector3<f64>,
    /// True target attitude (MRP, N -> T).
    pub q: Vector3<f64>,
    /// Gaussian noise on each coordinate, counts (1-sigma).
    pub noise: f64,
    /// Gaussian noise on each spot's magnitude, percent of it (1-sigma; 0 by default: the
    /// magnitudes are then exact but for their rounding to counts). Drawn from a stream of
    /// its own, so the coordinates' noise does not depend on it.
    pub magnitude_noise: f64,
    /// Probability that a burst of random bytes precedes a frame (line noise).
    pub garbage: f64,
    /// Probability that a frame carries one spot under another beacon's ID
    /// ([`cta_core::pose::mislabel`]: a random spot takes a random other spot's ID, which
    /// then marks no spot of its own). Drawn from a stream of its own.
    pub wrong_id: f64,
    /// Report rate, Hz (set by the board's rate command).
    pub rate_hz: u8,
    /// Sensitivity setting (set by the board's command; echoed in the frames).
    pub sensitivity: u8,
    /// The beacons' power level (the array's slide switches: 1 = 1 kOhm, 2 = 360 Ohm; 2 by
    /// default), for the magnitude law.
    pub power_level: u8,
    seq: u8,
    rng: StdRng,
    /// The magnitude noise's own stream.
    magnitude_rng: StdRng,
    /// The wrong IDs' own stream.
    wrong_rng: StdRng,
}

/// Mixed into the seed of the magnitude noise's stream (any constant: the two streams only
/// need to differ).
const MAGNITUDE_STREAM: u64 = 0x6d61_676e_6974_7564;
/// Mixed into the seed of the wrong IDs' stream.
const WRONG_ID_STREAM: u64 = 0x7772_6f6e_675f_6964;

impl SimNorthStar {
    /// A NorthStar mounted with `cal`'s head pose and near-field parameters (true physics:
    /// proximity, intensity, Lambertian beacon), seeing `constellation` at `(t, q)`.
    pub fn new(
        cal: &Calibration,
        constellation: Constellation,
        t: Vector3<f64>,
        q: Vector3<f64>,
        noise: f64,
        seed: u64,
    ) -> Self {
        SimNorthStar {
            physics: physics(cal),
            constellation,
            t,
            q,
            noise,
            magnitude_noise: 0.0,
            garbage: 0.0,
            wrong_id: 0.0,
            rate_hz: 10,
            sensitivity: 4,
            power_level: 2,
            seq: 0,
            rng: StdRng::seed_from_u64(seed),
            magnitude_rng: StdRng::seed_from_u64(seed ^ MAGNITUDE_STREAM),
            wrong_rng: StdRng::seed_from_u64(seed ^ WRONG_ID_STREAM),
        }
    }

    /// The next frame's bytes (with line noise before it, if configured).
    pub fn next_frame(&mut self) -> Vec<u8> {
        let normal = Normal::new(0.0, self.noise.max(0.0)).expect("finite sigma");
        let mag_normal =
            Normal::new(0.0, self.magnitude_noise.max(0.0) / 100.0).expect("finite sigma");
        let (rng, mag_rng) = (&mut self.rng, &mut self.magnitude_rng);
        // The NorthStar's magnitude law, counts per 1/in^2 at the current settings.
        let scale = magnitude_law::reading(
            1.0,
            magnitude_law::signal_at_30(&self.physics),
            self.power_level,
            self.sensitivity,
        );
        let mut spots = simulate_spots_scaled(
            &self.physics,
            &self.constellation,
            &self.t,
            &self.q,
            scale,
            |_| normal.sample(rng),
            |_| mag_normal.sample(mag_rng),
        );
        if self.wrong_id > 0.0 && spots.len() >= 2 {
            let w = &mut self.wrong_rng;
            if w.random::<f64>() < self.wrong_id {
                let n = spots.len();
                let j = w.random_range(0..n);
                let k = (j + w.random_range(1..n)) % n;
                cta_core::pose::mislabel(&mut spots, j, k);
            }
        }
        let frame = SpotFrame {
            seq: self.seq,
            sensitivity: self.sensitivity,
            spots,
        };
        self.seq = self.seq.wrapping_add(1);
        let mut out = Vec::new();
        if self.rng.random::<f64>() < self.garbage {
            let n = self.rng.random_range(1..40);
            out.extend((0..n).map(|_| self.rng.random::<u8>()));
        }
        let mut buf = [0u8; MAX_FRAME];
        let n = northstar::encode_report(&frame, &mut buf);
        out.extend_from_slice(&buf[..n]);
        out
    }

    /// Handle command bytes from the board; returns the acknowledgement frames.
    pub fn on_command_bytes(&mut self, bytes: &[u8]) -> Vec<u8> {
        answer_commands(&mut self.sensitivity, &mut self.rate_hz, bytes)
    }
}

/// The true physics for a calibration: head pose `d, p`, near-field geometry (nominal if
/// absent), proximity + intensity + Lambertian beacon.
pub fn physics(cal: &Calibration) -> Emulator<f64> {
    let nf = cal
        .near_field
        .unwrap_or(cta_core::pose::NearField::nominal());
    let [ax, ay] = nf.face_angles_deg().map(|a| (a as f64).to_radians());
    let head = Head {
        alpha_x: ax,
        alpha_y: ay,
        s: nf.s as f64,
        beta: nf.beta as f64,
    };
    let v = |a: [f32; 3]| Vector3::new(a[0] as f64, a[1] as f64, a[2] as f64);
    let effects = Effects {
        pattern: cta_core::pattern::Pattern::Lambertian {
            m: nf.pattern_m as f64,
        },
        gain: nf.cell_gains(),
        bias: nf.cell_biases(),
        ..Effects::default()
    };
    Emulator::new(
        head,
        HeadPose {
            d: v(cal.d),
            p: v(cal.p),
        },
        effects,
    )
}

#[cfg(unix)]
struct SimIo<'a> {
    port: &'a mut TTYPort,
    start: Instant,
    to_ns: Vec<u8>,
}

#[cfg(unix)]
impl Io for SimIo<'_> {
    fn now_us(&mut self) -> u64 {
        self.start.elapsed().as_micros() as u64
    }
    fn send_pc(&mut self, bytes: &[u8]) -> bool {
        self.port.write_all(bytes).is_ok()
    }
    fn send_ns(&mut self, bytes: &[u8]) {
        self.to_ns.extend_from_slice(bytes);
    }
}

/// A running simulated board. Dropping it stops the board thread.
#[cfg(unix)]
pub struct SimBoard {
    path: String,
    stop: Arc<AtomicBool>,
    northstar: Arc<Mutex<SimNorthStar>>,
    thread: Option<JoinHandle<()>>,
}

#[cfg(unix)]
impl SimBoard {
    /// Start the board (empty flash) behind a new pseudo-terminal.
    pub fn spawn(northstar: SimNorthStar) -> std::io::Result<Self> {
        Self::spawn_with_flash(northstar, RamFlash::default())
    }

    /// Start the board with the given flash contents (e.g. a previous run's).
    pub fn spawn_with_flash(northstar: SimNorthStar, flash: RamFlash) -> std::io::Result<Self> {
        let (mut master, slave) = TTYPort::pair().map_err(std::io::Error::other)?;
        let path = slave
            .name()
            .ok_or_else(|| std::io::Error::other("pseudo-terminal has no name"))?;
        master
            .set_timeout(Duration::from_millis(2))
            .map_err(std::io::Error::other)?;
        let stop = Arc::new(AtomicBool::new(false));
        let ns = Arc::new(Mutex::new(northstar));
        let (stop2, ns2) = (stop.clone(), ns.clone());
        let thread = std::thread::Builder::new()
            .name("sim-sensor-board".into())
            .spawn(move || run(master, slave, flash, ns2, stop2))?;
        Ok(SimBoard {
            path,
            stop,
            northstar: ns,
            thread: Some(thread),
        })
    }

    /// Path of the pseudo-terminal to open (like `/dev/ttyUSB0` for the real board).
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Change the simulated NorthStar (e.g. move the target).
    pub fn with_northstar<R>(&self, f: impl FnOnce(&mut SimNorthStar) -> R) -> R {
        let mut g = self.northstar.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut g)
    }
}

#[cfg(unix)]
impl Drop for SimBoard {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(unix)]
fn run(
    mut master: TTYPort,
    _slave: TTYPort,
    flash: RamFlash,
    ns: Arc<Mutex<SimNorthStar>>,
    stop: Arc<AtomicBool>,
) {
    let mut board = Board::new(flash, true, ResetCause::PowerOn);
    let start = Instant::now();
    let mut next_frame = Instant::now();
    let mut buf = [0u8; 256];
    {
        let mut io = SimIo {
            port: &mut master,
            start,
            to_ns: Vec::new(),
        };
        board.start(&mut io);
        let to_ns = std::mem::take(&mut io.to_ns);
        let acks = ns
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .on_command_bytes(&to_ns);
        board.on_ns_bytes(&acks, &mut io);
    }
    while !stop.load(Ordering::Relaxed) {
        let n = match master.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => 0,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => 0,
            Err(_) => {
                // No client attached (EIO on a pty master): wait and retry.
                std::thread::sleep(Duration::from_millis(5));
                0
            }
        };
        let mut io = SimIo {
            port: &mut master,
            start,
            to_ns: Vec::new(),
        };
        board.on_pc_bytes(&buf[..n], &mut io);
        let mut g = ns.lock().unwrap_or_else(|e| e.into_inner());
        if !io.to_ns.is_empty() {
            let to_ns = std::mem::take(&mut io.to_ns);
            let acks = g.on_command_bytes(&to_ns);
            board.on_ns_bytes(&acks, &mut io);
        }
        if Instant::now() >= next_frame {
            let bytes = g.next_frame();
            next_frame += Duration::from_secs_f64(1.0 / g.rate_hz.max(1) as f64);
            if next_frame < Instant::now() {
                next_frame = Instant::now();
            }
            drop(g);
            board.on_ns_bytes(&bytes, &mut io);
        }
    }
}

/// A simulated detector's answer to the board's NorthStar command bytes: applies valid
/// sensitivity (1-4) and rate (1-50 Hz) settings and returns one acknowledgement frame per
/// command (status 1 for an out-of-range value). Shared by every simulated NorthStar.
pub fn answer_commands(sensitivity: &mut u8, rate_hz: &mut u8, bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    for cmd in bytes.chunks(7) {
        let Some(c) = northstar::decode_command(cmd) else {
            continue;
        };
        let (kind, ok) = match c {
            NsCommand::SetSensitivity(s) => {
                let ok = (1..=4).contains(&s);
                if ok {
                    *sensitivity = s;
                }
                (0x10, ok)
            }
            NsCommand::SetRate(r) => {
                let ok = (1..=50).contains(&r);
                if ok {
                    *rate_hz = r;
                }
                (0x11, ok)
            }
        };
        let mut a = [0u8; 8];
        let n = northstar::encode_ack(kind, u8::from(!ok), &mut a);
        out.extend_from_slice(&a[..n]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::northstar::{NsDecoder, NsEvent};
    use cta_core::pose::cta_constellation;

    fn frames(ns: &mut SimNorthStar, n: usize) -> Vec<SpotFrame> {
        let mut d = NsDecoder::new();
        let mut out = Vec::new();
        for _ in 0..n {
            d.feed(&ns.next_frame(), |ev| {
                if let NsEvent::Report(f) = ev {
                    out.push(f);
                }
            });
        }
        assert_eq!(out.len(), n);
        out
    }

    /// The NorthStar reads the magnitude law of every simulator (`cta_core::magnitude_law`):
    /// each spot the law's counts of its signal, scaled by the power level and the
    /// sensitivity in force (0.36 at level 1; each step down halves it).
    #[test]
    fn the_magnitudes_follow_the_law_and_the_settings() {
        let t = Vector3::new(0.2, -0.1, 12.0);
        let q = Vector3::new(0.0, 0.0, 0.01);
        let mut ns = SimNorthStar::new(&Calibration::table3(), cta_constellation(), t, q, 0.0, 5);
        let at_30 = magnitude_law::signal_at_30(&ns.physics);
        let signals: Vec<f64> = {
            let ct = cta_core::mrp::dcm(&q).transpose();
            let em = ns
                .physics
                .with_boresight(&(ct * Vector3::new(0.0, 0.0, -1.0)));
            ns.constellation
                .beacons
                .iter()
                .map(|b| {
                    let r = Vector3::new(b.r[0] as f64, b.r[1] as f64, b.r[2] as f64);
                    em.magnitude(&(t + ct * r))
                })
                .collect()
        };
        for (power, sensitivity) in [(1, 4), (2, 3), (1, 2)] {
            ns.power_level = power;
            ns.sensitivity = sensitivity;
            let m: Vec<u16> = frames(&mut ns, 1)[0]
                .spots
                .iter()
                .map(|s| s.magnitude)
                .collect();
            let law: Vec<u16> = signals
                .iter()
                .map(|&s| {
                    magnitude_law::counts(magnitude_law::reading(s, at_30, power, sensitivity))
                })
                .collect();
            assert_eq!(m, law, "power {power}, sensitivity {sensitivity}");
        }
        // At 12 in, power level 1, sensitivity 4: tens of thousands of counts, unsaturated.
        ns.power_level = 1;
        ns.sensitivity = 4;
        let f = frames(&mut ns, 1);
        assert!(
            f[0].spots
                .iter()
                .all(|s| (20_000..60_000).contains(&s.magnitude)),
            "{f:?}"
        );
    }

    /// The magnitude noise scatters the magnitudes by the percentage asked for, from a
    /// stream of its own: the coordinates are those of the same NorthStar without it.
    #[test]
    fn magnitude_noise_has_its_own_stream() {
        // At 12 in, power level 1, the magnitudes are tens of thousands of counts, below
        // saturation: their rounding is negligible.
        let t = Vector3::new(0.2, -0.1, 12.0);
        let q = Vector3::new(0.0, 0.0, 0.01);
        let cal = Calibration::table3();
        let mut quiet = SimNorthStar::new(&cal, cta_constellation(), t, q, 32.768, 5);
        quiet.power_level = 1;
        let mut noisy = quiet.clone();
        noisy.magnitude_noise = 1.0;
        let (a, b) = (frames(&mut quiet, 200), frames(&mut noisy, 200));
        let mut rel = Vec::new();
        for (a, b) in a.iter().zip(&b) {
            assert_eq!(a.spots.len(), b.spots.len());
            for (a, b) in a.spots.iter().zip(&b.spots) {
                assert_eq!((a.id, a.x, a.y), (b.id, b.x, b.y));
                assert!(
                    a.magnitude > 2000 && a.magnitude < 60_000,
                    "{}",
                    a.magnitude
                );
                {
                    rel.push(b.magnitude as f64 / a.magnitude as f64 - 1.0);
                }
            }
        }
        let n = rel.len() as f64;
        assert!(n >= 1000.0, "{n} spots");
        let mean = rel.iter().sum::<f64>() / n;
        let sd = (rel.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        // 1 % asked for; the estimates' own scatter is about 0.02 % and 1.6 % of it.
        assert!(mean.abs() < 0.001, "mean {mean}");
        assert!((sd - 0.01).abs() < 0.001, "sd {sd}");
    }
}
