//! Grouped plans: which beacons a sweep point lights together, each at its own frequency.
//!
//! The NorthStar tells spots apart by their modulation frequency alone and reports up to 20
//! of them per frame, so a frame can carry one spot per frequency of the table. A plan with
//! `group = N` lights up to N beacons at once, each at a different frequency of its
//! `frequencies_hz`. The schedule of one plate position, power level and sensitivity (a
//! *block*) is built from the plan alone, the same in every block, so a point's index still
//! identifies it across a resume:
//!
//! * Round 0's groups are filled greedily, each beacon joining the group whose nearest member
//!   is farthest from it on the array, so a group's spots are spread over the detector's
//!   field. A group's members take the slots `0, 1, ...` in the order of their place on the
//!   array (row, then column): the groups are the rows of a matrix whose columns are slots.
//! * Round `r` keeps the columns and turns each by a shift: group `k` takes slot `j`'s member
//!   of round-0 group `k + s(r, j)`. Slot 0 never turns and slot 1 turns by `r`, so a beacon's
//!   group-mates change from round to round; the other slots turn by whichever shift keeps
//!   their members farthest from the group's, so groups stay spread.
//! * The member in slot `j` is lit at frequency `(j + r) mod F` in round `r`: one frequency per
//!   slot, so no two LEDs of a group share one, and over `frequencies_per_beacon` rounds (at
//!   most `F`) a beacon meets that many different frequencies, all of them when the plan asks
//!   for every one.

use std::sync::{Arc, OnceLock};

use cta_core::emulator::grid_position;

/// One beacon of a group: indices into the plan's `beacons` and `frequencies_hz`.
pub type Member = (usize, usize);

/// The groups of every round of a block: `rounds[r][g]` is group `g` of round `r`. Every
/// round has the same number of groups.
pub type Rounds = Vec<Vec<Vec<Member>>>;

/// A grouped plan's rounds, built once from the plan's keys and shared by its clones. Derived
/// data: two caches always compare equal, and none is serialized.
#[derive(Clone, Default)]
pub struct Cached(pub(crate) Arc<OnceLock<Rounds>>);

impl PartialEq for Cached {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for Cached {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Cached")
    }
}

/// Build the rounds of a block for `beacons` (LED ids on the 10 x 10 array), `n_freqs`
/// frequencies, groups of at most `group` beacons and `rounds` rounds. Requires
/// `1 <= group <= n_freqs` and `1 <= rounds <= n_freqs`.
pub fn build(beacons: &[u8], n_freqs: usize, group: usize, rounds: usize) -> Rounds {
    let nb = beacons.len();
    assert!(
        nb > 0 && (1..=n_freqs).contains(&group) && (1..=n_freqs).contains(&rounds),
        "checked by the plan"
    );
    let n_groups = nb.div_ceil(group);
    let dist = |a: usize, b: usize| distance(beacons[a], beacons[b]);
    let mut rows = lattice(beacons, n_groups, group).unwrap_or_else(|| spread(beacons, n_groups));
    for row in &mut rows {
        row.sort_by_key(|&b| {
            let (x, y) = place(beacons[b]);
            ((y * 10.0).round() as i64, (x * 10.0).round() as i64)
        });
    }
    let slots = rows.iter().map(Vec::len).max().unwrap_or(0);
    let member = |g: usize, j: usize| rows[g % n_groups].get(j).copied();
    (0..rounds)
        .map(|r| {
            let mut groups: Vec<Vec<Member>> = vec![Vec::new(); n_groups];
            for j in 0..slots {
                let shift = match j {
                    0 => 0,
                    1 => r % n_groups,
                    // The shift whose members stand farthest from their new groups.
                    _ => {
                        (0..n_groups)
                            .map(|s| {
                                let worst = (0..n_groups)
                                    .filter_map(|k| {
                                        let b = member(k + s, j)?;
                                        Some(
                                            groups[k]
                                                .iter()
                                                .map(|&(m, _)| dist(m, b))
                                                .fold(f64::INFINITY, f64::min),
                                        )
                                    })
                                    .fold(f64::INFINITY, f64::min);
                                (s, worst)
                            })
                            .fold(
                                (0, f64::NEG_INFINITY),
                                |best, c| {
                                    if c.1 > best.1 {
                                        c
                                    } else {
                                        best
                                    }
                                },
                            )
                            .0
                    }
                };
                for (k, g) in groups.iter_mut().enumerate() {
                    if let Some(b) = member(k + shift, j) {
                        g.push((b, (j + r) % n_freqs));
                    }
                }
            }
            groups.retain(|g| !g.is_empty());
            groups
        })
        .collect()
}

