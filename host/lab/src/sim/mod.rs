//! Emulated CTA data (thesis Ch V "Emulate NorthStar sensor output"), with the effect
//! vocabulary injectable, and the truth written to a sidecar manifest.

pub mod effects;

mod files;
mod placement;
mod rail;
/// The NorthStar's report rate a simulated file is timed at, Hz (the sensor's typical rate).
pub const SIM_RATE_HZ: f64 = 10.0;
/// Settle time before a simulated point's first report, s (a sweep plan's default).
pub const SIM_SETTLE_S: f64 = 0.2;
/// The requests around a point, s: four exchanges of a few dozen bytes at 115,200 baud (also
/// what `cta sweep --estimate` counts).
pub const SIM_REQUESTS_S: f64 = 0.08;
/// A plate move between separations with its corner readings, s (also the default
/// `cta sweep --estimate` assumes).
pub const SIM_PLATE_MOVE_S: f64 = 180.0;

/// When a one-at-a-time sweep would take sample `s` of beacon `i` (of `n`, `samples` each) at
/// separation `k`, in seconds since the run started: a plate move before each separation,
/// then each point its settle time, a report for the stream to start, and its samples at
/// [`SIM_RATE_HZ`]. Gives simulated files the `time_s` column a sweep writes, so effects that
/// drift over a run can be simulated and looked for.
pub fn sweep_time(k: usize, n: usize, i: usize, s: usize, samples: usize) -> f64 {
    let point = SIM_SETTLE_S + (samples as f64 + 1.0) / SIM_RATE_HZ + SIM_REQUESTS_S;
    let t = (k + 1) as f64 * SIM_PLATE_MOVE_S
        + (k * n + i) as f64 * point
        + SIM_SETTLE_S
        + (s as f64 + 1.0) / SIM_RATE_HZ;
    (t * 1e4).round() / 1e4
}

#[cfg(test)]
mod tests;
mod truth;

pub use files::{check_out, write_files, WriteError};
pub use placement::{led_emulator, ArrayPlace, Physics, Placement};
pub use rail::rail_note;
pub use truth::{Truth, TruthError};

use crate::data::{Dataset, Sample, MAX_SEPARATIONS};
use cta_core::emulator::{grid_position, saturate_i16, Effects, Emulator, Head, Pose};
use cta_core::magnitude_law;
use cta_core::pattern::Pattern;
use cta_core::real::deg;
use effects::{Effect, EffectError};
use nalgebra::Vector3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Normal, StandardNormal};
use std::path::PathBuf;

