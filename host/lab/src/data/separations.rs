//! Separations: the list and range syntax of `--separations`, the matching of a requested
//! separation to the file's nearest, and their formatting.

use std::path::PathBuf;

use super::Dataset;

/// Why a separation list is refused, or a selection finds no such separation in the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SeparationError {
    /// The step of a range is not a number.
    #[error("bad step in `{0}`")]
    BadStep(String),
    /// The start of a range is not a number.
    #[error("bad range start in `{0}`")]
    BadStart(String),
    /// The end of a range is not a number.
    #[error("bad range end in `{0}`")]
    BadEnd(String),
    /// A range with an infinite or NaN end or step.
    #[error("range `{0}`: the ends and the step must be finite numbers of inches")]
    NotFinite(String),
    /// A range `A..B` with `B < A`, or a step that is not positive.
    #[error("empty range `{0}` (use A..B with A <= B, step > 0)")]
    EmptyRange(String),
    /// A range giving more than [`MAX_SEPARATIONS`].
    #[error(
        "range `{part}` gives {count:.0} separations{}, more than the {MAX_SEPARATIONS} allowed \
         (use a larger step, e.g. `{start}..{end}:{step}`)",
        after(.before)
    )]
    RangeTooLong {
        /// The range as given.
        part: String,
        /// How many it gives.
        count: f64,
        /// Separations listed before it.
        before: usize,
        /// Its start, in.
        start: f64,
        /// Its end, in.
        end: f64,
        /// A step that keeps it within the limit.
        step: f64,
    },
    /// A list item that is not a number.
    #[error("`{0}` is not a separation in inches")]
    NotANumber(String),
    /// A list of more than [`MAX_SEPARATIONS`] items.
    #[error("more than the {MAX_SEPARATIONS} separations allowed in `{0}`")]
    TooMany(String),
    /// An empty list.
    #[error("no separations given")]
    NoneGiven,
    /// A separation that is not positive and finite.
    #[error("separation {0} in must be a positive, finite number of inches")]
    NotPositive(f64),
    /// A separation listed twice where the list makes data.
    #[error("{value} in is listed twice in `{list}`")]
    ListedTwice {
        /// The separation, in.
        value: f64,
        /// The list as given.
        list: String,
    },
    /// Separations asked for that the file does not have, nor any within [`SEP_MATCH_IN`].
    #[error(
        "{}: separation(s) {} not in the file, nor any within {SEP_MATCH_IN} in (it has {})",
        .path.display(), .missing.join(", "), fmt_list(.have)
    )]
    NotInFile {
        /// The measurement file.
        path: PathBuf,
        /// The separations asked for and not found, as given.
        missing: Vec<String>,
        /// The file's separations.
        have: Vec<f64>,
    },
}

impl Dataset {
    /// The distinct separations, ascending.
    pub fn separations(&self) -> Vec<f64> {
        let mut v: Vec<f64> = self.samples.iter().map(|s| s.separation_in).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    }

    /// The file's separation nearest to `want`, when one lies within [`SEP_MATCH_IN`]: a
    /// swept file records the measured mean of the four corner readings (`10.0125` for a
    /// nominal 10 in), so a requested `10` must find it.
    pub fn nearest_separation(&self, want: f64) -> Option<f64> {
        nearest_within(&self.separations(), want)
    }

    /// Keep only the given separations, each matched to the file's nearest separation within
    /// [`SEP_MATCH_IN`] (so `25,30` finds the measured 24.995 and 30.005). Errors name the
    /// requested separations with no file separation that near.
    pub fn select(&self, seps: &[f64]) -> Result<Dataset, SeparationError> {
        let have = self.separations();
        let mut keep: Vec<f64> = Vec::new();
        let mut missing: Vec<String> = Vec::new();
        for &s in seps {
            match nearest_within(&have, s) {
                Some(h) => keep.push(h),
                None => missing.push(format!("{s}")),
            }
        }
        if !missing.is_empty() {
            return Err(SeparationError::NotInFile {
                path: self.path.clone(),
                missing,
                have,
            });
        }
        Ok(Dataset {
            path: self.path.clone(),
            samples: self
                .samples
                .iter()
                .filter(|s| keep.contains(&s.separation_in))
                .copied()
                .collect(),
        })
    }
}

/// ` (after N before it)` when a list gave separations before a range, for its message.
fn after(before: &usize) -> String {
    if *before == 0 {
        String::new()
    } else {
        format!(" (after {before} before it)")
    }
}

