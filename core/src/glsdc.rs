//! Gaussian Least Squares Differential Correction (GLSDC), thesis eqs 56-59, generic over
//! the model.
//!
//! Minimises `J = 1/2 (dy - G dx)^T W (dy - G dx)` (eq 56) by repeating the normal-equation
//! step `dx = P G^T W dy`, `P = (G^T W G)^-1` (eqs 57, 58) and `x <- x + dx` (eq 59), with:
//! - a diagonal weighting `W` given per residual row (eq 56's `W`);
//! - the normal equations accumulated row by row, so a problem never stores its Jacobian
//!   (20,000 residuals cost 7x7 memory; on the chip, 6x6);
//! - Jacobi column scaling (so millimetres, milliradians and counts-per-unit parameters mix);
//! - a damped (Levenberg) step whenever a Gauss-Newton step raises the cost, and damping
//!   kept or raised while accepted steps gain much less than they predict (the gain ratio
//!   rule of Fletcher, 1971: below 1/4 more damping, above 3/4 less);
//! - stopping on a small step, a small cost change, or an iteration cap;
//! - optionally ([`solve_with`]), the last linearisation carried to the next solve of a
//!   tracked problem, for a first step that costs no model evaluation (the residuals at
//!   the start predicted from it) or a residual pass only;
//! - the covariance `P = (G^T W G)^-1`, scaled by the residual variance
//!   `sum w r^2 / (m - n)` unless the weights are absolute (`W = R^-1`);
//! - 1-sigma per parameter, residual RMS, iterations and the condition number of the scaled,
//!   weighted Jacobian;
//! - rank deficiency reported by naming the unobservable parameter combination (the null
//!   direction of the scaled normal matrix), never NaN parameters.
//!
//! Works with fixed-size dimensions without allocation (the chip) and, with the `alloc`
//! feature, with `nalgebra::Dyn` (the host's extended models).

use crate::Real;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OMatrix, OVector, U1};

/// Error raised by a model that cannot be evaluated at a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelError {
    /// A prediction or Jacobian element was NaN or infinite (e.g. a beacon behind the head).
    NonFinite,
    /// The model has no usable rows at this point (e.g. every cell in shadow).
    NoData,
}

/// A least-squares problem for GLSDC.
pub trait Problem<T: Real> {
    /// Dimension of the parameter vector (`U7`, `U6`, or `Dyn`).
    type D: Dim;
    /// The dimension value (for `Dyn`, the run-time size).
    fn dim(&self) -> Self::D;
    /// Number of scalar residual rows (`m`).
    fn n_rows(&self) -> usize;
    /// Visit every residual row at `x`: call `sink(residual, weight, jacobian_row)` with
    /// `residual = measured - predicted`, its weight (the diagonal of `W`), and, when `jac` is
    /// true, `d predicted / d x` (length `n`; an empty slice otherwise).
    fn rows(
        &self,
        x: &OVector<T, Self::D>,
        jac: bool,
        sink: &mut dyn FnMut(T, T, &[T]),
    ) -> Result<(), ModelError>
    where
        DefaultAllocator: Allocator<Self::D>;
    /// Visit the measured value `y_i` and the weight `w_i` of every row, in the order of
    /// [`Problem::rows`], without evaluating the model; `false` when the problem cannot
    /// (the default). With them, a linearisation carried by [`solve_with`] predicts the
    /// residuals at the next solve's start, `y_i - (h_i + J_i dx)`, and its first step
    /// evaluates no model at all.
    fn measurements(&self, _sink: &mut dyn FnMut(T, T)) -> bool {
        false
    }
    /// Write the name of parameter `i` (used to name unobservable combinations).
    fn param_name(&self, i: usize, w: &mut dyn core::fmt::Write) -> core::fmt::Result {
        write!(w, "x{}", i + 1)
    }
}

/// GLSDC settings.
#[derive(Debug, Clone, Copy)]
pub struct Settings<T> {
    /// Iteration cap.
    pub max_iter: usize,
    /// Stop when every `|dx_i| <= step_tol * (|x_i| + step_tol)`.
    pub step_tol: T,
    /// Stop when an accepted step changes the cost by less than `cost_tol * cost`.
    pub cost_tol: T,
    /// `true` when the weights are absolute (`W = R^-1`, inverse measurement variances):
    /// then `P` is not rescaled by the residual variance.
    pub weights_absolute: bool,
    /// Smallest acceptable ratio of the scaled normal matrix's extreme eigenvalues; below it
    /// the problem is reported rank deficient.
    pub rank_tol: T,
    /// How many times the damping may grow within one iteration before giving up.
    pub max_damping: usize,
    /// Stop after an undamped step that lowered `sum w r^2` by less than this (absolute;
    /// with absolute weights it is chi-square, and 0.01 is far below the noise).
    pub cost_abs_tol: T,
    /// When the Gauss-Newton step would lower `sum w r^2` by less than this (absolute), or
    /// by less than `cost_tol` of it, take the step without evaluating the model at its end
    /// and stop. With absolute weights a step worth `p` of chi-square is `sqrt(p)` standard
    /// deviations long (in the metric of the covariance): far inside the linear regime for
    /// `p` below 1, so its predicted end is its end.
    pub final_step_tol: T,
    /// Compute the condition number by eigen iteration (`true`), or report the cheap upper
    /// bound `sqrt(n trace(N^-1))` of the column-scaled normal matrix `N` (within a factor
    /// `sqrt(n)`; for the chip's instruction budget).
    pub exact_condition: bool,
    /// Evaluate trial points with the Jacobian (one pass instead of a cost pass plus a
    /// Jacobian pass per accepted step). Pays off when steps are rarely rejected and the
    /// Jacobian is cheap relative to the model (analytic): the pose solver on the chip.
    pub jacobian_in_trial: bool,
}

impl<T: Real> Default for Settings<T> {
    fn default() -> Self {
        let eps = T::default_epsilon();
        Settings {
            max_iter: 100,
            step_tol: eps.sqrt() * T::lit(1e-2),
            cost_tol: eps * T::lit(16.0),
            weights_absolute: false,
            rank_tol: eps * T::lit(1e4),
            max_damping: 30,
            cost_abs_tol: T::zero(),
            final_step_tol: T::zero(),
            exact_condition: true,
            jacobian_in_trial: false,
        }
    }
}

/// Why GLSDC stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// The step fell below `step_tol`.
    SmallStep,
    /// The cost changed by less than `cost_tol`.
    SmallCostChange,
    /// The residuals are zero.
    ZeroCost,
    /// No damped step lowers the cost any more: a minimum to working precision.
    NoFurtherDecrease,
    /// The Gauss-Newton step would lower the cost by less than the tolerances: it was taken
    /// without evaluating the model at its end (the cost there is the linear prediction,
    /// the covariance that of the point one sub-tolerance step before).
    SmallPredictedDecrease,
}

/// A converged GLSDC solution.
#[derive(Debug, Clone)]
pub struct Solution<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// Estimated parameters.
    pub x: OVector<T, D>,
    /// Covariance `P` (eq 58), scaled by the residual variance unless weights are absolute.
    pub covariance: OMatrix<T, D, D>,
    /// Parameter 1-sigma: `sqrt(diag P)`.
    pub sigma: OVector<T, D>,
    /// Final cost `J = 1/2 sum w r^2`.
    pub cost: T,
    /// Unweighted residual RMS `sqrt(sum r^2 / m)`.
    pub rms: T,
    /// Residual variance factor `sum w r^2 / (m - n)` (chi-square per degree of freedom when
    /// the weights are absolute).
    pub variance_factor: T,
    /// Number of residual rows.
    pub m: usize,
    /// Iterations taken.
    pub iterations: usize,
    /// Condition number of the column-scaled, weighted Jacobian.
    pub condition: T,
    /// Why it stopped.
    pub stop: Stop,
}

