//! Sweep plans: what a run measures, as data (a TOML file, documented in `host/SWEEP.md`).
//!
//! A plan is parsed strictly: unknown keys, missing keys and impossible values are errors
//! naming the file, the line and the key. A parsed [`Plan`] expands into an ordered list of
//! [`Point`]s (one beacon, lit at one frequency, at one power level and one sensitivity
//! setting, at one separation); the order is fixed by the plan alone, so a point's index
//! identifies it across a resume.
//!
//! Loop order, outermost first (thesis Ch VI: "finish a separation before moving the
//! plate"): separation, quadrant (quad layout only), power level, sensitivity, beacon,
//! frequency. Power levels alternate direction from one plate position to the next
//! (serpentine), so the operator flips the power switches once per plate position instead
//! of twice.

use std::fmt;
use std::path::Path;

use cta_core::pose::MAX_BEACONS as MAX_SPOTS;
use cta_core::schedule::{tick_cost, NORTHSTAR_TABLE_MHZ, TICK_BUDGET};
use cta_core::wire::beacon::{FreqSet, LedMode, DEADMAN_DEFAULT_MS, LED_COUNT, MAX_LIT_DEFAULT};
use cta_firmware_beacon::pins::BEACON_LINES;
use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::groups::Cached;
use super::metadata::{Metadata, EXPECTED};
use crate::data::parse_separations;

/// Longest `[timing] heartbeat_ms` accepted: half the beacon board's dead-man timeout
/// ([`DEADMAN_DEFAULT_MS`], 10 s; the sweep never changes it, and refuses a board whose timer
/// is shorter than twice the plan's heartbeat when it connects), so a heartbeat that is late by a
/// slow request or a settle step still arrives before the board turns the LED off mid-point.
pub const MAX_HEARTBEAT_MS: u64 = DEADMAN_DEFAULT_MS as u64 / 2;

/// How the beacon array is mounted on the plate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Layout {
    /// One 10 x 10 array centred on the plate.
    Single,
    /// The quad-array layout: the array is mounted in each of the plate's four quadrants in
    /// turn (a manual step), centres `spacing` inches apart in x and y. The row-major beacon
    /// id written to the data is `100 * quadrant + led`.
    Quad {
        /// Distance between neighbouring array centres, inches (10 = no gap).
        spacing: f64,
    },
}

impl Layout {
    /// Number of array placements per separation.
    pub fn quadrants(&self) -> usize {
        match self {
            Layout::Single => 1,
            Layout::Quad { .. } => 4,
        }
    }

    /// Centre of the array in quadrant `q` (N frame, inches): quadrants 0..4 are
    /// (-x,-y), (+x,-y), (-x,+y), (+x,+y).
    pub fn centre(&self, q: usize) -> [f64; 2] {
        match *self {
            Layout::Single => [0.0, 0.0],
            Layout::Quad { spacing } => {
                let h = spacing / 2.0;
                [
                    if q.is_multiple_of(2) { -h } else { h },
                    if q < 2 { -h } else { h },
                ]
            }
        }
    }
}

/// A validated plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// Free-text name.
    pub name: String,
    /// Nominal plate separations, inches, in measurement order.
    pub separations: Vec<f64>,
    /// Array mounting.
    pub layout: Layout,
    /// Beacons (LED ids 0..99 on the array, row-major from the -x,-y corner).
    pub beacons: Vec<u8>,
    /// Modulation frequencies, Hz (each one of the NorthStar table).
    pub frequencies_hz: Vec<f64>,
    /// Drive levels (the array's slide switches: 1 = 1 kOhm, 2 = 360 Ohm).
    pub power_levels: Vec<u8>,
    /// NorthStar sensitivity settings, 1..=4.
    pub sensitivities: Vec<u8>,
    /// Samples (sensor reports with the beacon's spot) per point.
    pub samples: u32,
    /// Wait between lighting a beacon and sampling, ms.
    pub settle_ms: u64,
    /// NorthStar report rate, Hz (10 is the sensor's typical rate).
    pub rate_hz: u8,
    /// Wait for one reply, ms.
    pub request_timeout_ms: u64,
    /// Resends of an unanswered request before the board counts as gone.
    pub retries: u32,
    /// A streaming sensor that sends no report for this long is stalled, ms.
    pub report_timeout_ms: u64,
    /// Reports without the beacon's spot after which the point is recorded as "no signal".
    pub no_signal_reports: u32,
    /// Largest number of reports read for one point (samples missing beyond this: the point is
    /// recorded as partial).
    pub max_reports: u32,
    /// Heartbeat the beacon board at least this often while sampling, ms.
    pub heartbeat_ms: u64,
    /// Longest wait between reconnection attempts to a lost board, s (backoff doubles up to it).
    pub backoff_max_s: f64,
    /// Give up (stop the run, resumable) after a board has been lost this long, s.
    pub give_up_s: f64,
    /// Beacons lit at once, each at its own frequency of `frequencies_hz` (1: one at a time).
    #[serde(default = "one")]
    pub group: usize,
    /// Frequencies of `frequencies_hz` each beacon is measured at per setting, in rounds that
    /// turn its frequency ([`super::groups`]); 0 (plans journalled before groups): all.
    #[serde(default)]
    pub frequencies_per_beacon: usize,
    /// Beacons per separation measured alone as well as in their group (the crosstalk check).
    #[serde(default)]
    pub crosstalk_check: usize,
    /// The `[metadata]` table: free key-value pairs describing the run (sensor serial,
    /// operator, temperature...), journalled with each session's plan.
    #[serde(default)]
    pub metadata: Metadata,
    /// The groups, built from the keys above on first use.
    #[serde(skip)]
    pub(crate) schedule: Cached,
}

fn one() -> usize {
    1
}

/// The plan keys `cta sweep --resume` accepts changed: the `[timing]` keys that govern only
/// how long the run waits and how often it tries again, never what is measured, where, or how
/// it is recorded. A committed point's rows come from one complete attempt; when a wait runs
/// out the attempt is abandoned with nothing of it written and the point is measured again
/// from the start (the simulated CTA's noise depends on the point and the sample, not on
/// time), or the run stops, resumable. So points measured before and after the change are the
/// same measurement:
///
/// * `timing.request_timeout_ms`, `timing.retries`: how long a reply is awaited and how often
///   a request is resent before the board counts as lost (the point is then retried);
/// * `timing.report_timeout_ms`: how long a streaming sensor may stay silent before it counts
///   as stalled (the point is then retried);
/// * `timing.heartbeat_ms`: how often the beacon board hears from the host while a point is
///   measured; the plan check keeps it within half the board's dead-man timer
///   ([`MAX_HEARTBEAT_MS`]), so the LED stays lit through every point whatever the value;
/// * `timing.backoff_max_s`, `timing.give_up_s`: the pauses between reconnection attempts to a
///   lost board, and how long they go on before the run stops.
///
/// Every other key stays as the run started, `[timing]` ones included:
/// `timing.no_signal_reports` and `timing.max_reports` decide whether a point is recorded as
/// ok, partial or "no signal" (rows, or a comment line instead); `settle_ms` (how long the
/// light settles before sampling) and `rate_hz` (the NorthStar's report rate) shape the
/// measurement on the apparatus; `name` is in the data file's header; the others define and
/// number the points.
///
/// `metadata` may change too: it describes the run (who operates it, the room's temperature,
/// which spare cable is in) and is neither measured nor used to number or record a point, so
/// it can be brought up to date at a resume (a new operator, a warmer afternoon). Nothing is
/// lost by it: each session journals its plan with the metadata it ran under, and the change
/// is said in a note.
pub const RESUME_MAY_CHANGE: [&str; 7] = [
    "timing.request_timeout_ms",
    "timing.retries",
    "timing.report_timeout_ms",
    "timing.heartbeat_ms",
    "timing.backoff_max_s",
    "timing.give_up_s",
    "metadata",
];

