//! End-to-end: the host's `Link` and the simulated sensor board (the firmware's `Board`,
//! fed by a simulated NorthStar running the eq 63 physics) over a pseudo-terminal: the
//! protocol (identify, configuration errors named, flash read-back, stream, pose, status,
//! garbage on both links) and the pose itself.

use std::io::Write;
use std::time::Duration;

use cta_core::mrp;
use cta_core::pose::{
    cta_constellation, CalField, Calibration, ConfigError, Magnitude, ModelKind, PoseStatus,
};
use cta_core::wire::sensor::{
    Mode, PoseReport, SensorError, SensorProtocol, SensorRequest, SensorResponse, SensorStatus,
};
use cta_core::wire::BoardKind;
use cta_lab::boards::link::{open_serial, Link, LinkConfig, LinkError};
use cta_lab::boards::sensor::firmware::sim::{SimBoard, SimNorthStar};
use cta_lab::boards::sensor::{read_reports, Vector3};

type SensorLink = Link<SensorProtocol, Box<dyn serialport::SerialPort>>;

/// A simulated board at 50 Hz whose NorthStar sees the CTA constellation from `truth`'s head
/// at pose `t`, `q` (noise 32.768 counts, seed 3), loaded with `cal` and the constellation.
fn configured_board(
    truth: &Calibration,
    t: Vector3<f64>,
    q: Vector3<f64>,
    cal: Calibration,
) -> (SimBoard, SensorLink) {
    let mut ns = SimNorthStar::new(truth, cta_constellation(), t, q, 32.768, 3);
    ns.rate_hz = 50;
    let sim = SimBoard::spawn(ns).unwrap();
    let mut l = connect(&sim);
    l.call(SensorRequest::LoadCalibration(cal)).unwrap();
    l.call(SensorRequest::LoadConstellation(cta_constellation()))
        .unwrap();
    (sim, l)
}

fn connect(sim: &SimBoard) -> SensorLink {
    let port = open_serial(sim.path()).expect("open the pty");
    Link::new(
        port,
        LinkConfig {
            timeout: Duration::from_millis(1500),
            retries: 1,
        },
    )
}

fn refused(r: Result<Option<SensorResponse>, LinkError<SensorError>>) -> SensorError {
    match r {
        Err(LinkError::Refused { error, .. }) => error,
        other => panic!("expected a refusal, got {other:?}"),
    }
}

fn status(l: &mut SensorLink) -> SensorStatus {
    match l.call(SensorRequest::Status).unwrap() {
        Some(SensorResponse::Status(s)) => s,
        other => panic!("{other:?}"),
    }
}

fn scene(range: f64, garbage: f64) -> (SimNorthStar, Vector3<f64>, Vector3<f64>) {
    let t = Vector3::new(0.2, -0.1, range);
    let q = mrp::from_axis_angle(&Vector3::new(0.2, 0.3, 1.0), 2f64.to_radians());
    let mut ns = SimNorthStar::new(&Calibration::table3(), cta_constellation(), t, q, 32.768, 7);
    ns.garbage = garbage;
    ns.rate_hz = 50;
    (ns, t, q)
}

fn poses(l: &mut SensorLink, n: u64) -> Vec<PoseReport> {
    let mut out = Vec::new();
    read_reports(l, n, |r| {
        if let SensorResponse::Pose(p) = r {
            out.push(p);
        }
    })
    .unwrap();
    out
}

