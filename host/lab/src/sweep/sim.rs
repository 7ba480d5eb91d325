//! The simulated CTA: both boards' firmware logic running in-process behind
//! pseudo-terminals, coupled through one simulated apparatus.
//!
//! * The beacon board is the firmware's own [`cta_firmware_beacon::board::Board`] (protocol,
//!   LED cap, dead-man timer); whatever it lights is published to the apparatus before its
//!   reply leaves, so the sensor sees a beacon as soon as the host is told it is lit.
//! * The sensor board is the firmware's own [`cta_firmware_sensor::board::Board`], fed
//!   NorthStar frames in the firmware's (assumed) NorthStar byte format
//!   ([`cta_firmware_sensor::northstar`]) by a simulated detector that looks at the lit LEDs
//!   through the core emulator (eqs 60-63) with the host's effect vocabulary
//!   ([`crate::sim::effects`]), the per-separation plate offset and separation error draws of
//!   [`crate::sim::SimConfig::physics`], and this module's signal model (power level,
//!   sensitivity, "no signal" below the NorthStar's floor, noise growing as the signal
//!   weakens).
//! * The plate moves itself: the run's operator steps call [`SimCta::move_plate`] and
//!   [`SimCta::set_power`] instead of prompting.
//!
//! Both boards are reached through symbolic links in a private temporary directory
//! (like `/dev/serial/by-id/...`), so a board can be unplugged (its pty closed and the link
//! removed) and plugged back (a new pty behind the same path) by the fault injection.
//!
//! **Determinism.** A sample's noise is a function of the seed, the point's physical state
//! (separation, quadrant, power, sensitivity, LED, channel) and the index of the NorthStar
//! frame since the sensor board entered stream mode, never of timing. A run resumed after a
//! kill therefore reproduces, point for point, the uninterrupted run with the same seed.
//!
//! **Speed.** By default the simulated detector is unthrottled: while the sensor board
//! streams, frames are produced as fast as the host reads them. `realtime` runs it at the
//! board's configured rate (10 Hz), as the real sensor.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::error::{bail, Context, Error, Result};
use cta_core::emulator::{grid_position, saturate_i16, Emulator};
use cta_core::magnitude_law;
use cta_core::pose::Spot;
use cta_core::schedule::NORTHSTAR_TABLE_MHZ;
use cta_core::wire::beacon::{FreqSet, LedMode, LED_COUNT};
use cta_core::wire::sensor::Mode;
use cta_core::wire::ResetCause;
use cta_firmware_beacon::board::{Board as BeaconBoard, Outputs};
use cta_firmware_sensor::board::{Board as SensorBoard, Io};
use cta_firmware_sensor::northstar::{self, SpotFrame};
use cta_firmware_sensor::storage::RamFlash;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use serialport::SerialPort;

use super::corners::{CORNER_ORDER, ROD_XY_IN};
use super::plan::{Layout, Plan};
use super::pty::{self, Port};
use super::store::{corner_mean, corner_uncertainty, SeparationEntry};
use crate::sim::effects::Effect;
use crate::sim::{Placement, SimConfig, Truth};

/// Below this reported magnitude the NorthStar does not track a spot (REFERENCE.md §4).
pub const NO_SIGNAL: f64 = 5_000.0;
/// Above this the signal is strong; the noise is `--sim-noise` there.
const STRONG: f64 = 47_000.0;

/// Which simulated board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Which {
    /// The beacon board.
    Beacon,
    /// The sensor board.
    Sensor,
}

/// A scheduled board fault.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// Unplugged: the pty is closed and its path removed, then a new one appears.
    Vanish,
    /// Powered but silent: the board ignores its input and sends nothing.
    Silent,
    /// The NorthStar stops sending frames (the sensor board still answers requests).
    Stall,
    /// The board restarts behind the host's back (its status then gives the reset cause
    /// `watchdog`; a brown-out would give power-on; the port stays):
    /// the beacon board at the `at`-th stream start, so the point's LED goes dark and its
    /// uptime starts again; the sensor board when the `at`-th stream ends, between points, so
    /// it comes back idle at sensitivity 4.
    Reset,
}

/// A fault that starts when the sensor board enters stream mode for the `at`-th time
/// (1-based; the `at`-th point attempt of the session) and lasts `for_ms`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScheduledFault {
    /// What.
    pub kind: FaultKind,
    /// Which board.
    pub board: Which,
    /// Stream start that triggers it.
    pub at: u64,
    /// Duration, ms.
    pub for_ms: u64,
}

/// Faults injected into the simulated boards' serial lines and behaviour.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Faults {
    /// Probability that a byte on either line (either direction) is dropped.
    pub drop: f64,
    /// Probability that a byte is corrupted (one bit flipped).
    pub corrupt: f64,
    /// Probability that a NorthStar frame carries a stray spot: one under an ID no LED is lit
    /// at (a reflection of another light source the detector locked onto).
    #[serde(default)]
    pub stray: f64,
    /// Scheduled faults.
    pub events: Vec<ScheduledFault>,
}

/// A fault spec that could not be read: which part, and what was expected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct FaultSpecError(pub String);

/// The largest `drop=P` or `corrupt=P` (per byte): a request and its reply of some 50 bytes
/// then get through 3 times in 4, so a session starts and runs (at 0.02 the identification
/// already fails its 3 attempts).
pub const MAX_BYTE_FAULT: f64 = 0.005;

