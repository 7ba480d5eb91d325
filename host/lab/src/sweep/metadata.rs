//! A plan's `[metadata]`: free key-value pairs that describe a run (sensor serial, operator,
//! room temperature...) without changing what it measures. Values are text, numbers or
//! booleans; the plan check (`plan.rs`) refuses anything else with the file, line and key.
//! Each session journals its plan with them, the manifest carries the last session's, and
//! `cta sweep --status` shows them.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

/// One metadata value, as written in the plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum MetaValue {
    /// `true` or `false`.
    Bool(bool),
    /// A whole number.
    Whole(i64),
    /// A number with a fraction or an exponent.
    Number(f64),
    /// Text in quotes.
    Text(String),
}

impl fmt::Display for MetaValue {
    /// As in TOML: text in quotes, numbers and booleans as written.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MetaValue::Bool(b) => write!(f, "{b}"),
            MetaValue::Whole(i) => write!(f, "{i}"),
            MetaValue::Number(x) => write!(f, "{x:?}"),
            MetaValue::Text(s) => write!(f, "{s:?}"),
        }
    }
}

/// The `[metadata]` table, keys in sorted order (a JSON object in the journal and manifest).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Metadata(pub BTreeMap<String, MetaValue>);

impl Metadata {
    /// Whether the plan has no `[metadata]` (or an empty one).
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The pairs as TOML lines would write them: `key = value`, sorted by key.
    pub fn lines(&self) -> Vec<String> {
        self.0
            .iter()
            .map(|(k, v)| {
                let bare = !k.is_empty()
                    && k.chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
                if bare {
                    format!("{k} = {v}")
                } else {
                    format!("{k:?} = {v}")
                }
            })
            .collect()
    }

    /// What differs from `before`, one entry per key in sorted order, as a resume's note says
    /// it: `` `operator`: "A. Lab" -> "B. Lab" ``, `` `room` added: "B12" ``, `` `lamp` removed
    /// (was true) ``.
    pub fn changes(&self, before: &Metadata) -> Vec<String> {
        let keys: std::collections::BTreeSet<&String> =
            self.0.keys().chain(before.0.keys()).collect();
        keys.into_iter()
            .filter_map(|k| match (before.0.get(k), self.0.get(k)) {
                (Some(w), Some(n)) if w != n => Some(format!("`{k}`: {w} -> {n}")),
                (None, Some(n)) => Some(format!("`{k}` added: {n}")),
                (Some(w), None) => Some(format!("`{k}` removed (was {w})")),
                _ => None,
            })
            .collect()
    }

    /// From the plan's table, already checked by the plan's type check (text, numbers and
    /// booleans only): anything else is the key's error message.
    pub(crate) fn from_toml(t: &toml::Table) -> Result<Metadata, (String, String)> {
        let mut m = BTreeMap::new();
        for (k, v) in t {
            let value = match v {
                toml::Value::Boolean(b) => MetaValue::Bool(*b),
                toml::Value::Integer(i) => MetaValue::Whole(*i),
                toml::Value::Float(x) if x.is_finite() => MetaValue::Number(*x),
                toml::Value::String(s) => MetaValue::Text(s.clone()),
                other => return Err((k.clone(), format!("{EXPECTED}, got {other}"))),
            };
            m.insert(k.clone(), value);
        }
        Ok(Metadata(m))
    }
}

impl fmt::Display for Metadata {
    /// `{key = value, ...}` (`{}` when empty), as a plan change shows it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{{{}}}", self.lines().join(", "))
    }
}

/// What a `[metadata]` value may be, as said in a type error.
pub(crate) const EXPECTED: &str =
    "expected text in quotes, a number or true/false, e.g. sensor_serial = \"NS-0412\"";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::plan::Plan;

    const SHORT: &str = "separations_in = [20]\nsamples = 5\n";

    fn parse(meta: &str) -> Result<Plan, String> {
        Plan::parse("p.toml", &format!("{SHORT}[metadata]\n{meta}\n")).map_err(|e| e.to_string())
    }

    #[test]
    fn text_numbers_and_booleans_are_kept_with_their_kind() {
        let p = parse(
            "sensor_serial = \"NS-0412\"\noperator = \"A. Lab\"\ntemperature_c = 21.5\n\
             run = 3\ndark_room = true",
        )
        .unwrap();
        let m = &p.metadata.0;
        assert_eq!(m["sensor_serial"], MetaValue::Text("NS-0412".into()));
        assert_eq!(m["temperature_c"], MetaValue::Number(21.5));
        assert_eq!(m["run"], MetaValue::Whole(3));
        assert_eq!(m["dark_room"], MetaValue::Bool(true));
        assert_eq!(
            p.metadata.lines(),
            [
                "dark_room = true",
                "operator = \"A. Lab\"",
                "run = 3",
                "sensor_serial = \"NS-0412\"",
                "temperature_c = 21.5"
            ]
        );
        // Through the journal's JSON and back, each value keeps its kind.
        let back: Plan = serde_json::from_str(&serde_json::to_string(&p).unwrap()).unwrap();
        assert_eq!(back.metadata, p.metadata);
        let v = serde_json::to_value(&p).unwrap();
        assert_eq!(v["metadata"]["temperature_c"], 21.5);
        assert_eq!(v["metadata"]["run"], 3);
        // Changes are said key by key.
        let q = parse("sensor_serial = \"NS-0412\"\ntemperature_c = 23.0\nroom = \"B12\"").unwrap();
        assert_eq!(
            q.metadata.changes(&p.metadata),
            [
                "`dark_room` removed (was true)",
                "`operator` removed (was \"A. Lab\")",
                "`room` added: \"B12\"",
                "`run` removed (was 3)",
                "`temperature_c`: 21.5 -> 23.0"
            ]
        );
        assert!(q.metadata.changes(&q.metadata).is_empty());
        // A plan without `[metadata]` has none.
        assert!(Plan::parse("p.toml", SHORT).unwrap().metadata.is_empty());
    }

    #[test]
    fn other_values_are_refused_with_file_line_and_key() {
        let e = parse("operator = \"x\"\ntaken = 2026-11-29").unwrap_err();
        assert!(
            e.starts_with(
                "p.toml:5: key `metadata.taken`: expected text in quotes, a number or \
                 true/false"
            ) && e.contains("got 2026-11-29 (a date: write it in quotes"),
            "{e}"
        );
        let e = parse("lenses = [1, 2]").unwrap_err();
        assert!(
            e.starts_with("p.toml:4: key `metadata.lenses`: expected text")
                && e.ends_with("got a list"),
            "{e}"
        );
        let e = parse("[metadata.room]\nt = 1").unwrap_err();
        assert!(
            e.starts_with("p.toml:") && e.contains("key `metadata.room`"),
            "{e}"
        );
        let e = Plan::parse("p.toml", &format!("metadata = \"x\"\n{SHORT}")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "p.toml:1: key `metadata`: expected a table, a `[metadata]` line then `key = value` \
             lines, e.g. operator = \"A. Lab\", got \"x\""
        );
    }
}
