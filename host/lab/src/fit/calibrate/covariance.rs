//! The near-field fit's full parameter covariance, kept in the calibration file
//! (`fitted.covariance`) for whatever uses the calibration downstream (a filter that weighs the
//! head's calibration against its measurements needs the correlations, not the 1-sigma alone:
//! `a` and `ay`, or `d3` and `s`, are known far better together than each alone).

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::fit::nearfield::NF_NAMES;

/// Each near-field parameter's unit, in the order of [`NF_NAMES`].
pub const NF_UNITS: [&str; 13] = [
    "in", "in", "in", "", "", "", "deg", "in", "", "", "1/in^2", "1/in^2", "deg",
];

/// A covariance matrix with its parameters' names and units (row-major, symmetric).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Covariance {
    /// The parameters, in the order of the rows and columns (those of `fitted.sigma`).
    pub parameters: Vec<String>,
    /// Each parameter's unit (empty: none; the MRPs `p` and the gains are pure numbers).
    pub units: Vec<String>,
    /// The matrix, one row per parameter; entry (i, j) in the units of i times those of j.
    pub matrix: Vec<Vec<f64>>,
}

impl Covariance {
    /// The covariance of the first `cov.nrows()` parameters of [`NF_NAMES`], the near-field
    /// fit's (8 without the extended parameters, all 13 with them).
    pub fn near_field(cov: &nalgebra::DMatrix<f64>) -> Covariance {
        let n = cov.nrows().min(NF_NAMES.len());
        Covariance {
            parameters: NF_NAMES[..n].iter().map(|s| s.to_string()).collect(),
            units: NF_UNITS[..n].iter().map(|s| s.to_string()).collect(),
            matrix: (0..n)
                .map(|i| (0..n).map(|j| cov[(i, j)]).collect())
                .collect(),
        }
    }

    /// Check the matrix as read from a file: one name and unit per row, no name twice, square,
    /// finite, symmetric (to 1e-9 of the diagonal's scale), variances not negative, and each
    /// variance the square of the parameter's 1-sigma in `sigma` where that has it (to 1e-6).
    /// The error names the entry at fault.
    pub fn check(&self, sigma: &BTreeMap<String, f64>) -> Result<(), String> {
        let n = self.parameters.len();
        if n == 0 || self.units.len() != n || self.matrix.len() != n {
            return Err(format!(
                "{n} parameters, {} units and {} rows: one of each per parameter",
                self.units.len(),
                self.matrix.len()
            ));
        }
        for (i, p) in self.parameters.iter().enumerate() {
            if self.parameters[..i].contains(p) {
                return Err(format!("parameter `{p}` named twice"));
            }
        }
        for (i, row) in self.matrix.iter().enumerate() {
            if row.len() != n {
                return Err(format!(
                    "row {i} (`{}`) has {} entries, not {n}",
                    self.parameters[i],
                    row.len()
                ));
            }
            if let Some(j) = row.iter().position(|v| !v.is_finite()) {
                return Err(format!(
                    "entry ({}, {}) is not a finite number",
                    self.parameters[i], self.parameters[j]
                ));
            }
        }
        for i in 0..n {
            let v = self.matrix[i][i];
            if v < 0.0 {
                return Err(format!(
                    "the variance of `{}` is negative ({v})",
                    self.parameters[i]
                ));
            }
            for j in 0..i {
                let (a, b) = (self.matrix[i][j], self.matrix[j][i]);
                let scale = (self.matrix[i][i] * self.matrix[j][j])
                    .sqrt()
                    .max(f64::MIN_POSITIVE);
                if (a - b).abs() > 1e-9 * scale {
                    return Err(format!(
                        "not symmetric: ({}, {}) = {a} but ({}, {}) = {b}",
                        self.parameters[i],
                        self.parameters[j],
                        self.parameters[j],
                        self.parameters[i]
                    ));
                }
            }
            if let Some(s) = sigma.get(&self.parameters[i]) {
                if (v.sqrt() - s).abs() > 1e-6 * s.max(f64::MIN_POSITIVE) {
                    return Err(format!(
                        "the variance of `{}` is {v}, but its 1-sigma in `sigma` is {s} (variance {})",
                        self.parameters[i],
                        s * s
                    ));
                }
            }
        }
        Ok(())
    }

