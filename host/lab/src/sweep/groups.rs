//! Grouped plans: which beacons a sweep point lights together, each at its own frequency.
//!
//! The NorthStar tells spots apart by their modulation frequency alone and reports up to 20
//! of them per frame, so a frame can carry one spot per frequency of the table. A plan with
//! `group = N` lights up to N beacons at once, each at a different frequency of its
//! `frequencies_hz` (F of them). The schedule of one plate position, power level and
//! sensitivity (a *block*) is built from the plan alone, the same in every block, so a point's
//! index still identifies it across a resume:
//!
//! * The block's measurements are the plan's beacons, each measured in `frequencies_per_beacon`
//!   rounds (K). They are laid in a row: round 0's beacons in a spread order, then round 1's
//!   in the same order, and so on, each round `L` places long (the number of beacons, and a
//!   place or two left empty when that is needed below). The groups are the row cut into
//!   windows of N places: every frame of the block carries N spots, but at the very end.
//! * The measurement at place `q` is lit at frequency `q mod F`. N consecutive places hold N
//!   different frequencies, so no two LEDs of a group share one; a beacon's places in
//!   successive rounds are `L` apart, and `L` is chosen so that its K frequencies differ, all
//!   of them when the plan asks for every one.
//! * The spread order walks the array by lattice cosets (beacon (x, y) in coset
//!   `(x + a y) mod M`, the slope `a` that keeps a coset's members farthest apart), each coset
//!   from its top row down, so that a window's beacons are spread over the detector's field.
//! * `L` is also chosen so that the windows fall elsewhere from one round to the next: a
//!   beacon does not keep the same group-mates.

use std::sync::{Arc, OnceLock};

use cta_core::emulator::grid_position;

/// One beacon of a group: indices into the plan's `beacons` and `frequencies_hz`.
pub type Member = (usize, usize);

/// The groups of a block, in measurement order.
pub type Groups = Vec<Vec<Member>>;

/// A grouped plan's groups, built once from the plan's keys and shared by its clones. Derived
/// data: two caches always compare equal, and none is serialized.
#[derive(Clone, Default)]
pub struct Cached(pub(crate) Arc<OnceLock<Groups>>);

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

/// The round length `L` for `nb` beacons, `n_freqs` frequencies, `rounds` rounds and groups of
/// `group`: at least `nb`; a beacon's frequencies `(i + r L) mod F` differ over the rounds;
/// and, when the block has more than one group, `L` is not a multiple of the group, so the
/// windows move from one round to the next.
fn round_length(nb: usize, n_freqs: usize, rounds: usize, group: usize) -> usize {
    (nb..)
        .find(|&l| {
            let distinct = (0..rounds).all(|r| (0..r).all(|q| (r - q) * l % n_freqs != 0));
            let moves = rounds == 1 || nb <= group || l % group != 0;
            // A beacon's places in two rounds never fall in one window.
            distinct && moves && l >= group
        })
        .expect("a length coprime to the frequencies exists")
}

/// Build the groups of a block for `beacons` (LED ids on the 10 x 10 array), `n_freqs`
/// frequencies, groups of at most `group` beacons and `rounds` rounds. Requires
/// `1 <= group <= n_freqs` and `1 <= rounds <= n_freqs`.
pub fn build(beacons: &[u8], n_freqs: usize, group: usize, rounds: usize) -> Groups {
    let nb = beacons.len();
    assert!(
        nb > 0 && (1..=n_freqs).contains(&group) && (1..=n_freqs).contains(&rounds),
        "checked by the plan"
    );
    let l = round_length(nb, n_freqs, rounds, group);
    let cut = |order: &[usize]| {
        let mut groups: Groups = Vec::new();
        for start in (0..rounds * l).step_by(group) {
            let g: Vec<Member> = (start..(start + group).min(rounds * l))
                .filter(|q| q % l < nb)
                .map(|q| (order[q % l], q % n_freqs))
                .collect();
            if !g.is_empty() {
                groups.push(g);
            }
        }
        groups
    };
    // The spread order whose groups hold the fewest members side by side (closer than a
    // diagonal pitch), then the fewest at a diagonal pitch.
    let close = |groups: &Groups| {
        let mut n = (0usize, 0usize);
        for g in groups {
            for (i, &(a, _)) in g.iter().enumerate() {
                for &(b, _) in &g[..i] {
                    let d = distance(beacons[a], beacons[b]);
                    n.0 += usize::from(d < 1.2);
                    n.1 += usize::from(d < 1.5);
                }
            }
        }
        n
    };
    let runs = [(nb / group).max(1), nb.div_ceil(group)];
    runs.iter()
        .flat_map(|&m| (0..m).flat_map(move |a| (0..4).map(move |walk| (m, a, walk))))
        .map(|(m, a, walk)| cut(&spread_order(beacons, m, a, walk)))
        .min_by_key(close)
        .expect("one order at least")
}

