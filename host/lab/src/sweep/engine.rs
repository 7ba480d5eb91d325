//! The run engine: walks the plan's points, drives both boards over serial, asks for the
//! manual steps, commits every point, and survives what a lab throws at it.
//!
//! Per point: light the beacon (beacon board `Set`), set the sensitivity if it changed
//! (sensor board), wait `settle_ms` (heartbeating the beacon board), switch the sensor board
//! to stream mode and read its spot reports until `samples` of them carry the beacon's spot
//! (or `no_signal_reports` carried none: "no signal"; or `max_reports` were read: "partial"),
//! switch it back to idle, turn the beacon off, commit.
//!
//! Faults: a board that stops answering (or whose port fails, e.g. unplugged) or a sensor
//! that stops reporting pauses the run: the point in progress is abandoned (nothing of it is
//! written), the board is reopened and re-identified and its state restored, with a backoff
//! that doubles up to `backoff_max_s`, and the point is measured again from the start. After
//! `give_up_s` without success the run stops cleanly, resumable. A board that restarts
//! behind the sweep, its port staying up, is found by its counters and clock going back (the
//! sensor board's spot reports; the beacon board's status after a point short of samples)
//! and handled the same way, its reset cause journalled. Every fault and what was done
//! is journalled. A refusal by a board (a plan the board cannot do) stops the run with the
//! board's message.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, LazyLock};
use std::time::{Duration, Instant};

use super::error::{Error, Result};
use cta_core::wire::beacon::{
    Beacon, BeaconRequest, BeaconResponse, FreqSet, LedMode, LedSetting, DEADMAN_DEFAULT_MS,
};
use cta_core::wire::sensor::{
    Mode, SensorProtocol, SensorRequest, SensorResponse, SensorStatus, SpotReport,
};
use cta_core::wire::{Identity, Protocol, Response};
use serialport::SerialPort;

use super::plan::{channel_of, Plan};
use super::points::{Lit, Point};
use super::signals as sig;
use super::sim::{separation_entry, SimCta};
use super::store::{now, Event, PointStatus, RunDir, SeparationEntry};
use super::watch::Watch;
use crate::boards::link::{open_serial, Link, LinkConfig, LinkError};
use crate::data::{Dataset, Sample};

/// Set by the signal handlers (Ctrl-C, SIGTERM, SIGHUP: see `sweep::run`); checked between
/// and inside points, and while waiting for the operator. Shared with `signal_hook`'s flag
/// handlers, hence the `Arc`.
pub static INTERRUPTED: LazyLock<Arc<AtomicBool>> =
    LazyLock::new(|| Arc::new(AtomicBool::new(false)));

/// The signal that set [`INTERRUPTED`] (0: none, or set without a signal).
pub static SIGNAL: LazyLock<Arc<AtomicUsize>> = LazyLock::new(|| Arc::new(AtomicUsize::new(0)));

/// What stopped the sweep, as the summary, the error and the journal say it: `Ctrl-C` for
/// SIGINT (and when [`INTERRUPTED`] was set without a signal), `SIGTERM`, `SIGHUP`.
pub fn interruption() -> &'static str {
    match interruption_signal() {
        sig::SIGTERM => "SIGTERM",
        sig::SIGHUP => "SIGHUP",
        _ => "Ctrl-C",
    }
}

/// The number of the signal that stopped the sweep: SIGTERM, SIGHUP, else SIGINT (Ctrl-C).
pub fn interruption_signal() -> i32 {
    match i32::try_from(SIGNAL.load(Ordering::SeqCst)).unwrap_or(0) {
        s @ (sig::SIGTERM | sig::SIGHUP) => s,
        _ => sig::SIGINT,
    }
}

type Port = Box<dyn SerialPort>;

/// Why a point attempt failed.
#[derive(Debug)]
pub enum Fault {
    /// A board stopped answering or its port failed: reconnect it.
    Lost(&'static str, String),
    /// The sensor board answers but sends no reports.
    Stalled(String),
    /// A board refused a request: the plan asks for something it cannot do. Stops the run.
    Fatal(Error),
    /// Ctrl-C.
    Interrupted,
}

fn link_fault<E: std::fmt::Debug + std::fmt::Display>(
    board: &'static str,
    e: LinkError<E>,
) -> Fault {
    match e {
        LinkError::Io(_) | LinkError::Timeout { .. } | LinkError::BadFrame { .. } => {
            Fault::Lost(board, e.to_string())
        }
        LinkError::Refused { .. } | LinkError::WrongBoard { .. } | LinkError::Encode(_) => {
            Fault::Fatal(Error::Board(format!("{board} board: {e}")))
        }
        LinkError::Unexpected { .. } => Fault::Lost(board, e.to_string()),
    }
}

/// One board's connection, reopened by path when lost.
struct Conn<P: Protocol> {
    name: &'static str,
    path: String,
    config: LinkConfig,
    link: Option<Link<P, Port>>,
}

impl<P: Protocol> Conn<P> {
    fn connect(&mut self) -> Result<Identity, Fault> {
        self.link = None;
        let port = open_serial(&self.path).map_err(|e| Fault::Lost(self.name, e.to_string()))?;
        let mut link = Link::new(port, self.config);
        let id = link.check_board().map_err(|e| match e {
            LinkError::WrongBoard { .. } => Fault::Fatal(Error::Board(format!(
                "{} port {}: {e}",
                self.name, self.path
            ))),
            e => Fault::Lost(self.name, e.to_string()),
        })?;
        self.link = Some(link);
        Ok(id)
    }