/// Why GLSDC failed. Every variant carries the last good estimate (never NaN).
#[derive(Debug, Clone)]
pub enum Error<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// Fewer residual rows than parameters.
    TooFewRows {
        /// Rows available.
        m: usize,
        /// Parameters.
        n: usize,
    },
    /// The model could not be evaluated at the starting point.
    Model(ModelError),
    /// The normal matrix is (numerically) singular: the parameters along `null` cannot be
    /// told apart from the data. `null` is a unit direction in parameter space scaled by
    /// the parameters' information scale; its large components name the combination.
    RankDeficient {
        /// Last good estimate.
        x: OVector<T, D>,
        /// Unobservable direction (unit length in scaled coordinates).
        null: OVector<T, D>,
        /// Ratio of the extreme eigenvalues of the scaled normal matrix.
        ratio: T,
    },
    /// The iteration cap was reached before convergence.
    NotConverged {
        /// Last good estimate.
        x: OVector<T, D>,
        /// Its cost.
        cost: T,
        /// Iterations taken.
        iterations: usize,
    },
}

struct Normal<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    n: OMatrix<T, D, D>,
    g: OVector<T, D>,
    wss: T,
    ss: T,
    /// Rows kept in the caller's store (0: none): see [`accumulate`].
    rows: usize,
}

impl<T: Real, D: Dim> Normal<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// Jacobi scaling `s_i = 1/sqrt(N_ii)` (0 for a parameter the data does not touch):
    /// returns the scaled normal matrix `S N S` and `s`.
    fn scaled(&self) -> (OMatrix<T, D, D>, OVector<T, D>) {
        let (dim, _) = self.n.shape_generic();
        let scale = OVector::<T, D>::from_fn_generic(dim, U1, |i, _| {
            let nii = self.n[(i, i)];
            if nii > T::zero() {
                T::one() / nii.sqrt()
            } else {
                T::zero()
            }
        });
        let mut ns = self.n.clone();
        for a in 0..dim.value() {
            for b in 0..dim.value() {
                ns[(a, b)] *= scale[a] * scale[b];
            }
        }
        (ns, scale)
    }
}

/// Cholesky factor `A = L L^T` of a symmetric positive definite matrix, with the
/// reciprocals of its diagonal: one division per column and none in the solves (each
/// soft-float division costs several multiplications on the chip). One factorisation per
/// iteration serves the rank test, the Gauss-Newton step and the covariance.
#[derive(Debug, Clone)]
struct Chol<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// `L` in the lower triangle (the strict upper triangle is unused).
    l: OMatrix<T, D, D>,
    inv_diag: OVector<T, D>,
}

impl<T: Real, D: Dim> Chol<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// Factor `a` (only its lower triangle is read); `None` unless every pivot is positive.
    fn new(a: &OMatrix<T, D, D>) -> Option<Self> {
        let (dim, _) = a.shape_generic();
        let n = dim.value();
        let mut l = a.clone();
        let mut inv_diag = OVector::<T, D>::zeros_generic(dim, U1);
        for j in 0..n {
            let mut d = l[(j, j)];
            for k in 0..j {
                d -= l[(j, k)] * l[(j, k)];
            }
            if !(d > T::zero()) {
                return None;
            }
            let dj = d.sqrt();
            let inv = T::one() / dj;
            l[(j, j)] = dj;
            inv_diag[j] = inv;
            for i in j + 1..n {
                let mut v = l[(i, j)];
                for k in 0..j {
                    v -= l[(i, k)] * l[(j, k)];
                }
                l[(i, j)] = v * inv;
            }
        }
        Some(Chol { l, inv_diag })
    }

    /// `A^-1 b` by forward and back substitution.
    fn solve(&self, b: &OVector<T, D>) -> OVector<T, D> {
        let n = b.len();
        let mut x = b.clone();
        for i in 0..n {
            let mut v = x[i];
            for k in 0..i {
                v -= self.l[(i, k)] * x[k];
            }
            x[i] = v * self.inv_diag[i];
        }
        for i in (0..n).rev() {
            let mut v = x[i];
            for k in i + 1..n {
                v -= self.l[(k, i)] * x[k];
            }
            x[i] = v * self.inv_diag[i];
        }
        x
    }

    /// `M = L^-1` (lower triangular; the strict upper triangle is zero): then
    /// `A^-1 = M^T M` and `trace(A^-1)` is the sum of the squares of `M`.
    fn inverse_factor(&self) -> OMatrix<T, D, D> {
        let (dim, _) = self.l.shape_generic();
        let n = dim.value();
        let mut m = OMatrix::<T, D, D>::zeros_generic(dim, dim);
        for j in 0..n {
            m[(j, j)] = self.inv_diag[j];
            for i in j + 1..n {
                let mut v = T::zero();
                for k in j..i {
                    v -= self.l[(i, k)] * m[(k, j)];
                }
                m[(i, j)] = v * self.inv_diag[i];
            }
        }
        m
    }

    /// `trace(A^-1)`.
    fn inverse_trace(&self) -> T {
        let m = self.inverse_factor();
        let n = self.inv_diag.len();
        let mut tr = T::zero();
        for j in 0..n {
            for i in j..n {
                tr += m[(i, j)] * m[(i, j)];
            }
        }
        tr
    }

    /// `A^-1 = M^T M`, symmetric.
    fn inverse(&self) -> OMatrix<T, D, D> {
        let m = self.inverse_factor();
        let n = self.inv_diag.len();
        let mut inv = m.clone();
        for a in 0..n {
            for b in a..n {
                let mut v = T::zero();
                for k in b..n {
                    v += m[(k, a)] * m[(k, b)];
                }
                inv[(a, b)] = v;
                inv[(b, a)] = v;
            }
        }
        inv
    }
}

fn cost_at<T: Real, P: Problem<T>>(prob: &P, x: &OVector<T, P::D>) -> Result<(T, T), ModelError>
where
    DefaultAllocator: Allocator<P::D>,
{
    let mut wss = T::zero();
    let mut ss = T::zero();
    prob.rows(x, false, &mut |r, w, _| {
        wss += w * r * r;
        ss += r * r;
    })?;
    if !(wss.is_finite()) {
        return Err(ModelError::NonFinite);
    }
    Ok((wss, ss))
}

fn accumulate<T: Real, P: Problem<T>>(
    prob: &P,
    x: &OVector<T, P::D>,
    store: Option<&mut [T]>,
) -> Result<Normal<T, P::D>, ModelError>
where
    DefaultAllocator: Allocator<P::D> + Allocator<P::D, P::D>,
{
    let d = prob.dim();
    let nn = d.value();
    let mut n = OMatrix::<T, P::D, P::D>::zeros_generic(d, d);
    let mut g = OVector::<T, P::D>::zeros_generic(d, U1);
    let mut wss = T::zero();
    let mut ss = T::zero();
    let mut store = store;
    // Each kept row: w J_i, then r_i.
    let stride = nn + 1;
    let cap = store.as_ref().map_or(0, |s| s.len() / stride);
    let mut row = 0;
    prob.rows(x, true, &mut |r, w, j| {
        debug_assert_eq!(j.len(), nn);
        // Unit weights save a multiplication per element (a soft-float call on the chip).
        let unit = w == T::one();
        let rr = r * r;
        wss += if unit { rr } else { w * rr };
        ss += rr;
        // The weighted row w J_i and the residual, kept (when there is room) so that this
        // linearisation can be carried to the next solve.
        let mut kept = match store.as_deref_mut() {
            Some(s) if row < cap => {
                let k = &mut s[row * stride..(row + 1) * stride];
                k[nn] = r;
                Some(k)
            }
            _ => None,
        };
        row += 1;
        // Upper triangle, column by column (contiguous in nalgebra's column-major storage).
        let ns = n.as_mut_slice();
        for (b, &jb) in j.iter().enumerate() {
            let wjb = if unit { jb } else { w * jb };
            if let Some(k) = kept.as_deref_mut() {
                k[b] = wjb;
            }
            if wjb == T::zero() {
                continue;
            }
            g[b] += wjb * r;
            for (nab, &ja) in ns[b * nn..b * nn + b + 1].iter_mut().zip(&j[..=b]) {
                *nab += wjb * ja;
            }
        }
    })?;
    for b in 0..nn {
        for a in 0..b {
            n[(b, a)] = n[(a, b)];
        }
    }
    if !(wss.is_finite() && g.iter().all(|v| v.is_finite()) && n.iter().all(|v| v.is_finite())) {
        return Err(ModelError::NonFinite);
    }
    let rows = if row <= cap { row } else { 0 };
    Ok(Normal {
        n,
        g,
        wss,
        ss,
        rows,
    })
}

