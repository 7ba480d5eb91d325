//! `cta beacon ...`: talk to the beacon board (or the simulated one) by hand.
//!
//! ```text
//! cta beacon sim                          # start the simulated board, prints its pty path
//! cta beacon --port /dev/ttyUSB0 identify
//! cta beacon --port /dev/ttyUSB0 set 45 3        # LED 45 at table entry 3 (3090 Hz)
//! cta beacon --port /dev/ttyUSB0 set 46 0,5      # LED 46 at entries 0 and 5 at once
//! cta beacon --port /dev/ttyUSB0 set-many 0=on 1=2 2=off
//! cta beacon --port /dev/ttyUSB0 status
//! cta beacon --sim status --json          # the same as one JSON object
//! cta beacon --port /dev/ttyUSB0 heartbeat --every-ms 2000   # keep LEDs lit (dead-man)
//! cta beacon --port /dev/ttyUSB0 all-off
//! cta beacon --port /dev/ttyUSB0 limits --deadman-ms 30000   # the cap stays as it is
//! cta beacon --sim set 45 3               # against an in-process simulated board instead
//! cta beacon --sim table                  # (it lives for that one command only)
//! cta beacon --port /dev/ttyUSB0 table --default   # restore the NorthStar table
//! cta beacon pins                         # the pin map
//! ```
//!
//! LED ids are `row * 10 + column`; frequencies are indices into the board's table
//! (`cta beacon --port P table` lists it; default: the 10 NorthStar ID pairs, entry `2k` and
//! `2k + 1` for ID `k`).
//!
//! `--sim` starts the simulated board (the one `cta beacon sim` serves on a pty) inside this
//! process for the one command and stops it when the command ends: what a command sets on it
//! (LED modes, the table, the limits) is gone for the next, and those commands say so. To keep
//! a simulated board across commands, run `cta beacon sim` and give its pty as `--port`.

use std::io::Write;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use cta_core::schedule::{grid_position, NORTHSTAR_TABLE_MHZ};
use cta_core::wire::beacon::{
    Beacon, BeaconRequest, BeaconResponse, BeaconStatus, FreqSet, LedMode, LedSetting, Limits,
    LED_COUNT, MAX_FREQS,
};
use cta_core::wire::{DecoderStats, Identity};
use cta_firmware_beacon::pins::{BEACON_LINES, BEACON_PINS, RESERVED_PINS, SPARE_PIN};
use cta_firmware_beacon::sim::SimBoard;
use serde::Serialize;

use crate::boards::link::{on_board, open_serial, Link, LinkConfig};

/// `cta beacon`: command the beacon board over its serial link.
///
/// The connection options go before the subcommand (`cta beacon --port P status`) or after
/// it (`cta beacon status --port P`); `--sim` talks to a simulated board started in this
/// process for the one command instead of `--port`; `sim`, `pins` and `measure` talk to no
/// board and refuse them.
#[derive(Debug, Args)]
pub struct BeaconArgs {
    /// How to reach the board.
    #[command(flatten)]
    pub conn: BeaconConn,
    /// What to do.
    #[command(subcommand)]
    pub command: BeaconCommand,
}

/// Reply timeout per attempt when `--timeout-ms` is not given, ms.
pub const DEFAULT_TIMEOUT_MS: u64 = 500;
/// Resends after a timeout when `--retries` is not given.
pub const DEFAULT_RETRIES: u32 = 2;

/// The connection options of the subcommands that talk to the board.
#[derive(Debug, Clone, Default, Args)]
pub struct BeaconConn {
    /// Serial port of the board (e.g. /dev/ttyUSB0, or the pty printed by `cta beacon sim`).
    #[arg(long, value_name = "PATH", conflicts_with = "sim")]
    pub port: Option<String>,
    /// Talk to a simulated board started in this process (instead of --port); it lives for
    /// this command only.
    #[arg(long)]
    pub sim: bool,
    /// Reply timeout per attempt, ms (1 or more) [default: 500].
    #[arg(long, value_name = "MS", value_parser = clap::value_parser!(u64).range(1..))]
    pub timeout_ms: Option<u64>,
    /// Resends after a timeout [default: 2].
    #[arg(long, value_name = "N")]
    pub retries: Option<u32>,
}

