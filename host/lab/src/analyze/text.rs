//! Wording shared by the text the command line prints and the HTML report: correlation
//! lines, a cause's rivals and parameters, a candidate's estimates, numbers and units.

use super::digits::pm;
use super::params::spreads;
use super::result::{
    Cause, Correlation, DroppedOut, Param, RuledOut, SepSpread, TrialOut, RIVAL_DBIC,
};
use super::select;

/// `A,B +0.66, C,D -0.51`.
pub fn correlations_text(c: &[Correlation]) -> String {
    c.iter()
        .map(|c| format!("{},{} {:+.2}", c.a, c.b, c.rho))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The correlation lines of a candidate (empty when none reaches its threshold):
/// `correlation: DX,DY +0.66`, `correlation with the starting model: S,d3 +0.93`.
pub fn correlation_lines(own: &[Correlation], base: &[Correlation]) -> Vec<String> {
    let mut v = Vec::new();
    if !own.is_empty() {
        v.push(format!("correlation: {}", correlations_text(own)));
    }
    if !base.is_empty() {
        v.push(format!(
            "correlation with the starting model: {}",
            correlations_text(base)
        ));
    }
    v
}

/// `correlation between causes: beacon_pattern.H_deg,proximity.S +1.00`, or None when there
/// is none
/// ([`Analysis::cross_correlations`]).
pub fn cross_correlation_line(c: &[Correlation]) -> Option<String> {
    (!c.is_empty()).then(|| format!("correlation between causes: {}", correlations_text(c)))
}

impl Cause {
    /// "`X` explains the data about as well ..." when the cause has rivals.
    pub fn rivals_line(&self) -> Option<String> {
        if self.rivals.is_empty() {
            return None;
        }
        let list: Vec<String> = self
            .rivals
            .iter()
            .map(|r| format!("{} (dBIC {:.1} vs {:.1})", r.effect, r.dbic, self.dbic))
            .collect();
        Some(format!(
            "but {} {} the data about as well: a BIC difference below {RIVAL_DBIC} does not \
             tell them apart (host/ANALYZE.md, Detection limits)",
            list.join(", "),
            if list.len() == 1 {
                "explains"
            } else {
                "explain"
            }
        ))
    }

    /// The global (not per-separation) parameters as `name = value PM sigma` strings
    /// ([`digits`]: the value to the decimal place of its 1-sigma's second digit).
    pub fn global_params(&self, pmark: &str) -> Vec<String> {
        self.params
            .iter()
            .filter(|(n, _)| !n.contains('@'))
            .map(|(n, v)| {
                let u = unit(&self.effect, n);
                if v.is_nan() {
                    // beacon_pattern's H_deg with m <= 0.
                    return format!(
                        "{n} = none (no half-intensity angle: the pattern does not fall off \
                         the axis)"
                    );
                }
                match self.sigma.get(n) {
                    Some(sg) => format!("{n} = {}{u}", pm(*v, *sg, pmark)),
                    None => format!("{n} = {}{u}", g(*v)),
                }
            })
            .collect()
    }
}

impl DroppedOut {
    /// One line of text: why it was dropped.
    pub fn line(&self) -> String {
        let why = match self.heldout_rms_without {
            None => format!(
                "keeping its {} parameters gains dBIC {:.0} (dchi2 {:.0}), at most {}",
                self.k,
                self.dbic_keep,
                self.dchi2_keep,
                select::BIC_MIN
            ),
            Some(w) => format!(
                "without it the held-out RMS is {w:.2} counts, {:.2} with it",
                self.heldout_rms_with
            ),
        };
        format!(
            "{}: named in round {} (dBIC {:.0}), but once {} {} named, {why}: it stood in for \
             them, so the search was rerun without it",
            self.effect,
            self.round,
            self.dbic_named,
            self.others.join(", "),
            if self.others.len() == 1 {
                "was"
            } else {
                "were"
            },
        )
    }
}

/// The unit of a candidate's parameter as printed (` in`, ` deg`, ...; empty for ratios and
/// names that carry their unit).
pub fn unit(effect: &str, param: &str) -> &'static str {
    match (effect, param) {
        ("proximity", "S") | ("led_position", "rms_in") | ("array_pose", "rms_in") => " in",
        ("cell_bias", _) | ("ambient", _) | ("saturation", "S") => " /in^2",
        ("face_angle", _) => " deg",
        _ => "",
    }
}

/// A candidate's estimates in one line: global parameters as `name = value PM sigma unit`
/// (with the no-effect value when it is not 0), per-separation ones as the RMS over the
/// separations against the RMS noise alone would give. "a switch, no parameter" for a fitted
/// candidate without parameters (`intensity`), empty when it was not fitted.
fn estimates_text(
    effect: &str,
    globals: &[&Param],
    spreads: &[SepSpread],
    fitted: bool,
    pmark: &str,
) -> String {
    let mut parts: Vec<String> = globals
        .iter()
        .map(|p| {
            let base = format!(
                "{} = {}{}",
                p.name,
                pm(p.value, p.sigma, pmark),
                unit(effect, &p.name)
            );
            match p.no_effect {
                Some(n) if n != 0.0 => format!("{base} (no effect: {})", g(n)),
                _ => base,
            }
        })
        .collect();
    if let Some(sp) = spreads.first() {
        let each: Vec<String> = spreads
            .iter()
            .map(|p| {
                // Names that carry their unit (`tx_deg`) print without one; the rest are in.
                let u = if p.name.ends_with("_deg") { "" } else { " in" };
                format!(
                    "{} weighted RMS {:.1e}{u} (noise alone {:.1e})",
                    p.name, p.rms, p.noise_rms
                )
            })
            .collect();
        let per = if effect.starts_with("led_") {
            "per LED"
        } else if effect == "array_pose" {
            "per array"
        } else {
            "per separation"
        };
        parts.push(format!("{per} ({}): {}", sp.separations, each.join(", ")));
    }
    if parts.is_empty() && fitted {
        parts.push("a switch, no parameter".into());
    }
    parts.join(", ")
}

impl RuledOut {
    /// The estimates in one line (empty when the candidate was not fitted).
    pub fn estimates(&self, pmark: &str) -> String {
        let globals: Vec<&Param> = self.params.iter().collect();
        estimates_text(
            &self.effect,
            &globals,
            &self.per_separation,
            self.fitted,
            pmark,
        )
    }
}

impl TrialOut {
    /// The estimates in one line (empty when the candidate was not fitted).
    pub fn estimates(&self, pmark: &str) -> String {
        let globals: Vec<&Param> = self
            .params
            .iter()
            .filter(|p| !p.name.contains('@'))
            .collect();
        estimates_text(
            &self.effect,
            &globals,
            &spreads(&self.params),
            self.fitted,
            pmark,
        )
    }
}

/// Compact number formatting.
pub fn g(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        format!("{:.6}", v)
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{v:.4e}")
    }
}
