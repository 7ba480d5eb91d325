//! A plan's points: what each point lights, where and under which settings, numbered in
//! the plan's fixed order so that a point's index identifies it across a resume.
//!
//! Loop order, outermost first (thesis Ch VI: "finish a separation before moving the
//! plate"): separation, quadrant (quad layout only), power level, sensitivity, then the
//! block's points. Power levels alternate direction from one plate position to the next
//! (serpentine), so the operator flips the power switches once per plate position instead
//! of twice. A block of a one-at-a-time plan is every beacon at every frequency (beacon
//! outer); a block of a grouped plan is its groups ([`super::groups`]). One block
//! of every separation (a different one from one separation to the next, so that over the run
//! every power level and sensitivity is checked) ends with the beacons of the crosstalk
//! check, each lit alone at the frequency it had in round 0.

use cta_core::emulator::grid_position;

use super::groups::{self, Groups};
use super::plan::{channel_of, Layout, Plan};

/// One beacon lit at a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lit {
    /// LED id on the array, 0..99.
    pub led: u8,
    /// Frequency channel in the NorthStar table (the spot ID the sensor reports).
    pub channel: u8,
    /// Modulation frequency, Hz.
    pub frequency_hz: f64,
}

impl Lit {
    /// Beacon id written to the data (`100 * quadrant + led`).
    pub fn beacon_id(&self, quadrant: usize) -> u32 {
        100 * quadrant as u32 + self.led as u32
    }

    /// Nominal position in N of the LED on the array in `quadrant`, for a plate at
    /// `separation` (recorded), inches.
    pub fn position(&self, layout: &Layout, quadrant: usize, separation: f64) -> [f64; 3] {
        let g = grid_position(10, 1.0, separation, self.led as usize);
        let c = layout.centre(quadrant);
        [g.x + c[0], g.y + c[1], g.z]
    }
}

/// One measurement point: the beacons lit together (one, or a group) under one setting.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Index in the plan's order (0-based).
    pub index: usize,
    /// Index into [`Plan::separations`].
    pub sep_idx: usize,
    /// Nominal separation, inches.
    pub separation: f64,
    /// Quadrant (0 for the single layout).
    pub quadrant: usize,
    /// Power level.
    pub power: u8,
    /// Sensitivity setting.
    pub sensitivity: u8,
    /// The block within the separation (its quadrant, power level and sensitivity), in
    /// measurement order.
    pub block: usize,
    /// The beacons lit, each at its own frequency.
    pub lit: Vec<Lit>,
    /// A crosstalk check: a beacon of a group lit alone, to compare with its reading in the
    /// group.
    pub alone: bool,
}

impl Point {
    /// The first beacon lit (the only one, in a one-at-a-time plan).
    pub fn first(&self) -> &Lit {
        &self.lit[0]
    }
}

impl Plan {
    /// Frequencies each beacon is measured at per setting: `frequencies_per_beacon`, all of
    /// `frequencies_hz` when not set.
    pub fn rounds(&self) -> usize {
        match self.frequencies_per_beacon {
            0 => self.frequencies_hz.len(),
            k => k,
        }
    }

    /// Whether the plan lights one beacon at a time at every frequency: the order of the
    /// plans written before groups existed.
    pub fn one_at_a_time(&self) -> bool {
        self.group <= 1 && self.rounds() == self.frequencies_hz.len() && self.crosstalk_check == 0
    }

    /// The groups of a block (built on first use).
    pub fn groups(&self) -> &Groups {
        self.schedule.0.get_or_init(|| {
            groups::build(
                &self.beacons,
                self.frequencies_hz.len(),
                self.group.max(1),
                self.rounds(),
            )
        })
    }

    /// Points per block (one plate position, power level and sensitivity), the crosstalk
    /// check's left out.
    pub fn per_block(&self) -> usize {
        if self.one_at_a_time() {
            self.beacons.len() * self.frequencies_hz.len()
        } else {
            self.groups().len()
        }
    }

    /// Beacons measured alone per separation (the crosstalk check).
    pub fn checks(&self) -> usize {
        if self.one_at_a_time() {
            0
        } else {
            self.crosstalk_check.min(self.beacons.len())
        }
    }

    /// Whether point `p` is in the block of its separation that holds the crosstalk check:
    /// the beacons measured alone, and the groups they are compared with.
    pub fn in_check_block(&self, p: &Point) -> bool {
        self.checks() > 0 && p.block == p.sep_idx % self.blocks()
    }

    /// Blocks per separation.
    pub fn blocks(&self) -> usize {
        self.layout.quadrants() * self.power_levels.len() * self.sensitivities.len()
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.per_separation() * self.separations.len()
    }

    /// `true` if the plan has no points (never, once validated).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Points per separation.
    pub fn per_separation(&self) -> usize {
        self.blocks() * self.per_block() + self.checks()
    }

    /// Samples the plan asks for in all: every beacon lit at every point, `samples` times.
    pub fn total_samples(&self) -> u64 {
        let lit_per_block = if self.one_at_a_time() {
            self.per_block()
        } else {
            self.rounds() * self.beacons.len()
        };
        ((lit_per_block * self.blocks() + self.checks()) * self.separations.len()) as u64
            * self.samples as u64
    }