impl Faults {
    /// Parse a comma-separated spec: `drop=P`, `corrupt=P`, `stray=P` (per frame),
    /// `KIND=BOARD@N:MS` with KIND `vanish`, `silent` or `stall`, BOARD `beacon` or `sensor`,
    /// and `reset=BOARD@N` ([`FaultKind::Reset`]).
    pub fn parse(spec: &str) -> Result<Faults, FaultSpecError> {
        Faults::parse_spec(spec).map_err(FaultSpecError)
    }

    fn parse_spec(spec: &str) -> Result<Faults, String> {
        let mut f = Faults::default();
        for part in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (k, v) = part
                .split_once('=')
                .ok_or_else(|| format!("fault `{part}`: expected NAME=VALUE"))?;
            let prob = |v: &str| -> Result<f64, String> {
                v.parse::<f64>()
                    .ok()
                    .filter(|p| (0.0..=MAX_BYTE_FAULT).contains(p))
                    .ok_or_else(|| {
                        format!(
                            "fault `{part}`: a probability per byte, 0..={MAX_BYTE_FAULT}: above \
                             it most frames (tens of bytes) are lost and the boards cannot even be \
                             identified"
                        )
                    })
            };
            match k {
                "stray" => {
                    f.stray = v
                        .parse::<f64>()
                        .ok()
                        .filter(|p| (0.0..=1.0).contains(p))
                        .ok_or_else(|| format!("fault `{part}`: a probability per frame, 0..=1"))?
                }
                "drop" => f.drop = prob(v)?,
                "corrupt" => f.corrupt = prob(v)?,
                "reset" => {
                    let bad = || {
                        format!(
                            "fault `{part}`: expected reset=BOARD@N, e.g. reset=beacon@5 (N, the \
                             point attempt of the session that triggers it, counts from 1)"
                        )
                    };
                    let (b, n) = v.split_once('@').ok_or_else(bad)?;
                    let board = match b {
                        "beacon" => Which::Beacon,
                        "sensor" => Which::Sensor,
                        _ => return Err(bad()),
                    };
                    f.events.push(ScheduledFault {
                        kind: FaultKind::Reset,
                        board,
                        at: n.parse().ok().filter(|n| *n >= 1).ok_or_else(bad)?,
                        for_ms: 0,
                    });
                }
                "vanish" | "silent" | "stall" => {
                    let bad = || {
                        format!(
                            "fault `{part}`: expected {k}=BOARD@N:MS, e.g. {k}=sensor@5:1500 (N, \
                             the point attempt of the session that triggers it, counts from 1; \
                             MS: how long, in milliseconds)"
                        )
                    };
                    let (b, rest) = v.split_once('@').ok_or_else(bad)?;
                    let (n, ms) = rest.split_once(':').ok_or_else(bad)?;
                    let board = match b {
                        "beacon" => Which::Beacon,
                        "sensor" => Which::Sensor,
                        _ => return Err(bad()),
                    };
                    let kind = match k {
                        "vanish" => FaultKind::Vanish,
                        "silent" => FaultKind::Silent,
                        _ => FaultKind::Stall,
                    };
                    if kind == FaultKind::Stall && board == Which::Beacon {
                        return Err(format!("fault `{part}`: only the sensor can stall"));
                    }
                    f.events.push(ScheduledFault {
                        kind,
                        board,
                        at: n.parse().ok().filter(|n| *n >= 1).ok_or_else(bad)?,
                        for_ms: ms.parse().map_err(|_| bad())?,
                    });
                }
                _ => {
                    return Err(format!(
                        "unknown fault `{k}` (drop, corrupt, vanish, silent, stall, reset)"
                    ))
                }
            }
        }
        Ok(f)
    }
}

/// How the simulated CTA behaves (stored in the journal so a resume simulates the same).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimSettings {
    /// Seed of the noise and of the geometry draws.
    pub seed: u64,
    /// Noise of a strong signal, counts (1-sigma); grows as 1/sqrt(magnitude) below it.
    pub noise: f64,
    /// Spot magnitude noise, percent of the magnitude (1-sigma); 0 (also in journals written
    /// before it existed): none.
    #[serde(default)]
    pub magnitude_noise: f64,
    /// The LEDs' brightness scatter, percent ([`crate::sim::led_brightness`], LED `i` of
    /// the array); 0 (also in journals written before it existed): all alike.
    #[serde(default)]
    pub led_brightness: f64,
    /// Effects (`NAME=VALUE`, the analysis vocabulary).
    pub effects: Vec<String>,
    /// Run the detector at the board's rate (10 Hz) instead of unthrottled.
    pub realtime: bool,
    /// Injected faults.
    pub faults: Faults,
}