impl BeaconConn {
    /// The options given, as they would be written (for the error of a subcommand that
    /// takes none).
    fn given(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        if self.port.is_some() {
            v.push("--port");
        }
        if self.sim {
            v.push("--sim");
        }
        if self.timeout_ms.is_some() {
            v.push("--timeout-ms");
        }
        if self.retries.is_some() {
            v.push("--retries");
        }
        v
    }

    /// These options (given before the subcommand) with those given after it; an option
    /// given in both places, or `--sim` with `--port`, is refused.
    fn merge(&self, after: &BeaconConn) -> Result<BeaconConn> {
        let conn = BeaconConn {
            port: one_of("--port", &self.port, &after.port)?,
            sim: self.sim || after.sim,
            timeout_ms: one_of("--timeout-ms", &self.timeout_ms, &after.timeout_ms)?,
            retries: one_of("--retries", &self.retries, &after.retries)?,
        };
        if conn.sim && conn.port.is_some() {
            bail!("--sim and --port exclude each other: use the simulated board or the one on the port");
        }
        Ok(conn)
    }
}

/// The value of an option that may stand before or after the subcommand, not both.
pub(crate) fn one_of<T: Clone>(
    name: &str,
    before: &Option<T>,
    after: &Option<T>,
) -> Result<Option<T>> {
    match (before, after) {
        (Some(_), Some(_)) => {
            bail!("{name} is given both before and after the subcommand: give it once")
        }
        (Some(v), None) | (None, Some(v)) => Ok(Some(v.clone())),
        (None, None) => Ok(None),
    }
}

/// `cta beacon` subcommands.
#[derive(Debug, Subcommand)]
pub enum BeaconCommand {
    /// Which board answers, its firmware and protocol version.
    Identify {
        #[command(flatten)]
        conn: BeaconConn,
    },
    /// Lit LEDs, limits, uptime, link counters.
    Status {
        /// Print one JSON object instead of text: every field the text prints, the last
        /// reset in its words (`power-on`, `watchdog`, ...), times in ms.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        conn: BeaconConn,
    },
    /// Set one LED: `off`, `on`, or table indices (`3`, or `0,5` for several at once).
    Set {
        /// LED id, row * 10 + column (0-99).
        #[arg(value_parser = clap::value_parser!(u8).range(0..=LED_COUNT as i64 - 1))]
        led: u8,
        /// `off`, `on` or comma-separated table indices.
        mode: String,
        #[command(flatten)]
        conn: BeaconConn,
    },
    /// Set several LEDs atomically: `ID=MODE ...` (e.g. `12=3 13=on 14=off`; ids 0-99).
    SetMany {
        /// `ID=MODE` pairs.
        #[arg(required = true)]
        settings: Vec<String>,
        #[command(flatten)]
        conn: BeaconConn,
    },
    /// Every LED off.
    AllOff {
        #[command(flatten)]
        conn: BeaconConn,
    },
    /// Show the frequency table, or replace it (`--set 3040,2010,...` in Hz, or `--default`
    /// for the NorthStar table; all LEDs go off).
    Table {
        /// New table, comma-separated frequencies in Hz.
        #[arg(long, value_delimiter = ',', conflicts_with = "default")]
        set: Option<Vec<f64>>,
        /// Restore the default table: the 20 NorthStar frequencies (3040, 2010, 4050, 3090,
        /// 4170, ... Hz; entries 2k and 2k + 1 for ID k), the table `cta sweep` needs.
        #[arg(long)]
        default: bool,
        #[command(flatten)]
        conn: BeaconConn,
    },
    /// The mode of every LED.
    Leds {
        #[command(flatten)]
        conn: BeaconConn,
    },
    /// Change the safety limits: the LED cap, the dead-man timeout or both (the one not
    /// given keeps the board's current value).
    #[command(group(clap::ArgGroup::new("limit").required(true).multiple(true).args(["max_lit", "deadman_ms"])))]
    Limits {
        /// Most LEDs lit at once (1..=100).
        #[arg(long)]
        max_lit: Option<u8>,
        /// Dead-man timeout, ms (all LEDs off after this long without a valid frame;
        /// 100..=3600000).
        #[arg(long)]
        deadman_ms: Option<u32>,
        #[command(flatten)]
        conn: BeaconConn,
    },
    /// Send heartbeats (once, or every `--every-ms` until Ctrl-C / `--count`).
    Heartbeat {
        /// Interval between heartbeats, ms (0: send one).
        #[arg(long, default_value_t = 0)]
        every_ms: u64,
        /// Stop after this many heartbeats (0: never, with --every-ms).
        #[arg(long, default_value_t = 0)]
        count: u64,
        #[command(flatten)]
        conn: BeaconConn,
    },
    /// Run the simulated beacon board on a pseudo-terminal and print its path.
    Sim {
        /// Stop after this many seconds (default: run until Ctrl-C).
        #[arg(long)]
        seconds: Option<f64>,
    },
    /// Print the pin map: LED id, grid cell, position (in) and GPIO.
    Pins,
    /// Measure the modulation on the simulated tick stream (no board needed): all 100 LEDs
    /// modulated (LED i at table entry i mod 20), mean frequency error and edge jitter per
    /// LED against the NorthStar table.
    Measure {
        /// Simulated duration, s.
        #[arg(long, default_value_t = 2.0)]
        seconds: f64,
    },
}

