//! The beacon board's requests (`cta beacon ...`): a link to an identified board, the LED
//! modes and frequency table, the modulation measured on the simulated tick stream, and the
//! pin map.
//!
//! LED ids are `row * 10 + column`; frequencies are indices into the board's table (default:
//! the 10 NorthStar ID pairs, entry `2k` and `2k + 1` for ID `k`).

use std::io;
use std::num::ParseIntError;
use std::time::Duration;

use cta_core::schedule::{grid_position, NORTHSTAR_TABLE_MHZ};
use cta_core::wire::beacon::{
    Beacon, BeaconError, BeaconRequest, BeaconResponse, BeaconStatus, FreqSet, LedMode, LedSetting,
    Limits, LED_COUNT, MAX_FREQS,
};
use cta_core::wire::Identity;
use cta_firmware_beacon::pins::{Pin, BEACON_LINES, BEACON_PINS, RESERVED_PINS, SPARE_PIN};

use crate::boards::link::{open_serial, BoardAt, Link, LinkConfig, LinkError};
use crate::boards::pty::BeaconSim as SimBoard;

/// What went wrong with a beacon board command.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The in-process simulated board could not be started.
    #[error("starting the simulated beacon board: {0}")]
    StartSim(io::Error),
    /// The simulated board served by `cta beacon sim` failed when stopped.
    #[error("simulated beacon board: {0}")]
    StopSim(io::Error),
    /// The serial port could not be opened (its message names the port).
    #[error(transparent)]
    Port(io::Error),
    /// The board on the port did not identify as a beacon board.
    #[error("identifying the board on {path}: {error}")]
    Identify {
        /// The port.
        path: String,
        /// What the link found.
        error: LinkError<BeaconError>,
    },
    /// A request to the identified board failed on the link, named by the board's port.
    #[error("beacon board on {path}: {error}")]
    OnBoard {
        /// The port.
        path: String,
        /// What the link found.
        error: LinkError<BeaconError>,
    },
    /// A well-formed reply of another kind than the request's.
    #[error("unexpected reply to {request}: {reply}")]
    Unexpected {
        /// The request.
        request: &'static str,
        /// The reply, as debugged.
        reply: String,
    },
    /// An LED mode that is not `off`, `on` or table indices.
    #[error("mode {mode:?}: expected `off`, `on` or table indices like `3` or `0,5`: {error}")]
    Mode {
        /// The mode as given.
        mode: String,
        /// Why an index did not parse.
        error: ParseIntError,
    },
    /// A table index beyond the largest table.
    #[error(
        "mode {mode:?}: table index {index} is beyond the largest table ({MAX_FREQS} entries)"
    )]
    Index {
        /// The mode as given.
        mode: String,
        /// The index.
        index: u8,
    },
    /// A setting without `=`.
    #[error("setting {0:?}: expected ID=MODE, e.g. 12=3")]
    Setting(String),
    /// A setting whose LED id is not a number.
    #[error("setting {setting:?}: LED id {id:?} is not a number: {error}")]
    LedId {
        /// The setting as given.
        setting: String,
        /// Its id part.
        id: String,
        /// Why it did not parse.
        error: ParseIntError,
    },
    /// More settings than LEDs.
    #[error("more than {LED_COUNT} settings")]
    TooManySettings,
    /// More frequencies than a table holds.
    #[error("more than {MAX_FREQS} frequencies")]
    TooManyFrequencies,
    /// A frequency that is not a positive number of Hz.
    #[error("frequency {0} Hz is not a positive number of Hz")]
    Frequency(f64),
    /// A simulated duration out of range.
    #[error("--seconds {0}: expected 0 < seconds <= 600")]
    Seconds(f64),
    /// The modulator refused the NorthStar table.
    #[error("default table rejected: {0}")]
    Table(String),
    /// The modulator's incremental outputs differed from its levels.
    #[error("incremental outputs diverged at tick {0}")]
    Diverged(u32),
    /// The measured modulation misses its targets.
    #[error("modulation outside its targets")]
    OutsideTargets,
}

/// Parse an LED mode: `off`, `on`, or comma-separated table indices.
pub fn parse_mode(s: &str) -> Result<LedMode, Error> {
    match s.trim() {
        "off" => return Ok(LedMode::Off),
        "on" => return Ok(LedMode::On),
        _ => {}
    }
    let mut set = 0u32;
    for part in s.split(',') {
        let i: u8 = part.trim().parse().map_err(|error| Error::Mode {
            mode: s.to_string(),
            error,
        })?;
        if i as usize >= MAX_FREQS {
            return Err(Error::Index {
                mode: s.to_string(),
                index: i,
            });
        }
        set |= 1 << i;
    }
    Ok(LedMode::Modulated(FreqSet(set)))
}