impl Default for SimSettings {
    fn default() -> Self {
        SimSettings {
            seed: 1,
            noise: 10.0,
            magnitude_noise: 0.0,
            led_brightness: 0.0,
            effects: Vec::new(),
            realtime: false,
            faults: Faults::default(),
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Apparatus {
    sep_idx: Option<usize>,
    quadrant: usize,
    power: u8,
    leds: [LedMode; LED_COUNT],
}

struct World {
    em: Emulator<f64>,
    /// Each LED's brightness factor (its magnitude is multiplied by it).
    brightness: Vec<f64>,
    geometry: Vec<Placement>,
    /// Each LED's true in-plane offset from its nominal place (`led_position`), in.
    led_offsets: Vec<[f64; 2]>,
    /// The share of other lit spots' signal in each spot's channel
    /// ([`crate::crosstalk::spot_crosstalk`]).
    spot_crosstalk: f64,
    separations: Vec<f64>,
    layout: Layout,
    settings: SimSettings,
    state: Mutex<Apparatus>,
    stream_starts: AtomicU64,
    /// Beacon-board resets ordered so far ([`FaultKind::Reset`]).
    beacon_resets: AtomicU64,
    /// What each board says of itself when identified ([`SimCta::spawn_posing_as`]).
    posing: Posing,
    stop: AtomicBool,
}

impl World {
    /// Whether a [`FaultKind::Reset`] of `board` is scheduled at `n` (the `n`-th stream
    /// start for the beacon board, end for the sensor board).
    fn resets_due(&self, board: Which, n: u64) -> bool {
        self.settings
            .faults
            .events
            .iter()
            .any(|e| e.kind == FaultKind::Reset && e.board == board && e.at == n)
    }

    fn state(&self) -> std::sync::MutexGuard<'_, Apparatus> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The NorthStar frame number `k` (since stream start) at `sensitivity`.
    fn frame(&self, k: u64, sensitivity: u8, seq: u8) -> SpotFrame {
        let st = *self.state();
        let mut spots = heapless::Vec::new();
        let Some(si) = st.sep_idx else {
            return SpotFrame {
                seq,
                sensitivity,
                spots,
            };
        };
        let place = self.geometry[si];
        let em = place.emulator(&self.em);
        let sep = self.separations[si];
        let c = self.layout.centre(st.quadrant);
        // The NorthStar's magnitude law (`cta_core::magnitude_law`), scaled by the head's own
        // on-axis signal at 30 in (the plate's placement aside).
        let at_30 = magnitude_law::signal_at_30(&self.em);
        // Every lit spot's noise-free reading and magnitude first: `spot_crosstalk` mixes
        // them.
        let mut lit: Vec<(usize, FreqSet, [f64; 2], f64)> = Vec::new();
        for (led, mode) in st.leds.iter().enumerate() {
            let LedMode::Modulated(set) = mode else {
                continue;
            };
            let g = grid_position(10, 1.0, sep, led);
            // The LED where it truly sits on its array (`led_position`), the array where it
            // is mounted, the plate where it truly is.
            let d = self.led_offsets.get(led).copied().unwrap_or_default();
            let r = place.beacon(&nalgebra::Vector3::new(
                g.x + c[0] + d[0],
                g.y + c[1] + d[1],
                g.z,
            ));
            let Some(out) = em.output(&r) else {
                continue;
            };
            let mag = magnitude_law::reading(em.magnitude(&r), at_30, st.power, sensitivity)
                * self.brightness[led];
            if mag.is_nan() || mag < NO_SIGNAL {
                continue;
            }
            lit.push((led, *set, out, mag));
        }
        let mixed = crate::crosstalk::spot_crosstalk(
            self.spot_crosstalk,
            &lit.iter().map(|&(_, _, o, m)| (o, m)).collect::<Vec<_>>(),
        );
        // A spot's noise is drawn afresh when it is lit with others: the same beacon alone
        // and in a group are two measurements (the crosstalk check compares them).
        let company = if lit.len() > 1 {
            lit.iter().fold(lit.len() as u64, |h, &(led, set, ..)| {
                mix(&[h, led as u64, set.0 as u64])
            })
        } else {
            0
        };
        for (&(led, set, _, mag), out) in lit.iter().zip(mixed) {
            let sigma = self.settings.noise * (STRONG / mag).sqrt().max(1.0);
            for ch in set.indices() {
                let key = [
                    self.settings.seed,
                    si as u64,
                    st.quadrant as u64,
                    st.power as u64,
                    sensitivity as u64,
                    led as u64,
                    ch as u64,
                    k,
                ];
                let seed = match company {
                    0 => mix(&key),
                    c => mix(&[mix(&key), c]),
                };
                let mut rng = StdRng::seed_from_u64(seed);
                let nx: f64 = rng.sample(StandardNormal);
                let ny: f64 = rng.sample(StandardNormal);
                // Drawn after x and y, so it never changes them.
                let m = if self.settings.magnitude_noise > 0.0 {
                    let nm: f64 = rng.sample(StandardNormal);
                    (mag * (1.0 + self.settings.magnitude_noise / 100.0 * nm)).max(0.0)
                } else {
                    mag
                };
                let _ = spots.push(Spot {
                    id: ch,
                    x: saturate_i16(out[0] + sigma * nx),
                    y: saturate_i16(out[1] + sigma * ny),
                    magnitude: magnitude_law::counts(m),
                });
            }
        }
        if self.settings.faults.stray > 0.0 {
            let key = [self.settings.seed, si as u64, st.quadrant as u64, k, 0x57a4];
            let mut rng = StdRng::seed_from_u64(mix(&key));
            let lit_ids: Vec<u8> = lit.iter().flat_map(|(_, set, ..)| set.indices()).collect();
            let free = (0..NORTHSTAR_TABLE_MHZ.len() as u8).find(|id| !lit_ids.contains(id));
            if let (true, Some(id)) = (rng.random::<f64>() < self.settings.faults.stray, free) {
                let _ = spots.push(Spot {
                    id,
                    x: rng.random_range(-20_000..20_000),
                    y: rng.random_range(-20_000..20_000),
                    magnitude: 8_000,
                });
            }
        }
        SpotFrame {
            seq,
            sensitivity,
            spots,
        }
    }
}

/// The value of a `spot_crosstalk=C` effect among the `--sim-effect` specs, and the other
/// specs: the sweep's simulated detector applies it between the spots of a frame; the other
/// effects act on each spot alone.
pub(crate) fn take_spot_crosstalk(specs: &[String]) -> Result<(f64, Vec<String>)> {
    let mut c = 0.0;
    let mut rest = Vec::new();
    for s in specs {
        match s.split_once('=') {
            Some((n, v)) if n.trim() == "spot_crosstalk" => {
                c = v
                    .trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|c| (0.0..0.5).contains(c))
                    .ok_or_else(|| {
                        Error::Refused(format!(
                            "--sim-effect {s}: spot_crosstalk=C takes a fraction C in [0, 0.5) \
                             (the share of every other lit spot's signal in a spot's channel)"
                        ))
                    })?;
            }
            _ => rest.push(s.clone()),
        }
    }
    Ok((c, rest))
}

/// SplitMix64 over a key: a well-mixed seed from the sample's identity.
fn mix(key: &[u64]) -> u64 {
    let mut h: u64 = 0x243f_6a88_85a3_08d3;
    for &k in key {
        h = h.wrapping_add(k).wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = h;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        h = z ^ (z >> 31);
    }
    h
}

/// A pty behind a stable symbolic link, which can be unplugged and plugged back.
struct Endpoint {
    link: PathBuf,
    master: Option<Port>,
    _slave: Option<Port>,
}

impl Endpoint {
    fn new(link: PathBuf) -> Result<Endpoint> {
        let mut e = Endpoint {
            link,
            master: None,
            _slave: None,
        };
        e.plug()?;
        Ok(e)
    }

    fn plug(&mut self) -> Result<()> {
        let (master, slave) = pty::plug(&self.link)?;
        self.master = Some(master);
        self._slave = Some(slave);
        Ok(())
    }

    fn unplug(&mut self) {
        let _ = std::fs::remove_file(&self.link);
        self.master = None;
        self._slave = None;
    }
}

/// Applies the line faults (drop, corrupt) to bytes.
struct Line {
    drop: f64,
    corrupt: f64,
    rng: StdRng,
}

impl Line {
    fn pass(&mut self, bytes: &[u8], out: &mut Vec<u8>) {
        if self.drop == 0.0 && self.corrupt == 0.0 {
            out.extend_from_slice(bytes);
            return;
        }
        for &b in bytes {
            if self.rng.random::<f64>() < self.drop {
                continue;
            }
            if self.rng.random::<f64>() < self.corrupt {
                out.push(b ^ (1 << self.rng.random_range(0..8)));
            } else {
                out.push(b);
            }
        }
    }
}

/// What a scheduled fault does to a board's loop right now.
#[derive(Default)]
struct FaultState {
    fired: Vec<bool>,
    until: Option<(FaultKind, Instant)>,
}

impl FaultState {
    /// Check the schedule; returns the fault in force (starting a due one).
    fn poll(&mut self, world: &World, which: Which) -> Option<FaultKind> {
        let events = &world.settings.faults.events;
        if self.fired.len() != events.len() {
            self.fired = vec![false; events.len()];
        }
        let starts = world.stream_starts.load(Ordering::Relaxed);
        if self.until.is_none() {
            for (i, e) in events.iter().enumerate() {
                // Resets happen in the sensor board's loop, where the streams start and end
                // ([`World::resets_due`]).
                if self.fired[i] || e.board != which || e.kind == FaultKind::Reset {
                    continue;
                }
                if starts >= e.at {
                    self.fired[i] = true;
                    self.until = Some((e.kind, Instant::now() + Duration::from_millis(e.for_ms)));
                    break;
                }
            }
        }
        match self.until {
            Some((k, t)) if Instant::now() < t => Some(k),
            _ => {
                self.until = None;
                None
            }
        }
    }
}

/// Write `pending` to the endpoint as far as it goes within ~`wait`; keeps the rest.
fn write_some(ep: &mut Endpoint, pending: &mut Vec<u8>, wait: Duration) {
    let Some(m) = ep.master.as_mut() else {
        pending.clear();
        return;
    };
    if pending.is_empty() {
        return;
    }
    let _ = m.set_timeout(wait);
    if let Ok(n) = m.write(pending) {
        pending.drain(..n);
    }
}

fn read_some(ep: &mut Endpoint, buf: &mut [u8], wait: Duration) -> usize {
    let Some(m) = ep.master.as_mut() else {
        std::thread::sleep(wait.max(Duration::from_millis(1)));
        return 0;
    };
    let _ = m.set_timeout(wait);
    m.read(buf).unwrap_or(0)
}

/// Unplug the endpoint for a `Vanish` fault, and plug it back when it is over.
fn vanish(ep: &mut Endpoint, fault: Option<FaultKind>) {
    match (fault, ep.master.is_some()) {
        (Some(FaultKind::Vanish), true) => ep.unplug(),
        (f, false) if f != Some(FaultKind::Vanish) => {
            let _ = ep.plug();
        }
        _ => {}
    }
}

struct LedOutputs<'a>(&'a World);

impl Outputs for LedOutputs<'_> {
    fn set_table(&mut self, _table_mhz: &[u32]) {
        // The detector identifies spots by channel index; the table's values do not change
        // what it sees.
    }
    fn set_modes(&mut self, modes: &[LedMode; LED_COUNT]) {
        self.0.state().leds = *modes;
    }
}

