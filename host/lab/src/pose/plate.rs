//! The CTA's beacon plate and the constellations the pose analyses (`cta sensor accuracy`,
//! `cta sensor floor`) are run on.
//!
//! The thesis (Ch IV; REFERENCE.md section 4) mounts either one 10 x 10 array (1 in pitch)
//! centred on the 24 in plate, or four of them in the plate's quadrants. The four-array
//! positions assume each 12 x 12 in board sits centred in its quadrant, its grid centre at
//! (+/-6, +/-6) in: LEDs at +/-1.5 .. +/-10.5 in on both axes, a 20 x 20 grid with a 3 in
//! gap through the middle (the arrays' 1.5 in margins meeting).
//!
//! Which plate is mounted matters twice: the calibration sweeps (pinhole at 25 and 30 in,
//! near-field at 2-30 in) see the plate's whole grid, so a calibration only covers the angles
//! its plate spans; and the constellation's spread sets how well attitude is observed (the
//! floor of `cta sensor floor`).

use cta_core::emulator::grid_position;
use cta_core::pose::{
    cta_constellation, flat_constellation, four_array_constellation, Constellation,
};
use cta_core::schedule::NORTHSTAR_TABLE_MHZ;
use nalgebra::Vector3;
use serde::Serialize;

use crate::boards::files::read_json;
use crate::pose::error::Error;

/// Which beacon arrays are on the plate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Plate {
    /// One 10 x 10 array centred over the sensor: x, y in -4.5 .. 4.5 in.
    One,
    /// Four arrays in the quadrants: x, y in +/-1.5 .. +/-10.5 in (a 20 x 20 grid with a
    /// 3 in gap at the centre).
    Four,
}

impl Plate {
    /// Every LED position of the plate at `separation` (in), in the sensor frame N.
    pub fn positions(self, separation: f64) -> Vec<Vector3<f64>> {
        let one = (0..100).map(move |i| grid_position(10, 1.0, separation, i));
        match self {
            Plate::One => one.collect(),
            Plate::Four => [(6.0, 6.0), (-6.0, 6.0), (-6.0, -6.0), (6.0, -6.0)]
                .iter()
                .flat_map(|&(cx, cy)| {
                    (0..100).map(move |i| {
                        grid_position(10, 1.0, separation, i) + Vector3::new(cx, cy, 0.0)
                    })
                })
                .collect(),
        }
    }

    /// Whether `(x, y)` (in) is an LED position of this plate (to 0.01 in).
    pub fn holds(self, x: f64, y: f64) -> bool {
        let on_axis = |v: f64| {
            let a = v.abs();
            let half = (a - 0.5).round() + 0.5; // nearest half-integer
            let (lo, hi) = match self {
                Plate::One => (0.5, 4.5),
                Plate::Four => (1.5, 10.5),
            };
            (a - half).abs() < 0.01 && half >= lo - 0.01 && half <= hi + 0.01
        };
        on_axis(x) && on_axis(y)
    }

    /// Short description for table headers.
    pub fn describe(self) -> &'static str {
        match self {
            Plate::One => "one array (x, y within 4.5 in)",
            Plate::Four => "four arrays (x, y 1.5-10.5 in)",
        }
    }
}

/// A built-in constellation: its name, plate, beacons (IDs in order, each one NorthStar
/// frequency channel: the NorthStar tracks up to 20 spots) and what it is for. `--depth`
/// raises every beacon after the first five.
struct BuiltIn {
    name: &'static str,
    plate: Plate,
    beacons: fn() -> Constellation,
    what: &'static str,
}

const BUILT_IN: [BuiltIn; 4] = [
    BuiltIn {
        name: "one-10",
        plate: Plate::One,
        beacons: cta_constellation,
        what: "the CTA constellation the chip is benchmarked on",
    },
    BuiltIn {
        name: "one-19",
        plate: Plate::One,
        beacons: one_19,
        what: "one-10 and nine more: every NorthStar frequency on one array",
    },
    BuiltIn {
        name: "four-10",
        plate: Plate::Four,
        beacons: four_10,
        what: "spread over four arrays: five inner (seen from 2 in), five near the edge",
    },
    BuiltIn {
        name: "four-19",
        plate: Plate::Four,
        beacons: four_19,
        what: "four-10 and nine more: every NorthStar frequency over four arrays",
    },
];