/// A plan key's value in a [`Plan`], in full, as [`Plan::differences`] compares it.
pub type KeyValue = fn(&Plan) -> String;

/// Every plan key as written in the file (`[timing]` ones as `timing.KEY`), with its value.
pub const KEYS: [(&str, KeyValue); 22] = [
    ("name", |p| show(&p.name)),
    ("separations_in", |p| show(&p.separations)),
    ("layout", |p| match p.layout {
        Layout::Single => "\"single\"".into(),
        Layout::Quad { spacing } => format!("\"quad\" (quad_spacing_in {spacing})"),
    }),
    ("beacons", |p| show(&p.beacons)),
    ("frequencies_hz", |p| show(&p.frequencies_hz)),
    ("power_levels", |p| show(&p.power_levels)),
    ("sensitivities", |p| show(&p.sensitivities)),
    ("samples", |p| show(&p.samples)),
    ("settle_ms", |p| show(&p.settle_ms)),
    ("rate_hz", |p| show(&p.rate_hz)),
    ("group", |p| show(&p.group)),
    ("frequencies_per_beacon", |p| show(&p.rounds())),
    ("crosstalk_check", |p| show(&p.crosstalk_check)),
    ("timing.request_timeout_ms", |p| show(&p.request_timeout_ms)),
    ("timing.retries", |p| show(&p.retries)),
    ("timing.report_timeout_ms", |p| show(&p.report_timeout_ms)),
    ("timing.no_signal_reports", |p| show(&p.no_signal_reports)),
    ("timing.max_reports", |p| show(&p.max_reports)),
    ("timing.heartbeat_ms", |p| show(&p.heartbeat_ms)),
    ("timing.backoff_max_s", |p| show(&p.backoff_max_s)),
    ("timing.give_up_s", |p| show(&p.give_up_s)),
    ("metadata", |p| p.metadata.to_string()),
];

/// Plan keys whose default is computed from other keys: the key, the keys its default
/// follows, and that default for a plan. When such a key is left at its default, a change of
/// the keys it follows changes it too: [`Plan::differences`] then shows it as following them
/// ([`Change::follows`]), not as a change of its own.
pub const DERIVED: [(&str, &[&str], KeyValue); 1] = [(
    "timing.max_reports",
    &["samples", "timing.no_signal_reports"],
    |p| show(&default_max_reports(p.samples, p.no_signal_reports)),
)];

/// `[timing] max_reports` when the plan does not set it: four reports per sample asked, and
/// never fewer than `no_signal_reports` (so a point can be found without signal).
pub fn default_max_reports(samples: u32, no_signal_reports: u32) -> u32 {
    4u32.saturating_mul(samples).max(no_signal_reports)
}

/// A value as [`Plan::differences`] compares it: its `Debug` form.
fn show<T: fmt::Debug>(v: &T) -> String {
    format!("{v:?}")
}

/// Two different values cut for display to about 60 characters each, around where they
/// first differ (`...` where something is left out), so a long list shows the change.
fn shorten(was: &str, now: &str) -> (String, String) {
    const WIDTH: usize = 60;
    const BEFORE: usize = 20;
    let w: Vec<char> = was.chars().collect();
    let same = w
        .iter()
        .zip(now.chars())
        .take_while(|(a, b)| **a == *b)
        .count();
    let from = if same > BEFORE && w.len().max(now.chars().count()) > WIDTH {
        // From the start of a list item (after a space), in the part both share.
        let f = same - BEFORE;
        w[..f].iter().rposition(|c| *c == ' ').map_or(f, |k| k + 1)
    } else {
        0
    };
    let cut = |s: &str| {
        let rest: Vec<char> = s.chars().skip(from).collect();
        let head = if from > 0 { "..." } else { "" };
        if rest.len() > WIDTH {
            format!("{head}{}...", rest[..WIDTH - 3].iter().collect::<String>())
        } else {
            format!("{head}{}", rest.iter().collect::<String>())
        }
    };
    (cut(was), cut(now))
}

/// A plan key whose value differs between two plans ([`Plan::differences`]); shown as
/// `` `samples`: 6 -> 8 ``, or, for a key left at a default that follows changed keys,
/// `` `timing.max_reports`: 24 -> 32 (its default follows `samples`) ``.
#[derive(Debug, Clone, PartialEq)]
pub struct Change {
    /// The key, as in [`KEYS`].
    pub key: &'static str,
    /// Its value in the earlier plan (cut for display when long).
    pub was: String,
    /// Its value now (likewise).
    pub now: String,
    /// Empty when the value itself was changed; otherwise the changed keys its default
    /// follows ([`DERIVED`]): it is at its default in both plans, and changed only with them.
    pub follows: Vec<&'static str>,
}

impl Change {
    /// Whether a resume accepts this change ([`RESUME_MAY_CHANGE`]).
    pub fn resumable(&self) -> bool {
        RESUME_MAY_CHANGE.contains(&self.key)
    }
}

impl fmt::Display for Change {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}`: {} -> {}", self.key, self.was, self.now)?;
        if !self.follows.is_empty() {
            let keys: Vec<String> = self.follows.iter().map(|k| format!("`{k}`")).collect();
            write!(f, " (its default follows {})", keys.join(" and "))?;
        }
        Ok(())
    }
}

/// A plan error: file, line (when known), key, message.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanError {
    /// The plan file.
    pub file: String,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// The key at fault, when known.
    pub key: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for PlanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        if let Some(k) = &self.key {
            write!(f, ": key `{k}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for PlanError {}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    name: Option<String>,
    separations_in: Spanned<toml::Value>,
    layout: Option<Spanned<String>>,
    quad_spacing_in: Option<Spanned<f64>>,
    beacons: Option<Spanned<toml::Value>>,
    frequencies_hz: Option<Spanned<Vec<f64>>>,
    power_levels: Option<Spanned<Vec<i64>>>,
    sensitivities: Option<Spanned<Vec<i64>>>,
    samples: Spanned<i64>,
    settle_ms: Option<Spanned<i64>>,
    rate_hz: Option<Spanned<i64>>,
    group: Option<Spanned<i64>>,
    frequencies_per_beacon: Option<Spanned<i64>>,
    crosstalk_check: Option<Spanned<i64>>,
    timing: Option<RawTiming>,
    metadata: Option<toml::Table>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawTiming {
    request_timeout_ms: Option<Spanned<i64>>,
    retries: Option<Spanned<i64>>,
    report_timeout_ms: Option<Spanned<i64>>,
    no_signal_reports: Option<Spanned<i64>>,
    max_reports: Option<Spanned<i64>>,
    heartbeat_ms: Option<Spanned<i64>>,
    backoff_max_s: Option<Spanned<f64>>,
    give_up_s: Option<Spanned<f64>>,
}

