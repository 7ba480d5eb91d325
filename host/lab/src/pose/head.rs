//! The simulated sensor board's scene (`cta sensor sim`): the target's pose and the noise of
//! its simulated NorthStar, and the head that NorthStar sees with: the Table 3 head, the
//! head of a simulation's truth sidecar, or the Table 3 head with effects of the vocabulary.

use std::path::{Path, PathBuf};

use cta_core::emulator::Emulator;
use cta_core::pose::{cta_constellation, Calibration};
use cta_firmware_sensor::sim::SimNorthStar;
use nalgebra::Vector3;

use crate::pose::error::Error;
use crate::pose::limits::check_ranges;

/// The simulated board's scene: the target's pose, the simulated NorthStar's noise, and
/// the head (`truth`, `effects`).
#[derive(Debug, Clone, PartialEq)]
pub struct SimScene {
    /// Target range (z of the target origin in the board frame), inches (above 0, at most
    /// 1000).
    pub range: f64,
    /// Target lateral offset x, y, inches.
    pub offset: [f64; 2],
    /// Target attitude: rotations about the board frame's x, y, z, in that order, degrees
    /// ([`cta_core::pose::attitude_xyz`]).
    pub attitude_deg: [f64; 3],
    /// Spot noise, counts (1-sigma, 0 to 32768).
    pub noise: f64,
    /// Spot magnitude noise, percent of the magnitude (1-sigma, 0 to 100).
    pub magnitude_noise: f64,
    /// Probability of line noise before a NorthStar frame (0 to 1).
    pub garbage: f64,
    /// Probability that a frame carries one spot under another beacon's ID (0 to 1).
    pub wrong_id: f64,
    /// The beacons' power level (1 or 2), for the magnitude law
    /// ([`cta_core::magnitude_law`]): level 1 keeps the default scene's spots (12 in) below
    /// saturation at sensitivity 4.
    pub power_level: u8,
    /// A simulation's truth sidecar whose head to simulate.
    pub truth: Option<PathBuf>,
    /// Effects of the vocabulary to give the Table 3 head, `NAME=VALUE`.
    pub effects: Vec<String>,
}

impl Default for SimScene {
    fn default() -> Self {
        SimScene {
            range: 12.0,
            offset: [0.2, -0.1],
            attitude_deg: [0.0, 0.0, 2.0],
            noise: 32.768,
            magnitude_noise: 0.07,
            garbage: 0.0,
            wrong_id: 0.0,
            power_level: 1,
            truth: None,
            effects: Vec::new(),
        }
    }
}

impl SimScene {
    /// Check the numbers of the scene (with an error naming the option and its allowed
    /// range); [`SimScene::head`] checks the head.
    pub fn check_values(&self) -> Result<(), Error> {
        check_ranges("--range", &[self.range])?;
        let bad = |m: String| Err(Error::Option(m));
        if !self.attitude_deg.iter().all(|a| a.is_finite()) {
            let [x, y, z] = self.attitude_deg;
            return bad(format!(
                "--attitude-deg {x},{y},{z}: expected three finite angles RX,RY,RZ, degrees"
            ));
        }
        if !(self.noise >= 0.0 && self.noise <= 32768.0) {
            return bad(format!(
                "--noise {}: expected 0 to 32768 counts",
                self.noise
            ));
        }
        if !(self.magnitude_noise >= 0.0 && self.magnitude_noise <= 100.0) {
            return bad(format!(
                "--magnitude-noise {}: expected 0 to 100 percent of the magnitude",
                self.magnitude_noise
            ));
        }
        if !(0.0..=1.0).contains(&self.wrong_id) {
            return bad(format!(
                "--wrong-id {}: expected a probability, 0 to 1",
                self.wrong_id
            ));
        }
        if !(0.0..=1.0).contains(&self.garbage) {
            return bad(format!(
                "--garbage {}: expected a probability, 0 to 1",
                self.garbage
            ));
        }
        if !(1..=2).contains(&self.power_level) {
            return bad(format!(
                "--power-level {}: expected 1 (1 kOhm) or 2 (360 Ohm)",
                self.power_level
            ));
        }
        Ok(())
    }

    /// Check the whole scene: its numbers and its head.
    pub fn check(&self) -> Result<(), Error> {
        self.check_values()?;
        self.head()?;
        Ok(())
    }

