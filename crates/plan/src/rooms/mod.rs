//! Stage 8 (beyond the paper): a story's free floor divided into rooms, joined by doors and
//! openings, with its walls as centre lines with a thickness.
//!
//! The story's valid polygons are the input: interior walls show in them as slits and holes
//! whose two faces lie a wall's thickness apart. The steps, one module each:
//! 1. `faces`: the polygons' boundary edges, each with the free floor on its left.
//! 2. `pairing`: two antiparallel faces a plausible thickness apart, with solid between them,
//!    are one wall: a centre line and a thickness. Faces left alone on the outer ring are
//!    exterior walls of an assumed thickness.
//! 3. `gaps`: from each end of a paired wall, along its centre line, the free floor up to the
//!    next face is a gap (a door's width apart); the points over it tell a door (wall above,
//!    a lintel) from an opening (nothing between the door height and the ceiling), and a gap
//!    the points show walled under the door height (a stretch of wall the plan lost) from both.
//! 4. `segment`: the gaps cut the free floor; what falls apart are the rooms. A door that
//!    separates nothing (free floor goes around it, as between a column and a wall) is no door
//!    and its cut is undone; an opening stays only when both sides are rooms of their own.
//! 5. `windows`: gaps in the points along outer walls with wall below and above them.

pub(crate) mod faces;
pub(crate) mod gaps;
pub(crate) mod pairing;
pub(crate) mod segment;
pub(crate) mod windows;

#[cfg(test)]
mod tests;

use std::ops::{Range, RangeInclusive};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geom::P2;
use crate::params::{within, ParamRange};
use crate::plan::{Spaces, StoryPlan};
use crate::samples::Blocks;
use crate::validity::Grid;

/// Parameters of [`find_rooms`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RoomsParams {
    /// Divide stories into rooms at all.
    pub enabled: bool,
    /// Two opposite faces this close or closer are not a wall (noise), m. Range 0..=0.2.
    pub min_thickness: f64,
    /// Two opposite faces farther apart are not one wall, m. Range 0.05..=1.
    pub max_thickness: f64,
    /// Opposite faces must run side by side for at least this long to pair, m. Short, so the
    /// 20 cm stub of wall beside a closet door pairs. Range 0.02..=2.
    pub min_overlap: f64,
    /// Faces within this angle of antiparallel may pair, degrees. Range 0..=20.
    pub max_angle_deg: f64,
    /// Gaps narrower than this are not doors, m. Range 0.1..=2.
    pub min_door_width: f64,
    /// Gaps wider than this are not doors or openings, m. Range 0.3..=10.
    pub max_door_width: f64,
    /// A lintel's underside is at least this high above the floor, m. Range 0.5..=5.
    pub min_head_height: f64,
    /// Points this close under the story's ceiling are ceiling, not a lintel, m. Range 0..=1.
    pub ceiling_margin: f64,
    /// A gap has a lintel when this share of its 10 cm slices along its width hold a point
    /// between the door height and the ceiling. Range 0..=1.
    pub lintel_coverage: f64,
    /// Pieces of free floor smaller than this are not rooms, m². Range 0..=100.
    pub min_room_area: f64,
    /// An opening (no lintel) divides two rooms only when each side is at least this large, m².
    /// Range 0..=1000.
    pub min_opening_room_area: f64,
    /// The thickness assumed for a wall seen from one side only, m. Range 0.01..=2.
    pub exterior_thickness: f64,
    /// Exterior walls shorter than this are left out (door jambs, corners), m. Range 0..=10.
    pub min_exterior_length: f64,
    /// Windows narrower than this are not looked at, m. Range 0.1..=5.
    pub min_window_width: f64,
    /// A window's sill is at least this high above the floor (lower gaps are doors), m.
    /// Range 0..=3.
    pub min_sill_height: f64,
}

