//! `cta demo`: the whole job on the built-in simulated CTA, no hardware.

use crate::args::{Profile, WeightsArg};
use crate::cmd::analyze::{AnalyzeArgs, Base, Weights};
use crate::cmd::calibrate::CalibrateArgs;
use crate::cmd::capture;
use crate::cmd::evaluate::EvaluateArgs;
use crate::cmd::fit::FitArgs;
use crate::cmd::nearfield::NearfieldArgs;
use crate::cmd::sweep::SweepArgs;
use crate::cmd::uncertainty::UncertaintyArgs;
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

/// Run the main job on the simulated CTA: near-field analysis, uncertainty, an unattended
/// sweep of the simulated apparatus with a hidden effect, calibration, evaluation, and the
/// analysis that names the hidden effect, ending in an HTML report.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder (created; must not exist unless --force, which replaces an earlier
    /// demo's folder and refuses one that holds anything else).
    #[arg(long, default_value = "cta-demo")]
    pub out: PathBuf,
    /// Replace an earlier demo's output folder.
    #[arg(long)]
    pub force: bool,
    /// The hidden effect injected into the simulated data (NAME=VALUE).
    #[arg(long, default_value = "cell_gain=0.02,-0.01")]
    pub effect: String,
    /// Random seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
}

/// The demo sweep plan (also shipped as `host/plans/demo.toml`).
const DEMO_PLAN: &str = include_str!("../../plans/demo.toml");

/// The file the demo writes first into its folder, saying what the folder is; `--force`
/// deletes only a folder that has it.
const DEMO_README: &str = "README.txt";

/// Its first line.
const DEMO_README_HEAD: &str = "written by `cta demo`: `cta demo --force` deletes this folder";

/// What the demo writes into its folder: `--force` deletes a folder holding only these, with
/// [`DEMO_README`].
const DEMO_ENTRIES: [&str; 12] = [
    DEMO_README,
    LOGS,
    "nearfield.svg",
    "uncertainty.svg",
    "plan.toml",
    "run",
    "fit.json",
    "figure57.svg",
    "cal.json",
    "calibration.svg",
    "report",
    "index.html",
];

/// The folder of the steps' full reports, one file each ([`LOG_FILES`]).
const LOGS: &str = "logs";

/// The steps' reports in [`LOGS`], in order.
const LOG_FILES: [&str; 7] = [
    "1-nearfield.txt",
    "2-uncertainty.txt",
    "3-sweep.txt",
    "4-fit.txt",
    "5-figure57.txt",
    "6-calibrate.txt",
    "7-analyze.txt",
];

/// The demo's plots, each with what it claims: the captions of its `index.html`.
const DEMO_FIGURES: [(&str, &str); 4] = [
    (
        "nearfield.svg",
        "Ch II: each near-field error (proximity, intensity, the beacon's pattern) against the \
         distance in sensor diameters, and where it falls below the sensor's 0.1 deg noise.",
    ),
    (
        "uncertainty.svg",
        "Ch IV: the apparatus's own uncertainty (Table 2's budget) against the near-field error \
         it is built to measure.",
    ),
    (
        "figure57.svg",
        "Figure 57: the error in angle of the 20-30 in pinhole calibration at every separation. \
         It grows close in, where the pinhole model cannot follow the near field.",
    ),
    (
        "calibration.svg",
        "The sensor board's calibration: the residuals of the pinhole and the near-field model \
         per separation against the noise. The near-field model, with the hidden gains it \
         recovered, stays at the noise close in.",
    ),
];

/// Delete an earlier demo's folder; refuse a folder holding anything the demo does not write.
fn remove_earlier_demo(out: &std::path::Path) -> Result<()> {
    if !out.is_dir() {
        bail!("--out {}: exists and is not a folder", out.display());
    }
    let mut foreign = Vec::new();
    for e in std::fs::read_dir(out).with_context(|| format!("{}", out.display()))? {
        let name = e
            .with_context(|| format!("{}", out.display()))?
            .file_name()
            .to_string_lossy()
            .into_owned();
        if !DEMO_ENTRIES.contains(&name.as_str()) {
            foreign.push(name);
        }
    }
    if !foreign.is_empty() {
        foreign.sort();
        bail!(
            "--out {}: holds files the demo did not write ({}): not deleting it; choose another --out",
            out.display(),
            foreign.join(", ")
        );
    }
    let readme = out.join(DEMO_README);
    let ours = std::fs::read_to_string(&readme).is_ok_and(|t| t.starts_with(DEMO_README_HEAD));
    // A demo folder of an older cta (before README.txt) is known by its report; an empty
    // folder holds nothing to lose.
    let older = cta_lab::plot::is_cta_output(&out.join("report").join("index.html"));
    let empty = std::fs::read_dir(out).is_ok_and(|mut d| d.next().is_none());
    if !(ours || older || empty) {
        bail!(
            "--out {}: has no {} written by `cta demo` (demos write it first) nor a report by \
             an older cta, so it is not known to be an earlier demo's folder: not deleting it; \
             remove it yourself or choose another --out",
            out.display(),
            readme.display()
        );
    }
    std::fs::remove_dir_all(out).with_context(|| format!("{}", out.display()))
}

