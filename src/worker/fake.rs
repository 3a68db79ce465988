//! A synthetic pipeline for testing the service without the real stages (`--fake-pipeline-ms`).
//!
//! It counts the cloud's non-empty lines as points, spends a fixed time in each stage (checking
//! for cancellation every 10 ms), and returns a 4 m × 3 m one-story plan (two rooms, a door, a
//! window and five walls with thickness) through the real writers (with `spin`, it burns CPU instead of sleeping). A cloud whose text contains `#fail:CODE` fails with CODE; `#panic` panics;
//! `#hang:SECS` spends SECS seconds in the fit stage without looking at its stop token (a
//! stage stuck in a call that cannot be interrupted); `#stories:N` walks the per-story stages N
//! times, reporting each story's number (the plan still has one). Each run that completes appends its job
//! id to the completions log, so tests can count runs.

use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use asbuilt_plan::plan::{
    Door, DoorKind, FloorPlan, InputSummary, Polygon, Room, Spaces, StoryPlan, Wall, WallCentre,
    WallModel, Window,
};
use asbuilt_plan::progress::{Progress, Stage, STAGES};
use asbuilt_plan::underlay::Underlay;

use crate::errors::JobCode;

use super::pipeline::{check_points, JobInput, JobResults, Pipeline, PipelineFailure};

/// The stages the fake walks through: the pipeline's own table, less smoothing, which the
/// fake's plan reports as turned off (so the page shows it skipped).
fn stages() -> impl Iterator<Item = Stage> {
    STAGES
        .iter()
        .map(|row| row.stage)
        .filter(|s| *s != Stage::Smoothing)
}

/// See the module documentation.
pub struct FakePipeline {
    pub stage_time: Duration,
    pub completions: Option<PathBuf>,
    /// Burn CPU instead of sleeping (load measurements).
    pub spin: bool,
}

impl FakePipeline {
    fn wait(&self, progress: &dyn Progress) -> Result<(), PipelineFailure> {
        let end = Instant::now() + self.stage_time;
        loop {
            if progress.cancelled() {
                return Err(PipelineFailure::cancelled());
            }
            let now = Instant::now();
            if now >= end {
                return Ok(());
            }
            if self.spin {
                let until = now + (end - now).min(Duration::from_millis(10));
                while Instant::now() < until {
                    std::hint::spin_loop();
                }
            } else {
                std::thread::sleep((end - now).min(Duration::from_millis(10)));
            }
        }
    }
}

/// A room over the rectangle `[x0, x1] × [0, 3]`, floor 0 to ceiling 2.5.
fn room(id: &str, x0: f64, x1: f64, neighbour: &str) -> Room {
    Room {
        id: id.into(),
        polygon: Polygon {
            exterior: vec![[x0, 0.0], [x1, 0.0], [x1, 3.0], [x0, 3.0]],
            holes: vec![],
        },
        area: (x1 - x0) * 3.0,
        perimeter: 2.0 * (x1 - x0 + 3.0),
        floor_z: 0.0,
        ceiling_z: 2.5,
        scanners: vec![],
        neighbours: vec![neighbour.into()],
    }
}

/// The fake plan's rooms: a 10 cm wall at x = 2.5 with a door splits the 4 × 3 m floor; a
/// window lights the west room; exterior walls (30 cm assumed) run round the outside.
/// Points under the fake plan: its outline dark (walls in the slice), the floor pale, at 10 cm,
/// reaching 0.5 m beyond the outline on every side.
fn underlay() -> Underlay {
    let (nx, ny) = (50, 40);
    let levels = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| (i, j)))
        .map(|(i, j)| {
            let on_wall = |k: usize, at: usize| k.abs_diff(at) <= 1;
            let inside = (5..=45).contains(&i) && (5..=35).contains(&j);
            match inside && (on_wall(i, 5) || on_wall(i, 45) || on_wall(j, 5) || on_wall(j, 35)) {
                true => 255,
                false if inside => 1,
                false => 0,
            }
        })
        .collect();
    Underlay {
        origin: [-0.5, -0.5],
        cell: 0.1,
        nx,
        ny,
        slice_z: [1.0, 1.5],
        levels,
        full: 100,
    }
}

fn spaces() -> Spaces {
    let some = |id: &str| Some(id.to_string());
    let wall =
        |n: usize, a: [f64; 2], b: [f64; 2], thickness: f64, left: &str, right: Option<String>| {
            WallCentre {
                id: format!("L0-C{n}"),
                a,
                b,
                thickness,
                exterior: right.is_none(),
                rooms: [some(left), right],
            }
        };
    let o = 0.15;
    Spaces {
        rooms: vec![
            room("L0-R1", 0.0, 2.45, "L0-R2"),
            room("L0-R2", 2.55, 4.0, "L0-R1"),
        ],
        doors: vec![Door {
            id: "L0-D1".into(),
            kind: DoorKind::Door,
            a: [2.5, 1.0],
            b: [2.5, 1.9],
            width: 0.9,
            head_z: Some(2.0),
            depth: 0.1,
            rooms: [some("L0-R1"), some("L0-R2")],
        }],
        windows: vec![Window {
            id: "L0-W1".into(),
            a: [0.6, -o],
            b: [1.8, -o],
            width: 1.2,
            sill_z: 0.9,
            head_z: 2.1,
            room: some("L0-R1"),
        }],
        walls: vec![
            wall(1, [2.5, 0.0], [2.5, 3.0], 0.1, "L0-R1", some("L0-R2")),
            wall(2, [-o, -o], [4.0 + o, -o], 0.3, "L0-R1", None),
            wall(3, [4.0 + o, -o], [4.0 + o, 3.0 + o], 0.3, "L0-R2", None),
            wall(4, [4.0 + o, 3.0 + o], [-o, 3.0 + o], 0.3, "L0-R2", None),
            wall(5, [-o, 3.0 + o], [-o, -o], 0.3, "L0-R1", None),
        ],
    }
}