/// A board's frame-decoder counters in the JSON of `cta beacon status` and `cta sensor
/// status`: good frames, the bad ones in all, then by kind, as the text's line has them.
#[derive(Debug, Serialize)]
pub(crate) struct FrameCounts {
    ok: u32,
    bad: u32,
    oversized: u32,
    encoding: u32,
    truncated: u32,
    crc: u32,
    malformed: u32,
    version: u32,
}

impl From<&DecoderStats> for FrameCounts {
    fn from(d: &DecoderStats) -> Self {
        FrameCounts {
            ok: d.ok,
            bad: d.bad(),
            oversized: d.oversized,
            encoding: d.encoding,
            truncated: d.truncated,
            crc: d.crc,
            malformed: d.malformed,
            version: d.version,
        }
    }
}

/// `cta beacon status --json`: every field of the text, under the names of the board's
/// status reply ([`BeaconStatus`]), the reset cause in the text's words.
#[derive(Debug, Serialize)]
struct StatusJson {
    uptime_ms: u64,
    reset_cause: &'static str,
    lit: u8,
    limits: Limits,
    since_host_ms: u32,
    deadman_trips: u32,
    decoder: FrameCounts,
    refused: u32,
    uart_errors: u32,
    tick_hz: u32,
    table_len: u8,
}

impl From<&BeaconStatus> for StatusJson {
    fn from(s: &BeaconStatus) -> Self {
        StatusJson {
            uptime_ms: s.uptime_ms,
            reset_cause: s.reset_cause.name(),
            lit: s.lit,
            limits: s.limits,
            since_host_ms: s.since_host_ms,
            deadman_trips: s.deadman_trips,
            decoder: FrameCounts::from(&s.decoder),
            refused: s.refused,
            uart_errors: s.uart_errors,
            tick_hz: s.tick_hz,
            table_len: s.table_len,
        }
    }
}

/// Parse an LED mode: `off`, `on`, or comma-separated table indices.
pub fn parse_mode(s: &str) -> Result<LedMode> {
    match s.trim() {
        "off" => return Ok(LedMode::Off),
        "on" => return Ok(LedMode::On),
        _ => {}
    }
    let mut set = 0u32;
    for part in s.split(',') {
        let i: u8 = part.trim().parse().with_context(|| {
            format!("mode {s:?}: expected `off`, `on` or table indices like `3` or `0,5`")
        })?;
        if i as usize >= MAX_FREQS {
            bail!("mode {s:?}: table index {i} is beyond the largest table ({MAX_FREQS} entries)");
        }
        set |= 1 << i;
    }
    Ok(LedMode::Modulated(FreqSet(set)))
}