/// NorthStar channels that share a frequency in the default table
/// ([`NORTHSTAR_TABLE_MHZ`], the hobbyists' table: ID k's LEDs at 4050 + 120 (k - 1) and
/// 3090 + 120 (k - 1) Hz give ID 9's second LED, channel 19, the 4050 Hz of ID 1's first,
/// channel 2): a detector sees one spot there and cannot tell which, so a constellation may
/// use one channel of each pair. 19 distinct frequencies, not 20.
pub fn shared_channels() -> Vec<(u8, u8)> {
    let t = &NORTHSTAR_TABLE_MHZ;
    let mut out = Vec::new();
    for i in 0..t.len() {
        for j in i + 1..t.len() {
            if t[i] == t[j] {
                out.push((i as u8, j as u8));
            }
        }
    }
    out
}

/// Refuses a constellation with two beacons on channels that share a frequency
/// ([`shared_channels`]).
pub fn check_channels(con: &Constellation) -> Result<(), Error> {
    let has = |id: u8| con.beacons.iter().any(|b| b.id == id);
    for (a, b) in shared_channels() {
        if has(a) && has(b) {
            return Err(Error::SharedChannels {
                a,
                b,
                hz: NORTHSTAR_TABLE_MHZ[a as usize] as f64 / 1000.0,
            });
        }
    }
    Ok(())
}

/// A constellation file (`cta sensor load-constellation`, `--constellation FILE`): read,
/// validated as the board validates it, and refused when it cannot work or is surely a
/// slip: more beacons than the board holds, two channels of one frequency
/// ([`check_channels`]), two beacons at one place, all beacons on one line (the attitude
/// about it is unobservable). Beacons farther than 60 in from the target's origin are
/// warned about (millimetres for inches?). Returns the constellation and the warnings.
pub fn read_constellation(file: &str) -> Result<(Constellation, Vec<String>), Error> {
    let text = std::fs::read_to_string(file).map_err(|error| Error::Read {
        file: file.to_string(),
        error,
    })?;
    let refused = |why: String| Error::Constellation {
        file: file.to_string(),
        why,
    };
    if let Ok(v) = serde_json::from_str::<serde_json::Value>(&text) {
        if let Some(n) = v["beacons"].as_array().map(Vec::len) {
            if n > cta_core::pose::MAX_BEACONS {
                return Err(refused(format!(
                    "{n} beacons; the board holds at most {} (the NorthStar tracks 20 spots, 19 \
                     distinct frequencies)",
                    cta_core::pose::MAX_BEACONS
                )));
            }
        }
    }
    let con: Constellation = read_json(file)?;
    con.validate().map_err(|e| refused(e.to_string()))?;
    check_channels(&con).map_err(|e| refused(e.to_string()))?;
    let r: Vec<Vector3<f64>> = con
        .beacons
        .iter()
        .map(|b| Vector3::new(b.r[0], b.r[1], b.r[2]).cast())
        .collect();
    for i in 0..r.len() {
        for j in i + 1..r.len() {
            if (r[i] - r[j]).norm() < 0.01 {
                return Err(refused(format!(
                    "beacons {} and {} are at the same place ({:?} in): the solver cannot tell \
                     their directions apart",
                    con.beacons[i].id, con.beacons[j].id, con.beacons[i].r
                )));
            }
        }
    }
    // Collinear: every beacon within 0.01 in of the line through the two farthest apart.
    let (a, b) = (0..r.len())
        .flat_map(|i| (i + 1..r.len()).map(move |j| (i, j)))
        .max_by(|&(i, j), &(k, l)| (r[i] - r[j]).norm().total_cmp(&(r[k] - r[l]).norm()))
        .unwrap_or((0, 0));
    let axis = (r[b] - r[a]).normalize();
    if r.iter()
        .all(|p| ((p - r[a]) - axis * (p - r[a]).dot(&axis)).norm() < 0.01)
    {
        return Err(refused(format!(
            "all {} beacons lie on one line: the attitude about it is unobservable; put at least \
             one beacon off it",
            r.len()
        )));
    }
    let far = r.iter().map(|p| p.norm()).fold(0.0, f64::max);
    let mut warnings = Vec::new();
    if far > 60.0 {
        warnings.push(format!(
            "{file}: a beacon {far:.0} in from the target's origin: positions are in inches \
             (millimetres would be 25.4 times too far)"
        ));
    }
    Ok((con, warnings))
}

/// How far (in) a beacon's `(x, y)` may lie from an LED of a calibration's `led_brightness`
/// to take its brightness ([`set_brightness`]).
pub const BRIGHTNESS_MATCH_IN: f64 = 0.05;

