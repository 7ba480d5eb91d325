//! The pose of logged spot frames, solved on the host with the board's own solver: the same
//! `cta_core::pose::PoseSolver` in `f32`, configured from the same calibration and
//! constellation, frame after frame as the board does (thesis eqs 56-59 on eq 65 or eqs
//! 60-63). A lab can post-process a run, compare the models on its own frames, or check the
//! board's poses.
//!
//! The frames are JSON lines, one spot report a line, as `cta sensor stream --json` prints
//! them: `{"seq":..,"t_us":..,"ns_seq":..,"sensitivity":..,"spots":[{"id":..,"x":..,"y":..,
//! "magnitude":..},..]}`.

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::time::Instant;

use cta_core::pose::{Calibration, Constellation, ModelKind, PoseSolver, SolverSettings};
use cta_core::wire::sensor::{PoseHeader, PoseReport, SpotReport};

use super::plate::built_in_constellation;
use crate::boards::sensor::{constellation_file, with_brightness, ConstellationFile};

/// The longest line a frames file may have: a report of 20 spots is about 1.2 KB.
pub const MAX_LINE: usize = 16 * 1024;

/// Why logged frames could not be solved.
#[derive(Debug, thiserror::Error)]
pub enum OfflineError {
    /// The frames file could not be read.
    #[error("{}: cannot read: {error}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// A line is not a spot report.
    #[error(
        "{}:{line}: not a spot report ({error}); the frames are the JSON lines `cta sensor \
         stream --json` prints",
        .path.display()
    )]
    Frame {
        /// The file.
        path: PathBuf,
        /// The line, from 1.
        line: usize,
        /// What the JSON reader found.
        error: serde_json::Error,
    },
    /// A line longer than any spot report.
    #[error("{}:{line}: longer than {MAX_LINE} bytes: not a spot report", .path.display())]
    LongLine {
        /// The file.
        path: PathBuf,
        /// The line, from 1.
        line: usize,
    },
    /// The file holds no frame.
    #[error("{}: no spot report in the file", .path.display())]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// The calibration or the constellation was refused by the solver's checks.
    #[error("the calibration or the constellation: {0}")]
    Config(cta_core::pose::ConfigError),
}

