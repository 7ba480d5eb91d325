//! The reported parameters of causes and candidates: values, 1-sigma and correlations by the
//! delta method (`J P J^T` through the fitted covariance `P`, eq 59), and the spread of
//! per-separation corrections.

use nalgebra::DMatrix;

use super::model::{Cand, FitResult, Model};
use super::result::{
    Correlation, Param, ParamMap, SepSpread, BASE_CORRELATION_MIN, CORRELATION_MIN,
};

/// The parameters of the fit `f` of `model` with their 1-sigma: the global ones only when
/// `globals_only`, else with every per-separation one (named by `seps`).
pub(super) fn params_of(
    model: &Model,
    f: &FitResult,
    seps: &[f64],
    globals_only: bool,
) -> Vec<Param> {
    let names = model.names(seps);
    let n = if globals_only {
        model.n_global_params()
    } else {
        names.len()
    };
    (0..n)
        .map(|i| Param {
            name: names[i].clone(),
            value: f.x[i],
            sigma: f.sigma[i],
            no_effect: None,
        })
        .collect()
}

/// Quantities derived from effect `c`'s global parameters in the fit `f` of `model`, with
/// their covariance by the delta method (numerical gradient of the quantities through the
/// fitted covariance of those parameters, `J P J^T`), and their covariance with the starting
/// model's parameters from the same fit (no second fit).
pub(super) struct Propagated<'n> {
    /// Name, value and 1-sigma of each quantity.
    q: Vec<(&'n str, f64, f64)>,
    /// Their covariance.
    pub(super) cov: DMatrix<f64>,
    /// How many fitted parameters they derive from (fewer than 2: any correlation between
    /// them is the identity of one parameter, e.g. `beacon_pattern`'s H_deg and m).
    raw: usize,
    /// Each free parameter of the starting model: name, variance, covariance with each
    /// quantity.
    base: Vec<(&'static str, f64, Vec<f64>)>,
}

/// Correlation coefficient from a covariance and two variances; None when a variance is not
/// positive and finite.
fn rho(cov: f64, var_a: f64, var_b: f64) -> Option<f64> {
    let d = var_a * var_b;
    let r = cov / d.sqrt();
    (d > 0.0 && d.is_finite() && r.is_finite()).then(|| r.clamp(-1.0, 1.0))
}

impl Propagated<'_> {
    /// Every pair of the quantities whose correlation is at least [`CORRELATION_MIN`] in
    /// magnitude, in the order of the quantities.
    pub(super) fn correlations(&self) -> Vec<Correlation> {
        let n = self.q.len();
        let mut out = Vec::new();
        if self.raw < 2 {
            return out;
        }
        for i in 0..n {
            for j in i + 1..n {
                let Some(r) = rho(self.cov[(i, j)], self.cov[(i, i)], self.cov[(j, j)]) else {
                    continue;
                };
                if r.abs() >= CORRELATION_MIN {
                    out.push(Correlation {
                        a: self.q[i].0.into(),
                        b: self.q[j].0.into(),
                        rho: r,
                    });
                }
            }
        }
        out
    }

    /// Every (quantity, starting-model parameter) pair whose correlation is at least
    /// [`BASE_CORRELATION_MIN`] in magnitude. With one underlying parameter
    /// (`beacon_pattern`'s H_deg and m) the quantities are transforms of it: only the first is
    /// listed.
    pub(super) fn base_correlations(&self) -> Vec<Correlation> {
        let mut out = Vec::new();
        let shown = if self.raw < 2 { 1 } else { self.q.len() };
        for (i, q) in self.q.iter().enumerate().take(shown) {
            for (name, var, cross) in &self.base {
                let Some(r) = rho(cross[i], self.cov[(i, i)], *var) else {
                    continue;
                };
                if r.abs() >= BASE_CORRELATION_MIN {
                    out.push(Correlation {
                        a: q.0.into(),
                        b: (*name).into(),
                        rho: r,
                    });
                }
            }
        }
        out
    }
}

