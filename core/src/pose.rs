//! On-chip 6-dof pose solution (being written by the firmware-sensor issue).

use serde::{Deserialize, Serialize};

/// One IR spot as the NorthStar reports it.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Spot {
    /// Frequency channel 0..=19 (beacon `k` uses channels `2k` and `2k + 1`).
    pub id: u8,
    /// X output, signed counts (eq 63).
    pub x: i16,
    /// Y output, signed counts (eq 63).
    pub y: i16,
    /// Signal strength 0..65535 (about 5000 is the noise floor, above 47000 is strong).
    pub magnitude: u16,
}