/// Parse `ID=MODE`.
pub fn parse_setting(s: &str) -> Result<LedSetting, Error> {
    let (id, mode) = s
        .split_once('=')
        .ok_or_else(|| Error::Setting(s.to_string()))?;
    let led = id.trim().parse().map_err(|error| Error::LedId {
        setting: s.to_string(),
        id: id.to_string(),
        error,
    })?;
    Ok(LedSetting {
        led,
        mode: parse_mode(mode)?,
    })
}

/// One entry of the board's frequency table, with the other entries of the same frequency
/// (a NorthStar cannot tell them apart: the default table's 2 and 19 are both 4050 Hz).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TableEntry {
    /// The frequency, mHz.
    pub mhz: u32,
    /// The other entries of this frequency.
    pub same: Vec<usize>,
}

/// A link to a beacon board that answered as one, on a port or in this process.
pub struct BeaconBoard {
    link: Link<Beacon, Box<dyn serialport::SerialPort>>,
    id: Identity,
    path: String,
    // Declared after the link: the board outlives the link to it.
    sim: Option<SimBoard>,
}

impl BeaconBoard {
    /// Open the board at `at` (starting the in-process simulated board first when asked) and
    /// check that it is a beacon board speaking our protocol.
    pub fn open(at: &BoardAt, config: LinkConfig) -> Result<BeaconBoard, Error> {
        let sim = match at {
            BoardAt::InProcess => Some(SimBoard::spawn().map_err(Error::StartSim)?),
            BoardAt::Port(_) => None,
        };
        let path = match (&sim, at) {
            (Some(s), _) => s.path().to_string(),
            (None, BoardAt::Port(p)) => p.clone(),
            (None, BoardAt::InProcess) => unreachable!("the simulated board was started"),
        };
        let port = open_serial(&path).map_err(Error::Port)?;
        let mut link = Link::<Beacon, _>::new(port, config);
        let id = link.check_board().map_err(|error| Error::Identify {
            path: path.clone(),
            error,
        })?;
        Ok(BeaconBoard {
            link,
            id,
            path,
            sim,
        })
    }

    /// Who answered.
    pub fn identity(&self) -> &Identity {
        &self.id
    }

    /// Whether this is the in-process simulated board (it lives for the one command).
    pub fn in_process(&self) -> bool {
        self.sim.is_some()
    }

    /// A link error named by the board and its port.
    fn named(&self, error: LinkError<BeaconError>) -> Error {
        Error::OnBoard {
            path: self.path.clone(),
            error,
        }
    }

    /// Send `request`; `None` for an acknowledgement.
    fn call(&mut self, request: BeaconRequest) -> Result<Option<BeaconResponse>, Error> {
        self.link.call(request).map_err(|e| self.named(e))
    }

    /// The board's status.
    pub fn status(&mut self) -> Result<BeaconStatus, Error> {
        match self.call(BeaconRequest::Status)? {
            Some(BeaconResponse::Status(s)) => Ok(s),
            other => Err(Error::Unexpected {
                request: "Status",
                reply: format!("{other:?}"),
            }),
        }
    }

    /// Set one LED to `mode` (`off`, `on` or table indices); returns what was set.
    pub fn set(&mut self, led: u8, mode: &str) -> Result<LedSetting, Error> {
        let setting = LedSetting {
            led,
            mode: parse_mode(mode)?,
        };
        self.call(BeaconRequest::Set(setting))?;
        Ok(setting)
    }

    /// Set several LEDs at once from `ID=MODE` settings; returns how many.
    pub fn set_many(&mut self, settings: &[String]) -> Result<usize, Error> {
        let mut v = heapless::Vec::new();
        for s in settings {
            v.push(parse_setting(s)?)
                .map_err(|_| Error::TooManySettings)?;
        }
        let n = v.len();
        self.call(BeaconRequest::SetMany(v))?;
        Ok(n)
    }

    /// Every LED off.
    pub fn all_off(&mut self) -> Result<(), Error> {
        self.call(BeaconRequest::AllOff)?;
        Ok(())
    }

    /// Restore the NorthStar table (all LEDs go off).
    pub fn restore_table(&mut self) -> Result<(), Error> {
        let v = heapless::Vec::from_slice(&NORTHSTAR_TABLE_MHZ)
            .map_err(|_| Error::TooManyFrequencies)?;
        self.call(BeaconRequest::SetTable(v))?;
        Ok(())
    }

