//! The load-time warnings: values that read without error but do not look like the CTA in
//! inches (millimetres, a beacon off its plate, a separation typo, glitches).

use std::collections::BTreeMap;

use super::{Dataset, Sample, FAR_SEPARATION_IN, SEP_TYPO_IN, SEP_TYPO_RATIO};

impl Dataset {
    /// Warnings about values that read without error but do not look like the CTA in
    /// inches: separations beyond [`FAR_SEPARATION_IN`] (a file in millimetres?), and beacons
    /// far from the plate (`beacon_z_in` given from the plate, not in N), and glitches: samples
    /// far beyond the noise from their point's median ([`Dataset::glitches`]). Each names the
    /// file and its first line(s); every analysis command prints them before its results.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        let file = self.path.display();
        if let Some(s) = self
            .samples
            .iter()
            .find(|s| s.separation_in > FAR_SEPARATION_IN)
        {
            let max = self
                .separations()
                .last()
                .copied()
                .unwrap_or(s.separation_in);
            w.push(format!(
                "{file}:{}: separation_in {} in (the file's largest {max} in), far beyond the \
                 CTA's 0-30 in: is the file in millimetres (divide by 25.4) or centimetres (by \
                 2.54)? Every length column is in inches",
                s.line, s.separation_in
            ));
        }
        let off: Vec<&Sample> = self
            .samples
            .iter()
            .filter(|s| (s.r[2] - s.separation_in).abs() > (0.25 * s.separation_in).max(1.0))
            .collect();
        if let Some(s) = off.first() {
            w.push(format!(
                "{file}:{}: beacon_z_in {} in with separation_in {} in ({} of {} rows like \
                 it): beacon positions are in the sensor-board frame N, so on the CTA \
                 beacon_z_in is the plate's separation, not 0",
                s.line,
                s.r[2],
                s.separation_in,
                off.len(),
                self.samples.len()
            ));
        }
        if let Some(t) = self.separation_typos() {
            w.push(t);
        }
        if let Some(g) = self.glitches().warning(&self.path, self.samples.len()) {
            w.push(g);
        }
        w
    }

    /// The warning (without `warning: `) on separations that look like typos of another: a
    /// value within [`SEP_TYPO_IN`] of one with at least [`SEP_TYPO_RATIO`] times its rows
    /// (`2.0001` on one row beside `2` on 99). One plate position records one value
    /// (MEASUREMENTS.md), so such rows make a separation of their own, which `--separations`
    /// then never selects (it takes the nearest). Names the values and their lines.
    fn separation_typos(&self) -> Option<String> {
        // Each separation's rows and first lines, ascending.
        let mut by: BTreeMap<u64, (usize, Vec<usize>)> = BTreeMap::new();
        for s in &self.samples {
            let e = by.entry(s.separation_in.to_bits()).or_default();
            e.0 += 1;
            if e.1.len() < 5 {
                e.1.push(s.line);
            }
        }
        // Positive numbers sort as their bits do.
        let seps: Vec<(f64, usize, Vec<usize>)> = by
            .into_iter()
            .map(|(b, (n, lines))| (f64::from_bits(b), n, lines))
            .collect();
        let rows = |n: usize| format!("{n} row{}", if n == 1 { "" } else { "s" });
        let mut odd: Vec<(usize, String)> = Vec::new();
        for (i, (v, n, lines)) in seps.iter().enumerate() {
            let lo = seps[..i].iter().rev();
            let hi = seps[i + 1..].iter();
            let beside = lo
                .take_while(|o| v - o.0 < SEP_TYPO_IN)
                .chain(hi.take_while(|o| o.0 - v < SEP_TYPO_IN))
                .filter(|o| o.1 >= SEP_TYPO_RATIO * n)
                .max_by_key(|o| o.1);
            if let Some((b, m, _)) = beside {
                let shown: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
                odd.push((
                    lines[0],
                    format!(
                        "separation_in {v} on {} (line{} {}{}) beside {b} on {}",
                        rows(*n),
                        if *n == 1 { "" } else { "s" },
                        shown.join(", "),
                        if *n > lines.len() { ", ..." } else { "" },
                        rows(*m)
                    ),
                ));
            }
        }
        let (first, _) = *odd.iter().min_by_key(|o| o.0)?;
        let n = odd.len();
        let listed: Vec<String> = odd.into_iter().take(5).map(|o| o.1).collect();
        Some(format!(
            "{}:{first}: {}{}: within {SEP_TYPO_IN} in of a separation with at least \
             {SEP_TYPO_RATIO} times the rows, closer than two plate positions can be told apart. \
             One plate position records one value of separation_in (a sweep writes the mean of \
             its corner readings on every row), so these rows make a separation of their own, \
             which --separations never selects: a typo? Correct them to the value beside them (a plate \
             placed again within one separation, as a resumed sweep may do, reads a little \
             differently: then they are real, and the warning can be ignored)",
            self.path.display(),
            listed.join("; "),
            if n > 5 {
                format!("; and {} more", n - 5)
            } else {
                String::new()
            },
        ))
    }
}