/// The gradient and the sums `sum w r^2`, `sum r^2` of a chord evaluation.
type ChordEval<T, D> = (OVector<T, D>, T, T);

/// The sums of a chord evaluation, row by row: the gradient `g = sum (w J_i) r_i` from the
/// weighted rows `kept` of an earlier linearisation (see [`accumulate`]), `sum w r^2` and
/// `sum r^2`, and the rows seen.
struct ChordSums<'k, T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    kept: &'k [T],
    rows: usize,
    g: OVector<T, D>,
    wss: T,
    ss: T,
    row: usize,
}

impl<'k, T: Real, D: Dim> ChordSums<'k, T, D>
where
    DefaultAllocator: Allocator<D>,
{
    fn new(d: D, kept: &'k [T], rows: usize) -> Self {
        ChordSums {
            kept,
            rows,
            g: OVector::<T, D>::zeros_generic(d, U1),
            wss: T::zero(),
            ss: T::zero(),
            row: 0,
        }
    }

    /// The kept row about to be added (empty past the kept ones).
    fn next_kept(&self) -> &'k [T] {
        let nn = self.g.len();
        match self.row < self.rows {
            true => &self.kept[self.row * (nn + 1)..(self.row + 1) * (nn + 1)],
            false => &[],
        }
    }

    /// The next row's residual `r` and weight `w`.
    fn add(&mut self, r: T, w: T) {
        let kept = self.next_kept();
        for (gb, &jb) in self.g.iter_mut().zip(kept) {
            *gb += jb * r;
        }
        self.row += 1;
        let rr = r * r;
        self.wss += if w == T::one() { rr } else { w * rr };
        self.ss += rr;
    }

    /// The evaluation, if finite; `Ok(None)` when the rows did not line up with the kept.
    fn done(self) -> Result<Option<ChordEval<T, D>>, ModelError> {
        if self.row != self.rows {
            return Ok(None);
        }
        if !(self.wss.is_finite() && self.g.iter().all(|v| v.is_finite())) {
            return Err(ModelError::NonFinite);
        }
        Ok(Some((self.g, self.wss, self.ss)))
    }
}

/// A chord evaluation at `x`: the residuals there and the gradient from the kept rows
/// (`rows` of them) of an earlier linearisation ([`ChordSums`]). `None` when the model
/// visits a different number of rows at `x` (the kept rows no longer line up).
fn chord_at<T: Real, P: Problem<T>>(
    prob: &P,
    x: &OVector<T, P::D>,
    kept: &[T],
    rows: usize,
) -> Result<Option<ChordEval<T, P::D>>, ModelError>
where
    DefaultAllocator: Allocator<P::D>,
{
    let mut sums = ChordSums::new(prob.dim(), kept, rows);
    prob.rows(x, false, &mut |r, w, _| sums.add(r, w))?;
    sums.done()
}

/// The start of a solve from a carried linearisation whose kept rows hold the predicted
/// model values `h_i` at the carried solution (see [`predict`]): the residuals there,
/// `y_i - h_i` with this problem's measurements, and the gradient from the kept rows, with
/// no model evaluation. `None` when the problem does not give its measurements or they do
/// not line up with the kept rows (or are not finite).
fn predicted_start<T: Real, P: Problem<T>>(
    prob: &P,
    kept: &[T],
    rows: usize,
) -> Option<ChordEval<T, P::D>>
where
    DefaultAllocator: Allocator<P::D>,
{
    let nn = prob.dim().value();
    let mut sums = ChordSums::new(prob.dim(), kept, rows);
    let told = prob.measurements(&mut |y, w| {
        let h = sums.next_kept().get(nn).copied().unwrap_or(y);
        sums.add(y - h, w);
    });
    match told {
        true => sums.done().ok().flatten(),
        false => None,
    }
}

/// Turn the kept rows of the linearisation at `x_lin` (`w J_i`, `r_i`) into predictions for
/// the next solve: `r_i` is replaced by the model value the linearisation predicts at the
/// solution `x`, `h_i = y_i - r_i + J_i (x - x_lin)`. `false` (nothing usable) when the
/// problem does not give its measurements or they do not line up.
fn predict<T: Real, P: Problem<T>>(
    prob: &P,
    x: &OVector<T, P::D>,
    x_lin: &OVector<T, P::D>,
    kept: &mut [T],
    rows: usize,
) -> bool
where
    DefaultAllocator: Allocator<P::D>,
{
    let nn = prob.dim().value();
    let dx = x - x_lin;
    let moved = dx.iter().any(|v| *v != T::zero());
    let mut row = 0;
    let told = prob.measurements(&mut |y, w| {
        if row < rows {
            let k = &mut kept[row * (nn + 1)..(row + 1) * (nn + 1)];
            // J_i dx from the weighted row.
            let mut jdx = T::zero();
            if moved {
                for (&jb, &db) in k.iter().zip(dx.iter()) {
                    jdx += jb * db;
                }
                if w != T::one() {
                    jdx /= w;
                }
            }
            k[nn] = y - k[nn] + jdx;
        }
        row += 1;
    });
    told && row == rows
}

/// Extreme eigenvalues of a symmetric positive semi-definite matrix and the eigenvector of
/// the smallest, by power and inverse iteration (no eigen-decomposition: small code on the
/// chip). Returns `(lambda_max, lambda_min, v_min)`.
fn extreme_eigen<T: Real, D: Dim>(a: &OMatrix<T, D, D>, shift: T) -> (T, T, OVector<T, D>)
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let (dim, _) = a.shape_generic();
    let n = dim.value();
    // Power iteration for lambda_max.
    let mut v = OVector::<T, D>::from_element_generic(dim, U1, T::one());
    v /= v.norm();
    // Relative change at which an eigenvalue estimate is taken as converged: the
    // condition number is reported to a few digits, not to working precision.
    let tol = T::default_epsilon().sqrt();
    let mut lmax = T::zero();
    for _ in 0..60 {
        let w = a * &v;
        let nw = w.norm();
        if nw == T::zero() {
            break;
        }
        let l = v.dot(&w);
        v = w / nw;
        let done = (l - lmax).abs() <= tol * l.abs();
        lmax = l;
        if done {
            break;
        }
    }
    // Inverse iteration on (A + shift I) for lambda_min.
    let mut shifted = a.clone();
    for i in 0..n {
        shifted[(i, i)] += shift;
    }
    let mut u =
        OVector::<T, D>::from_fn_generic(dim, U1, |i, _| T::one() + T::lit(0.1) * T::lit(i as f64));
    u /= u.norm();
    let mut lmin = lmax;
    if let Some(ch) = Chol::new(&shifted) {
        let mut mu = T::zero();
        for _ in 0..60 {
            let w = ch.solve(&u);
            let nw = w.norm();
            if !(nw.is_finite()) || nw == T::zero() {
                break;
            }
            u = w / nw;
            // u . (A + shift)^-1 u converges to 1 / (lambda_min + shift).
            let done = (nw - mu).abs() <= tol * nw;
            mu = nw;
            if done {
                break;
            }
        }
        lmin = u.dot(&(a * &u)).max(T::zero());
    }
    (lmax, lmin, u)
}

