//! The `cta` command line: argument parsing, dispatch and rendering over the `cta_lab` library.

use clap::{Parser, Subcommand};

pub mod args;
pub mod cmd;
pub mod conn;
pub mod say;
pub mod signals;

/// `cta --version`: the package version and the commit it was built from.
const VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), " (", env!("CTA_COMMIT"), ")");

#[derive(Parser)]
#[command(
    name = "cta",
    version = VERSION,
    about = "Characterize a NorthStar coarse sun sensor in the near field: simulate, sweep, fit, evaluate, \
calibrate, analyze (start with `cta demo`)",
    long_about = "CTA turns the NorthStar IR coarse sun sensor (four photocells in a pyramid) into a 6-dof \
relative-navigation sensor. Close to a beacon the sun-sensor assumptions break: the cells see the beacon from \
different places (proximity), at different distances (intensity), through a non-uniform LED pattern. `cta` \
quantifies those near-field errors (thesis Ch II), the apparatus uncertainty (Ch IV), emulates the sensor and \
fits its calibration model (Ch V), sweeps the apparatus (Ch VI), calibrates the sensor board, and analyzes \
measured data for what the model gets wrong.\n\n\
Conventions: inches and degrees at every interface; N = sensor-board frame, O = sensor-head frame; \
d = N origin -> head centre (in N); C(p) maps N to O (MRP p). Equation numbers are those of Stancliffe (2010).\n\n\
Start with:  cta demo    (the main job on the built-in simulated CTA, no hardware: a sweep, the calibrations, \
Figure 57 and the analysis report, in cta-demo/)\n\
Step by step:  cta simulate --out sim.csv --separations 20,25 && cta fit sim.csv --save fit.json && \
cta evaluate fit.json sim.csv"
)]
pub struct Cli {
    /// Say nothing on stderr but errors: no warnings, notes, progress or "plot: FILE" lines
    /// (the results on stdout and the files are the same).
    #[arg(long, short = 'q', global = true)]
    quiet: bool,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
pub enum Cmd {
    /// Ch II: how far away each near-field effect (proximity, intensity, beacon pattern)
    /// falls below the sensor noise, in sensor diameters (2-D model, eqs 1-22).
    Nearfield(cmd::nearfield::NearfieldArgs),
    /// Ch IV: the apparatus uncertainty budget (root-sum-square, eq 26; default Table 2)
    /// and the 2-D angle uncertainty it causes (eq 40) against the near-field error.
    Uncertainty(cmd::uncertainty::UncertaintyArgs),
    /// Ch V: emulated NorthStar reports of the CTA beacon grid (eqs 60-63), optionally with
    /// noise and hidden effects; the truth is written next to the data.
    Simulate(cmd::simulate::SimulateArgs),
    /// Ch V: fit the 7-parameter collinearity model (d, MRP p, scale height H; eq 65) by
    /// GLSDC (eqs 56-59): parameters, 1-sigma, residual RMS, condition number.
    Fit(cmd::fit::FitArgs),
    /// Ch V: the error in angle of a saved fit per separation (eq 67), the Figure 57 curve,
    /// against the truth when the data carries it.
    Evaluate(cmd::evaluate::EvaluateArgs),
    /// The sensor board's calibration from a measured sweep: the pinhole (eq 65) and
    /// near-field (eqs 60-63: d, p, face angles, cell offset, cell gains and offsets) fits,
    /// the residual RMS of both per separation (flagging where the model misses), and the
    /// JSON file `cta sensor load-calibration` stores in flash.
    Calibrate(cmd::calibrate::CalibrateArgs),
    /// The main job on the built-in simulated CTA (no hardware): near-field errors,
    /// uncertainty, a simulated characterization with a hidden effect, calibration and
    /// evaluation, with plots, in one folder.
    Demo(cmd::demo::DemoArgs),
    /// Autonomous CTA data collection over serial (or on the simulated CTA with --sim):
    /// a plan of separations, beacons, frequencies, power levels and sensitivities,
    /// resumable after any interruption, never losing or duplicating a point.
    Sweep(cmd::sweep::SweepArgs),
    /// From measured data to a named cause: where the model disagrees with the data, the
    /// physical effect responsible, the extended model and its held-out gain.
    Analyze(cmd::analyze::AnalyzeArgs),
    /// The noise of repeated samples by separation, angle, magnitude, frequency, power and
    /// sensitivity (the Ch VI questions), and the weighting it implies for fit and analyze.
    Noise(cmd::noise::NoiseArgs),
    /// Talk to the beacon array board (STM32F103ZET6) by hand: identify, light beacons,
    /// status, heartbeat; `--sim` for an in-process simulated board, or serve one on a
    /// pseudo-terminal.
    Beacon(cmd::beacon::BeaconArgs),
    /// Talk to the sensor board (STM32F103C8): identify, stream spots, load a calibration
    /// and constellation, read poses; simulated board; the pose accuracy table.
    Sensor(cmd::sensor::SensorArgs),
    /// Solve logged spot frames (`cta sensor stream --json`) on the host with the board's
    /// solver: pose, 1-sigma, residual and status per frame.
    Pose(cmd::pose::PoseArgs),
    /// Print the shell completion script (bash, zsh, fish, powershell, elvish).
    Completions(cmd::completions::CompletionsArgs),
    /// Write the man pages (cta.1 and one per command).
    Man(cmd::completions::ManArgs),
}

/// List options whose value may start with a minus sign (`--separations -5,3` is not a
/// number, so `allow_negative_numbers` alone lets clap read it as a flag).
const LIST_OPTIONS: [&str; 4] = ["separations", "holdout", "theta", "ranges"];

/// Every option value may be a negative number (`--noise -3` reaches the option's own range
/// check, which names the allowed range, instead of clap's "unexpected argument '-3'"), and
/// every list option a list starting with one (`--separations -5,3` reaches the separation
/// parser, which says why -5 is refused).
fn negative_values(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|a| {
        if !a.get_action().takes_values() {
            a
        } else if LIST_OPTIONS.contains(&a.get_id().as_str()) {
            a.allow_hyphen_values(true)
        } else {
            a.allow_negative_numbers(true)
        }
    })
    .mut_subcommands(negative_values)
}

