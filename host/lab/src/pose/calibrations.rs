//! The calibrations the pose analyses and the simulated boards solve with, fitted to
//! simulated CTA sweeps as the lab would fit them to measured ones: the pinhole (eq 65), the
//! near-field (eqs 60-63) and the spot magnitude law; and the random poses and attitude
//! errors the tables are made of.

use cta_core::collinearity::{self, Fit, Obs as FitObs, Params, ParamsExt};
use cta_core::emulator::{Head, Pose as HeadPose};
use cta_core::glsdc::{self, Settings};
use cta_core::mrp;
use cta_core::pose::{Calibration, Magnitude, PinholeHead};
use cta_core::real::rad;
use nalgebra::Vector3;
use rand::rngs::StdRng;
use rand::Rng;
use rand_distr::{Distribution, Normal};

use crate::pose::error::Error;
use crate::pose::plate::Plate;

/// The calibration the simulated boards start with (`--sim`, `sensor sim --configured`; the
/// calibration template is it without `pinhole`): the Table 3 truth head and the nominal
/// near-field parameters the simulated NorthStar has, with the pinhole model's own eye point
/// `d, p` and its `H` from [`pinhole_calibration`] on the CTA grid, as `cta calibrate` writes
/// them (with the true head's `d, p` the pinhole pose would read ranges short). It holds the
/// simulated NorthStar's spot magnitude law (linear, the scatter `magnitude_noise` percent it
/// simulates; the validation's floor, 0.001 %, for none), so that its poses fit the
/// magnitudes as a calibrated board's would.
pub fn sim_calibration(magnitude_noise: f64) -> Result<Calibration, Error> {
    let mut cal = Calibration::table3();
    let ph = pinhole_calibration(&cal, Plate::One)?;
    cal.h = ph.h;
    cal.pinhole = Some(PinholeHead { d: ph.d, p: ph.p });
    cal.magnitude = Some(Magnitude::simulated(magnitude_noise.max(0.001) as f32));
    Ok(cal)
}

/// The 7-parameter pinhole calibration fitted (GLSDC, eq 65) to noise-free eq 63 data of
/// every LED of `plate` at 25 and 30 in (Ch VI's recommended procedure, from Table 3; for the
/// one-array plate, the thesis's own 10 x 10 grid).
pub fn pinhole_calibration(truth: &Calibration, plate: Plate) -> Result<Calibration, Error> {
    let em = cta_firmware_sensor::sim::physics(truth);
    let mut obs = Vec::new();
    for sep in [25.0, 30.0] {
        for r in plate.positions(sep) {
            if let Some(y) = em.output(&r) {
                obs.push(FitObs { r, y, w: [1.0; 2] });
            }
        }
    }
    let head = Head::<f64>::northstar();
    let x0 = Params::from_pose(
        &HeadPose {
            d: Vector3::zeros(),
            p: Vector3::zeros(),
        },
        head.h(),
    );
    let sol = glsdc::solve(&Fit { obs: &obs }, x0, &Settings::default())
        .map_err(|e| Error::PinholeFit(format!("{e:?}")))?;
    let x = sol.x;
    Ok(Calibration {
        d: [x[0] as f32, x[1] as f32, x[2] as f32],
        p: [x[3] as f32, x[4] as f32, x[5] as f32],
        h: collinearity::ParamsExt::h(&x) as f32,
        noise: truth.noise,
        near_field: None,
        pinhole: None,
        magnitude: None,
    })
}

/// The near-field calibration the lab would load: `d`, `p`, the face angle `a` and the
/// cell offset `s` of the eq 60-63 model fitted (GLSDC, finite-difference Jacobian) to a
/// simulated CTA sweep of `truth`'s physics: every LED of `plate` at 2, 3, ..., 30 in (Ch
/// VI's 1 in steps), each point the mean of `samples` noisy samples. The start is the pinhole
/// calibration's `d, p` and the nominal `a, s` (REFERENCE.md: start from the 7-parameter fit
/// to avoid false minima). Returns the calibration and its fitted 1-sigma (d1..3, p1..3, a
/// in degrees, s).
pub fn nearfield_calibration(
    truth: &Calibration,
    start: &Calibration,
    plate: Plate,
    samples: usize,
    rng: &mut StdRng,
) -> Result<(Calibration, [f64; 8]), Error> {
    let em = cta_firmware_sensor::sim::physics(truth);
    let sigma = truth.noise as f64 / (samples.max(1) as f64).sqrt();
    let normal = Normal::new(0.0, sigma).map_err(|error| Error::Noise {
        what: "noise",
        error,
    })?;
    let mut obs = Vec::new();
    for sep in 2..=30 {
        for r in plate.positions(sep as f64) {
            if let Some(y) = em.output(&r) {
                // Points the NorthStar would report unsaturated.
                if y.iter().all(|v| v.abs() < 32000.0) {
                    obs.push((r, [y[0] + normal.sample(rng), y[1] + normal.sample(rng)]));
                }
            }
        }
    }
    let w = 1.0 / (sigma * sigma);
    let obs: Vec<crate::fit::calibrate::NfObs> = obs
        .into_iter()
        .map(|(r, y)| crate::fit::calibrate::NfObs { r, y, w: [w; 2] })
        .collect();
    let start = Calibration {
        noise: truth.noise,
        ..*start
    };
    let sol = crate::fit::calibrate::fit_near_field(&obs, &start, false)
        .map_err(|e| Error::NearFieldFit(format!("{e:#}")))?;
    let mut sigma = [0.0; 8];
    sigma.copy_from_slice(&sol.sigma[..8]);
    Ok((sol.calibration, sigma))
}