/// One linearisation: the scaled normal matrix at `x`, its scale and Cholesky factor, and
/// how many rows of it the caller's store holds (0: none; see [`accumulate`]).
#[derive(Debug, Clone)]
struct Lin<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    x: OVector<T, D>,
    ns: OMatrix<T, D, D>,
    scale: OVector<T, D>,
    ch: Option<Chol<T, D>>,
    kept: usize,
    /// When the kept rows end in the model values predicted at a solution ([`predict`]),
    /// not in the residuals at `x`: that solution.
    predicted: Option<OVector<T, D>>,
}

impl<T: Real, D: Dim> Lin<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    fn new(ne: &Normal<T, D>, x: &OVector<T, D>) -> Self {
        let (ns, scale) = ne.scaled();
        let ch = Chol::new(&ns);
        Lin {
            x: x.clone(),
            ns,
            scale,
            ch,
            kept: ne.rows,
            predicted: None,
        }
    }
}

/// The last linearisation of a [`solve_with`], carried to the next solve of a similar
/// problem (the next frame of a tracked pose): its factored normal matrix here, its
/// weighted Jacobian rows (and the predicted model values, when the problem gives its
/// measurements) in the caller's store.
#[derive(Debug, Clone)]
pub struct Carry<T: Real, D: Dim>(Lin<T, D>)
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>;

/// A trial point's evaluation.
enum Trial<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// Cost only (`wss`, `ss`): the next iteration linearises there.
    Cost(T, T),
    /// A fresh linearisation there.
    Fresh(Normal<T, D>),
}

impl<T: Real, D: Dim> Trial<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    fn sums(&self) -> (T, T) {
        match self {
            Trial::Cost(w, s) => (*w, *s),
            Trial::Fresh(ne) => (ne.wss, ne.ss),
        }
    }
}

/// Run GLSDC from `x0`.
pub fn solve<T: Real, P: Problem<T>>(
    prob: &P,
    x0: OVector<T, P::D>,
    settings: &Settings<T>,
) -> Result<Solution<T, P::D>, Error<T, P::D>>
where
    DefaultAllocator: Allocator<P::D> + Allocator<P::D, P::D>,
{
    solve_with(prob, x0, settings, &mut [], &mut None)
}

/// [`solve`] for a sequence of similar problems (a tracked pose, frame after frame), with a
/// linearisation carried from one to the next. `store` keeps the weighted Jacobian rows
/// `w J_i` of each linearisation and one value more per row (room for `m (n + 1)` values;
/// less: none are kept and nothing is carried). On entry, `carry` is the previous solve's
/// last linearisation (`None`: start afresh); on return, this one's (`None` after an
/// error).
///
/// A carried linearisation whose rows line up with this problem's (the same count) serves
/// the first step, a chord step with the gradient `sum (w J_i) r_i` over the kept rows. The
/// residuals at `x0` are predicted when the problem gives its measurements
/// ([`Problem::measurements`]): `r_i = y_i - h_i`, with `h_i` the model value the carried
/// linearisation predicts at the previous solution (the previous solve's last step is
/// often taken as predicted anyway), so the step evaluates no model. Otherwise (another
/// `x0` than the previous solution, or no measurements) they cost one pass without the
/// Jacobian. A carried Jacobian only
/// moves the estimate: no stop is decided from it (the next point is linearised afresh
/// before any stop), so the answer is the Gauss-Newton answer, and a step it spoils (the
/// cost rises) is retried from a fresh linearisation at `x0`.
pub fn solve_with<T: Real, P: Problem<T>>(
    prob: &P,
    x0: OVector<T, P::D>,
    settings: &Settings<T>,
    store: &mut [T],
    carry: &mut Option<Carry<T, P::D>>,
) -> Result<Solution<T, P::D>, Error<T, P::D>>
where
    DefaultAllocator: Allocator<P::D> + Allocator<P::D, P::D>,
{
    let carried = carry.take();
    let d = prob.dim();
    let n = d.value();
    let m = prob.n_rows();
    if m < n {
        return Err(Error::TooFewRows { m, n });
    }
    let half = T::lit(0.5);
    let mut x = x0;
    // Fresh normal equations at `x` not yet factored (the start with `jacobian_in_trial`,
    // or an accepted trial), or the gradient at `x` from the carried linearisation.
    let mut fresh: Option<Normal<T, P::D>> = None;
    let mut lin: Option<Lin<T, P::D>> = None;
    let mut chord_g: Option<OVector<T, P::D>> = None;
    let mut start = None;
    if let Some(Carry(l)) = carried {
        if l.kept == m && store.len() >= m * (n + 1) {
            // Predicted residuals serve a start at the point they were predicted for;
            // otherwise (or when the problem cannot give its measurements) a residual pass.
            let eval = match &l.predicted {
                Some(at) if *at == x => predicted_start(prob, store, m),
                _ => None,
            };
            let eval = match eval {
                Some(e) => Some(e),
                None => chord_at(prob, &x, store, m).map_err(Error::Model)?,
            };
            if let Some((g, w, s)) = eval {
                chord_g = Some(g);
                lin = Some(l);
                start = Some((w, s));
            }
        }
    }
    let (mut wss, mut ss) = match start {
        Some(c) => c,
        None if settings.jacobian_in_trial => {
            let ne = accumulate(prob, &x, Some(&mut *store)).map_err(Error::Model)?;
            let c = (ne.wss, ne.ss);
            fresh = Some(ne);
            c
        }
        None => cost_at(prob, &x).map_err(Error::Model)?,
    };
    let mut lambda = T::zero();
    let mut iterations = 0;
    let mut stop = None;
    while iterations < settings.max_iter {
        iterations += 1;
        // The normal equations of this iteration: a new linearisation at `x`, or the
        // carried one with the gradient at `x`.
        let g = match (fresh.take(), chord_g.take(), lin.is_some()) {
            (None, Some(g), true) => g,
            (ne, _, _) => {
                let ne = match ne {
                    Some(ne) => ne,
                    None => accumulate(prob, &x, Some(&mut *store)).map_err(Error::Model)?,
                };
                let l = Lin::new(&ne, &x);
                if let Some(err) = rank_check(&l.ns, l.ch.as_ref(), &l.scale, &x, settings) {
                    return Err(err);
                }
                lin = Some(l);
                ne.g
            }
        };
        let Some(l) = lin.as_mut() else {
            // Not reached: a linearisation was just made or kept.
            return Err(Error::Model(ModelError::NoData));
        };
        let gs = g.component_mul(&l.scale);
        // Stops are decided only from a linearisation at the current point.
        let current = l.x == x;
        // The Gauss-Newton step. Gauss-Newton predicts sum w r^2 to fall by g^T dx; below
        // the tolerances the step is taken without evaluating the model at its end (it is
        // far inside the linear regime, so the prediction is the cost there, and `ss` scales
        // with it) and the solve stops. This is checked whatever the damping: in a flat,
        // curved valley (the pose at 30 in) the full step can overshoot while damped steps
        // crawl on, each gaining a few hundredths of the noise, to the iteration cap.
        let mut gauss_newton = l.ch.as_ref().map(|ch| ch.solve(&gs));
        if let (Some(ds), true) = (&gauss_newton, current) {
            let predicted = gs.dot(ds);
            if predicted <= settings.final_step_tol || predicted <= settings.cost_tol * wss {
                let wn = (wss - predicted).max(T::zero());
                if wss > T::zero() {
                    ss *= wn / wss;
                }
                wss = wn;
                x += ds.component_mul(&l.scale);
                stop = Some(Stop::SmallPredictedDecrease);
                break;
            }
        }
        // Gauss-Newton first, Levenberg damping when the cost rises or an accepted step gains
        // much less than it predicts.
        let mut accepted = false;
        let mut relinearise = false;
        for _ in 0..settings.max_damping {
            let ds = if lambda == T::zero() {
                gauss_newton.take()
            } else {
                let mut a = l.ns.clone();
                for i in 0..n {
                    a[(i, i)] += lambda;
                }
                Chol::new(&a).map(|ch| ch.solve(&gs))
            };
            // The fall of sum w r^2 the (damped) step predicts: with (A + lambda I) ds = g,
            // 2 g.ds - ds.A.ds = g.ds + lambda |ds|^2.
            let predicted;
            let step = match ds {
                Some(ds) => {
                    predicted = gs.dot(&ds) + lambda * ds.norm_squared();
                    ds.component_mul(&l.scale)
                }
                None => {
                    lambda = if lambda == T::zero() {
                        T::lit(1e-6)
                    } else {
                        lambda * T::lit(10.0)
                    };
                    continue;
                }
            };
            let xn = &x + &step;
            let trial = if settings.jacobian_in_trial {
                // The store now holds the trial's rows, not the linearisation's.
                l.kept = 0;
                accumulate(prob, &xn, Some(&mut *store)).map(Trial::Fresh)
            } else {
                cost_at(prob, &xn).map(|(w, s)| Trial::Cost(w, s))
            };
            match trial {
                Ok(t) if t.sums().0 <= wss => {
                    let (wn, sn) = t.sums();
                    let small_step = (0..n).all(|i| {
                        step[i].abs() <= settings.step_tol * (x[i].abs() + settings.step_tol)
                    });
                    // An undamped (Gauss-Newton) step that lowered the cost by less than
                    // cost_abs_tol: the next would not be worth it either. In a flat valley
                    // the predicted decrease can stay just above the tolerance step after
                    // step while the actual one falls below it (the pose at 30 in: 20
                    // iterations, then NotConverged next to the minimum). A damped step may
                    // be small because of the damping, not the valley: it does not stop.
                    let small_cost = (wss - wn) <= settings.cost_tol * wss
                        || (lambda == T::zero()
                            && settings.cost_abs_tol > T::zero()
                            && (wss - wn) <= settings.cost_abs_tol);
                    if let Trial::Fresh(ne) = t {
                        fresh = Some(ne);
                    }
                    x = xn;
                    let prev = wss;
                    wss = wn;
                    ss = sn;
                    accepted = true;
                    // Fletcher's gain ratio: a step that gains less than a quarter of its
                    // prediction met a curved valley (GN overshoots across it and zig-zags:
                    // the pose at 30 in, then 20 iterations and NotConverged), so the next
                    // is damped more; one that gains three quarters or more, less.
                    let gain = (prev - wss) / predicted;
                    lambda = if gain < T::lit(0.25) {
                        if lambda == T::zero() {
                            T::lit(1e-3)
                        } else {
                            lambda * T::lit(10.0)
                        }
                    } else if gain < T::lit(0.75) {
                        lambda
                    } else if lambda <= T::lit(1e-7) {
                        T::zero()
                    } else {
                        lambda / T::lit(10.0)
                    };
                    if wss == T::zero() {
                        stop = Some(Stop::ZeroCost);
                    } else if !current {
                        // A step of the carried Jacobian: decide at the new point.
                    } else if small_step {
                        stop = Some(Stop::SmallStep);
                    } else if small_cost && prev > T::zero() {
                        stop = Some(Stop::SmallCostChange);
                    }
                    break;
                }
                _ if !current => {
                    // The carried Jacobian may be what failed: linearise afresh at `x`.
                    relinearise = true;
                    break;
                }
                _ => {
                    lambda = if lambda == T::zero() {
                        T::lit(1e-3)
                    } else {
                        lambda * T::lit(10.0)
                    };
                }
            }
        }
        if relinearise {
            lin = None;
            fresh = None;
            continue;
        }
        if !accepted {
            stop = Some(Stop::NoFurtherDecrease);
        }
        if stop.is_some() {
            break;
        }
    }
    let Some(stop) = stop else {
        return Err(Error::NotConverged {
            x,
            cost: half * wss,
            iterations,
        });
    };
    // Prefer fresh normal equations at the final point when a trial computed them.
    let mut l = match (fresh, lin) {
        (Some(ne), _) => Lin::new(&ne, &x),
        (None, Some(l)) => l,
        // Not reached: at least one iteration ran.
        (None, None) => return Err(Error::Model(ModelError::NoData)),
    };
    let out = finish(
        Final {
            x,
            lin: &l,
            wss,
            ss,
            m,
            iterations,
            stop,
        },
        settings,
    );
    if let Ok(sol) = &out {
        if l.kept == m {
            // From the residuals the kept rows end in; a linearisation still carried from
            // an earlier solve (a first step that ended it) holds that solve's predictions.
            l.predicted = match l.predicted {
                None => predict(prob, &sol.x, &l.x, store, m).then(|| sol.x.clone()),
                Some(_) => None,
            };
            *carry = Some(Carry(l));
        }
    }
    out
}

