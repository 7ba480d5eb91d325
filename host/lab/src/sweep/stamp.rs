//! The journal's times: `at`, seconds since the Unix epoch (what the run computes with), and
//! beside it `time`, the same instant in ISO 8601 UTC to the millisecond
//! (`2026-11-29T04:12:03.412Z`), which a person, a spreadsheet, pandas or MATLAB read as a
//! date. Journals of versions before `time` hold `at` alone and load as they are; a line
//! with `time` alone (written by another tool) loads too.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::time::{Duration, UNIX_EPOCH};

/// `t` (seconds since the epoch) in ISO 8601 UTC, rounded to the millisecond, e.g.
/// `2026-11-29T04:12:03.412Z`; `None` for a time before the epoch or not finite. (Rounded, not
/// truncated: 1795925523.412 is stored as 1795925523.41199994, which is .412.)
pub fn iso8601(t: f64) -> Option<String> {
    let ms = (t * 1000.0).round();
    if !(0.0..=u64::MAX as f64).contains(&ms) {
        return None;
    }
    let when = UNIX_EPOCH.checked_add(Duration::from_millis(ms as u64))?;
    Some(humantime::format_rfc3339_millis(when).to_string())
}

/// Seconds since the epoch of an ISO 8601 UTC time (`Z` or `+00:00`, any fraction);
/// `None` if it is not one.
pub fn from_iso8601(s: &str) -> Option<f64> {
    let when = humantime::parse_rfc3339(s).ok()?;
    Some(when.duration_since(UNIX_EPOCH).ok()?.as_secs_f64())
}

/// What a journal line may hold for a time.
#[derive(Deserialize)]
struct Times {
    at: Option<f64>,
    time: Option<String>,
}

impl Times {
    /// `at`, else `time` read back; an unreadable `time` is named.
    fn seconds<E: serde::de::Error>(self) -> Result<Option<f64>, E> {
        match (self.at, self.time) {
            (Some(at), _) => Ok(Some(at)),
            (None, Some(t)) => from_iso8601(&t).map(Some).ok_or_else(|| {
                E::custom(format!(
                    "`time` {t:?}: expected an ISO 8601 UTC time such as 2026-11-29T04:12:03.412Z"
                ))
            }),
            (None, None) => Ok(None),
        }
    }
}

/// The two keys written for a time.
#[derive(Serialize)]
struct Written {
    at: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    time: Option<String>,
}

/// `#[serde(flatten, with = "stamp::at")]` on an `at: f64`: writes `at` and `time`, reads
/// either (`at` first).
pub mod at {
    use super::*;

    /// `"at":T,"time":"ISO"`.
    pub fn serialize<S: Serializer>(at: &f64, s: S) -> Result<S::Ok, S::Error> {
        Written {
            at: *at,
            time: iso8601(*at),
        }
        .serialize(s)
    }

    /// `at`, else `time`; one of them is required.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Times::deserialize(d)?
            .seconds()?
            .ok_or_else(|| serde::de::Error::missing_field("at"))
    }
}

/// `#[serde(flatten, with = "stamp::opt_at")]` on an `at: Option<f64>`: as [`at`], nothing
/// written for `None`, `None` when neither key is there (journals of versions before it).
pub mod opt_at {
    use super::*;

    /// `"at":T,"time":"ISO"`, or nothing.
    pub fn serialize<S: Serializer>(at: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        at.map(|at| Written {
            at,
            time: iso8601(at),
        })
        .serialize(s)
    }

    /// `at`, else `time`, else `None`.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
        Times::deserialize(d)?.seconds()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::event::{Event, PointStatus};