/// Why a simulation is refused: a configuration beyond its limits, or one that simulates
/// nothing.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// No separations.
    #[error("no separations given")]
    NoSeparations,
    /// More than [`MAX_SEPARATIONS`].
    #[error("{0} separations, more than the {MAX_SEPARATIONS} allowed")]
    TooManySeparations(usize),
    /// A separation that is not positive and finite.
    #[error("separation {0} in must be a positive, finite number of inches")]
    BadSeparation(f64),
    /// A grid of no beacons or more than the beacon column holds.
    #[error("grid {}x{}: between 1x1 and {max} beacons", .grid.0, .grid.1)]
    Grid {
        /// Columns and rows.
        grid: (usize, usize),
        /// The most beacons.
        max: usize,
    },
    /// A pitch that is not positive.
    #[error("grid pitch {0} in must be > 0")]
    Pitch(f64),
    /// A quad layout whose spacing is not positive, or whose grid has more LEDs than an
    /// array's 100 beacon ids.
    #[error(
        "quad layout (spacing {spacing} in, {beacons} LEDs per array): the spacing must be > 0 \
         and an array at most 100 LEDs (beacon ids 100 * array + LED)"
    )]
    Quad {
        /// Distance between array centres, in.
        spacing: f64,
        /// LEDs per array.
        beacons: usize,
    },
    /// `array_pose` on one array, whose pose is the head's: nothing to simulate.
    #[error(
        "array_pose needs several arrays on the plate (the quad layout, `--quad SPACING`): one \
         array's shift and turn are the head's offset and attitude"
    )]
    OneArray,
    /// Samples per point outside 1..=[`MAX_SAMPLES`].
    #[error("{0} samples per point: between 1 and {MAX_SAMPLES} (as in a sweep plan)")]
    Samples(usize),
    /// A negative or non-finite noise.
    #[error("noise {0} counts must be >= 0")]
    Noise(f64),
    /// A magnitude noise outside 0..=[`MAX_MAGNITUDE_NOISE`].
    #[error(
        "magnitude noise {0} %: between 0 and {MAX_MAGNITUDE_NOISE} % (beyond that a \
         Gaussian draw makes magnitudes negative)"
    )]
    MagnitudeNoise(f64),
    /// An LED brightness scatter outside 0..=[`MAX_LED_BRIGHTNESS`].
    #[error("LED brightness scatter {0} %: between 0 and {MAX_LED_BRIGHTNESS} %")]
    LedBrightness(f64),
    /// More than [`MAX_REPORTS`] reports in all.
    #[error(
        "{separations} separations x {beacons} beacons x {samples} samples = {reports} reports, more than the \
         {MAX_REPORTS} one simulation writes: fewer separations, beacons or samples"
    )]
    TooManyReports {
        /// Separations.
        separations: usize,
        /// Beacons.
        beacons: usize,
        /// Samples per point.
        samples: usize,
        /// Their product.
        reports: u128,
    },
    /// An effect refused (given twice).
    #[error(transparent)]
    Effect(#[from] EffectError),
    /// Every beacon outside the field of view or without signal.
    #[error(
        "nothing to write: all {skipped} beacon positions ({separations} separation(s) x {beacons} beacons) are outside \
         the field of view or give no signal (separations {span} in; effects [{effects}]); choose \
         separations and effects under which the sensor sees the beacons"
    )]
    Nothing {
        /// Beacon positions skipped.
        skipped: usize,
        /// Separations.
        separations: usize,
        /// Beacons per separation.
        beacons: usize,
        /// The separations, in words.
        span: String,
        /// The effects, `NAME=VALUE` separated by spaces.
        effects: String,
    },
}

/// A beacon grid `COLSxROWS` that cannot be read or is too large.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// Not `COLSxROWS`.
    #[error("grid `{0}`: expected COLSxROWS, e.g. 10x10")]
    Syntax(String),
    /// The column count is not a number.
    #[error("grid `{0}`: bad column count")]
    Columns(String),
    /// The row count is not a number.
    #[error("grid `{0}`: bad row count")]
    Rows(String),
    /// No beacons, or more than beacon ids reach.
    #[error("grid `{grid}`: between 1x1 and {max} beacons (beacon ids 0..{}, e.g. 20x20)", .max - 1)]
    Size {
        /// The grid as given.
        grid: String,
        /// The most beacons.
        max: usize,
    },
}

/// The most samples per point: the same cap as a sweep plan's `samples`.
pub const MAX_SAMPLES: usize = 100_000;

/// The most reports one simulation writes (separations x beacons x samples): about 1.4 GB
/// in memory and 0.6 GB of CSV; ten times `cargo bench --bench analyze_1m`.
pub const MAX_REPORTS: usize = 10_000_000;

/// The largest spot magnitude noise a simulation takes, percent (1-sigma): a Gaussian draw
/// this wide is negative once in 30,000 reports (clamped to 0, which `cta noise` skips).
pub const MAX_MAGNITUDE_NOISE: f64 = 25.0;

/// Mixed into the seed of the magnitude noise's stream.
const MAGNITUDE_STREAM: u64 = 0x6d61_676e_6974_7564;

/// Mixed into the seed of the LEDs' brightness draws ("brightns").
const BRIGHTNESS_STREAM: u64 = 0x6272_6967_6874_6e73;