/// Quantities `rep` of effect `c`'s global parameters in the fit `f` of `model`: each name and
/// value, the gradient of each with respect to the fit's free parameters (one row per
/// quantity, in the order of `f.cov`; numerical, zero for parameters held fixed), and how many
/// fitted parameters they derive from.
fn gradients<'n>(
    model: &Model,
    c: Cand,
    f: &FitResult,
    rep: impl Fn(&[f64]) -> Vec<(&'n str, f64)>,
) -> (Vec<(&'n str, f64)>, DMatrix<f64>, usize) {
    let idx: Vec<usize> = model.global_indices(c).collect();
    let v: Vec<f64> = idx.iter().map(|&i| f.x[i]).collect();
    let values = rep(&v);
    let mut g = DMatrix::zeros(values.len(), f.free.len());
    for (j, &i) in idx.iter().enumerate() {
        // Where the parameter sits in the covariance of the free parameters.
        let Some(pj) = f.free.iter().position(|&fi| fi == i) else {
            continue;
        };
        let h = 1e-7 * (1.0 + v[j].abs());
        let mut vp = v.clone();
        vp[j] += h;
        let moved = rep(&vp);
        for (k, &(_, val)) in values.iter().enumerate() {
            g[(k, pj)] = (moved[k].1 - val) / h;
        }
    }
    (values, g, v.len())
}

/// Quantities `rep` of effect `c`'s global parameters in the fit `f` of `model`, propagated
/// by the delta method ([`Propagated`]).
pub(super) fn delta_method<'n>(
    model: &Model,
    c: Cand,
    f: &FitResult,
    rep: impl Fn(&[f64]) -> Vec<(&'n str, f64)>,
) -> Propagated<'n> {
    let (values, g, raw) = gradients(model, c, f, rep);
    // Covariance of the quantities with every free parameter (J P), and between them.
    let gp = &g * &f.cov;
    let cov = &gp * g.transpose();
    let q = values
        .iter()
        .enumerate()
        .map(|(k, &(name, val))| (name, val, cov[(k, k)].max(0.0).sqrt()))
        .collect();
    let base = model
        .base
        .names()
        .iter()
        .enumerate()
        .filter_map(|(i, &name)| {
            let pb = f.free.iter().position(|&j| j == i)?;
            Some((
                name,
                f.cov[(pb, pb)],
                gp.column(pb).iter().copied().collect(),
            ))
        })
        .collect();
    Propagated { q, cov, raw, base }
}

/// Correlations between the reported global quantities ([`Cand::report`]) of two different
/// effects of `model`, in the order of `effects`, from the one fit `f` (delta method, as
/// [`delta_method`]), at least [`BASE_CORRELATION_MIN`] in magnitude. Names are qualified by
/// effect (`proximity.S`); `a` is the earlier effect's. An effect whose quantities derive from
/// one fitted parameter (`beacon_pattern`'s H_deg and m) contributes its first only;
/// per-separation parameters are not included.
pub(super) fn cross_correlations(
    model: &Model,
    f: &FitResult,
    effects: &[Cand],
) -> Vec<Correlation> {
    /// One effect's quantities: qualified names, gradient rows (J) and J P.
    struct Quantities {
        names: Vec<String>,
        g: DMatrix<f64>,
        gp: DMatrix<f64>,
    }
    impl Quantities {
        fn var(&self, k: usize) -> f64 {
            self.gp.row(k).dot(&self.g.row(k))
        }
    }
    let per: Vec<Quantities> = effects
        .iter()
        .map(|&c| {
            let (values, g, raw) = gradients(model, c, f, |v| c.report(model.base, v));
            let shown = if raw < 2 {
                values.len().min(1)
            } else {
                values.len()
            };
            let g = g.rows(0, shown).into_owned();
            Quantities {
                names: values
                    .iter()
                    .take(shown)
                    .map(|(n, _)| format!("{}.{n}", c.name()))
                    .collect(),
                gp: &g * &f.cov,
                g,
            }
        })
        .collect();
    let mut out = Vec::new();
    for (i, a) in per.iter().enumerate() {
        for b in &per[i + 1..] {
            for (k, na) in a.names.iter().enumerate() {
                for (l, nb) in b.names.iter().enumerate() {
                    let cov = a.gp.row(k).dot(&b.g.row(l));
                    let Some(r) = rho(cov, a.var(k), b.var(l)) else {
                        continue;
                    };
                    if r.abs() >= BASE_CORRELATION_MIN {
                        out.push(Correlation {
                            a: na.clone(),
                            b: nb.clone(),
                            rho: r,
                        });
                    }
                }
            }
        }
    }
    out
}

/// The reported parameters of a cause: values, 1-sigma, correlations between them and with
/// the starting model.
pub(super) type CauseParams = (ParamMap, ParamMap, Vec<Correlation>, Vec<Correlation>);

/// The reported parameters of `c` in the fit `f` of `model`, with 1-sigma and correlations by
/// the delta method (numerical gradient of the reported quantities through the fitted
/// covariance). In the model's order: the reported global quantities as [`Cand::report`]
/// lists them, then (per-separation effects) `rms_in` and every `x@2in`, separation by
/// separation.
pub(super) fn cause_params(model: &Model, c: Cand, f: &FitResult, seps: &[f64]) -> CauseParams {
    let mut p = ParamMap::default();
    let mut s = ParamMap::default();
    let prop = delta_method(model, c, f, |v| c.report(model.base, v));
    for &(name, val, sg) in &prop.q {
        p.insert(name, val);
        s.insert(name, sg);
    }
    if !c.local_names().is_empty() {
        // name, value, 1-sigma of every per-separation parameter, separation by separation.
        let locals: Vec<(String, f64, f64)> = seps
            .iter()
            .enumerate()
            .flat_map(|(k, sep)| {
                model
                    .local_indices(c, k)
                    .zip(c.local_names())
                    .map(move |(i, n)| (format!("{n}@{sep}in"), f.x[i], f.sigma[i]))
            })
            .collect();
        let sumsq: f64 = locals.iter().map(|l| l.1 * l.1).sum();
        p.insert(
            c.local_rms_name(),
            (sumsq / locals.len().max(1) as f64).sqrt(),
        );
        for (name, val, sg) in locals {
            p.insert(name.clone(), val);
            s.insert(name, sg);
        }
    }
    for (name, i) in led_values(model, c) {
        p.insert(name.clone(), f.x[i]);
        s.insert(name, f.sigma[i]);
    }
    (p, s, prop.correlations(), prop.base_correlations())
}

