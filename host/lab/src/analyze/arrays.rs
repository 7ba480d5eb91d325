//! `array_pose`: several beacon arrays on the plate (the quad layout, Ch IV), each placed by
//! hand as a rigid body, so each sits shifted and turned in the plate's plane by its own
//! (dx, dy, dtheta), the same at every separation.
//!
//! An array turned by dtheta about its centre c and shifted by (dx, dy) moves an LED
//! recorded at r to `c + R(dtheta) (r - c) + (dx, dy)`. **Gauge:** the same shift of every
//! array is the head offset d1, d2, and the same turn of every array about the plate's centre
//! (the N z axis) is the head's p3 (a turn of each array about its own centre plus a shift of
//! its centre, `dtheta (-c_y, c_x)`). The three directions are fixed by holding the arrays'
//! mean dx, mean dy and mean dtheta at zero: each array's pose is relative to the arrays'
//! mean place, which the head pose carries. With the four arrays placed symmetrically about
//! the centre, the mean turn held at zero leaves the mean shift unchanged, so the three
//! constraints are independent of one another.

use super::model::Led;

/// Beacon ids per array: array `a` holds ids `100 a` to `100 a + 99` (the sweep's `quad`
/// layout, [`crate::data::MAX_BEACON_ID`]).
pub const IDS_PER_ARRAY: u32 = 100;

/// One array on the plate, as the data shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Array {
    /// Array number (beacon id / 100).
    pub id: u32,
    /// Nominal centre: the mean recorded (x, y) of its LEDs, in.
    pub centre: [f64; 2],
}

/// The arrays of `leds` (by beacon id / 100), by number ascending; empty with fewer than two
/// (one array's pose is the head's).
pub fn arrays_of(leds: &[Led]) -> Vec<Array> {
    let mut out: Vec<(u32, [f64; 2], f64)> = Vec::new();
    for l in leds {
        let id = l.id / IDS_PER_ARRAY;
        match out.iter_mut().find(|a| a.0 == id) {
            Some(a) => {
                a.1[0] += l.xy[0];
                a.1[1] += l.xy[1];
                a.2 += 1.0;
            }
            None => out.push((id, l.xy, 1.0)),
        }
    }
    if out.len() < 2 {
        return Vec::new();
    }
    out.sort_by_key(|a| a.0);
    out.into_iter()
        .map(|(id, s, n)| Array {
            id,
            centre: [s[0] / n, s[1] / n],
        })
        .collect()
}

/// The in-plane move of a point recorded at `(x, y)` on an array centred at `c` whose pose
/// is `pose` (dx, dy in, dtheta deg; counter-clockwise seen from +z): turned about `c`, then
/// shifted.
pub fn displacement(c: [f64; 2], pose: [f64; 3], x: f64, y: f64) -> [f64; 2] {
    let (s, co) = pose[2].to_radians().sin_cos();
    let (u, v) = (x - c[0], y - c[1]);
    [co * u - s * v - u + pose[0], s * u + co * v - v + pose[1]]
}

/// The gauge rows of the array poses whose parameters start at `start` (dx, dy, dtheta per
/// array, `n` arrays): the mean dx, mean dy and mean dtheta held at zero (module doc).
pub fn gauge(start: usize, n: usize) -> Vec<Vec<(usize, f64)>> {
    let w = 1.0 / n.max(1) as f64;
    (0..3)
        .map(|c| (0..n).map(|a| (start + 3 * a + c, w)).collect())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn led(id: u32, x: f64, y: f64) -> Led {
        Led { id, xy: [x, y] }
    }

    /// Arrays from beacon ids, centred on their LEDs; one array is none.
    #[test]
    fn arrays_are_told_by_their_ids() {
        let leds = [
            led(0, -7.0, -6.0),
            led(1, -5.0, -6.0),
            led(105, 6.0, -6.0),
            led(301, 6.0, 6.0),
        ];
        let a = arrays_of(&leds);
        assert_eq!(a.iter().map(|a| a.id).collect::<Vec<_>>(), [0, 1, 3]);
        assert_eq!(a[0].centre, [-6.0, -6.0]);
        assert!(arrays_of(&leds[..2]).is_empty());
    }

    /// A turn of 90 deg takes +x of the centre to +y (counter-clockwise), then the shift.
    #[test]
    fn a_turn_is_counter_clockwise_about_the_centre() {
        let d = displacement([6.0, 6.0], [0.1, -0.2, 90.0], 7.0, 6.0);
        assert!((d[0] - (-1.0 + 0.1)).abs() < 1e-12 && (d[1] - (1.0 - 0.2)).abs() < 1e-12);
        let d = displacement([6.0, 6.0], [0.0, 0.0, 0.0], 7.0, 6.0);
        assert_eq!(d, [0.0, 0.0]);
    }
}