/// The largest LED brightness scatter a simulation takes, percent (1-sigma of its
/// logarithm): 4 sigma is then a factor 7.4, within what a constellation takes (0.05-20).
pub const MAX_LED_BRIGHTNESS: f64 = 50.0;

/// The relative brightness of `n` LEDs, log-normal with `percent` the 1-sigma of the logarithm
/// (all 1 at 0), drawn from a stream of the seed's own so that the seed's other draws stay.
pub fn led_brightness(seed: u64, percent: f64, n: usize) -> Vec<f64> {
    if percent == 0.0 {
        return vec![1.0; n];
    }
    let mut rng = StdRng::seed_from_u64(seed ^ BRIGHTNESS_STREAM);
    (0..n)
        .map(|_| (percent / 100.0 * rng.sample::<f64, _>(StandardNormal)).exp())
        .collect()
}

/// Seed of the plate tilts' stream ("plattilt"), XORed with the seed.
const TILT_STREAM: u64 = 0x706c_6174_7469_6c74;

/// Seed of the LED placement draws' stream ("ledplace"), XORed with the seed.
const LED_STREAM: u64 = 0x6c65_6470_6c61_6365;

/// Seed of the LED tilt draws' stream ("ledtilts"), XORed with the seed.
const LED_TILT_STREAM: u64 = 0x6c65_6474_696c_7473;

/// Seed of the array pose draws' stream ("arrposes"), XORed with the seed.
const ARRAY_STREAM: u64 = 0x6172_7270_6f73_6573;

/// What to simulate.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// Plate separations, inches.
    pub separations: Vec<f64>,
    /// Grid size (columns, rows), 1 in pitch, centred on the N origin.
    pub grid: (usize, usize),
    /// Grid pitch, inches.
    pub pitch: f64,
    /// The quad layout (Ch IV: four arrays in the plate's quadrants), the distance between
    /// neighbouring array centres in x and y, in: four copies of the grid centred at
    /// (+/-spacing/2, +/-spacing/2), array `a` at x = -/+ for `a` even/odd and y = -/+ for
    /// `a` below/from 2, its beacon ids `100 a + LED` (as the sweep's `quad` layout). None:
    /// one grid on the N axis.
    pub quad: Option<f64>,
    /// The base beacon pattern (before effects).
    pub pattern: Pattern<f64>,
    /// Far-field base physics (no proximity, no intensity) instead of the thesis physics.
    pub far_field: bool,
    /// The true head pose.
    pub pose: Pose<f64>,
    /// Injected effects.
    pub effects: Vec<Effect>,
    /// Gaussian noise, counts (1-sigma). 0: noise-free (the thesis's emulation).
    pub noise: f64,
    /// Samples per point.
    pub samples: usize,
    /// Round to whole counts (as the sensor reports). Always on when `noise > 0`.
    pub round: bool,
    /// Spot magnitude noise, percent of the magnitude (1-sigma, Gaussian, each report drawn
    /// independently). 0: every report of a point has the same magnitude. No model of the
    /// NorthStar's magnitude noise exists: this is a what-if for `cta noise` and
    /// `cta sensor floor --magnitude-noise`. Drawn from its own stream, so it never changes
    /// the x, y noise of a seed.
    pub magnitude_noise: f64,
    /// The LEDs' brightness scatter, percent ([`led_brightness`]): each beacon's magnitude is
    /// multiplied by its LED's brightness (its x, y are unchanged: a ratio). 0: all alike.
    pub led_brightness: f64,
    /// Random seed.
    pub seed: u64,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            separations: (2..=30).map(f64::from).collect(),
            grid: (10, 10),
            pitch: 1.0,
            quad: None,
            pattern: Pattern::vsml3710(),
            far_field: false,
            pose: Pose::table3(),
            effects: Vec::new(),
            noise: 0.0,
            samples: 1,
            round: false,
            magnitude_noise: 0.0,
            led_brightness: 0.0,
            seed: 1,
        }
    }
}