/// Run `cta demo`.
pub fn run(a: &DemoArgs) -> Result<()> {
    // Refuse a bad effect before anything is deleted or written.
    cta_lab::sim::effects::Effect::parse(&a.effect)
        .map_err(|e| anyhow::anyhow!("--effect: {e}"))?;
    if a.out.exists() {
        if !a.force {
            bail!("{} exists; pass --force to replace it", a.out.display());
        }
        remove_earlier_demo(&a.out)?;
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}", a.out.display()))?;
    let p = |f: &str| a.out.join(f);
    cta_lab::data::write_output(
        &p(DEMO_README),
        format!(
            "{DEMO_README_HEAD}\n\nThe walkthrough of `cta demo` on the built-in simulated CTA (see the \
             top-level README.md):\nnearfield.svg, uncertainty.svg: Ch II errors and Ch IV budget\n\
             plan.toml, run/: the simulated sweep\nfit.json, figure57.svg: the 20-30 in \
             calibration and Figure 57\ncal.json, calibration.svg: the sensor board's \
             calibration\nreport/index.html: cta analyze's report\nindex.html: every plot with its caption\n\
             logs/: each step's full report, as the command prints it\n"
        )
        .as_bytes(),
    )
    .map_err(anyhow::Error::msg)?;
    let logs = p(LOGS);
    std::fs::create_dir_all(&logs).with_context(|| format!("{}", logs.display()))?;
    let log = |n: &str| logs.join(n);
    // Each step prints its full report into its log; the terminal gets one line per step.
    let step = |n: &str, f: &dyn Fn() -> Result<()>| capture::to_file(&log(n), f);
    let mut summary = vec![format!(
        "cta demo: the main job on the simulated CTA, hidden effect `{}`, seed {}; in {}",
        a.effect,
        a.seed,
        a.out.display()
    )];

    step("1-nearfield.txt", &|| {
        crate::cmd::nearfield::run(&NearfieldArgs {
            alpha: 30.0,
            theta: "6,18,30,45".into(),
            noise_deg: 0.1,
            profile: Profile::Lambertian,
            half_angle: 60.0,
            diameter_in: 0.35,
            plot: Some(p("nearfield.svg")),
            json: false,
        })
    })?;
    summary
        .push(" 1. Ch II near-field errors (2-D, 0.1 deg noise, D 0.35 in): nearfield.svg".into());
    step("2-uncertainty.txt", &|| {
        crate::cmd::uncertainty::run(&UncertaintyArgs {
            budget: None,
            diameter_in: 0.35,
            plot: Some(p("uncertainty.svg")),
            json: false,
        })
    })?;
    let rss = capture::line_with(&log("2-uncertainty.txt"), "root-sum-square")
        .map(|l| {
            let v: Vec<&str> = l.split_whitespace().skip(1).collect();
            format!(
                ": X {} Y {} Z {} mils",
                v.first().unwrap_or(&"?"),
                v.get(2).unwrap_or(&"?"),
                v.get(4).unwrap_or(&"?")
            )
        })
        .unwrap_or_default();
    summary.push(format!(
        " 2. Ch IV CTA uncertainty (Table 2){rss}: uncertainty.svg"
    ));

    let run_dir = p("run");
    let plan = p("plan.toml");
    std::fs::write(&plan, DEMO_PLAN).with_context(|| format!("{}", plan.display()))?;
    step("3-sweep.txt", &|| {
        println!(
            "An unattended sweep of the simulated CTA (both boards on pseudo-terminals), 4-30 in, \
             noise 0.1 % of beta for a strong spot (growing as a spot dims, about 50 counts at 30 \
             in), spot magnitudes scattering 0.07 % (what that noise implies if both come from \
             the cells), hidden effect `{}`",
            a.effect
        );
        crate::cmd::sweep::run(&SweepArgs {
            plan: Some(plan.clone()),
            out: Some(run_dir.clone()),
            sim: true,
            sim_noise: Some(32.8),
            sim_magnitude_noise: Some(0.07),
            sim_effect: vec![a.effect.clone()],
            sim_seed: Some(a.seed),
            yes: true,
            ..SweepArgs::default()
        })
    })?;
    let points = std::fs::read_to_string(run_dir.join("manifest.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .map(|m| {
            let n = |k: &str| m["points"][k].as_u64().unwrap_or(0);
            format!(
                "{} points ({} ok, {} no signal, {} partial), {} samples",
                n("total"),
                n("ok"),
                n("no_signal"),
                n("partial"),
                m["samples"].as_u64().unwrap_or(0)
            )
        })
        .unwrap_or_default();
    summary.push(format!(
        " 3. Ch VI sweep of the simulated CTA, 4-30 in: {points}: run/data.csv"
    ));

    let data = run_dir.join("data.csv");
    let fit = p("fit.json");
    step("4-fit.txt", &|| {
        println!("Calibrate the pinhole model at 20-30 in (thesis recommendation)");
        crate::cmd::fit::run(&FitArgs {
            file: data.clone(),
            separations: Some("20..30:2".into()),
            weights: WeightsArg::Pooled,
            save: Some(fit.clone()),
            force: false,
            drop_glitches: false,
            json: false,
        })
    })?;
    let rms = capture::line_with(&log("4-fit.txt"), "residual RMS")
        .map(|l| format!(": {l}"))
        .unwrap_or_default();
    summary.push(format!(" 4. Ch V pinhole fit at 20-30 in{rms}: fit.json"));
    step("5-figure57.txt", &|| {
        println!("Figure 57: error in angle of that calibration at every separation");
        crate::cmd::evaluate::run(&EvaluateArgs {
            fit: fit.clone(),
            file: data.clone(),
            separations: None,
            head: None,
            budget: None,
            without_rail: false,
            drop_glitches: false,
            plot: Some(p("figure57.svg")),
            json: false,
        })
    })?;
    let ratio = capture::line_with(&log("5-figure57.txt"), "std over the CTA uncertainty")
        .and_then(|l| {
            l.split_once("uncertainty: ")
                .map(|(_, r)| r.split(';').next().unwrap_or(r).to_string())
        })
        .map(|r| format!(": std / CTA uncertainty {r}"))
        .unwrap_or_default();
    summary.push(format!(" 5. Figure 57{ratio}: figure57.svg"));

    let cal = p("cal.json");
    step("6-calibrate.txt", &|| {
        println!(
            "The sensor board's calibration from the sweep (pinhole, then the chip's near-field model)"
        );
        crate::cmd::calibrate::run(&calibrate_args(&data, &cal, &p("calibration.svg")))
    })?;
    let near = capture::line_with(&log("6-calibrate.txt"), "iterations, condition")
        .map(|l| {
            let l = l.split(", ").take(2).collect::<Vec<_>>().join(", ");
            format!(": near-field {l}")
        })
        .unwrap_or_default();
    summary.push(format!(
        " 6. The sensor board's calibration{near}: cal.json"
    ));

    let report = p("report");
    let analyze = analyze_args(&data, &report);
    step("7-analyze.txt", &|| {
        println!("What the simulation gets wrong, why, and the gain of the extended model");
        crate::cmd::analyze::run(&analyze)
    })?;
    let named = capture::line_with(&log("7-analyze.txt"), "named:")
        .unwrap_or_else(|| "no effect named".into());
    summary.push(format!(" 7. cta analyze: {named}: report/index.html"));
    if let Some(l) = capture::line_with(&log("7-analyze.txt"), "on the sensor board:") {
        summary.push(format!("    {l}"));
    }
    let page = cta_lab::html::gallery(
        "cta demo",
        &format!(
            "The main job on the simulated CTA, with the hidden effect `{}`: every plot the demo \
             made, with what it shows.",
            a.effect
        ),
        &DEMO_FIGURES,
        &[
            ("report/index.html", "cta analyze's report: the hidden effect named, its parameters and the held-out gain"),
            ("run/data.csv", "the sweep's measurements (run/: its journal, manifest and truth)"),
            ("cal.json", "the sensor board's calibration, for cta sensor load-calibration"),
        ],
    );
    cta_lab::data::write_output(&p("index.html"), page.as_bytes()).map_err(anyhow::Error::msg)?;
    let warned: usize = LOG_FILES.iter().map(|n| capture::warnings(&log(n))).sum();
    summary.push(format!(
        "Every plot with its caption: {}; each step's full report ({warned} warning(s)): {}",
        p("index.html").display(),
        logs.display()
    ));
    println!("{}", summary.join("\n"));
    print!("{}", rehearsal(&run_dir, &cal, &a.effect)?);
    Ok(())
}

