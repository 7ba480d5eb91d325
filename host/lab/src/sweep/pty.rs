//! The pseudo-terminals of the simulated CTA ([`super::sim`]), each behind a stable symbolic
//! link: Unix only. Elsewhere (Windows) opening one fails naming the commands that need it, so
//! `cta sweep` with real boards builds and runs there.

use std::path::Path;

use super::error::Result;

/// One end of a simulated board's pty (the simulator's, or the one the host opens).
#[cfg(unix)]
pub(super) type Port = serialport::TTYPort;
/// A serial port (never opened here: [`plug`] fails on this system).
#[cfg(windows)]
pub(super) type Port = serialport::COMPort;

/// A new pty, its device linked at `link` (replacing what was there): (master, slave).
#[cfg(unix)]
pub(super) fn plug(link: &Path) -> Result<(Port, Port)> {
    use super::error::{Context, Error};
    use serialport::SerialPort;
    let (master, slave) = Port::pair().context("cannot create a pseudo-terminal")?;
    let name = slave
        .name()
        .ok_or_else(|| Error::Refused("pseudo-terminal without a name".into()))?;
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(&name, link)
        .with_context(|| format!("cannot link {}", link.display()))?;
    Ok((master, slave))
}

/// Fails: no pseudo-terminal on this system (`link` would have named it).
#[cfg(windows)]
pub(super) fn plug(_link: &Path) -> Result<(Port, Port)> {
    let e = crate::boards::pty::no_pty("`cta sweep --sim` and `cta demo`");
    Err(super::error::Error::Refused(e.to_string()))
}
