//! The plate's tilt from the operator's four corner readings.
//!
//! Thesis Ch IV levels each plate at its centre with a machinist's level (5 mils per foot)
//! and measures the separation "at four locations around the outer edges of the plates",
//! averaging them to the height at the centre. The same four readings also say how the
//! beacon plate leans: a plate higher by `h` at the rods on +x than at those on -x leans by
//! `atan(h / 2r)` about y. The sweep asks for the corners in a fixed order ([`CORNER_ORDER`],
//! at the rods [`ROD_XY_IN`] from the centre along x and y) and records the rods' place with
//! them; `cta analyze` turns them into each separation's plate tilt ([`corner_tilt`]) and
//! places the plate with it (host/ANALYZE.md, "Plate corners").
//!
//! Four readings fix the plate's height, its two slopes and one more number, the *twist*
//! `(c++ - c+- - c-+ + c--) / 4`: zero for a flat plate read exactly, so it shows how well
//! the corners were read (a reading to 1 mil gives a twist of about 0.3 mil).

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::error::{Context, Result};
use super::store::{self, Event};

/// Where the four corners are read: at x, y = +/-`ROD_XY_IN` in the sensor board's frame N
/// (in). Ch IV's level bound, 5 mils per foot "over one foot from the center", puts the
/// corners about a foot from the centre: 12 in / sqrt(2) = 8.5 in along each axis.
pub const ROD_XY_IN: f64 = 8.5;

/// The order of the four corner readings: (sign of x, sign of y) of each rod.
pub const CORNER_ORDER: [(f64, f64); 4] = [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)];

/// The order in words, as the operator is asked for it.
pub const CORNER_ORDER_TEXT: &str = "+x+y, +x-y, -x+y, -x-y";

/// What four corner readings say about the plate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CornerTilt {
    /// The plate's tilt vector (tx, ty), deg, as `plate_tilt` and
    /// [`crate::sim::Placement::tilt_deg`] define it: the plate's downward normal leans
    /// toward (tx, ty); a plate higher on +x has tx > 0.
    pub tilt_deg: [f64; 2],
    /// The twist, in: `(c++ - c+- - c-+ + c--) / 4`, zero for a flat plate read exactly.
    pub twist_in: f64,
}

/// The tilt of a plate whose corners, read in [`CORNER_ORDER`] at the rods `rods_xy_in` from
/// the centre, are `corners` (in); `None` unless there are four readings and the rods' place
/// is positive.
pub fn corner_tilt(corners: &[f64], rods_xy_in: f64) -> Option<CornerTilt> {
    let [pp, pm, mp, mm] = <[f64; 4]>::try_from(corners).ok()?;
    if !(rods_xy_in > 0.0 && rods_xy_in.is_finite()) || corners.iter().any(|c| !c.is_finite()) {
        return None;
    }
    let slope_x = (pp + pm - mp - mm) / (4.0 * rods_xy_in);
    let slope_y = (pp - pm + mp - mm) / (4.0 * rods_xy_in);
    Some(CornerTilt {
        tilt_deg: [slope_x.atan().to_degrees(), slope_y.atan().to_degrees()],
        twist_in: (pp - pm - mp + mm) / 4.0,
    })
}

/// One plate position's corners, as journalled.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlateCorners {
    /// The recorded separation (the corners' mean, as written in every row), in.
    pub separation: f64,
    /// The four readings, in.
    pub corners: Vec<f64>,
    /// The tilt they give; `None` when the journal does not record where and in which order
    /// they were read (a journal of an older version).
    pub tilt: Option<CornerTilt>,
}

/// The corner readings of a run: the journal they come from and every measured plate
/// position in it (the last entry of a position measured twice).
#[derive(Debug, Clone, PartialEq)]
pub struct RunCorners {
    /// The journal read.
    pub journal: PathBuf,
    /// Measured plate positions (entries without readings, `--yes` runs, left out).
    pub plates: Vec<PlateCorners>,
}