/// `cta calibrate DATA --out CAL --plot PLOT`, everything else the command's defaults.
fn calibrate_args(data: &Path, cal: &Path, plot: &Path) -> CalibrateArgs {
    CalibrateArgs {
        file: data.to_path_buf(),
        out: Some(cal.to_path_buf()),
        force: false,
        separations: None,
        pinhole_separations: None,
        noise: None,
        pattern_m: 1.0,
        plot: Some(plot.to_path_buf()),
        drop_glitches: false,
        no_magnitude: false,
        magnitude_sensitivity: None,
        json: false,
    }
}

/// `cta analyze DATA --report REPORT`, everything else the command's defaults.
fn analyze_args(data: &Path, report: &Path) -> AnalyzeArgs {
    AnalyzeArgs {
        file: data.to_path_buf(),
        from: Base::Thesis,
        folds: 5,
        holdout: None,
        separations: None,
        weights: Weights::Separation,
        noise: None,
        candidates: None,
        exclude: None,
        max_effects: 5,
        drop_glitches: false,
        ignore_corners: false,
        budget: None,
        report: Some(report.to_path_buf()),
        json: false,
        quiet: false,
    }
}

/// What the rehearsal's simulated board does with the demo's hidden effect: a head effect is
/// included (the truth sidecar carries it); an effect of the plate (its tilt, offsets,
/// separation errors, LED boresights) is no part of the head, and `cta sensor sim` leaves it
/// out.
fn hidden_effect_words(effect: &str) -> String {
    let on_head = cta_lab::sim::effects::Effect::parse(effect)
        .map(|e| cta_lab::pose::head::acts_on_the_head(&e))
        .unwrap_or(true);
    if on_head {
        format!(
            "its hidden `{effect}` included: the plain `cta sensor sim` head has none, and its \
             poses would be off by what the calibration corrects"
        )
    } else {
        format!(
            "its hidden `{effect}` is the CTA plate's, not the head's, so the simulated board \
             leaves it out: cal.json was fitted to data with it, and the poses are off by what \
             the calibration absorbed of it"
        )
    }
}