    /// Replace the table by these frequencies, Hz (all LEDs go off).
    pub fn set_table(&mut self, hz: &[f64]) -> Result<(), Error> {
        let mut v = heapless::Vec::new();
        for &f in hz {
            if !(f.is_finite() && f > 0.0 && f < 4.0e6) {
                return Err(Error::Frequency(f));
            }
            v.push((f * 1000.0).round() as u32)
                .map_err(|_| Error::TooManyFrequencies)?;
        }
        self.call(BeaconRequest::SetTable(v))?;
        Ok(())
    }

    /// The board's frequency table, each entry with the others of its frequency.
    pub fn table(&mut self) -> Result<Vec<TableEntry>, Error> {
        match self.call(BeaconRequest::GetTable)? {
            Some(BeaconResponse::Table(t)) => Ok(t
                .iter()
                .enumerate()
                .map(|(i, mhz)| TableEntry {
                    mhz: *mhz,
                    same: t
                        .iter()
                        .enumerate()
                        .filter(|&(j, m)| j != i && m == mhz)
                        .map(|(j, _)| j)
                        .collect(),
                })
                .collect()),
            other => Err(Error::Unexpected {
                request: "GetTable",
                reply: format!("{other:?}"),
            }),
        }
    }

    /// The mode of every LED, by id.
    pub fn leds(&mut self) -> Result<Vec<LedMode>, Error> {
        match self.call(BeaconRequest::GetLeds)? {
            Some(BeaconResponse::Leds(modes)) => Ok(modes.to_vec()),
            other => Err(Error::Unexpected {
                request: "GetLeds",
                reply: format!("{other:?}"),
            }),
        }
    }

    /// Change the safety limits; the one not given keeps the board's value. Returns the
    /// limits set.
    pub fn limits(
        &mut self,
        max_lit: Option<u8>,
        deadman_ms: Option<u32>,
    ) -> Result<Limits, Error> {
        let current = self.status()?.limits;
        let limits = Limits {
            max_lit: max_lit.unwrap_or(current.max_lit),
            deadman_ms: deadman_ms.unwrap_or(current.deadman_ms),
        };
        self.call(BeaconRequest::SetLimits(limits))?;
        Ok(limits)
    }

    /// Send heartbeats: one when `every_ms` is 0, else one every `every_ms` until `count`
    /// were sent (0: never stop). Returns how many were acknowledged.
    pub fn heartbeats(&mut self, every_ms: u64, count: u64) -> Result<u64, Error> {
        let mut sent = 0u64;
        loop {
            self.link.heartbeat().map_err(|e| self.named(e))?;
            sent += 1;
            if every_ms == 0 || (count > 0 && sent >= count) {
                break;
            }
            std::thread::sleep(Duration::from_millis(every_ms));
        }
        Ok(sent)
    }
}

/// Start the simulated beacon board on a pseudo-terminal (`cta beacon sim`).
pub fn start_sim() -> Result<SimBoard, Error> {
    SimBoard::spawn().map_err(Error::StartSim)
}

/// Stop a simulated board started by [`start_sim`].
pub fn stop_sim(sim: SimBoard) -> Result<(), Error> {
    sim.stop().map_err(Error::StopSim)
}

/// The worst modulation of one table entry over the LEDs modulated at it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EntryModulation {
    /// Table index.
    pub index: u8,
    /// Table frequency, Hz.
    pub nominal_hz: f64,
    /// Largest `|mean - nominal| / nominal`.
    pub error: f64,
    /// Largest peak-to-peak edge jitter, us.
    pub jitter_pp_us: f64,
    /// Largest RMS edge jitter, us.
    pub jitter_rms_us: f64,
}

/// The modulation of every LED on the simulated tick stream (`cta beacon measure`): the
/// frequency error and edge jitter against the NorthStar table.
#[derive(Debug, Clone, PartialEq)]
pub struct Modulation {
    /// LEDs measured.
    pub leds: usize,
    /// Ticks simulated.
    pub ticks: u32,
    /// Tick rate, Hz.
    pub tick_hz: u32,
    /// Simulated duration, s.
    pub seconds: f64,
    /// Mean port operations per tick.
    pub mean_writes: f64,
    /// Most port operations in one tick.
    pub max_writes: u32,
    /// Per table entry.
    pub entries: Vec<EntryModulation>,
    /// Largest relative frequency error of any LED.
    pub worst_error: f64,
    /// Largest peak-to-peak jitter of any LED, us.
    pub worst_pp_us: f64,
    /// Largest RMS jitter of any LED, us.
    pub worst_rms_us: f64,
}

impl Modulation {
    /// `Ok` when the modulation meets its targets: frequency error within 0.05 %, jitter
    /// within 10 us peak-to-peak.
    pub fn check(&self) -> Result<(), Error> {
        if self.worst_error > 5e-4 || self.worst_pp_us > 10.0 {
            return Err(Error::OutsideTargets);
        }
        Ok(())
    }
}

