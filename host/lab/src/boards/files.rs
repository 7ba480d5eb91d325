//! The files the sensor board stores, a calibration and a constellation, read from JSON.
//!
//! A key the type does not have is refused, naming it and the keys it has there: a typo
//! (`gains` for `gain`, `nearfield` for `near_field`) would otherwise be dropped, and the
//! board would store the nominal value in its place. Another kind of `cta` file (a saved
//! fit, a truth sidecar, a measurement file) is named, with the command that makes the file
//! wanted.

use cta_core::pose::{Calibration, Constellation};

/// Why a board file was refused.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file could not be read.
    #[error("reading {file}: {error}")]
    Read {
        /// The file.
        file: String,
        /// Why.
        error: std::io::Error,
    },
    /// The file is another kind of `cta` file; the message says which and what to do.
    #[error("{0}")]
    OtherKind(String),
    /// The file is not JSON of the expected shape.
    #[error(
        "{file}: not a valid JSON document of the expected shape (see `cta sensor template`): {error}"
    )]
    Shape {
        /// The file.
        file: String,
        /// What the JSON reader found.
        error: serde_json::Error,
    },
    /// A key the type does not have.
    #[error(
        "{file}: unknown key `{key}` (a typo? the keys there are {keys}; see `cta sensor template`)"
    )]
    UnknownKey {
        /// The file.
        file: String,
        /// The key, by path (`near_field.gains`, `beacons[3].pos`).
        key: String,
        /// The keys there, quoted, comma-separated.
        keys: String,
    },
    /// The parsed document could not be compared with the file's keys.
    #[error(transparent)]
    Json(serde_json::Error),
}

/// A file the board stores: a calibration or a constellation (what [`read_json`] expects).
pub trait BoardFile {
    /// What it is, for messages: `calibration`, `constellation`.
    const WHAT: &'static str;
    /// Where one comes from.
    const MADE_BY: &'static str;
    /// The `cta sensor` subcommand that loads one.
    const LOAD: &'static str;
    /// Top-level keys of host-side data the board ignores.
    const HOST_KEYS: &'static [&'static str] = &["fitted"];
}

impl BoardFile for Calibration {
    const WHAT: &'static str = "calibration";
    const MADE_BY: &'static str = "a calibration comes from `cta calibrate DATA.csv --out \
         cal.json` (a sweep's data) or `cta sensor template calibration` (to edit)";
    const LOAD: &'static str = "load-calibration";
    // `cta calibrate`'s provenance and the LEDs' brightness
    // (`load-constellation --brightness`).
    const HOST_KEYS: &'static [&'static str] = &["fitted", "led_brightness"];
}

impl BoardFile for Constellation {
    const WHAT: &'static str = "constellation";
    const MADE_BY: &'static str =
        "a constellation comes from `cta sensor template constellation > con.json` (to edit)";
    const LOAD: &'static str = "load-constellation";
}

/// Read a calibration or constellation file, refusing a key the type does not have (the
/// host-side keys of [`BoardFile::HOST_KEYS`] excepted: what `cta calibrate` records of the
/// fit, and the LEDs' brightness) and naming another kind of `cta` file.
pub fn read_json<T: serde::de::DeserializeOwned + serde::Serialize + BoardFile>(
    file: &str,
) -> Result<T, Error> {
    let text = crate::bounded::read_text(
        std::path::Path::new(file),
        crate::bounded::MAX_JSON_BYTES,
        "a JSON file",
    )
    .map_err(|error| Error::Read {
        file: file.to_string(),
        error,
    })?;
    let t: T = match serde_json::from_str(&text) {
        Ok(t) => t,
        Err(error) => {
            if let Some(why) = other_kind::<T>(file, &text) {
                return Err(Error::OtherKind(why));
            }
            return Err(Error::Shape {
                file: file.to_string(),
                error,
            });
        }
    };
    // Every key is read again as JSON (a value the type skips, e.g. a number out of range
    // in the host-side keys, fails here): the error names the file.
    let given: serde_json::Value = serde_json::from_str(&text).map_err(|error| Error::Shape {
        file: file.to_string(),
        error,
    })?;
    let known = serde_json::to_value(&t).map_err(Error::Json)?;
    if let Some((key, keys)) = unknown_key(&given, &known, "", T::HOST_KEYS) {
        return Err(Error::UnknownKey {
            file: file.to_string(),
            key,
            keys,
        });
    }
    Ok(t)
}