/// Parse `ID=MODE`.
pub fn parse_setting(s: &str) -> Result<LedSetting> {
    let (id, mode) = s
        .split_once('=')
        .with_context(|| format!("setting {s:?}: expected ID=MODE, e.g. 12=3"))?;
    let led = id
        .trim()
        .parse()
        .with_context(|| format!("setting {s:?}: LED id {id:?} is not a number"))?;
    Ok(LedSetting {
        led,
        mode: parse_mode(mode)?,
    })
}

fn mode_text(m: LedMode) -> String {
    match m {
        LedMode::Off => "off".into(),
        LedMode::On => "on".into(),
        LedMode::Modulated(set) => set
            .indices()
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(","),
    }
}

impl BeaconCommand {
    /// The connection options given after the subcommand; `None` for the subcommands that
    /// talk to no board.
    fn conn(&self) -> Option<&BeaconConn> {
        match self {
            BeaconCommand::Identify { conn }
            | BeaconCommand::Status { conn, .. }
            | BeaconCommand::Set { conn, .. }
            | BeaconCommand::SetMany { conn, .. }
            | BeaconCommand::AllOff { conn }
            | BeaconCommand::Table { conn, .. }
            | BeaconCommand::Leds { conn }
            | BeaconCommand::Limits { conn, .. }
            | BeaconCommand::Heartbeat { conn, .. } => Some(conn),
            BeaconCommand::Sim { .. } | BeaconCommand::Pins | BeaconCommand::Measure { .. } => None,
        }
    }

    /// The name on the command line of a subcommand that talks to no board.
    fn name(&self) -> &'static str {
        match self {
            BeaconCommand::Sim { .. } => "sim",
            BeaconCommand::Pins => "pins",
            BeaconCommand::Measure { .. } => "measure",
            _ => "",
        }
    }
}

/// Run `cta beacon`, printing to stdout.
pub fn run(args: &BeaconArgs) -> Result<()> {
    run_to(args, &mut std::io::stdout())
}

/// Run `cta beacon`, writing what it prints to `out`.
pub fn run_to(args: &BeaconArgs, out: &mut dyn Write) -> Result<()> {
    let Some(after) = args.command.conn() else {
        let given = args.conn.given();
        if !given.is_empty() {
            bail!(
                "{} {} nothing for `cta beacon {}`: it talks to no board",
                given.join(", "),
                if given.len() == 1 { "means" } else { "mean" },
                args.command.name()
            );
        }
        return match &args.command {
            BeaconCommand::Sim { seconds } => run_sim(*seconds, out),
            BeaconCommand::Pins => print_pins(out),
            BeaconCommand::Measure { seconds } => measure(*seconds, out),
            _ => unreachable!("every board command has connection options"),
        };
    };
    let conn = args.conn.merge(after)?;
    // In-process simulated board when --sim (kept alive for the whole command).
    let sim = if conn.sim {
        Some(SimBoard::spawn().context("starting the simulated beacon board")?)
    } else {
        None
    };
    let path = match (&sim, &conn.port) {
        (Some(s), _) => s.path(),
        (None, Some(p)) => p.as_str(),
        (None, None) => bail!(
            "--port PATH is required (the board's serial port, or the pty of `cta beacon sim`), or use --sim"
        ),
    };
    let port = open_serial(path)?;
    let mut link = Link::<Beacon, _>::new(
        port,
        LinkConfig {
            timeout: Duration::from_millis(conn.timeout_ms.unwrap_or(DEFAULT_TIMEOUT_MS)),
            retries: conn.retries.unwrap_or(DEFAULT_RETRIES),
        },
    );
    let id = link
        .check_board()
        .with_context(|| format!("identifying the board on {path}"))?;
    board_command(&args.command, &conn, &id, &mut link, out)
        .map_err(|e| on_board::<Beacon>(e, path))
}