    /// Point number `index` (in `0..len()`).
    pub fn point(&self, index: usize) -> Point {
        let nu = self.per_block();
        let ns = self.sensitivities.len();
        let np = self.power_levels.len();
        let nq = self.layout.quadrants();
        let nc = self.checks();
        let sep_idx = index / self.per_separation();
        let rem = index % self.per_separation();
        // The block that carries the crosstalk check at this separation.
        let jc = sep_idx % self.blocks();
        let (block, unit) = if rem < jc * nu {
            (rem / nu, rem % nu)
        } else if rem < (jc + 1) * nu + nc {
            (jc, rem - jc * nu)
        } else {
            let after = rem - (jc + 1) * nu - nc;
            (jc + 1 + after / nu, after % nu)
        };
        let s = block % ns;
        let p = (block / ns) % np;
        let q = block / (ns * np);
        // Serpentine power order: reversed on every other plate position.
        let place = sep_idx * nq + q;
        let p = if place % 2 == 1 { np - 1 - p } else { p };
        let lit = |b: usize, f: usize| {
            let hz = self.frequencies_hz[f];
            Lit {
                led: self.beacons[b],
                channel: channel_of(hz).unwrap_or(0),
                frequency_hz: hz,
            }
        };
        let nf = self.frequencies_hz.len();
        let (lit, alone) = if self.one_at_a_time() {
            (vec![lit(unit / nf, unit % nf)], false)
        } else {
            let groups = self.groups();
            let ng = groups.len();
            if unit < ng {
                let g = &groups[unit];
                (g.iter().map(|&(b, f)| lit(b, f)).collect(), false)
            } else {
                let checked = groups::checked(self.beacons.len(), nc, sep_idx);
                let b = checked[unit - ng];
                (vec![lit(b, groups::first_frequency(groups, b))], true)
            }
        };
        Point {
            index,
            sep_idx,
            separation: self.separations[sep_idx],
            quadrant: q,
            power: self.power_levels[p],
            sensitivity: self.sensitivities[s],
            block,
            lit,
            alone,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::plan::tests::SHORT;

    #[test]
    fn expands_in_order_with_serpentine_power() {
        let p = Plan::parse("p.toml", SHORT).unwrap();
        assert_eq!(p.len(), 2 * 2 * 3);
        let pts: Vec<Point> = (0..p.len()).map(|i| p.point(i)).collect();
        assert_eq!(
            pts.iter().map(|p| p.power).collect::<Vec<_>>(),
            [1, 1, 1, 2, 2, 2, 2, 2, 2, 1, 1, 1]
        );
        assert_eq!(pts[4].first().led, 45);
        assert_eq!(pts[7].separation, 25.0);
        assert_eq!(pts[0].first().channel, 2);
        assert_eq!(
            pts[0].first().position(&p.layout, 0, 20.0),
            [-4.5, -4.5, 20.0]
        );
        assert!(pts.iter().all(|p| p.lit.len() == 1 && !p.alone));
    }

    #[test]
    fn quad_layout_offsets_quadrants() {
        let p = Plan::parse(
            "p.toml",
            "separations_in = \"10..11\"\nlayout = \"quad\"\nbeacons = [0]\nsamples = 1\n",
        )
        .unwrap();
        assert_eq!(p.len(), 8);
        let q3 = p.point(3);
        assert_eq!(q3.first().beacon_id(q3.quadrant), 300);
        assert_eq!(
            q3.first().position(&p.layout, q3.quadrant, 10.0),
            [1.0, 1.0, 10.0]
        );
    }

    /// A grouped plan: the same beacons and frequencies as one at a time, measured in far
    /// fewer points, and the crosstalk check's beacons alone at the end of one block per
    /// separation, at the frequency of their round-0 group.
    #[test]
    fn a_grouped_plan_measures_every_beacon_in_fewer_points() {
        let src = "separations_in = [10, 20]\nbeacons = \"all\"\nfrequencies_hz = [2010, 3040, \
                   3090, 3210, 3330, 3450, 3570, 3690, 3810, 3930, 4050, 4170, 4290, 4410, 4530, \
                   4650, 4770, 4890, 5010]\nfrequencies_per_beacon = 3\ngroup = 19\n\
                   crosstalk_check = 2\nsensitivities = [2, 4]\nsamples = 5\n";
        let p = Plan::parse("g.toml", src).unwrap();
        assert_eq!(p.per_block(), 16);
        assert_eq!(p.per_separation(), 2 * 16 + 2);
        assert_eq!(p.len(), 2 * 34);
        assert_eq!(p.total_samples(), 2 * (2 * 300 + 2) * 5);
        let mut per_beacon = vec![Vec::new(); 100];
        for i in 0..p.per_block() {
            let pt = p.point(i);
            if pt.alone {
                continue;
            }
            assert!(pt.lit.len() == 19 || i == 15, "{}", pt.lit.len());
            for l in &pt.lit {
                per_beacon[l.led as usize].push(l.channel);
            }
        }
        assert!(per_beacon.iter().all(|c| c.len() == 3));
        // Separation 0 checks in its first block, separation 1 in its second.
        let check = p.point(16);
        assert!(check.alone && check.lit.len() == 1 && check.sensitivity == 2);
        assert!(!p.point(18).alone && p.point(18).sensitivity == 4);
        let later = p.point(34 + 16 + 16);
        assert!(later.alone && later.sensitivity == 4 && later.sep_idx == 1);
        assert_eq!((check.block, p.point(18).block, later.block), (0, 1, 1));
        assert!(p.in_check_block(&check) && p.in_check_block(&later));
        assert!(!p.in_check_block(&p.point(18)) && p.in_check_block(&p.point(34 + 16)));
        let b = check.first().led;
        let grouped = (0..16)
            .map(|i| p.point(i))
            .find(|pt| pt.lit.iter().any(|l| l.led == b))
            .unwrap();
        let there = grouped.lit.iter().find(|l| l.led == b).unwrap();
        assert_eq!(there.channel, check.first().channel);
        // The next separation checks other beacons.
        assert_ne!(later.first().led, b);
    }
}
