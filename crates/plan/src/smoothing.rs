//! Stage 3 (§3.2): average wall samples across small registration errors.
//!
//! Each sample moves to the mean position of its smoothing set: the samples within the
//! smoothing distance along ±n, within `across_cells` × d_s across n, and with a normal within
//! `max_angle` of n. All means are taken over the original positions, so the result does not
//! depend on the order of the samples.

use std::collections::HashMap;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cancel::{Cancel, Cancelled};
use crate::geom::{cross, dot, sub, P2};
use crate::params::{within, ParamRange};
use crate::samples::{WallSample, WallSamples};

/// Parameters of [`smooth_samples`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SmoothingParams {
    /// Expected registration error, metres. `None` turns smoothing off (§3.2: "not necessary if
    /// registration error is smaller than d_s"). Range 0.001..=0.5.
    pub registration_error: Option<f64>,
    /// Smoothing distance along ±n, metres; `None` uses 2 × the registration error (§3.2: at
    /// least the registration error, less than the spacing of parallel walls). Range 0.001..=1.
    pub distance: Option<f64>,
    /// Extent across n, in cells of d_s (§3.2: 3 d_s). Range 0.1..=20.
    pub across_cells: f64,
    /// Maximum normal angle, radians (§3.2: π/8). Range 0..=π.
    pub max_angle: f64,
}

/// The accepted values of [`SmoothingParams`] (see [`crate::params::ParamRange`]). The
/// smoothing set's search radius follows from them, so they also bound its cost per sample.
pub const RANGES: &[ParamRange] = &[
    ParamRange::new("registration_error", 0.001, 0.5, "m"),
    ParamRange::new("distance", 0.001, 1.0, "m"),
    ParamRange::new("across_cells", 0.1, 20.0, ""),
    ParamRange::new("max_angle", 0.0, std::f64::consts::PI, "rad"),
];

impl Default for SmoothingParams {
    fn default() -> Self {
        SmoothingParams {
            registration_error: None,
            distance: None,
            across_cells: 3.0,
            max_angle: std::f64::consts::FRAC_PI_8,
        }
    }
}

/// Why smoothing failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SmoothingError {
    /// A parameter is outside its range.
    #[error("invalid smoothing parameter `{name}`: {why}")]
    BadParam {
        /// The parameter's name.
        name: &'static str,
        /// What is wrong.
        why: String,
    },
    /// The run was stopped from outside.
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
}

/// Moves each sample to the mean of its smoothing set. `cell_size` is d_s. Stops with
/// `Cancelled` once `cancel` says so, leaving the samples as they were.
pub fn smooth_samples(
    samples: &mut WallSamples,
    cell_size: f64,
    params: &SmoothingParams,
    cancel: &Cancel,
) -> Result<(), SmoothingError> {
    params.check(cell_size)?;
    let Some(error) = params.registration_error else {
        return Ok(());
    };
    let along = params.distance.unwrap_or(2.0 * error);
    let across = params.across_cells * cell_size;
    let set = SmoothingSet {
        along,
        across,
        min_cos: params.max_angle.cos(),
    };
    let index = Buckets::new(&samples.samples, along.hypot(across));
    let means: Vec<P2> = samples
        .samples
        .par_iter()
        .map(|s| {
            if cancel.is_stopped() {
                return s.pos;
            }
            set.mean(s, &samples.samples, &index)
        })
        .collect();
    cancel.check()?;
    for (s, m) in samples.samples.iter_mut().zip(means) {
        s.pos = m;
    }
    Ok(())
}

impl SmoothingParams {
    /// Checks every value for grid cells of `cell_size` metres; the error names the parameter.
    /// Only a run with smoothing on reads them, so only then are they checked.
    pub fn check(&self, cell_size: f64) -> Result<(), SmoothingError> {
        let Some(error) = self.registration_error else {
            return Ok(());
        };
        let check = |name, v: f64| {
            within(RANGES, name, v).map_err(|(name, why)| SmoothingError::BadParam { name, why })
        };
        check("registration_error", error)?;
        if let Some(d) = self.distance {
            check("distance", d)?;
        }
        check("across_cells", self.across_cells)?;
        check("max_angle", self.max_angle)?;
        let across = self.across_cells * cell_size;
        if !(across.is_finite() && across > 0.0) {
            return Err(SmoothingError::BadParam {
                name: "across_cells",
                why: format!("across_cells × cell_size = {across} is not a positive distance"),
            });
        }
        Ok(())
    }
}

/// The smoothing-set tests of §3.2.
struct SmoothingSet {
    along: f64,
    across: f64,
    min_cos: f64,
}

impl SmoothingSet {
    /// Whether `t` belongs to the smoothing set of `s`. Normals compare as oriented when both
    /// samples were seen by a scanner, else as lines (an unoriented normal's sign means nothing).
    fn contains(&self, s: &WallSample, t: &WallSample) -> bool {
        let d = sub(t.pos, s.pos);
        let cos = dot(s.normal, t.normal);
        let oriented = !s.seen_from.is_empty() && !t.seen_from.is_empty();
        dot(d, s.normal).abs() <= self.along
            && cross(s.normal, d).abs() <= self.across
            && (if oriented { cos } else { cos.abs() }) >= self.min_cos
    }