impl SimConfig {
    /// Build the emulator and draw the per-separation geometry errors (seeded).
    pub fn physics(&self) -> Physics {
        let mut head = Head::northstar();
        let mut fx = if self.far_field {
            Effects::far_field()
        } else {
            Effects::default()
        };
        fx.pattern = if self.far_field {
            Pattern::Uniform
        } else {
            self.pattern
        };
        for e in &self.effects {
            e.apply(&mut head, &mut fx);
        }
        let emulator = Emulator::new(head, self.pose, fx);
        // Geometry draws use their own stream so noise settings do not change them.
        let mut rng = StdRng::seed_from_u64(self.seed ^ 0x9e37_79b9_7f4a_7c15);
        // The tilts have a stream of their own: adding `plate_tilt` leaves the offsets and
        // separation errors of a seed as they were.
        let mut tilt_rng = StdRng::seed_from_u64(self.seed ^ TILT_STREAM);
        let mut plate_sigma = 0.0;
        let mut sep_sigma = 0.0;
        let mut tilt_sigma = 0.0;
        for e in &self.effects {
            match *e {
                Effect::PlateOffset(s) => plate_sigma = s,
                Effect::SeparationError(s) => sep_sigma = s,
                Effect::PlateTilt(s) => tilt_sigma = s,
                _ => {}
            }
        }
        let std = Normal::new(0.0, 1.0).unwrap();
        let geometry = self
            .separations
            .iter()
            .map(|_| {
                let offset = [rng.sample(std) * plate_sigma, rng.sample(std) * plate_sigma];
                let sep_error = rng.sample(std) * sep_sigma;
                let tilt_deg = [
                    tilt_rng.sample(std) * tilt_sigma,
                    tilt_rng.sample(std) * tilt_sigma,
                ];
                Placement {
                    offset,
                    sep_error,
                    tilt_deg,
                }
            })
            .collect();
        // One (dx, dy) per LED of the grid, from a stream of its own (the seed's other draws
        // stay as they were).
        let led_sigma = self
            .effects
            .iter()
            .find_map(|e| match *e {
                Effect::LedPosition(s) => Some(s),
                _ => None,
            })
            .unwrap_or(0.0);
        let mut led_rng = StdRng::seed_from_u64(self.seed ^ LED_STREAM);
        let ids = self.beacon_ids();
        let n_ids = ids.last().map_or(0, |&i| i + 1);
        let led_offsets = (0..n_ids)
            .map(|_| {
                if led_sigma > 0.0 {
                    [
                        rng_n(&mut led_rng) * led_sigma,
                        rng_n(&mut led_rng) * led_sigma,
                    ]
                } else {
                    [0.0; 2]
                }
            })
            .collect();
        let tilt_sigma = self
            .effects
            .iter()
            .find_map(|e| match *e {
                Effect::LedTilt(s) => Some(s),
                _ => None,
            })
            .unwrap_or(0.0);
        let mut tilt_rng = StdRng::seed_from_u64(self.seed ^ LED_TILT_STREAM);
        let led_tilts_deg = (0..n_ids)
            .map(|_| {
                if tilt_sigma > 0.0 {
                    [
                        rng_n(&mut tilt_rng) * tilt_sigma,
                        rng_n(&mut tilt_rng) * tilt_sigma,
                    ]
                } else {
                    [0.0; 2]
                }
            })
            .collect();
        let (pose_in, pose_deg) = self
            .effects
            .iter()
            .find_map(|e| match *e {
                Effect::ArrayPose(a, b) => Some((a, b)),
                _ => None,
            })
            .unwrap_or((0.0, 0.0));
        let mut array_rng = StdRng::seed_from_u64(self.seed ^ ARRAY_STREAM);
        let arrays = self
            .array_centres()
            .into_iter()
            .map(|centre| ArrayPlace {
                centre,
                pose: [
                    rng_n(&mut array_rng) * pose_in,
                    rng_n(&mut array_rng) * pose_in,
                    rng_n(&mut array_rng) * pose_deg,
                ],
            })
            .collect();
        Physics {
            emulator,
            geometry,
            led_offsets,
            led_tilts_deg,
            arrays,
        }
    }

