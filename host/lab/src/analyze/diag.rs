//! Residual diagnostics: where a fitted model disagrees with the data.
//!
//! Every residual is normalised by its weight, `z = r sqrt(w)`, so a model that explains the
//! data leaves `z` with unit variance everywhere: chi-square per residual ~1 in every bin.
//! The bins: separation, off-boresight angle of the beacon seen from the head, the
//! radial/tangential split of the residual in the (X, Y) output plane (radial = along the
//! predicted output, i.e. away from boresight), the X and Y axes, and the beacon.
//!
//! The angle error (Figure 57's quantity, eq 67 generalised): the direction the fitted model
//! infers from a measured (X, Y), compared with the direction it predicts for the recorded
//! beacon position. For the pinhole model this is eq 67 with the fitted d; for near-field
//! models the direction is found by Newton iteration on the model itself at the beacon's
//! range. Real data has no truth, so this is the model's residual expressed as an angle.

use super::data::Data;
use super::model::Model;
use cta_core::mrp;
use nalgebra::{Matrix2, Vector2, Vector3};
use serde::Serialize;

/// One bin of normalised residuals.
#[derive(Debug, Clone, Serialize)]
pub struct Bin {
    /// What the bin holds.
    pub label: String,
    /// Residual rows.
    pub rows: usize,
    /// Chi-square per residual (1 when the model explains the bin).
    pub chi2_per_row: f64,
    /// Mean normalised residual (a systematic offset shows as |mean| >> 1/sqrt(rows)).
    pub mean_z: f64,
}

#[derive(Default, Clone)]
struct Acc {
    n: usize,
    s2: f64,
    s1: f64,
}
impl Acc {
    fn add(&mut self, z: f64) {
        self.n += 1;
        self.s2 += z * z;
        self.s1 += z;
    }
    fn bin(&self, label: String) -> Bin {
        let n = self.n.max(1) as f64;
        Bin {
            label,
            rows: self.n,
            chi2_per_row: self.s2 / n,
            mean_z: self.s1 / n,
        }
    }
}

/// Residual structure of one fitted model.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnostics {
    /// Chi-square per residual, all data.
    pub chi2_per_row: f64,
    /// By separation.
    pub by_separation: Vec<Bin>,
    /// By off-boresight angle (10 deg bins).
    pub by_angle: Vec<Bin>,
    /// Radial and tangential components.
    pub radial_tangential: Vec<Bin>,
    /// X and Y axes.
    pub by_axis: Vec<Bin>,
    /// The five beacons (grid positions, all separations) with the largest chi-square.
    pub worst_beacons: Vec<Bin>,
}

/// Per-point residuals of a fitted model: (measured - predicted) in counts, and the
/// predicted output.
pub fn residuals(model: &Model, x: &[f64], data: &Data) -> Vec<([f64; 2], [f64; 2])> {
    let all: Vec<usize> = (0..data.points.len()).collect();
    let y = model
        .predict(x, data, &all)
        .unwrap_or_else(|_| vec![[f64::NAN; 2]; all.len()]);
    data.points
        .iter()
        .zip(y)
        .map(|(p, y)| ([p.y[0] - y[0], p.y[1] - y[1]], y))
        .collect()
}

