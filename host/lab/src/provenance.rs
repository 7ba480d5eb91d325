//! Where an output came from: the tool and its commit, when, the command line, and a hash of
//! every input file, so that a report or a JSON file read months later says what made it.

use std::io::Read;
use std::path::Path;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// The provenance of an output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The tool, its version and commit, e.g. `cta 0.1.0 (4917bb28b804)`.
    pub software: String,
    /// When the output was made, UTC, RFC 3339 (`2026-11-29T02:30:00Z`).
    pub date_utc: String,
    /// The command line.
    pub command: Vec<String>,
    /// The input files, each with its size and SHA-256.
    pub inputs: Vec<InputFile>,
}

/// One input file as it was read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputFile {
    /// The path as given.
    pub path: String,
    /// Its size, bytes (`None` when it could not be read).
    pub bytes: Option<u64>,
    /// Its SHA-256, lower-case hex (`None` when it could not be read).
    pub sha256: Option<String>,
}

impl InputFile {
    /// Hash the file at `path`, streamed; an unreadable file is recorded without a hash.
    pub fn hash(path: &Path) -> InputFile {
        let digest = || -> std::io::Result<(u64, String)> {
            let mut f = std::fs::File::open(path)?;
            let mut h = Sha256::new();
            let mut buf = vec![0u8; 1 << 16];
            let mut n = 0u64;
            loop {
                let k = f.read(&mut buf)?;
                if k == 0 {
                    break;
                }
                h.update(&buf[..k]);
                n += k as u64;
            }
            let hex = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
            Ok((n, hex))
        };
        let (bytes, sha256) = match digest() {
            Ok((n, s)) => (Some(n), Some(s)),
            Err(_) => (None, None),
        };
        InputFile {
            path: path.display().to_string(),
            bytes,
            sha256,
        }
    }
}

impl Provenance {
    /// The provenance of an output made now by `software` run as `command`, from `inputs`.
    pub fn now(software: &str, command: Vec<String>, inputs: &[&Path]) -> Provenance {
        Provenance {
            software: software.to_string(),
            date_utc: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
            command,
            inputs: inputs.iter().map(|p| InputFile::hash(p)).collect(),
        }
    }

    /// `value` with this provenance under the key `provenance`, when it is a JSON object
    /// (other values are returned as they are).
    pub fn attach(&self, mut value: serde_json::Value) -> serde_json::Value {
        if let (Some(map), Ok(p)) = (value.as_object_mut(), serde_json::to_value(self)) {
            map.insert("provenance".into(), p);
        }
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SHA-256 of a known text, the size, and an unreadable file recorded as such.
    #[test]
    fn inputs_are_hashed() {
        let dir = std::env::temp_dir().join(format!("cta-prov-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("abc.txt");
        std::fs::write(&f, "abc").unwrap();
        let p = Provenance::now("cta 0 (test)", vec!["cta".into()], &[&f, &dir.join("gone")]);
        assert_eq!(p.inputs[0].bytes, Some(3));
        assert_eq!(
            p.inputs[0].sha256.as_deref(),
            Some("ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad")
        );
        assert_eq!(
            (p.inputs[1].bytes, p.inputs[1].sha256.as_deref()),
            (None, None)
        );
        assert!(
            p.date_utc.ends_with('Z') && p.date_utc.len() == 20,
            "{}",
            p.date_utc
        );
        let v = p.attach(serde_json::json!({"a": 1}));
        assert_eq!(v["provenance"]["software"], "cta 0 (test)");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