/// Each per-LED parameter of `c` in `model` as (`dx@bID`, index), LED by LED, then the
/// per-array ones.
fn led_values(model: &Model, c: Cand) -> Vec<(String, usize)> {
    let own = c.global_names(model.base).len();
    let start = model.global_indices(c).start + own;
    let w = c.led_names().len();
    model
        .leds
        .iter()
        .enumerate()
        .filter(|_| w > 0)
        .flat_map(|(k, l)| {
            c.led_names()
                .iter()
                .enumerate()
                .map(move |(j, n)| (format!("{n}@b{}", l.id), start + k * w + j))
        })
        .chain(array_values(model, c))
        .collect()
}

/// Each per-array parameter of `c` in `model` as (`dx@aN`, index), array by array.
fn array_values(model: &Model, c: Cand) -> Vec<(String, usize)> {
    let start = model.global_indices(c).start
        + c.global_names(model.base).len()
        + c.led_names().len() * model.leds.len();
    let w = c.array_names().len();
    model
        .arrays
        .iter()
        .enumerate()
        .filter(|_| w > 0)
        .flat_map(|(k, a)| {
            c.array_names()
                .iter()
                .enumerate()
                .map(move |(j, n)| (format!("{n}@a{}", a.id), start + k * w + j))
        })
        .collect()
}

/// The parameters of candidate `c` in its trial fit `f` of `model` (the round's model plus
/// `c`), as [`Cand::trial_report`] gives them (smooth through the no-effect value, which each
/// carries), 1-sigma by the delta method; then every per-separation value (`x@2in`, no-effect
/// value 0). With the correlations between the global ones, and of those with the starting
/// model.
pub(super) fn trial_params(
    model: &Model,
    c: Cand,
    f: &FitResult,
    seps: &[f64],
) -> (Vec<Param>, Vec<Correlation>, Vec<Correlation>) {
    let idx: Vec<usize> = model.global_indices(c).collect();
    let v: Vec<f64> = idx.iter().map(|&i| f.x[i]).collect();
    let nulls: Vec<Option<f64>> = c.trial_report(model.base, &v).iter().map(|r| r.2).collect();
    let rep = |v: &[f64]| {
        c.trial_report(model.base, v)
            .into_iter()
            .map(|(n, x, _)| (n, x))
            .collect::<Vec<_>>()
    };
    let prop = delta_method(model, c, f, rep);
    let mut out: Vec<Param> = prop
        .q
        .iter()
        .zip(nulls)
        .map(|(&(name, value, sigma), no_effect)| Param {
            name: name.into(),
            value,
            sigma,
            no_effect,
        })
        .collect();
    for (k, sep) in seps.iter().enumerate() {
        for (j, i) in model.local_indices(c, k).enumerate() {
            out.push(Param {
                name: format!("{}@{}in", c.local_names()[j], sep),
                value: f.x[i],
                sigma: f.sigma[i],
                no_effect: Some(0.0),
            });
        }
    }
    for (name, i) in led_values(model, c) {
        out.push(Param {
            name,
            value: f.x[i],
            sigma: f.sigma[i],
            no_effect: Some(0.0),
        });
    }
    (out, prop.correlations(), prop.base_correlations())
}

/// The spread of per-separation values `NAME@SEPin` in `params`, per name, in order of first
/// appearance: the inverse-variance weighted RMS of the estimates and the value noise alone
/// would give it (values without a positive 1-sigma are skipped).
pub fn spreads(params: &[Param]) -> Vec<SepSpread> {
    // name, sum of x^2 / sigma^2, sum of 1 / sigma^2, count.
    let mut out: Vec<(String, f64, f64, usize)> = Vec::new();
    for p in params {
        let Some((name, _)) = p.name.split_once('@') else {
            continue;
        };
        if !(p.sigma > 0.0 && p.sigma.is_finite()) {
            continue;
        }
        let e = match out.iter().position(|o| o.0 == name) {
            Some(k) => &mut out[k],
            None => {
                out.push((name.to_string(), 0.0, 0.0, 0));
                out.last_mut().expect("just pushed")
            }
        };
        let w = 1.0 / (p.sigma * p.sigma);
        e.1 += w * p.value * p.value;
        e.2 += w;
        e.3 += 1;
    }
    out.into_iter()
        .map(|(name, swx2, sw, n)| SepSpread {
            name,
            rms: (swx2 / sw).sqrt(),
            noise_rms: (n as f64 / sw).sqrt(),
            separations: n,
        })
        .collect()
}