/// What [`run`] does once the board on the port is identified as a beacon board. Errors
/// of the link are named by the board and the port there ([`on_board`]).
fn board_command<S: std::io::Read + std::io::Write>(
    command: &BeaconCommand,
    conn: &BeaconConn,
    id: &Identity,
    link: &mut Link<Beacon, S>,
    out: &mut dyn Write,
) -> Result<()> {
    match command {
        BeaconCommand::Identify { .. } => writeln!(
            out,
            "{} board, firmware {}, protocol {}{}, max frame {} bytes",
            id.board,
            id.firmware,
            id.protocol,
            if id.simulated { " (simulated)" } else { "" },
            id.max_frame
        )?,
        BeaconCommand::Status { json, .. } => match link.call(BeaconRequest::Status)? {
            Some(BeaconResponse::Status(s)) if *json => {
                writeln!(
                    out,
                    "{}",
                    serde_json::to_string_pretty(&StatusJson::from(&s))?
                )?;
            }
            Some(BeaconResponse::Status(s)) => {
                writeln!(out, "uptime          {:.1} s", s.uptime_ms as f64 / 1000.0)?;
                writeln!(out, "last reset      {}", s.reset_cause)?;
                writeln!(out, "lit LEDs        {} (cap {})", s.lit, s.limits.max_lit)?;
                writeln!(
                    out,
                    "dead-man        {} ms, host silent for {} ms, tripped {} time(s)",
                    s.limits.deadman_ms, s.since_host_ms, s.deadman_trips
                )?;
                writeln!(
                    out,
                    "frames          {} good, {} bad (oversized {}, encoding {}, truncated {}, crc {}, malformed {}, version {})",
                    s.decoder.ok,
                    s.decoder.bad(),
                    s.decoder.oversized,
                    s.decoder.encoding,
                    s.decoder.truncated,
                    s.decoder.crc,
                    s.decoder.malformed,
                    s.decoder.version
                )?;
                writeln!(out, "refused         {}", s.refused)?;
                writeln!(out, "uart errors     {}", s.uart_errors)?;
                writeln!(
                    out,
                    "tick            {} Hz, table of {} frequencies",
                    s.tick_hz, s.table_len
                )?;
            }
            other => bail!("unexpected reply to Status: {other:?}"),
        },
        BeaconCommand::Set { led, mode, .. } => {
            let setting = LedSetting {
                led: *led,
                mode: parse_mode(mode)?,
            };
            link.call(BeaconRequest::Set(setting))?;
            writeln!(
                out,
                "LED {led}: {}{}",
                mode_text(setting.mode),
                sim_note(conn)
            )?;
        }
        BeaconCommand::SetMany { settings, .. } => {
            let mut v = heapless::Vec::new();
            for s in settings {
                v.push(parse_setting(s)?)
                    .map_err(|_| anyhow::anyhow!("more than {LED_COUNT} settings"))?;
            }
            let n = v.len();
            link.call(BeaconRequest::SetMany(v))?;
            writeln!(out, "{n} LED(s) set{}", sim_note(conn))?;
        }
        BeaconCommand::AllOff { .. } => {
            link.call(BeaconRequest::AllOff)?;
            writeln!(out, "all LEDs off{}", sim_note(conn))?;
        }
        BeaconCommand::Table { set, default, .. } => {
            if *default {
                let v = heapless::Vec::from_slice(&NORTHSTAR_TABLE_MHZ)
                    .map_err(|_| anyhow::anyhow!("more than {MAX_FREQS} frequencies"))?;
                link.call(BeaconRequest::SetTable(v))?;
                writeln!(
                    out,
                    "table replaced by the NorthStar table; all LEDs off{}",
                    sim_note(conn)
                )?;
            }
            if let Some(hz) = set {
                let mut v = heapless::Vec::new();
                for &f in hz {
                    if !(f.is_finite() && f > 0.0 && f < 4.0e6) {
                        bail!("frequency {f} Hz is not a positive number of Hz");
                    }
                    v.push((f * 1000.0).round() as u32)
                        .map_err(|_| anyhow::anyhow!("more than {MAX_FREQS} frequencies"))?;
                }
                link.call(BeaconRequest::SetTable(v))?;
                writeln!(out, "table replaced; all LEDs off{}", sim_note(conn))?;
            }
            match link.call(BeaconRequest::GetTable)? {
                Some(BeaconResponse::Table(t)) => {
                    for (i, mhz) in t.iter().enumerate() {
                        // A NorthStar cannot tell two entries of one frequency apart (the
                        // default table's 2 and 19 are both 4050 Hz).
                        let same: Vec<String> = t
                            .iter()
                            .enumerate()
                            .filter(|&(j, m)| j != i && m == mhz)
                            .map(|(j, _)| j.to_string())
                            .collect();
                        let note = if same.is_empty() {
                            String::new()
                        } else {
                            format!(
                                "   (the frequency of entry {}: a NorthStar cannot tell them \
                                 apart; light one of them at a time)",
                                same.join(", ")
                            )
                        };
                        writeln!(out, "{i:2}  {:.3} Hz{note}", *mhz as f64 / 1000.0)?;
                    }
                }
                other => bail!("unexpected reply to GetTable: {other:?}"),
            }
        }
        BeaconCommand::Leds { .. } => match link.call(BeaconRequest::GetLeds)? {
            Some(BeaconResponse::Leds(modes)) => {
                for (i, m) in modes.iter().enumerate() {
                    if m.is_lit() {
                        writeln!(out, "{i:3}  {}", mode_text(*m))?;
                    }
                }
                let lit = modes.iter().filter(|m| m.is_lit()).count();
                writeln!(out, "{lit} lit, {} off", modes.len() - lit)?;
            }
            other => bail!("unexpected reply to GetLeds: {other:?}"),
        },
        BeaconCommand::Limits {
            max_lit,
            deadman_ms,
            ..
        } => {
            // The one not given keeps the board's value.
            let current = match link.call(BeaconRequest::Status)? {
                Some(BeaconResponse::Status(s)) => s.limits,
                other => bail!("unexpected reply to Status: {other:?}"),
            };
            let limits = Limits {
                max_lit: max_lit.unwrap_or(current.max_lit),
                deadman_ms: deadman_ms.unwrap_or(current.deadman_ms),
            };
            link.call(BeaconRequest::SetLimits(limits))?;
            writeln!(
                out,
                "cap {} LEDs, dead-man {} ms{}",
                limits.max_lit,
                limits.deadman_ms,
                sim_note(conn)
            )?;
        }
        BeaconCommand::Heartbeat {
            every_ms, count, ..
        } => {
            let mut sent = 0u64;
            loop {
                link.heartbeat()?;
                sent += 1;
                if *every_ms == 0 || (*count > 0 && sent >= *count) {
                    break;
                }
                std::thread::sleep(Duration::from_millis(*every_ms));
            }
            writeln!(out, "{sent} heartbeat(s) acknowledged")?;
        }
        BeaconCommand::Sim { .. } | BeaconCommand::Pins | BeaconCommand::Measure { .. } => {
            unreachable!("handled above")
        }
    }
    Ok(())
}