#[test]
fn protocol_and_pose_over_a_pty() {
    let (ns, t, q) = scene(12.0, 0.0);
    let sim = SimBoard::spawn(ns).unwrap();
    let mut l = connect(&sim);
    let id = l.check_board().unwrap();
    assert_eq!(id.board, BoardKind::Sensor);
    assert!(id.simulated);

    // Nothing stored yet: pose mode is refused, naming what is missing.
    assert_eq!(
        refused(l.call(SensorRequest::SetMode(Mode::Pose(ModelKind::NearField)))),
        SensorError::NotConfigured {
            calibration: false,
            constellation: false
        }
    );
    // Bad configurations are refused by name.
    let mut con = cta_constellation();
    con.beacons[4].id = con.beacons[1].id;
    assert_eq!(
        refused(l.call(SensorRequest::LoadConstellation(con))),
        SensorError::Config(ConfigError::DuplicateId { id: 1 })
    );
    let mut con = cta_constellation();
    con.beacons.truncate(3);
    assert_eq!(
        refused(l.call(SensorRequest::LoadConstellation(con))),
        SensorError::Config(ConfigError::TooFewBeacons { count: 3, min: 4 })
    );
    let mut cal = Calibration::table3();
    cal.p = [0.9, 0.9, 0.0];
    let err = refused(l.call(SensorRequest::LoadCalibration(cal)));
    assert_eq!(
        err,
        SensorError::Config(ConfigError::CalibrationOutOfRange { field: CalField::P })
    );
    assert!(err.to_string().contains("|p| <= 1"), "{err}");
    assert_eq!(
        refused(l.call(SensorRequest::SetSensitivity(0))),
        SensorError::SensitivityOutOfRange { got: 0 }
    );

    // Good configuration, read back from flash.
    l.call(SensorRequest::LoadCalibration(Calibration::table3()))
        .unwrap();
    l.call(SensorRequest::LoadConstellation(cta_constellation()))
        .unwrap();
    match l.call(SensorRequest::GetConfig).unwrap() {
        Some(SensorResponse::Config(c)) => {
            assert_eq!(c.generation, 2);
            assert_eq!(c.calibration, Some(Calibration::table3()));
            assert_eq!(c.constellation, Some(cta_constellation()));
        }
        other => panic!("{other:?}"),
    }

    // Stream mode: spot reports with a running sequence number and board time.
    l.call(SensorRequest::SetMode(Mode::Stream)).unwrap();
    let mut reports = Vec::new();
    read_reports(&mut l, 3, |r| {
        if let SensorResponse::Spots(s) = r {
            reports.push(s);
        }
    })
    .unwrap();
    assert_eq!(reports.len(), 3);
    assert!(reports
        .windows(2)
        .all(|w| w[1].seq > w[0].seq && w[1].t_us > w[0].t_us));
    assert!(reports
        .iter()
        .all(|r| r.spots.len() == 10 && r.sensitivity == 4));

    // Pose mode, near-field model: at 12 in the noise floor is ~0.02 in and ~0.4 deg.
    l.call(SensorRequest::SetSensitivity(3)).unwrap();
    l.call(SensorRequest::SetMode(Mode::Pose(ModelKind::NearField)))
        .unwrap();
    // The spot reports of the stream that arrived before the reply are queued: drop them,
    // so that every report read below is a pose, the first one the board's first solve.
    l.discard_unsolicited();
    let ps = poses(&mut l, 6);
    assert_eq!(ps.len(), 6, "only pose reports after SetMode(Pose)");
    // Entering pose mode builds a fresh solver: its first solve has no previous pose, so
    // it starts cold (then the others warm, checked below).
    assert!(
        ps[0].cold_start && ps[0].status == PoseStatus::Ok,
        "first pose: {:?}",
        ps[0]
    );
    for p in &ps[1..] {
        assert_eq!(p.status, PoseStatus::Ok, "{p:?}");
        assert_eq!(p.beacons, 10);
        let pos = Vector3::new(
            p.position[0] as f64,
            p.position[1] as f64,
            p.position[2] as f64,
        );
        assert!((pos - t).norm() < 0.1, "{p:?}");
        let qe = Vector3::new(p.mrp[0] as f64, p.mrp[1] as f64, p.mrp[2] as f64);
        let err = mrp::angle(&mrp::from_dcm(&(mrp::dcm(&qe) * mrp::dcm(&q).transpose())));
        assert!(err.to_degrees() < 2.0, "{p:?}");
        assert!(
            p.sigma_position.iter().all(|s| *s > 0.0 && *s < 0.2),
            "{p:?}"
        );
        assert!(!p.cold_start, "warm start after the first pose: {p:?}");
    }

    // Moving the target far away: fewer beacons are not an issue, but a blocked view is.
    sim.with_northstar(|ns| ns.constellation.beacons.truncate(3));
    let ps = poses(&mut l, 3);
    assert!(
        ps.iter()
            .all(|p| p.status == PoseStatus::TooFewBeacons
                && p.position.iter().all(|v| v.is_finite()))
    );

    let s = status(&mut l);
    assert_eq!(s.mode, Mode::Pose(ModelKind::NearField));
    assert_eq!(s.sensitivity, 3);
    assert!(s.calibrated && s.constellation);
    assert_eq!(s.last_pose, Some(PoseStatus::TooFewBeacons));
    assert!(s.reports >= 12 && s.northstar.frames >= 12);
    l.call(SensorRequest::SetMode(Mode::Idle)).unwrap();
}

