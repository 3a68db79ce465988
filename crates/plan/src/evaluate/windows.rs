//! Windows against the truth: each truth window paired with the nearest plan window whose
//! centre is within `WINDOW_MATCH_DISTANCE` (nearest pairs first, each once), and the matched
//! pairs' centre, width, sill and head errors.

use serde::Serialize;

use crate::geom;
use crate::plan::StoryPlan;
use crate::simulate::truth::TruthStory;

/// A plan window is the truth window's when their centres are this close, m: a finding, not
/// yet a good one; the errors say how good.
pub const WINDOW_MATCH_DISTANCE: f64 = 0.3;

/// One story's windows.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct WindowsScore {
    /// Windows in the truth.
    pub truth_windows: usize,
    /// Windows in the plan.
    pub plan_windows: usize,
    /// Truth windows a plan window matched.
    pub matched: usize,
    /// Of the matched windows: the largest centre error, m.
    pub centre_max: f64,
    /// The largest width error, m.
    pub width_max: f64,
    /// The largest sill height error, m.
    pub sill_max: f64,
    /// The largest head height error, m.
    pub head_max: f64,
}

impl WindowsScore {
    /// Share of truth windows matched (1 when the truth has none and the plan none).
    pub fn recall(&self) -> f64 {
        ratio(self.matched, self.truth_windows)
    }
    /// Share of plan windows that match a truth window.
    pub fn precision(&self) -> f64 {
        ratio(self.matched, self.plan_windows)
    }
    /// One line, for reports.
    pub fn summary(&self) -> String {
        format!(
            "windows {}/{} matched ({} in plan): recall {:.3} precision {:.3}, centre max {:.3} m, width max {:.3} m, sill max {:.3} m, head max {:.3} m",
            self.matched,
            self.truth_windows,
            self.plan_windows,
            self.recall(),
            self.precision(),
            self.centre_max,
            self.width_max,
            self.sill_max,
            self.head_max,
        )
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    match (a, b) {
        (0, 0) => 1.0,
        (_, 0) => 0.0,
        _ => a as f64 / b as f64,
    }
}

/// Scores `plan`'s windows (already in the truth's frame) against `truth`; `None` when the
/// truth has no windows and the plan none (nothing to say).
pub fn score_windows(plan: &StoryPlan, truth: &TruthStory) -> Option<WindowsScore> {
    let found = &plan.spaces.windows;
    if truth.windows.is_empty() && found.is_empty() {
        return None;
    }
    let mut pairs = Vec::new();
    for (i, t) in truth.windows.iter().enumerate() {
        for (j, w) in found.iter().enumerate() {
            let e = geom::dist(geom::scale(geom::add(w.a, w.b), 0.5), t.center());
            if e <= WINDOW_MATCH_DISTANCE {
                pairs.push((e, i, j));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut used_t = vec![false; truth.windows.len()];
    let mut used_p = vec![false; found.len()];
    let mut out = WindowsScore {
        truth_windows: truth.windows.len(),
        plan_windows: found.len(),
        ..Default::default()
    };
    for (e, i, j) in pairs {
        if used_t[i] || used_p[j] {
            continue;
        }
        (used_t[i], used_p[j]) = (true, true);
        let (t, w) = (&truth.windows[i], &found[j]);
        out.matched += 1;
        out.centre_max = out.centre_max.max(e);
        out.width_max = out.width_max.max((w.width - t.width).abs());
        out.sill_max = out.sill_max.max((w.sill_z - t.sill_z).abs());
        out.head_max = out.head_max.max((w.head_z - t.head_z).abs());
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::Window;
    use crate::simulate::truth::TruthWindow;

    fn truth_with(windows: Vec<TruthWindow>) -> TruthStory {
        TruthStory {
            level: 0,
            floor_z: 0.0,
            ceiling_z: 2.5,
            polygons: Vec::new(),
            walls: Vec::new(),
            rooms: Vec::new(),
            doors: Vec::new(),
            windows,
        }
    }

    fn plan_with(windows: Vec<Window>) -> StoryPlan {
        StoryPlan {
            level: 0,
            floor_z: 0.0,
            ceiling_z: 2.5,
            polygons: Vec::new(),
            walls: Vec::new(),
            samples: Vec::new(),
            spaces: crate::plan::Spaces {
                windows,
                ..Default::default()
            },
            underlay: None,
        }
    }

    fn window(x0: f64, x1: f64, sill: f64, head: f64) -> Window {
        Window {
            id: String::new(),
            a: [x0, 0.0],
            b: [x1, 0.0],
            width: x1 - x0,
            sill_z: sill,
            head_z: head,
            room: None,
        }
    }

    #[test]
    fn matches_nearest_windows_and_measures_their_errors() {
        let t = |x0: f64, x1: f64| TruthWindow {
            a: [x0, 0.0],
            b: [x1, 0.0],
            width: x1 - x0,
            sill_z: 0.9,
            head_z: 2.1,
            depth: 0.3,
            outward: [0.0, -1.0],
        };
        let truth = truth_with(vec![t(1.0, 2.0), t(5.0, 6.2)]);
        // The first found 4 cm wide and 5 cm low; the second missed; one window extra.
        let plan = plan_with(vec![
            window(0.98, 2.02, 0.85, 2.1),
            window(8.0, 9.0, 0.9, 2.1),
        ]);
        let s = score_windows(&plan, &truth).unwrap();
        assert_eq!((s.truth_windows, s.plan_windows, s.matched), (2, 2, 1));
        assert!((s.recall() - 0.5).abs() < 1e-12 && (s.precision() - 0.5).abs() < 1e-12);
        assert!(s.centre_max < 1e-12);
        assert!((s.width_max - 0.04).abs() < 1e-9);
        assert!((s.sill_max - 0.05).abs() < 1e-9 && s.head_max < 1e-12);
        // Nothing on either side: nothing to score.
        assert_eq!(
            score_windows(&plan_with(Vec::new()), &truth_with(Vec::new())),
            None
        );
    }
}
