//! Cancellation and time limits reach inside every stage: each stage returns its `Cancelled`
//! error once the token is raised, a search with an absurd iteration count stops soon after a
//! cancel, and a whole plan stops at its deadline with `time_limit`.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use asbuilt_plan::boundary::trace_boundary;
use asbuilt_plan::fitting::ransac::find_models;
use asbuilt_plan::fitting::{fit_walls, BoundarySamples, FittingError, FittingParams};
use asbuilt_plan::io::{ply, read_cloud_with, ReadError, ReadOptions};
use asbuilt_plan::labeling::{label, LabelingError};
use asbuilt_plan::progress::{Progress, Stage};
use asbuilt_plan::samples::{sample_walls, SamplesError};
use asbuilt_plan::simulate::{simulate, BuildingKind, ScanOptions};
use asbuilt_plan::smoothing::{smooth_samples, SmoothingError, SmoothingParams};
use asbuilt_plan::stories::split_cloud_stories;
use asbuilt_plan::{Cancel, Cancelled, Params, PlanError};

/// A progress that hands the run a given token.
struct Stoppable(Cancel);

impl Progress for Stoppable {
    fn report(&mut self, _: Stage, _: f64) {}
    fn cancel(&self) -> Cancel {
        self.0.clone()
    }
}

fn raised() -> Cancel {
    let c = Cancel::new();
    c.cancel();
    c
}

#[test]
fn every_stage_returns_cancelled_once_the_flag_is_raised() {
    let sim = simulate(
        BuildingKind::SquareRoom,
        &ScanOptions {
            points: 120_000,
            seed: 3,
            ..Default::default()
        },
    )
    .unwrap();
    let cloud = &sim.cloud;
    let params = Params::default();
    let never = Cancel::never();
    let stories = split_cloud_stories(&cloud.xyz, &params.stories).unwrap();
    let story = &stories[0];

    let stop = raised();
    assert_eq!(
        sample_walls(cloud, story, &params.samples, &stop).unwrap_err(),
        SamplesError::Cancelled(Cancelled::ByCaller)
    );
    let mut samples = sample_walls(cloud, story, &params.samples, &never).unwrap();

    let smoothing = SmoothingParams {
        registration_error: Some(0.01),
        ..Default::default()
    };
    let before = samples.clone();
    assert_eq!(
        smooth_samples(&mut samples, 0.05, &smoothing, &stop).unwrap_err(),
        SmoothingError::Cancelled(Cancelled::ByCaller)
    );
    assert_eq!(samples, before, "a cancelled smoothing leaves the samples");

    assert_eq!(
        label(&samples, &params.labeling, &stop).unwrap_err(),
        LabelingError::Cancelled(Cancelled::ByCaller)
    );
    let labeled = label(&samples, &params.labeling, &never).unwrap();
    let boundary = trace_boundary(&labeled).unwrap();
    assert_eq!(
        fit_walls(&labeled, &boundary, &params.fitting, &stop).unwrap_err(),
        FittingError::Cancelled(Cancelled::ByCaller)
    );
    assert!(fit_walls(&labeled, &boundary, &params.fitting, &never).is_ok());

    let err = asbuilt_plan::plan(cloud, &params, &mut Stoppable(stop.clone())).unwrap_err();
    assert!(
        matches!(err, PlanError::Cancelled(Cancelled::ByCaller)),
        "{err}"
    );
    assert_eq!(err.code(), "cancelled");

    // The readers: the token is checked whenever the reader asks for bytes.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.ply");
    ply::write_ply(&path, cloud, ply::Encoding::BinaryLittleEndian).unwrap();
    let stopped = ReadOptions {
        cancel: stop,
        ..Default::default()
    };
    match read_cloud_with(&path, &stopped) {
        Err(e @ ReadError::Cancelled(Cancelled::ByCaller, _)) => assert_eq!(e.code(), "cancelled"),
        other => panic!("{:?}", other.map(|c| c.len())),
    }
    assert_eq!(
        read_cloud_with(&path, &ReadOptions::default())
            .unwrap()
            .len(),
        cloud.len()
    );
}

#[test]
fn a_plan_past_its_deadline_stops_with_time_limit() {
    let sim = simulate(
        BuildingKind::SquareRoom,
        &ScanOptions {
            points: 50_000,
            seed: 4,
            ..Default::default()
        },
    )
    .unwrap();
    let late = Cancel::new().with_deadline(Instant::now());
    let err = asbuilt_plan::plan(&sim.cloud, &Params::default(), &mut Stoppable(late)).unwrap_err();
    assert!(
        matches!(err, PlanError::Cancelled(Cancelled::TimeLimit)),
        "{err}"
    );
    assert_eq!(err.code(), "time_limit");
}

/// Samples around a circle of radius 5 m, spaced 2.5 cm, with random normals: no model finds
/// `min_inliers` of them, so RANSAC would run every one of its iterations.
fn noise(n: usize) -> BoundarySamples {
    let pos: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let a = i as f64 / n as f64 * std::f64::consts::TAU;
            let r = 5.0 + 0.3 * ((i * 7919) % 13) as f64;
            [r * a.cos(), r * a.sin()]
        })
        .collect();
    let normal = (0..n)
        .map(|i| {
            let a = (i * 104_729 % 360) as f64 * std::f64::consts::PI / 180.0;
            Some([a.cos(), a.sin()])
        })
        .collect();
    let adj = (0..n)
        .map(|i| vec![((i + n - 1) % n) as u32, ((i + 1) % n) as u32])
        .collect();
    BoundarySamples {
        pos,
        normal,
        adj,
        oriented: vec![true; n],
    }
}

/// `fitting.iterations` far beyond its documented range (the service refuses it up front;
/// the stage itself must still stop): the search ends soon after the cancel.
#[test]
fn an_unbounded_ransac_search_stops_after_a_cancel() {
    let samples = noise(2000);
    let params = FittingParams {
        iterations: usize::MAX,
        min_inliers: 500,
        ..Default::default()
    };
    let cancel = Cancel::new();
    let run = cancel.clone();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let out = find_models(&samples, &params, &run).map(|c| c.models.len());
        let _ = tx.send((out, Instant::now()));
    });
    // Let it get going, then stop it.
    std::thread::sleep(Duration::from_millis(300));
    assert!(rx.try_recv().is_err(), "the search ended on its own");
    let asked = Instant::now();
    cancel.cancel();
    let (out, ended) = rx
        .recv_timeout(Duration::from_secs(60))
        .expect("the search stops after a cancel");
    assert_eq!(out.unwrap_err(), Cancelled::ByCaller);
    eprintln!(
        "RANSAC with usize::MAX iterations stopped {:.3} ms after the cancel",
        ended.saturating_duration_since(asked).as_secs_f64() * 1e3
    );
}