    /// The 1-sigma of parameter `name`, when the matrix has it.
    pub fn sigma(&self, name: &str) -> Option<f64> {
        let i = self.parameters.iter().position(|p| p == name)?;
        Some(self.matrix[i][i].sqrt())
    }

    /// The correlation of parameters `a` and `b`, when the matrix has both and neither has
    /// zero variance.
    pub fn correlation(&self, a: &str, b: &str) -> Option<f64> {
        let i = self.parameters.iter().position(|p| p == a)?;
        let j = self.parameters.iter().position(|p| p == b)?;
        let d = (self.matrix[i][i] * self.matrix[j][j]).sqrt();
        (d > 0.0).then(|| self.matrix[i][j] / d)
    }
}

/// The covariance of the calibration file at `path` (`fitted.covariance`), checked against the
/// file's `fitted.sigma`: `None` for a file without one (written before it was kept, or not
/// by `cta calibrate`), an error naming the file and the entry for one that does not hold.
pub fn read(path: &Path) -> Result<Option<Covariance>, String> {
    let text = crate::bounded::read_text(path, crate::bounded::MAX_JSON_BYTES, "a JSON file")
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let Some(c) = v.get("fitted").and_then(|f| f.get("covariance")) else {
        return Ok(None);
    };
    let cov: Covariance = serde_json::from_value(c.clone())
        .map_err(|e| format!("{}: field `fitted.covariance`: {e}", path.display()))?;
    let sigma: BTreeMap<String, f64> = v["fitted"]
        .get("sigma")
        .and_then(|s| serde_json::from_value(s.clone()).ok())
        .unwrap_or_default();
    cov.check(&sigma)
        .map_err(|e| format!("{}: field `fitted.covariance`: {e}", path.display()))?;
    Ok(Some(cov))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A matrix that does not hold is refused naming the entry; a good one gives its 1-sigma
    /// and correlations with their sign.
    #[test]
    fn a_covariance_is_checked_and_read() {
        let mut m = nalgebra::DMatrix::<f64>::identity(8, 8) * 1e-4;
        m[(0, 0)] = 4e-4;
        m[(0, 3)] = -0.9 * 2e-2 * 1e-2;
        m[(3, 0)] = m[(0, 3)];
        let c = Covariance::near_field(&m);
        assert_eq!(c.parameters, ["d1", "d2", "d3", "p1", "p2", "p3", "a", "s"]);
        assert_eq!(c.units[0], "in");
        assert_eq!(c.units[6], "deg");
        let sigma: BTreeMap<String, f64> = [("d1".to_string(), 0.02), ("s".into(), 0.01)].into();
        c.check(&sigma).unwrap();
        assert_eq!(c.sigma("d1"), Some(0.02));
        assert!((c.correlation("d1", "p1").unwrap() + 0.9).abs() < 1e-12);
        assert!(c.correlation("d1", "ay").is_none());
        let bad = |f: &dyn Fn(&mut Covariance)| {
            let mut b = c.clone();
            f(&mut b);
            b.check(&sigma).unwrap_err()
        };
        assert!(bad(&|b| b.matrix[3][0] = 0.0).starts_with("not symmetric: (p1, d1)"));
        assert!(bad(&|b| b.matrix[0][0] = 1e-4)
            .contains("`d1` is 0.0001, but its 1-sigma in `sigma` is 0.02"));
        assert!(
            bad(&|b| b.matrix[2].pop().map(|_| ()).unwrap()).contains("row 2 (`d3`) has 7 entries")
        );
        assert!(bad(&|b| b.parameters[1] = "d1".into()).contains("`d1` named twice"));
        assert!(bad(&|b| b.matrix[1][1] = f64::NAN).contains("(d2, d2) is not a finite"));
        assert!(bad(&|b| b.units.pop().map(|_| ()).unwrap()).contains("8 parameters, 7 units"));
    }
}