/// Set each beacon's [`Beacon::brightness`](cta_core::pose::Beacon::brightness) from the LEDs'
/// brightness `cta calibrate` fitted (the calibration file `cal`'s `led_brightness`): the LED
/// whose plate position `(x, y)` (as the measurement file gave it, N frame) lies within
/// [`BRIGHTNESS_MATCH_IN`] of the beacon's `(x, y)` in T (for a constellation built from the
/// plate's LEDs, T is the plate frame). Beacons without one keep theirs, and are named in a
/// warning. Returns how many were set and the warnings.
pub fn set_brightness(con: &mut Constellation, cal: &str) -> Result<(usize, Vec<String>), Error> {
    let text = std::fs::read_to_string(cal).map_err(|error| Error::Read {
        file: cal.to_string(),
        error,
    })?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|error| Error::NotJson {
        file: cal.to_string(),
        error,
    })?;
    let Some(list) = v.get("led_brightness") else {
        return Err(Error::NoBrightness {
            file: cal.to_string(),
            constellation: v.get("beacons").is_some(),
        });
    };
    let leds: Vec<crate::fit::magnitude::LedBrightness> = serde_json::from_value(list.clone())
        .map_err(|error| Error::Brightness {
            file: cal.to_string(),
            error,
        })?;
    let mut set = 0;
    let mut missed = Vec::new();
    for b in con.beacons.iter_mut() {
        let (x, y) = (f64::from(b.r[0]), f64::from(b.r[1]));
        let nearest = leds
            .iter()
            .map(|l| (l, (l.x_in - x).hypot(l.y_in - y)))
            .filter(|(_, d)| *d <= BRIGHTNESS_MATCH_IN)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match nearest {
            Some((l, _)) => {
                b.brightness = l.brightness as f32;
                set += 1;
            }
            None => missed.push(format!("{} at ({x}, {y}) in", b.id)),
        }
    }
    let mut warnings = Vec::new();
    if !missed.is_empty() {
        warnings.push(format!(
            "{cal}: no LED within {BRIGHTNESS_MATCH_IN} in of beacon(s) {}: they keep their \
             brightness ({} LEDs in the calibration; beacon positions are matched to the LEDs' \
             plate positions, the constellation's x, y in the plate frame)",
            missed.join(", "),
            leds.len()
        ));
    }
    con.validate().map_err(|error| Error::WithBrightness {
        file: cal.to_string(),
        error,
    })?;
    Ok((set, warnings))
}

/// `con` without its beacons on channel `id`.
fn without(mut con: Constellation, id: u8) -> Constellation {
    con.beacons.retain(|b| b.id != id);
    con
}

/// The largest constellation on one array: [`one_20`] without channel 19 (the frequency of
/// channel 2, [`shared_channels`]).
fn one_19() -> Constellation {
    without(one_20(), 19)
}

/// The largest constellation over four arrays: core's 20-beacon
/// [`four_array_constellation`] (which the QEMU harness times, the chip's capacity) without
/// channel 19 (the frequency of channel 2, [`shared_channels`]).
fn four_19() -> Constellation {
    without(four_array_constellation(), 19)
}

/// one-10 and ten more LEDs of the one-array grid (corners and the gaps between).
fn one_20() -> Constellation {
    const ADD: [[f32; 2]; 10] = [
        [-4.5, -4.5],
        [4.5, 4.5],
        [-4.5, 4.5],
        [4.5, -4.5],
        [-0.5, -0.5],
        [-1.5, 2.5],
        [2.5, -2.5],
        [-4.5, 0.5],
        [0.5, 4.5],
        [-0.5, -4.5],
    ];
    let xy: Vec<[f32; 2]> = cta_constellation()
        .beacons
        .iter()
        .map(|b| [b.r[0], b.r[1]])
        .chain(ADD)
        .collect();
    flat_constellation(&xy)
}

/// The first ten beacons of the four-array constellation.
fn four_10() -> Constellation {
    let mut con = four_array_constellation();
    con.beacons.truncate(10);
    con
}

/// The names of the built-in constellations, with what each is, for `--help` and errors.
pub fn built_in_list() -> String {
    BUILT_IN
        .iter()
        .map(|b| {
            format!(
                "\n  {:8} {} beacons, {}",
                b.name,
                (b.beacons)().beacons.len(),
                b.what
            )
        })
        .collect()
}

/// The built-in constellation `name`; an error lists the built-ins.
pub fn built_in_constellation(name: &str) -> Result<Constellation, Error> {
    match BUILT_IN.iter().find(|b| b.name == name) {
        Some(b) => Ok((b.beacons)()),
        None => Err(Error::NoBuiltIn {
            name: name.to_string(),
            built_ins: built_in_list(),
        }),
    }
}