fn parse() -> Cli {
    use clap::{CommandFactory, FromArgMatches};
    let matches = negative_values(Cli::command()).get_matches();
    Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
}

/// Run `cta` with the process's arguments and exit as the tool does.
pub fn main() {
    // Like other command-line tools, end quietly when the reader of our output goes away
    // (`cta fit data.csv | head -1`) instead of panicking in `println!`. Everything a
    // command writes to files is written before it prints, or is resumable (sweeps).
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE, before any other thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = parse();
    say::set_quiet(cli.quiet);
    let r = match &cli.cmd {
        Cmd::Nearfield(a) => cmd::nearfield::run(a),
        Cmd::Uncertainty(a) => cmd::uncertainty::run(a),
        Cmd::Simulate(a) => cmd::simulate::run(a),
        Cmd::Fit(a) => cmd::fit::run(a),
        Cmd::Evaluate(a) => cmd::evaluate::run(a),
        Cmd::Calibrate(a) => cmd::calibrate::run(a),
        Cmd::Demo(a) => cmd::demo::run(a),
        Cmd::Sweep(a) => cmd::sweep::run(&cmd::sweep::SweepArgs {
            quiet: cli.quiet,
            ..a.clone()
        }),
        Cmd::Analyze(a) => cmd::analyze::run(&cmd::analyze::AnalyzeArgs {
            quiet: cli.quiet,
            ..a.clone()
        }),
        Cmd::Noise(a) => cmd::noise::run(a),
        Cmd::Beacon(a) => cmd::beacon::run(a),
        Cmd::Sensor(a) => cmd::sensor::run(a),
        Cmd::Pose(a) => cmd::pose::run(a),
        Cmd::Completions(a) => cmd::completions::completions(a),
        Cmd::Man(a) => cmd::completions::man(a),
    };
    exit_on_error(r);
}

/// The provenance of an output this run makes from `inputs`: the tool with its commit, now,
/// the command line and each input's SHA-256.
pub fn provenance(inputs: &[&std::path::Path]) -> cta_lab::provenance::Provenance {
    cta_lab::provenance::Provenance::now(
        concat!(
            "cta ",
            env!("CARGO_PKG_VERSION"),
            " (",
            env!("CTA_COMMIT"),
            ")"
        ),
        std::env::args().collect(),
        inputs,
    )
}

/// `value` as pretty JSON with the provenance of `inputs` under `provenance`.
pub fn json_with_provenance(
    value: &impl serde::Serialize,
    inputs: &[&std::path::Path],
) -> serde_json::Result<String> {
    // Through the text, not `to_value`: an `f32` keeps its shortest digits (1.0000306, not
    // 1.0000306367874146).
    let v: serde_json::Value = serde_json::from_str(&serde_json::to_string(value)?)?;
    serde_json::to_string_pretty(&provenance(inputs).attach(v))
}

/// What the binary does with a command's error: prints `cta: error: ...` with its causes and
/// exits with 1, or an interrupted sweep's [`cmd::sweep::Interrupted::exit_code`] (128 + the
/// signal). Returns on success.
pub fn exit_on_error(r: anyhow::Result<()>) {
    if let Err(e) = r {
        eprintln!("cta: error: {e:#}");
        let code = e
            .downcast_ref::<cmd::sweep::Interrupted>()
            .map_or(1, |i| i.exit_code);
        std::process::exit(code);
    }
}
