//! Emulated CTA data (thesis Ch V "Emulate NorthStar sensor output"), with the effect
//! vocabulary injectable, and the truth written to a sidecar manifest.

pub mod effects;

use crate::data::{Dataset, Sample, MAX_SEPARATIONS};
use cta_core::emulator::{grid_position, saturate_i16, Effects, Emulator, Head, Pose};
use cta_core::pattern::Pattern;
use cta_core::real::{deg, rad};
use effects::Effect;
use nalgebra::{Rotation3, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Normal, StandardNormal};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};

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

/// The relative brightness of `n` LEDs scattered `percent` (1-sigma of the logarithm, so a
/// few percent is that scatter in percent; log-normal, always positive), drawn once from a
/// stream of the seed's own: every LED 1 when `percent` is 0, and other draws of the seed (the
/// noise, the geometry) are the same either way. `cta simulate --led-brightness` and the
/// simulated sweep's `--sim-led-brightness` (LED `i` of the array) use it.
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

/// What to simulate.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// Plate separations, inches.
    pub separations: Vec<f64>,
    /// Grid size (columns, rows), 1 in pitch, centred on the N origin.
    pub grid: (usize, usize),
    /// Grid pitch, inches.
    pub pitch: f64,
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

/// The truth behind a simulated file: written next to it as `FILE.truth.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Truth {
    /// What wrote this.
    pub generator: String,
    /// True head offset d, in.
    pub d: [f64; 3],
    /// True MRP p.
    pub p: [f64; 3],
    /// The far-field scale height `H = beta tan(a_x)` of the true head.
    pub h: f64,
    /// Cell offset s, in.
    pub s: f64,
    /// Face angles of the X and Y pairs, deg.
    pub alpha_deg: [f64; 2],
    /// Base physics: "thesis" or "far-field".
    pub physics: String,
    /// Base beacon pattern, e.g. "lambertian H=60".
    pub pattern: String,
    /// Injected effects, `NAME=VALUE` as on the command line.
    pub effects: Vec<String>,
    /// Per separation: the plate's true lateral offset (x, y) in (plate_offset effect).
    pub plate_offsets: Vec<[f64; 2]>,
    /// Per separation: true separation minus recorded separation, in (separation_error).
    pub separation_errors: Vec<f64>,
    /// Per separation: the plate's tilt vector (tx, ty), deg (plate_tilt; see
    /// [`Placement::tilt_deg`]). Empty in files written before it existed.
    #[serde(default)]
    pub plate_tilts_deg: Vec<[f64; 2]>,
    /// Recorded separations, in.
    pub separations: Vec<f64>,
    /// Noise 1-sigma, counts.
    pub noise_counts: f64,
    /// How the noise varies, when it is not `noise_counts` everywhere (the sweep
    /// simulator's grows as a spot dims).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_law: Option<String>,
    /// Spot magnitude noise, percent (1-sigma); 0 (also in files written before it existed):
    /// none.
    #[serde(default)]
    pub magnitude_noise_percent: f64,
    /// The LEDs' brightness scatter, percent (1-sigma of the logarithm); 0 (also in files
    /// written before it existed): all alike.
    #[serde(default)]
    pub led_brightness_percent: f64,
    /// Each LED's brightness factor (its magnitudes are multiplied by it), by beacon id (the
    /// array's LED for a sweep: the four-array layout's beacon `100 a + i` is LED `i`); absent
    /// when all are 1.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub led_brightness: Vec<f64>,
    /// Samples per point.
    pub samples: usize,
    /// Seed.
    pub seed: u64,
    /// Beacons skipped because a cell pair saw nothing (outside the field of view).
    pub skipped_points: usize,
}

impl Truth {
    /// Sidecar path for a measurement file: `FILE.csv` -> `FILE.truth.json`.
    pub fn path_for(csv: &Path) -> PathBuf {
        csv.with_extension("truth.json")
    }

    /// Load the sidecar of `csv` if there is one.
    pub fn load_for(csv: &Path) -> Option<Result<Truth, String>> {
        let p = Self::path_for(csv);
        if !p.exists() {
            return None;
        }
        Some(
            std::fs::read_to_string(&p)
                .map_err(|e| format!("{}: {e}", p.display()))
                .and_then(|s| {
                    serde_json::from_str(&s).map_err(|e| format!("{}: {e}", p.display()))
                }),
        )
    }