/// The target of a pose analysis (`cta sensor accuracy`, `cta sensor floor`): which
/// constellation, on which plate, raised how far.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scene {
    /// A built-in constellation's name or a constellation file (`None`: one-10, the chip's
    /// benchmark).
    pub constellation: Option<String>,
    /// The plate the calibration sweeps see (`None`: the built-in's own; for a file, `four`
    /// if a beacon lies beyond 4.5 in).
    pub plate: Option<Plate>,
    /// How far every beacon after the first five is raised toward the sensor, in, on top of
    /// the height a file gives them.
    pub depth: f64,
}

impl TestScene {
    /// Refuse ranges at which a beacon would sit at or behind the sensor (raised by `--depth`
    /// or by the file to the range or beyond): such a pose sees fewer beacons and the tables
    /// would compare something else than they say.
    pub fn check_ranges(&self, ranges: &[f64]) -> Result<(), Error> {
        let highest = self
            .con
            .beacons
            .iter()
            .map(|b| -f64::from(b.r[2]))
            .fold(f64::NEG_INFINITY, f64::max);
        let closest = ranges.iter().copied().fold(f64::INFINITY, f64::min);
        if highest >= closest {
            return Err(Error::BeaconAtSensor { highest, closest });
        }
        Ok(())
    }
}

impl Scene {
    /// The constellation, plate and label of this target ([`test_scene`]).
    pub fn resolve(&self) -> Result<TestScene, Error> {
        test_scene(self.constellation.as_deref(), self.plate, self.depth)
    }
}

/// The constellation a pose analysis runs on, the plate its calibrations are swept over,
/// and a label for table headers.
#[derive(Debug, Clone)]
pub struct TestScene {
    /// Beacons (outer ones raised by `depth`).
    pub con: Constellation,
    /// The plate of the calibration sweeps.
    pub plate: Plate,
    /// Header text: the constellation, its plate, the raise.
    pub label: String,
    /// Plot titles: the constellation, its beacon count, the raise.
    pub short: String,
    /// Warnings about the constellation file (beacons improbably far away).
    pub warnings: Vec<String>,
}