/// The plan's beacons (indices into its list) in an order whose runs are spread over the
/// array: coset by coset of the lattice `(x + a y) mod m` (`m` about the groups of a round),
/// each walked by `walk`: 0 row by row from the top, 1 the same but every other coset from the
/// bottom, 2 column by column, 3 the same but every other coset from the right. The plan's
/// order when `m` is 1.
fn spread_order(beacons: &[u8], m: usize, a: usize, walk: usize) -> Vec<usize> {
    let nb = beacons.len();
    if m <= 1 {
        return (0..nb).collect();
    }
    let mut order: Vec<usize> = (0..nb).collect();
    order.sort_by_key(|&b| {
        let (x, y) = (beacons[b] as usize % 10, beacons[b] as usize / 10);
        let c = (x + a * y) % m;
        let flip = walk % 2 == 1 && c % 2 == 1;
        let (major, minor) = if walk < 2 { (y, x) } else { (x, y) };
        (c, if flip { 9 - major } else { major }, minor)
    });
    order
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

/// The frequency (index into the plan's list) beacon `b` has in round 0: at its first place.
pub fn first_frequency(groups: &Groups, b: usize) -> usize {
    groups
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

    /// Every beacon `rounds` times, each time at another frequency; no frequency twice in a
    /// group; groups full but at the end of the block.
    #[test]
    fn every_beacon_at_as_many_frequencies_as_rounds() {
        for (nb, nf, group, rounds, points) in [
            (100, 19, 19, 3, 16),
            (100, 20, 20, 3, 16),
            (100, 20, 20, 20, 101),
            (100, 20, 10, 4, 41),
            (100, 3, 3, 3, 100),
            (37, 5, 4, 5, 47),
            (3, 20, 3, 2, 2),
            (5, 1, 1, 1, 5),
        ] {
            let beacons: Vec<u8> = (0..nb as u8).collect();
            let gs = build(&beacons, nf, group, rounds);
            assert_eq!(gs.len(), points, "{nb} {nf} {group} {rounds}");
            let mut met = vec![BTreeSet::new(); nb];
            let mut times = vec![0; nb];
            for g in &gs {
                assert!(!g.is_empty() && g.len() <= group);
                let freqs: BTreeSet<usize> = g.iter().map(|&(_, f)| f).collect();
                assert_eq!(freqs.len(), g.len(), "a frequency twice in {g:?}");
                let members: BTreeSet<usize> = g.iter().map(|&(b, _)| b).collect();
                assert_eq!(members.len(), g.len(), "a beacon twice in {g:?}");
                for &(b, f) in g {
                    times[b] += 1;
                    met[b].insert(f);
                }
            }
            assert!(times.iter().all(|&n| n == rounds));
            assert!(met.iter().all(|m| m.len() == rounds), "{nb} {nf} {group}");
        }
    }

    /// A full array in groups of 19 or 20: few members of a group side by side, and a beacon's
    /// group-mates change from one round to the next.
    #[test]
    fn groups_are_spread_and_mix_from_round_to_round() {
        for group in [19, 20] {
            let gs = build(&all(), 20.max(group), group, 3);
            let mut close = 0;
            for g in &gs {
                for (i, &(a, _)) in g.iter().enumerate() {
                    for &(b, _) in &g[..i] {
                        close += usize::from(distance(a as u8, b as u8) < 1.4);
                    }
                }
            }
            // Of about 2,900 pairs in 16 groups of 19 or 20.
            assert_eq!(close, 0, "group {group}: {close} pairs side by side");
            let mates = |r: usize, b: usize| -> BTreeSet<usize> {
                gs.iter()
                    .filter(|g| g.iter().any(|&(m, _)| m == b))
                    .nth(r)
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
