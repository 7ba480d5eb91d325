//! The pose analyses: the CTA's beacon plate and constellations, the calibrations a pose is
//! solved with, the simulated sensor head, the accuracy table, the docking envelope and the
//! pose noise floor.

pub mod accuracy;
pub mod calibrations;
pub mod envelope;
pub mod error;
pub mod floor;
pub mod head;
pub mod limits;
pub mod offline;
pub mod plate;

pub use error::Error;

/// The result of the pose analyses.
pub type Result<T, E = Error> = std::result::Result<T, E>;
