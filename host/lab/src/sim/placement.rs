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
    /// Per LED (beacon id): its boresight's own tilt vector (tx, ty), deg (`led_tilt`; all
    /// zero without it), applied as [`led_emulator`] says.
    pub led_tilts_deg: Vec<[f64; 2]>,
    /// The arrays on the plate (one, or four in the quad layout) and where each truly sits.
    pub arrays: Vec<ArrayPlace>,
}

/// One beacon array on the plate: its nominal centre and its true pose against it
/// (`array_pose`: a rigid shift and turn in the plate's plane, all zero without it).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ArrayPlace {
    /// Nominal centre (x, y) on the plate, in.
    pub centre: [f64; 2],
    /// Shift (dx, dy), in, and turn dtheta, deg, about the centre (counter-clockwise seen
    /// from the sensor's +z: x toward y).
    pub pose: [f64; 3],
}

impl ArrayPlace {
    /// Where a point recorded at `(x, y)` on this array truly is: turned about the array's
    /// centre by dtheta, then shifted by (dx, dy).
    pub fn place(&self, x: f64, y: f64) -> [f64; 2] {
        let [dx, dy, dt] = self.pose;
        if dt == 0.0 {
            return [x + dx, y + dy];
        }
        let (s, c) = rad(dt).sin_cos();
        let (u, v) = (x - self.centre[0], y - self.centre[1]);
        [
            self.centre[0] + c * u - s * v + dx,
            self.centre[1] + s * u + c * v + dy,
        ]
    }
}

/// `em` (a separation's emulator, its boresight turned with the plate) for an LED whose
/// boresight is tilted by its own tilt vector `t` (deg, [`Placement::tilt_deg`]'s
/// convention: -z leans `|t|` toward `atan2(ty, tx)`), turned on top of the plate's.
pub fn led_emulator(em: &Emulator<f64>, t: [f64; 2]) -> Emulator<f64> {
    if t == [0.0, 0.0] {
        return *em;
    }
    let r = Placement {
        tilt_deg: t,
        ..Placement::default()
    }
    .rotation();
    em.with_boresight(&(r * em.boresight()))
}

impl Physics {
    /// The emulator of LED `id` at a separation whose emulator is `em` ([`led_emulator`]).
    pub fn led_emulator(&self, id: usize, em: &Emulator<f64>) -> Emulator<f64> {
        led_emulator(em, self.led_tilts_deg.get(id).copied().unwrap_or_default())
    }

    /// The true position (N, in) of LED `id`, recorded at `nominal`, at separation `k`.
    /// Its LED is off its pads by its offset, its array placed by the array's pose
    /// ([`ArrayPlace::place`]; array `id / 100` of several), the plate placed at the
    /// separation.
    pub fn beacon(&self, k: usize, id: usize, nominal: &Vector3<f64>) -> Vector3<f64> {
        let d = self.led_offsets.get(id).copied().unwrap_or_default();
        let (x, y) = (nominal.x + d[0], nominal.y + d[1]);
        let a = if self.arrays.len() > 1 { id / 100 } else { 0 };
        let [x, y] = match self.arrays.get(a) {
            Some(a) => a.place(x, y),
            None => [x, y],
        };
        self.geometry[k].beacon(&Vector3::new(x, y, nominal.z))
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