    /// The simulated head when `truth` or `effects` change it (`None`: the Table 3 head with
    /// the nominal near-field physics), with what it is, for the output, and the effects of
    /// the truth file that were left out (the CTA plate's, not the head's).
    pub fn head(&self) -> Result<Option<SimHead>, Error> {
        let (config, from, left_out) = if let Some(path) = &self.truth {
            let (config, left_out) = truth_head(path)?;
            (config, format!("the head of {}", path.display()), left_out)
        } else if !self.effects.is_empty() {
            let effects = crate::sim::effects::parse_all(&self.effects).map_err(Error::Effect)?;
            if let Some(e) = effects.iter().find(|e| !acts_on_the_head(e)) {
                return Err(Error::PlateEffect {
                    effect: e.to_string(),
                    name: e.name().to_string(),
                });
            }
            let config = crate::sim::SimConfig {
                separations: Vec::new(),
                effects,
                ..Default::default()
            };
            (config, "the Table 3 head".to_string(), Vec::new())
        } else {
            return Ok(None);
        };
        let names: Vec<String> = config.effects.iter().map(|e| e.to_string()).collect();
        let emulator = config.physics().emulator;
        Ok(Some(SimHead {
            describe: format!(
                "{from}: d = {}, {}, {} in, p = {}, {}, {}, {} physics, beacon {}, effects [{}]",
                config.pose.d.x,
                config.pose.d.y,
                config.pose.d.z,
                config.pose.p.x,
                config.pose.p.y,
                config.pose.p.z,
                if config.far_field {
                    "far-field"
                } else {
                    "thesis"
                },
                crate::sim::describe_pattern(&emulator.effects.pattern),
                names.join(" ")
            ),
            emulator,
            left_out,
        }))
    }

    /// The simulated NorthStar of this scene (the CTA constellation; the Table 3 head, or the
    /// one `truth` or `effects` give), or the error of a bad `truth` or `effects`.
    pub fn try_northstar(&self) -> Result<SimNorthStar, Error> {
        let t = Vector3::new(self.offset[0], self.offset[1], self.range);
        let q = cta_core::pose::attitude_xyz(self.attitude_deg);
        let mut ns = SimNorthStar::new(
            &Calibration::table3(),
            cta_constellation(),
            t,
            q,
            self.noise,
            1,
        );
        if let Some(head) = self.head()? {
            ns.physics = head.emulator;
        }
        ns.magnitude_noise = self.magnitude_noise;
        ns.garbage = self.garbage;
        ns.wrong_id = self.wrong_id;
        ns.power_level = self.power_level;
        Ok(ns)
    }

    /// [`SimScene::try_northstar`] for a scene that passed [`SimScene::check`] (the default
    /// head always does). Panics on a bad `truth` or `effects`.
    pub fn northstar(&self) -> SimNorthStar {
        self.try_northstar()
            .expect("the scene's head passed SimScene::check")
    }
}

/// The head `cta sensor sim` simulates when a truth file or effects change it.
#[derive(Debug, Clone)]
pub struct SimHead {
    /// Its physics.
    pub emulator: Emulator<f64>,
    /// What it is (for the output).
    pub describe: String,
    /// Effects of the truth file left out: the CTA plate's, not the head's.
    pub left_out: Vec<String>,
}

/// Whether an effect acts on the sensor head (and so on `cta sensor sim`'s NorthStar), not on
/// the CTA's beacon plate (its tilt, lateral offsets and separation errors).
pub fn acts_on_the_head(e: &crate::sim::effects::Effect) -> bool {
    use crate::sim::effects::Effect;
    !matches!(
        e,
        Effect::BeaconTilt(..)
            | Effect::PlateOffset(_)
            | Effect::SeparationError(_)
            | Effect::PlateTilt(_)
    )
}

