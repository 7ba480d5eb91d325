//! The output files of `cta` commands: written whole through a `.partial` file, with missing
//! folders created, and never over a file the command did not write.

use std::io::Write;
use std::path::{Path, PathBuf};

/// Why an output file was not written, or may not be.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// A folder above the file could not be created.
    #[error("cannot write {}: cannot create the folder {}: {error}", .path.display(), .dir.display())]
    Folder {
        /// The output file.
        path: PathBuf,
        /// The folder that could not be created.
        dir: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// The file could not be written or renamed into place.
    #[error("cannot write {}: {error}", .path.display())]
    Write {
        /// The output file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// The output named is a folder.
    #[error("{flag} {}: is a folder; give a file name (e.g. {example})", .path.display())]
    IsFolder {
        /// The option that named it.
        flag: String,
        /// The folder.
        path: PathBuf,
        /// A file name to suggest.
        example: String,
    },
    /// The output named is the measurement file it is derived from.
    #[error("{flag} {}: is the measurement file", .path.display())]
    IsData {
        /// The option that named it.
        flag: String,
        /// The file.
        path: PathBuf,
    },
    /// The output names an existing file that is not this command's own output.
    #[error(
        "{flag} {}: exists and is not {what}; not replaced: give another file name, or \
         --force to replace it",
        .path.display()
    )]
    NotOurs {
        /// The option that named it.
        flag: String,
        /// The file.
        path: PathBuf,
        /// What it would have to be to be replaced.
        what: String,
    },
}

/// Create the folders missing above the output file `path` (`--save nd1/fit.json` creates
/// `nd1`), so that a computed result is never lost to a missing folder.
pub fn create_parent_folders(path: &Path) -> Result<(), OutputError> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() && !dir.is_dir() => std::fs::create_dir_all(dir)
            .map_err(|error| OutputError::Folder {
                path: path.to_path_buf(),
                dir: dir.to_path_buf(),
                error,
            }),
        _ => Ok(()),
    }
}

/// Write an output file of a `cta` command (`fit --save`, `calibrate --out`, every `--plot`
/// SVG) the one way they are all written: missing folders created, the bytes written to
/// `PATH.partial` and renamed into place when complete, so an earlier file is replaced whole
/// or not at all. Whether `path` may be replaced is the caller's check.
pub fn write_output(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    create_parent_folders(path)?;
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    let tmp = path.with_file_name(name);
    let write = || -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    };
    write().map_err(|error| {
        let _ = std::fs::remove_file(&tmp);
        OutputError::Write {
            path: path.to_path_buf(),
            error,
        }
    })
}

/// Whether a file derived from the measurement file `data` (a saved fit, a calibration) may
/// be written to `out`, given on the command line as `flag`: never a folder or `data` itself;
/// an existing file only when `earlier` recognises it as this command's own output (`what`
/// names that in the refusal), or with `force`. Nothing is modified.
pub fn check_derived_output(
    flag: &str,
    out: &Path,
    data: &Path,
    example: &str,
    what: &str,
    earlier: impl Fn(&Path) -> bool,
    force: bool,
) -> Result<(), OutputError> {
    if out.is_dir() {
        return Err(OutputError::IsFolder {
            flag: flag.into(),
            path: out.to_path_buf(),
            example: example.into(),
        });
    }
    if !out.exists() {
        return Ok(());
    }
    if let (Ok(a), Ok(b)) = (out.canonicalize(), data.canonicalize()) {
        if a == b {
            return Err(OutputError::IsData {
                flag: flag.into(),
                path: out.to_path_buf(),
            });
        }
    }
    if force || earlier(out) {
        return Ok(());
    }
    Err(OutputError::NotOurs {
        flag: flag.into(),
        path: out.to_path_buf(),
        what: what.into(),
    })
}
