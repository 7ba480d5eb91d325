//! A bounded mutation test (fault audit, issue 32): measurement files, plans, saved fits and
//! calibrations with bytes changed, inserted, deleted, lines repeated or dropped, cut short,
//! given to the commands that read them. Every run must end with exit status 0 or 1 (no
//! panic, no abort), print no NaN or inf, and on an error name the file.
//!
//! `cargo test -p cta --test mutation` tries 120 runs of the binary, 40 calibrations and 80
//! plans (seconds); `cargo test -p cta --test mutation -- --ignored` 12,000 runs, 4,000
//! calibrations and 8,000 plans (minutes). Each prints the counts it tried.

mod common;

use std::path::Path;
use std::process::Output;

use common::{cta, s, simulate, stderr, tmpdir_of};

/// A small deterministic generator (SplitMix64): the same mutations on every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Text a mutation may put in: what breaks readers (separators, quotes, line breaks, signs,
/// exponents, huge and tiny numbers, non-numbers, a byte that is not UTF-8).
const PIECES: [&[u8]; 18] = [
    b",",
    b"\n",
    b"\r",
    b"\"",
    b"-",
    b"e",
    b"9",
    b"0",
    b".",
    b"#",
    b"NaN",
    b"inf",
    b"1e308",
    b"-1e-320",
    b"99999999999999999999",
    b"\xff",
    b" ",
    b"",
];

/// One mutation of `bytes`.
fn mutate(bytes: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = bytes.to_vec();
    let at = rng.below(b.len());
    match rng.below(6) {
        // Replace a byte.
        0 => {
            let p = PIECES[rng.below(PIECES.len())];
            b.splice(at..(at + 1).min(b.len()), p.iter().copied());
        }
        // Insert.
        1 => {
            let p = PIECES[rng.below(PIECES.len())];
            b.splice(at..at, p.iter().copied());
        }
        // Delete a run of bytes.
        2 => {
            let end = (at + 1 + rng.below(40)).min(b.len());
            b.drain(at..end);
        }
        // Cut short.
        3 => b.truncate(at),
        // Repeat a line.
        4 => {
            let start = b[..at]
                .iter()
                .rposition(|&c| c == b'\n')
                .map_or(0, |k| k + 1);
            let end = b[at..]
                .iter()
                .position(|&c| c == b'\n')
                .map_or(b.len(), |k| at + k + 1);
            let line = b[start..end].to_vec();
            b.splice(end..end, line);
        }
        // A digit run replaced by a number far out of any range.
        _ => {
            let start = at;
            let end = b[start..]
                .iter()
                .position(|c| !c.is_ascii_digit())
                .map_or(b.len(), |k| start + k);
            b.splice(start..end, b"1e300".iter().copied());
        }
    }
    b
}

/// What went wrong with one run, if anything: a panic or a signal, a NaN or inf printed, an
/// error that does not name `file`.
fn fault(o: &Output, file: &Path) -> Option<String> {
    let out = String::from_utf8_lossy(&o.stdout);
    let err = stderr(o);
    match o.status.code() {
        Some(0) | Some(1) => {}
        other => return Some(format!("exit {other:?}: {err}")),
    }
    if err.contains("panicked") {
        return Some(format!("panic: {err}"));
    }
    let words = |t: &str| {
        t.split(|c: char| !(c.is_ascii_alphanumeric() || c == '.'))
            .any(|w| matches!(w, "NaN" | "inf" | "nan"))
    };
    // A value the file holds is quoted in an error (`NaN` is not a finite number): only
    // what the command computed must be free of them.
    if words(&out) {
        return Some(format!("NaN or inf in the output:\n{out}"));
    }
    if !o.status.success() {
        let name = file.file_name().unwrap().to_string_lossy();
        if !err.contains(&*name) {
            return Some(format!("an error that does not name {name}: {err}"));
        }
    }
    None
}

/// Mutate `good` `n` times (written to `path`), run `args` (with `{}` for the path) on each,
/// and return the faults found.
fn campaign(
    good: &[u8],
    path: &Path,
    args: &[&str],
    n: usize,
    rng: &mut Rng,
    faults: &mut Vec<String>,
) -> usize {
    for _ in 0..n {
        let m = mutate(good, rng);
        std::fs::write(path, &m).unwrap();
        let a: Vec<&str> = args
            .iter()
            .map(|&x| if x == "{}" { s(path) } else { x })
            .collect();
        let o = cta(&a);
        if let Some(f) = fault(&o, path) {
            let keep = path.with_extension(format!("fault{}", faults.len()));
            std::fs::write(&keep, &m).unwrap();
            faults.push(format!(
                "cta {}: {f} (kept as {})",
                a.join(" "),
                keep.display()
            ));
        }
    }
    n
}