fn rank_check<T: Real, D: Dim>(
    ns: &OMatrix<T, D, D>,
    ch: Option<&Chol<T, D>>,
    scale: &OVector<T, D>,
    x: &OVector<T, D>,
    settings: &Settings<T>,
) -> Option<Error<T, D>>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let (dim, _) = ns.shape_generic();
    let n = dim.value();
    // A parameter the data does not touch at all.
    for i in 0..n {
        if scale[i] == T::zero() {
            let null = OVector::<T, D>::from_fn_generic(dim, U1, |k, _| {
                if k == i {
                    T::one()
                } else {
                    T::zero()
                }
            });
            return Some(Error::RankDeficient {
                x: x.clone(),
                null,
                ratio: T::zero(),
            });
        }
    }
    // Cheap certificate first: the scaled matrix has a unit diagonal, so
    // lambda_max <= trace = n and lambda_min >= 1 / trace(N^-1); when that lower bound on
    // lambda_min / lambda_max clears the tolerance, no eigen iteration is needed (the usual
    // case, and the one that matters on the chip).
    if let Some(ch) = ch {
        let tr = ch.inverse_trace();
        if tr.is_finite()
            && tr > T::zero()
            && T::one() / (T::lit(n as f64) * tr) >= settings.rank_tol
        {
            return None;
        }
    }
    let (lmax, lmin, v) = extreme_eigen(ns, settings.rank_tol * T::lit(1e-3));
    let ratio = if lmax > T::zero() {
        lmin / lmax
    } else {
        T::zero()
    };
    if ratio < settings.rank_tol {
        return Some(Error::RankDeficient {
            x: x.clone(),
            null: v,
            ratio,
        });
    }
    None
}

/// The state GLSDC stops in: the solution, the scaled normal matrix of the last
/// linearisation (at most one sub-tolerance step before `x`, so it is reused for the
/// covariance rather than paying one more Jacobian pass), and the final residual sums.
struct Final<'a, T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    x: OVector<T, D>,
    /// The scaled normal matrix, its scale and its Cholesky factor (`None`: not positive
    /// definite).
    lin: &'a Lin<T, D>,
    wss: T,
    ss: T,
    m: usize,
    iterations: usize,
    stop: Stop,
}