/// The kind of value a plan key takes, for [`check_types`].
#[derive(Clone, Copy)]
enum Kind {
    /// Text in quotes.
    Text,
    /// A whole number.
    Whole,
    /// A number (whole or not).
    Number,
    /// A list of whole numbers.
    WholeList,
    /// A list of numbers.
    NumberList,
    /// Checked by [`Plan::parse`] itself (several forms are allowed).
    Any,
    /// The `[timing]` table.
    Timing,
    /// The `[metadata]` table.
    Metadata,
    /// A `[metadata]` value: text, a number or a boolean.
    Scalar,
}

/// Every plan key with the kind of its value and an example, as said in a type error:
/// ``key `samples`: expected a whole number, e.g. 20, got 5.5``.
const KINDS: [(&str, Kind, &str); 24] = [
    ("name", Kind::Text, "\"lab run 1\""),
    ("separations_in", Kind::Any, ""),
    ("layout", Kind::Text, "\"single\""),
    ("quad_spacing_in", Kind::Number, "11"),
    ("beacons", Kind::Any, ""),
    ("frequencies_hz", Kind::NumberList, "[4050]"),
    ("power_levels", Kind::WholeList, "[2]"),
    ("sensitivities", Kind::WholeList, "[4]"),
    ("samples", Kind::Whole, "20"),
    ("settle_ms", Kind::Whole, "200"),
    ("rate_hz", Kind::Whole, "10"),
    ("group", Kind::Whole, "19"),
    ("frequencies_per_beacon", Kind::Whole, "3"),
    ("crosstalk_check", Kind::Whole, "4"),
    ("timing", Kind::Timing, ""),
    ("timing.request_timeout_ms", Kind::Whole, "500"),
    ("timing.retries", Kind::Whole, "2"),
    ("timing.report_timeout_ms", Kind::Whole, "2000"),
    ("timing.no_signal_reports", Kind::Whole, "20"),
    ("timing.max_reports", Kind::Whole, "80"),
    ("timing.heartbeat_ms", Kind::Whole, "2000"),
    ("timing.backoff_max_s", Kind::Number, "30"),
    ("timing.give_up_s", Kind::Number, "3600"),
    ("metadata", Kind::Metadata, ""),
];

/// A TOML value as a type error shows it: numbers, booleans and dates as written, text in
/// quotes, lists and tables by name.
fn shown(v: &toml::de::DeValue<'_>) -> String {
    use toml::de::DeValue;
    match v {
        DeValue::String(s) => format!("{s:?}"),
        DeValue::Integer(i) => i.to_string(),
        DeValue::Float(f) => f.to_string(),
        DeValue::Boolean(b) => b.to_string(),
        DeValue::Datetime(d) => d.to_string(),
        DeValue::Array(_) => "a list".into(),
        DeValue::Table(_) => "a table".into(),
    }
}

/// Check that every known key of the plan has a value of the right kind, before the plan is
/// read into [`Raw`] (whose own type errors, from serde, name no key and speak Rust: "invalid
/// type: floating point `5.5`, expected i64"). The first wrong value in the file fails: its
/// key, its span and the message (``expected a whole number, e.g. 20, got 5.5``). Syntax
/// errors, unknown and missing keys are left to the reading into [`Raw`].
fn check_types(src: &str) -> Result<(), (String, std::ops::Range<usize>, String)> {
    use toml::de::{DeTable, DeValue};
    let Ok(doc) = DeTable::parse(src) else {
        return Ok(());
    };
    let mut values: Vec<(String, &Spanned<DeValue<'_>>)> = Vec::new();
    for (k, v) in doc.get_ref() {
        values.push((k.get_ref().to_string(), v));
        let table = k.get_ref().as_ref();
        if let (true, DeValue::Table(t)) = (["timing", "metadata"].contains(&table), v.get_ref()) {
            values.extend(
                t.iter()
                    .map(|(k, v)| (format!("{table}.{}", k.get_ref()), v)),
            );
        }
    }
    values.sort_by_key(|(_, v)| v.span().start);
    let number = |v: &DeValue<'_>| matches!(v, DeValue::Integer(_) | DeValue::Float(_));
    let whole = |v: &DeValue<'_>| matches!(v, DeValue::Integer(_));
    for (key, v) in values {
        let free = key
            .starts_with("metadata.")
            .then_some((key.as_str(), Kind::Scalar, ""));
        let Some((_, kind, example)) = KINDS.iter().copied().find(|(k, _, _)| *k == key).or(free)
        else {
            continue;
        };
        let fail = |at: &Spanned<DeValue<'_>>, expected: String| {
            // A number in quotes: say so.
            let hint = match at.get_ref() {
                DeValue::String(s) if s.trim().parse::<f64>().is_ok() => {
                    " (text: write a number without quotes)"
                }
                DeValue::Datetime(_) => " (a date: write it in quotes, e.g. \"2026-01-31\")",
                _ => "",
            };
            Err((
                key.clone(),
                at.span(),
                format!("expected {expected}, got {}{hint}", shown(at.get_ref())),
            ))
        };
        let list = |is: &dyn Fn(&DeValue<'_>) -> bool, each: &str| match v.get_ref() {
            DeValue::Array(a) => match a.iter().find(|x| !is(x.get_ref())) {
                Some(x) => fail(x, format!("{each} in the list, e.g. {example}")),
                None => Ok(()),
            },
            _ => fail(v, format!("a list, e.g. {example}")),
        };
        match kind {
            Kind::Text if !matches!(v.get_ref(), DeValue::String(_)) => {
                fail(v, format!("text in quotes, e.g. {example}"))?
            }
            Kind::Whole if !whole(v.get_ref()) => {
                fail(v, format!("a whole number, e.g. {example}"))?
            }
            Kind::Number if !number(v.get_ref()) => fail(v, format!("a number, e.g. {example}"))?,
            Kind::WholeList => list(&whole, "whole numbers")?,
            Kind::NumberList => list(&number, "numbers")?,
            Kind::Timing if !matches!(v.get_ref(), DeValue::Table(_)) => fail(
                v,
                "a table: a `[timing]` line, then its keys one per line".into(),
            )?,
            Kind::Metadata if !matches!(v.get_ref(), DeValue::Table(_)) => fail(
                v,
                "a table, a `[metadata]` line then `key = value` lines, e.g. operator = \"A. Lab\""
                    .into(),
            )?,
            Kind::Scalar
                if !matches!(
                    v.get_ref(),
                    DeValue::String(_)
                        | DeValue::Integer(_)
                        | DeValue::Float(_)
                        | DeValue::Boolean(_)
                ) =>
            {
                let e = EXPECTED.strip_prefix("expected ").unwrap_or(EXPECTED);
                fail(v, e.into())?
            }
            _ => {}
        }
    }
    Ok(())
}

