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

use anyhow::Result;
use clap::{Args, Subcommand};
use cta_core::wire::beacon::{BeaconStatus, LedMode, Limits, LED_COUNT};
use cta_core::wire::{DecoderStats, Identity};
use cta_lab::boards::beacon::{self, BeaconBoard, Modulation, PinMap};
use serde::Serialize;

use crate::conn::{self, BoardConn};

/// The connection options of `cta beacon`.
pub type BeaconConn = BoardConn<conn::Beacon>;

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
        args.conn.refuse_for(args.command.name())?;
        return match &args.command {
            BeaconCommand::Sim { seconds } => run_sim(*seconds, out),
            BeaconCommand::Pins => print_pins(&beacon::pin_map(), out),
            BeaconCommand::Measure { seconds } => {
                let m = beacon::measure(*seconds)?;
                print_modulation(&m, out)?;
                Ok(m.check()?)
            }
            _ => unreachable!("every board command has connection options"),
        };
    };
    let conn = args.conn.merge(after)?;
    let mut board = BeaconBoard::open(&conn.at()?, conn.link_config())?;
    board_command(&args.command, &conn, &mut board, out)
}

/// What [`run`] does once the board on the port is identified as a beacon board.
fn board_command(
    command: &BeaconCommand,
    conn: &BeaconConn,
    board: &mut BeaconBoard,
    out: &mut dyn Write,
) -> Result<()> {
    match command {
        BeaconCommand::Identify { .. } => print_identity(board.identity(), out)?,
        BeaconCommand::Status { json, .. } => {
            let s = board.status()?;
            if *json {
                writeln!(
                    out,
                    "{}",
                    serde_json::to_string_pretty(&StatusJson::from(&s))?
                )?;
            } else {
                print_status(&s, out)?;
            }
        }
        BeaconCommand::Set { led, mode, .. } => {
            let setting = board.set(*led, mode)?;
            writeln!(
                out,
                "LED {led}: {}{}",
                mode_text(setting.mode),
                sim_note(conn)
            )?;
        }
        BeaconCommand::SetMany { settings, .. } => {
            let n = board.set_many(settings)?;
            writeln!(out, "{n} LED(s) set{}", sim_note(conn))?;
        }
        BeaconCommand::AllOff { .. } => {
            board.all_off()?;
            writeln!(out, "all LEDs off{}", sim_note(conn))?;
        }
        BeaconCommand::Table { set, default, .. } => {
            if *default {
                board.restore_table()?;
                writeln!(
                    out,
                    "table replaced by the NorthStar table; all LEDs off{}",
                    sim_note(conn)
                )?;
            }
            if let Some(hz) = set {
                board.set_table(hz)?;
                writeln!(out, "table replaced; all LEDs off{}", sim_note(conn))?;
            }
            for (i, e) in board.table()?.iter().enumerate() {
                let note = if e.same.is_empty() {
                    String::new()
                } else {
                    let same: Vec<String> = e.same.iter().map(|j| j.to_string()).collect();
                    format!(
                        "   (the frequency of entry {}: a NorthStar cannot tell them \
                         apart; light one of them at a time)",
                        same.join(", ")
                    )
                };
                writeln!(out, "{i:2}  {:.3} Hz{note}", e.mhz as f64 / 1000.0)?;
            }
        }
        BeaconCommand::Leds { .. } => {
            let modes = board.leds()?;
            for (i, m) in modes.iter().enumerate() {
                if m.is_lit() {
                    writeln!(out, "{i:3}  {}", mode_text(*m))?;
                }
            }
            let lit = modes.iter().filter(|m| m.is_lit()).count();
            writeln!(out, "{lit} lit, {} off", modes.len() - lit)?;
        }
        BeaconCommand::Limits {
            max_lit,
            deadman_ms,
            ..
        } => {
            let limits: Limits = board.limits(*max_lit, *deadman_ms)?;
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
            let sent = board.heartbeats(*every_ms, *count)?;
            writeln!(out, "{sent} heartbeat(s) acknowledged")?;
        }
        BeaconCommand::Sim { .. } | BeaconCommand::Pins | BeaconCommand::Measure { .. } => {
            unreachable!("handled above")
        }
    }
    Ok(())
}

/// `identify`: who answered (as `cta sensor identify` says it).
pub(crate) fn print_identity(id: &Identity, out: &mut dyn Write) -> Result<()> {
    writeln!(
        out,
        "{} board, firmware {}, protocol {}{}, max frame {} bytes",
        id.board,
        id.firmware,
        id.protocol,
        if id.simulated { " (simulated)" } else { "" },
        id.max_frame
    )?;
    Ok(())
}

/// `status` as text.
fn print_status(s: &BeaconStatus, out: &mut dyn Write) -> Result<()> {
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

/// Wait `seconds` (`None`: until the process is stopped) while a simulated board serves.
pub(crate) fn serve_for(seconds: Option<f64>) {
    let start = std::time::Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(100));
        if let Some(s) = seconds {
            if start.elapsed().as_secs_f64() >= s {
                break;
            }
        }
    }
}

fn run_sim(seconds: Option<f64>, out: &mut dyn Write) -> Result<()> {
    let sim = beacon::start_sim()?;
    writeln!(out, "simulated beacon board on {}", sim.path())?;
    writeln!(
        out,
        "try: cta beacon --port {} identify   (Ctrl-C stops the board)",
        sim.path()
    )?;
    out.flush()?;
    serve_for(seconds);
    beacon::stop_sim(sim)?;
    Ok(())
}

/// `measure`: the frequency error and jitter of every table entry.
fn print_modulation(m: &Modulation, out: &mut dyn Write) -> Result<()> {
    writeln!(
        out,
        "{} LEDs, {} ticks at {} Hz ({} s simulated); {:.2} port operations per tick (max {})",
        m.leds, m.ticks, m.tick_hz, m.seconds, m.mean_writes, m.max_writes
    )?;
    writeln!(
        out,
        "index  nominal Hz   worst |error|   worst jitter p-p   worst jitter rms"
    )?;
    for e in &m.entries {
        writeln!(
            out,
            "{:5}  {:10.3}   {:11.2e} %   {:12.3} us   {:12.3} us",
            e.index,
            e.nominal_hz,
            e.error * 100.0,
            e.jitter_pp_us,
            e.jitter_rms_us
        )?;
    }
    writeln!(
        out,
        "worst: frequency error {:.2e} % (target 0.05 %), jitter {:.3} us peak-to-peak, {:.3} us rms (target 10 us)",
        m.worst_error * 100.0,
        m.worst_pp_us,
        m.worst_rms_us
    )?;
    Ok(())
}

/// `pins`: the pin map.
fn print_pins(map: &PinMap, out: &mut dyn Write) -> Result<()> {
    writeln!(out, "id  row col   x(in)  y(in)  GPIO")?;
    for p in &map.leds {
        writeln!(
            out,
            "{:3} {:3} {:3}  {:6.1} {:6.1}  {}",
            p.id, p.row, p.col, p.x, p.y, p.gpio
        )?;
    }
    writeln!(out, "reserved:")?;
    for (pin, why) in &map.reserved {
        writeln!(out, "  {pin:5} {why}")?;
    }
    writeln!(out, "spare: {}", map.spare)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

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