/// When `text` (the file `file`, which did not parse as a `T`) is another kind of `cta` file
/// (a saved fit, a calibration where a constellation belongs or the reverse, a truth sidecar,
/// a measurement file), the error saying which and what to do.
fn other_kind<T: BoardFile>(file: &str, text: &str) -> Option<String> {
    let want = format!("a sensor board {} (`cta sensor {}`)", T::WHAT, T::LOAD);
    let Ok(v) = serde_json::from_str::<serde_json::Value>(text) else {
        return crate::data::looks_like_measurements(text).then(|| {
            format!(
                "{file}: this is a measurement file (CSV), not {want}: {}",
                if T::WHAT == "calibration" {
                    format!("`cta calibrate {file} --out cal.json` makes the calibration from it")
                } else {
                    T::MADE_BY.to_string()
                }
            )
        });
    };
    let has = |k: &str| v.get(k).is_some();
    let (what, instead) = if has("params") && has("covariance") {
        let source = v["source"].as_str().unwrap_or("DATA.csv");
        (
            "a saved fit (`cta fit --save`: the 7-parameter pinhole model of eq 65, read by `cta \
             evaluate`)",
            if T::WHAT == "calibration" {
                format!(
                    "the board's calibration is made from the measurement file the fit came from: \
                     `cta calibrate {source} --out cal.json`, then load that"
                )
            } else {
                T::MADE_BY.to_string()
            },
        )
    } else if has("beacons") && T::WHAT != "constellation" {
        (
            "a constellation (its `beacons`)",
            format!(
                "load it with `cta sensor --port PORT load-constellation {file}`; {}",
                T::MADE_BY
            ),
        )
    } else if has("h") && has("noise") && has("d") && T::WHAT != "calibration" {
        (
            "a sensor calibration (`cta calibrate --out`)",
            format!(
                "load it with `cta sensor --port PORT load-calibration {file}`; {}",
                T::MADE_BY
            ),
        )
    } else if has("generator") && has("effects") {
        (
            "a simulation's truth sidecar (the head and effects a simulation used)",
            format!(
                "`cta sensor sim --truth {file}` simulates that head; {}",
                T::MADE_BY
            ),
        )
    } else if has("plan") && has("sessions") {
        (
            "a sweep's manifest (manifest.json)",
            if T::WHAT == "calibration" {
                let data = std::path::Path::new(file).with_file_name("data.csv");
                format!(
                    "`cta calibrate {} --out cal.json` makes the calibration from the sweep's data",
                    data.display()
                )
            } else {
                T::MADE_BY.to_string()
            },
        )
    } else {
        return None;
    };
    Some(format!("{file}: this is {what}, not {want}: {instead}"))
}

/// The first key of `given` (by path, `near_field.gains`, `beacons[3].pos`) that `known`
/// (the same document as parsed and written back) lacks, with the keys `known` has there.
/// `allow`: top-level keys to pass.
fn unknown_key(
    given: &serde_json::Value,
    known: &serde_json::Value,
    path: &str,
    allow: &[&str],
) -> Option<(String, String)> {
    use serde_json::Value;
    match (given, known) {
        (Value::Object(g), Value::Object(k)) => {
            for (name, v) in g {
                let here = if path.is_empty() {
                    name.clone()
                } else {
                    format!("{path}.{name}")
                };
                match k.get(name) {
                    Some(kv) => {
                        if let Some(found) = unknown_key(v, kv, &here, &[]) {
                            return Some(found);
                        }
                    }
                    None if allow.contains(&name.as_str()) => {}
                    None => {
                        let keys: Vec<String> = k.keys().map(|n| format!("`{n}`")).collect();
                        return Some((here, keys.join(", ")));
                    }
                }
            }
            None
        }
        (Value::Array(g), Value::Array(k)) => g
            .iter()
            .zip(k)
            .enumerate()
            .find_map(|(i, (gv, kv))| unknown_key(gv, kv, &format!("{path}[{i}]"), &[])),
        _ => None,
    }
}