/// When `src` (named `file`) is not TOML but another kind of file: the line that shows it and
/// what it looks like. Only asked about text that TOML cannot read: a CSV line (commas, no
/// `=`), JSON (`{` or `[` followed by a quote or a brace), or a `.csv`/`.json` name.
fn not_toml(file: &str, src: &str) -> Option<(usize, String)> {
    if toml::de::DeTable::parse(src).is_ok() {
        return None;
    }
    let (n, line) = src
        .lines()
        .enumerate()
        .map(|(n, l)| (n + 1, l.trim()))
        .find(|(_, l)| !l.is_empty() && !l.starts_with('#'))?;
    let shown: String = line.chars().take(60).collect();
    let shown = if shown.len() < line.len() {
        format!("{shown}...")
    } else {
        shown
    };
    let lower = file.to_ascii_lowercase();
    let json = line.starts_with('{')
        || (line.starts_with('[') && line[1..].trim_start().starts_with(['{', '"', '[']));
    if line.contains(',') && !line.contains('=') && !line.starts_with('[') {
        Some((
            n,
            format!("line {n} reads `{shown}`, a CSV header or row (a measurement file?)"),
        ))
    } else if json || lower.ends_with(".json") || lower.ends_with(".jsonl") {
        Some((n, format!("line {n} reads `{shown}`, JSON")))
    } else if lower.ends_with(".csv") {
        Some((
            n,
            format!("line {n} reads `{shown}`, and the file is named .csv"),
        ))
    } else {
        None
    }
}

impl Plan {
    /// Read and validate a plan file.
    pub fn load(path: &Path) -> Result<Plan, PlanError> {
        let file = path.display().to_string();
        let src = crate::bounded::read_text(path, crate::bounded::MAX_PLAN_BYTES, "a plan")
            .map_err(|e| PlanError {
                file: file.clone(),
                line: None,
                key: None,
                message: format!("cannot read the plan: {e}"),
            })?;
        Plan::parse(&file, &src)
    }

