//! The pose analyses: the CTA's beacon plate and constellations, and the pose noise floor.

pub mod floor;
pub mod plate;
