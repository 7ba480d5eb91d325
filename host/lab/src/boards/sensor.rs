//! The sensor board's requests (`cta sensor ...`): a link to an identified board, its
//! calibration and constellation files, its settings, the stream of spot and pose reports,
//! and the simulated board on a pseudo-terminal.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use cta_core::pose::{cta_constellation, Calibration, Constellation};
use cta_core::wire::sensor::{
    Mode, PoseReport, SensorConfig, SensorError, SensorProtocol, SensorRequest, SensorResponse,
    SensorStatus,
};
use cta_core::wire::{Identity, Response};
/// The sensor firmware's library (board logic, NorthStar link, simulated board).
pub use cta_firmware_sensor as firmware;
/// The vector type of the pose API (for callers without their own nalgebra dependency).
pub use nalgebra::Vector3;

use crate::boards::files::read_json;
use crate::boards::link::{open_serial, BoardAt, Link, LinkConfig, LinkError};
use crate::boards::pty::SensorSim as SimBoard;
use crate::pose::calibrations::sim_calibration;
use crate::pose::head::SimScene;
use crate::pose::plate::{read_constellation, set_brightness};

/// What went wrong with a sensor board command.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A simulated board could not be started.
    #[error("starting the simulated sensor board: {0}")]
    StartSim(io::Error),
    /// The serial port could not be opened (its message names the port).
    #[error(transparent)]
    Port(io::Error),
    /// The board on the port did not identify as a sensor board.
    #[error("identifying the board on {path}: {error}")]
    Identify {
        /// The port.
        path: String,
        /// What the link found.
        error: LinkError<SensorError>,
    },
    /// A request to the identified board failed on the link, named by the board's port.
    #[error("sensor board on {path}: {error}")]
    OnBoard {
        /// The port.
        path: String,
        /// What the link found.
        error: LinkError<SensorError>,
    },
    /// Loading a file into the identified board failed on the link.
    #[error("sensor board on {path}: loading the {what} of {file}: {error}")]
    Loading {
        /// The port.
        path: String,
        /// `calibration` or `constellation`.
        what: &'static str,
        /// The file.
        file: String,
        /// What the link found.
        error: LinkError<SensorError>,
    },
    /// A request failed on a link not named by its port (a simulated board's own).
    #[error(transparent)]
    Link(#[from] LinkError<SensorError>),
    /// A well-formed reply of another kind than the request's.
    #[error("unexpected reply to {request}: {reply}")]
    Unexpected {
        /// The request.
        request: &'static str,
        /// The reply, as debugged.
        reply: String,
    },
    /// The board sent no report for 5 s.
    #[error("no report from the board for 5 s (is the NorthStar connected?)")]
    Silent,
    /// Writing out a report failed.
    #[error(transparent)]
    Output(io::Error),
    /// A calibration or constellation file was refused.
    #[error(transparent)]
    BoardFile(#[from] crate::boards::files::Error),
    /// The simulated scene, a constellation file or a simulated calibration failed.
    #[error(transparent)]
    Pose(#[from] crate::pose::Error),
}

/// The attitude of a pose report as a rotation vector about x, y, z, degrees: `4 atan(|q|)
/// q/|q|` of its MRP `q` (exact; close to Euler angles only for small rotations).
pub fn attitude_deg(p: &PoseReport) -> [f64; 3] {
    small_angles_deg(&Vector3::new(
        p.mrp[0] as f64,
        p.mrp[1] as f64,
        p.mrp[2] as f64,
    ))
}

/// The rotation vector of an MRP, degrees.
fn small_angles_deg(q: &Vector3<f64>) -> [f64; 3] {
    let n = q.norm();
    if n == 0.0 {
        return [0.0; 3];
    }
    let v = q * (4.0 * n.atan() / n);
    [v.x.to_degrees(), v.y.to_degrees(), v.z.to_degrees()]
}

/// A constellation file ready to load: read and checked ([`read_constellation`]), its
/// beacons' brightness set from a calibration when one is given ([`set_brightness`]).
#[derive(Debug, Clone)]
pub struct ConstellationFile {
    /// The constellation.
    pub constellation: Constellation,
    /// Beacons whose brightness the calibration set (`None`: no calibration given).
    pub brightness_set: Option<usize>,
    /// Warnings about the file and the brightness.
    pub warnings: Vec<String>,
}

/// Read the constellation file `file` and, with `brightness`, set its beacons' brightness
/// from that calibration file's `led_brightness`.
pub fn constellation_file(
    file: &str,
    brightness: Option<&str>,
) -> Result<ConstellationFile, Error> {
    let (constellation, warnings) = read_constellation(file)?;
    with_brightness(constellation, warnings, brightness)
}

/// `constellation` (read with `warnings`) with its beacons' brightness set from the
/// calibration file `brightness`, when given ([`set_brightness`]).
pub fn with_brightness(
    mut constellation: Constellation,
    mut warnings: Vec<String>,
    brightness: Option<&str>,
) -> Result<ConstellationFile, Error> {
    let brightness_set = match brightness {
        Some(cal) => {
            let (set, w) = set_brightness(&mut constellation, cal)?;
            warnings.extend(w);
            Some(set)
        }
        None => None,
    };
    Ok(ConstellationFile {
        constellation,
        brightness_set,
        warnings,
    })
}

/// A link to a sensor board that answered as one, on a port or in this process.
pub struct SensorBoard {
    link: Link<SensorProtocol, Box<dyn serialport::SerialPort>>,
    id: Identity,
    path: String,
    // Declared after the link: the board outlives the link to it.
    sim: Option<SimBoard>,
}

impl SensorBoard {
    /// Open the board at `at` and check that it is a sensor board speaking our protocol. The
    /// in-process simulated board (the default scene) starts with empty flash: it is loaded
    /// with the simulated CTA's calibration ([`sim_calibration`]) and constellation.
    pub fn open(at: &BoardAt, config: LinkConfig) -> Result<SensorBoard, Error> {
        let sim = match at {
            BoardAt::InProcess => {
                Some(SimBoard::spawn(SimScene::default().northstar()).map_err(Error::StartSim)?)
            }
            BoardAt::Port(_) => None,
        };
        let path = match (&sim, at) {
            (Some(s), _) => s.path().to_string(),
            (None, BoardAt::Port(p)) => p.clone(),
            (None, BoardAt::InProcess) => unreachable!("the simulated board was started"),
        };
        let port = open_serial(&path).map_err(Error::Port)?;
        let mut link = Link::<SensorProtocol, _>::new(port, config);
        let id = link.check_board().map_err(|error| Error::Identify {
            path: path.clone(),
            error,
        })?;
        let mut board = SensorBoard {
            link,
            id,
            path,
            sim,
        };
        if board.sim.is_some() {
            let cal = sim_calibration(SimScene::default().magnitude_noise)?;
            board.call(SensorRequest::LoadCalibration(cal))?;
            board.call(SensorRequest::LoadConstellation(cta_constellation()))?;
        }
        Ok(board)
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
    fn named(&self, error: LinkError<SensorError>) -> Error {
        Error::OnBoard {
            path: self.path.clone(),
            error,
        }
    }

    /// Send `request`; `None` for an acknowledgement.
    fn call(&mut self, request: SensorRequest) -> Result<Option<SensorResponse>, Error> {
        self.link.call(request).map_err(|e| self.named(e))
    }

    /// The board's status.
    pub fn status(&mut self) -> Result<SensorStatus, Error> {
        match self.call(SensorRequest::Status)? {
            Some(SensorResponse::Status(s)) => Ok(s),
            other => Err(Error::Unexpected {
                request: "Status",
                reply: format!("{other:?}"),
            }),
        }
    }

    /// Send one heartbeat.
    pub fn heartbeat(&mut self) -> Result<(), Error> {
        self.link.heartbeat().map_err(|e| self.named(e))
    }

    /// Store the calibration file `file` in the board's flash, without its spot magnitude law
    /// when `no_magnitude`. Returns whether a magnitude law was left out.
    pub fn load_calibration(&mut self, file: &str, no_magnitude: bool) -> Result<bool, Error> {
        let mut cal: Calibration = read_json(file)?;
        let dropped = no_magnitude && cal.magnitude.take().is_some();
        self.link
            .call(SensorRequest::LoadCalibration(cal))
            .map_err(|error| Error::Loading {
                path: self.path.clone(),
                what: "calibration",
                file: file.to_string(),
                error,
            })?;
        Ok(dropped)
    }

    /// Store the constellation of the file `file` ([`constellation_file`]) in the board's
    /// flash.
    pub fn load_constellation(&mut self, con: Constellation, file: &str) -> Result<(), Error> {
        self.link
            .call(SensorRequest::LoadConstellation(con))
            .map_err(|error| Error::Loading {
                path: self.path.clone(),
                what: "constellation",
                file: file.to_string(),
                error,
            })?;
        Ok(())
    }

    /// The calibration and constellation in the board's flash.
    pub fn config(&mut self) -> Result<SensorConfig, Error> {
        match self.call(SensorRequest::GetConfig)? {
            Some(SensorResponse::Config(c)) => Ok(c),
            other => Err(Error::Unexpected {
                request: "GetConfig",
                reply: format!("{other:?}"),
            }),
        }
    }

    /// Whether the board's stored calibration has no near-field part (near-field poses then
    /// use the nominal head). `false` without a calibration, or when the reply is not the
    /// configuration.
    pub fn lacks_near_field(&mut self) -> Result<bool, Error> {
        Ok(match self.call(SensorRequest::GetConfig)? {
            Some(SensorResponse::Config(c)) => {
                matches!(&c.calibration, Some(cal) if cal.near_field.is_none())
            }
            _ => false,
        })
    }

    /// Set the NorthStar light sensitivity (1..=4).
    pub fn set_sensitivity(&mut self, level: u8) -> Result<(), Error> {
        self.call(SensorRequest::SetSensitivity(level))?;
        Ok(())
    }

    /// Set the NorthStar report rate, Hz (1..=50).
    pub fn set_rate(&mut self, hz: u8) -> Result<(), Error> {
        self.call(SensorRequest::SetRate(hz))?;
        Ok(())
    }

    /// Set the board's mode: idle, streaming spot reports, or solving poses with a model.
    pub fn set_mode(&mut self, mode: Mode) -> Result<(), Error> {
        self.call(SensorRequest::SetMode(mode))?;
        Ok(())
    }

    /// Set the board idle.
    pub fn idle(&mut self) -> Result<(), Error> {
        self.set_mode(Mode::Idle)
    }

    /// Pass the board's spot and pose reports to `on_report` until `count` arrived (0: no
    /// limit) or `stop` is set ([`read_reports_until`]).
    pub fn read_reports(
        &mut self,
        count: u64,
        stop: &AtomicBool,
        on_report: impl FnMut(SensorResponse) -> io::Result<()>,
    ) -> Result<(), Error> {
        read_reports_until(&mut self.link, count, stop, on_report).map_err(|e| match e {
            Error::Link(error) => Error::OnBoard {
                path: self.path.clone(),
                error,
            },
            e => e,
        })
    }
}

/// Read unsolicited reports (seq SEQ_NONE) until `count` arrived (0: forever); fails after 5 s
/// without a report.
pub fn read_reports<S: io::Read + io::Write>(
    link: &mut Link<SensorProtocol, S>,
    count: u64,
    mut on_report: impl FnMut(SensorResponse),
) -> Result<(), Error> {
    read_reports_until(link, count, &AtomicBool::new(false), |r| {
        on_report(r);
        Ok(())
    })
}

/// Read unsolicited reports (seq SEQ_NONE) and pass the spot and pose reports to `on_report`
/// until `count` arrived (0: forever) or `stop` is set (by a signal); fails after 5 s without
/// a report, or when `on_report` fails.
pub fn read_reports_until<S: io::Read + io::Write>(
    link: &mut Link<SensorProtocol, S>,
    count: u64,
    stop: &AtomicBool,
    mut on_report: impl FnMut(SensorResponse) -> io::Result<()>,
) -> Result<(), Error> {
    let mut seen = 0u64;
    let mut last = Instant::now();
    while (count == 0 || seen < count) && !stop.load(Ordering::SeqCst) {
        let next = link
            .next_unsolicited(Duration::from_millis(100))
            .map_err(LinkError::<SensorError>::Io)?;
        match next {
            Some(Response::Board(r @ (SensorResponse::Spots(_) | SensorResponse::Pose(_)))) => {
                seen += 1;
                last = Instant::now();
                on_report(r).map_err(Error::Output)?;
            }
            Some(_) => {}
            None if last.elapsed() > Duration::from_secs(5) => return Err(Error::Silent),
            None => {}
        }
    }
    Ok(())
}

/// Start a simulated sensor board on a pseudo-terminal with the NorthStar of `scene`
/// (`cta sensor sim`); `configured`: loaded with the simulated CTA's calibration (its
/// magnitude law at the scene's magnitude noise) and constellation.
pub fn start_sim(scene: &SimScene, configured: bool) -> Result<SimBoard, Error> {
    let sim = SimBoard::spawn(scene.try_northstar()?).map_err(Error::StartSim)?;
    if configured {
        let port = open_serial(sim.path()).map_err(Error::Port)?;
        let mut link = Link::<SensorProtocol, _>::new(port, LinkConfig::default());
        link.call(SensorRequest::LoadCalibration(sim_calibration(
            scene.magnitude_noise,
        )?))?;
        link.call(SensorRequest::LoadConstellation(cta_constellation()))?;
    }
    Ok(sim)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cta_core::mrp;

    #[test]
    fn small_angles() {
        let q = mrp::from_axis_angle(&Vector3::z(), 0.1);
        let e = small_angles_deg(&q);
        assert!((e[2] - 0.1f64.to_degrees()).abs() < 1e-9);
    }
}
