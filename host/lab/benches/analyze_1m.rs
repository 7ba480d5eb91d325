//! Performance target of issue 3: `cta analyze` on 1,000,000 samples (29 separations x 100
//! beacons x 345 samples) in under 10 s on the 2-core build machine, with a progress bar.
//!
//! Run (release, as shipped):
//!
//! ```text
//! cargo bench -p cta-lab --bench analyze_1m
//! ```
//!
//! It simulates the file first (thesis physics, noise 32.8 counts, a hidden `cell_gain`;
//! not timed), writes it as CSV to the temp folder, then times what a user waits for:
//! reading the CSV and the whole analysis (forward selection with cross-validation), and
//! prints the time and the verdict. `CTA_BENCH_EFFECT=crosstalk=0.03` (any `--effect` value)
//! times another hidden effect (cross-talk is the slow case: nothing fits, fits iterate
//! longest). The same measurement from the command line:
//!
//! ```text
//! cta simulate --out /tmp/m1.csv --separations 2..30 --noise 32.8 --samples 345 --effect cell_gain=0.03,-0.02
//! time cta analyze /tmp/m1.csv
//! ```

use cta_lab::analyze::{analyze, Options};
use cta_lab::data::Dataset;
use cta_lab::progress::Progress;
use cta_lab::sim::effects::Effect;
use cta_lab::sim::SimConfig;
use std::time::Instant;

/// The spinner `cta analyze` draws: the fits so far and what was fitted last.
struct Spinner(indicatif::ProgressBar);

impl Progress for Spinner {
    fn position(&self, done: u64, _total: u64) {
        self.0.set_position(done);
    }

    fn message(&self, what: &str) {
        self.0.set_message(what.to_string());
    }
}

fn main() -> anyhow::Result<()> {
    let cfg = SimConfig {
        separations: (2..=30).map(f64::from).collect(),
        noise: 32.768,
        samples: 345,
        seed: 1,
        effects: vec![Effect::parse(
            &std::env::var("CTA_BENCH_EFFECT").unwrap_or_else(|_| "cell_gain=0.03,-0.02".into()),
        )
        .map_err(anyhow::Error::msg)?],
        ..Default::default()
    };
    let (ds, _) = cfg.run();
    let path = std::env::temp_dir().join("cta_analyze_1m.csv");
    {
        let mut w = std::io::BufWriter::new(std::fs::File::create(&path)?);
        ds.write(&mut w, &["cta bench analyze_1m".into()])?;
    }
    eprintln!("{} samples written to {}", ds.samples.len(), path.display());
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_style(indicatif::ProgressStyle::with_template(
        "{spinner} [{elapsed_precise}] {pos} fits  {msg}",
    )?);
    bar.enable_steady_tick(std::time::Duration::from_millis(120));
    let t0 = Instant::now();
    bar.set_message("reading");
    let ds = Dataset::read(&path).map_err(anyhow::Error::msg)?;
    let t_read = t0.elapsed();
    let bar = Spinner(bar);
    let a = analyze(&ds, &Options::default(), &bar)?;
    let t = t0.elapsed();
    bar.0.finish_and_clear();
    println!(
        "analyze_1m: {} samples, {} points: read {:.2} s, total {:.2} s (target < 10 s) on {} threads",
        a.samples,
        a.points,
        t_read.as_secs_f64(),
        t.as_secs_f64(),
        rayon::current_num_threads()
    );
    println!("verdict: {}", a.verdict);
    std::fs::remove_file(&path).ok();
    if t.as_secs_f64() >= 10.0 {
        eprintln!("analyze_1m: over the 10 s target");
        std::process::exit(1);
    }
    Ok(())
}