fn finish<T: Real, D: Dim>(
    f: Final<'_, T, D>,
    settings: &Settings<T>,
) -> Result<Solution<T, D>, Error<T, D>>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let Final {
        x,
        lin,
        wss,
        ss,
        m,
        iterations,
        stop,
    } = f;
    let (ns, scale) = (&lin.ns, &lin.scale);
    let (dim, _) = ns.shape_generic();
    let n = dim.value();
    let inv = match &lin.ch {
        Some(ch) => ch.inverse(),
        None => {
            let (_, _, v) = extreme_eigen(ns, settings.rank_tol);
            return Err(Error::RankDeficient {
                x,
                null: v,
                ratio: T::zero(),
            });
        }
    };
    let condition = if settings.exact_condition {
        let (lmax, lmin, _) = extreme_eigen(ns, T::zero());
        if lmin > T::zero() {
            (lmax / lmin).sqrt()
        } else {
            T::max_value().unwrap_or(T::lit(1e300))
        }
    } else {
        // lambda_max <= trace(N) = n (unit diagonal), 1/lambda_min <= trace(N^-1).
        let tr = (0..n).fold(T::zero(), |a, i| a + inv[(i, i)]);
        (T::lit(n as f64) * tr).sqrt()
    };
    let dof = if m > n { m - n } else { 1 };
    let variance_factor = wss / T::lit(dof as f64);
    let mut cov = inv;
    for a in 0..n {
        for b in 0..n {
            cov[(a, b)] *= scale[a] * scale[b];
        }
    }
    if !settings.weights_absolute {
        cov *= variance_factor;
    }
    let sigma = OVector::<T, D>::from_fn_generic(dim, U1, |i, _| cov[(i, i)].max(T::zero()).sqrt());
    Ok(Solution {
        x,
        covariance: cov,
        sigma,
        cost: T::lit(0.5) * wss,
        rms: (ss / T::lit(m as f64)).sqrt(),
        variance_factor,
        m,
        iterations,
        condition,
        stop,
    })
}

/// The most poorly determined parameter direction at `x`: the eigenvector of the smallest
/// eigenvalue of the column-scaled normal matrix, and the ratio of its extreme eigenvalues
/// (`1 / condition^2`). Used to name what an ill-conditioned fit cannot pin down.
pub fn weakest_direction<T: Real, P: Problem<T>>(
    prob: &P,
    x: &OVector<T, P::D>,
) -> Result<(OVector<T, P::D>, T), ModelError>
where
    DefaultAllocator: Allocator<P::D> + Allocator<P::D, P::D>,
{
    let (ns, _) = accumulate(prob, x, None)?.scaled();
    let (lmax, lmin, v) = extreme_eigen(&ns, lmax_guard::<T>());
    let ratio = if lmax > T::zero() {
        lmin / lmax
    } else {
        T::zero()
    };
    Ok((v, ratio))
}

#[inline]
fn lmax_guard<T: Real>() -> T {
    T::default_epsilon() * T::lit(1e-2)
}