    /// The nominal centre of each array on the plate (one at the origin without
    /// [`SimConfig::quad`]).
    pub fn array_centres(&self) -> Vec<[f64; 2]> {
        match self.quad {
            None => vec![[0.0, 0.0]],
            Some(spacing) => {
                let h = spacing / 2.0;
                (0..4)
                    .map(|a| [if a % 2 == 0 { -h } else { h }, if a < 2 { -h } else { h }])
                    .collect()
            }
        }
    }

    /// Every beacon id of the plate, ascending: the grid's LEDs in order, `100 a + LED` on
    /// array `a` of the quad layout.
    pub fn beacon_ids(&self) -> Vec<usize> {
        let n = self.grid.0 * self.grid.1;
        match self.quad {
            None => (0..n).collect(),
            Some(_) => (0..4)
                .flat_map(|a| (0..n).map(move |i| 100 * a + i))
                .collect(),
        }
    }

    /// Check a configuration before running it: separations, grid, samples, noise, the
    /// total number of reports and repeated effects. Errors say which limit and why.
    pub fn check(&self) -> Result<(), SimError> {
        if self.separations.is_empty() {
            return Err(SimError::NoSeparations);
        }
        if self.separations.len() > MAX_SEPARATIONS {
            return Err(SimError::TooManySeparations(self.separations.len()));
        }
        if let Some(s) = self
            .separations
            .iter()
            .find(|s| !(s.is_finite() && **s > 0.0))
        {
            return Err(SimError::BadSeparation(*s));
        }
        let beacons = self.grid.0.saturating_mul(self.grid.1);
        let max_beacons = crate::data::MAX_BEACON_ID as usize + 1;
        if beacons == 0 || beacons > max_beacons {
            return Err(SimError::Grid {
                grid: self.grid,
                max: max_beacons,
            });
        }
        if !(self.pitch.is_finite() && self.pitch > 0.0) {
            return Err(SimError::Pitch(self.pitch));
        }
        if let Some(spacing) = self.quad {
            if !(spacing.is_finite() && spacing > 0.0) || beacons > 100 {
                return Err(SimError::Quad { spacing, beacons });
            }
        } else if self
            .effects
            .iter()
            .any(|e| matches!(e, Effect::ArrayPose(..)))
        {
            return Err(SimError::OneArray);
        }
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return Err(SimError::Samples(self.samples));
        }
        if !(self.noise.is_finite() && self.noise >= 0.0) {
            return Err(SimError::Noise(self.noise));
        }
        if !(0.0..=MAX_MAGNITUDE_NOISE).contains(&self.magnitude_noise) {
            return Err(SimError::MagnitudeNoise(self.magnitude_noise));
        }
        if !(0.0..=MAX_LED_BRIGHTNESS).contains(&self.led_brightness) {
            return Err(SimError::LedBrightness(self.led_brightness));
        }
        let beacons = beacons * self.array_centres().len();
        let reports = (self.separations.len() as u128) * (beacons as u128) * (self.samples as u128);
        if reports > MAX_REPORTS as u128 {
            return Err(SimError::TooManyReports {
                separations: self.separations.len(),
                beacons,
                samples: self.samples,
                reports,
            });
        }
        Ok(effects::check_unique(&self.effects)?)
    }

    /// Check the configuration ([`SimConfig::check`]), run it, and refuse a result without
    /// a single report (every beacon outside the field of view or without signal): what
    /// `cta simulate` uses.
    pub fn try_run(&self) -> Result<(Dataset, Truth), SimError> {
        self.check()?;
        let (ds, truth) = self.run();
        if ds.samples.is_empty() {
            return Err(SimError::Nothing {
                skipped: truth.skipped_points,
                separations: self.separations.len(),
                beacons: self.beacon_ids().len(),
                span: span(&self.separations),
                effects: truth.effects.join(" "),
            });
        }
        Ok((ds, truth))
    }

    /// Run the simulation: the dataset and its truth; each row timed as a one-at-a-time sweep
    /// would take it ([`sweep_time`]). Unchecked: for user input, use
    /// [`SimConfig::try_run`].
    pub fn run(&self) -> (Dataset, Truth) {
        let phys = self.physics();
        let em = &phys.emulator;
        let mut rng = StdRng::seed_from_u64(self.seed);
        let noise = Normal::new(0.0, self.noise.max(0.0)).unwrap();
        let round = self.round || self.noise > 0.0;
        // The magnitude noise has its own stream: turning it on leaves x and y as they were.
        let mut mag_rng = StdRng::seed_from_u64(self.seed ^ MAGNITUDE_STREAM);
        let mag_sigma = self.magnitude_noise / 100.0;
        let ids = self.beacon_ids();
        let centres = self.array_centres();
        let n = ids.len();
        let bright = led_brightness(self.seed, self.led_brightness, n);
        let mut samples = Vec::with_capacity(
            self.separations
                .len()
                .saturating_mul(n)
                .saturating_mul(self.samples)
                .min(MAX_REPORTS),
        );
        let mut skipped = 0;
        // The NorthStar's magnitude law (`cta_core::magnitude_law`), at power level 2 and
        // sensitivity 4 (the data carry no settings).
        let at_30 = magnitude_law::signal_at_30(em);
        for (k, &sep) in self.separations.iter().enumerate() {
            let place = phys.geometry[k];
            let em = place.emulator(em);
            for (&i, brightness) in ids.iter().zip(&bright) {
                let (c, led) = match self.quad {
                    None => ([0.0; 2], i),
                    Some(_) => (centres[i / 100], i % 100),
                };
                let nominal = grid_position_xy(self.grid, self.pitch, sep, led)
                    + Vector3::new(c[0], c[1], 0.0);
                let truth = phys.beacon(k, i, &nominal);
                let em = phys.led_emulator(i, &em);
                let Some(out) = em.output(&truth) else {
                    skipped += 1;
                    continue;
                };
                let mag = magnitude_law::reading(em.magnitude(&truth), at_30, 2, 4) * brightness;
                for s in 0..self.samples {
                    let mut v = [out[0], out[1]];
                    if self.noise > 0.0 {
                        v[0] += rng.sample(noise);
                        v[1] += rng.sample(noise);
                    }
                    let v = if round {
                        v.map(|c| f64::from(saturate_i16(c)))
                    } else {
                        v.map(|c| c.clamp(-32768.0, 32767.0))
                    };
                    samples.push(Sample {
                        separation_in: sep,
                        r: [nominal.x, nominal.y, nominal.z],
                        x: v[0],
                        y: v[1],
                        beacon: Some(i as u32),
                        sample: Some(s as u32),
                        magnitude: Some({
                            let m = if mag_sigma > 0.0 {
                                let z: f64 = mag_rng.sample(StandardNormal);
                                mag * (1.0 + mag_sigma * z)
                            } else {
                                mag
                            };
                            // Counts, saturated; whole ones where the coordinates are.
                            if round {
                                f64::from(magnitude_law::counts(m))
                            } else {
                                m.clamp(0.0, magnitude_law::MAX_COUNTS)
                            }
                        }),
                        time_s: Some(sweep_time(k, n, i, s, self.samples)),
                        ..Default::default()
                    });
                }
            }
        }
        let head = em.head;
        let truth = Truth {
            generator: format!("cta {} simulate", env!("CARGO_PKG_VERSION")),
            d: self.pose.d.into(),
            p: self.pose.p.into(),
            h: head.h(),
            s: if em.effects.proximity { head.s } else { 0.0 },
            alpha_deg: [deg(head.alpha_x), deg(head.alpha_y)],
            physics: if self.far_field {
                "far-field".into()
            } else {
                "thesis".into()
            },
            pattern: describe_pattern(&em.effects.pattern),
            effects: self.effects.iter().map(|e| e.to_string()).collect(),
            plate_offsets: phys.geometry.iter().map(|g| g.offset).collect(),
            separation_errors: phys.geometry.iter().map(|g| g.sep_error).collect(),
            plate_tilts_deg: phys.geometry.iter().map(|g| g.tilt_deg).collect(),
            led_offsets: if phys.led_offsets.iter().any(|d| d != &[0.0, 0.0]) {
                phys.led_offsets.clone()
            } else {
                Vec::new()
            },
            led_tilts_deg: if phys.led_tilts_deg.iter().any(|d| d != &[0.0, 0.0]) {
                phys.led_tilts_deg.clone()
            } else {
                Vec::new()
            },
            array_centres: if centres.len() > 1 {
                centres.clone()
            } else {
                Vec::new()
            },
            array_poses: if phys.arrays.iter().any(|a| a.pose != [0.0; 3]) {
                phys.arrays.iter().map(|a| a.pose).collect()
            } else {
                Vec::new()
            },
            separations: self.separations.clone(),
            noise_counts: self.noise,
            noise_law: None,
            magnitude_noise_percent: self.magnitude_noise,
            led_brightness_percent: self.led_brightness,
            led_brightness: if self.led_brightness > 0.0 {
                bright
            } else {
                Vec::new()
            },
            samples: self.samples,
            seed: self.seed,
            skipped_points: skipped,
        };
        (
            Dataset {
                path: PathBuf::new(),
                samples,
            },
            truth,
        )
    }
}