    fn link(&mut self) -> Result<&mut Link<P, Port>, Fault> {
        self.link
            .as_mut()
            .ok_or_else(|| Fault::Lost(self.name, "not connected".into()))
    }
}

/// What the operator does: the manual steps of a run.
pub trait Operator {
    /// The plate must be at `p.separation`: move it (or confirm it is still there, when
    /// `previous` was recorded before a resume) and give the corner readings.
    fn separation(
        &mut self,
        p: &Point,
        previous: Option<&SeparationEntry>,
    ) -> Result<SeparationEntry>;
    /// Mount the array in quadrant `q` (quad layout). Returns who confirmed it.
    fn quadrant(&mut self, q: usize) -> Result<String>;
    /// Set the power switches to `level`. Returns who confirmed it.
    fn power(&mut self, level: u8) -> Result<String>;
}

/// Scripted runs (`--yes`): nothing is asked; separations are the plan's nominal values,
/// recorded as not measured.
pub struct Scripted;

impl Operator for Scripted {
    fn separation(
        &mut self,
        p: &Point,
        previous: Option<&SeparationEntry>,
    ) -> Result<SeparationEntry> {
        if let Some(e) = previous {
            return Ok(e.clone());
        }
        Ok(separation_entry(
            p.sep_idx,
            p.separation,
            Vec::new(),
            "scripted (--yes): nominal, not measured".into(),
        ))
    }
    fn quadrant(&mut self, _q: usize) -> Result<String> {
        Ok("scripted (--yes)".into())
    }
    fn power(&mut self, _level: u8) -> Result<String> {
        Ok("scripted (--yes)".into())
    }
}

/// The simulated plate moves itself.
pub struct SimOperator<'a>(pub &'a SimCta);

impl Operator for SimOperator<'_> {
    fn separation(
        &mut self,
        p: &Point,
        _previous: Option<&SeparationEntry>,
    ) -> Result<SeparationEntry> {
        Ok(self.0.move_plate(p.sep_idx, p.separation, p.quadrant))
    }
    fn quadrant(&mut self, q: usize) -> Result<String> {
        // Called on every change of quadrant; move_plate only runs when the separation
        // changes (the first quadrant of each separation).
        self.0.mount_quadrant(q);
        Ok("simulated plate".into())
    }
    fn power(&mut self, level: u8) -> Result<String> {
        self.0.set_power(level);
        Ok("simulated power switches".into())
    }
}

/// Counters of a session.
#[derive(Debug, Default, Clone, Copy)]
pub struct Stats {
    /// Points committed, by outcome.
    pub ok: usize,
    /// "no signal" points.
    pub no_signal: usize,
    /// Partial points.
    pub partial: usize,
    /// Samples written.
    pub samples: u64,
    /// Faults.
    pub faults: usize,
    /// Point attempts repeated.
    pub retries: usize,
    /// Successful reconnections.
    pub reconnects: usize,
    /// Reports lost on the wire.
    pub lost_reports: u64,
    /// Beacons measured (a grouped point lights several), by outcome: all their samples, none
    /// (no signal), some (partial).
    pub beacons: (usize, usize, usize),
}

/// How a session ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// Every point measured.
    Complete,
    /// Ctrl-C.
    Interrupted,
    /// A board stayed lost past `give_up_s`.
    GaveUp(String),
}

/// Result of one point's measurement.
struct Measured {
    status: PointStatus,
    /// Per beacon lit, in the point's order: its samples (x, y, magnitude, seconds since the
    /// run started, report counter).
    samples: Vec<Vec<(i16, i16, u16, f64, u32)>>,
    reports: u32,
    lost: u32,
    /// Spots left out of the data, by ID: an ID no LED of the point was lit at (a
    /// reflection, another light source), or one ID twice in a report.
    strays: std::collections::BTreeMap<u8, u32>,
}

impl Measured {
    /// Samples of all beacons.
    fn total(&self) -> usize {
        self.samples.iter().map(Vec::len).sum()
    }
}

/// Spot reports in a row at another sensitivity than the point's before the sweep counts the
/// sensor board as reset behind its back (its own resends fix a detector that missed a
/// setting within a frame or two, `firmware-sensor` `RESEND_EVERY`).
pub const WRONG_SENSITIVITY_REPORTS: u32 = 3;
/// The same, at a point that has just set the sensitivity: the detector may take a few
/// frames to apply it, and the board resends a setting it missed after 10 frames.
pub const WRONG_SENSITIVITY_AFTER_CHANGE: u32 = 25;

/// The beacon board's status at the last reading: what a reset or a dead-man trip since
/// then changes ([`Engine::check_beacon`]).
#[derive(Debug, Clone, Copy)]
struct BeaconSeen {
    at: Instant,
    uptime_ms: u64,
    deadman_trips: u32,
}

/// The sensor board's counters as last seen in this board's life: its next spot report
/// carries at least this report number and board time. Both restart at 0 when the board
/// restarts, and a restarted board streams nothing until told to, so a report below either
/// is from a board that was reset after the last one seen ([`Engine::collect`]), when its
/// sensitivity and rate went back to their start-up values (4, 10 Hz).
#[derive(Debug, Clone, Copy)]
struct SensorSeen {
    seq: u32,
    t_us: u64,
}

/// Whether the sensor board's wrapping report counter went back from `seen` to `now` (a
/// step of more than half its range counts as back, so a wrap after 2^32 reports does not).
fn went_back(now: u32, seen: u32) -> bool {
    now.wrapping_sub(seen) > u32::MAX / 2
}

/// The sensor board's report clock tied to the host's wall clock at the last restore.
#[derive(Debug, Clone, Copy, Default)]
struct BoardClock {
    /// Board time at the tie, microseconds since its reset.
    board_us: u64,
    /// Host time at the tie, seconds since the epoch.
    epoch_s: f64,
}

impl BoardClock {
    /// Seconds since `run_start` (epoch seconds) of a report the board timed `t_us`, to
    /// 0.1 ms.
    fn seconds(&self, t_us: u64, run_start: f64) -> f64 {
        let t = self.epoch_s + (t_us as f64 - self.board_us as f64) / 1e6 - run_start;
        (t.max(0.0) * 1e4).round() / 1e4
    }
}