    /// Parse and validate plan text; `file` names it in errors.
    pub fn parse(file: &str, src: &str) -> Result<Plan, PlanError> {
        if src.trim().is_empty() {
            return Err(PlanError {
                file: file.into(),
                line: None,
                key: None,
                message: "the file is empty (a copy not finished, a disk that filled as it was \
                          written?): a plan has `key = value` lines, e.g. `samples = 20`: see \
                          host/plans/short.toml and host/SWEEP.md"
                    .into(),
            });
        }
        let line_of = |offset: usize| src[..offset.min(src.len())].matches('\n').count() + 1;
        check_types(src).map_err(|(key, span, message)| PlanError {
            file: file.into(),
            line: Some(line_of(span.start)),
            key: Some(key),
            message,
        })?;
        let raw: Raw = toml::from_str(src).map_err(|e| {
            // toml's messages name the key ("unknown field `x`", "missing field `y`"); we add
            // the line of its span.
            let line = e.span().map(|s| line_of(s.start));
            // Not TOML at all (a measurement file given as the plan): said so, rather than
            // the first syntax error the file happens to make.
            if let Some((at, what)) = not_toml(file, src) {
                return PlanError {
                    file: file.into(),
                    line: Some(at),
                    key: None,
                    message: format!(
                        "does not look like a plan TOML file: {what} (TOML: {}). A plan has \
                         `key = value` lines, e.g. `samples = 20`: see host/plans/short.toml \
                         and host/SWEEP.md",
                        e.message().trim()
                    ),
                };
            }
            PlanError {
                file: file.into(),
                line,
                key: None,
                message: e.message().trim().to_string(),
            }
        })?;
        let err = |key: &str, span: std::ops::Range<usize>, message: String| PlanError {
            file: file.into(),
            line: Some(line_of(span.start)),
            key: Some(key.into()),
            message,
        };
        // Integers in a range, with the key and line on failure.
        let int = |key: &str, v: &Spanned<i64>, lo: i64, hi: i64, what: &str| {
            let x = *v.get_ref();
            if x < lo || x > hi {
                Err(err(
                    key,
                    v.span(),
                    format!("{x} is not {what} ({lo}..={hi})"),
                ))
            } else {
                Ok(x)
            }
        };

        let sv = &raw.separations_in;
        let separations = match sv.get_ref() {
            toml::Value::String(s) => parse_separations(s).map_err(|e| e.to_string()),
            toml::Value::Array(a) => a
                .iter()
                .map(|v| match v {
                    toml::Value::Integer(i) => Ok(*i as f64),
                    toml::Value::Float(f) => Ok(*f),
                    other => Err(format!("`{other}` is not a separation in inches")),
                })
                .collect::<Result<Vec<f64>, String>>()
                .and_then(|v| {
                    if v.is_empty() {
                        Err("no separations given".into())
                    } else {
                        Ok(v)
                    }
                }),
            other => Err(format!(
                "expected a list of inches or a range string like \"2..30\", got `{other}`"
            )),
        }
        .map_err(|m| err("separations_in", sv.span(), m))?;
        if let Some(bad) = separations
            .iter()
            .find(|s| !(s.is_finite() && **s > 0.0 && **s <= 60.0))
        {
            return Err(err(
                "separations_in",
                sv.span(),
                format!("{bad} in is not a plate separation (0 < s <= 60 in)"),
            ));
        }
        for (i, a) in separations.iter().enumerate() {
            if separations[..i].iter().any(|b| (a - b).abs() < 1e-9) {
                return Err(err(
                    "separations_in",
                    sv.span(),
                    format!("{a} in is listed twice"),
                ));
            }
        }

        let layout = match &raw.layout {
            None => Layout::Single,
            Some(l) => match l.get_ref().as_str() {
                "single" => Layout::Single,
                "quad" => Layout::Quad { spacing: 11.0 },
                other => {
                    return Err(err(
                        "layout",
                        l.span(),
                        format!("`{other}`: expected \"single\" or \"quad\""),
                    ))
                }
            },
        };
        let layout = match (layout, &raw.quad_spacing_in) {
            (Layout::Quad { .. }, Some(s)) => {
                let v = *s.get_ref();
                if !(v.is_finite() && (10.0..=40.0).contains(&v)) {
                    return Err(err(
                        "quad_spacing_in",
                        s.span(),
                        format!("{v} in: arrays are 10 in wide, spacing must be 10..=40 in"),
                    ));
                }
                Layout::Quad { spacing: v }
            }
            (Layout::Single, Some(s)) => {
                return Err(err(
                    "quad_spacing_in",
                    s.span(),
                    "only meaningful with layout = \"quad\"".into(),
                ))
            }
            (l, None) => l,
        };

        let beacons: Vec<u8> = match &raw.beacons {
            None => (0..LED_COUNT as u8).collect(),
            Some(b) => match b.get_ref() {
                toml::Value::String(s) if s == "all" => (0..LED_COUNT as u8).collect(),
                toml::Value::Array(a) if !a.is_empty() => {
                    let mut out = Vec::new();
                    for v in a {
                        let id = v.as_integer().filter(|i| (0..LED_COUNT as i64).contains(i));
                        let Some(id) = id else {
                            return Err(err(
                                "beacons",
                                b.span(),
                                format!("`{v}` is not a beacon id (0..=99)"),
                            ));
                        };
                        if out.contains(&(id as u8)) {
                            return Err(err(
                                "beacons",
                                b.span(),
                                format!("beacon {id} is listed twice"),
                            ));
                        }
                        out.push(id as u8);
                    }
                    out
                }
                other => {
                    return Err(err(
                        "beacons",
                        b.span(),
                        format!("`{other}`: expected \"all\" or a non-empty list of ids 0..=99"),
                    ))
                }
            },
        };

        let frequencies_hz = match &raw.frequencies_hz {
            None => vec![NORTHSTAR_TABLE_MHZ[2] as f64 / 1000.0],
            Some(f) => {
                if f.get_ref().is_empty() {
                    return Err(err("frequencies_hz", f.span(), "empty list".into()));
                }
                for &hz in f.get_ref() {
                    if channel_of(hz).is_none() {
                        let table: Vec<String> = NORTHSTAR_TABLE_MHZ
                            .iter()
                            .map(|m| format!("{}", *m as f64 / 1000.0))
                            .collect();
                        return Err(err(
                            "frequencies_hz",
                            f.span(),
                            format!(
                                "{hz} Hz is not a NorthStar frequency (the table: {})",
                                table.join(", ")
                            ),
                        ));
                    }
                }
                // One channel twice would measure its points twice, under one key the data
                // file's reader refuses as duplicate reports.
                let list = f.get_ref();
                for (i, &hz) in list.iter().enumerate() {
                    if let Some(&first) =
                        list[..i].iter().find(|&&a| channel_of(a) == channel_of(hz))
                    {
                        return Err(err(
                            "frequencies_hz",
                            f.span(),
                            if first == hz {
                                format!("{hz} Hz is listed twice")
                            } else {
                                format!("{first} Hz and {hz} Hz are one NorthStar frequency, listed twice")
                            },
                        ));
                    }
                }
                list.clone()
            }
        };

        let small_list = |key: &str,
                          v: &Option<Spanned<Vec<i64>>>,
                          default: Vec<u8>,
                          lo: i64,
                          hi: i64,
                          what: &str|
         -> Result<Vec<u8>, PlanError> {
            let Some(v) = v else { return Ok(default) };
            if v.get_ref().is_empty() {
                return Err(err(key, v.span(), "empty list".into()));
            }
            let mut out = Vec::new();
            for &x in v.get_ref() {
                if x < lo || x > hi {
                    return Err(err(
                        key,
                        v.span(),
                        format!("{x} is not {what} ({lo}..={hi})"),
                    ));
                }
                if out.contains(&(x as u8)) {
                    return Err(err(key, v.span(), format!("{x} is listed twice")));
                }
                out.push(x as u8);
            }
            Ok(out)
        };
        let power_levels = small_list(
            "power_levels",
            &raw.power_levels,
            vec![2],
            1,
            2,
            "a power level (1 = 1 kOhm, 2 = 360 Ohm)",
        )?;
        let sensitivities = small_list(
            "sensitivities",
            &raw.sensitivities,
            vec![4],
            1,
            4,
            "a sensitivity setting",
        )?;
        let samples = int(
            "samples",
            &raw.samples,
            1,
            crate::sim::MAX_SAMPLES as i64,
            "a number of samples",
        )? as u32;
        let opt = |key: &str, v: &Option<Spanned<i64>>, d: i64, lo: i64, hi: i64| match v {
            None => Ok(d),
            Some(v) => int(key, v, lo, hi, "allowed"),
        };
        let settle_ms = opt("settle_ms", &raw.settle_ms, 200, 0, 600_000)? as u64;
        let rate_hz = opt("rate_hz", &raw.rate_hz, 10, 1, 50)? as u8;
        let (group, frequencies_per_beacon, crosstalk_check) =
            grouping(&raw, &beacons, &frequencies_hz, &err)?;
        let t = raw.timing.unwrap_or_default();
        let key = |k: &str| format!("timing.{k}");
        let request_timeout_ms = opt(
            &key("request_timeout_ms"),
            &t.request_timeout_ms,
            500,
            10,
            60_000,
        )? as u64;
        let retries = opt(&key("retries"), &t.retries, 2, 0, 100)? as u32;
        let report_timeout_ms = opt(
            &key("report_timeout_ms"),
            &t.report_timeout_ms,
            2000,
            10,
            600_000,
        )? as u64;
        let no_signal_reports = opt(
            &key("no_signal_reports"),
            &t.no_signal_reports,
            20,
            1,
            100_000,
        )? as u32;
        let max_reports = opt(
            &key("max_reports"),
            &t.max_reports,
            default_max_reports(samples, no_signal_reports) as i64,
            1,
            10_000_000,
        )? as u32;
        if max_reports < samples {
            return Err(err(
                &key("max_reports"),
                t.max_reports.as_ref().map(|s| s.span()).unwrap_or(0..0),
                format!("{max_reports} is fewer than the {samples} samples per point"),
            ));
        }
        let heartbeat_ms = opt(&key("heartbeat_ms"), &t.heartbeat_ms, 2000, 50, 60_000)? as u64;
        if heartbeat_ms > MAX_HEARTBEAT_MS {
            return Err(err(
                &key("heartbeat_ms"),
                t.heartbeat_ms.as_ref().map(|s| s.span()).unwrap_or(0..0),
                format!(
                    "{heartbeat_ms} ms is too long: the beacon board's dead-man timer turns the \
                     LEDs off after {DEADMAN_DEFAULT_MS} ms without a heartbeat; heartbeat at \
                     most every {MAX_HEARTBEAT_MS} ms (half of it)"
                ),
            ));
        }
        let secs = |k: &str, v: &Option<Spanned<f64>>, d: f64, lo: f64, hi: f64| match v {
            None => Ok(d),
            Some(s) => {
                let x = *s.get_ref();
                if x.is_finite() && (lo..=hi).contains(&x) {
                    Ok(x)
                } else {
                    Err(err(
                        &key(k),
                        s.span(),
                        format!("{x} s is not allowed ({lo}..={hi})"),
                    ))
                }
            }
        };
        let backoff_max_s = secs("backoff_max_s", &t.backoff_max_s, 30.0, 0.01, 3600.0)?;
        let give_up_s = secs("give_up_s", &t.give_up_s, 3600.0, 0.1, 7.0 * 86400.0)?;

        let metadata = match &raw.metadata {
            Some(t) => Metadata::from_toml(t).map_err(|(k, message)| PlanError {
                file: file.into(),
                line: None,
                key: Some(format!("metadata.{k}")),
                message,
            })?,
            None => Metadata::default(),
        };

        Ok(Plan {
            name: raw.name.unwrap_or_else(|| "unnamed".into()),
            separations,
            layout,
            beacons,
            frequencies_hz,
            power_levels,
            sensitivities,
            samples,
            settle_ms,
            rate_hz,
            request_timeout_ms,
            retries,
            report_timeout_ms,
            no_signal_reports,
            max_reports,
            heartbeat_ms,
            backoff_max_s,
            give_up_s,
            group,
            frequencies_per_beacon,
            crosstalk_check,
            metadata,
            schedule: Cached::default(),
        })
    }