    /// The mean position of the smoothing set of `s`, which always holds `s` itself.
    fn mean(&self, s: &WallSample, all: &[WallSample], index: &Buckets) -> P2 {
        let (mut sum, mut n) = ([0.0, 0.0], 0usize);
        for k in index.near(s.pos) {
            let t = &all[k as usize];
            if self.contains(s, t) {
                sum = [sum[0] + t.pos[0], sum[1] + t.pos[1]];
                n += 1;
            }
        }
        if n == 0 {
            return s.pos;
        }
        [sum[0] / n as f64, sum[1] / n as f64]
    }
}

/// Samples bucketed on a square grid of the search radius: a disc of that radius around any
/// point lies in the 3 × 3 buckets around it.
struct Buckets {
    size: f64,
    cells: HashMap<(i64, i64), Vec<u32>>,
}

impl Buckets {
    fn new(samples: &[WallSample], size: f64) -> Buckets {
        let mut cells: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
        for (k, s) in samples.iter().enumerate() {
            cells.entry(key(s.pos, size)).or_default().push(k as u32);
        }
        Buckets { size, cells }
    }

    fn near(&self, p: P2) -> impl Iterator<Item = u32> + '_ {
        let (i, j) = key(p, self.size);
        (-1..=1)
            .flat_map(move |di| {
                (-1..=1).map(move |dj| (i.saturating_add(di), j.saturating_add(dj)))
            })
            .filter_map(|c| self.cells.get(&c))
            .flatten()
            .copied()
    }
}

fn key(p: P2, size: f64) -> (i64, i64) {
    ((p[0] / size).floor() as i64, (p[1] / size).floor() as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(pos: P2, normal: P2, seen: bool) -> WallSample {
        WallSample {
            pos,
            normal,
            confidence: 1.0,
            seen_from: if seen { vec![0] } else { Vec::new() },
        }
    }

    /// Samples every 4 cm along x from 0 to 2 m at height `y` (off the 15 cm set boundary).
    fn wall(y: f64, normal: P2, seen: bool) -> Vec<WallSample> {
        (0..=50)
            .map(|k| sample([0.04 * k as f64, y], normal, seen))
            .collect()
    }

    fn on(error: f64) -> SmoothingParams {
        SmoothingParams {
            registration_error: Some(error),
            ..Default::default()
        }
    }

    #[test]
    fn two_offset_copies_of_a_wall_converge() {
        let mut s = WallSamples {
            samples: [wall(0.0, [0.0, 1.0], false), wall(0.02, [0.0, 1.0], false)].concat(),
            ..Default::default()
        };
        smooth_samples(&mut s, 0.05, &on(0.02), &Cancel::never()).unwrap();
        for t in &s.samples {
            assert!((t.pos[1] - 0.01).abs() < 1e-12, "{t:?}");
        }
        // Along the wall, interior samples stay where they were (symmetric sets).
        assert!((s.samples[25].pos[0] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn off_by_default() {
        let before = WallSamples {
            samples: [wall(0.0, [0.0, 1.0], false), wall(0.02, [0.0, 1.0], false)].concat(),
            ..Default::default()
        };
        let mut after = before.clone();
        smooth_samples(
            &mut after,
            0.05,
            &SmoothingParams::default(),
            &Cancel::never(),
        )
        .unwrap();
        assert_eq!(before, after);
    }

    #[test]
    fn walls_at_an_angle_or_facing_away_stay_apart() {
        // A perpendicular wall meeting the first at x = 1, and the far face of a 6 cm wall.
        let across: Vec<WallSample> = (1..=10)
            .map(|k| sample([1.0, 0.05 * k as f64], [1.0, 0.0], true))
            .collect();
        let mut s = WallSamples {
            samples: [
                wall(0.0, [0.0, 1.0], true),
                across,
                wall(-0.06, [0.0, -1.0], true),
            ]
            .concat(),
            ..Default::default()
        };
        let before = s.clone();
        smooth_samples(&mut s, 0.05, &on(0.05), &Cancel::never()).unwrap();
        for (a, b) in s.samples.iter().zip(&before.samples) {
            // Only moves along a wall, never across it.
            let moved = sub(a.pos, b.pos);
            assert!(dot(moved, a.normal).abs() < 1e-12, "{b:?} → {a:?}");
        }
        // Unoriented, the two faces merge into one line.
        let mut faces = WallSamples {
            samples: [
                wall(0.0, [0.0, 1.0], false),
                wall(-0.06, [0.0, -1.0], false),
            ]
            .concat(),
            ..Default::default()
        };
        smooth_samples(&mut faces, 0.05, &on(0.05), &Cancel::never()).unwrap();
        assert!(faces
            .samples
            .iter()
            .all(|t| (t.pos[1] + 0.03).abs() < 1e-12));
    }

    #[test]
    fn bad_parameters_are_named() {
        let mut s = WallSamples::default();
        let err = smooth_samples(&mut s, 0.05, &on(-1.0), &Cancel::never()).unwrap_err();
        assert!(matches!(
            err,
            SmoothingError::BadParam {
                name: "registration_error",
                ..
            }
        ));
        let p = SmoothingParams {
            max_angle: 4.0,
            ..on(0.01)
        };
        assert!(matches!(
            smooth_samples(&mut s, 0.05, &p, &Cancel::never()),
            Err(SmoothingError::BadParam {
                name: "max_angle",
                ..
            })
        ));
    }
}