/// Resolve `--constellation` (a built-in name or a JSON file; default `one-10`), `--plate`
/// (default: the built-in's plate; for a file, `four` if a beacon lies outside the one-array
/// grid's 4.5 in, else `one`) and `--depth` (every beacon after the first five raised this far
/// toward the sensor, in).
pub fn test_scene(
    constellation: Option<&str>,
    plate: Option<Plate>,
    depth: f64,
) -> Result<TestScene, Error> {
    let spec = constellation.unwrap_or("one-10");
    let mut warnings = Vec::new();
    let (mut con, own_plate, name) = match BUILT_IN.iter().find(|b| b.name == spec) {
        Some(b) => ((b.beacons)(), b.plate, format!("constellation {spec}")),
        None if !std::path::Path::new(spec).exists() => {
            return Err(Error::NoConstellation {
                spec: spec.to_string(),
                built_ins: built_in_list(),
            })
        }
        None => {
            let (con, file_warnings) = read_constellation(spec)?;
            warnings = file_warnings;
            let wide = con
                .beacons
                .iter()
                .any(|b| b.r[0].abs() > 4.51 || b.r[1].abs() > 4.51);
            let plate = if wide { Plate::Four } else { Plate::One };
            (con, plate, format!("constellation {spec}"))
        }
    };
    // On top of the beacons' own heights: a file's 3-D target keeps its shape.
    for b in con.beacons.iter_mut().skip(5) {
        b.r[2] -= depth as f32;
    }
    let plate = plate.unwrap_or(own_plate);
    let off_plate = con
        .beacons
        .iter()
        .filter(|b| !plate.holds(b.r[0] as f64, b.r[1] as f64))
        .count();
    let mut short = format!("{name}, {} beacons", con.beacons.len());
    if depth != 0.0 {
        short += &format!(", raised {depth:.1} in");
    }
    let mut label = format!(
        "{name} ({} beacons), calibrations swept over {}",
        con.beacons.len(),
        plate.describe()
    );
    if depth != 0.0 {
        label += &format!(", beacons after the fifth raised {depth:.1} in");
    }
    if off_plate > 0 {
        label += &format!(
            "; {off_plate} beacon(s) not on an LED position of that plate (the calibrations \
             extrapolate to them)"
        );
    }
    Ok(TestScene {
        con,
        plate,
        label,
        short,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plates_have_their_leds() {
        let one = Plate::One.positions(5.0);
        assert_eq!(one.len(), 100);
        assert!(one
            .iter()
            .all(|r| r[2] == 5.0 && Plate::One.holds(r[0], r[1])));
        let four = Plate::Four.positions(5.0);
        assert_eq!(four.len(), 400);
        assert!(four.iter().all(|r| Plate::Four.holds(r[0], r[1])));
        let max = four
            .iter()
            .map(|r| r[0].abs().max(r[1].abs()))
            .fold(0.0, f64::max);
        let min = four
            .iter()
            .map(|r| r[0].abs().min(r[1].abs()))
            .fold(99.0, f64::min);
        assert_eq!((min, max), (1.5, 10.5));
        // No LED twice.
        for (i, a) in four.iter().enumerate() {
            assert!(four[i + 1..].iter().all(|b| (a - b).norm() > 0.5));
        }
        assert!(!Plate::Four.holds(0.5, 2.5) && !Plate::One.holds(5.5, 0.5));
        assert!(!Plate::One.holds(0.0, 0.5) && !Plate::Four.holds(11.5, 1.5));
    }

    #[test]
    fn built_ins_are_valid_and_on_their_plate() {
        let mut sizes = Vec::new();
        for b in &BUILT_IN {
            let s = test_scene(Some(b.name), None, 0.0).unwrap();
            s.con.validate().unwrap();
            assert_eq!(s.plate, b.plate);
            assert!(
                !s.label.contains("not on an LED"),
                "{}: {}",
                b.name,
                s.label
            );
            sizes.push(s.con.beacons.len());
        }
        assert_eq!(sizes, [10, 19, 10, 19]);
        // one-10 is the benchmark constellation itself.
        let s = test_scene(None, None, 0.0).unwrap();
        assert_eq!(s.con, cta_constellation());
        // Forcing the one-array plate onto a four-array constellation is named.
        let s = test_scene(Some("four-10"), Some(Plate::One), 0.0).unwrap();
        assert!(s.label.contains("5 beacon(s) not on an LED"), "{}", s.label);
        // A depth moves the outer beacons only.
        let s = test_scene(Some("four-19"), None, 2.0).unwrap();
        assert!(s.con.beacons[..5].iter().all(|b| b.r[2] == 0.0));
        assert!(s.con.beacons[5..].iter().all(|b| b.r[2] == -2.0));
    }

    #[test]
    fn a_files_heights_are_kept_and_the_depth_adds_to_them() {
        let path = std::env::temp_dir().join(format!("cta-posts-{}.json", std::process::id()));
        let mut con = cta_constellation();
        for (i, b) in con.beacons.iter_mut().enumerate() {
            b.r[2] = -0.25 * i as f32;
        }
        std::fs::write(&path, serde_json::to_string(&con).unwrap()).unwrap();
        let spec = path.to_str().unwrap();
        let s = test_scene(Some(spec), None, 0.0).unwrap();
        assert_eq!(s.con, con);
        let s = test_scene(Some(spec), None, 1.0).unwrap();
        std::fs::remove_file(&path).unwrap();
        for (i, b) in s.con.beacons.iter().enumerate() {
            let want = -0.25 * i as f32 - if i >= 5 { 1.0 } else { 0.0 };
            assert_eq!(b.r[2], want, "beacon {i}");
        }
    }

    /// Channels 2 and 19 share 4050 Hz in the NorthStar table: no built-in uses both, and a
    /// file that does is refused, naming them.
    #[test]
    fn no_constellation_uses_two_channels_of_one_frequency() {
        assert_eq!(shared_channels(), [(2, 19)]);
        for b in &BUILT_IN {
            let con = (b.beacons)();
            check_channels(&con).unwrap_or_else(|e| panic!("{}: {e}", b.name));
        }
        assert_eq!(built_in_constellation("four-19").unwrap().beacons.len(), 19);
        assert_eq!(built_in_constellation("one-19").unwrap().beacons.len(), 19);
        let e = check_channels(&four_array_constellation())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("channels 2 and 19") && e.contains("4050 Hz"),
            "{e}"
        );
        let path = std::env::temp_dir().join(format!("cta-shared-{}.json", std::process::id()));
        std::fs::write(&path, serde_json::to_string(&one_20()).unwrap()).unwrap();
        let e = test_scene(Some(path.to_str().unwrap()), None, 0.0)
            .unwrap_err()
            .to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(e.contains("channels 2 and 19"), "{e}");
    }

    #[test]
    fn unknown_name_lists_the_built_ins() {
        let e = test_scene(Some("four-30"), None, 0.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("four-30") && e.contains("four-19") && e.contains("one-10"),
            "{e}"
        );
    }
}