/// A calibration with a magnitude law (the simulated NorthStar's, fitted at sensitivity 4)
/// goes through the wire and the flash, and the near-field poses fit the spot magnitudes
/// while the NorthStar reports that sensitivity: every beacon's (`magnitudes` 10), with an
/// attitude 1-sigma well below the spots' alone (at 10 in the mean over the three axes was
/// 0.06 against 0.25 deg when this test was written). After `SetSensitivity` to another setting the poses are the spots' alone
/// (`magnitudes` 0), and back at 4 the magnitudes are fitted again.
#[test]
fn a_magnitude_law_is_fitted_at_its_sensitivity_only() {
    let (mut ns, t, _) = scene(10.0, 0.0);
    ns.magnitude_noise = 0.07;
    // The magnitude law's readings at 10 in: below saturation at power level 1.
    ns.power_level = 1;
    let sim = SimBoard::spawn(ns).unwrap();
    let mut l = connect(&sim);
    let cal = Calibration {
        magnitude: Some(Magnitude::simulated(0.07)),
        ..Calibration::table3()
    };
    assert_eq!(cal.magnitude.unwrap().sensitivity, 4);
    l.call(SensorRequest::LoadCalibration(cal)).unwrap();
    l.call(SensorRequest::LoadConstellation(cta_constellation()))
        .unwrap();
    match l.call(SensorRequest::GetConfig).unwrap() {
        Some(SensorResponse::Config(c)) => assert_eq!(c.calibration, Some(cal)),
        other => panic!("{other:?}"),
    }
    l.call(SensorRequest::SetMode(Mode::Pose(ModelKind::NearField)))
        .unwrap();
    // The attitude 1-sigma (mean over the axes and the poses) of 6 poses at `sensitivity`,
    // each checked: Ok, all 10 beacons, `magnitudes` fitted, position within 0.1 in.
    let mut at = |sensitivity: u8, magnitudes: u8| -> f64 {
        l.call(SensorRequest::SetSensitivity(sensitivity)).unwrap();
        l.discard_unsolicited();
        let ps = poses(&mut l, 6);
        assert_eq!(ps.len(), 6);
        let mut sigma = 0.0;
        for p in &ps {
            assert_eq!(p.status, PoseStatus::Ok, "{p:?}");
            assert_eq!(p.beacons, 10, "{p:?}");
            assert_eq!(
                p.magnitudes, magnitudes,
                "at sensitivity {sensitivity}: {p:?}"
            );
            let pos = Vector3::new(
                p.position[0] as f64,
                p.position[1] as f64,
                p.position[2] as f64,
            );
            assert!((pos - t).norm() < 0.1, "{p:?}");
            sigma += p.sigma_attitude_deg.iter().map(|&s| s as f64).sum::<f64>() / 18.0;
        }
        sigma
    };
    let with = at(4, 10);
    let without = at(3, 0);
    assert!(
        with < 0.5 * without,
        "attitude 1-sigma {with:.3} deg with the magnitudes, {without:.3} deg without"
    );
    at(4, 10);
    l.call(SensorRequest::SetMode(Mode::Idle)).unwrap();
}

#[test]
fn garbage_on_both_links_is_survived() {
    let (ns, t, _) = scene(20.0, 0.5);
    let sim = SimBoard::spawn(ns).unwrap();
    let mut l = connect(&sim);
    // Line noise from the host side, then normal requests.
    l.port_mut()
        .write_all(&[0x00, 0x13, 0x37, 0xff, 0x00, 0x42, 0x00, 0x99, 0x98])
        .unwrap();
    l.check_board().unwrap();
    l.call(SensorRequest::LoadCalibration(Calibration::table3()))
        .unwrap();
    l.call(SensorRequest::LoadConstellation(cta_constellation()))
        .unwrap();
    l.call(SensorRequest::SetMode(Mode::Pose(ModelKind::NearField)))
        .unwrap();
    // Half the NorthStar frames are preceded by random bytes: poses still arrive.
    let ps = poses(&mut l, 8);
    let ok: Vec<_> = ps.iter().filter(|p| p.status == PoseStatus::Ok).collect();
    assert!(ok.len() >= 6, "{ps:?}");
    for p in ok {
        // At 20 in the near-field pose's noise floor is ~0.05 in.
        assert!((p.position[2] as f64 - t.z).abs() < 0.3, "{p:?}");
    }
    let s = status(&mut l);
    assert!(s.pc.bad() >= 1, "{s:?}");
    assert!(s.northstar.discarded > 0, "{s:?}");
}