/// The engine.
pub struct Engine<'a> {
    plan: &'a Plan,
    beacon: Conn<Beacon>,
    sensor: Conn<SensorProtocol>,
    sensitivity: Option<u8>,
    last_heartbeat: Instant,
    /// Skip settle waits (the unthrottled simulated CTA has nothing to settle).
    pub skip_settle: bool,
    /// Session counters.
    pub stats: Stats,
    /// The points of the crosstalk check's blocks measured in this session, summed up
    /// ([`crate::crosstalk`]).
    pub checked: Vec<crate::crosstalk::PointSums>,
    /// When the run started (its first session), seconds since the epoch: the origin of the
    /// data's `time_s`.
    pub run_start: f64,
    /// The sensor board's clock as tied at the last restore.
    clock: BoardClock,
    /// The beacon board's frequency table (millihertz), as read at the last connection and
    /// checked against the plan ([`Engine::check_table`]): the table the run lights from.
    pub table_mhz: Vec<u32>,
    /// The beacon board's status at the last reading.
    beacon_seen: Option<BeaconSeen>,
    /// The sensor board's report counter and clock as last seen (from its status at the
    /// last restore, then from each spot report); `None` until read.
    sensor_seen: Option<SensorSeen>,
}

impl<'a> Engine<'a> {
    /// An engine for `plan` with the boards at these paths (not yet connected).
    pub fn new(plan: &'a Plan, beacon_path: &str, sensor_path: &str) -> Self {
        let config = LinkConfig {
            timeout: Duration::from_millis(plan.request_timeout_ms),
            retries: plan.retries,
        };
        Engine {
            plan,
            beacon: Conn {
                name: "beacon",
                path: beacon_path.into(),
                config,
                link: None,
            },
            sensor: Conn {
                name: "sensor",
                path: sensor_path.into(),
                config,
                link: None,
            },
            sensitivity: None,
            last_heartbeat: Instant::now(),
            skip_settle: false,
            stats: Stats::default(),
            checked: Vec::new(),
            run_start: now(),
            clock: BoardClock::default(),
            table_mhz: Vec::new(),
            beacon_seen: None,
            sensor_seen: None,
        }
    }

    /// Connect both boards and check who answers (errors name the board and the answer).
    pub fn connect(&mut self) -> Result<(Identity, Identity)> {
        let b = self
            .beacon
            .connect()
            .and_then(|id| self.check_table(false).map(|()| id))
            .and_then(|id| self.check_beacon(false).map(|()| id))
            .map_err(|f| fault_error(&self.beacon.path, f))?;
        let s = self
            .sensor
            .connect()
            .map_err(|f| fault_error(&self.sensor.path, f))?;
        self.restore().map_err(|f| {
            let path = match &f {
                Fault::Lost("beacon", _) => &self.beacon.path,
                _ => &self.sensor.path,
            };
            fault_error(path, f)
        })?;
        Ok((b, s))
    }

    /// Read the beacon board's status and compare it with the last reading
    /// ([`Engine::beacon_seen`]; none: this reading is the first, after a connection). The
    /// board answers heartbeats whatever its LEDs do, so a reset (a watchdog, a brown-out)
    /// or a dead-man trip would otherwise darken a point unnoticed, and the point would be
    /// committed as "partial" or "no signal" and never measured again: both are a
    /// [`Fault::Lost`] (reconnect, check the table, measure the point again). `lit`: the
    /// point's LED must still be lit. A dead-man timeout too short for the plan's heartbeat
    /// is [`Fault::Fatal`]: every point would trip it.
    fn check_beacon(&mut self, lit: bool) -> Result<(), Fault> {
        let s = match self
            .beacon
            .link()?
            .call(BeaconRequest::Status)
            .map_err(|e| link_fault("beacon", e))?
        {
            Some(BeaconResponse::Status(s)) => s,
            other => {
                return Err(Fault::Lost(
                    "beacon",
                    format!("unexpected reply to Status: {other:?}"),
                ))
            }
        };
        // Twice the heartbeat (the plan's own rule against the default timer), and room for
        // a heartbeat plus one request to the sensor board with its retries, which may come
        // between two heartbeats, and 0.5 s.
        let heartbeat = self.plan.heartbeat_ms;
        let blocked = self.plan.request_timeout_ms * (u64::from(self.plan.retries) + 1);
        let needed = (2 * heartbeat).max(heartbeat + blocked + 500);
        if u64::from(s.limits.deadman_ms) < needed {
            let port = &self.beacon.path;
            return Err(Fault::Fatal(Error::Board(format!(
                "beacon board on {port}: its dead-man timeout is {} ms, shorter than the {needed} ms \
                 the plan needs (twice its heartbeat, {heartbeat} ms, or a heartbeat and a request \
                 to the sensor board with its retries, {blocked} ms, and 0.5 s): it would turn the \
                 LED off mid-point. Set it back with `cta beacon --port {port} limits --deadman-ms \
                 {DEADMAN_DEFAULT_MS}` (or lower [timing] heartbeat_ms), then resume",
                s.limits.deadman_ms
            ))));
        }
        if usize::from(s.limits.max_lit) < self.plan.group {
            let port = &self.beacon.path;
            return Err(Fault::Fatal(Error::Board(format!(
                "beacon board on {port}: it lights at most {} LEDs at once (its cap), and the \
                 plan's `group` lights {}: raise the cap with `cta beacon --port {port} limits \
                 --max-lit {}`, or make the group smaller",
                s.limits.max_lit, self.plan.group, self.plan.group
            ))));
        }
        let now = Instant::now();
        let prev = self.beacon_seen.replace(BeaconSeen {
            at: now,
            uptime_ms: s.uptime_ms,
            deadman_trips: s.deadman_trips,
        });
        if let Some(prev) = prev {
            // The board's uptime must have grown with the host's clock (1 s and 1 % slack),
            // and can never go back without a reset.
            let elapsed = now.duration_since(prev.at).as_millis() as u64;
            let least = (prev.uptime_ms + elapsed).saturating_sub(1000 + elapsed / 100);
            if s.uptime_ms < least || s.uptime_ms < prev.uptime_ms {
                return Err(Fault::Lost(
                    "beacon",
                    format!(
                        "the board was reset behind the sweep (up {:.1} s, where {:.1} s had \
                         passed since it was up {:.1} s; last reset: {}): its LEDs went dark",
                        s.uptime_ms as f64 / 1e3,
                        elapsed as f64 / 1e3,
                        prev.uptime_ms as f64 / 1e3,
                        s.reset_cause
                    ),
                ));
            }
            if s.deadman_trips != prev.deadman_trips {
                return Err(Fault::Lost(
                    "beacon",
                    format!(
                        "its dead-man switch turned the LEDs off (trips {} -> {}): no frame \
                         reached it for {} ms",
                        prev.deadman_trips, s.deadman_trips, s.limits.deadman_ms
                    ),
                ));
            }
        }
        if lit && s.lit == 0 {
            return Err(Fault::Lost(
                "beacon",
                format!(
                    "the point's LED is off on the board (nothing lit: reset, or switched off \
                     by another program; the board is up {:.1} s, last reset: {})",
                    s.uptime_ms as f64 / 1e3,
                    s.reset_cause
                ),
            ));
        }
        Ok(())
    }