/// Round 0's groups as cosets of a lattice on the array: beacon (x, y) in group
/// `(x + a y) mod G`, for the slope `a` that keeps the members of a group farthest apart
/// (on a full 10 x 10 array in 5 groups, `a = 2`: every member at least a knight's move,
/// sqrt(5) pitches, from the others). `None` when no slope gives `n_groups` groups of at
/// most `group` beacons (a plan of a few scattered beacons).
fn lattice(beacons: &[u8], n_groups: usize, group: usize) -> Option<Vec<Vec<usize>>> {
    let mut best: Option<(f64, Vec<Vec<usize>>)> = None;
    for a in 0..n_groups {
        let mut rows: Vec<Vec<usize>> = vec![Vec::new(); n_groups];
        for (b, &led) in beacons.iter().enumerate() {
            let (x, y) = (led as usize % 10, led as usize / 10);
            rows[(x + a * y) % n_groups].push(b);
        }
        if rows.iter().any(|r| r.is_empty() || r.len() > group) {
            continue;
        }
        let closest = rows
            .iter()
            .flat_map(|r| {
                r.iter().enumerate().flat_map(move |(i, &p)| {
                    r[..i]
                        .iter()
                        .map(move |&q| distance(beacons[p], beacons[q]))
                })
            })
            .fold(f64::INFINITY, f64::min);
        if best.as_ref().is_none_or(|(d, _)| closest > *d) {
            best = Some((closest, rows));
        }
    }
    best.map(|(_, rows)| rows)
}

/// Round 0's groups, greedily: balanced sizes, spread.
fn spread(beacons: &[u8], n_groups: usize) -> Vec<Vec<usize>> {
    let nb = beacons.len();
    let dist = |a: usize, b: usize| distance(beacons[a], beacons[b]);
    // Round 0: groups of balanced sizes, spread. The beacon placed next is the one whose
    // best group (the one whose nearest member is farthest from it) is worst: the most
    // constrained first, so that the last beacons are not left with only close company.
    let room = |g: usize| nb / n_groups + usize::from(g < nb % n_groups);
    let mut rows: Vec<Vec<usize>> = vec![Vec::new(); n_groups];
    let mut left: Vec<usize> = (0..nb).collect();
    while !left.is_empty() {
        let mut pick: Option<(f64, usize, usize)> = None; // (distance, index in left, group)
        for (li, &b) in left.iter().enumerate() {
            let mut best: Option<(f64, usize)> = None;
            for (g, members) in rows.iter().enumerate() {
                if members.len() >= room(g) {
                    continue;
                }
                let nearest = members
                    .iter()
                    .map(|&m| dist(m, b))
                    .fold(f64::INFINITY, f64::min);
                if best.is_none_or(|(d, _)| nearest > d) {
                    best = Some((nearest, g));
                }
            }
            let (d, g) = best.expect("the groups hold every beacon");
            if pick.is_none_or(|(pd, _, _)| d < pd) {
                pick = Some((d, li, g));
            }
        }
        let (_, li, g) = pick.expect("a beacon is left");
        rows[g].push(left.remove(li));
    }
    rows
}

/// Distance between two LEDs on the array, in pitches.
fn distance(a: u8, b: u8) -> f64 {
    let ((ax, ay), (bx, by)) = (place(a), place(b));
    (ax - bx).hypot(ay - by)
}

/// A beacon's place on its array, in LED pitches.
fn place(led: u8) -> (f64, f64) {
    let g = grid_position(10, 1.0, 1.0, led as usize);
    (g.x, g.y)
}

/// The frequency (index into the plan's list) beacon `b` has in round 0.
pub fn first_frequency(rounds: &Rounds, b: usize) -> usize {
    rounds[0]
        .iter()
        .flatten()
        .find(|&&(m, _)| m == b)
        .map_or(0, |&(_, f)| f)
}

