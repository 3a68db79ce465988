//! Windows on the simulator's buildings that have them, against their exact truth: every
//! window found and none extra, its centre and width within 5 cm, its sill and head within
//! 5 cm, with poses and without.

use asbuilt_plan::evaluate::windows::WindowsScore;
use asbuilt_plan::evaluate::{evaluate, EvaluateParams};
use asbuilt_plan::progress::NoProgress;
use asbuilt_plan::simulate::{simulate, BuildingKind, Keep, ScanOptions};
use asbuilt_plan::Params;

/// Plans a simulated building and scores its windows, story by story.
fn windows(kind: BuildingKind, points: usize, seed: u64, keep: Keep) -> Vec<WindowsScore> {
    let sim = simulate(
        kind,
        &ScanOptions {
            points,
            seed,
            keep,
            ..Default::default()
        },
    )
    .expect("simulation");
    let plan = asbuilt_plan::plan(&sim.cloud, &Params::default(), &mut NoProgress).expect("plan");
    let e = evaluate(&plan, &sim.truth, &EvaluateParams::default());
    for (s, t) in plan.stories.iter().zip(&sim.truth.stories) {
        for w in &t.windows {
            eprintln!(
                "{} {keep:?} level {} truth  {:?} {:?} w {:.3} sill {:.3} head {:.3}",
                kind.name(),
                t.level,
                w.a,
                w.b,
                w.width,
                w.sill_z,
                w.head_z
            );
        }
        for w in &s.spaces.windows {
            eprintln!(
                "{} {keep:?} level {} found  {:?} {:?} w {:.3} sill {:.3} head {:.3}",
                kind.name(),
                s.level,
                w.a,
                w.b,
                w.width,
                w.sill_z,
                w.head_z
            );
        }
    }
    eprintln!("{} {keep:?}:\n{}", kind.name(), e.summary());
    e.stories
        .iter()
        .map(|s| s.windows.clone().expect("the truth has windows"))
        .collect()
}

fn assert_bounds(name: &str, level: usize, s: &WindowsScore) {
    let line = s.summary();
    assert!(
        s.truth_windows > 0,
        "{name} level {level}: no truth windows"
    );
    assert_eq!(
        (s.matched, s.plan_windows),
        (s.truth_windows, s.truth_windows),
        "{name} level {level}: count\n{line}"
    );
    assert!(s.centre_max <= 0.05, "{name} level {level}: centre\n{line}");
    assert!(s.width_max <= 0.05, "{name} level {level}: width\n{line}");
    assert!(s.sill_max <= 0.05, "{name} level {level}: sill\n{line}");
    assert!(s.head_max <= 0.05, "{name} level {level}: head\n{line}");
}

#[test]
fn rotated_l_windows() {
    for keep in [Keep::Poses, Keep::ScanIds] {
        for (level, s) in windows(BuildingKind::RotatedL, 400_000, 14, keep)
            .iter()
            .enumerate()
        {
            assert_bounds("rotated_l", level, s);
        }
    }
}

#[test]
fn office_windows() {
    for keep in [Keep::Poses, Keep::ScanIds] {
        let scores = windows(BuildingKind::Office3Story, 1_500_000, 12, keep);
        assert_eq!(scores.len(), 3);
        for (level, s) in scores.iter().enumerate() {
            assert_bounds("office_3story", level, s);
        }
    }
}
