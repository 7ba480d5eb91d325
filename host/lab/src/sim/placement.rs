//! Where the beacon plate truly is at each separation, against where it was recorded: the
//! apparatus errors `plate_offset`, `separation_error` and `plate_tilt` of the effect vocabulary.

use cta_core::emulator::Emulator;
use cta_core::real::rad;
use nalgebra::{Rotation3, Vector3};

/// The physics of a configuration: head, effects, and the per-separation geometry draws.
pub struct Physics {
    /// The emulator.
    pub emulator: Emulator<f64>,
    /// Per separation (in `separations` order): where the plate truly is.
    pub geometry: Vec<Placement>,
    /// Per LED (beacon id, in grid order): its true in-plane offset (dx, dy) from its
    /// nominal place on the plate, in (`led_position`; all zero without it). A beacon's true
    /// position is [`Placement::beacon`] of its nominal position plus this offset.
    pub led_offsets: Vec<[f64; 2]>,
}

impl Physics {
    /// The true position (N, in) of LED `id`, recorded at `nominal`, at separation `k`.
    pub fn beacon(&self, k: usize, id: usize, nominal: &Vector3<f64>) -> Vector3<f64> {
        let d = self.led_offsets.get(id).copied().unwrap_or_default();
        self.geometry[k].beacon(&(nominal + Vector3::new(d[0], d[1], 0.0)))
    }
}

/// Where the beacon plate truly is at one separation, against where it was recorded: the
/// per-separation apparatus errors `plate_offset`, `separation_error` and `plate_tilt`.
/// The recorded plate is centred on the N z axis at z = the recorded separation, parallel
/// to the sensor board.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Placement {
    /// Lateral offset of the plate's centre (x, y), in (`plate_offset`).
    pub offset: [f64; 2],
    /// True minus recorded separation, in (`separation_error`).
    pub sep_error: f64,
    /// Tilt vector (tx, ty), deg (`plate_tilt`): the plate's downward normal leans
    /// `|t|` from -z of N toward the azimuth `atan2(ty, tx)`.
    pub tilt_deg: [f64; 2],
}

impl Placement {
    /// Whether the plate is tilted.
    pub fn tilted(&self) -> bool {
        self.tilt_deg != [0.0, 0.0]
    }

    /// The plate's rotation about its centre: -z goes to
    /// `(sin T cos AZ, sin T sin AZ, -cos T)` by a rotation about the in-plate axis
    /// perpendicular to the azimuth (scaled axis `(ty, -tx, 0)`, radians).
    pub fn rotation(&self) -> Rotation3<f64> {
        let [tx, ty] = self.tilt_deg.map(rad);
        Rotation3::from_scaled_axis(Vector3::new(ty, -tx, 0.0))
    }

    /// The true position (N, in) of a beacon recorded at `r` (N, in): the plate's recorded
    /// centre is `(0, 0, r.z)`; the beacon's place on the plate is turned with the plate
    /// about its centre, and the centre moved by the offset and separation error.
    pub fn beacon(&self, r: &Vector3<f64>) -> Vector3<f64> {
        let moved = r + Vector3::new(self.offset[0], self.offset[1], self.sep_error);
        if !self.tilted() {
            return moved;
        }
        let u = Vector3::new(r.x, r.y, 0.0);
        moved - u + self.rotation() * u
    }

    /// `em` with its LEDs' boresight turned with the plate (on top of any `beacon_tilt`).
    pub fn emulator(&self, em: &Emulator<f64>) -> Emulator<f64> {
        if !self.tilted() {
            return *em;
        }
        em.with_boresight(&(self.rotation() * em.boresight()))
    }
}
