//! Reading the files `cta` is given with a bound on their size and on a line's length: a
//! wrong path (`/dev/zero`, a disk image, a log that never ends) is refused with the limit
//! named instead of read until memory runs out. The limits are far above any real file.

use std::io::{BufRead, Read};
use std::path::Path;

/// The longest line of a measurement file: a row is under 200 bytes, a comment a sentence.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// The largest measurement file: a full sweep of every key of a plan writes tens of MB.
pub const MAX_CSV_BYTES: u64 = 1 << 30;

/// The largest JSON file (a saved fit, a calibration, a constellation, a budget, a truth
/// sidecar): the largest `cta` writes is a few MB.
pub const MAX_JSON_BYTES: u64 = 64 << 20;

/// The largest plan file: a plan is a page of `key = value` lines.
pub const MAX_PLAN_BYTES: u64 = 1 << 20;

/// `n` bytes in words: `64 KiB`, `1 GiB`.
pub fn show_bytes(n: u64) -> String {
    for (unit, name) in [(1u64 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")] {
        if n >= unit && n.is_multiple_of(unit) {
            return format!("{} {name}", n / unit);
        }
    }
    format!("{n} bytes")
}

/// The whole of the text file at `path`, refused (an `InvalidData` error saying so) when it
/// holds more than `limit` bytes or is not UTF-8. `what` names the kind of file in the
/// message ("a JSON file", "a plan").
pub fn read_text(path: &Path, limit: u64, what: &str) -> std::io::Result<String> {
    let f = std::fs::File::open(path)?;
    let mut bytes = Vec::new();
    f.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_big(limit, what));
    }
    String::from_utf8(bytes).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "not UTF-8 text (byte {} is not; a binary file?)",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// The error of a file over `limit` bytes.
pub fn too_big(limit: u64, what: &str) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::InvalidData,
        format!(
            "larger than {} (the limit for {what}, far above any real one): the wrong file?",
            show_bytes(limit)
        ),
    )
}

/// One line read by [`read_line`].
#[derive(Debug, PartialEq)]
pub enum Line {
    /// The end of the input: nothing more was read.
    End,
    /// A line, in the buffer with its line break (none on a last line without one).
    Read,
    /// More than the limit without a line break: the buffer holds the limit's worth.
    TooLong,
}

/// Read one line into `out` (cleared first): up to and including its `\n`, `\r\n`, or a `\r`
/// alone (the line break of old Mac files), but no more than `max` bytes before the break.
pub fn read_line(r: &mut impl BufRead, out: &mut Vec<u8>, max: usize) -> std::io::Result<Line> {
    out.clear();
    loop {
        let buf = r.fill_buf()?;
        if buf.is_empty() {
            return Ok(if out.is_empty() {
                Line::End
            } else {
                Line::Read
            });
        }
        let brk = buf.iter().position(|&b| b == b'\n' || b == b'\r');
        let take = brk.map_or(buf.len(), |k| k + 1);
        let content = out.len() + brk.unwrap_or(take);
        if content > max {
            let room = max.saturating_sub(out.len()).min(take);
            out.extend_from_slice(&buf[..room]);
            r.consume(room);
            return Ok(Line::TooLong);
        }
        out.extend_from_slice(&buf[..take]);
        r.consume(take);
        if brk.is_some() {
            if out.last() == Some(&b'\r') && r.fill_buf()?.first() == Some(&b'\n') {
                out.push(b'\n');
                r.consume(1);
            }
            return Ok(Line::Read);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(input: &[u8], max: usize) -> Vec<(Line, Vec<u8>)> {
        // A one-byte buffer: every line break falls on a buffer's edge somewhere.
        let mut r = std::io::BufReader::with_capacity(1, input);
        let mut out = Vec::new();
        let mut v = Vec::new();
        loop {
            let l = read_line(&mut r, &mut out, max).unwrap();
            if l == Line::End {
                return v;
            }
            let stop = l == Line::TooLong;
            v.push((l, out.clone()));
            if stop {
                return v;
            }
        }
    }

    /// `\n`, `\r\n` and `\r` alone each end one line; a line over the limit stops the reading
    /// at the limit.
    #[test]
    fn every_line_break_ends_a_line_and_a_long_line_is_cut_at_the_limit() {
        let got = lines(b"a\nbb\r\ncc\rd", 8);
        let want: Vec<(Line, Vec<u8>)> = vec![
            (Line::Read, b"a\n".to_vec()),
            (Line::Read, b"bb\r\n".to_vec()),
            (Line::Read, b"cc\r".to_vec()),
            (Line::Read, b"d".to_vec()),
        ];
        assert_eq!(got, want);
        let got = lines(b"12345678\n123456789\n", 8);
        assert_eq!(got[0], (Line::Read, b"12345678\n".to_vec()));
        assert_eq!(got[1], (Line::TooLong, b"12345678".to_vec()));
        assert_eq!(lines(&[0u8; 100_000], 10)[0].0, Line::TooLong);
    }

    #[test]
    fn a_file_over_its_limit_is_refused_naming_the_limit() {
        let d = std::env::temp_dir().join(format!("cta-bounded-{}", std::process::id()));
        std::fs::write(&d, "x".repeat(2049)).unwrap();
        let e = read_text(&d, 2048, "a plan").unwrap_err().to_string();
        assert!(
            e.contains("larger than 2 KiB") && e.contains("a plan"),
            "{e}"
        );
        assert_eq!(read_text(&d, 4096, "a plan").unwrap().len(), 2049);
        let _ = std::fs::remove_file(&d);
        let e = read_text(Path::new("/dev/zero"), 1 << 20, "a JSON file")
            .unwrap_err()
            .to_string();
        assert!(e.contains("1 MiB"), "{e}");
    }
}