    /// What differs from `before`, one entry per plan key (`` `samples`: 6 -> 8 `` when
    /// shown), in the order of [`KEYS`]. Empty when the plans are equal. Values are compared
    /// in full and shown cut around where they differ. A key of [`DERIVED`] that is at its
    /// default in both plans changed only because keys its default follows changed: its entry
    /// names them ([`Change::follows`]).
    pub fn differences(&self, before: &Plan) -> Vec<Change> {
        let value_of = |key: &str, p: &Plan| {
            KEYS.iter()
                .find(|(k, _)| *k == key)
                .map(|(_, value)| value(p))
        };
        KEYS.iter()
            .filter_map(|&(key, value)| {
                let (was, now) = (value(before), value(self));
                (was != now).then(|| {
                    let follows = DERIVED
                        .iter()
                        .find(|(k, _, _)| *k == key)
                        .filter(|(_, _, default)| was == default(before) && now == default(self))
                        .map(|(_, sources, _)| {
                            sources
                                .iter()
                                .copied()
                                .filter(|s| value_of(s, before) != value_of(s, self))
                                .collect()
                        })
                        .unwrap_or_default();
                    let (was, now) = shorten(&was, &now);
                    Change {
                        key,
                        was,
                        now,
                        follows,
                    }
                })
            })
            .collect()
    }
}

/// The keys of a grouped plan, checked: `group`, `frequencies_per_beacon` (all of
/// `frequencies_hz` when not given) and `crosstalk_check` (4 in a grouped plan when not
/// given). A group needs a frequency of its own for each beacon (the NorthStar tells spots
/// apart by frequency alone), at most [`MAX_SPOTS`] spots per frame, at most the beacon
/// board's default cap of lit LEDs, and a modulator that keeps up with it.
fn grouping(
    raw: &Raw,
    beacons: &[u8],
    frequencies_hz: &[f64],
    err: &dyn Fn(&str, std::ops::Range<usize>, String) -> PlanError,
) -> Result<(usize, usize, usize), PlanError> {
    let nf = frequencies_hz.len();
    let (group, gspan) = match &raw.group {
        None => (1, 0..0),
        Some(g) => (*g.get_ref(), g.span()),
    };
    let limit = MAX_SPOTS.min(MAX_LIT_DEFAULT as usize) as i64;
    if group < 1 || group > limit {
        return Err(err(
            "group",
            gspan,
            format!(
                "{group} is not a group size (1..={limit}: the NorthStar reports at most \
                 {MAX_SPOTS} spots a frame, and the beacon board lights at most \
                 {MAX_LIT_DEFAULT} LEDs at once by default)"
            ),
        ));
    }
    let group = group as usize;
    if group > nf {
        return Err(err(
            "group",
            gspan,
            format!(
                "{group} beacons at once need {group} different frequencies, but \
                 `frequencies_hz` lists {nf}: the NorthStar tells spots apart by frequency \
                 alone. List at least {group} frequencies of the NorthStar table ({} distinct), \
                 or make the group at most {nf}",
                distinct_table_frequencies()
            ),
        ));
    }
    if group > beacons.len() {
        return Err(err(
            "group",
            gspan,
            format!(
                "{group} beacons at once, but the plan has {} (`beacons`): make the group at \
                 most {}",
                beacons.len(),
                beacons.len()
            ),
        ));
    }
    let rounds = match &raw.frequencies_per_beacon {
        None => nf,
        Some(k) => {
            let v = *k.get_ref();
            if v < 1 || v > nf as i64 {
                return Err(err(
                    "frequencies_per_beacon",
                    k.span(),
                    format!(
                        "{v} is not allowed: each beacon can be measured at 1..={nf} of the \
                         plan's frequencies (`frequencies_hz` lists {nf})"
                    ),
                ));
            }
            v as usize
        }
    };
    let check = match &raw.crosstalk_check {
        None if group > 1 => 4.min(beacons.len()),
        None => 0,
        Some(c) => {
            let v = *c.get_ref();
            if v > 0 && group == 1 {
                return Err(err(
                    "crosstalk_check",
                    c.span(),
                    "compares beacons measured alone with the same beacons in their group: \
                     it needs `group` above 1"
                        .into(),
                ));
            }
            if v < 0 || v > beacons.len() as i64 {
                return Err(err(
                    "crosstalk_check",
                    c.span(),
                    format!(
                        "{v} is not allowed: 0..={} beacons per separation (the plan's \
                         beacons)",
                        beacons.len()
                    ),
                ));
            }
            v as usize
        }
    };
    // The modulator's tick must keep up with the largest group (every LED at one frequency).
    if group > 1 {
        let table = NORTHSTAR_TABLE_MHZ;
        let mut modes = [LedMode::Off; LED_COUNT];
        for (i, &hz) in frequencies_hz.iter().take(group).enumerate() {
            let ch = channel_of(hz).unwrap_or(0);
            modes[beacons[i] as usize] = LedMode::Modulated(FreqSet::single(ch));
        }
        let cost = tick_cost(&table, &modes, &BEACON_LINES);
        if cost > TICK_BUDGET {
            return Err(err(
                "group",
                gspan,
                format!(
                    "{group} LEDs at once would cost the beacon board's modulator about {cost} \
                     instructions a tick, over its budget of {TICK_BUDGET}: make the group \
                     smaller"
                ),
            ));
        }
    }
    Ok((group, if rounds == nf { 0 } else { rounds }, check))
}

/// Distinct frequencies of the NorthStar table ([`NORTHSTAR_TABLE_MHZ`]): 19 of its 20 entries
/// (ID 1's first LED and ID 9's second are both 4050 Hz), so at most 19 spots can be told
/// apart in a frame.
pub fn distinct_table_frequencies() -> usize {
    let mut seen: Vec<u32> = Vec::new();
    for m in NORTHSTAR_TABLE_MHZ {
        if !seen.contains(&m) {
            seen.push(m);
        }
    }
    seen.len()
}