/// The lab's whole path on the simulated CTA: a sweep of a head mounted off its nominal place
/// with mismatched cells and pairs (`cta simulate --effect cell_gain=... --effect
/// cell_bias=... --effect face_angle=...`), `cta calibrate`, the calibration loaded into the
/// board, poses solved on the board. The fitted calibration puts the pose on the noise floor;
/// the nominal (Table 3) calibration, which is what the board would hold without the sweep,
/// misses by the mounting error and the cells' and pairs' differences.
#[test]
fn a_calibration_fitted_to_a_sweep_solves_poses() {
    use cta_lab::fit::calibrate::calibrate;
    use cta_lab::sim::SimConfig;
    let truth = Calibration {
        d: [0.55, 0.12, 0.07],
        p: [0.002, -0.001, 0.003],
        near_field: Some(cta_core::pose::NearField {
            gain: [0.02, -0.01],
            bias: [3e-5, -2e-5],
            alpha_y_deg: Some(30.4),
            ..cta_core::pose::NearField::nominal()
        }),
        ..Calibration::table3()
    };
    let f = |a: [f32; 3]| Vector3::new(a[0] as f64, a[1] as f64, a[2] as f64);
    let sweep = SimConfig {
        separations: (1..=15).map(|k| 2.0 * k as f64).chain([25.0]).collect(),
        pose: cta_core::emulator::Pose {
            d: f(truth.d),
            p: f(truth.p),
        },
        effects: vec![
            cta_lab::sim::effects::Effect::CellGain(0.02, -0.01),
            cta_lab::sim::effects::Effect::CellBias(3e-5, -2e-5),
            cta_lab::sim::effects::Effect::FaceAngle(0.0, 0.4),
        ],
        noise: 32.8,
        samples: 4,
        seed: 11,
        ..Default::default()
    };
    let (ds, _) = sweep.try_run().unwrap();
    let rep = calibrate(&ds, &ds, None, None, 1.0).unwrap();
    let fitted = rep.file.calibration;
    assert!(rep.file.fitted.chi2_dof < 1.15, "{:?}", rep.file.fitted);
    let gain = fitted.near_field.unwrap().gain;
    assert!(
        (gain[0] - 0.02).abs() < 3e-4 && (gain[1] + 0.01).abs() < 3e-4,
        "{gain:?}"
    );
    let bias = fitted.near_field.unwrap().bias;
    assert!(
        (bias[0] - 3e-5).abs() < 1e-6 && (bias[1] + 2e-5).abs() < 1e-6,
        "{bias:?}"
    );
    let ay = fitted.near_field.unwrap().alpha_y_deg.unwrap();
    assert!((ay - 30.4).abs() < 0.02, "{ay}");

    let t = Vector3::new(0.2, -0.1, 6.0);
    let q = mrp::from_axis_angle(&Vector3::new(0.2, 0.3, 1.0), 2f64.to_radians());
    let mean_error = |cal: Calibration| -> (f64, f64) {
        let (_sim, mut l) = configured_board(&truth, t, q, cal);
        l.call(SensorRequest::SetMode(Mode::Pose(ModelKind::NearField)))
            .unwrap();
        let ps = poses(&mut l, 12);
        l.call(SensorRequest::SetMode(Mode::Idle)).unwrap();
        let mut pos = Vector3::zeros();
        for p in &ps[2..] {
            assert_eq!(p.status, PoseStatus::Ok, "{p:?}");
            pos += f(p.position) / (ps.len() - 2) as f64;
        }
        let sigma = ps[2..]
            .iter()
            .map(|p| f(p.sigma_position).norm())
            .sum::<f64>()
            / (ps.len() - 2) as f64;
        ((pos - t).norm(), sigma)
    };
    let (err_fitted, sigma) = mean_error(fitted);
    let (err_nominal, _) = mean_error(Calibration::table3());
    // The mean of 10 frames: its noise is a third of one frame's 1-sigma.
    assert!(
        err_fitted < sigma,
        "fitted: {err_fitted} in (1-sigma {sigma})"
    );
    assert!(
        err_nominal > 5.0 * err_fitted && err_nominal > 0.03,
        "nominal {err_nominal} in vs fitted {err_fitted} in"
    );
}