/// `n` mutations of each kind of file.
fn run(name: &str, n: usize) {
    let d = tmpdir_of("mutation", name);
    let sim = d.join("sim.csv");
    simulate(
        &sim,
        &[
            "--separations",
            "20,25",
            "--grid",
            "4x4",
            "--samples",
            "3",
            "--noise",
            "10",
        ],
    );
    let fit = d.join("fit.json");
    let o = cta(&["fit", s(&sim), "--save", s(&fit)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cal = d.join("cal.json");
    let o = cta(&["sensor", "template", "calibration"]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::write(&cal, &o.stdout).unwrap();
    let mut rng = Rng(32);
    let mut faults = Vec::new();
    let data = std::fs::read(&sim).unwrap();
    let m = d.join("m.csv");
    let mut tried = 0;
    tried += campaign(&data, &m, &["fit", "{}"], n, &mut rng, &mut faults);
    tried += campaign(&data, &m, &["noise", "{}"], n, &mut rng, &mut faults);
    tried += campaign(
        &data,
        &m,
        &["evaluate", s(&fit), "{}"],
        n,
        &mut rng,
        &mut faults,
    );
    tried += campaign(&data, &m, &["analyze", "{}"], n, &mut rng, &mut faults);
    let out = d.join("out-cal.json");
    tried += campaign(
        &data,
        &m,
        &["calibrate", "{}", "--out", s(&out)],
        n,
        &mut rng,
        &mut faults,
    );
    let mf = d.join("m-fit.json");
    tried += campaign(
        &std::fs::read(&fit).unwrap(),
        &mf,
        &["evaluate", "{}", s(&sim)],
        n,
        &mut rng,
        &mut faults,
    );
    // Calibrations and plans, in this process (a calibration is read as `cta sensor
    // load-calibration` reads it, before anything is sent; no board's timing in the way):
    // no panic, and an error names the file.
    let mc = d.join("m-cal.json");
    let good = std::fs::read(&cal).unwrap();
    let mut calibrations = 0;
    for _ in 0..n * 2 {
        std::fs::write(&mc, mutate(&good, &mut rng)).unwrap();
        calibrations += 1;
        let file = s(&mc).to_string();
        match std::panic::catch_unwind(|| {
            cta_lab::boards::files::read_json::<cta_core::pose::Calibration>(&file)
        }) {
            Err(_) => faults.push(format!("reading a calibration panicked: {}", mc.display())),
            Ok(Err(e)) if !e.to_string().contains("m-cal.json") => faults.push(format!(
                "a calibration error that does not name its file: {e}"
            )),
            Ok(_) => {}
        }
    }
    // Plans, in this process: no panic, and an error names the file.
    let plan = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/plans/short.toml")).unwrap();
    let mut plans = 0;
    for _ in 0..n * 4 {
        let m = mutate(&plan, &mut rng);
        let text = String::from_utf8_lossy(&m).into_owned();
        plans += 1;
        match std::panic::catch_unwind(|| cta_lab::sweep::plan::Plan::parse("m.toml", &text)) {
            Err(_) => faults.push(format!("plan parse panicked on:\n{text}")),
            Ok(Err(e)) if !e.to_string().starts_with("m.toml") => {
                faults.push(format!("a plan error that does not name its file: {e}"))
            }
            Ok(_) => {}
        }
    }
    eprintln!(
        "mutation: {tried} runs of the cta binary on mutated measurement files and fits, \
         {calibrations} mutated calibrations read, {plans} mutated plans parsed: {} faults",
        faults.len()
    );
    assert!(faults.is_empty(), "{}", faults.join("\n\n"));
}

#[test]
fn mutated_files_are_read_or_refused_by_name_without_a_panic_or_nan() {
    run("bounded", 20);
}

#[test]
#[ignore = "thousands of mutations: minutes; run with --ignored"]
fn many_mutated_files() {
    run("long", 2000);
}