/// The head of a truth sidecar ([`crate::sim::Truth`]) as the simulation that wrote it
/// had it: `d`, `p`, base physics, pattern and the effects that act on the head; and the
/// effects left out (the plate's).
fn truth_head(path: &Path) -> Result<(crate::sim::SimConfig, Vec<String>), Error> {
    use crate::sim::effects::Effect;
    use cta_core::pattern::Pattern;
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|error| Error::TruthRead {
        path: shown.clone(),
        error,
    })?;
    let t: crate::sim::Truth = serde_json::from_str(&text).map_err(|error| Error::NotTruth {
        path: shown.clone(),
        error,
    })?;
    let bad = |what: String| Error::Truth {
        path: shown.clone(),
        what,
    };
    let far_field = match t.physics.as_str() {
        "thesis" => false,
        "far-field" => true,
        other => {
            return Err(bad(format!(
                "unknown physics `{other}` (thesis, far-field)"
            )))
        }
    };
    // As `describe_pattern` writes it.
    let pattern = if t.pattern == "uniform" {
        Pattern::Uniform
    } else if t.pattern.starts_with("quartic") {
        Pattern::Quartic
    } else if let Some(h) = t
        .pattern
        .strip_prefix("lambertian H=")
        .and_then(|r| r.split_whitespace().next())
        .and_then(|h| h.parse::<f64>().ok())
        .filter(|h| *h > 0.0 && *h < 90.0)
    {
        Pattern::lambertian_half_angle(h)
    } else {
        return Err(bad(format!(
            "unknown beacon pattern `{}` (lambertian H=..., uniform, quartic)",
            t.pattern
        )));
    };
    let all: Vec<Effect> = t
        .effects
        .iter()
        .map(|e| Effect::parse(e).map_err(|m| bad(format!("effect `{e}`: {m}"))))
        .collect::<Result<_, _>>()?;
    let (effects, plate): (Vec<Effect>, Vec<Effect>) = all.into_iter().partition(acts_on_the_head);
    let v = |a: [f64; 3], what: &str| -> Result<Vector3<f64>, Error> {
        if a.iter().all(|x| x.is_finite() && x.abs() <= 12.0) {
            Ok(Vector3::from(a))
        } else {
            Err(bad(format!(
                "`{what}` {a:?} is not a head offset or attitude within +/-12"
            )))
        }
    };
    Ok((
        crate::sim::SimConfig {
            separations: Vec::new(),
            pattern,
            far_field,
            pose: cta_core::emulator::Pose {
                d: v(t.d, "d")?,
                p: v(t.p, "p")?,
            },
            effects,
            ..Default::default()
        },
        plate.iter().map(|e| e.to_string()).collect(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `cta sensor sim --effect` gives the head the effect as `cta simulate --effect` does,
    /// `--truth` the head of a simulation's sidecar (the same physics), and effects of the CTA
    /// plate are refused from the command line and left out of a truth file.
    #[test]
    fn the_sim_head_takes_effects_and_truth_files() {
        let with = |effects: &[&str], truth: Option<std::path::PathBuf>| SimScene {
            effects: effects.iter().map(|e| e.to_string()).collect(),
            truth,
            ..SimScene::default()
        };
        assert!(with(&[], None).head().unwrap().is_none());
        let h = with(&["cell_gain=0.02,-0.01"], None)
            .head()
            .unwrap()
            .unwrap();
        assert_eq!(h.emulator.effects.gain, [1.02, 1.0, 0.99, 1.0]);
        assert!(
            h.describe.contains("effects [cell_gain=0.02,-0.01]"),
            "{}",
            h.describe
        );
        let ns = with(&["face_angle=1,0.5"], None).northstar();
        assert!((ns.physics.head.alpha_x.to_degrees() - 31.0).abs() < 1e-9);
        for e in [
            "beacon_tilt=3,45",
            "plate_offset=0.05",
            "separation_error=0.05",
            "plate_tilt=0.5",
        ] {
            let err = with(&[e], None).check().unwrap_err().to_string();
            assert!(
                err.contains("describes the CTA's beacon plate"),
                "{e}: {err}"
            );
        }
        assert!(with(&["glare=1"], None).check().is_err());
        // A truth sidecar written by a simulation: the same head, the plate's effects left out.
        let d = std::env::temp_dir().join(format!("cta-sim-head-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let cfg = crate::sim::SimConfig {
            separations: vec![20.0],
            grid: (2, 2),
            effects: crate::sim::effects::parse_all(&[
                "cell_gain=0.02,-0.01",
                "plate_offset=0.05",
                "beacon_pattern=45",
            ])
            .unwrap(),
            // A head pose other than Table 3's (the default), which the sidecar must carry.
            pose: cta_core::emulator::Pose {
                d: Vector3::new(-0.3, 0.4, 0.2),
                p: Vector3::new(0.01, -0.02, 0.03),
            },
            ..Default::default()
        };
        let (ds, truth) = cfg.try_run().unwrap();
        let csv = d.join("t.csv");
        let tp = crate::sim::write_files(&csv, &ds, &truth, false).unwrap();
        let h = with(&[], Some(tp.clone())).head().unwrap().unwrap();
        let want = crate::sim::SimConfig {
            effects: crate::sim::effects::parse_all(&["cell_gain=0.02,-0.01", "beacon_pattern=45"])
                .unwrap(),
            ..cfg.clone()
        }
        .physics()
        .emulator;
        let r = Vector3::new(1.5, -2.0, 10.0);
        assert_eq!(h.emulator.output(&r), want.output(&r));
        let table3 = crate::sim::SimConfig::default().physics().emulator;
        assert_ne!(h.emulator.output(&r), table3.output(&r));
        assert_eq!(h.left_out, ["plate_offset=0.05"]);
        std::fs::write(&tp, "{}").unwrap();
        let err = with(&[], Some(tp)).check().unwrap_err().to_string();
        assert!(err.contains("not a truth sidecar"), "{err}");
        let _ = std::fs::remove_dir_all(&d);
    }
}