/// The plan every fake run returns: one story, a 4 × 3 m floor in two rooms, one arc wall.
pub fn square_plan(points: u64) -> FloorPlan {
    let arc: Vec<[f64; 2]> = (0..=8)
        .map(|i| {
            let a = std::f64::consts::PI * (i as f64 / 8.0 - 0.5);
            [4.0 + 0.5 * a.cos(), 1.5 + 0.5 * a.sin()]
        })
        .collect();
    FloorPlan {
        origin: [0.0; 3],
        crs: None,
        georeference: None,
        input: InputSummary {
            points,
            format: "xyz".into(),
            scans: 0,
            ..Default::default()
        },
        parameters: asbuilt_plan::Params::default().to_json(),
        timings_ms: vec![],
        stories: vec![StoryPlan {
            level: 0,
            floor_z: 0.0,
            ceiling_z: 2.5,
            polygons: vec![Polygon {
                exterior: vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]],
                holes: vec![],
            }],
            walls: vec![
                Wall {
                    model: WallModel::Line,
                    points: vec![[0.0, 0.0], [4.0, 0.0]],
                    support: 10,
                },
                Wall {
                    model: WallModel::Arc {
                        center: [4.0, 1.5],
                        radius: 0.5,
                    },
                    points: arc,
                    support: 5,
                },
            ],
            samples: vec![],
            spaces: spaces(),
            underlay: Some(underlay()),
        }],
        notes: vec![],
    }
}

/// The stages in the order a run of `stories` stories reports them, with the run's fraction and
/// the story (from 1) of the per-story ones.
fn walk(stories: usize) -> Vec<(Stage, f64, Option<usize>)> {
    let per_story = |s: &Stage| s.row().weight > 0.0;
    let mut out: Vec<_> = stages()
        .filter(|s| !per_story(s) && *s != Stage::Write)
        .map(|s| (s, 0.0, None))
        .collect();
    for k in 0..stories {
        for s in stages().filter(per_story) {
            out.push((s, (k as f64 + s.start()) / stories as f64, Some(k + 1)));
        }
    }
    out.push((Stage::Write, 1.0, None));
    out
}

impl Pipeline for FakePipeline {
    fn run(
        &self,
        input: &JobInput,
        progress: &mut dyn Progress,
    ) -> Result<JobResults, PipelineFailure> {
        let text = std::fs::read(&input.cloud)
            .map_err(|e| PipelineFailure::new(JobCode::IoError, e.to_string()))?;
        let text = String::from_utf8_lossy(&text);
        if text.contains("#panic") {
            panic!("the fake pipeline was asked to panic");
        }
        if let Some(rest) = text.split("#fail:").nth(1) {
            let code: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            return Err(PipelineFailure::from_pipeline(
                &code,
                "the fake pipeline was asked to fail",
            ));
        }
        let points = text
            .lines()
            .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
            .count() as u64;
        check_points(points, input.max_points)?;
        let directive = |name: &str| -> Option<f64> {
            text.split(name)
                .nth(1)
                .and_then(|rest| rest.split_whitespace().next())
                .and_then(|s| s.parse().ok())
        };
        let hang = directive("#hang:");
        let stories = directive("#stories:").map_or(1, |n| n.clamp(1.0, 20.0) as usize);
        // Reading, as the real pipeline reports it: the file's bytes, all read at once.
        let bytes = text.len() as u64;
        let mut timings: Vec<(String, u64)> = vec![];
        for (stage, fraction, story) in walk(stories) {
            if let Some(k) = story {
                progress.story(k, stories);
            }
            progress.report(stage, fraction);
            if stage == Stage::Read {
                progress.read(bytes, bytes);
            }
            let start = Instant::now();
            if let (Some(secs), Stage::Fitting) = (hang, stage) {
                std::thread::sleep(Duration::from_secs_f64(secs.clamp(0.0, 3600.0)));
            }
            self.wait(progress)?;
            let ms = start.elapsed().as_millis() as u64;
            match timings.iter_mut().find(|(n, _)| n == stage.name()) {
                Some((_, t)) => *t += ms,
                None => timings.push((stage.name().to_string(), ms)),
            }
        }
        let total = timings.iter().map(|(_, ms)| ms).sum();
        timings.push(("total".into(), total));
        let mut plan = square_plan(points);
        plan.timings_ms = timings.clone();
        // Placed as the real pipeline places it, so the WGS84 copy can be followed end to end.
        plan.georeference = input.georeference.clone();
        // The writers read their options from the plan's parameters, as after a real run.
        plan.parameters["svg_underlay"] = input.params.svg_underlay.into();
        let results = JobResults::of(&plan)?;
        if let Some(log) = &self.completions {
            let mut f = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(log)
                .map_err(|e| PipelineFailure::new(JobCode::IoError, e.to_string()))?;
            // One write per line: `writeln!` writes the id and the newline separately, and two
            // workers appending at once interleaved them ("id1id2\n\n").
            let _ = f.write_all(format!("{}\n", input.job).as_bytes());
        }
        Ok(results)
    }
}