/// The accepted values of [`RoomsParams`] (see [`crate::params::ParamRange`]).
pub const RANGES: &[ParamRange] = &[
    ParamRange::new("min_thickness", 0.0, 0.2, "m"),
    ParamRange::new("max_thickness", 0.05, 1.0, "m"),
    ParamRange::new("min_overlap", 0.02, 2.0, "m"),
    ParamRange::new("max_angle_deg", 0.0, 20.0, "°"),
    ParamRange::new("min_door_width", 0.1, 2.0, "m"),
    ParamRange::new("max_door_width", 0.3, 10.0, "m"),
    ParamRange::new("min_head_height", 0.5, 5.0, "m"),
    ParamRange::new("ceiling_margin", 0.0, 1.0, "m"),
    ParamRange::new("lintel_coverage", 0.0, 1.0, ""),
    ParamRange::new("min_room_area", 0.0, 100.0, "m²"),
    ParamRange::new("min_opening_room_area", 0.0, 1000.0, "m²"),
    ParamRange::new("exterior_thickness", 0.01, 2.0, "m"),
    ParamRange::new("min_exterior_length", 0.0, 10.0, "m"),
    ParamRange::new("min_window_width", 0.1, 5.0, "m"),
    ParamRange::new("min_sill_height", 0.0, 3.0, "m"),
];

impl Default for RoomsParams {
    fn default() -> Self {
        RoomsParams {
            enabled: true,
            min_thickness: 0.03,
            max_thickness: 0.5,
            min_overlap: 0.1,
            max_angle_deg: 5.0,
            min_door_width: 0.5,
            max_door_width: 2.5,
            min_head_height: 1.7,
            ceiling_margin: 0.1,
            lintel_coverage: 0.5,
            min_room_area: 0.5,
            min_opening_room_area: 4.0,
            exterior_thickness: 0.3,
            min_exterior_length: 0.3,
            min_window_width: 0.4,
            min_sill_height: 0.3,
        }
    }
}

impl RoomsParams {
    /// Checks every value; the error names the parameter and gives its range.
    pub fn check(&self) -> Result<(), RoomsError> {
        let values = [
            ("min_thickness", self.min_thickness),
            ("max_thickness", self.max_thickness),
            ("min_overlap", self.min_overlap),
            ("max_angle_deg", self.max_angle_deg),
            ("min_door_width", self.min_door_width),
            ("max_door_width", self.max_door_width),
            ("min_head_height", self.min_head_height),
            ("ceiling_margin", self.ceiling_margin),
            ("lintel_coverage", self.lintel_coverage),
            ("min_room_area", self.min_room_area),
            ("min_opening_room_area", self.min_opening_room_area),
            ("exterior_thickness", self.exterior_thickness),
            ("min_exterior_length", self.min_exterior_length),
            ("min_window_width", self.min_window_width),
            ("min_sill_height", self.min_sill_height),
        ];
        for (name, v) in values {
            within(RANGES, name, v).map_err(|(name, why)| RoomsError::BadParam { name, why })?;
        }
        // Crossed bounds (a minimum over its maximum) are allowed: nothing then qualifies.
        Ok(())
    }
}

/// Why a story could not be divided into rooms. The pipeline keeps the story's plan and notes
/// this; it never fails a job.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RoomsError {
    /// A parameter is outside its range.
    #[error("parameter `{name}`: {why}")]
    BadParam {
        /// The parameter's name.
        name: &'static str,
        /// What is wrong.
        why: String,
    },
    /// The free floor cut at the doors could not be made valid.
    #[error("the rooms could not be made valid: {0}")]
    Invalid(String),
}

/// A scanner position: its index as the user names it, and where it stood (local frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scanner {
    /// The scan's index as the user names it.
    pub index: usize,
    /// Where it stood, local frame.
    pub position: [f64; 3],
}

/// What [`find_rooms`] found on one story.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RoomsOutcome {
    /// The story's rooms, doors, windows and centre-line walls.
    pub spaces: Spaces,
    /// Things worth telling the user.
    pub notes: Vec<String>,
}

/// The story's points that tell lintels and windows: local x, y, z (any story's points may be
/// given; only those between the story's floor and ceiling are read). Empty when the cloud is
/// not held (streaming), and then no gap is known to have a lintel.
pub struct StoryPoints<'a> {
    /// Local x, y, z of the points.
    pub xyz: &'a [[f32; 3]],
    /// The height range of each block of `xyz`, when known: a pass then skips the blocks
    /// outside the heights it reads, which are most of a multi-story cloud.
    pub blocks: Option<&'a Blocks>,
}