/// The spot magnitude law the lab would load with the near-field calibration: `cta
/// calibrate`'s fit ([`crate::fit::magnitude::fit_dataset`], with the fitted head's summed cell
/// signal) to the magnitudes of a simulated CTA sweep of `truth`'s physics, as the simulated
/// NorthStar reports them (`cta_core::pose::simulate_spots_with`: `SIM_MAGNITUDE_SCALE` times
/// the signal, `noise_percent` of scatter, rounded to counts and saturated at 65535): every
/// LED of `plate` at 2, 3, ..., 30 in, `samples` readings each. Returns the fit's report.
pub fn magnitude_calibration(
    truth: &Calibration,
    fitted: &Calibration,
    plate: Plate,
    samples: usize,
    noise_percent: f64,
    rng: &mut StdRng,
) -> Result<crate::fit::magnitude::MagnitudeReport, Error> {
    let em = cta_firmware_sensor::sim::physics(truth);
    let normal = Normal::new(0.0, noise_percent / 100.0).map_err(|error| Error::Noise {
        what: "magnitude noise",
        error,
    })?;
    let scale = cta_core::pose::SIM_MAGNITUDE_SCALE;
    let mut ds = crate::data::Dataset::default();
    for sep in 2..=30 {
        for (i, r) in plate.positions(sep as f64).into_iter().enumerate() {
            let Some(y) = em.output(&r) else { continue };
            let m = em.magnitude(&r) * scale;
            for k in 0..samples {
                ds.samples.push(crate::data::Sample {
                    separation_in: sep as f64,
                    r: r.into(),
                    x: y[0].round().clamp(-32768.0, 32767.0),
                    y: y[1].round().clamp(-32768.0, 32767.0),
                    beacon: Some(i as u32),
                    sample: Some(k as u32),
                    magnitude: Some((m * (1.0 + normal.sample(rng))).round().clamp(0.0, 65535.0)),
                    ..Default::default()
                });
            }
        }
    }
    let head = cta_firmware_sensor::sim::physics(fitted);
    match crate::fit::magnitude::fit_dataset(&ds, &head, Some(4))
        .map_err(|e| Error::MagnitudeFit(format!("{e:#}")))?
    {
        crate::fit::magnitude::Outcome::Law(report) => Ok(*report),
        crate::fit::magnitude::Outcome::NoLaw(why) => Err(Error::NoMagnitudeLaw(why)),
    }
}

/// Angle of the rotation between two attitudes (MRPs), degrees.
pub fn angle_between_deg(q_est: &Vector3<f64>, q_true: &Vector3<f64>) -> f64 {
    let err = mrp::dcm(q_est) * mrp::dcm(q_true).transpose();
    mrp::angle(&mrp::from_dcm(&err)).to_degrees()
}

/// A pose of the accuracy table's distribution at `range`: lateral offset uniform in
/// +/-0.5 in, rotation uniform in 0-3 deg about a random axis. Returns `(t, MRP)`.
pub fn random_pose(rng: &mut StdRng, range: f64) -> (Vector3<f64>, Vector3<f64>) {
    let t = Vector3::new(
        rng.random_range(-0.5..0.5),
        rng.random_range(-0.5..0.5),
        range,
    );
    let axis = Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    (
        t,
        mrp::from_axis_angle(&axis, rad(rng.random_range(0.0..3.0))),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pinhole_calibration_reproduces_table3_far_pair() {
        let c = pinhole_calibration(&Calibration::table3(), Plate::One).unwrap();
        // REFERENCE.md Table 3, (25, 30) in: d3 = +1.1378, H = 19016.
        assert!((c.d[2] - 1.1378).abs() < 0.03, "{c:?}");
        assert!((c.h - 19016.0).abs() / 19016.0 < 0.003, "{c:?}");
    }
}
