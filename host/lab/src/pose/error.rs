//! The errors of the pose analyses and of the simulated sensor head.

use cta_core::pose::ConfigError;

/// What went wrong in a pose analysis, a constellation or the simulated head.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An option out of its range; the message names the option and the range.
    #[error("{0}")]
    Option(String),
    /// A file could not be read.
    #[error("reading {file}: {error}")]
    Read {
        /// The file.
        file: String,
        /// Why.
        error: std::io::Error,
    },
    /// A calibration or constellation file was refused.
    #[error(transparent)]
    BoardFile(#[from] crate::boards::files::Error),
    /// A constellation file that cannot work or is surely a slip.
    #[error("{file}: {why}")]
    Constellation {
        /// The file.
        file: String,
        /// Why.
        why: String,
    },
    /// Two beacons on channels that share a frequency in the NorthStar table.
    #[error(
        "beacons on channels {a} and {b}: the NorthStar frequency table gives both {hz} Hz \
         (ID {}'s first LED and ID {}'s second), so the detector cannot tell them apart; \
         use one of them (the built-in one-19 and four-19 leave channel {b} out)",
        .a / 2,
        .b / 2
    )]
    SharedChannels {
        /// The lower channel.
        a: u8,
        /// The higher channel.
        b: u8,
        /// Their frequency, Hz.
        hz: f64,
    },
    /// No built-in constellation of this name.
    #[error("no built-in constellation {name}; the built-ins:{built_ins}")]
    NoBuiltIn {
        /// The name asked for.
        name: String,
        /// The built-ins, one a line, each with what it is.
        built_ins: String,
    },
    /// `--constellation` names neither a file nor a built-in.
    #[error(
        "--constellation {spec}: no such file, and not a built-in name; the built-ins:{built_ins}"
    )]
    NoConstellation {
        /// What was given.
        spec: String,
        /// The built-ins, one a line, each with what it is.
        built_ins: String,
    },
    /// A beacon raised to a range of the table or beyond.
    #[error(
        "a beacon stands {highest:.1} in toward the sensor (--depth, or the constellation's \
         heights): at the {closest} in range it would be at the sensor or behind it; keep the \
         ranges beyond the highest beacon"
    )]
    BeaconAtSensor {
        /// Height of the highest beacon toward the sensor, in.
        highest: f64,
        /// The closest range, in.
        closest: f64,
    },
    /// `--brightness` is not a JSON file.
    #[error(
        "{file}: not a JSON calibration file ({error}); --brightness takes the file `cta \
         calibrate --out` writes"
    )]
    NotJson {
        /// The file.
        file: String,
        /// What the JSON reader found.
        error: serde_json::Error,
    },
    /// `--brightness` names a file without the LEDs' brightness.
    #[error(
        "{file}: no `led_brightness` (the LEDs' brightness `cta calibrate` fits from a sweep's \
         spot magnitudes): {}",
        brightness_hint(.constellation)
    )]
    NoBrightness {
        /// The file.
        file: String,
        /// Whether it is a constellation.
        constellation: bool,
    },
    /// The LEDs' brightness of a calibration file could not be read.
    #[error("{file}: `led_brightness`: {error}")]
    Brightness {
        /// The file.
        file: String,
        /// What the JSON reader found.
        error: serde_json::Error,
    },
    /// The constellation with the brightness set is not valid.
    #[error("with the brightness of {file}: {error}")]
    WithBrightness {
        /// The calibration file.
        file: String,
        /// What the validation found.
        error: ConfigError,
    },
    /// `--effect` does not parse.
    #[error("--effect: {0}")]
    Effect(crate::sim::effects::EffectError),
    /// `--effect` of the CTA's plate, not the head.
    #[error(
        "--effect {effect}: `{name}` describes the CTA's beacon plate, not the sensor head (the \
         simulated target's LEDs face along its constellation's boresight, turned by \
         --attitude-deg or --yaw-deg); the head takes proximity, intensity, beacon_pattern, cell_gain, \
         cell_bias, face_angle, saturation and crosstalk"
    )]
    PlateEffect {
        /// The effect as written.
        effect: String,
        /// Its name.
        name: String,
    },
    /// The truth sidecar could not be read.
    #[error("--truth {path}: {error}")]
    TruthRead {
        /// The file.
        path: String,
        /// Why.
        error: std::io::Error,
    },
    /// `--truth` is not a truth sidecar.
    #[error(
        "--truth {path}: not a truth sidecar ({error}); give the FILE.truth.json `cta simulate \
         --out FILE.csv` writes, or the RUN/data.truth.json of a sweep of the simulated CTA \
         (`cta sweep --sim`, `cta demo`)"
    )]
    NotTruth {
        /// The file.
        path: String,
        /// What the JSON reader found.
        error: serde_json::Error,
    },
    /// A truth sidecar whose head cannot be simulated.
    #[error("--truth {path}: {what}")]
    Truth {
        /// The file.
        path: String,
        /// What is wrong.
        what: String,
    },
    /// A noise distribution could not be made.
    #[error("{what}: {error}")]
    Noise {
        /// Which noise.
        what: &'static str,
        /// Why.
        error: rand_distr::NormalError,
    },
    /// The pinhole calibration fit failed.
    #[error("pinhole calibration fit failed: {0}")]
    PinholeFit(String),
    /// The near-field calibration fit failed (its message).
    #[error("{0}")]
    NearFieldFit(String),
    /// The magnitude law fit failed (its message).
    #[error("{0}")]
    MagnitudeFit(String),
    /// The simulated sweep gave no magnitude law.
    #[error("simulated magnitude calibration: {0}")]
    NoMagnitudeLaw(String),
    /// The pose solver refused the calibration or constellation.
    #[error("{0}")]
    Solver(ConfigError),
    /// A plot could not be written.
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    /// `cta sensor accuracy --check`: design targets that do not hold, each with its figures.
    #[error("accuracy design targets not met:\n  {}", .0.join("\n  "))]
    TargetsNotMet(Vec<String>),
}

/// What to do about a `--brightness` file without the LEDs' brightness.
fn brightness_hint(constellation: &bool) -> &'static str {
    if *constellation {
        "this is a constellation; --brightness takes a calibration"
    } else {
        "calibrate from a sweep that recorded magnitudes (`cta calibrate DATA.csv --out \
         cal.json`), without --no-magnitude"
    }
}