fn beacon_loop(world: Arc<World>, mut ep: Endpoint) {
    let mut board = BeaconBoard::new(!world.posing.beacon_hardware, ResetCause::PowerOn);
    board.start(&mut LedOutputs(&world));
    let mut t0 = Instant::now();
    let mut resets = 0;
    let mut rx = [0u8; 512];
    let mut tx = [0u8; cta_core::wire::MAX_FRAME];
    let f = &world.settings.faults;
    let mut line_in = Line {
        drop: f.drop,
        corrupt: f.corrupt,
        rng: StdRng::seed_from_u64(world.settings.seed ^ 0xbeac),
    };
    let mut line_out = Line {
        drop: f.drop,
        corrupt: f.corrupt,
        rng: StdRng::seed_from_u64(world.settings.seed ^ 0xbeac0),
    };
    let mut faults = FaultState::default();
    let mut bytes = Vec::new();
    let mut pending = Vec::new();
    while !world.stop.load(Ordering::Relaxed) {
        let fault = faults.poll(&world, Which::Beacon);
        vanish(&mut ep, fault);
        let n = read_some(&mut ep, &mut rx, Duration::from_millis(2));
        // After the read: a request sent after the reset was ordered meets the new board.
        let due = world.beacon_resets.load(Ordering::Relaxed);
        if resets < due {
            resets = due;
            board = BeaconBoard::new(!world.posing.beacon_hardware, ResetCause::Watchdog);
            board.start(&mut LedOutputs(&world));
            t0 = Instant::now();
        }
        let now_ms = t0.elapsed().as_millis() as u64;
        if fault.is_none() {
            bytes.clear();
            line_in.pass(&rx[..n], &mut bytes);
            for &b in &bytes {
                if let Some(frame) = board.feed(b, now_ms, &mut LedOutputs(&world), &mut tx) {
                    line_out.pass(frame, &mut pending);
                }
            }
        }
        board.poll(now_ms, &mut LedOutputs(&world));
        write_some(&mut ep, &mut pending, Duration::from_millis(20));
    }
}

