//! Journal lines a resume can check. Each line of `journal.jsonl` ends with `"chain"`: a hash
//! (FNV-1a 64) of the line and of the chain of the line before it. A line edited, copied,
//! moved or removed breaks the chain at the next line, so a forged `point` line (a copy of
//! the last one with its index raised, which would make the run "complete" without that
//! point's rows) is refused instead of believed; the points must also follow each other, each
//! ending past where the point before left the data file. Journals of older
//! versions, without chains, still load; once a line has its chain, every later line must.
//!
//! What a resume finds past the last committed point is never deleted: the decision of
//! what to keep aside and when a manifest that says more was done than the journal commits is
//! refused is here too ([`contradiction`]).

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

use super::error::{bail, Context, Result};

use super::event::Event;
use super::layout::{DATA, DATA_TAIL, JOURNAL, JOURNAL_TAIL, MANIFEST};

/// The chain before a journal's first line.
pub(crate) const START: u64 = 0xcbf2_9ce4_8422_2325;

/// The key the chain is written under, as the last field of each line.
const KEY: &str = ",\"chain\":\"";

/// FNV-1a 64 of `bytes`, continuing from `h`.
fn fnv(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The chain of the line whose JSON (without its chain) is `json`, after a line of chain
/// `prev`.
fn link(prev: u64, json: &[u8]) -> u64 {
    fnv(fnv(START, &prev.to_le_bytes()), json)
}

/// The journal line for `json` (one event: a JSON object, `{...}`, no line break) after a
/// line of chain `prev`: the object with its `chain` as last field, and a line break; and
/// the new chain.
pub(crate) fn seal(prev: u64, json: &str) -> (String, u64) {
    let h = link(prev, json.as_bytes());
    let body = json.strip_suffix('}').unwrap_or(json);
    (format!("{body}{KEY}{h:016x}\"}}\n"), h)
}

/// [`seal`] each line of `lines` (whole lines, each ending with a line break) in turn, from
/// `prev`: the bytes to write and the chain after the last.
pub(crate) fn seal_lines(prev: u64, lines: &[u8]) -> (Vec<u8>, u64) {
    let mut out = Vec::with_capacity(lines.len() + 40);
    let mut h = prev;
    for l in lines.split(|&b| b == b'\n').filter(|l| !l.is_empty()) {
        let (line, next) = seal(h, &String::from_utf8_lossy(l));
        out.extend_from_slice(line.as_bytes());
        h = next;
    }
    (out, h)
}

/// The JSON of one journal line (`line`, without its line break) once its chain is checked
/// against `prev`; and the chain after it (`prev` for a line of an older version, which has
/// none: accepted only while no line before had one, `sealed` false). `at` names the line in
/// errors.
pub(crate) fn check(
    prev: u64,
    sealed: bool,
    line: &[u8],
    at: &str,
) -> Result<(Vec<u8>, u64, bool)> {
    let line = line.trim_ascii_end();
    let k = KEY.len();
    let hex_end = line.len().saturating_sub(2);
    let has = line.len() >= k + 18
        && line.ends_with(b"\"}")
        && &line[hex_end - 16 - k..hex_end - 16] == KEY.as_bytes();
    if !has {
        if sealed {
            bail!(
                "{at}: a journal line without its check (`chain`) after lines that have one: \
                 added or edited by hand, or written by another program. Not resuming, nothing \
                 was changed: restore {JOURNAL} as the sweep wrote it, or start a new run with \
                 --out"
            );
        }
        return Ok((line.to_vec(), prev, false));
    }
    let hex = std::str::from_utf8(&line[hex_end - 16..hex_end]).ok();
    let given = hex.and_then(|h| u64::from_str_radix(h, 16).ok());
    let mut json = line[..hex_end - 16 - k].to_vec();
    json.push(b'}');
    let h = link(prev, &json);
    if given != Some(h) {
        bail!(
            "{at}: the journal line's check (`chain`) does not match: the line was edited, \
             copied or moved, or a line before it was removed or changed (the sweep never \
             writes such a line). Not resuming, nothing was changed: restore {JOURNAL} as the \
             sweep wrote it, or start a new run with --out"
        );
    }
    Ok((json, h, true))
}

/// A journal as read by a resume ([`read`]).
pub(crate) struct Read {
    /// Its events.
    pub events: Vec<Event>,
    /// The length of its whole lines (a torn last line left out).
    pub good_len: u64,
    /// Its length after each event's line.
    pub line_ends: Vec<u64>,
    /// The chain after each event's line.
    pub chains: Vec<u64>,
    /// The chain after its last whole line.
    pub chain: u64,
}

/// Read the journal `jp` for a resume: every whole line checked ([`check`]) and parsed, the
/// points checked ([`check_points`]); a torn last line (the process died mid-write) is left
/// out, with a note in `notes`.
pub(crate) fn read(jp: &Path, notes: &mut Vec<String>) -> Result<Read> {
    let f = File::open(jp).with_context(|| format!("{}: cannot open", jp.display()))?;
    let mut r = BufReader::new(f);
    let mut out = Read {
        events: Vec::new(),
        good_len: 0,
        line_ends: Vec::new(),
        chains: Vec::new(),
        chain: START,
    };
    let mut lines = Vec::new();
    let mut sealed = false;
    let mut line = Vec::new();
    let mut lineno = 0;
    loop {
        line.clear();
        let n = r
            .read_until(b'\n', &mut line)
            .with_context(|| format!("{}: cannot read", jp.display()))?;
        if n == 0 {
            break;
        }
        lineno += 1;
        if !line.ends_with(b"\n") {
            notes.push(format!(
                "{JOURNAL}: dropped its torn last line ({n} bytes), which the previous session \
                 was writing when it stopped"
            ));
            break;
        }
        let at = format!("{}:{lineno}", jp.display());
        let (json, next, now_sealed) = check(out.chain, sealed, &line, &at)?;
        match serde_json::from_slice::<Event>(&json) {
            Ok(e) => out.events.push(e),
            Err(e) => bail!("{at}: unreadable journal entry: {e}"),
        }
        (out.chain, sealed) = (next, now_sealed);
        out.good_len += n as u64;
        out.line_ends.push(out.good_len);
        out.chains.push(out.chain);
        lines.push(lineno);
    }
    check_points(&out.events, &lines, jp)?;
    Ok(out)
}

/// The points of a journal must follow each other (0, 1, 2, ...; a recovery or a crash cuts
/// the journal back, never leaves a gap or a repeat) and each must end later in the data
/// file than the one before (every point writes its rows or a comment line): otherwise the
/// journal would have a point "committed" whose rows are not in the data file. `lines` gives each event's line number.
pub(crate) fn check_points(events: &[Event], lines: &[usize], path: &Path) -> Result<()> {
    let mut prev: Option<(usize, u64)> = None;
    for (e, line) in events.iter().zip(lines) {
        let Event::Point { i, csv_end, .. } = e else {
            continue;
        };
        let want = prev.map_or(0, |(p, _)| p + 1);
        let before = prev.map_or(0, |(_, e)| e);
        if *i != want || (prev.is_some() && *csv_end <= before) {
            bail!(
                "{}:{line}: point {i}, {}: the journal's points must follow each other, each \
                 ending past where the one before left {DATA} (a line copied or edited?). \
                 Not resuming, nothing was changed: restore {JOURNAL} as the sweep wrote it, or \
                 start a new run with --out",
                path.display(),
                if *i != want {
                    format!("where point {want} belongs")
                } else {
                    format!(
                        "ending at byte {csv_end} of {DATA}, where point {} ended at {before}",
                        i - 1
                    )
                }
            );
        }
        prev = Some((*i, *csv_end));
    }
    Ok(())
}

/// `manifest.json` in `dir`, when it reads as JSON.
fn manifest(dir: &Path) -> Option<serde_json::Value> {
    let text = crate::bounded::read_text(
        &dir.join(MANIFEST),
        crate::bounded::MAX_JSON_BYTES,
        "a manifest",
    )
    .ok()?;
    serde_json::from_str(&text).ok()
}

/// Whether the data file `dp` holds, in its first bytes, what the manifest `m` recorded of
/// it through the last point it saw committed (`data.bytes`, `data.hash`: FNV-1a 64, as the
/// journal's `csv_hash`). `None` when the manifest records nothing (an older version).
fn data_as_recorded(m: &serde_json::Value, dp: &Path) -> Option<(u64, bool)> {
    let bytes = m["data"]["bytes"].as_u64()?;
    let hash = m["data"]["hash"].as_str()?;
    let f = File::open(dp).ok()?;
    let mut r = BufReader::new(std::io::Read::take(f, bytes));
    let (mut h, mut n) = (START, 0u64);
    loop {
        let buf = r.fill_buf().ok()?;
        if buf.is_empty() {
            break;
        }
        h = fnv(h, buf);
        n += buf.len() as u64;
        let k = buf.len();
        r.consume(k);
    }
    Some((bytes, n == bytes && format!("{h:016x}") == hash))
}

/// When the manifest says more points were done than the journal commits (`next`, one past
/// its last point), the journal lost lines the manifest saw (cut short, an older copy put
/// back): resuming would measure those points again and cut their rows from the data file.
/// The refusal says so; with `recover` (`--recover-truncated`) the resume goes ahead: the
/// note to say, and the folder the `past` bytes of the data file beyond the journal's last
/// point (and a torn journal line) are moved to.
pub(crate) fn contradiction(
    dir: &Path,
    events: &[Event],
    next: usize,
    recover: bool,
    past: u64,
) -> Result<Option<(String, PathBuf)>> {
    let Some(m) = manifest(dir) else {
        return Ok(None);
    };
    let Some(done) = m["points"]["done"].as_u64() else {
        return Ok(None);
    };
    if done <= next as u64 {
        return Ok(None);
    }
    let (mp, jp) = (dir.join(MANIFEST), dir.join(JOURNAL));
    let folder = super::layout::recovery_folder(dir);
    let checked = match data_as_recorded(&m, &dir.join(DATA)) {
        Some((bytes, true)) => format!(
            "; {DATA}'s first {bytes} bytes are as the manifest recorded them (checked against \
             its hash): the rows of points {next} to {} are whole in it",
            done - 1
        ),
        Some((bytes, false)) => format!(
            "; {DATA}'s first {bytes} bytes are not as the manifest recorded them (its hash \
             differs)"
        ),
        None => String::new(),
    };
    let said = format!(
        "{} says {done} points were done, but {} commits {next} (the journal lost its last \
         lines: cut short, or an older copy put back){checked}",
        mp.display(),
        jp.display()
    );
    if !recover {
        let ports = super::last_session_ports(events);
        bail!(
            "{said}. Resuming would measure points {next} to {} again and cut their rows from \
             {DATA}. Not resuming, nothing was changed: put back the journal that goes with the \
             manifest, if you have it, and resume as usual; or continue from point {next} with \
             `{} --recover-truncated`, which keeps the bytes of {DATA} past point {} and the \
             journal's torn last line aside in {} and measures those points again",
            done - 1,
            super::resume_command(dir, ports.as_ref().map(|(b, s)| (b.as_str(), s.as_str()))),
            next.saturating_sub(1),
            folder.display()
        );
    }
    let note = format!(
        "{said}: --recover-truncated: resuming at point {next}; moved to {}: {DATA}'s {past} \
         bytes past the last committed point ({DATA_TAIL}) and the journal's torn last line, if \
         any ({JOURNAL_TAIL})",
        folder.display()
    );
    Ok(Some((note, folder)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sealed line checks; the same line after another line, or with one byte changed,
    /// does not; an unsealed line is accepted only before the first sealed one.
    #[test]
    fn a_line_checks_only_in_its_place_and_as_written() {
        let a = r#"{"event":"point","i":0,"csv_end":10}"#;
        let b = r#"{"event":"point","i":1,"csv_end":20}"#;
        let (la, ha) = seal(START, a);
        let (lb, hb) = seal(ha, b);
        assert!(la.ends_with("\"}\n") && la.contains("\"chain\":\""), "{la}");
        let (json, h, sealed) = check(START, false, la.as_bytes(), "j:1").unwrap();
        assert_eq!((json.as_slice(), h, sealed), (a.as_bytes(), ha, true));
        assert_eq!(check(ha, true, lb.as_bytes(), "j:2").unwrap().1, hb);
        // The last line copied after itself, its index raised: its chain is the old one's.
        let forged = lb.replace("\"i\":1", "\"i\":2");
        let e = check(hb, true, forged.as_bytes(), "j:3")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("j:3: the journal line's check"), "{e}");
        // A line copied verbatim: its chain follows the wrong line.
        assert!(check(hb, true, lb.as_bytes(), "j:3").is_err());
        // An older journal's line: accepted before any sealed line, refused after one.
        assert_eq!(check(START, false, a.as_bytes(), "j:1").unwrap().1, START);
        let e = check(ha, true, a.as_bytes(), "j:2")
            .unwrap_err()
            .to_string();
        assert!(e.contains("without its check"), "{e}");
        let (bytes, h) = seal_lines(START, format!("{a}\n{b}\n").as_bytes());
        assert_eq!(
            (String::from_utf8(bytes).unwrap(), h),
            (format!("{la}{lb}"), hb)
        );
    }
}