/// The demo's closing instructions: rehearse the sensor board with its calibration on `cta
/// sensor sim`, whose head must be the sweep's (its truth sidecar: a hidden effect of the head included),
/// with the calibration's spot noise. Each command line is indented by two spaces, starts with
/// `cta ` and holds `PTY` where the pseudo-terminal goes.
fn rehearsal(run_dir: &std::path::Path, cal: &std::path::Path, effect: &str) -> Result<String> {
    let text = std::fs::read_to_string(cal).with_context(|| format!("{}", cal.display()))?;
    let calibration = serde_json::from_str::<cta_core::pose::Calibration>(&text)
        .with_context(|| format!("{}", cal.display()))?;
    let noise = calibration.noise;
    let truth = cta_lab::sim::Truth::path_for(&run_dir.join("data.csv"));
    // The simulated board's own scene, as `cta sensor sim --truth` takes it by default.
    let scene = cta_lab::pose::head::SimScene {
        truth: Some(truth.clone()),
        ..Default::default()
    };
    // What becomes of the spot magnitudes on the simulated board: its NorthStar reads them by
    // the same law as the sweep's (`cta_core::magnitude_law`), so those within cal.json's law
    // are fitted with the spots.
    let magnitudes = match calibration.magnitude {
        Some(m) => {
            let ns = scene.try_northstar()?;
            let law = cta_core::magnitude_law::reading(
                1.0,
                cta_core::magnitude_law::signal_at_30(&ns.physics),
                ns.power_level,
                ns.sensitivity,
            );
            let spots = cta_core::pose::simulate_spots_scaled(
                &ns.physics,
                &ns.constellation,
                &ns.t,
                &ns.q,
                law,
                |_| 0.0,
                |_| 0.0,
            );
            let read: Vec<f32> = spots.iter().map(|s| f32::from(s.magnitude)).collect();
            let used = read.iter().filter(|&&r| r >= m.min && r < m.max).count();
            let (lo, hi) = read.iter().fold((f32::INFINITY, 0.0f32), |(lo, hi), &r| {
                (lo.min(r), hi.max(r))
            });
            format!(
                "; the `mag` column shows {used} magnitudes fitted\n(the board's NorthStar reads \
                 the sweep's law at power level {}, sensitivity {}: {lo:.0}-{hi:.0} counts for \
                 the {} spots; cal.json's law holds {:.0}-{:.0})",
                ns.power_level,
                ns.sensitivity,
                read.len(),
                m.min,
                m.max
            )
        }
        None => String::new(),
    };
    let [x, y] = scene.offset;
    let hidden = hidden_effect_words(effect);
    Ok(format!(
        "Rehearse the board with cal.json, no hardware (the first command in another terminal \
         prints the PTY):\n\
         \x20 cta sensor sim --truth {} --noise {noise:.1} --configured\n\
         \x20 cta sensor --port PTY load-calibration {}\n\
         \x20 cta sensor --port PTY pose --count 5\n\
         Poses scatter about x {x}, y {y}, z {} in by their 1-sigma{magnitudes}.\n\
         The simulated head is this sweep's: {hidden}.\n",
        truth.display(),
        cal.display(),
        scene.range,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rehearsal says the simulated board has a head effect and leaves a plate's out (as
    /// `cta sensor sim --truth` does: with `plate_tilt=0.2` hidden, 40 rehearsal poses read x
    /// 0.0046 in off, 0.6 of a pose's 1-sigma).
    #[test]
    fn the_rehearsal_says_what_becomes_of_the_hidden_effect() {
        for e in ["cell_gain=0.03", "face_angle=1", "proximity=0.2"] {
            assert!(hidden_effect_words(e).contains("included"), "{e}");
        }
        for e in [
            "plate_tilt=0.2",
            "plate_offset=0.05",
            "separation_error=0.05",
            "beacon_tilt=3,45",
        ] {
            let w = hidden_effect_words(e);
            assert!(
                w.contains("the CTA plate's") && w.contains("leaves it out"),
                "{e}: {w}"
            );
        }
    }

    /// `--force` deletes a folder the demo wrote (its README first), and nothing else: not a
    /// folder with the demo's file names but no README, nor one with other files.
    #[test]
    fn only_an_earlier_demos_folder_is_deleted() {
        let d = std::env::temp_dir().join(format!("cta-demo-rm-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(d.join("run")).unwrap();
        std::fs::write(d.join("fit.json"), "mine").unwrap();
        std::fs::write(d.join("nearfield.svg"), "mine").unwrap();
        let e = remove_earlier_demo(&d).unwrap_err().to_string();
        assert!(
            e.contains("not known to be an earlier demo's folder"),
            "{e}"
        );
        std::fs::write(d.join(DEMO_README), "notes").unwrap();
        assert!(remove_earlier_demo(&d).is_err());
        // An older demo's folder: no README.txt, but its report is cta's.
        std::fs::remove_file(d.join(DEMO_README)).unwrap();
        std::fs::create_dir_all(d.join("report")).unwrap();
        std::fs::write(
            d.join("report").join("index.html"),
            "<!doctype html><html><head><meta charset=utf-8><title>cta analyze: x</title>",
        )
        .unwrap();
        remove_earlier_demo(&d).unwrap();
        assert!(!d.exists());
        // An empty folder holds nothing to lose.
        std::fs::create_dir_all(&d).unwrap();
        remove_earlier_demo(&d).unwrap();
        std::fs::create_dir_all(d.join("run")).unwrap();
        std::fs::write(d.join(DEMO_README), format!("{DEMO_README_HEAD}\n")).unwrap();
        std::fs::write(d.join("mine.txt"), "x").unwrap();
        let e = remove_earlier_demo(&d).unwrap_err().to_string();
        assert!(e.contains("(mine.txt)"), "{e}");
        std::fs::remove_file(d.join("mine.txt")).unwrap();
        remove_earlier_demo(&d).unwrap();
        assert!(!d.exists());
    }

    /// The demo's calibrate and analyze steps are the commands' own defaults, as `cta
    /// calibrate` and `cta analyze` would read their command lines.
    #[test]
    fn demo_steps_take_the_commands_defaults() {
        use clap::Parser;
        #[derive(Parser)]
        struct Wrap<B: clap::Args> {
            #[command(flatten)]
            inner: B,
        }
        let (d, c, p, r) = (
            Path::new("run/data.csv"),
            Path::new("cal.json"),
            Path::new("calibration.svg"),
            Path::new("report"),
        );
        let cal = Wrap::<CalibrateArgs>::parse_from([
            "cta",
            "run/data.csv",
            "--out",
            "cal.json",
            "--plot",
            "calibration.svg",
        ]);
        assert_eq!(
            format!("{:?}", cal.inner),
            format!("{:?}", calibrate_args(d, c, p))
        );
        let an = Wrap::<AnalyzeArgs>::parse_from(["cta", "run/data.csv", "--report", "report"]);
        assert_eq!(
            format!("{:?}", an.inner),
            format!("{:?}", analyze_args(d, r))
        );
    }
}