struct SimIo<'a> {
    t0: Instant,
    pc: &'a mut Vec<u8>,
    ns: Vec<u8>,
}

impl Io for SimIo<'_> {
    fn now_us(&mut self) -> u64 {
        self.t0.elapsed().as_micros() as u64
    }
    fn send_pc(&mut self, bytes: &[u8]) -> bool {
        self.pc.extend_from_slice(bytes);
        true
    }
    fn send_ns(&mut self, bytes: &[u8]) {
        self.ns.extend_from_slice(bytes);
    }
}

/// The simulated detector's side of the NorthStar link.
struct Detector {
    sensitivity: u8,
    rate_hz: u8,
    seq: u8,
}

impl Detector {
    /// Handle command bytes from the board; returns the acknowledgements.
    fn commands(&mut self, bytes: &[u8]) -> Vec<u8> {
        cta_firmware_sensor::sim::answer_commands(&mut self.sensitivity, &mut self.rate_hz, bytes)
    }
}

fn sensor_loop(world: Arc<World>, mut ep: Endpoint) {
    let mut board = SensorBoard::new(
        RamFlash::default(),
        !world.posing.sensor_hardware,
        ResetCause::PowerOn,
    );
    let mut t0 = Instant::now();
    let mut det = Detector {
        sensitivity: 4,
        rate_hz: 10,
        seq: 0,
    };
    let f = &world.settings.faults;
    let mut line_in = Line {
        drop: f.drop,
        corrupt: f.corrupt,
        rng: StdRng::seed_from_u64(world.settings.seed ^ 0x5e45),
    };
    let mut line_out = Line {
        drop: f.drop,
        corrupt: f.corrupt,
        rng: StdRng::seed_from_u64(world.settings.seed ^ 0x5e450),
    };
    let mut to_pc: Vec<u8> = Vec::new();
    let mut pending: Vec<u8> = Vec::new();
    {
        let mut io = SimIo {
            t0,
            pc: &mut to_pc,
            ns: Vec::new(),
        };
        board.start(&mut io);
        let acks = det.commands(&std::mem::take(&mut io.ns));
        board.on_ns_bytes(&acks, &mut io);
    }
    let mut rx = [0u8; 512];
    let mut bytes = Vec::new();
    let mut k: u64 = 0;
    let mut ends: u64 = 0;
    let mut faults = FaultState::default();
    let mut next_frame = Instant::now();
    let mut frame_buf = [0u8; northstar::MAX_FRAME];
    while !world.stop.load(Ordering::Relaxed) {
        let fault = faults.poll(&world, Which::Sensor);
        vanish(&mut ep, fault);
        let streaming = board.mode() == Mode::Stream;
        let busy = !pending.is_empty() || (streaming && !world.settings.realtime);
        let wait = if busy {
            Duration::ZERO
        } else {
            Duration::from_millis(1)
        };
        let n = read_some(&mut ep, &mut rx, wait);
        let mut io = SimIo {
            t0,
            pc: &mut to_pc,
            ns: Vec::new(),
        };
        if n > 0 && !matches!(fault, Some(FaultKind::Silent | FaultKind::Vanish)) {
            bytes.clear();
            line_in.pass(&rx[..n], &mut bytes);
            let before = board.mode();
            board.on_pc_bytes(&bytes, &mut io);
            if board.mode() == Mode::Stream && before != Mode::Stream {
                k = 0;
                let n = world.stream_starts.fetch_add(1, Ordering::Relaxed) + 1;
                if world.resets_due(Which::Beacon, n) {
                    // Dark before the point's first frame; the beacon loop restarts its board.
                    world.state().leds = [LedMode::Off; LED_COUNT];
                    world.beacon_resets.fetch_add(1, Ordering::Relaxed);
                }
            }
            if before == Mode::Stream && board.mode() != Mode::Stream {
                ends += 1;
                if world.resets_due(Which::Sensor, ends) {
                    // A new board (a new flash too: the sweep stores nothing) that sends the
                    // detector its start-up settings, as on power-up.
                    board = SensorBoard::new(
                        RamFlash::default(),
                        !world.posing.sensor_hardware,
                        ResetCause::Watchdog,
                    );
                    t0 = Instant::now();
                    io.t0 = t0;
                    board.start(&mut io);
                }
            }
            if !io.ns.is_empty() {
                let acks = det.commands(&std::mem::take(&mut io.ns));
                board.on_ns_bytes(&acks, &mut io);
            }
        }
        // The detector.
        let stalled = fault.is_some();
        let streaming = board.mode() == Mode::Stream;
        if !stalled {
            let frames = if world.settings.realtime {
                let now = Instant::now();
                if now >= next_frame {
                    next_frame += Duration::from_secs_f64(1.0 / det.rate_hz.max(1) as f64);
                    if next_frame < now {
                        next_frame = now;
                    }
                    1
                } else {
                    0
                }
            } else if streaming && pending.len() < 4096 {
                16
            } else {
                0
            };
            for _ in 0..frames {
                let frame = if streaming {
                    world.frame(k, det.sensitivity, det.seq)
                } else {
                    SpotFrame {
                        seq: det.seq,
                        sensitivity: det.sensitivity,
                        spots: heapless::Vec::new(),
                    }
                };
                if streaming {
                    k += 1;
                }
                det.seq = det.seq.wrapping_add(1);
                let len = northstar::encode_report(&frame, &mut frame_buf);
                board.on_ns_bytes(&frame_buf[..len], &mut io);
            }
        }
        if !to_pc.is_empty() {
            if matches!(fault, Some(FaultKind::Silent | FaultKind::Vanish)) {
                to_pc.clear();
            } else {
                line_out.pass(&to_pc, &mut pending);
                to_pc.clear();
            }
        }
        write_some(&mut ep, &mut pending, Duration::from_millis(1));
    }
}