    /// Read the beacon board's frequency table and check that every entry the plan lights
    /// holds the frequency the plan records for it (a point lights table entry
    /// [`Point::channel`] and records [`Point::frequency_hz`]): a table changed by hand
    /// (`cta beacon table --set ...`) would otherwise have the data mislabel every sample.
    /// A mismatch is [`Fault::Fatal`]: the run does not start, or stops (resumable) when found
    /// at a reconnection (`reconnected`). On success the table is kept in
    /// [`Engine::table_mhz`].
    fn check_table(&mut self, reconnected: bool) -> Result<(), Fault> {
        let table = match self
            .beacon
            .link()?
            .call(BeaconRequest::GetTable)
            .map_err(|e| link_fault("beacon", e))?
        {
            Some(BeaconResponse::Table(t)) => t.to_vec(),
            other => {
                return Err(Fault::Lost(
                    "beacon",
                    format!("unexpected reply to GetTable: {other:?}"),
                ))
            }
        };
        let wrong = table_mismatches(self.plan, &table);
        if !wrong.is_empty() {
            let port = &self.beacon.path;
            return Err(Fault::Fatal(Error::Board(format!(
                "beacon board on {port}{}: its frequency table does not hold the frequencies the \
                 plan records (the NorthStar table): {}; lit from it, the data would \
                 name the wrong frequency. Restore the NorthStar table with `cta beacon --port \
                 {port} table --default` (all LEDs go off), then {}",
                if reconnected { " (reconnected)" } else { "" },
                wrong.join("; "),
                if reconnected {
                    "resume the run"
                } else {
                    "run the sweep again"
                }
            ))));
        }
        self.table_mhz = table;
        Ok(())
    }

    /// Put both boards in the state a point starts from: LEDs off, sensor idle at the
    /// plan's rate.
    fn restore(&mut self) -> Result<(), Fault> {
        let rate = self.plan.rate_hz;
        self.beacon
            .link()?
            .call(BeaconRequest::AllOff)
            .map_err(|e| link_fault("beacon", e))?;
        // A new reading to compare the next points with: whatever happened to the board
        // during a pause (a dead-man trip while the sensor was away) is behind us.
        self.beacon_seen = None;
        self.check_beacon(false)?;
        let s = self.sensor.link()?;
        s.call(SensorRequest::SetMode(Mode::Idle))
            .map_err(|e| link_fault("sensor", e))?;
        s.call(SensorRequest::SetRate(rate))
            .map_err(|e| link_fault("sensor", e))?;
        self.sensitivity = None;
        // Whatever happened to the sensor board before (a reset during the pause) is put
        // right: its counters from now on tell a reset after this restore.
        let s = self.sensor_status()?;
        self.sensor_seen = Some(SensorSeen {
            seq: s.reports,
            t_us: s.uptime_ms * 1000,
        });
        // The board's clock tied to the host's (to the status's round trip, milliseconds): the
        // time of each sample from the report's own clock, across resets and sessions.
        self.clock = BoardClock {
            board_us: s.uptime_ms * 1000,
            epoch_s: now(),
        };
        Ok(())
    }

    fn sensor_status(&mut self) -> Result<SensorStatus, Fault> {
        match self
            .sensor
            .link()?
            .call(SensorRequest::Status)
            .map_err(|e| link_fault("sensor", e))?
        {
            Some(SensorResponse::Status(s)) => Ok(s),
            other => Err(Fault::Lost(
                "sensor",
                format!("unexpected reply to Status: {other:?}"),
            )),
        }
    }

    /// The fault of a sensor board found reset behind the sweep at point `p` (`how`: what
    /// showed it), with the cause and the settings its status gives (they are restored and
    /// the point measured again, as after any lost board).
    fn sensor_reset(&mut self, p: &Point, how: String) -> Fault {
        let what = match self.sensor_status() {
            Ok(s) => format!(
                "up {:.1} s, last reset: {}): it is at sensitivity {}, {} Hz, the point's are \
                 {}, {} Hz",
                s.uptime_ms as f64 / 1e3,
                s.reset_cause,
                s.sensitivity,
                s.rate_hz,
                p.sensitivity,
                self.plan.rate_hz
            ),
            Err(_) => "its status could not be read)".into(),
        };
        Fault::Lost(
            "sensor",
            format!("the board was reset behind the sweep ({how}; {what}"),
        )
    }