/// After a command that changes the board's LED modes, table or limits: with `--sim` the
/// board lives for this one command, so the change is gone when it ends.
fn sim_note(conn: &BeaconConn) -> &'static str {
    if conn.sim {
        " on the simulated board (--sim: it lives for this command only, so the next command \
         starts from its defaults; `cta beacon sim` keeps one running on a pty for --port)"
    } else {
        ""
    }
}

fn run_sim(seconds: Option<f64>, out: &mut dyn Write) -> Result<()> {
    let sim = SimBoard::spawn().context("starting the simulated beacon board")?;
    writeln!(out, "simulated beacon board on {}", sim.path())?;
    writeln!(
        out,
        "try: cta beacon --port {} identify   (Ctrl-C stops the board)",
        sim.path()
    )?;
    out.flush()?;
    let start = std::time::Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(100));
        if let Some(s) = seconds {
            if start.elapsed().as_secs_f64() >= s {
                break;
            }
        }
    }
    sim.stop().context("simulated beacon board")?;
    Ok(())
}

/// Frequency error and jitter of every table frequency on the simulated tick stream.
pub fn measure(seconds: f64, out: &mut dyn Write) -> Result<()> {
    use cta_core::schedule::{measure::run, Modulator, TICK_HZ};
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 600.0) {
        bail!("--seconds {seconds}: expected 0 < seconds <= 600");
    }
    let mut m = Modulator::new(&NORTHSTAR_TABLE_MHZ, &BEACON_LINES)
        .map_err(|e| anyhow::anyhow!("default table rejected: {e:?}"))?;
    let modes: [LedMode; LED_COUNT] =
        std::array::from_fn(|i| LedMode::Modulated(FreqSet::single((i % 20) as u8)));
    m.configure(&modes);
    let ticks = (seconds * TICK_HZ as f64).round() as u32;
    let (stats, load) = run(&mut m, &modes, &NORTHSTAR_TABLE_MHZ, ticks)
        .map_err(|t| anyhow::anyhow!("incremental outputs diverged at tick {t}"))?;
    writeln!(
        out,
        "{} LEDs, {ticks} ticks at {TICK_HZ} Hz ({seconds} s simulated); {:.2} port operations per tick (max {})",
        stats.len(),
        load.mean_writes,
        load.max_writes
    )?;
    writeln!(
        out,
        "index  nominal Hz   worst |error|   worst jitter p-p   worst jitter rms"
    )?;
    let (mut worst_err, mut worst_pp, mut worst_rms) = (0f64, 0f64, 0f64);
    for i in 0..NORTHSTAR_TABLE_MHZ.len() as u8 {
        let of_i: Vec<_> = stats.iter().filter(|s| s.index == i).collect();
        let e = of_i.iter().map(|s| s.rel_error.abs()).fold(0.0, f64::max);
        let pp = of_i.iter().map(|s| s.jitter_pp_us).fold(0.0, f64::max);
        let rms = of_i.iter().map(|s| s.jitter_rms_us).fold(0.0, f64::max);
        writeln!(
            out,
            "{i:5}  {:10.3}   {:11.2e} %   {pp:12.3} us   {rms:12.3} us",
            NORTHSTAR_TABLE_MHZ[i as usize] as f64 / 1000.0,
            e * 100.0
        )?;
        worst_err = worst_err.max(e);
        worst_pp = worst_pp.max(pp);
        worst_rms = worst_rms.max(rms);
    }
    writeln!(
        out,
        "worst: frequency error {:.2e} % (target 0.05 %), jitter {worst_pp:.3} us peak-to-peak, {worst_rms:.3} us rms (target 10 us)",
        worst_err * 100.0
    )?;
    if worst_err > 5e-4 || worst_pp > 10.0 {
        bail!("modulation outside its targets");
    }
    Ok(())
}