    #[test]
    fn times_are_iso_8601_utc_to_the_millisecond() {
        assert_eq!(iso8601(0.0).unwrap(), "1970-01-01T00:00:00.000Z");
        assert_eq!(
            iso8601(1_795_419_264.0).unwrap(),
            "2026-11-23T07:34:24.000Z"
        );
        // Rounded: the stored double is just below .412.
        assert_eq!(
            iso8601(1_795_925_523.412).unwrap(),
            "2026-11-29T04:12:03.412Z"
        );
        assert_eq!(
            iso8601(1_795_925_523.4126).unwrap(),
            "2026-11-29T04:12:03.413Z"
        );
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(iso8601(bad), None, "{bad}");
        }
        let back = from_iso8601("2026-11-29T04:12:03.412Z").unwrap();
        assert!((back - 1_795_925_523.412).abs() < 1e-6, "{back}");
        assert_eq!(from_iso8601("2026-11-29T04:12:03Z"), Some(1_795_925_523.0));
        assert_eq!(from_iso8601("2026-11-29 04:12:03"), None);
        assert_eq!(from_iso8601("1795925523.412"), None);
    }

    fn stop(at: f64) -> Event {
        Event::Stop {
            at,
            reason: "complete".into(),
            next_point: 3,
            notes: Vec::new(),
        }
    }

    /// A line holds `at` and, right after it, `time`; it reads back to the same event.
    #[test]
    fn a_journal_line_holds_both_times() {
        let line = serde_json::to_string(&stop(1_795_925_523.412)).unwrap();
        assert_eq!(
            line,
            r#"{"event":"stop","at":1795925523.412,"time":"2026-11-29T04:12:03.412Z","reason":"complete","next_point":3}"#
        );
        assert_eq!(
            serde_json::from_str::<Event>(&line).unwrap(),
            stop(1_795_925_523.412)
        );
    }

    /// Journals of earlier versions (`at` alone) load; a line with `time` alone loads to its
    /// seconds; `at` wins over a `time` that says otherwise; neither is refused, naming `at`,
    /// and an unreadable `time` is named.
    #[test]
    fn epoch_only_and_iso_only_lines_load() {
        let old = r#"{"event":"stop","at":1795925523.412,"reason":"complete","next_point":3}"#;
        assert_eq!(
            serde_json::from_str::<Event>(old).unwrap(),
            stop(1_795_925_523.412)
        );
        let iso = r#"{"event":"stop","time":"2026-11-29T04:12:03.5Z","reason":"complete","next_point":3}"#;
        assert_eq!(
            serde_json::from_str::<Event>(iso).unwrap(),
            stop(1_795_925_523.5)
        );
        let both = r#"{"event":"stop","at":7.0,"time":"2026-11-29T04:12:03.5Z","reason":"complete","next_point":3}"#;
        assert_eq!(serde_json::from_str::<Event>(both).unwrap(), stop(7.0));
        let neither = r#"{"event":"stop","reason":"complete","next_point":3}"#;
        let e = serde_json::from_str::<Event>(neither)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`at`"), "{e}");
        let bad = r#"{"event":"stop","time":"yesterday","reason":"complete","next_point":3}"#;
        let e = serde_json::from_str::<Event>(bad).unwrap_err().to_string();
        assert!(
            e.contains("`time` \"yesterday\"") && e.contains("ISO 8601"),
            "{e}"
        );
    }

    /// A point's time is optional (journals before it had none): absent, neither key is
    /// written and it reads back as none.
    #[test]
    fn a_point_without_a_time_stays_without() {
        let point = |at| Event::Point {
            i: 4,
            status: PointStatus::Ok,
            samples: 3,
            reports: 3,
            lost: 0,
            attempts: 1,
            csv_end: 120,
            csv_hash: None,
            at,
        };
        let line = serde_json::to_string(&point(None)).unwrap();
        assert!(
            !line.contains("\"at\"") && !line.contains("\"time\""),
            "{line}"
        );
        assert_eq!(serde_json::from_str::<Event>(&line).unwrap(), point(None));
        let line = serde_json::to_string(&point(Some(0.25))).unwrap();
        assert!(
            line.ends_with(r#""at":0.25,"time":"1970-01-01T00:00:00.250Z"}"#),
            "{line}"
        );
        assert_eq!(
            serde_json::from_str::<Event>(&line).unwrap(),
            point(Some(0.25))
        );
    }
}