/// The reviewer's case: `cta sensor sim --configured --offset 30,30 --range 3` puts the
/// target out of view, and the simulated NorthStar still reports nine or ten spots whose
/// coordinates all sit a few noise sigmas from the rail (32695..32767, magnitude 0). No
/// pose may be Ok: before the rail margin and the plausibility gate, 4 of its 40 frames were
/// Ok some 5,800 in away with a 1-sigma of 2,000 in.
#[test]
fn an_out_of_view_target_is_never_ok() {
    let scene = cta_lab::pose::head::SimScene {
        offset: [30.0, 30.0],
        range: 3.0,
        ..Default::default()
    };
    let mut ns = scene.northstar();
    ns.rate_hz = 50;
    let sim = SimBoard::spawn(ns).unwrap();
    let mut l = connect(&sim);
    l.call(SensorRequest::LoadCalibration(Calibration::table3()))
        .unwrap();
    l.call(SensorRequest::LoadConstellation(cta_constellation()))
        .unwrap();
    for model in [ModelKind::NearField, ModelKind::Pinhole] {
        l.call(SensorRequest::SetMode(Mode::Pose(model))).unwrap();
        let ps = poses(&mut l, 60);
        l.call(SensorRequest::SetMode(Mode::Idle)).unwrap();
        assert_eq!(ps.len(), 60);
        let ok: Vec<_> = ps.iter().filter(|p| p.status == PoseStatus::Ok).collect();
        assert!(ok.is_empty(), "{model:?}: {} of 60 Ok: {ok:?}", ok.len());
        assert!(ps.iter().all(|p| p.position.iter().all(|v| v.is_finite())));
    }
}

/// `cta calibrate` fits two models and the file holds both head poses: the near-field fit's
/// `d, p` (the head) and, as `pinhole`, the eq 65 fit's own (its eye point, about 1 in above
/// the head: README, "virtual eye"), which the board's pinhole model solves with, with the
/// same fit's `H`. At 12 in its range is then right; with the pinhole head dropped (the file
/// before it held one) the board solved eq 65 from the head with the pinhole's `H`, and read
/// the range about 0.9 in short.
#[test]
fn the_boards_pinhole_pose_uses_the_pinhole_fits_eye() {
    use cta_lab::fit::calibrate::calibrate;
    use cta_lab::sim::SimConfig;
    let sweep = SimConfig {
        separations: (1..=15).map(|k| 2.0 * k as f64).chain([25.0]).collect(),
        noise: 32.8,
        samples: 4,
        seed: 5,
        ..Default::default()
    };
    let (ds, _) = sweep.try_run().unwrap();
    let fitted = calibrate(&ds, &ds, None, None, 1.0)
        .unwrap()
        .file
        .calibration;
    let eye = fitted
        .pinhole
        .expect("calibrate writes the pinhole fit's d, p");
    let truth = Calibration::table3();
    assert!((fitted.d[2] - truth.d[2]).abs() < 0.01, "{fitted:?}");
    assert!(eye.d[2] - fitted.d[2] > 0.8, "{fitted:?}");

    let t = Vector3::new(0.2, -0.1, 12.0);
    let q = mrp::from_axis_angle(&Vector3::new(0.2, 0.3, 1.0), 2f64.to_radians());
    let range = |cal: Calibration| -> f64 {
        let (_sim, mut l) = configured_board(&truth, t, q, cal);
        // Read back as loaded: the pinhole head went through the wire and the flash.
        match l.call(SensorRequest::GetConfig).unwrap() {
            Some(SensorResponse::Config(c)) => assert_eq!(c.calibration, Some(cal)),
            other => panic!("{other:?}"),
        }
        l.call(SensorRequest::SetMode(Mode::Pose(ModelKind::Pinhole)))
            .unwrap();
        let ps = poses(&mut l, 12);
        l.call(SensorRequest::SetMode(Mode::Idle)).unwrap();
        let ok: Vec<_> = ps[2..]
            .iter()
            .filter(|p| p.status == PoseStatus::Ok)
            .collect();
        assert!(ok.len() >= 8, "{ps:?}");
        ok.iter().map(|p| p.position[2] as f64).sum::<f64>() / ok.len() as f64
    };
    let with = range(fitted);
    let without = range(Calibration {
        pinhole: None,
        ..fitted
    });
    eprintln!("range at 12 in: {with:.3} with the pinhole head, {without:.3} without");
    assert!((with - t.z).abs() < 0.1, "with the pinhole head: {with} in");
    assert!(t.z - without > 0.6, "without: {without} in");
}