    /// The sidecar of `csv` for `cta fit`, which can do without it: an unreadable sidecar
    /// gives a warning (naming the file and the parse error) instead of an error.
    pub fn load_for_fit(csv: &Path) -> (Option<Truth>, Option<String>) {
        match Self::load_for(csv) {
            None => (None, None),
            Some(Ok(t)) => (Some(t), None),
            Some(Err(e)) => (
                None,
                Some(format!(
                    "{e} (unreadable truth sidecar: the fit is not compared with the truth)"
                )),
            ),
        }
    }

    /// The true pose.
    pub fn pose(&self) -> Pose<f64> {
        Pose {
            d: Vector3::from(self.d),
            p: Vector3::from(self.p),
        }
    }
}

/// The physics of a configuration: head, effects, and the per-separation geometry draws.
pub struct Physics {
    /// The emulator.
    pub emulator: Emulator<f64>,
    /// Per separation (in `separations` order): where the plate truly is.
    pub geometry: Vec<Placement>,
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
        Physics { emulator, geometry }
    }

    /// Check a configuration before running it: separations, grid, samples, noise, the
    /// total number of reports and repeated effects. Errors say which limit and why.
    pub fn check(&self) -> Result<(), String> {
        if self.separations.is_empty() {
            return Err("no separations given".into());
        }
        if self.separations.len() > MAX_SEPARATIONS {
            return Err(format!(
                "{} separations, more than the {MAX_SEPARATIONS} allowed",
                self.separations.len()
            ));
        }
        if let Some(s) = self
            .separations
            .iter()
            .find(|s| !(s.is_finite() && **s > 0.0))
        {
            return Err(format!(
                "separation {s} in must be a positive, finite number of inches"
            ));
        }
        let beacons = self.grid.0.saturating_mul(self.grid.1);
        let max_beacons = crate::data::MAX_BEACON_ID as usize + 1;
        if beacons == 0 || beacons > max_beacons {
            return Err(format!(
                "grid {}x{}: between 1x1 and {max_beacons} beacons",
                self.grid.0, self.grid.1
            ));
        }
        if !(self.pitch.is_finite() && self.pitch > 0.0) {
            return Err(format!("grid pitch {} in must be > 0", self.pitch));
        }
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return Err(format!(
                "{} samples per point: between 1 and {MAX_SAMPLES} (as in a sweep plan)",
                self.samples
            ));
        }
        if !(self.noise.is_finite() && self.noise >= 0.0) {
            return Err(format!("noise {} counts must be >= 0", self.noise));
        }
        if !(0.0..=MAX_MAGNITUDE_NOISE).contains(&self.magnitude_noise) {
            return Err(format!(
                "magnitude noise {} %: between 0 and {MAX_MAGNITUDE_NOISE} % (beyond that a \
                 Gaussian draw makes magnitudes negative)",
                self.magnitude_noise
            ));
        }
        if !(0.0..=MAX_LED_BRIGHTNESS).contains(&self.led_brightness) {
            return Err(format!(
                "LED brightness scatter {} %: between 0 and {MAX_LED_BRIGHTNESS} %",
                self.led_brightness
            ));
        }
        let reports = (self.separations.len() as u128) * (beacons as u128) * (self.samples as u128);
        if reports > MAX_REPORTS as u128 {
            return Err(format!(
                "{} separations x {beacons} beacons x {} samples = {reports} reports, more than the \
                 {MAX_REPORTS} one simulation writes: fewer separations, beacons or samples",
                self.separations.len(),
                self.samples
            ));
        }
        effects::check_unique(&self.effects)
    }

    /// Check the configuration ([`SimConfig::check`]), run it, and refuse a result without
    /// a single report (every beacon outside the field of view or without signal): what
    /// `cta simulate` uses.
    pub fn try_run(&self) -> Result<(Dataset, Truth), String> {
        self.check()?;
        let (ds, truth) = self.run();
        if ds.samples.is_empty() {
            return Err(format!(
                "nothing to write: all {} beacon positions ({} separation(s) x {} beacons) are outside \
                 the field of view or give no signal (separations {} in; effects [{}]); choose \
                 separations and effects under which the sensor sees the beacons",
                truth.skipped_points,
                self.separations.len(),
                self.grid.0 * self.grid.1,
                span(&self.separations),
                truth.effects.join(" ")
            ));
        }
        Ok((ds, truth))
    }

    /// Run the simulation: the dataset and its truth. Unchecked: for user input, use
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
        let n = self.grid.0 * self.grid.1;
        let bright = led_brightness(self.seed, self.led_brightness, n);
        let mut samples = Vec::with_capacity(
            self.separations
                .len()
                .saturating_mul(n)
                .saturating_mul(self.samples)
                .min(MAX_REPORTS),
        );
        let mut skipped = 0;
        for (k, &sep) in self.separations.iter().enumerate() {
            let place = phys.geometry[k];
            let em = place.emulator(em);
            for (i, brightness) in bright.iter().enumerate() {
                let nominal = grid_position_xy(self.grid, self.pitch, sep, i);
                let truth = place.beacon(&nominal);
                let Some(out) = em.output(&truth) else {
                    skipped += 1;
                    continue;
                };
                let mag = em.magnitude(&truth) * brightness;
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
                        magnitude: Some(if mag_sigma > 0.0 {
                            let z: f64 = mag_rng.sample(StandardNormal);
                            (mag * (1.0 + mag_sigma * z)).max(0.0)
                        } else {
                            mag
                        }),
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

/// Whether a simulation may be written to `out`: not a directory; a new file, or an earlier
/// `cta simulate` output (its first line names `cta ... simulate`), which is replaced; any
/// other existing file (a sweep's data, a measurement file from a rig) only with `force`.
/// [`write_files`] checks it before writing anything; a caller that wants to refuse before
/// simulating (as `cta simulate` does) calls it first. Nothing is modified.
pub fn check_out(out: &Path, force: bool) -> Result<(), String> {
    use std::io::BufRead;
    if out.is_dir() {
        return Err(format!(
            "--out {}: is a folder; give a file name (e.g. {})",
            out.display(),
            out.join("sim.csv").display()
        ));
    }
    if force {
        return Ok(());
    }
    // The truth sidecar is replaced too: an existing one must be a simulation's as well.
    let tp = Truth::path_for(out);
    if tp.exists() {
        let generator = std::fs::read_to_string(&tp)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| v["generator"].as_str().map(str::to_string));
        if !generator.is_some_and(|g| g.starts_with("cta ") && g.ends_with(" simulate")) {
            return Err(format!(
                "--out {1}: {0} exists and is not the truth of an earlier `cta simulate` \
                 output, and writing {1} would replace it; not replaced: give another file name, \
                 or --force to replace it",
                tp.display(),
                out.display()
            ));
        }
    }
    if !out.exists() {
        return Ok(());
    }
    let mut first = String::new();
    std::fs::File::open(out)
        .map(std::io::BufReader::new)
        .and_then(|mut r| r.read_line(&mut first))
        .map_err(|e| {
            format!(
                "--out {}: exists and cannot be read ({e}), so it is not known to be an \
                 earlier `cta simulate` output; not replaced: give another file name, or --force \
                 to replace it",
                out.display()
            )
        })?;
    if first.starts_with("# cta ") && first.contains(" simulate ") {
        return Ok(());
    }
    Err(format!(
        "--out {}: exists and is not an earlier `cta simulate` output (first line: `{}`); not \
         replaced: give another file name, or --force to replace it",
        out.display(),
        first.trim().chars().take(80).collect::<String>()
    ))
}

/// Write a simulation to `out` (CSV) and its truth to `FILE.truth.json`, each through a
/// `.partial` file renamed into place only when complete; missing folders above `out` are
/// created (as for every `cta` output, [`crate::data::create_parent_folders`]). `out`
/// must pass [`check_out`] with `force` (otherwise nothing is written). On any error both
/// partial files are removed and the error names the path. Returns the truth path.
pub fn write_files(
    out: &Path,
    ds: &Dataset,
    truth: &Truth,
    force: bool,
) -> Result<PathBuf, String> {
    check_out(out, force)?;
    crate::data::create_parent_folders(out)?;
    let tp = Truth::path_for(out);
    let tmp = out.with_extension("csv.partial");
    let tmp_truth = tp.with_extension("json.partial");
    let comments = vec![
        format!("{} ; truth in {}", truth.generator, tp.display()),
        format!(
            "physics {} ; beacon {} ; effects [{}]",
            truth.physics,
            truth.pattern,
            truth.effects.join(" ")
        ),
    ];
    let write_csv = || -> std::io::Result<()> {
        let mut w = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        ds.write(&mut w, &comments)?;
        w.flush()?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()
    };
    let json = serde_json::to_string_pretty(truth).map_err(|e| format!("{}: {e}", tp.display()))?;
    let result = write_csv()
        .map_err(|e| {
            format!(
                "cannot write {} (via {}): {e}",
                out.display(),
                tmp.display()
            )
        })
        .and_then(|()| {
            std::fs::write(&tmp_truth, json).map_err(|e| {
                format!(
                    "cannot write {} (via {}): {e}",
                    tp.display(),
                    tmp_truth.display()
                )
            })
        })
        .and_then(|()| {
            std::fs::rename(&tmp_truth, &tp)
                .map_err(|e| format!("cannot write {}: {e}", tp.display()))
        })
        .and_then(|()| {
            std::fs::rename(&tmp, out).map_err(|e| format!("cannot write {}: {e}", out.display()))
        });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
        let _ = std::fs::remove_file(&tmp_truth);
    }
    result.map(|()| tp)
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
pub fn parse_grid(s: &str) -> Result<(usize, usize), String> {
    let (a, b) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("grid `{s}`: expected COLSxROWS, e.g. 10x10"))?;
    let a: usize = a
        .trim()
        .parse()
        .map_err(|_| format!("grid `{s}`: bad column count"))?;
    let b: usize = b
        .trim()
        .parse()
        .map_err(|_| format!("grid `{s}`: bad row count"))?;
    let max = crate::data::MAX_BEACON_ID as usize + 1;
    if a == 0 || b == 0 || a.saturating_mul(b) > max {
        return Err(format!(
            "grid `{s}`: between 1x1 and {max} beacons (beacon ids 0..{}, e.g. 20x20)",
            max - 1
        ));
    }
    Ok((a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_free_matches_emulator_and_is_seeded() {
        let cfg = SimConfig {
            separations: vec![20.0, 25.0],
            ..Default::default()
        };
        let (d, t) = cfg.run();
        assert_eq!(d.samples.len(), 200);
        assert_eq!(t.skipped_points, 0);
        let em = cfg.physics().emulator;
        let s = d.samples[37];
        let o = em.output(&Vector3::from(s.r)).unwrap();
        assert_eq!([s.x, s.y], o);
        let noisy = SimConfig {
            noise: 30.0,
            samples: 3,
            seed: 9,
            ..cfg.clone()
        };
        let (a, _) = noisy.run();
        let (b, _) = noisy.run();
        assert_eq!(a.samples, b.samples);
        assert!(a.samples.iter().all(|s| s.x.fract() == 0.0));
    }

    /// Magnitude noise is drawn from its own stream (x and y of a seed are unchanged), is
    /// recovered by `cta noise`, is recorded in the truth, and is refused beyond 25 %.
    #[test]
    fn magnitude_noise_is_its_own_stream_and_measurable() {
        let base = SimConfig {
            separations: vec![5.0, 20.0],
            noise: 30.0,
            samples: 20,
            seed: 3,
            ..Default::default()
        };
        let (plain, t0) = base.run();
        let with = SimConfig {
            magnitude_noise: 0.5,
            ..base.clone()
        };
        let (noisy, t1) = with.run();
        assert_eq!(t0.magnitude_noise_percent, 0.0);
        assert_eq!(t1.magnitude_noise_percent, 0.5);
        assert_eq!(plain.samples.len(), noisy.samples.len());
        for (a, b) in plain.samples.iter().zip(&noisy.samples) {
            assert_eq!([a.x, a.y], [b.x, b.y]);
        }
        assert!(plain
            .samples
            .iter()
            .zip(&noisy.samples)
            .any(|(a, b)| a.magnitude != b.magnitude));
        let zero = crate::noise::analyze_noise(&plain)
            .unwrap()
            .magnitude
            .unwrap();
        assert!(zero.percent < 1e-9);
        // 200 points x 19 degrees of freedom: the pooled estimate is within ~1.2 % (1-sigma)
        // of the truth; 5 % is four sigma.
        let m = crate::noise::analyze_noise(&noisy)
            .unwrap()
            .magnitude
            .unwrap();
        assert!((m.percent - 0.5).abs() < 0.025, "{m:?}");
        for bad in [-0.1, 25.5, f64::NAN] {
            let e = SimConfig {
                magnitude_noise: bad,
                ..base.clone()
            }
            .check()
            .unwrap_err();
            assert!(e.contains("magnitude noise"), "{e}");
        }
    }

    /// The LEDs' brightness scatter multiplies each beacon's magnitudes by its LED's factor
    /// (recorded in the truth, drawn from a stream of its own: x, y and the magnitude noise of
    /// the seed are unchanged), about as widely as asked; 0 leaves the file as it was, and the
    /// truth without factors; beyond 50 % it is refused.
    #[test]
    fn led_brightness_scales_the_magnitudes_by_their_leds_factor() {
        let base = SimConfig {
            separations: vec![5.0, 20.0],
            noise: 30.0,
            samples: 2,
            magnitude_noise: 0.5,
            seed: 8,
            ..Default::default()
        };
        let (plain, t0) = base.run();
        assert!(t0.led_brightness.is_empty() && t0.led_brightness_percent == 0.0);
        let json = serde_json::to_string(&t0).unwrap();
        assert!(!json.contains("\"led_brightness\""), "{json}");
        let (bright, t1) = SimConfig {
            led_brightness: 10.0,
            ..base.clone()
        }
        .run();
        assert_eq!(t1.led_brightness_percent, 10.0);
        assert_eq!(t1.led_brightness.len(), 100);
        assert_eq!(t1.led_brightness, led_brightness(8, 10.0, 100));
        for (a, b) in plain.samples.iter().zip(&bright.samples) {
            assert_eq!([a.x, a.y], [b.x, b.y]);
            let f = t1.led_brightness[a.beacon.unwrap() as usize];
            let (ma, mb) = (a.magnitude.unwrap(), b.magnitude.unwrap());
            assert!((mb / ma / f - 1.0).abs() < 1e-12, "{ma} {mb} {f}");
        }
        let ln: Vec<f64> = t1.led_brightness.iter().map(|b| b.ln()).collect();
        let sd = (ln.iter().map(|v| v * v).sum::<f64>() / ln.len() as f64).sqrt();
        assert!((0.08..0.12).contains(&sd), "{sd}");
        assert!(led_brightness(8, 0.0, 3) == [1.0; 3]);
        for bad in [-1.0, 50.5, f64::NAN] {
            let e = SimConfig {
                led_brightness: bad,
                ..base.clone()
            }
            .check()
            .unwrap_err();
            assert!(e.contains("LED brightness"), "{e}");
        }
    }

    #[test]
    fn grid_ids_fit_the_beacon_column() {
        assert_eq!(parse_grid("20x20").unwrap(), (20, 20));
        // 10,000 beacons used to be allowed; ids above 399 make files `cta` cannot read.
        assert!(parse_grid("100x100").unwrap_err().contains("400 beacons"));
        assert!(parse_grid("21x20").is_err());
        assert!(parse_grid("0x5").is_err());
    }

    fn tmpdir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("cta-simulate-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn huge_sample_counts_are_refused_before_allocating() {
        // `--samples 100000000` used to abort on a 1.36 TB allocation.
        let cfg = SimConfig {
            samples: 100_000_000,
            ..Default::default()
        };
        let e = cfg.try_run().unwrap_err();
        assert!(e.contains("between 1 and 100000"), "{e}");
        let cfg = SimConfig {
            samples: 0,
            ..Default::default()
        };
        assert!(cfg.try_run().is_err());
        // Within the per-point cap but too many reports in all.
        let cfg = SimConfig {
            samples: MAX_SAMPLES,
            ..Default::default()
        };
        let e = cfg.try_run().unwrap_err();
        assert!(
            e.contains("29 separations x 100 beacons x 100000 samples"),
            "{e}"
        );
        assert!(e.contains("more than the 10000000"), "{e}");
    }

    #[test]
    fn nothing_simulated_is_an_error() {
        // `--separations 1e300`: the signal underflows; 0 reports used to exit 0.
        let cfg = SimConfig {
            separations: vec![1e300],
            ..Default::default()
        };
        assert!(cfg.run().0.samples.is_empty());
        let e = cfg.try_run().unwrap_err();
        assert!(
            e.contains("nothing to write: all 100 beacon positions"),
            "{e}"
        );
        assert!(e.contains("1e300"), "{e}");
    }

    #[test]
    fn repeated_effects_are_refused() {
        let cfg = SimConfig {
            separations: vec![20.0],
            effects: vec![Effect::CellGain(0.1, 0.0), Effect::CellGain(0.2, 0.0)],
            ..Default::default()
        };
        assert!(cfg.try_run().unwrap_err().contains("given twice"));
    }

    #[test]
    fn write_files_leaves_no_partial_file_behind() {
        let d = tmpdir("write");
        let cfg = SimConfig {
            separations: vec![20.0],
            ..Default::default()
        };
        let (ds, truth) = cfg.try_run().unwrap();
        let partials = |d: &Path| {
            std::fs::read_dir(d)
                .unwrap()
                .filter(|e| {
                    e.as_ref()
                        .unwrap()
                        .path()
                        .to_string_lossy()
                        .ends_with(".partial")
                })
                .count()
        };
        // --out is a directory.
        let e = write_files(&d, &ds, &truth, false).unwrap_err();
        assert!(
            e.contains(&d.display().to_string()) && e.contains("is a folder"),
            "{e}"
        );
        // The truth cannot be put in place: both partial files are removed.
        let out = d.join("x.csv");
        std::fs::create_dir_all(d.join("x.truth.json").join("sub")).unwrap();
        let e = write_files(&out, &ds, &truth, false).unwrap_err();
        assert!(e.contains("x.truth.json"), "{e}");
        assert_eq!(partials(&d), 0);
        assert!(!out.exists());
        // A folder that does not exist is created; one that cannot be (a file is in the way)
        // is an error naming the file.
        let y = d.join("no").join("y.csv");
        write_files(&y, &ds, &truth, false).unwrap();
        assert!(y.exists() && d.join("no").join("y.truth.json").exists());
        let e = write_files(&y.join("z.csv"), &ds, &truth, false).unwrap_err();
        assert!(e.starts_with("cannot write") && e.contains("z.csv"), "{e}");
        // Success: both files, readable, no partial.
        let tp = write_files(&d.join("ok.csv"), &ds, &truth, false).unwrap();
        assert_eq!(partials(&d), 0);
        assert_eq!(Dataset::read(&d.join("ok.csv")).unwrap().samples.len(), 100);
        assert!(Truth::load_for(&d.join("ok.csv")).unwrap().is_ok());
        assert_eq!(tp, d.join("ok.truth.json"));
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn write_files_replaces_only_an_earlier_simulation() {
        // The guard is in the library: a caller other than `cta simulate` cannot replace a
        // sweep's data either.
        let d = tmpdir("replace");
        let cfg = SimConfig {
            separations: vec![20.0],
            ..Default::default()
        };
        let (ds, truth) = cfg.try_run().unwrap();
        let data = d.join("data.csv");
        let text = "# cta 0.1.0 sweep: plan `x`\nseparation_in,beacon_x_in,beacon_y_in\n";
        std::fs::write(&data, text).unwrap();
        let e = write_files(&data, &ds, &truth, false).unwrap_err();
        assert_eq!(
            e,
            format!(
                "--out {}: exists and is not an earlier `cta simulate` output (first line: `# cta \
                 0.1.0 sweep: plan `x``); not replaced: give another file name, or --force to \
                 replace it",
                data.display()
            )
        );
        assert_eq!(std::fs::read_to_string(&data).unwrap(), text, "untouched");
        assert!(!d.join("data.truth.json").exists() && !d.join("data.csv.partial").exists());
        assert_eq!(check_out(&data, false).unwrap_err(), e);
        // An earlier simulation is replaced; anything else with `force`.
        let sim = d.join("sim.csv");
        write_files(&sim, &ds, &truth, false).unwrap();
        check_out(&sim, false).unwrap();
        write_files(&sim, &ds, &truth, false).unwrap();
        write_files(&data, &ds, &truth, true).unwrap();
        assert_eq!(Dataset::read(&data).unwrap().samples.len(), 100);
        // A new file name whose truth sidecar exists and is something else: refused, the
        // sidecar untouched.
        let other = d.join("new.truth.json");
        std::fs::write(&other, "{\"notes\": 1}").unwrap();
        let e = write_files(&d.join("new.csv"), &ds, &truth, false).unwrap_err();
        assert!(
            e.contains("new.truth.json") && e.contains("not the truth"),
            "{e}"
        );
        assert_eq!(std::fs::read_to_string(&other).unwrap(), "{\"notes\": 1}");
        assert!(!d.join("new.csv").exists());
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn fit_warns_about_a_corrupt_truth_sidecar() {
        let d = tmpdir("truth");
        let csv = d.join("m.csv");
        assert!(matches!(Truth::load_for_fit(&csv), (None, None)));
        std::fs::write(d.join("m.truth.json"), "{ not json").unwrap();
        let (t, w) = Truth::load_for_fit(&csv);
        assert!(t.is_none());
        let w = w.unwrap();
        assert!(
            w.contains("m.truth.json") && w.contains("key must be a string"),
            "{w}"
        );
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn plate_offset_moves_truth_not_record() {
        let cfg = SimConfig {
            separations: vec![10.0],
            effects: vec![Effect::PlateOffset(0.1)],
            ..Default::default()
        };
        let (d, t) = cfg.run();
        assert!(t.plate_offsets[0][0].abs() > 0.0);
        assert_eq!(d.samples[0].r, [-4.5, -4.5, 10.0]);
    }

    /// A plate tilted T toward azimuth AZ: its downward normal (and so every LED boresight)
    /// leans T toward AZ, the side toward AZ is farther from the sensor by u sin T, the
    /// centre stays put and distances on the plate are kept.
    #[test]
    fn a_tilted_plate_turns_about_its_centre() {
        let t = 2.0f64;
        for az in [0.0f64, 90.0, 135.0, -60.0] {
            let (c, s) = (az.to_radians().cos(), az.to_radians().sin());
            let pl = Placement {
                offset: [0.1, -0.2],
                sep_error: 0.05,
                tilt_deg: [t * c, t * s],
            };
            let n = pl.rotation() * Vector3::new(0.0, 0.0, -1.0);
            let want = Vector3::new(rad(t).sin() * c, rad(t).sin() * s, -rad(t).cos());
            assert!((n - want).norm() < 1e-12, "AZ {az}: {n}");
            let centre = pl.beacon(&Vector3::new(0.0, 0.0, 10.0));
            assert!((centre - Vector3::new(0.1, -0.2, 10.05)).norm() < 1e-12);
            // 4 in from the centre toward AZ: farther by 4 sin T; the opposite side nearer.
            let toward = pl.beacon(&Vector3::new(4.0 * c, 4.0 * s, 10.0));
            let away = pl.beacon(&Vector3::new(-4.0 * c, -4.0 * s, 10.0));
            assert!(
                (toward.z - 10.05 - 4.0 * rad(t).sin()).abs() < 1e-12,
                "AZ {az}"
            );
            assert!(
                (away.z - 10.05 + 4.0 * rad(t).sin()).abs() < 1e-12,
                "AZ {az}"
            );
            assert!(((toward - centre).norm() - 4.0).abs() < 1e-12);
            // Across the azimuth: no change in z.
            let side = pl.beacon(&Vector3::new(-4.0 * s, 4.0 * c, 10.0));
            assert!((side.z - 10.05).abs() < 1e-12, "AZ {az}");
            let em = SimConfig::default().physics().emulator;
            assert!((pl.emulator(&em).boresight() - want).norm() < 1e-12);
        }
        // No tilt: the recorded place plus the offsets, the emulator unchanged.
        let flat = Placement {
            offset: [0.1, 0.0],
            ..Default::default()
        };
        assert_eq!(
            flat.beacon(&Vector3::new(3.0, 1.0, 5.0)),
            Vector3::new(3.1, 1.0, 5.0)
        );
        // A seed's offsets and separation errors do not change when a tilt is added.
        let run = |fx: Vec<Effect>| {
            SimConfig {
                separations: vec![5.0, 10.0],
                effects: fx,
                ..Default::default()
            }
            .physics()
            .geometry
        };
        let a = run(vec![Effect::PlateOffset(0.1), Effect::SeparationError(0.1)]);
        let b = run(vec![
            Effect::PlateOffset(0.1),
            Effect::SeparationError(0.1),
            Effect::PlateTilt(0.5),
        ]);
        for (a, b) in a.iter().zip(&b) {
            assert_eq!((a.offset, a.sep_error), (b.offset, b.sep_error));
            assert!(!a.tilted() && b.tilted());
        }
    }
}
