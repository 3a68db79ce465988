//! # asbuilt-plan
//!
//! Turns a point cloud of a building interior into a watertight floor plan per story, after
//! Turner & Zakhor, "Watertight As-Built Architectural Floor Plans Generated from Laser Range
//! Data". The crate is pure and synchronous: no HTTP, no async runtime, no database. Only
//! [`io`] touches files.
//!
//! # Entry points
//! Both are re-exported here, with an example each:
//! - [`plan_scan`]: a scan file and its sidecar in, the plan with every stage's time out (the
//!   CLI and the service's worker call only this). [`Scan`] says what to read and how.
//! - [`plan()`]: the stages on a [`PointCloud`] already in memory.
//!
//! # Layout
//! - [`run::plan_scan`] is the front door: a scan file and its sidecar in, the plan out.
//! - [`pipeline::plan`] runs the stages in order:
//!   [`stories`] → [`samples`] → [`smoothing`] → [`labeling`] → [`cleanup`] → [`boundary`] → [`fitting`].
//! - [`params::Params`] holds every stage's parameters, with the paper's defaults and each
//!   number's accepted range.
//! - [`cancel::Cancel`] stops a run from outside (a flag, a deadline): every long loop checks it.
//! - [`cloud::PointCloud`] is the input, [`plan::FloorPlan`] the output.
//! - [`viewpoints`] estimates scanner positions the input does not give.
//! - [`io`] reads clouds and pose sidecars and writes GeoJSON, SVG and DXF.
//! - [`simulate`] builds and scans synthetic buildings with exact ground truth; [`evaluate`] scores plans.

#![warn(missing_docs)]

pub mod boundary;
pub mod cancel;
pub mod cleanup;
pub mod cloud;
pub mod evaluate;
pub mod fitting;
pub mod geom;
pub mod georef;
pub mod io;
pub mod labeling;
pub mod params;
pub mod pipeline;
pub mod plan;
pub mod progress;
pub mod rooms;
pub mod run;
pub mod samples;
pub mod simulate;
pub mod smoothing;
pub mod stories;
pub mod streaming;
pub mod underlay;
pub mod validity;
pub mod viewpoints;

pub use cancel::{Cancel, Cancelled};
pub use cloud::PointCloud;
pub use io::{ReadOptions, SidecarKind};
pub use params::Params;
pub use pipeline::{plan, PlanError};
pub use plan::FloorPlan;
pub use progress::{NoProgress, Progress, Stage};
pub use run::{plan_decoded, plan_scan, Planned, RunError, Scan};
pub use streaming::StreamingParams;