/// A standard normal draw.
fn rng_n(rng: &mut StdRng) -> f64 {
    rng.sample(StandardNormal)
}

/// The separations for a message: the list when short, else its span; numbers far from
/// inches in exponent form.
fn span(seps: &[f64]) -> String {
    let f = |v: f64| {
        if v != 0.0 && !(1e-3..1e6).contains(&v.abs()) {
            format!("{v:e}")
        } else {
            format!("{v}")
        }
    };
    if seps.len() <= 8 {
        seps.iter().map(|&v| f(v)).collect::<Vec<_>>().join(", ")
    } else {
        let lo = seps.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = seps.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        format!("{} from {} to {}", seps.len(), f(lo), f(hi))
    }
}

/// Beacon `i` of a `cols x rows` grid at `pitch`, centred on the N origin, plate at `z = sep`.
pub fn grid_position_xy(grid: (usize, usize), pitch: f64, sep: f64, i: usize) -> Vector3<f64> {
    if grid.0 == grid.1 {
        return grid_position(grid.0, pitch, sep, i);
    }
    let (c, r) = (i % grid.0, i / grid.0);
    Vector3::new(
        (c as f64 - (grid.0 as f64 - 1.0) / 2.0) * pitch,
        (r as f64 - (grid.1 as f64 - 1.0) / 2.0) * pitch,
        sep,
    )
}

/// Human description of a pattern.
pub fn describe_pattern(p: &Pattern<f64>) -> String {
    match p {
        Pattern::Lambertian { m } => format!(
            "lambertian H={:.3} (m={m:.4})",
            p.half_angle_deg().unwrap_or(f64::NAN)
        ),
        Pattern::Uniform => "uniform".into(),
        Pattern::Quartic => "quartic (thesis eq 17, printed)".into(),
    }
}

/// Parse a grid `10x10`: at most 400 beacons, so that every beacon id fits the measurement
/// file's `beacon` column (0..399, MEASUREMENTS.md).
pub fn parse_grid(s: &str) -> Result<(usize, usize), GridError> {
    let (a, b) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| GridError::Syntax(s.into()))?;
    let a: usize = a.trim().parse().map_err(|_| GridError::Columns(s.into()))?;
    let b: usize = b.trim().parse().map_err(|_| GridError::Rows(s.into()))?;
    let max = crate::data::MAX_BEACON_ID as usize + 1;
    if a == 0 || b == 0 || a.saturating_mul(b) > max {
        return Err(GridError::Size {
            grid: s.into(),
            max,
        });
    }
    Ok((a, b))
}