fn print_pins(out: &mut dyn Write) -> Result<()> {
    writeln!(out, "id  row col   x(in)  y(in)  GPIO")?;
    for (id, pin) in BEACON_PINS.iter().enumerate() {
        let (row, col, x, y) = grid_position(id as u8);
        writeln!(out, "{id:3} {row:3} {col:3}  {x:6.1} {y:6.1}  {pin}")?;
    }
    writeln!(out, "reserved:")?;
    for (pin, why) in RESERVED_PINS {
        writeln!(out, "  {pin:5} {why}")?;
    }
    writeln!(out, "spare: {SPARE_PIN}")?;
    Ok(())
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
        measure(0.2, &mut std::io::sink()).unwrap();
        assert!(measure(0.0, &mut std::io::sink()).is_err());
    }

    /// `cta beacon ARGS...` as the command line parses it.
    fn parse(args: &[&str]) -> std::result::Result<BeaconArgs, clap::Error> {
        use clap::FromArgMatches as _;
        let m = BeaconArgs::augment_args(clap::Command::new("beacon"))
            .try_get_matches_from(std::iter::once("beacon").chain(args.iter().copied()))?;
        BeaconArgs::from_arg_matches(&m)
    }

    /// What `cta beacon ARGS...` prints, or its error.
    fn beacon(args: &[&str]) -> Result<String> {
        let mut out = Vec::new();
        run_to(&parse(args)?, &mut out)?;
        Ok(String::from_utf8(out)?)
    }

    /// The error of `cta beacon ARGS...`, which must fail.
    fn refused(args: &[&str]) -> String {
        match beacon(args) {
            Ok(out) => panic!("{args:?} succeeded: {out}"),
            Err(e) => format!("{e:#}"),
        }
    }

    const NOTE: &str = " on the simulated board (--sim: it lives for this command only, so the \
                        next command starts from its defaults; `cta beacon sim` keeps one \
                        running on a pty for --port)";

    #[test]
    fn sim_serves_one_command_in_process() {
        let out = beacon(&["--sim", "identify"]).unwrap();
        assert!(
            out.starts_with("beacon board, firmware ") && out.contains(" (simulated), max frame"),
            "{out}"
        );
        // After the subcommand too, with the other connection options.
        let out = beacon(&["status", "--sim", "--timeout-ms", "300", "--retries", "1"]).unwrap();
        assert!(out.contains("lit LEDs        0 (cap 20)"), "{out}");
        // Commands that only read say nothing more.
        assert_eq!(beacon(&["--sim", "leds"]).unwrap(), "0 lit, 100 off\n");
        // Those that change the board say that the change ends with the command.
        for (args, said) in [
            (&["--sim", "set", "45", "3"][..], "LED 45: 3"),
            (&["set-many", "0=2", "9=on", "--sim"][..], "2 LED(s) set"),
            (&["--sim", "all-off"][..], "all LEDs off"),
            (
                &["--sim", "limits", "--max-lit", "40"][..],
                "cap 40 LEDs, dead-man 10000 ms",
            ),
        ] {
            assert_eq!(beacon(args).unwrap(), format!("{said}{NOTE}\n"), "{args:?}");
        }
        // The board served the whole command: the table it lists is the one just set.
        let out = beacon(&["--sim", "table", "--set", "3040,2010"]).unwrap();
        assert_eq!(
            out,
            format!("table replaced; all LEDs off{NOTE}\n 0  3040.000 Hz\n 1  2010.000 Hz\n")
        );
        let out = beacon(&["--sim", "heartbeat", "--every-ms", "10", "--count", "2"]).unwrap();
        assert_eq!(out, "2 heartbeat(s) acknowledged\n");
        // Without --sim (a real board or `cta beacon sim` on --port) there is no note.
        assert_eq!(sim_note(&BeaconConn::default()), "");
    }

    #[test]
    fn sim_and_port_exclude_each_other() {
        let e = parse(&["--sim", "--port", "/dev/null", "identify"]).unwrap_err();
        assert!(
            e.to_string()
                .contains("'--sim' cannot be used with '--port <PATH>'"),
            "{e}"
        );
        let e = parse(&["set", "1", "on", "--port", "/dev/null", "--sim"]).unwrap_err();
        assert!(e.to_string().contains("cannot be used with"), "{e}");
        // Split across the subcommand: refused before any port is opened.
        for args in [
            &["--sim", "identify", "--port", "/dev/null"][..],
            &["--port", "/dev/null", "status", "--sim"][..],
        ] {
            assert_eq!(
                refused(args),
                "--sim and --port exclude each other: use the simulated board or the one on the port"
            );
        }
        assert!(
            refused(&["identify"]).contains("--port PATH is required")
                && refused(&["leds"]).ends_with(", or use --sim"),
        );
    }

    #[test]
    fn sim_only_where_a_board_is_talked_to() {
        for sub in ["pins", "measure", "sim"] {
            assert_eq!(
                refused(&["--sim", sub]),
                format!("--sim means nothing for `cta beacon {sub}`: it talks to no board")
            );
            let e = parse(&[sub, "--sim"]).unwrap_err();
            assert!(e.to_string().contains("unexpected argument '--sim'"), "{e}");
        }
        assert!(refused(&["--sim", "--retries", "1", "pins"])
            .starts_with("--sim, --retries mean nothing for `cta beacon pins`"));
        let mut cmd = BeaconArgs::augment_args(clap::Command::new("beacon"));
        for sub in ["identify", "set", "table", "heartbeat"] {
            let help = cmd
                .find_subcommand_mut(sub)
                .unwrap()
                .render_help()
                .to_string();
            assert!(
                help.contains("--sim") && help.contains("this command only"),
                "{sub}: {help}"
            );
        }
        let help = cmd
            .find_subcommand_mut("pins")
            .unwrap()
            .render_help()
            .to_string();
        assert!(!help.contains("--sim"), "{help}");
    }
}