fn off_boresight_deg(model: &Model, x: &[f64], data: &Data, i: usize) -> f64 {
    let p = &data.points[i];
    let d = Vector3::new(x[0], x[1], x[2]);
    let c = mrp::dcm(&Vector3::new(x[3], x[4], x[5]));
    let bore = c.transpose() * Vector3::z();
    let u = model.placement(x, p.sep).beacon(&p.r) - d;
    (u.normalize().dot(&bore))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Diagnose the residuals of `model` at `x`.
pub fn diagnose(model: &Model, x: &[f64], data: &Data) -> Diagnostics {
    let res = residuals(model, x, data);
    let nsep = data.seps.len();
    let mut all = Acc::default();
    let mut sep = vec![Acc::default(); nsep];
    let mut ang = vec![Acc::default(); 8];
    let mut rt = [Acc::default(), Acc::default()];
    let mut axis = [Acc::default(), Acc::default()];
    let mut beacons: std::collections::BTreeMap<(i64, i64), Acc> = Default::default();
    for (i, (p, (r, y))) in data.points.iter().zip(&res).enumerate() {
        if !(r[0].is_finite() && r[1].is_finite()) {
            continue;
        }
        let z = [r[0] * p.w[0].sqrt(), r[1] * p.w[1].sqrt()];
        let a = off_boresight_deg(model, x, data, i);
        let ab = ((a / 10.0) as usize).min(7);
        let key = (
            (p.r.x * 1000.0).round() as i64,
            (p.r.y * 1000.0).round() as i64,
        );
        for (k, &zk) in z.iter().enumerate() {
            all.add(zk);
            sep[p.sep].add(zk);
            ang[ab].add(zk);
            axis[k].add(zk);
            beacons.entry(key).or_default().add(zk);
        }
        let n = (y[0] * y[0] + y[1] * y[1]).sqrt();
        if n > 1.0 {
            let (er, et) = ([y[0] / n, y[1] / n], [-y[1] / n, y[0] / n]);
            rt[0].add(z[0] * er[0] + z[1] * er[1]);
            rt[1].add(z[0] * et[0] + z[1] * et[1]);
        }
    }
    let mut worst: Vec<Bin> = beacons
        .iter()
        .map(|(k, a)| {
            a.bin(format!(
                "beacon at ({}, {}) in",
                k.0 as f64 / 1000.0,
                k.1 as f64 / 1000.0
            ))
        })
        .collect();
    worst.sort_by(|a, b| b.chi2_per_row.total_cmp(&a.chi2_per_row));
    worst.truncate(5);
    Diagnostics {
        chi2_per_row: all.bin(String::new()).chi2_per_row,
        by_separation: sep
            .iter()
            .enumerate()
            .map(|(k, a)| a.bin(format!("{} in", data.seps[k])))
            .collect(),
        by_angle: ang
            .iter()
            .enumerate()
            .filter(|(_, a)| a.n > 0)
            .map(|(k, a)| {
                a.bin(if k == 7 {
                    "70+ deg".to_string()
                } else {
                    format!("{}-{} deg", k * 10, k * 10 + 10)
                })
            })
            .collect(),
        radial_tangential: vec![rt[0].bin("radial".into()), rt[1].bin("tangential".into())],
        by_axis: vec![axis[0].bin("X".into()), axis[1].bin("Y".into())],
        worst_beacons: worst,
    }
}

impl Diagnostics {
    /// Where the structure is, in words: the bins whose chi-square per residual stands out.
    pub fn notes(&self) -> Vec<String> {
        let mut v = Vec::new();
        let base = self.chi2_per_row.max(1.0);
        let hot =
            |b: &Bin| b.chi2_per_row > 1.5 * base.max(1.0) || b.chi2_per_row > 1.5 && b.rows > 0;
        let list = |bins: &[Bin]| -> String {
            let mut s: Vec<&Bin> = bins.iter().filter(|b| hot(b)).collect();
            s.sort_by(|a, b| b.chi2_per_row.total_cmp(&a.chi2_per_row));
            s.iter()
                .take(4)
                .map(|b| format!("{} ({:.1})", b.label, b.chi2_per_row))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let s = list(&self.by_separation);
        if !s.is_empty() {
            v.push(format!("by separation, chi2 per residual highest at: {s}"));
        }
        let s = list(&self.by_angle);
        if !s.is_empty() {
            v.push(format!("by off-boresight angle: {s}"));
        }
        let (r, t) = (&self.radial_tangential[0], &self.radial_tangential[1]);
        if r.chi2_per_row.max(t.chi2_per_row) > 1.5 {
            v.push(format!(
                "radial {:.1} vs tangential {:.1} (mean radial z {:+.2}: {})",
                r.chi2_per_row,
                t.chi2_per_row,
                r.mean_z,
                if r.mean_z > 0.0 {
                    "beacons measured farther off boresight than modelled"
                } else {
                    "beacons measured closer to boresight than modelled"
                }
            ));
        }
        let (x, y) = (&self.by_axis[0], &self.by_axis[1]);
        if x.chi2_per_row.max(y.chi2_per_row) > 1.5 {
            v.push(format!(
                "by axis: X {:.1} (mean z {:+.2}), Y {:.1} (mean z {:+.2})",
                x.chi2_per_row, x.mean_z, y.chi2_per_row, y.mean_z
            ));
        }
        let s = list(&self.worst_beacons);
        if !s.is_empty() {
            v.push(format!("worst beacons: {s}"));
        }
        v
    }
}

/// Angle error (deg) of every point: the direction the model infers from the measured
/// output against the one it predicts (see the module doc). NaN where the model cannot reach
/// the measured output. The predicted direction is to where the model puts the beacon: its
/// plate placed, its LED moved by its offset and its array by its pose.
pub fn angle_errors(model: &Model, x: &[f64], data: &Data) -> Vec<f64> {
    let d = Vector3::new(x[0], x[1], x[2]);
    let view = model.view(x);
    inferred_directions(model, x, data)
        .iter()
        .zip(&data.points)
        .map(|(dir, p)| match dir {
            Some(v) => angle_deg(v, &(view.beacon(p) - d)),
            None => f64::NAN,
        })
        .collect()
}

/// Angle between two vectors, deg (atan2 of the cross and dot products: accurate at small
/// angles, where acos is not).
pub fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.cross(b).norm().atan2(a.dot(b)).to_degrees()
}

/// The beacon direction the model infers from every point's measured output: a unit vector
/// in the CTA frame from the model's head, found by Newton iteration on the model at the
/// beacon's range in the tangent plane of the predicted direction (for the pinhole model
/// this is eq 67). None where the model cannot reach the measured output.
pub fn inferred_directions(model: &Model, x: &[f64], data: &Data) -> Vec<Option<Vector3<f64>>> {
    let view = model.view(x);
    let d = Vector3::new(x[0], x[1], x[2]);
    data.points
        .iter()
        .map(|p| {
            // The LED's own boresight (`led_tilt`) turned on top of the plate's.
            let v = view.led_vals(p);
            let em = crate::sim::led_emulator(view.emulator(p.sep), [v[2], v[3]]);
            let u = view.beacon(p) - d;
            let len = u.norm();
            let un = u / len;
            let helper = if un.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let e1 = un.cross(&helper).normalize();
            let e2 = un.cross(&e1);
            let dir = |t: &Vector2<f64>| (un + e1 * t.x + e2 * t.y).normalize();
            let at = |t: &Vector2<f64>| -> Option<Vector2<f64>> {
                em.output(&(d + dir(t) * len))
                    .map(|o| Vector2::new(o[0], o[1]))
            };
            let meas = Vector2::new(p.y[0], p.y[1]);
            let mut t = Vector2::zeros();
            let h = 1e-6;
            for _ in 0..6 {
                let (y0, y1, y2) = (
                    at(&t)?,
                    at(&(t + Vector2::new(h, 0.0)))?,
                    at(&(t + Vector2::new(0.0, h)))?,
                );
                let j = Matrix2::from_columns(&[(y1 - y0) / h, (y2 - y0) / h]);
                let step = j.try_inverse()? * (meas - y0);
                // Keep Newton inside a sane neighbourhood (0.5 rad).
                let n = step.norm();
                t += if n > 0.5 { step * (0.5 / n) } else { step };
                if n < 1e-12 {
                    break;
                }
            }
            Some(dir(&t))
        })
        .collect()
}

/// Standard deviation over the beacons of each separation of the angle errors (Figure 57's
/// statistic: the spread of the error magnitudes).
pub fn angle_std_by_sep(errors: &[f64], data: &Data) -> Vec<f64> {
    let nsep = data.seps.len();
    let mut v = vec![Vec::new(); nsep];
    for (p, &e) in data.points.iter().zip(errors) {
        if e.is_finite() {
            v[p.sep].push(e);
        }
    }
    v.iter()
        .map(|e| {
            if e.len() < 2 {
                return f64::NAN;
            }
            let n = e.len() as f64;
            let m = e.iter().sum::<f64>() / n;
            (e.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        })
        .collect()
}