/// Measure the modulation of all 100 LEDs (LED i at table entry i mod 20) over `seconds` of
/// the simulated tick stream (no board needed).
pub fn measure(seconds: f64) -> Result<Modulation, Error> {
    use cta_core::schedule::{measure::run, Modulator, TICK_HZ};
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 600.0) {
        return Err(Error::Seconds(seconds));
    }
    let mut m = Modulator::new(&NORTHSTAR_TABLE_MHZ, &BEACON_LINES)
        .map_err(|e| Error::Table(format!("{e:?}")))?;
    let modes: [LedMode; LED_COUNT] =
        std::array::from_fn(|i| LedMode::Modulated(FreqSet::single((i % 20) as u8)));
    m.configure(&modes);
    let ticks = (seconds * TICK_HZ as f64).round() as u32;
    let (stats, load) =
        run(&mut m, &modes, &NORTHSTAR_TABLE_MHZ, ticks).map_err(Error::Diverged)?;
    let (mut worst_error, mut worst_pp_us, mut worst_rms_us) = (0f64, 0f64, 0f64);
    let mut entries = Vec::new();
    for i in 0..NORTHSTAR_TABLE_MHZ.len() as u8 {
        let of_i: Vec<_> = stats.iter().filter(|s| s.index == i).collect();
        let e = of_i.iter().map(|s| s.rel_error.abs()).fold(0.0, f64::max);
        let pp = of_i.iter().map(|s| s.jitter_pp_us).fold(0.0, f64::max);
        let rms = of_i.iter().map(|s| s.jitter_rms_us).fold(0.0, f64::max);
        entries.push(EntryModulation {
            index: i,
            nominal_hz: NORTHSTAR_TABLE_MHZ[i as usize] as f64 / 1000.0,
            error: e,
            jitter_pp_us: pp,
            jitter_rms_us: rms,
        });
        worst_error = worst_error.max(e);
        worst_pp_us = worst_pp_us.max(pp);
        worst_rms_us = worst_rms_us.max(rms);
    }
    Ok(Modulation {
        leds: stats.len(),
        ticks,
        tick_hz: TICK_HZ,
        seconds,
        mean_writes: load.mean_writes,
        max_writes: load.max_writes,
        entries,
        worst_error,
        worst_pp_us,
        worst_rms_us,
    })
}

/// One LED of the pin map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LedPin {
    /// LED id, `row * 10 + column`.
    pub id: u8,
    /// Grid row.
    pub row: u8,
    /// Grid column.
    pub col: u8,
    /// Position on the array, in.
    pub x: f64,
    /// Position on the array, in.
    pub y: f64,
    /// The GPIO that drives it.
    pub gpio: Pin,
}

/// The beacon board's pin map (`cta beacon pins`): every LED's grid cell, position and GPIO,
/// the pins the LEDs must not use (with why), and the spare pin.
#[derive(Debug, Clone, PartialEq)]
pub struct PinMap {
    /// The LEDs by id.
    pub leds: Vec<LedPin>,
    /// Reserved pins and what they are for.
    pub reserved: Vec<(Pin, &'static str)>,
    /// The pin left over.
    pub spare: Pin,
}

/// The beacon board's pin map.
pub fn pin_map() -> PinMap {
    PinMap {
        leds: BEACON_PINS
            .iter()
            .enumerate()
            .map(|(id, pin)| {
                let (row, col, x, y) = grid_position(id as u8);
                LedPin {
                    id: id as u8,
                    row,
                    col,
                    x,
                    y,
                    gpio: *pin,
                }
            })
            .collect(),
        reserved: RESERVED_PINS.to_vec(),
        spare: SPARE_PIN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_parse() {
        assert_eq!(parse_mode("off").unwrap(), LedMode::Off);
        assert_eq!(parse_mode("on").unwrap(), LedMode::On);
        assert_eq!(parse_mode("3").unwrap(), LedMode::Modulated(FreqSet(8)));
        assert_eq!(parse_mode("0, 5").unwrap(), LedMode::Modulated(FreqSet(33)));
        assert!(parse_mode("40").is_err());
        assert!(parse_mode("blink").is_err());
        let s = parse_setting("12=on").unwrap();
        assert_eq!((s.led, s.mode), (12, LedMode::On));
        assert!(parse_setting("12").is_err());
        assert!(parse_setting("x=on").is_err());
    }

    #[test]
    fn simulated_modulation_meets_its_targets() {
        measure(0.2).unwrap().check().unwrap();
        assert!(measure(0.0).is_err());
    }
}