/// Indices a share of a pass covers, at least (fewer shares, fewer `empty()` to merge).
const SHARE: usize = 1 << 18;

impl StoryPoints<'_> {
    /// Every `stride`-th point (by index in `xyz`) with a height in `z`, and maybe others, on
    /// all cores: each share is added into its own `empty()`, and the shares merged. The
    /// result must not depend on how the points were shared out. `add` updates the
    /// accumulator in place: moving it in and out for every point copied it.
    pub(crate) fn fold<T: Send>(
        &self,
        stride: usize,
        z: RangeInclusive<f64>,
        empty: impl Fn() -> T + Sync + Send,
        add: impl Fn(&mut T, &[f32; 3]) + Sync + Send,
        merge: impl Fn(T, T) -> T + Sync + Send,
    ) -> T {
        let n = self.xyz.len();
        let spans = match self.blocks {
            Some(b) => b.spans_within(z),
            None => std::iter::once(0..n).collect(),
        };
        shares(&spans, stride, n)
            .into_par_iter()
            .fold(&empty, |mut acc, r| {
                for k in r.step_by(stride) {
                    add(&mut acc, &self.xyz[k]);
                }
                acc
            })
            .reduce(&empty, merge)
    }
}

/// `spans` (in order) cut into shares of at most [`SHARE`] strides, each starting on a multiple
/// of `stride` and ending by `n`: their `step_by(stride)` visit the multiples of `stride` in
/// `spans`, the points a stride over the whole cloud visits there.
fn shares(spans: &[Range<usize>], stride: usize, n: usize) -> Vec<Range<usize>> {
    spans
        .iter()
        .flat_map(|r| {
            let (start, end) = (r.start.div_ceil(stride) * stride, r.end.min(n));
            (start..end)
                .step_by(SHARE * stride)
                .map(move |s| s..(s + SHARE * stride).min(end))
        })
        .collect()
}

/// Divides `story`'s free floor into rooms, finds its doors, openings and windows, and pairs
/// its walls' faces. `grid` is the output grid the rooms' polygons are made valid on.
pub fn find_rooms(
    story: &StoryPlan,
    points: &StoryPoints<'_>,
    scanners: &[Scanner],
    params: &RoomsParams,
    grid: &Grid,
) -> Result<RoomsOutcome, RoomsError> {
    params.check()?;
    let mut out = RoomsOutcome::default();
    if !params.enabled || story.polygons.is_empty() {
        return Ok(out);
    }
    let faces = faces::faces(&story.polygons);
    let free = segment::Free::new(&story.polygons);
    let paired = pairing::pair(&faces, &free, params);
    let mut candidates = gaps::find(&paired.0, &faces, &free, params);
    let seen = !points.xyz.is_empty();
    if seen {
        gaps::lintels(&mut candidates, story, points, params);
        let walled = candidates.iter().filter(|g| g.walled && !g.crack).count();
        if walled > 0 {
            out.notes.push(format!(
                "rooms: {walled} gap(s) in the plan's walls closed where the points show the wall standing"
            ));
        }
    } else if !candidates.is_empty() {
        out.notes
            .push("rooms: no points held to look for lintels; every gap is taken as a door, its jambs the plan's faces".into());
        for c in &mut candidates {
            c.lintel = true;
        }
    }
    let divided = segment::divide(&story.polygons, &candidates, params, grid)?;
    let stations: Vec<(usize, P2)> = scanners
        .iter()
        .filter(|s| s.position[2] >= story.floor_z - 0.5 && s.position[2] <= story.ceiling_z + 0.5)
        .map(|s| (s.index, [s.position[0], s.position[1]]))
        .collect();
    out.spaces = segment::spaces(
        story,
        &divided,
        &candidates,
        &paired,
        &faces,
        &stations,
        params,
    );
    if seen {
        out.spaces.windows = windows::find(story, &faces, &paired.1, points, &out.spaces, params);
    }
    if divided.dropped > 0 {
        out.notes.push(format!(
            "rooms: {} piece(s) of free floor under {} m² are in no room",
            divided.dropped, params.min_room_area
        ));
    }
    Ok(out)
}