/// Which simulated boards identify themselves as hardware (`simulated: false` in the
/// identity they answer with), standing in for real boards in tests of what a sweep does on
/// the real CTA: what it records of the apparatus, and a resume onto another kind of board
/// ([`SimCta::spawn_posing_as`]). The default: both say they are simulated, as the
/// simulated CTA and `cta beacon sim`, `cta sensor sim` do.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Posing {
    /// The beacon board says it is hardware.
    pub beacon_hardware: bool,
    /// The sensor board says it is hardware.
    pub sensor_hardware: bool,
}

/// The running simulated CTA.
pub struct SimCta {
    world: Arc<World>,
    dir: PathBuf,
    threads: Vec<JoinHandle<()>>,
    config: SimConfig,
}

impl SimCta {
    /// Start both simulated boards for `plan`.
    pub fn spawn(plan: &Plan, settings: &SimSettings) -> Result<SimCta> {
        SimCta::spawn_posing_as(plan, settings, Posing::default())
    }

    /// [`SimCta::spawn`], with the boards `posing` names identifying themselves as hardware
    /// (for tests; the sweep's own simulated CTA never does).
    pub fn spawn_posing_as(plan: &Plan, settings: &SimSettings, posing: Posing) -> Result<SimCta> {
        let (spot_crosstalk, others) = take_spot_crosstalk(&settings.effects)?;
        let effects = others
            .iter()
            .map(|s| Effect::parse(s).map_err(|e| Error::Refused(format!("--sim-effect {s}: {e}"))))
            .collect::<Result<Vec<_>>>()?;
        crate::sim::effects::check_unique(&effects)
            .and_then(|_| crate::sim::effects::check_sweep(&effects))
            .map_err(|e| Error::Refused(format!("--sim-effect: {e}")))?;
        if !(settings.noise.is_finite() && settings.noise >= 0.0) {
            bail!(
                "--sim-noise {}: must be a non-negative number of counts",
                settings.noise
            );
        }
        if !(0.0..=crate::sim::MAX_MAGNITUDE_NOISE).contains(&settings.magnitude_noise) {
            bail!(
                "--sim-magnitude-noise {}: between 0 and {} percent",
                settings.magnitude_noise,
                crate::sim::MAX_MAGNITUDE_NOISE
            );
        }
        if !(0.0..=crate::sim::MAX_LED_BRIGHTNESS).contains(&settings.led_brightness) {
            bail!(
                "--sim-led-brightness {}: between 0 and {} percent",
                settings.led_brightness,
                crate::sim::MAX_LED_BRIGHTNESS
            );
        }
        let config = SimConfig {
            separations: plan.separations.clone(),
            effects,
            noise: settings.noise,
            magnitude_noise: settings.magnitude_noise,
            led_brightness: settings.led_brightness,
            seed: settings.seed,
            samples: plan.samples as usize,
            ..SimConfig::default()
        };
        let phys = config.physics();
        let world = Arc::new(World {
            em: phys.emulator,
            brightness: crate::sim::led_brightness(
                settings.seed,
                settings.led_brightness,
                LED_COUNT,
            ),
            geometry: phys.geometry,
            led_offsets: phys.led_offsets,
            spot_crosstalk,
            separations: plan.separations.clone(),
            layout: plan.layout,
            settings: settings.clone(),
            state: Mutex::new(Apparatus {
                sep_idx: None,
                quadrant: 0,
                power: plan.power_levels[0],
                leds: [LedMode::Off; LED_COUNT],
            }),
            stream_starts: AtomicU64::new(0),
            beacon_resets: AtomicU64::new(0),
            posing,
            stop: AtomicBool::new(false),
        });
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let dir = std::env::temp_dir().join(format!(
            "cta-sim-{}-{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let beacon = Endpoint::new(dir.join("beacon"))?;
        let sensor = Endpoint::new(dir.join("sensor"))?;
        let (w1, w2) = (world.clone(), world.clone());
        let threads = vec![
            std::thread::Builder::new()
                .name("sim-beacon-board".into())
                .spawn(move || beacon_loop(w1, beacon))?,
            std::thread::Builder::new()
                .name("sim-sensor-board".into())
                .spawn(move || sensor_loop(w2, sensor))?,
        ];
        Ok(SimCta {
            world,
            dir,
            threads,
            config,
        })
    }

    /// Serial device of the simulated beacon board.
    pub fn beacon_path(&self) -> PathBuf {
        self.dir.join("beacon")
    }

    /// Serial device of the simulated sensor board.
    pub fn sensor_path(&self) -> PathBuf {
        self.dir.join("sensor")
    }

    /// Move the plate to separation `sep_idx` of the plan, the array in `quadrant`; returns
    /// the simulated operator's corner readings ([`plate_corners`]): the plate's true heights
    /// at the rods, read to 1 mil. The simulated plate is level unless a `plate_tilt` is
    /// simulated; then the corners show that tilt, as a real plate's would.
    pub fn move_plate(&self, sep_idx: usize, nominal: f64, quadrant: usize) -> SeparationEntry {
        {
            let mut st = self.world.state();
            st.sep_idx = Some(sep_idx);
            st.quadrant = quadrant;
        }
        let place = self.world.geometry[sep_idx];
        let corners = plate_corners(self.world.settings.seed, sep_idx, nominal, &place);
        separation_entry(sep_idx, nominal, corners, "simulated plate".into())
    }

    /// Mount the simulated array in `quadrant` of the plate (quad layout).
    pub fn mount_quadrant(&self, quadrant: usize) {
        self.world.state().quadrant = quadrant;
    }

    /// Flip the simulated power switches.
    pub fn set_power(&self, level: u8) {
        self.world.state().power = level;
    }

    /// The truth behind the simulated data (written next to it as `data.truth.json`).
    pub fn truth(&self) -> Truth {
        let (d, mut t) = SimConfig {
            separations: vec![],
            ..self.config.clone()
        }
        .run();
        drop(d);
        let phys = self.config.physics();
        t.generator = format!("cta {} sweep --sim", env!("CARGO_PKG_VERSION"));
        t.separations = self.config.separations.clone();
        t.plate_offsets = phys.geometry.iter().map(|g| g.offset).collect();
        t.separation_errors = phys.geometry.iter().map(|g| g.sep_error).collect();
        t.plate_tilts_deg = phys.geometry.iter().map(|g| g.tilt_deg).collect();
        t.noise_counts = self.config.noise;
        if self.world.spot_crosstalk > 0.0 {
            t.effects
                .push(format!("spot_crosstalk={}", self.world.spot_crosstalk));
        }
        t.noise_law = Some(format!(
            "noise_counts for a spot of magnitude {STRONG} or more, noise_counts * sqrt({STRONG} \
             / magnitude) for a dimmer one (its shot noise; about 1.5x at 30 in on axis)"
        ));
        t
    }

    /// Sensor-board stream starts so far (the fault schedule's clock).
    pub fn stream_starts(&self) -> u64 {
        self.world.stream_starts.load(Ordering::Relaxed)
    }

    /// The directory holding the boards' device links.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for SimCta {
    fn drop(&mut self) {
        self.world.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The simulated operator's corner readings of the plate at separation `sep_idx` (nominal
/// `nominal` in, placed by `place`), for the simulation's `seed` ([`SimCta::move_plate`]):
/// at each rod ([`CORNER_ORDER`], [`ROD_XY_IN`]) the height of the plate's surface turned by
/// the placement's tilt about its centre, with a reading error of up to 1 mil, read to 1
/// mil (so a reading is within 1.5 mil of the true height, a level plate's within 1 mil of
/// the nominal). The separation error (`separation_error`) is a misreading of the whole plate, not
/// of one corner: the corners average to the nominal, as the operator recorded it.
fn plate_corners(seed: u64, sep_idx: usize, nominal: f64, place: &Placement) -> Vec<f64> {
    let mut rng = StdRng::seed_from_u64(mix(&[seed, 0x7117, sep_idx as u64]));
    let n = place.rotation() * nalgebra::Vector3::z();
    CORNER_ORDER
        .iter()
        .map(|(sx, sy)| {
            let (x, y) = (sx * ROD_XY_IN, sy * ROD_XY_IN);
            let height = nominal - (n.x * x + n.y * y) / n.z;
            round3(height + rng.random_range(-0.001..=0.001))
        })
        .collect()
}

fn round3(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

/// A separation entry from corner readings: their mean (rounded to 0.1 mil) and its Ch IV
/// uncertainty, the largest difference between a reading and the mean
/// ([`corner_uncertainty`]). Readings are taken in [`CORNER_ORDER`] at the rods
/// [`ROD_XY_IN`] from the centre, and the entry says so.
pub fn separation_entry(
    sep_idx: usize,
    nominal: f64,
    corners: Vec<f64>,
    source: String,
) -> SeparationEntry {
    let corners_empty = corners.is_empty();
    let (mean, uncertainty) = if corners_empty {
        (nominal, 0.0)
    } else {
        let m = corner_mean(&corners);
        ((m * 1e4).round() / 1e4, corner_uncertainty(&corners))
    };
    SeparationEntry {
        sep_idx,
        nominal,
        corners,
        mean,
        uncertainty,
        source,
        rods_xy_in: (!corners_empty).then_some(ROD_XY_IN),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::corners::corner_tilt;

    /// Thesis Ch IV: the corners are averaged to the centre height, whose uncertainty is "the
    /// difference between the center height and the maximum and minimum measurements". One
    /// corner 3t above the mean and three t below: the bound is 3t (the corners' standard
    /// deviation would say 2t); one corner low, the same by symmetry.
    #[test]
    fn the_separation_uncertainty_is_the_largest_corner_difference_from_the_mean() {
        let t = 0.002;
        for (corners, mean, bound) in [
            (
                vec![10.0 + 3.0 * t, 10.0 - t, 10.0 - t, 10.0 - t],
                10.0,
                3.0 * t,
            ),
            (
                vec![20.0 - 3.0 * t, 20.0 + t, 20.0 + t, 20.0 + t],
                20.0,
                3.0 * t,
            ),
            // A tilted plate: two corners high, two low.
            (vec![5.004, 5.004, 4.996, 4.996], 5.0, 0.004),
            // Max and min unequally far from the mean: the larger of the two.
            (vec![8.010, 8.0, 8.0, 7.998], 8.002, 0.008),
        ] {
            let e = separation_entry(0, mean, corners.clone(), "test".into());
            assert!((e.mean - mean).abs() < 1e-9, "{corners:?}: mean {}", e.mean);
            assert!(
                (e.uncertainty - bound).abs() < 1e-9,
                "{corners:?}: uncertainty {} for {bound}",
                e.uncertainty
            );
        }
        // Not measured (`--yes`): the nominal, no uncertainty claimed.
        let e = separation_entry(3, 12.0, vec![], "scripted".into());
        assert_eq!((e.mean, e.uncertainty), (12.0, 0.0));
    }

    /// The simulated plate is level unless a tilt is simulated: its corners are within the
    /// reading's 1 mil of the nominal (the operator's question about corners beyond +/-5
    /// mils never comes up) and say no tilt beyond what a mil gives. A tilted plate's
    /// corners give its tilt back to within that, and their mean is still the nominal (to
    /// the readings' 1.5 mil).
    #[test]
    fn simulated_corners_read_the_plate_as_placed() {
        // The most readings within 1.5 mil of the truth turn a slope: 4 x 1.5 mils over 4 rod
        // distances (the four readings all wrong the same way for one slope).
        let mil_deg = (0.0015 / ROD_XY_IN).atan().to_degrees();
        for seed in 0..200 {
            for (i, nominal) in [1.0, 2.0, 7.5, 15.0, 30.0].into_iter().enumerate() {
                let level = plate_corners(seed, i, nominal, &Placement::default());
                assert!(
                    super::super::store::levelness_question(&level).is_none(),
                    "{level:?}"
                );
                assert!(level.iter().all(|c| (c - nominal).abs() <= 0.001 + 1e-12));
                let t = corner_tilt(&level, ROD_XY_IN).unwrap();
                assert!(t.tilt_deg.iter().all(|v| v.abs() <= mil_deg), "{t:?}");
                let tilt = [0.3 * (seed as f64 / 100.0 - 1.0), 0.2];
                let place = Placement {
                    tilt_deg: tilt,
                    sep_error: 0.05,
                    ..Placement::default()
                };
                let c = plate_corners(seed, i, nominal, &place);
                let t = corner_tilt(&c, ROD_XY_IN).unwrap();
                for j in 0..2 {
                    assert!(
                        (t.tilt_deg[j] - tilt[j]).abs() <= mil_deg,
                        "{tilt:?}: {t:?}"
                    );
                }
                let e = separation_entry(i, nominal, c, "test".into());
                assert!((e.mean - nominal).abs() <= 0.0016, "{e:?}");
                assert_eq!(e.rods_xy_in, Some(ROD_XY_IN));
            }
        }
        // A 0.2 deg tilt is ~30 mils across the rods: the operator would be asked.
        let c = plate_corners(
            1,
            0,
            10.0,
            &Placement {
                tilt_deg: [0.2, 0.0],
                ..Placement::default()
            },
        );
        assert!(
            super::super::store::levelness_question(&c).is_some(),
            "{c:?}"
        );
    }
}