/// Describe an unobservable direction in words: the parameters whose components exceed
/// 0.25 (of a unit vector), with signs, e.g. `d3 - H` meaning "d3 up with H down".
pub fn describe_null<T: Real, P: Problem<T>>(
    prob: &P,
    null: &OVector<T, P::D>,
    w: &mut dyn core::fmt::Write,
) -> core::fmt::Result
where
    DefaultAllocator: Allocator<P::D>,
{
    let mut first = true;
    // Largest component first.
    let n = null.len();
    let mut order: [usize; 64] = [0; 64];
    let k = n.min(64);
    for (i, o) in order.iter_mut().enumerate().take(k) {
        *o = i;
    }
    order[..k].sort_unstable_by(|&a, &b| {
        null[b]
            .abs()
            .partial_cmp(&null[a].abs())
            .unwrap_or(core::cmp::Ordering::Equal)
    });
    let sign0 = if null[order[0]] < T::zero() {
        -T::one()
    } else {
        T::one()
    };
    for &i in &order[..k] {
        let c = null[i] * sign0;
        if c.abs() < T::lit(0.25) {
            continue;
        }
        if first {
            if c < T::zero() {
                w.write_str("-")?;
            }
        } else {
            w.write_str(if c < T::zero() { " - " } else { " + " })?;
        }
        write!(w, "{:.2} ", c.abs().to_f64())?;
        prob.param_name(i, w)?;
        first = false;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, U2};

    /// y = a exp(b t): a small nonlinear problem (counting its Jacobian passes).
    struct Exp<'a> {
        t: &'a [f64],
        y: &'a [f64],
        /// Gives its measurements ([`Problem::measurements`]).
        tells: bool,
        passes: Passes,
    }

    /// Model passes of a test problem: (with the Jacobian, without).
    #[derive(Default)]
    struct Passes(core::cell::Cell<(usize, usize)>);
    impl Passes {
        fn count(&self, jac: bool) {
            let (j, r) = self.0.get();
            self.0.set((j + usize::from(jac), r + usize::from(!jac)));
        }
        fn get(&self) -> (usize, usize) {
            self.0.get()
        }
    }

    impl<'a> Exp<'a> {
        fn new(t: &'a [f64], y: &'a [f64]) -> Self {
            Exp {
                t,
                y,
                tells: true,
                passes: Passes::default(),
            }
        }
        /// Model passes: (with the Jacobian, without).
        fn passes(&self) -> (usize, usize) {
            self.passes.get()
        }
    }
    impl Problem<f64> for Exp<'_> {
        type D = U2;
        fn dim(&self) -> U2 {
            U2
        }
        fn n_rows(&self) -> usize {
            self.t.len()
        }
        fn rows(
            &self,
            x: &Vector2<f64>,
            jac: bool,
            sink: &mut dyn FnMut(f64, f64, &[f64]),
        ) -> Result<(), ModelError> {
            self.passes.count(jac);
            for (&t, &y) in self.t.iter().zip(self.y) {
                let e = (x[1] * t).exp();
                let f = x[0] * e;
                if jac {
                    sink(y - f, 1.0, &[e, x[0] * t * e]);
                } else {
                    sink(y - f, 1.0, &[]);
                }
            }
            Ok(())
        }
        fn measurements(&self, sink: &mut dyn FnMut(f64, f64)) -> bool {
            if self.tells {
                self.y.iter().for_each(|&y| sink(y, 1.0));
            }
            self.tells
        }
    }

    #[test]
    fn recovers_exponential() {
        let t: [f64; 8] = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5];
        let y: [f64; 8] = core::array::from_fn(|i| 2.0 * (-0.7 * t[i]).exp());
        let p = Exp::new(&t, &y);
        // A poor start: the GN step overshoots, so damping is exercised.
        let s = solve(&p, Vector2::new(10.0, 1.0), &Settings::default()).unwrap();
        assert!(
            (s.x[0] - 2.0).abs() < 1e-9 && (s.x[1] + 0.7).abs() < 1e-9,
            "{:?}",
            s.x
        );
        assert!(s.rms < 1e-9);
    }

    /// y = (a + b) t: a and b cannot be told apart.
    struct Degenerate;
    impl Problem<f64> for Degenerate {
        type D = U2;
        fn dim(&self) -> U2 {
            U2
        }
        fn n_rows(&self) -> usize {
            4
        }
        fn rows(
            &self,
            x: &Vector2<f64>,
            _jac: bool,
            sink: &mut dyn FnMut(f64, f64, &[f64]),
        ) -> Result<(), ModelError> {
            for t in 1..5 {
                let t = t as f64;
                sink(3.0 * t - (x[0] + x[1]) * t, 1.0, &[t, t]);
            }
            Ok(())
        }
        fn param_name(&self, i: usize, w: &mut dyn core::fmt::Write) -> core::fmt::Result {
            w.write_str(["a", "b"][i])
        }
    }

    #[test]
    fn rank_deficiency_names_the_combination() {
        match solve(&Degenerate, Vector2::new(0.0, 0.0), &Settings::default()) {
            Err(Error::RankDeficient { x, null, .. }) => {
                assert!(x.iter().all(|v| v.is_finite()));
                let mut s = heapless::String::<64>::new();
                describe_null(&Degenerate, &null, &mut s).unwrap();
                assert_eq!(s.as_str(), "0.71 a - 0.71 b");
            }
            other => panic!("expected rank deficiency, got {other:?}"),
        }
    }

    #[test]
    fn covariance_scaled_by_residual_variance() {
        // Linear fit y = a + b t with known residuals: P = s^2 (G^T G)^-1.
        struct Lin;
        impl Problem<f64> for Lin {
            type D = U2;
            fn dim(&self) -> U2 {
                U2
            }
            fn n_rows(&self) -> usize {
                4
            }
            fn rows(
                &self,
                x: &Vector2<f64>,
                _j: bool,
                sink: &mut dyn FnMut(f64, f64, &[f64]),
            ) -> Result<(), ModelError> {
                let y = [1.1, 1.9, 3.2, 3.8];
                for (i, yi) in y.iter().enumerate() {
                    let t = i as f64;
                    sink(yi - (x[0] + x[1] * t), 1.0, &[1.0, t]);
                }
                Ok(())
            }
        }
        let s = solve(&Lin, Vector2::new(0.0, 0.0), &Settings::default()).unwrap();
        // Ordinary least squares by hand.
        let (b, a) = (0.94, 1.09);
        assert!((s.x[0] - a).abs() < 1e-12 && (s.x[1] - b).abs() < 1e-12);
        let rss: f64 = [1.1, 1.9, 3.2, 3.8]
            .iter()
            .enumerate()
            .map(|(i, y)| (y - (a + b * i as f64)).powi(2))
            .sum();
        let s2 = rss / 2.0;
        // (G^T G)^-1 for t = 0..3: [[0.7, -0.3], [-0.3, 0.2]].
        assert!((s.covariance[(0, 0)] - 0.7 * s2).abs() < 1e-12);
        assert!((s.covariance[(0, 1)] + 0.3 * s2).abs() < 1e-12);
        assert!((s.sigma[1] - (0.2 * s2).sqrt()).abs() < 1e-12);
        assert!(s.condition > 1.0);
    }

    /// `y = a + b t + c t^2 + k (t^3 - 7 t)` at `t = -3..3`: the cubic term is the discrete
    /// orthogonal polynomial of degree 3 on these points (`sum t^j (t^3 - 7t) = 0` for
    /// j = 0, 1, 2: the values are -6, 6, 6, 0, -6, -6, 6), so the normal equations'
    /// solution is `(a, b, c)` exactly, with residuals `k (t^3 - 7t)` (cost `108 k^2`).
    struct Quadratic {
        truth: [f64; 3],
        k: f64,
    }
    impl Problem<f64> for Quadratic {
        type D = nalgebra::U3;
        fn dim(&self) -> nalgebra::U3 {
            nalgebra::U3
        }
        fn n_rows(&self) -> usize {
            7
        }
        fn rows(
            &self,
            x: &nalgebra::Vector3<f64>,
            _jac: bool,
            sink: &mut dyn FnMut(f64, f64, &[f64]),
        ) -> Result<(), ModelError> {
            let [a, b, c] = self.truth;
            for i in -3..=3 {
                let t = f64::from(i);
                let y = a + b * t + c * t * t + self.k * (t * t * t - 7.0 * t);
                sink(y - (x[0] + x[1] * t + x[2] * t * t), 1.0, &[1.0, t, t * t]);
            }
            Ok(())
        }
    }

    /// A linear problem from a far start with large residuals: the first Gauss-Newton step
    /// lands on the answer up to the rounding of a 1e5-long step (~1e-11), and the final,
    /// tiny step (taken without a model evaluation, `Stop::SmallPredictedDecrease`) must
    /// remove that: the answer equals the closed-form least-squares solution to 1e-12.
    #[test]
    fn linear_problem_matches_the_normal_equations() {
        let truth = [2.0, -3.0, 0.5];
        for (k, x0) in [
            (100.0, [1e5, -1e5, 1e5]),
            (3.0, [-4e4, 7e4, 2e4]),
            (0.0, [1e5, 1e5, -1e5]),
        ] {
            let p = Quadratic { truth, k };
            let s = solve(&p, nalgebra::Vector3::from(x0), &Settings::default()).unwrap();
            for (i, (got, want)) in s.x.iter().zip(truth).enumerate() {
                assert!(
                    (got - want).abs() < 1e-12,
                    "k {k}: x{i} = {got} want {want} ({:?})",
                    s.stop
                );
            }
            assert!((s.cost - 108.0 * k * k).abs() <= 1e-9 * (1.0 + 108.0 * k * k));
        }
    }

    /// The nonlinear `y = a exp(b t)` with residuals that do not vanish at the answer: GLSDC's
    /// answer against an independent plain Gauss-Newton run to convergence (2 x 2 normal
    /// equations by Cramer's rule, 200 steps). GLSDC stops once a Gauss-Newton step would
    /// gain less than `cost_tol` (16 eps) of the cost, so it ends a little short of the
    /// minimum: here 1.2-1.4e-9 from it; without the final step (taken without evaluating
    /// the model), 1.3-1.5e-8. Hence 4e-9.
    #[test]
    fn nonlinear_problem_converges_to_the_minimum() {
        let t: [f64; 10] = core::array::from_fn(|i| i as f64 * 0.4);
        let wiggle = [0.3, -0.2, 0.25, -0.4, 0.1, 0.35, -0.3, 0.05, -0.15, 0.2];
        let y: [f64; 10] = core::array::from_fn(|i| 2.0 * (-0.7 * t[i]).exp() + wiggle[i]);
        let mut r = [2.0f64, -0.7];
        for _ in 0..200 {
            let (mut n00, mut n01, mut n11, mut g0, mut g1) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for i in 0..10 {
                let e = (r[1] * t[i]).exp();
                let (j0, j1, res) = (e, r[0] * t[i] * e, y[i] - r[0] * e);
                n00 += j0 * j0;
                n01 += j0 * j1;
                n11 += j1 * j1;
                g0 += j0 * res;
                g1 += j1 * res;
            }
            let det = n00 * n11 - n01 * n01;
            r[0] += (n11 * g0 - n01 * g1) / det;
            r[1] += (n00 * g1 - n01 * g0) / det;
        }
        for x0 in [
            Vector2::new(10.0, 1.0),
            Vector2::new(1.0, -2.0),
            Vector2::new(2.5, -0.5),
        ] {
            let s = solve(&Exp::new(&t, &y), x0, &Settings::default()).unwrap();
            assert!(
                (s.x[0] - r[0]).abs() < 4e-9 && (s.x[1] - r[1]).abs() < 4e-9,
                "from {x0:?}: {:?} want {r:?} ({:?})",
                s.x,
                s.stop
            );
        }
    }

    #[test]
    fn iteration_cap_reports_last_cost_not_nan() {
        let t: [f64; 8] = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5];
        let y: [f64; 8] = core::array::from_fn(|i| 2.0 * (-0.7 * t[i]).exp());
        let p = Exp::new(&t, &y);
        let s = Settings {
            max_iter: 1,
            ..Settings::default()
        };
        match solve(&p, Vector2::new(10.0, 1.0), &s) {
            Err(Error::NotConverged {
                x,
                cost,
                iterations,
            }) => {
                assert_eq!(iterations, 1);
                assert!(cost.is_finite() && cost > 0.0 && x.iter().all(|v| v.is_finite()));
            }
            other => panic!("expected NotConverged, got {other:?}"),
        }
    }

    #[test]
    fn carried_linearisation_starts_the_next_solve() {
        let t: [f64; 8] = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5];
        // Residuals of +-0.01, so that the covariance is not all rounding.
        let e = |i: usize| if i.is_multiple_of(2) { 0.01 } else { -0.01 };
        let y1: [f64; 8] = core::array::from_fn(|i| 2.0 * (-0.7 * t[i]).exp() + e(i));
        let y2: [f64; 8] = core::array::from_fn(|i| 2.02 * (-0.69 * t[i]).exp() - e(i));
        let settings = Settings {
            jacobian_in_trial: true,
            ..Settings::default()
        };
        // A store of m (n + 1) values; the first problem's solve, carried.
        let first = |tells: bool, x0: Vector2<f64>| {
            let mut p1 = Exp::new(&t, &y1);
            p1.tells = tells;
            let mut store = [0.0; 24];
            let mut carry = None;
            let s1 = solve_with(&p1, x0, &settings, &mut store, &mut carry).unwrap();
            assert!(carry.is_some(), "the last linearisation is carried");
            (s1, store, carry)
        };
        let (s1, _, _) = first(true, Vector2::new(1.5, -0.5));
        // The next problem from the last answer, afresh.
        let fresh = Exp::new(&t, &y2);
        let a = solve_with(&fresh, s1.x, &settings, &mut [0.0; 24], &mut None).unwrap();
        // With the carried linearisation: from the predicted residuals (no model pass
        // before the first step), from a residual pass when the problem does not give its
        // measurements, and from a residual pass when the start is not the carried answer.
        let x_other = s1.x + Vector2::new(1e-3, -1e-3);
        for (tells, x0, residual_passes) in [(true, s1.x, 0), (false, s1.x, 1), (true, x_other, 1)]
        {
            let (_, mut store, mut carry) = first(tells, Vector2::new(1.5, -0.5));
            let mut carried = Exp::new(&t, &y2);
            carried.tells = tells;
            let b = solve_with(&carried, x0, &settings, &mut store, &mut carry).unwrap();
            let case = format!("measurements given: {tells}, start {x0:?}");
            assert!((a.x - b.x).norm() < 1e-9, "{case}: {:?} vs {:?}", a.x, b.x);
            assert!((a.sigma - b.sigma).norm() < 1e-6 * a.sigma.norm(), "{case}");
            assert!(
                carried.passes().0 < fresh.passes().0,
                "{case}: Jacobian passes: {} carried, {} fresh",
                carried.passes().0,
                fresh.passes().0
            );
            assert_eq!(
                carried.passes().1,
                residual_passes,
                "{case}: residual passes"
            );
        }
        // Too small a store keeps nothing and carries nothing.
        let p1 = Exp::new(&t, &y1);
        let mut none = None;
        let x0 = Vector2::new(1.5, -0.5);
        solve_with(&p1, x0, &settings, &mut [0.0; 23], &mut none).unwrap();
        assert!(none.is_none());
    }

    /// Four readings of `a` and four of `b`: exact fits in one step, in exact binary
    /// arithmetic (the normal matrix is 4 I, its Jacobi scale 1/2), so a carried step can
    /// reach zero cost.
    struct Pairs {
        y: [f64; 8],
        passes: Passes,
    }
    impl Pairs {
        fn new(a: f64, b: f64) -> Self {
            Pairs {
                y: core::array::from_fn(|i| if i < 4 { a } else { b }),
                passes: Passes::default(),
            }
        }
    }
    impl Problem<f64> for Pairs {
        type D = U2;
        fn dim(&self) -> U2 {
            U2
        }
        fn n_rows(&self) -> usize {
            8
        }
        fn rows(
            &self,
            x: &Vector2<f64>,
            jac: bool,
            sink: &mut dyn FnMut(f64, f64, &[f64]),
        ) -> Result<(), ModelError> {
            self.passes.count(jac);
            for (i, &y) in self.y.iter().enumerate() {
                let k = usize::from(i >= 4);
                let mut j = [0.0; 2];
                j[k] = 1.0;
                sink(y - x[k], 1.0, if jac { &j } else { &[] });
            }
            Ok(())
        }
        fn measurements(&self, sink: &mut dyn FnMut(f64, f64)) -> bool {
            self.y.iter().for_each(|&y| sink(y, 1.0));
            true
        }
    }

    /// A step of the carried Jacobian that reaches zero cost stops the solve (the only stop
    /// decided away from a fresh linearisation: nothing is left to gain). Its linearisation
    /// is the carried one, whose kept rows already hold the earlier solve's predictions:
    /// they must not be turned into predictions again. The solve after it then starts from
    /// one residual pass and is exact in one step; predictions made from the stale rows
    /// would start it wrong and cost further passes.
    #[test]
    fn zero_cost_on_a_carried_step_keeps_the_carry_sound() {
        for jacobian_in_trial in [false, true] {
            let settings = Settings {
                jacobian_in_trial,
                ..Settings::default()
            };
            let mut store = [0.0; 24];
            let mut carry = None;
            let case = format!("jacobian_in_trial {jacobian_in_trial}");
            let mut run = |p: &Pairs, x0: Vector2<f64>| {
                let s = solve_with(p, x0, &settings, &mut store, &mut carry).unwrap();
                assert!(carry.is_some(), "{case}: carried on");
                s
            };
            let p1 = Pairs::new(1.0, 2.0);
            let s1 = run(&p1, Vector2::new(0.0, 0.0));
            assert_eq!(s1.x, Vector2::new(1.0, 2.0), "{case}");
            // From the carried answer: predicted residuals, one carried step to zero cost.
            let p2 = Pairs::new(3.0, 5.0);
            let s2 = run(&p2, s1.x);
            assert_eq!(s2.x, Vector2::new(3.0, 5.0), "{case}");
            assert_eq!(s2.stop, Stop::ZeroCost, "{case}");
            assert_eq!(s2.iterations, 1, "{case}");
            assert_eq!(
                p2.passes.get(),
                (
                    usize::from(jacobian_in_trial),
                    usize::from(!jacobian_in_trial)
                ),
                "{case}: the trial is the only model pass"
            );
            let p3 = Pairs::new(4.0, 4.0);
            let s3 = run(&p3, s2.x);
            assert_eq!(s3.x, Vector2::new(4.0, 4.0), "{case}");
            assert_eq!(s3.iterations, 1, "{case}");
            // With the trial's fresh rows (jacobian_in_trial) the third solve starts from
            // predictions again; else from one residual pass over the carried rows.
            let expected = match jacobian_in_trial {
                true => (1, 0),
                false => (0, 2),
            };
            assert_eq!(
                p3.passes.get(),
                expected,
                "{case}: model passes of the third solve"
            );
            assert!(s3.sigma.iter().all(|s| *s == 0.0), "{case}: {:?}", s3.sigma);
        }
    }

    #[test]
    fn cholesky_helper_matches_nalgebra() {
        use nalgebra::{Matrix5, Vector5};
        let g = Matrix5::from_fn(|i, j| {
            ((i * 7 + j * 3) % 5) as f64 - 1.7 + 0.3 * (i == j) as u8 as f64
        });
        let a = g.transpose() * g + Matrix5::identity() * 0.1;
        let ch = Chol::new(&a).unwrap();
        let inv = a.cholesky().unwrap().inverse();
        assert!((ch.inverse() - inv).norm() < 1e-9 * inv.norm());
        assert!((ch.inverse_trace() - inv.trace()).abs() < 1e-9 * inv.trace());
        let b = Vector5::new(1.0, -2.0, 0.5, 3.0, -1.0);
        assert!((a * ch.solve(&b) - b).norm() < 1e-9);
        let mut bad = a;
        bad[(3, 3)] = -1.0;
        assert!(Chol::new(&bad).is_none());
    }

    #[test]
    fn works_in_f32() {
        struct Lin32;
        impl Problem<f32> for Lin32 {
            type D = U2;
            fn dim(&self) -> U2 {
                U2
            }
            fn n_rows(&self) -> usize {
                5
            }
            fn rows(
                &self,
                x: &Vector2<f32>,
                _j: bool,
                sink: &mut dyn FnMut(f32, f32, &[f32]),
            ) -> Result<(), ModelError> {
                for i in 0..5 {
                    let t = i as f32;
                    sink(1.5 + 0.25 * t - (x[0] + x[1] * t), 1.0, &[1.0, t]);
                }
                Ok(())
            }
        }
        let s = solve(&Lin32, Vector2::new(0.0f32, 0.0), &Settings::default()).unwrap();
        assert!((s.x[0] - 1.5).abs() < 1e-5 && (s.x[1] - 0.25).abs() < 1e-5);
    }
}
