//! The simulated boards behind pseudo-terminals (`cta beacon sim`, `cta sensor sim`, and
//! `--sim` of `cta beacon` and `cta sensor`): the firmware's own simulated boards on Unix.
//! Other systems (Windows) have no pty: there each is a type with no value, whose start
//! fails naming the commands and the systems that run them, so the rest of the tool (the
//! real boards on their COM ports, every analysis) builds and works there.

#[cfg(unix)]
pub use cta_firmware_beacon::sim::SimBoard as BeaconSim;
#[cfg(unix)]
pub use cta_firmware_sensor::sim::SimBoard as SensorSim;

#[cfg(not(unix))]
pub use elsewhere::{BeaconSim, SensorSim};

/// Why `commands` cannot run here: their simulated boards need a Unix pseudo-terminal.
pub fn no_pty(commands: &str) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::Unsupported,
        format!(
            "{commands} need a Unix pseudo-terminal (pty) for the simulated boards, which {} \
             has not got: run them on Linux or macOS (the real boards work here, on their \
             serial ports, e.g. COM3)",
            std::env::consts::OS
        ),
    )
}

#[cfg(not(unix))]
mod elsewhere {
    use std::convert::Infallible;
    use std::io;

    use cta_firmware_sensor::sim::SimNorthStar;

    use super::no_pty;

    /// The simulated beacon board, which needs a pty: never started here.
    pub struct BeaconSim(Infallible);

    impl BeaconSim {
        /// Fails: no pseudo-terminal on this system.
        pub fn spawn() -> io::Result<BeaconSim> {
            Err(no_pty("`cta beacon sim` and `cta beacon --sim`"))
        }

        /// The pty (never reached: there is no value).
        pub fn path(&self) -> &str {
            match self.0 {}
        }

        /// Stop the board (never reached: there is no value).
        pub fn stop(self) -> io::Result<()> {
            match self.0 {}
        }
    }

    /// The simulated sensor board, which needs a pty: never started here.
    pub struct SensorSim(Infallible);

    impl SensorSim {
        /// Fails: no pseudo-terminal on this system.
        pub fn spawn(_northstar: SimNorthStar) -> io::Result<SensorSim> {
            Err(no_pty("`cta sensor sim` and `cta sensor --sim`"))
        }

        /// The pty (never reached: there is no value).
        pub fn path(&self) -> &str {
            match self.0 {}
        }
    }
}

#[cfg(test)]
mod tests {
    /// The refusal names the commands, the need (a Unix pty) and what works instead.
    #[test]
    fn the_refusal_names_the_commands_and_the_way_out() {
        let e = super::no_pty("`cta sensor sim`");
        assert_eq!(e.kind(), std::io::ErrorKind::Unsupported);
        let m = e.to_string();
        for part in [
            "`cta sensor sim`",
            "Unix pseudo-terminal",
            "Linux or macOS",
            "COM3",
        ] {
            assert!(m.contains(part), "{part}: {m}");
        }
    }
}