impl RunCorners {
    /// The corner readings journalled beside the measurement file `data`
    /// (`DIR/journal.jsonl` for `DIR/data.csv`): `None` when there is no journal there.
    pub fn beside(data: &Path) -> Option<Result<RunCorners>> {
        let dir = data.parent().unwrap_or(Path::new("."));
        let journal = dir.join(store::JOURNAL);
        if !journal.is_file() {
            return None;
        }
        Some(RunCorners::read(&journal))
    }

    /// Read the corner readings of the journal `journal`.
    pub fn read(journal: &Path) -> Result<RunCorners> {
        let bytes = std::fs::read(journal)
            .with_context(|| format!("{}: cannot read", journal.display()))?;
        let (events, _torn) = super::status::parse_journal(journal, &bytes)?;
        let mut plates: Vec<PlateCorners> = Vec::new();
        for e in events {
            let Event::Separation(s) = e else { continue };
            if s.corners.is_empty() {
                continue;
            }
            let p = PlateCorners {
                separation: s.mean,
                tilt: s.rods_xy_in.and_then(|r| corner_tilt(&s.corners, r)),
                corners: s.corners,
            };
            match plates.iter_mut().find(|q| q.separation == p.separation) {
                Some(q) => *q = p,
                None => plates.push(p),
            }
        }
        Ok(RunCorners {
            journal: journal.to_path_buf(),
            plates,
        })
    }

    /// The plate position recorded at `separation` (the value every row of it carries,
    /// rounded to 0.1 mil): its entry, if the corners were read.
    pub fn at(&self, separation: f64) -> Option<&PlateCorners> {
        self.plates
            .iter()
            .find(|p| (p.separation - separation).abs() < 5e-5)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::Placement;
    use nalgebra::Vector3;

    /// A plate turned by a known tilt about its centre, read at the rods: the tilt comes
    /// back, the twist is zero, and each sign goes the way `plate_tilt` defines it.
    #[test]
    fn corners_give_back_the_tilt_that_placed_the_plate() {
        for tilt in [[0.3, 0.0], [0.0, -0.2], [0.25, 0.4], [-1.0, 0.7]] {
            let pl = Placement {
                tilt_deg: tilt,
                ..Placement::default()
            };
            let z0 = 12.0;
            // The height of the plate's surface above each rod (the turned plane through the
            // centre, met at the rod's x, y).
            let n = pl.rotation() * Vector3::z();
            let corners: Vec<f64> = CORNER_ORDER
                .iter()
                .map(|(sx, sy)| {
                    let (x, y) = (sx * ROD_XY_IN, sy * ROD_XY_IN);
                    z0 - (n.x * x + n.y * y) / n.z
                })
                .collect();
            let t = corner_tilt(&corners, ROD_XY_IN).unwrap();
            for j in 0..2 {
                assert!(
                    (t.tilt_deg[j] - tilt[j]).abs() < 1e-3 * tilt[0].abs().max(tilt[1].abs()),
                    "{tilt:?}: {t:?}"
                );
            }
            assert!(t.twist_in.abs() < 1e-4, "{t:?}");
            // A plate higher on +x has tx > 0: Placement moves a beacon at +x up by about x tx.
            let b = pl.beacon(&Vector3::new(ROD_XY_IN, 0.0, z0));
            assert_eq!((b.z - z0).signum(), tilt[0].signum(), "{tilt:?}: {b}");
        }
        // One corner read 4 mils high: half the twist's size shows in each slope.
        let t = corner_tilt(&[10.004, 10.0, 10.0, 10.0], ROD_XY_IN).unwrap();
        assert!((t.twist_in - 0.001).abs() < 1e-12, "{t:?}");
        assert!((t.tilt_deg[0] - (0.001 / ROD_XY_IN).atan().to_degrees()).abs() < 1e-12);
        assert!(corner_tilt(&[1.0, 2.0, 3.0], ROD_XY_IN).is_none());
        assert!(corner_tilt(&[1.0; 4], 0.0).is_none());
        assert!(corner_tilt(&[1.0, 1.0, f64::NAN, 1.0], ROD_XY_IN).is_none());
    }
}
