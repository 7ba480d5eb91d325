//! How the board commands (`cta beacon`, `cta sensor`) reach their board: one set of
//! connection options, given before the subcommand or after it, with each board's own help
//! and defaults.

use std::marker::PhantomData;
use std::time::Duration;

use anyhow::{bail, Result};
use clap::Args;
use cta_lab::boards::link::{BoardAt, LinkConfig};

/// What the connection options say for one kind of board.
pub trait Board: std::fmt::Debug + Clone + Default + Send + Sync + 'static {
    /// The command's name: `beacon`, `sensor`.
    const NAME: &'static str;
    /// The help of `--port`.
    const PORT_HELP: &'static str;
    /// The help of `--sim`.
    const SIM_HELP: &'static str;
    /// Reply timeout per attempt when `--timeout-ms` is not given, ms.
    const DEFAULT_TIMEOUT_MS: u64;
    /// Resends after a timeout when `--retries` is not given.
    const DEFAULT_RETRIES: u32;
}

/// The beacon board (`cta beacon`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Beacon;

impl Board for Beacon {
    const NAME: &'static str = "beacon";
    const PORT_HELP: &'static str =
        "Serial port of the board (e.g. /dev/ttyUSB0, COM3 on Windows, or the pty printed by `cta beacon sim`)";
    const SIM_HELP: &'static str = "Talk to a simulated board started in this process (instead \
         of --port); it lives for this command only";
    const DEFAULT_TIMEOUT_MS: u64 = 500;
    const DEFAULT_RETRIES: u32 = 2;
}

/// The sensor board (`cta sensor`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sensor;

impl Board for Sensor {
    const NAME: &'static str = "sensor";
    const PORT_HELP: &'static str =
        "Serial port of the board (e.g. /dev/ttyUSB1, COM4 on Windows, or the pty printed by `cta sensor sim`)";
    const SIM_HELP: &'static str =
        "Talk to a simulated board started in this process (instead of --port)";
    const DEFAULT_TIMEOUT_MS: u64 = 500;
    // As `cta beacon`.
    const DEFAULT_RETRIES: u32 = Beacon::DEFAULT_RETRIES;
}

/// The connection options of the subcommands that talk to a board of kind `B`.
#[derive(Debug, Clone, Default, Args)]
pub struct BoardConn<B: Board> {
    /// Serial port of the board.
    #[arg(long, value_name = "PATH", conflicts_with = "sim", help = B::PORT_HELP)]
    pub port: Option<String>,
    /// Talk to a simulated board started in this process.
    #[arg(long, help = B::SIM_HELP)]
    pub sim: bool,
    /// Reply timeout per attempt, ms (1 or more) [default: 500].
    #[arg(long, value_name = "MS", value_parser = clap::value_parser!(u64).range(1..))]
    pub timeout_ms: Option<u64>,
    /// Resends after a timeout [default: 2].
    #[arg(long, value_name = "N")]
    pub retries: Option<u32>,
    /// The kind of board.
    #[arg(skip)]
    pub board: PhantomData<B>,
}

/// The value of an option that may stand before or after the subcommand, not both.
pub fn one_of<T: Clone>(name: &str, before: &Option<T>, after: &Option<T>) -> Result<Option<T>> {
    match (before, after) {
        (Some(_), Some(_)) => {
            bail!("{name} is given both before and after the subcommand: give it once")
        }
        (Some(v), None) | (None, Some(v)) => Ok(Some(v.clone())),
        (None, None) => Ok(None),
    }
}

impl<B: Board> BoardConn<B> {
    /// The options given, as they would be written (for the error of a subcommand that
    /// takes none).
    pub fn given(&self) -> Vec<&'static str> {
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

    /// Refuse these options (given before the subcommand) for the subcommand `sub`, which
    /// talks to no board.
    pub fn refuse_for(&self, sub: &str) -> Result<()> {
        let given = self.given();
        if !given.is_empty() {
            bail!(
                "{} {} nothing for `cta {} {sub}`: it talks to no board",
                given.join(", "),
                if given.len() == 1 { "means" } else { "mean" },
                B::NAME
            );
        }
        Ok(())
    }

    /// These options (given before the subcommand) with those given after it; an option
    /// given in both places, or `--sim` with `--port`, is refused.
    pub fn merge(&self, after: &Self) -> Result<Self> {
        let conn = BoardConn {
            port: one_of("--port", &self.port, &after.port)?,
            sim: self.sim || after.sim,
            timeout_ms: one_of("--timeout-ms", &self.timeout_ms, &after.timeout_ms)?,
            retries: one_of("--retries", &self.retries, &after.retries)?,
            board: PhantomData,
        };
        if conn.sim && conn.port.is_some() {
            bail!("--sim and --port exclude each other: use the simulated board or the one on the port");
        }
        Ok(conn)
    }

    /// Where the board is: the in-process simulated board with `--sim`, else the port.
    pub fn at(&self) -> Result<BoardAt> {
        match (&self.port, self.sim) {
            (_, true) => Ok(BoardAt::InProcess),
            (Some(p), false) => Ok(BoardAt::Port(p.clone())),
            (None, false) => bail!(
                "--port PATH is required (the board's serial port, or the pty of `cta {} sim`), or use --sim",
                B::NAME
            ),
        }
    }

    /// The link's timing: `--timeout-ms` and `--retries`, or the board's defaults.
    pub fn link_config(&self) -> LinkConfig {
        LinkConfig {
            timeout: Duration::from_millis(self.timeout_ms.unwrap_or(B::DEFAULT_TIMEOUT_MS)),
            retries: self.retries.unwrap_or(B::DEFAULT_RETRIES),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The help's defaults are each board's.
    fn help_defaults<B: Board>() {
        let mut cmd = BoardConn::<B>::augment_args(clap::Command::new("board").term_width(1000));
        let help = cmd.render_help().to_string();
        assert!(
            help.contains(&format!("[default: {}]", B::DEFAULT_TIMEOUT_MS))
                && help.contains(&format!("[default: {}]", B::DEFAULT_RETRIES))
                && help.contains(&format!("`cta {} sim`", B::NAME)),
            "{help}"
        );
    }

    #[test]
    fn the_help_says_each_boards_defaults() {
        help_defaults::<Beacon>();
        help_defaults::<Sensor>();
    }
}
