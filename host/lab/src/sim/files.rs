//! Writing a simulation: the measurement file and its truth sidecar, each whole or not at all,
//! and never over a file that is not an earlier simulation's.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::Truth;
use crate::data::{Dataset, OutputError};

/// Why a simulation was not written, or may not be written to the file named.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// `--out` names a folder.
    #[error("--out {}: is a folder; give a file name (e.g. {})", .out.display(), .out.join("sim.csv").display())]
    IsFolder {
        /// The folder.
        out: PathBuf,
    },
    /// The truth sidecar's name holds a file that is not an earlier simulation's truth.
    #[error(
        "--out {}: {} exists and is not the truth of an earlier `cta simulate` \
         output, and writing {} would replace it; not replaced: give another file name, \
         or --force to replace it",
        .out.display(), .truth.display(), .out.display()
    )]
    TruthNotOurs {
        /// The measurement file to write.
        out: PathBuf,
        /// Its sidecar's path.
        truth: PathBuf,
    },
    /// An existing file that cannot be read, so it is not known to be a simulation.
    #[error(
        "--out {}: exists and cannot be read ({error}), so it is not known to be an \
         earlier `cta simulate` output; not replaced: give another file name, or --force \
         to replace it",
        .out.display()
    )]
    Unreadable {
        /// The file.
        out: PathBuf,
        /// Why it cannot be read.
        error: std::io::Error,
    },
    /// An existing file that is not an earlier simulation.
    #[error(
        "--out {}: exists and is not an earlier `cta simulate` output (first line: `{first}`); not \
         replaced: give another file name, or --force to replace it",
        .out.display()
    )]
    NotOurs {
        /// The file.
        out: PathBuf,
        /// Its first line (at most 80 characters).
        first: String,
    },
    /// A folder above the file could not be created.
    #[error(transparent)]
    Folder(#[from] OutputError),
    /// The truth could not be put in JSON.
    #[error("{}: {error}", .truth.display())]
    TruthJson {
        /// The sidecar's path.
        truth: PathBuf,
        /// serde_json's message.
        error: String,
    },
    /// A partial file could not be written.
    #[error("cannot write {} (via {}): {error}", .path.display(), .via.display())]
    Partial {
        /// The file to write.
        path: PathBuf,
        /// The partial file.
        via: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// A partial file could not be renamed into place.
    #[error("cannot write {}: {error}", .path.display())]
    Rename {
        /// The file to write.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
}

/// Whether a simulation may be written to `out`: a new file or an earlier `cta simulate`
/// output (its first line names `cta ... simulate`), any other file only with `force`, never a
/// folder. [`write_files`] checks it too; calling it first refuses before simulating.
pub fn check_out(out: &Path, force: bool) -> Result<(), WriteError> {
    use std::io::BufRead;
    if out.is_dir() {
        return Err(WriteError::IsFolder {
            out: out.to_path_buf(),
        });
    }
    if force {
        return Ok(());
    }
    // The truth sidecar is replaced too: an existing one must be a simulation's as well.
    let tp = Truth::path_for(out);
    if tp.exists() {
        let generator =
            crate::bounded::read_text(&tp, crate::bounded::MAX_JSON_BYTES, "a JSON file")
                .ok()
                .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
                .and_then(|v| v["generator"].as_str().map(str::to_string));
        if !generator.is_some_and(|g| g.starts_with("cta ") && g.ends_with(" simulate")) {
            return Err(WriteError::TruthNotOurs {
                out: out.to_path_buf(),
                truth: tp,
            });
        }
    }
    if !out.exists() {
        return Ok(());
    }
    let mut first = String::new();
    std::fs::File::open(out)
        .map(std::io::BufReader::new)
        .and_then(|mut r| r.read_line(&mut first))
        .map_err(|error| WriteError::Unreadable {
            out: out.to_path_buf(),
            error,
        })?;
    if first.starts_with("# cta ") && first.contains(" simulate ") {
        return Ok(());
    }
    Err(WriteError::NotOurs {
        out: out.to_path_buf(),
        first: first.trim().chars().take(80).collect(),
    })
}

/// Write a simulation to `out` (CSV) and its truth to `FILE.truth.json`, each through a
/// `.partial` file renamed into place when complete (both removed on error), once `out` passes
/// [`check_out`]. Returns the truth's path.
pub fn write_files(
    out: &Path,
    ds: &Dataset,
    truth: &Truth,
    force: bool,
) -> Result<PathBuf, WriteError> {
    check_out(out, force)?;
    crate::data::create_parent_folders(out)?;
    let tp = Truth::path_for(out);
    let tmp = out.with_extension("csv.partial");
    let tmp_truth = tp.with_extension("json.partial");
    let comments = vec![
        format!("{} ; truth in {}", truth.generator, tp.display()),
        format!(
            "physics {} ; beacon {} ; effects [{}]",
            truth.physics,
            truth.pattern,
            truth.effects.join(" ")
        ),
    ];
    let write_csv = || -> std::io::Result<()> {
        let mut w = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        ds.write(&mut w, &comments)?;
        w.flush()?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()
    };
    let json = serde_json::to_string_pretty(truth).map_err(|e| WriteError::TruthJson {
        truth: tp.clone(),
        error: e.to_string(),
    })?;
    let result = write_csv()
        .map_err(|error| WriteError::Partial {
            path: out.to_path_buf(),
            via: tmp.clone(),
            error,
        })
        .and_then(|()| {
            std::fs::write(&tmp_truth, json).map_err(|error| WriteError::Partial {
                path: tp.clone(),
                via: tmp_truth.clone(),
                error,
            })
        })
        .and_then(|()| {
            std::fs::rename(&tmp_truth, &tp).map_err(|error| WriteError::Rename {
                path: tp.clone(),
                error,
            })
        })
        .and_then(|()| {
            std::fs::rename(&tmp, out).map_err(|error| WriteError::Rename {
                path: out.to_path_buf(),
                error,
            })
        });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
        let _ = std::fs::remove_file(&tmp_truth);
    }
    result.map(|()| tp)
}