/// The beacons (indices into the plan's list) measured alone at separation `sep_idx` by a
/// crosstalk check of `n` beacons: spread over the list, and different from one separation
/// to the next.
pub fn checked(n_beacons: usize, n: usize, sep_idx: usize) -> Vec<usize> {
    let mut out: Vec<usize> = Vec::with_capacity(n);
    for m in 0..n.min(n_beacons) {
        let mut b = (m * n_beacons / n + sep_idx * 7) % n_beacons;
        while out.contains(&b) {
            b = (b + 1) % n_beacons;
        }
        out.push(b);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    fn all() -> Vec<u8> {
        (0..100).collect()
    }

    /// Every beacon once per round; no frequency twice in a group; each beacon meets as many
    /// different frequencies as there are rounds.
    #[test]
    fn every_beacon_once_per_round_at_a_new_frequency() {
        for (nb, nf, group, rounds) in [
            (100, 20, 20, 3),
            (100, 20, 20, 20),
            (100, 20, 10, 4),
            (100, 3, 3, 3),
            (37, 5, 4, 5),
            (100, 19, 19, 3),
            (3, 20, 20, 2),
        ] {
            let beacons: Vec<u8> = (0..nb as u8).collect();
            let rs = build(&beacons, nf, group, rounds);
            assert_eq!(rs.len(), rounds);
            let mut met = vec![BTreeSet::new(); nb];
            for groups in &rs {
                assert_eq!(groups.len(), nb.div_ceil(group));
                let mut seen = vec![0; nb];
                for g in groups {
                    assert!(g.len() <= group, "{nb} {nf} {group}: {} > {group}", g.len());
                    let freqs: BTreeSet<usize> = g.iter().map(|&(_, f)| f).collect();
                    assert_eq!(freqs.len(), g.len(), "a frequency twice in {g:?}");
                    for &(b, f) in g {
                        seen[b] += 1;
                        met[b].insert(f);
                    }
                }
                assert!(seen.iter().all(|&n| n == 1), "{seen:?}");
            }
            assert!(met.iter().all(|m| m.len() == rounds));
        }
    }

    /// A full array in groups of 19 or 20: each group spread over the array (no two members
    /// side by side: at least a diagonal pitch apart in round 0 and most of each later round),
    /// and a beacon's group-mates change from one round to the next.
    #[test]
    fn groups_are_spread_and_mix_from_round_to_round() {
        for group in [19, 20] {
            let rs = build(&all(), 20, group, 3);
            let mut close = 0;
            for (r, groups) in rs.iter().enumerate() {
                assert_eq!(groups.len(), 100usize.div_ceil(group));
                for g in groups {
                    for (i, &(a, _)) in g.iter().enumerate() {
                        for &(b, _) in &g[..i] {
                            let ((ax, ay), (bx, by)) = (place(a as u8), place(b as u8));
                            let d = (ax - bx).hypot(ay - by);
                            assert!(r > 0 || d >= 1.4, "round 0: {a} and {b} {d} apart");
                            close += usize::from(d < 1.4);
                        }
                    }
                }
            }
            // Pairs in a group of 20: 190; in all the groups of three rounds about 2,850.
            assert!(close <= 30, "group {group}: {close} pairs side by side");
        }
        let rs = build(&all(), 20, 20, 3);
        let mates = |r: usize, b: usize| -> BTreeSet<usize> {
            rs[r]
                .iter()
                .find(|g| g.iter().any(|&(m, _)| m == b))
                .unwrap()
                .iter()
                .map(|&(m, _)| m)
                .filter(|&m| m != b)
                .collect()
        };
        for b in 0..100 {
            assert_ne!(mates(0, b), mates(1, b), "beacon {b} kept its neighbours");
        }
    }

    #[test]
    fn checked_beacons_are_distinct_and_turn_with_the_separation() {
        let a = checked(100, 4, 0);
        assert_eq!(a, [0, 25, 50, 75]);
        let b = checked(100, 4, 1);
        assert_eq!(b, [7, 32, 57, 82]);
        assert_eq!(checked(3, 5, 0).len(), 3);
        let c = checked(3, 3, 2);
        assert_eq!(c.iter().collect::<BTreeSet<_>>().len(), 3);
    }
}