/// The NorthStar table channel of a frequency in Hz (exact to 1 mHz).
pub fn channel_of(hz: f64) -> Option<u8> {
    NORTHSTAR_TABLE_MHZ
        .iter()
        .position(|&m| (m as f64 - hz * 1000.0).abs() < 0.5)
        .map(|i| i as u8)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A short plan the tests of the plan and of its points share.
    pub(crate) const SHORT: &str = r#"
name = "t"
separations_in = [20, 25]
beacons = [0, 45, 99]
frequencies_hz = [4050]
power_levels = [1, 2]
sensitivities = [4]
samples = 5
settle_ms = 0
"#;

    /// A measurement file (or JSON) given as the plan is said not to be a plan, at its first
    /// line that is not a comment; a plan with a TOML mistake keeps TOML's own message.
    #[test]
    fn a_file_of_another_kind_is_said_not_to_be_a_plan() {
        let csv = "# cta simulate: 2 points\n# noise 10\nseparation_in,beacon_x_in,beacon_y_in,\
                   beacon_z_in,x,y\n10,0,0,10,1,2\n";
        let e = Plan::parse("tilt.csv", csv).unwrap_err();
        let s = e.to_string();
        assert!(
            s.starts_with(
                "tilt.csv:3: does not look like a plan TOML file: line 3 reads \
                           `separation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y`, a CSV header \
                           or row (a measurement file?)"
            ) && s.contains("host/plans/short.toml"),
            "{s}"
        );
        let e = Plan::parse("fit.json", "{\"d\": [1, 2]}\n").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("fit.json:1: does not look like a plan TOML file: line 1 reads"),
            "{e}"
        );
        // A plan with a mistake in it: TOML's message, no guess.
        let e = Plan::parse("p.toml", &SHORT.replace("samples = 5", "samples =")).unwrap_err();
        assert!(!e.to_string().contains("does not look like"), "{e}");
    }

    #[test]
    fn errors_name_key_and_line() {
        let e = Plan::parse("p.toml", &SHORT.replace("samples = 5", "sample = 5")).unwrap_err();
        let s = e.to_string();
        assert!(s.starts_with("p.toml:8"), "{s}");
        assert!(s.contains("sample"), "{s}");
        let e = Plan::parse("p.toml", &SHORT.replace("[4]", "[5]")).unwrap_err();
        assert_eq!(e.line, Some(7));
        assert_eq!(e.key.as_deref(), Some("sensitivities"));
        let e = Plan::parse("p.toml", &SHORT.replace("4050", "4000")).unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(5), Some("frequencies_hz"))
        );
        let e = Plan::parse("p.toml", &SHORT.replace("samples = 5\n", "")).unwrap_err();
        assert!(e.to_string().contains("missing field `samples`"), "{e}");
        let e = Plan::parse("p.toml", &format!("{SHORT}[timing]\nretrys = 3\n")).unwrap_err();
        assert!(e.to_string().contains("retrys"), "{e}");
        assert_eq!(e.line, Some(11));
        let e = Plan::parse("p.toml", &SHORT.replace("[20, 25]", "\"30..2\"")).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("separations_in"));
    }

    #[test]
    fn type_errors_name_the_key_and_say_what_is_expected_in_words() {
        let said = |from: &str, to: &str| {
            assert!(SHORT.contains(from), "{from}");
            Plan::parse("q.toml", &SHORT.replace(from, to))
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            said("samples = 5", "samples = 5.5"),
            "q.toml:8: key `samples`: expected a whole number, e.g. 20, got 5.5"
        );
        assert_eq!(
            said("samples = 5", "samples = \"10\""),
            "q.toml:8: key `samples`: expected a whole number, e.g. 20, got \"10\" (text: write \
             a number without quotes)"
        );
        assert_eq!(
            said("power_levels = [1, 2]", "power_levels = 2"),
            "q.toml:6: key `power_levels`: expected a list, e.g. [2], got 2"
        );
        assert_eq!(
            said("power_levels = [1, 2]", "power_levels = [1, 1.5]"),
            "q.toml:6: key `power_levels`: expected whole numbers in the list, e.g. [2], got 1.5"
        );
        assert_eq!(
            said("frequencies_hz = [4050]", "frequencies_hz = 4050"),
            "q.toml:5: key `frequencies_hz`: expected a list, e.g. [4050], got 4050"
        );
        assert_eq!(
            said("name = \"t\"", "name = 7"),
            "q.toml:2: key `name`: expected text in quotes, e.g. \"lab run 1\", got 7"
        );
        assert_eq!(
            said("settle_ms = 0", "settle_ms = true"),
            "q.toml:9: key `settle_ms`: expected a whole number, e.g. 200, got true"
        );
        // [timing] keys, and the table itself.
        let t = |timing: &str| {
            Plan::parse("q.toml", &format!("{SHORT}[timing]\n{timing}\n"))
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            t("retries = [3]"),
            "q.toml:11: key `timing.retries`: expected a whole number, e.g. 2, got a list"
        );
        assert_eq!(
            t("give_up_s = \"1h\""),
            "q.toml:11: key `timing.give_up_s`: expected a number, e.g. 3600, got \"1h\""
        );
        let e = Plan::parse("q.toml", &format!("{SHORT}timing = 5\n")).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("timing"));
        assert!(e.message.starts_with("expected a table"), "{e}");
        // The first wrong value in the file is the one reported.
        let e = Plan::parse(
            "q.toml",
            &SHORT
                .replace("samples = 5", "samples = 5.5")
                .replace("[1, 2]", "2"),
        )
        .unwrap_err();
        assert_eq!(e.key.as_deref(), Some("power_levels"));
        // Numbers where a number may be whole or not; other errors are unchanged.
        let p = Plan::parse(
            "q.toml",
            &format!("layout = \"quad\"\nquad_spacing_in = 12\n{SHORT}[timing]\ngive_up_s = 60\n"),
        )
        .unwrap();
        assert_eq!(p.layout, Layout::Quad { spacing: 12.0 });
        assert_eq!(p.give_up_s, 60.0);
        assert!(said("samples = 5", "samples = 0").contains("0 is not a number of samples"));
    }

    #[test]
    fn heartbeat_must_beat_the_beacon_dead_man_timer() {
        let with = |ms: u64| {
            Plan::parse(
                "p.toml",
                &format!("{SHORT}[timing]\nretries = 3\nheartbeat_ms = {ms}\n"),
            )
        };
        assert_eq!(with(MAX_HEARTBEAT_MS).unwrap().heartbeat_ms, 5000);
        for ms in [MAX_HEARTBEAT_MS + 1, 10_000, 60_000] {
            let e = with(ms).unwrap_err();
            assert_eq!(
                (e.line, e.key.as_deref()),
                (Some(12), Some("timing.heartbeat_ms")),
                "{e}"
            );
            let s = e.to_string();
            assert!(
                s.starts_with("p.toml:12: key `timing.heartbeat_ms`: "),
                "{s}"
            );
            assert!(s.contains("dead-man") && s.contains("10000 ms"), "{s}");
        }
        // The shipped plans are valid.
        for p in ["chvi.toml", "chvi-single.toml", "demo.toml", "short.toml"] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../plans")
                .join(p);
            Plan::load(&path).unwrap();
        }
    }

    /// `host/plans/chvi-single.toml` and `chvi.toml` are the thesis Ch VI scheme they say
    /// they are: 2 to 30 in by 1 in (step 1), every beacon measured 100-200 times "at various
    /// frequencies for each intensity level" (step 2: several frequencies, both power levels),
    /// all four sensitivities (step 3); about 3.5 million samples, the size the sweep's
    /// performance target is set for (host/SWEEP.md, Performance). The grouped plan takes the
    /// same samples, and its crosstalk check's, in 18 times fewer points.
    #[test]
    fn the_shipped_ch_vi_plans_are_the_thesis_scheme() {
        let load = |name: &str| {
            Plan::load(
                &Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("../plans")
                    .join(name),
            )
            .unwrap()
        };
        let (single, grouped) = (load("chvi-single.toml"), load("chvi.toml"));
        for p in [&single, &grouped] {
            let inches: Vec<f64> = (2..=30).map(f64::from).collect();
            assert_eq!(p.separations, inches);
            assert_eq!(p.beacons, (0..100).collect::<Vec<u8>>());
            assert!(
                p.rounds() >= 3,
                "various frequencies: {:?}",
                p.frequencies_hz
            );
            assert_eq!(p.power_levels, [1, 2]);
            assert_eq!(p.sensitivities, [1, 2, 3, 4]);
            let per_location = p.samples as usize * p.rounds();
            assert!((100..=200).contains(&per_location), "{per_location}");
        }
        // The arithmetic of the header comments.
        assert_eq!(single.len(), 69_600);
        assert_eq!(single.total_samples(), 3_480_000);
        assert_eq!((grouped.group, grouped.per_block()), (19, 16));
        assert_eq!(grouped.len(), 29 * (8 * 16 + 4));
        assert_eq!(grouped.total_samples(), 3_480_000 + 29 * 4 * 50);
    }

    #[test]
    fn differences_name_every_key_and_only_timing_may_change_on_resume() {
        // Every field of a plan has its key: a field left out would change unseen on resume.
        let p = Plan::parse("p.toml", SHORT).unwrap();
        let fields = serde_json::to_value(&p).unwrap().as_object().unwrap().len();
        assert_eq!(fields, KEYS.len());
        for k in RESUME_MAY_CHANGE {
            assert!(KEYS.iter().any(|(key, _)| *key == k), "{k}");
        }
        let with =
            |timing: &str| Plan::parse("p.toml", &format!("{SHORT}[timing]\n{timing}\n")).unwrap();
        let d = with("retries = 5\ngive_up_s = 60\nheartbeat_ms = 500").differences(&p);
        let shown: Vec<String> = d.iter().map(|c| c.to_string()).collect();
        assert_eq!(
            shown,
            [
                "`timing.retries`: 2 -> 5",
                "`timing.heartbeat_ms`: 2000 -> 500",
                "`timing.give_up_s`: 3600.0 -> 60.0"
            ]
        );
        assert!(d.iter().all(Change::resumable));
        // What decides how a point is recorded, or shapes the measurement, is not timing.
        for (changed, key) in [
            (with("no_signal_reports = 7"), "timing.no_signal_reports"),
            (with("max_reports = 50"), "timing.max_reports"),
            (
                Plan::parse("p.toml", &SHORT.replace("settle_ms = 0", "settle_ms = 50")).unwrap(),
                "settle_ms",
            ),
            (
                Plan::parse("p.toml", &format!("rate_hz = 20\n{SHORT}")).unwrap(),
                "rate_hz",
            ),
            (
                Plan::parse("p.toml", &SHORT.replace("samples = 5", "samples = 6")).unwrap(),
                "samples",
            ),
        ] {
            let d = changed.differences(&p);
            assert!(d.iter().any(|c| c.key == key && !c.resumable()), "{d:?}");
        }
        assert!(p.differences(&p).is_empty());
    }

    #[test]
    fn a_default_that_follows_a_changed_key_is_shown_as_following_it() {
        // `timing.max_reports` left at its default follows `samples` (and `no_signal_reports`):
        // a changed `samples` is not also a change the user made to `max_reports`.
        for (key, sources, _) in DERIVED {
            for k in std::iter::once(key).chain(sources.iter().copied()) {
                assert!(KEYS.iter().any(|(kk, _)| *kk == k), "{k}");
            }
        }
        let p = Plan::parse("p.toml", SHORT).unwrap();
        assert_eq!(p.max_reports, default_max_reports(5, 20));
        let shown = |changed: &str| -> Vec<String> {
            Plan::parse("p.toml", changed)
                .unwrap()
                .differences(&p)
                .iter()
                .map(|c| c.to_string())
                .collect()
        };
        let samples = |n: u32| SHORT.replace("samples = 5", &format!("samples = {n}"));
        assert_eq!(
            shown(&samples(6)),
            [
                "`samples`: 5 -> 6",
                "`timing.max_reports`: 20 -> 24 (its default follows `samples`)"
            ]
        );
        assert_eq!(
            shown(&format!("{SHORT}[timing]\nno_signal_reports = 30\n")),
            [
                "`timing.no_signal_reports`: 20 -> 30",
                "`timing.max_reports`: 20 -> 30 (its default follows `timing.no_signal_reports`)"
            ]
        );
        assert_eq!(
            shown(&format!(
                "{}[timing]\nno_signal_reports = 30\n",
                samples(10)
            ))[2],
            "`timing.max_reports`: 20 -> 40 (its default follows `samples` and \
             `timing.no_signal_reports`)"
        );
        // Set in the file, it is the user's own change, shown as such ...
        assert_eq!(
            shown(&format!("{}[timing]\nmax_reports = 50\n", samples(6))),
            ["`samples`: 5 -> 6", "`timing.max_reports`: 20 -> 50"]
        );
        // ... or no change at all when it keeps its value.
        assert_eq!(
            shown(&format!("{}[timing]\nmax_reports = 20\n", samples(6))),
            ["`samples`: 5 -> 6"]
        );
        // A following key is still not one a resume may change.
        let d = Plan::parse("p.toml", &samples(6)).unwrap().differences(&p);
        assert_eq!(d[1].follows, ["samples"]);
        assert!(!d[1].resumable());
    }

    #[test]
    fn long_values_are_compared_in_full_and_shown_where_they_differ() {
        // Once, values were compared cut to 60 characters: dropping the last separation or
        // beacon of a long list went unseen, and a resume continued another plan.
        let all = Plan::parse("p.toml", "separations_in = \"2..30\"\nsamples = 1\n").unwrap();
        let fewer = Plan::parse(
            "p.toml",
            &format!(
                "separations_in = \"2..29\"\nbeacons = {:?}\nsamples = 1\n",
                (0..99).collect::<Vec<u8>>()
            ),
        )
        .unwrap();
        let shown: Vec<String> = fewer
            .differences(&all)
            .iter()
            .map(|c| c.to_string())
            .collect();
        assert_eq!(
            shown,
            [
                "`separations_in`: ...26.0, 27.0, 28.0, 29.0, 30.0] -> ...26.0, 27.0, 28.0, 29.0]",
                "`beacons`: ...93, 94, 95, 96, 97, 98, 99] -> ...93, 94, 95, 96, 97, 98]",
            ]
        );
        // Short values, and long ones differing early, are shown from the start.
        assert_eq!(
            shorten("[1, 2]", "[1, 3]"),
            ("[1, 2]".into(), "[1, 3]".into())
        );
        let (a, b) = shorten(&"1".repeat(100), &format!("2{}", "1".repeat(99)));
        assert_eq!((a.len(), b.len()), (60, 60));
        assert!(
            a.starts_with("111") && b.starts_with("211") && a.ends_with("..."),
            "{a}"
        );
    }
}