/// Read the frames file `path`: one spot report a line; blank lines and lines starting with
/// `#` are skipped.
pub fn read_frames(path: &Path) -> Result<Vec<SpotReport>, OfflineError> {
    let read = |error| OfflineError::Read {
        path: path.to_path_buf(),
        error,
    };
    let f = std::fs::File::open(path).map_err(read)?;
    let mut r = std::io::BufReader::new(f);
    let mut frames = Vec::new();
    let mut buf = Vec::new();
    let mut line = 0;
    loop {
        buf.clear();
        line += 1;
        let n = std::io::Read::take(&mut r, MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut buf)
            .map_err(read)?;
        if n == 0 {
            break;
        }
        if buf.len() > MAX_LINE {
            return Err(OfflineError::LongLine {
                path: path.to_path_buf(),
                line,
            });
        }
        let text = String::from_utf8_lossy(&buf);
        let text = text.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let frame = serde_json::from_str(text).map_err(|error| OfflineError::Frame {
            path: path.to_path_buf(),
            line,
            error,
        })?;
        frames.push(frame);
    }
    if frames.is_empty() {
        return Err(OfflineError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(frames)
}

/// The constellation `spec` names: a JSON file, or else a built-in name (one-10, one-19,
/// four-10, four-19); with `brightness`, the beacons' brightness from that calibration file.
pub fn constellation(
    spec: &str,
    brightness: Option<&str>,
) -> Result<ConstellationFile, crate::boards::sensor::Error> {
    if Path::new(spec).exists() {
        return constellation_file(spec, brightness);
    }
    with_brightness(built_in_constellation(spec)?, Vec::new(), brightness)
}

/// How the frames are solved.
#[derive(Debug, Clone, Copy)]
pub struct OfflineOptions {
    /// The measurement model.
    pub model: ModelKind,
    /// Solve every frame from a cold start, as if it were the first; by default each frame
    /// starts from the last good pose, as on the board.
    pub cold: bool,
}

/// Solve `frames` with `cal` and `con`: one pose report a frame, as the board would send it in
/// pose mode (`solve_us` is the host's time).
pub fn solve_frames(
    cal: &Calibration,
    con: &Constellation,
    frames: &[SpotReport],
    options: OfflineOptions,
) -> Result<Vec<PoseReport>, OfflineError> {
    let settings = SolverSettings {
        model: options.model,
        ..SolverSettings::default()
    };
    let mut solver = PoseSolver::<f32>::new(cal, con, settings).map_err(OfflineError::Config)?;
    Ok(frames
        .iter()
        .map(|f| {
            if options.cold {
                solver.reset();
            }
            let t0 = Instant::now();
            let sol = solver.solve_frame(&f.spots, f.sensitivity);
            let header = PoseHeader {
                seq: f.seq,
                t_us: f.t_us,
                ns_seq: f.ns_seq,
                model: options.model,
                solve_us: t0.elapsed().as_micros().min(u32::MAX as u128) as u32,
            };
            PoseReport::new(header, &sol)
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boards::link::{BoardAt, LinkConfig};
    use crate::boards::sensor::SensorBoard;
    use crate::pose::calibrations::sim_calibration;
    use crate::pose::head::SimScene;
    use cta_core::pose::{cta_constellation, PoseStatus};
    use cta_core::wire::sensor::{Mode, SensorResponse};
    use std::sync::atomic::AtomicBool;

    /// The in-process simulated board (the default scene, configured as `--sim` does) in
    /// `mode`: its first `n` reports.
    fn board_reports(mode: Mode, n: u64) -> Vec<SensorResponse> {
        let mut b = SensorBoard::open(&BoardAt::InProcess, LinkConfig::default()).unwrap();
        b.set_mode(mode).unwrap();
        let mut out = Vec::new();
        b.read_reports(n, &AtomicBool::new(false), |r| {
            out.push(r);
            Ok(())
        })
        .unwrap();
        b.idle().unwrap();
        out
    }

    /// Frames recorded from the simulated board and solved here give the poses the board
    /// itself reports for the same frames (the simulated NorthStar draws the same noise in
    /// both runs), to the bit: the same solver, the same configuration, the same warm starts.
    #[test]
    fn logged_frames_solve_to_the_boards_own_poses() {
        let n = 12;
        let frames: Vec<SpotReport> = board_reports(Mode::Stream, n)
            .into_iter()
            .filter_map(|r| match r {
                SensorResponse::Spots(s) => Some(s),
                _ => None,
            })
            .collect();
        let model = ModelKind::NearField;
        let board: Vec<PoseReport> = board_reports(Mode::Pose(model), n)
            .into_iter()
            .filter_map(|r| match r {
                SensorResponse::Pose(p) => Some(p),
                _ => None,
            })
            .collect();
        assert_eq!((frames.len(), board.len()), (n as usize, n as usize));
        let cal = sim_calibration(SimScene::default().magnitude_noise).unwrap();
        let options = OfflineOptions { model, cold: false };
        let here = solve_frames(&cal, &cta_constellation(), &frames, options).unwrap();
        for (h, b) in here.iter().zip(&board) {
            assert_eq!(h.ns_seq, b.ns_seq);
            assert_eq!(
                (
                    h.status,
                    h.position,
                    h.mrp,
                    h.iterations,
                    h.beacons,
                    h.cold_start
                ),
                (
                    b.status,
                    b.position,
                    b.mrp,
                    b.iterations,
                    b.beacons,
                    b.cold_start
                )
            );
            assert_eq!(h.sigma_position, b.sigma_position);
        }
        // The scene: the target at (0.2, -0.1, 12) in, turned 2 deg about z.
        assert!(here.iter().all(|p| p.status == PoseStatus::Ok));
        assert!((here[0].position[2] - 12.0).abs() < 5.0 * here[0].sigma_position[2]);
        // Cold, each frame on its own: the first frame's pose, the others' cold starts.
        let cold = solve_frames(
            &cal,
            &cta_constellation(),
            &frames,
            OfflineOptions { model, cold: true },
        )
        .unwrap();
        assert_eq!(cold[0].position, here[0].position);
        assert!(cold.iter().all(|p| p.cold_start));
        assert!(here[1..].iter().all(|p| !p.cold_start));
    }

    /// A line that is not a spot report is named with its line number; comments and blank
    /// lines are skipped; an empty file is refused.
    #[test]
    fn frames_files_are_checked_by_line() {
        let dir = std::env::temp_dir().join(format!("cta-offline-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let good = r#"{"seq":0,"t_us":1,"ns_seq":1,"sensitivity":4,"spots":[{"id":0,"x":1,"y":2,"magnitude":3}]}"#;
        let p = dir.join("frames.jsonl");
        std::fs::write(&p, format!("# run 1\n\n{good}\n{{\"seq\":\n")).unwrap();
        let e = read_frames(&p).unwrap_err().to_string();
        assert!(e.contains("frames.jsonl:4: not a spot report"), "{e}");
        std::fs::write(&p, format!("# run 1\n{good}\n")).unwrap();
        assert_eq!(read_frames(&p).unwrap().len(), 1);
        std::fs::write(&p, "# nothing\n").unwrap();
        assert!(matches!(read_frames(&p), Err(OfflineError::Empty { .. })));
        std::fs::write(&p, vec![b'x'; MAX_LINE + 10]).unwrap();
        let e = read_frames(&p).unwrap_err().to_string();
        assert!(e.contains(":1: longer than 16384 bytes"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
