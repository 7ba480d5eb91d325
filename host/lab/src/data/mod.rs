//! The CTA measurement file: what sweeps write, what `cta simulate` writes, and what users
//! bring from their own rigs. The format is documented in `host/MEASUREMENTS.md`.
//!
//! CSV with a header line. Required columns: `separation_in`, `beacon_x_in`, `beacon_y_in`,
//! `beacon_z_in`, `x`, `y`. Optional: `beacon`, `frequency_hz`, `power`, `sensitivity`,
//! `sample`, `magnitude`. Unknown columns are ignored; lines starting with `#` are comments.
//! Beacon positions are in the N frame (inches); `x`, `y` are NorthStar counts.

mod error;
mod glitches;
mod output;
mod read;
mod sample;
mod separations;
#[cfg(test)]
mod tests;
mod warnings;
pub mod weights;

pub use error::{ReadError, Reason};
pub use glitches::{
    AxisGlitches, Glitches, WithoutGlitches, GLITCH_FLOOR_COUNTS, GLITCH_MIN_SAMPLES, GLITCH_SIGMA,
};
pub use output::{check_derived_output, create_parent_folders, write_output, OutputError};
pub use read::{file_looks_like_measurements, looks_like_measurements, MAX_INCHES};
pub use sample::{
    any_sample_pinned, comment_text, mean_near_rail, write_row, Dataset, Point, Sample,
    MAX_BEACON_ID, OPTIONAL, RAIL, REQUIRED,
};
pub use separations::{
    fmt_list, nearest_within, parse_new_separations, parse_separations, SeparationError,
    FAR_SEPARATION_IN, MAX_SEPARATIONS, SEP_MATCH_IN, SEP_TYPO_IN, SEP_TYPO_RATIO,
};