    /// Measure points `from..` of the plan, committing each to `store`.
    pub fn run(
        &mut self,
        store: &mut RunDir,
        operator: &mut dyn Operator,
        from: usize,
        watch: &dyn Watch,
    ) -> Result<Ending> {
        let plan = self.plan;
        let mut place: Option<(usize, usize)> = None; // (sep_idx, quadrant) in place
        let mut entry: Option<SeparationEntry> = None;
        let mut power: Option<u8> = None;
        // Resume: the last recorded plate position, to confirm (also when a recovery cut it
        // from the journal: the plate is where it was last recorded, and a point at another
        // separation asks for it to be moved).
        let mut previous_entry = store.plate.clone();
        watch.start(plan, from);
        // An operator's answer, or `None` when the run was interrupted while waiting for it
        // (then nothing is recorded for that question).
        fn answered<T>(r: Result<T>) -> Result<Option<T>> {
            match r {
                Ok(v) => Ok(Some(v)),
                Err(_) if INTERRUPTED.load(Ordering::SeqCst) => Ok(None),
                Err(e) => Err(e),
            }
        }
        for i in from..plan.len() {
            if INTERRUPTED.load(Ordering::SeqCst) {
                self.quiet_off();
                return Ok(Ending::Interrupted);
            }
            let p = plan.point(i);
            if place != Some((p.sep_idx, p.quadrant)) {
                let prev = previous_entry.take().filter(|e| e.sep_idx == p.sep_idx);
                let moved = place.map(|(s, _)| s) != Some(p.sep_idx);
                if moved || entry.is_none() {
                    let Some(e) = answered(operator.separation(&p, prev.as_ref()))? else {
                        self.quiet_off();
                        return Ok(Ending::Interrupted);
                    };
                    store.log(Event::Separation(e.clone()))?;
                    entry = Some(e);
                    watch.separation(plan, &p);
                }
                if plan.layout.quadrants() > 1 {
                    let Some(source) = answered(operator.quadrant(p.quadrant))? else {
                        self.quiet_off();
                        return Ok(Ending::Interrupted);
                    };
                    store.log(Event::Quadrant {
                        quadrant: p.quadrant,
                        source,
                    })?;
                }
                place = Some((p.sep_idx, p.quadrant));
            }
            if power != Some(p.power) {
                let Some(source) = answered(operator.power(p.power))? else {
                    self.quiet_off();
                    return Ok(Ending::Interrupted);
                };
                store.log(Event::Power {
                    level: p.power,
                    source,
                })?;
                power = Some(p.power);
            }
            let e = entry.as_ref().expect("set above");
            match self.point_with_retries(store, &p, watch)? {
                Some((m, attempts)) => {
                    let (rows, comments) = rows_of(plan, &p, e.mean, &m);
                    if plan.in_check_block(&p) {
                        self.checked.extend(crate::crosstalk::point_sums(&Dataset {
                            path: Default::default(),
                            samples: rows.clone(),
                        }));
                    }
                    if !m.strays.is_empty() {
                        store.log(Event::Fault {
                            at: now(),
                            point: i,
                            board: "sensor".into(),
                            what: strays_text(&m),
                            action: "left out of the data".into(),
                        })?;
                    }
                    store
                        .commit_point(i, m.status, &rows, &comments, m.reports, m.lost, attempts)?;
                    match m.status {
                        PointStatus::Ok => self.stats.ok += 1,
                        PointStatus::NoSignal => self.stats.no_signal += 1,
                        PointStatus::Partial => self.stats.partial += 1,
                    }
                    self.stats.samples += rows.len() as u64;
                    for got in m.samples.iter().map(Vec::len) {
                        match got {
                            0 => self.stats.beacons.1 += 1,
                            n if n >= plan.samples as usize => self.stats.beacons.0 += 1,
                            _ => self.stats.beacons.2 += 1,
                        }
                    }
                    self.stats.lost_reports += m.lost as u64;
                    watch.point_done(plan, i, p.separation);
                }
                None if INTERRUPTED.load(Ordering::SeqCst) => {
                    self.quiet_off();
                    return Ok(Ending::Interrupted);
                }
                None => {
                    // The last fault that names a board (while reconnecting, the links are
                    // down and the faults say so, not which board went away).
                    let faults = || {
                        store.events.iter().rev().filter_map(|e| match e {
                            Event::Fault { board, what, .. } => Some((board, what)),
                            _ => None,
                        })
                    };
                    let what = faults()
                        .find(|(b, _)| b.as_str() != "host")
                        .or_else(|| faults().next())
                        .map(|(b, w)| format!("{b}: {w}"))
                        .unwrap_or_default();
                    return Ok(Ending::GaveUp(what));
                }
            }
        }
        self.quiet_off();
        Ok(Ending::Complete)
    }

    /// Stop the run on a fatal fault at point `p`: logged and journalled (`board` names who),
    /// LEDs off and sensor idle. Returns the error to end the session with (or the journal's
    /// own write error).
    fn stop(
        &mut self,
        store: &mut RunDir,
        watch: &dyn Watch,
        p: &Point,
        board: &str,
        e: Error,
    ) -> Result<Error> {
        watch.log(&format!("fault at point {}: {e:#}; stop", p.index));
        store.log(Event::Fault {
            at: now(),
            point: p.index,
            board: board.into(),
            what: format!("{e:#}"),
            action: "stop".into(),
        })?;
        self.quiet_off();
        Ok(e)
    }

    /// Best effort: LEDs off, sensor idle (at the end of a session).
    fn quiet_off(&mut self) {
        if let Ok(l) = self.beacon.link() {
            let _ = l.call(BeaconRequest::AllOff);
        }
        if let Ok(l) = self.sensor.link() {
            let _ = l.call(SensorRequest::SetMode(Mode::Idle));
        }
    }