/// Format a list of separations compactly.
pub fn fmt_list(v: &[f64]) -> String {
    v.iter()
        .map(|s| format!("{s}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The most separations a list or range may give (`cta simulate --separations`, a sweep
/// plan's `separations_in`): the count is computed before anything is expanded, so a range
/// like `1..1e12` or `2..30:0.0000001` is refused at once instead of filling the memory.
pub const MAX_SEPARATIONS: usize = 10_000;

/// Separations above this (in) are far beyond the CTA (0-30 in) and the sweep plans' 60 in
/// limit, and beyond the 100 in of the README's Figure 57 example: [`Dataset::warnings`]
/// asks whether the file is in millimetres.
pub const FAR_SEPARATION_IN: f64 = 120.0;

/// Separations closer than this (in) are one plate position written two ways when one has far
/// more rows ([`SEP_TYPO_RATIO`]): twice Ch IV's +/-5 mil bound on a separation, closer than
/// the CTA can set two positions apart, while a typo in the last digits falls inside it.
pub const SEP_TYPO_IN: f64 = 0.01;

/// A separation is warned about as a typo when a neighbour within [`SEP_TYPO_IN`] has at least
/// this many times its rows: a few rows beside a whole plate position. (Two values with
/// comparable rows are rather two positions, or a plate re-measured mid-sweep.)
pub const SEP_TYPO_RATIO: usize = 4;

/// How far (in) a requested separation may lie from a recorded one and still select it: a
/// few times the scatter of a measured plate position (the mean of four corner readings,
/// +/-0.015 in on the CTA), and well under the 1 in between the CTA's closest separations.
pub const SEP_MATCH_IN: f64 = 0.1;

/// The value of `have` nearest to `want`, when it lies within [`SEP_MATCH_IN`].
pub fn nearest_within(have: &[f64], want: f64) -> Option<f64> {
    have.iter()
        .copied()
        .filter(|h| (h - want).abs() <= SEP_MATCH_IN)
        .min_by(|a, b| (a - want).abs().total_cmp(&(b - want).abs()))
}

/// Parse a separation list: `20,25`, `2..30` (step 1), `2..30:2` (step 2), or a mix
/// `3,5,20..30:5`. Every end and step must be finite, and the whole list may give at most
/// [`MAX_SEPARATIONS`] separations.
pub fn parse_separations(s: &str) -> Result<Vec<f64>, SeparationError> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        if let Some((a, rest)) = part.split_once("..") {
            let (b, step) = match rest.split_once(':') {
                Some((b, st)) => (
                    b,
                    st.trim()
                        .parse::<f64>()
                        .map_err(|_| SeparationError::BadStep(part.into()))?,
                ),
                None => (rest, 1.0),
            };
            let a: f64 = a
                .trim()
                .parse()
                .map_err(|_| SeparationError::BadStart(part.into()))?;
            let b: f64 = b
                .trim()
                .parse()
                .map_err(|_| SeparationError::BadEnd(part.into()))?;
            if !(a.is_finite() && b.is_finite() && step.is_finite()) {
                return Err(SeparationError::NotFinite(part.into()));
            }
            if !(step > 0.0) || b < a {
                return Err(SeparationError::EmptyRange(part.into()));
            }
            // Count first (in floating point: no overflow), expand only when it is small.
            let count = ((b - a) / step + 1e-9).floor() + 1.0;
            if count + out.len() as f64 > MAX_SEPARATIONS as f64 {
                return Err(SeparationError::RangeTooLong {
                    part: part.into(),
                    count,
                    before: out.len(),
                    start: a,
                    end: b,
                    step: suggest_step(a, b),
                });
            }
            let n = count as usize - 1;
            for k in 0..=n {
                out.push(a + step * k as f64);
            }
        } else {
            out.push(
                part.parse::<f64>()
                    .map_err(|_| SeparationError::NotANumber(part.into()))?,
            );
            if out.len() > MAX_SEPARATIONS {
                return Err(SeparationError::TooMany(s.into()));
            }
        }
    }
    if out.is_empty() {
        return Err(SeparationError::NoneGiven);
    }
    if let Some(bad) = out.iter().find(|s| !(**s > 0.0 && s.is_finite())) {
        return Err(SeparationError::NotPositive(*bad));
    }
    Ok(out)
}

/// [`parse_separations`] for a list that makes data (`simulate --separations`): a separation
/// given twice is refused, as it would be simulated twice, a file its readers refuse as pasted
/// in twice. (A selection may overlap: `2..10,10..30:5` selects 10 in once.)
pub fn parse_new_separations(s: &str) -> Result<Vec<f64>, SeparationError> {
    let out = parse_separations(s)?;
    let mut sorted = out.clone();
    sorted.sort_by(f64::total_cmp);
    if let Some(w) = sorted.windows(2).find(|w| w[1] - w[0] < 1e-9) {
        return Err(SeparationError::ListedTwice {
            value: w[0],
            list: s.into(),
        });
    }
    Ok(out)
}

/// A step that keeps `a..b` within [`MAX_SEPARATIONS`] (a round number), for the message.
fn suggest_step(a: f64, b: f64) -> f64 {
    let need = (b - a) / (MAX_SEPARATIONS as f64 - 1.0);
    let p = 10f64.powf(need.log10().ceil());
    if p.is_finite() && p > 0.0 {
        p
    } else {
        1.0
    }
}