    /// Measure one point, retrying through faults. `None`: interrupted or gave up.
    fn point_with_retries(
        &mut self,
        store: &mut RunDir,
        p: &Point,
        watch: &dyn Watch,
    ) -> Result<Option<(Measured, u32)>> {
        let mut attempts = 0u32;
        let mut first_failure: Option<Instant> = None;
        let mut backoff = Duration::from_millis(100);
        // Why the last reconnection failed (the board and its error, with the port).
        let mut reconnect_error: Option<(&'static str, String)> = None;
        loop {
            if INTERRUPTED.load(Ordering::SeqCst) {
                return Ok(None);
            }
            attempts += 1;
            let r = match (self.beacon.link.is_some(), self.sensor.link.is_some()) {
                (true, true) => self.measure(p),
                _ if reconnect_error.is_some() => {
                    let (b, w) = reconnect_error.take().expect("checked");
                    Err(Fault::Lost(b, format!("cannot reconnect: {w}")))
                }
                (false, true) => Err(Fault::Lost("beacon", "not connected (reconnecting)".into())),
                (true, false) => Err(Fault::Lost("sensor", "not connected (reconnecting)".into())),
                (false, false) => Err(Fault::Lost(
                    "host",
                    "no board connected (reconnecting)".into(),
                )),
            };
            let fault = match r {
                Ok(m) => {
                    watch.message("");
                    return Ok(Some((m, attempts)));
                }
                Err(Fault::Interrupted) => return Ok(None),
                Err(Fault::Fatal(e)) => return Err(self.stop(store, watch, p, "host", e)?),
                Err(f) => f,
            };
            let (board, what) = match &fault {
                Fault::Lost(b, w) => (*b, w.clone()),
                Fault::Stalled(w) => ("sensor", w.clone()),
                _ => unreachable!("handled above"),
            };
            let since = *first_failure.get_or_insert_with(Instant::now);
            if since.elapsed().as_secs_f64() > self.plan.give_up_s {
                let action = format!("stop: no recovery within {} s", self.plan.give_up_s);
                watch.log(&format!(
                    "fault at point {}: {board}: {what}; {action}",
                    p.index
                ));
                store.log(Event::Fault {
                    at: now(),
                    point: p.index,
                    board: board.into(),
                    what: what.clone(),
                    action,
                })?;
                return Ok(None);
            }
            self.stats.faults += 1;
            self.stats.retries += 1;
            let action = format!(
                "pause {:.1} s, reconnect, retry point",
                backoff.as_secs_f64()
            );
            watch.log(&format!(
                "fault at point {}: {board}: {what}; {action}",
                p.index
            ));
            store.log(Event::Fault {
                at: now(),
                point: p.index,
                board: board.into(),
                what: what.clone(),
                action,
            })?;
            watch.message(&format!(
                "paused: {board}: {what}; retry in {:.1} s",
                backoff.as_secs_f64()
            ));
            if !sleep_interruptible(backoff) {
                return Ok(None);
            }
            backoff = (backoff * 2).min(Duration::from_secs_f64(self.plan.backoff_max_s));
            // Reconnect what was lost (or both when unsure) and restore the state.
            let reconnect = |c: &mut dyn FnMut() -> Result<Identity, Fault>| c();
            let mut ok = true;
            // Which boards were reopened (for the log line).
            let mut reopened = (false, false);
            if matches!(fault, Fault::Lost(b, _) if b != "sensor") || self.beacon.link.is_none() {
                reopened.0 = true;
                // A beacon board that comes back must still hold the plan's frequencies (it
                // may have been reset, or its table changed while it was away).
                self.beacon_seen = None;
                match self
                    .beacon
                    .connect()
                    .and_then(|_| self.check_table(true))
                    .and_then(|()| self.check_beacon(false))
                {
                    Ok(()) => {}
                    Err(Fault::Fatal(e)) => return Err(self.stop(store, watch, p, "beacon", e)?),
                    Err(f) => {
                        ok = false;
                        reconnect_error = Some(("beacon", at_port(&self.beacon.path, f)));
                    }
                }
            }
            if ok
                && (matches!(fault, Fault::Lost(b, _) if b != "beacon")
                    || self.sensor.link.is_none())
            {
                reopened.1 = true;
                match reconnect(&mut || self.sensor.connect()) {
                    Ok(_) => {}
                    Err(Fault::Fatal(e)) => return Err(self.stop(store, watch, p, "sensor", e)?),
                    Err(f) => {
                        ok = false;
                        reconnect_error = Some(("sensor", at_port(&self.sensor.path, f)));
                    }
                }
            }
            if ok {
                match self.restore() {
                    Ok(()) => {}
                    // A refusal (a dead-man timeout too short, a request the board refuses).
                    Err(Fault::Fatal(e)) => return Err(self.stop(store, watch, p, "host", e)?),
                    Err(f) => {
                        ok = false;
                        let (board, path) = match &f {
                            Fault::Lost("beacon", _) => ("beacon", &self.beacon.path),
                            _ => ("sensor", &self.sensor.path),
                        };
                        reconnect_error = Some((board, at_port(path, f)));
                    }
                }
            }
            if ok && matches!(fault, Fault::Lost(..)) {
                self.stats.reconnects += 1;
                let which = match reopened {
                    (true, true) => "both boards",
                    (true, false) => "beacon board",
                    (false, true) => "sensor board",
                    // A fault that needed no new connection (a stall): the state restored.
                    (false, false) => match board {
                        "beacon" => "beacon board",
                        _ => "sensor board",
                    },
                };
                watch.log(&format!(
                    "reconnected ({which}); measuring point {} again",
                    p.index
                ));
            }
            if !ok {
                // Drop the link of the board that failed (a failed connect has dropped it
                // already; a failed restore has not): the next attempt reconnects it after
                // the backoff. The other board's link is kept: it answered, and reopening it
                // would only disturb a healthy board (a beacon board reopened is re-identified
                // and its table read again). Whatever happened to it during the pause is
                // found by the restore that follows the reconnection (LEDs off, the status
                // read afresh), and a board that stopped answering meanwhile fails that
                // restore and is reconnected in turn.
                match reconnect_error.as_ref().map(|(b, _)| *b) {
                    Some("beacon") => self.beacon.link = None,
                    Some("sensor") => self.sensor.link = None,
                    _ => {
                        self.beacon.link = None;
                        self.sensor.link = None;
                    }
                }
            }
        }
    }

    fn heartbeat(&mut self) -> Result<(), Fault> {
        if self.last_heartbeat.elapsed() >= Duration::from_millis(self.plan.heartbeat_ms) {
            self.beacon
                .link()?
                .heartbeat()
                .map_err(|e| link_fault("beacon", e))?;
            self.last_heartbeat = Instant::now();
        }
        Ok(())
    }

    /// Light the point's beacons, each at its frequency (`on`), or turn them off. One beacon
    /// is set alone (`Set`); a group is lit in one request (`SetMany`), which the board applies
    /// whole or refuses whole (over its cap of lit LEDs, over its modulator's budget).
    fn set_leds(&mut self, p: &Point, on: bool) -> Result<(), Fault> {
        let mode = |l: &Lit| {
            if on {
                LedMode::Modulated(FreqSet::single(l.channel))
            } else {
                LedMode::Off
            }
        };
        let request = match p.lit.as_slice() {
            [l] => BeaconRequest::Set(LedSetting {
                led: l.led,
                mode: mode(l),
            }),
            _ if !on => BeaconRequest::AllOff,
            lit => BeaconRequest::SetMany(
                lit.iter()
                    .map(|l| LedSetting {
                        led: l.led,
                        mode: mode(l),
                    })
                    .collect(),
            ),
        };
        self.beacon
            .link()?
            .call(request)
            .map_err(|e| link_fault("beacon", e))?;
        self.last_heartbeat = Instant::now();
        Ok(())
    }

    fn measure(&mut self, p: &Point) -> Result<Measured, Fault> {
        self.set_leds(p, true)?;
        let changed = self.sensitivity != Some(p.sensitivity);
        if changed {
            self.sensor
                .link()?
                .call(SensorRequest::SetSensitivity(p.sensitivity))
                .map_err(|e| link_fault("sensor", e))?;
            self.sensitivity = Some(p.sensitivity);
        }
        if !self.skip_settle && self.plan.settle_ms > 0 {
            let end = Instant::now() + Duration::from_millis(self.plan.settle_ms);
            while Instant::now() < end {
                self.heartbeat()?;
                if !sleep_interruptible((end - Instant::now()).min(Duration::from_millis(100))) {
                    return Err(Fault::Interrupted);
                }
            }
        }
        self.sensor_mode(Mode::Stream)?;
        let mut m = Measured {
            status: PointStatus::Ok,
            samples: vec![Vec::with_capacity(self.plan.samples as usize); p.lit.len()],
            reports: 0,
            lost: 0,
            strays: Default::default(),
        };
        let wrong_limit = if changed {
            WRONG_SENSITIVITY_AFTER_CHANGE
        } else {
            WRONG_SENSITIVITY_REPORTS
        };
        let collected = self.collect(p, &mut m, wrong_limit);
        // Stop streaming even after a stall (best effort; a lost board is reconnected).
        let stopped = self.sensor_mode(Mode::Idle);
        collected?;
        stopped?;
        // Samples short: was the LED dark (a beacon reset or dead-man trip) rather than out
        // of view? A full point saw its LED's channel throughout.
        if m.status != PointStatus::Ok {
            self.check_beacon(true)?;
        }
        self.set_leds(p, false)?;
        Ok(m)
    }

    /// Send `SetMode(mode)` to the sensor board and wait for its acknowledgement (the link
    /// retries). Spot reports that arrived before the acknowledgement are stale (the previous
    /// LED or mode) and are discarded; those after it are the new stream's first and stay
    /// in the link for [`Self::collect`].
    fn sensor_mode(&mut self, mode: Mode) -> Result<(), Fault> {
        let link = self.sensor.link()?;
        link.call(SensorRequest::SetMode(mode))
            .map_err(|e| link_fault("sensor", e))?;
        link.discard_unsolicited();
        Ok(())
    }

    /// Read spot reports into `m` until the point is done; `wrong_limit` reports in a row at
    /// another sensitivity than the point's are a fault.
    fn collect(&mut self, p: &Point, m: &mut Measured, wrong_limit: u32) -> Result<(), Fault> {
        let plan = self.plan;
        let mut last_seq: Option<u32> = None;
        let mut last_report = Instant::now();
        let timeout = Duration::from_millis(plan.report_timeout_ms);
        // Done when every beacon has its samples or, still without any, counts as without
        // signal; or when the reports allowed are spent.
        let done = |m: &Measured| {
            m.reports >= plan.max_reports
                || m.samples.iter().all(|s| {
                    s.len() >= plan.samples as usize
                        || (s.is_empty() && m.reports >= plan.no_signal_reports)
                })
        };
        // Reports in a row at another sensitivity than the point's, and the last one's.
        let mut wrong_sensitivity = (0u32, 0u8);
        // The board's clock, tied to the host's at the first report since the last restore.
        let (clock, run_start) = (self.clock, self.run_start);
        // Takes a report in; returns the sensitivity it reports when that is not the point's.
        let mut absorb = |r: SpotReport, m: &mut Measured| -> Option<u8> {
            if done(m) {
                return None;
            }
            if let Some(prev) = last_seq {
                m.lost += r.seq.wrapping_sub(prev).wrapping_sub(1).min(1_000_000);
            }
            last_seq = Some(r.seq);
            // Never recorded under the point's sensitivity: a board reset behind the sweep
            // (it starts at 4) or a detector that has not taken the setting yet.
            if r.sensitivity != p.sensitivity {
                return Some(r.sensitivity);
            }
            m.reports += 1;
            let time_s = clock.seconds(r.t_us, run_start);
            for s in &r.spots {
                let once = r.spots.iter().filter(|o| o.id == s.id).count() == 1;
                match p.lit.iter().position(|l| l.channel == s.id) {
                    Some(k) if once => {
                        if m.samples[k].len() < plan.samples as usize {
                            m.samples[k].push((s.x, s.y, s.magnitude, time_s, r.seq));
                        }
                    }
                    _ => *m.strays.entry(s.id).or_default() += 1,
                }
            }
            None
        };
        while !done(m) {
            let next = self
                .sensor
                .link()?
                .next_unsolicited(Duration::from_millis(10))
                .map_err(|e| Fault::Lost("sensor", format!("port lost: {e}")))?;
            if let Some(Response::Board(SensorResponse::Spots(r))) = next {
                // Before anything of it is recorded: is it from a board reset since the last
                // report (or the restore)? Its settings are then the start-up ones, whatever
                // the point's sensitivity.
                if let Some(seen) = self.sensor_seen {
                    if went_back(r.seq, seen.seq) || r.t_us < seen.t_us {
                        let how = format!(
                            "its report counter went from {} to {}, its clock from {:.3} s to \
                             {:.3} s",
                            seen.seq,
                            r.seq,
                            seen.t_us as f64 / 1e6,
                            r.t_us as f64 / 1e6
                        );
                        return Err(self.sensor_reset(p, how));
                    }
                }
                self.sensor_seen = Some(SensorSeen {
                    seq: r.seq.wrapping_add(1),
                    t_us: r.t_us,
                });
                wrong_sensitivity = match absorb(r, m) {
                    Some(s) => (wrong_sensitivity.0 + 1, s),
                    None => (0, 0),
                };
                last_report = Instant::now();
                if wrong_sensitivity.0 >= wrong_limit {
                    return Err(Fault::Lost(
                        "sensor",
                        format!(
                            "the detector reports sensitivity {} in {} reports in a row, the \
                             point's is {} (was the board reset?)",
                            wrong_sensitivity.1, wrong_sensitivity.0, p.sensitivity
                        ),
                    ));
                }
            } else if last_report.elapsed() > timeout {
                // A board reset mid-point comes back idle and sends nothing: its status then
                // shows the counters restarted. Otherwise (or unread: a silent board) the
                // NorthStar stalled.
                if let (Some(seen), Ok(s)) = (self.sensor_seen, self.sensor_status()) {
                    if went_back(s.reports, seen.seq) || s.uptime_ms < seen.t_us / 1000 {
                        let how = format!(
                            "no spot report for {} ms while streaming, and its report counter \
                             went from {} to {}, its clock from {:.3} s to {:.3} s",
                            plan.report_timeout_ms,
                            seen.seq,
                            s.reports,
                            seen.t_us as f64 / 1e6,
                            s.uptime_ms as f64 / 1e3
                        );
                        return Err(self.sensor_reset(p, how));
                    }
                }
                return Err(Fault::Stalled(format!(
                    "no spot report for {} ms while streaming",
                    plan.report_timeout_ms
                )));
            }
            if INTERRUPTED.load(Ordering::SeqCst) {
                return Err(Fault::Interrupted);
            }
            self.heartbeat()?;
        }
        m.status = if m.samples.iter().all(|s| s.len() >= plan.samples as usize) {
            PointStatus::Ok
        } else if m.total() == 0 {
            PointStatus::NoSignal
        } else {
            PointStatus::Partial
        };
        Ok(())
    }
}

/// The data rows of point `p` measured as `m` with the plate at `separation` (as recorded),
/// every beacon's samples in the point's order; and a comment line for each beacon short of
/// its samples (`no signal: ...`, `partial: ...`).
fn rows_of(plan: &Plan, p: &Point, separation: f64, m: &Measured) -> (Vec<Sample>, Vec<String>) {
    let mut rows = Vec::with_capacity(m.total());
    let mut comments = Vec::new();
    for (l, samples) in p.lit.iter().zip(&m.samples) {
        let beacon = l.beacon_id(p.quadrant);
        rows.extend(
            samples
                .iter()
                .enumerate()
                .map(|(k, &(x, y, mag, t, seq))| Sample {
                    separation_in: separation,
                    r: l.position(&plan.layout, p.quadrant, separation),
                    x: x as f64,
                    y: y as f64,
                    beacon: Some(beacon),
                    frequency_hz: Some(l.frequency_hz),
                    power: Some(p.power as f64),
                    sensitivity: Some(p.sensitivity as f64),
                    sample: Some(k as u32),
                    magnitude: Some(mag as f64),
                    group: Some(p.index as u32),
                    time_s: Some(t),
                    report: Some(seq),
                    line: 0,
                }),
        );
        if samples.len() < plan.samples as usize {
            comments.push(format!(
                "{}: point {} separation {separation} beacon {beacon} frequency_hz {} power {} \
                 sensitivity {}: {} of {} samples in {} reports",
                if samples.is_empty() {
                    "no signal"
                } else {
                    "partial"
                },
                p.index,
                l.frequency_hz,
                p.power,
                p.sensitivity,
                samples.len(),
                plan.samples,
                m.reports
            ));
        }
    }
    (rows, comments)
}

/// What the spots left out of a point's data were ([`Measured::strays`]).
fn strays_text(m: &Measured) -> String {
    let ids: Vec<String> = m
        .strays
        .iter()
        .map(|(id, n)| format!("ID {id} in {n}"))
        .collect();
    format!(
        "spots under an ID no LED of the point was lit at, or one ID twice in a report (a \
         reflection, another light source): {} of {} reports",
        ids.join(", "),
        m.reports
    )
}

/// The entries of the beacon board's `table` (millihertz) that the plan lights but that do
/// not hold the frequency the plan records for them, described (`entry 2 is 3090 Hz, the
/// plan records 4050 Hz`); empty when the table serves the plan.
pub fn table_mismatches(plan: &Plan, table: &[u32]) -> Vec<String> {
    let mut wrong = Vec::new();
    for &hz in &plan.frequencies_hz {
        let Some(i) = channel_of(hz) else { continue };
        let said = match table.get(i as usize) {
            Some(&mhz) if (mhz as f64 - hz * 1000.0).abs() < 0.5 => continue,
            Some(&mhz) => format!("is {} Hz", mhz as f64 / 1000.0),
            None => format!("is missing (the table has {} entries)", table.len()),
        };
        wrong.push(format!("entry {i} {said}, the plan records {hz} Hz"));
    }
    wrong
}

/// A fault's words, without its board, naming the port `path` (once).
fn at_port(path: &str, f: Fault) -> String {
    let w = match f {
        Fault::Lost(_, w) | Fault::Stalled(w) => w,
        Fault::Fatal(e) => format!("{e:#}"),
        Fault::Interrupted => "interrupted".into(),
    };
    if w.contains(path) {
        w
    } else {
        format!("{path}: {w}")
    }
}

fn fault_error(path: &str, f: Fault) -> Error {
    match f {
        Fault::Lost(b, w) if w.contains(path) => Error::Board(format!("{b} board: {w}")),
        Fault::Lost(b, w) => Error::Board(format!("{b} board on {path}: {w}")),
        Fault::Stalled(w) => Error::Board(format!("sensor board on {path}: {w}")),
        Fault::Fatal(e) => e,
        Fault::Interrupted => Error::Board("interrupted".into()),
    }
}

/// Sleep up to `d`; `false` if Ctrl-C came meanwhile.
fn sleep_interruptible(d: Duration) -> bool {
    let end = Instant::now() + d;
    while Instant::now() < end {
        if INTERRUPTED.load(Ordering::SeqCst) {
            return false;
        }
        std::thread::sleep((end - Instant::now()).min(Duration::from_millis(50)));
    }
    !INTERRUPTED.load(Ordering::SeqCst)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_counter_went_back_only_when_it_did() {
        assert!(went_back(3, 10));
        assert!(!went_back(10, 10) && !went_back(11, 10));
        // The counter wrapping after 2^32 reports is no reset.
        assert!(!went_back(2, u32::MAX - 1));
        assert!(went_back(0, 1 << 31));
    }
}
