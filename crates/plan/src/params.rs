//! Every stage's parameters in one place, with overrides from files and `key=value` pairs.

use serde::{Deserialize, Serialize};

use crate::cleanup::CleanupParams;
use crate::fitting::FittingParams;
use crate::labeling::LabelingParams;
use crate::rooms::RoomsParams;
use crate::samples::SamplesParams;
use crate::smoothing::SmoothingParams;
use crate::stories::StoriesParams;
use crate::viewpoints::ViewpointsParams;

/// The parameters of a whole run; each field is one stage's parameter struct.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// Stage 1, the stories (§3.1).
    pub stories: StoriesParams,
    /// Stage 2, the wall samples (§3.1).
    pub samples: SamplesParams,
    /// Stage 3, smoothing the samples (§3.2).
    pub smoothing: SmoothingParams,
    /// Stage 4, labeling (§3.3).
    pub labeling: LabelingParams,
    /// Stage 5, cleanup (§3.4).
    pub cleanup: CleanupParams,
    /// Stage 6, fitting the walls (§3.5).
    pub fitting: FittingParams,
    /// Scanner positions when the input gives none (beyond the paper).
    pub viewpoints: ViewpointsParams,
    /// Rooms, doors, windows and walls with thickness (beyond the paper).
    pub rooms: RoomsParams,
    /// Include each story's wall samples as a `wall_samples` feature.
    pub emit_samples: bool,
    /// Draw each story's points at mid-height (the underlay) under the SVG plan.
    pub svg_underlay: bool,
}

/// The values a numeric parameter accepts, both ends included. Each stage lists its own
/// (`RANGES` in the stage's module) and checks them first; the service refuses a value outside
/// before the job is queued, and the OpenAPI document states the same bounds. The ranges are
/// wide enough for any real scan and narrow enough that no value makes a stage run for hours
/// or allocate without bound.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ParamRange {
    /// The field's name within its stage's parameters.
    pub name: &'static str,
    /// The smallest accepted value.
    pub min: f64,
    /// The largest accepted value.
    pub max: f64,
    /// For messages: `m`, `m²`, `rad`, or empty for counts and fractions.
    pub unit: &'static str,
}

impl ParamRange {
    /// A range for `name`, from `min` to `max` inclusive, in `unit`.
    pub const fn new(name: &'static str, min: f64, max: f64, unit: &'static str) -> ParamRange {
        ParamRange {
            name,
            min,
            max,
            unit,
        }
    }

    /// `Err` with a message giving the range when `value` lies outside it (NaN always does).
    pub fn check(&self, value: f64) -> Result<(), String> {
        if value >= self.min && value <= self.max {
            return Ok(());
        }
        let unit = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        Err(format!(
            "{value} is outside the accepted range {}..={}{unit}",
            self.min, self.max
        ))
    }
}

/// Checks `value` against the range called `name` in a stage's `ranges`; the error names the
/// field and gives the range. Every name a stage checks is in its table (a test sets each one
/// out of range).
pub(crate) fn within(
    ranges: &[ParamRange],
    name: &'static str,
    value: f64,
) -> Result<(), (&'static str, String)> {
    match ranges.iter().find(|r| r.name == name) {
        Some(r) => r.check(value).map_err(|why| (name, why)),
        None => Err((name, "has no documented range (a bug)".into())),
    }
}

/// Every stage's ranges, with the section each belongs to: for documents and tests.
pub fn ranges() -> Vec<(&'static str, ParamRange)> {
    let sections: [(&'static str, &[ParamRange]); 8] = [
        ("stories", crate::stories::RANGES),
        ("samples", crate::samples::RANGES),
        ("smoothing", crate::smoothing::RANGES),
        ("labeling", crate::labeling::RANGES),
        ("cleanup", crate::cleanup::RANGES),
        ("fitting", crate::fitting::RANGES),
        ("viewpoints", crate::viewpoints::RANGES),
        ("rooms", crate::rooms::RANGES),
    ];
    sections
        .into_iter()
        .flat_map(|(s, list)| list.iter().map(move |r| (s, *r)))
        .collect()
}

/// A parameter that could not be set. The message names the parameter.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ParamsError {
    /// An override is not `section.name=value`.
    #[error("parameter override `{0}` is not of the form section.name=value")]
    Syntax(String),
    /// No parameter has that name.
    #[error("unknown parameter `{0}`")]
    Unknown(String),
    /// The value is not accepted; `why` says why.
    #[error("invalid value for parameter `{name}`: {why}")]
    Invalid {
        /// The parameter, `section.name`.
        name: String,
        /// Why it is refused.
        why: String,
    },
    /// The parameter file cannot be read or parsed.
    #[error("parameter file: {0}")]
    File(String),
}

impl Params {
    /// Parses a TOML or JSON parameter file's text (JSON when it starts with `{`).
    pub fn from_file_text(text: &str) -> Result<Params, ParamsError> {
        if text.trim_start().starts_with('{') {
            serde_json::from_str(text).map_err(|e| ParamsError::File(e.to_string()))
        } else {
            toml::from_str(text).map_err(|e| ParamsError::File(e.to_string()))
        }
    }

    /// Applies one `section.name=value` override. The value is read as JSON when it parses as
    /// JSON (numbers, booleans, `null`), else as a string.
    pub fn set(&mut self, assignment: &str) -> Result<(), ParamsError> {
        let (key, raw) = assignment
            .split_once('=')
            .ok_or_else(|| ParamsError::Syntax(assignment.into()))?;
        let key = key.trim();
        let value: serde_json::Value = serde_json::from_str(raw.trim())
            .unwrap_or_else(|_| serde_json::Value::String(raw.trim().into()));
        let mut tree = serde_json::to_value(&*self).expect("params serialize");
        let mut slot = &mut tree;
        for part in key.split('.') {
            slot = slot
                .as_object_mut()
                .and_then(|o| o.get_mut(part))
                .ok_or_else(|| ParamsError::Unknown(key.into()))?;
        }
        *slot = value;
        *self = serde_json::from_value(tree).map_err(|e| ParamsError::Invalid {
            name: key.into(),
            why: e.to_string(),
        })?;
        Ok(())
    }

    /// Checks one `section.name=value` override on its own, before anything else arrives: the
    /// name is known, the value parses, and a number lies within its range. Rules between
    /// parameters wait for [`Params::check`].
    pub fn check_override(assignment: &str) -> Result<(), ParamsError> {
        let mut p = Params::default();
        p.set(assignment)?;
        let key = assignment.split_once('=').map_or("", |(k, _)| k.trim());
        let Some((section, name)) = key.split_once('.') else {
            return Ok(());
        };
        let range = ranges()
            .into_iter()
            .find(|(s, r)| *s == section && r.name == name);
        if let (Some((_, r)), Some(v)) = (range, p.to_json()[section][name].as_f64()) {
            r.check(v).map_err(|why| ParamsError::Invalid {
                name: key.into(),
                why,
            })?;
        }
        Ok(())
    }

    /// Checks every stage's values before a run, so a bad value is refused up front (the service
    /// answers 422) rather than failing the run later. The error names `section.name`.
    pub fn check(&self) -> Result<(), ParamsError> {
        fn named(section: &str, name: &str, why: String) -> ParamsError {
            ParamsError::Invalid {
                name: format!("{section}.{name}"),
                why,
            }
        }
        use crate::fitting::FittingError;
        use crate::labeling::LabelingError;
        use crate::samples::SamplesError;
        use crate::smoothing::SmoothingError;
        use crate::stories::StoriesError;
        match self.stories.check() {
            Err(StoriesError::BadParam { name, why }) => return Err(named("stories", name, why)),
            Err(e) => return Err(named("stories", "?", e.to_string())),
            Ok(()) => {}
        }
        match self.samples.check() {
            Err(SamplesError::BadParam { name, why }) => return Err(named("samples", name, why)),
            Err(e) => return Err(named("samples", "?", e.to_string())),
            Ok(()) => {}
        }
        match self.smoothing.check(self.samples.cell_size) {
            Err(SmoothingError::BadParam { name, why }) => {
                return Err(named("smoothing", name, why))
            }
            Err(e) => return Err(named("smoothing", "?", e.to_string())),
            Ok(()) => {}
        }
        match self.labeling.check() {
            Err(LabelingError::BadParam { name, why }) => return Err(named("labeling", name, why)),
            Err(e) => return Err(named("labeling", "?", e.to_string())),
            Ok(()) => {}
        }
        if let Err((name, why)) = self.cleanup.check() {
            return Err(named("cleanup", name, why));
        }
        if let Err(FittingError::BadParam { name, why }) = self.fitting.check() {
            return Err(named("fitting", name, why));
        }
        if let Err(crate::viewpoints::ViewpointsError::BadParam { name, why }) =
            self.viewpoints.check()
        {
            return Err(named("viewpoints", name, why));
        }
        if let Err(crate::rooms::RoomsError::BadParam { name, why }) = self.rooms.check() {
            return Err(named("rooms", name, why));
        }
        Ok(())
    }

    /// The parameters as JSON, for `floorplan.parameters`.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("params serialize")
    }

    /// The parameters a run uses on a cloud whose points lie `spacing` metres apart (the
    /// median nearest-neighbour distance; `None` when unmeasured), and the parameters JSON that
    /// reports them: the given values, with each derived one beside it (`*_derived`).
    ///
    /// Beyond the paper: the grid cell d_s is at least [`CELLS_PER_SPACING`] point spacings,
    /// so that a neighbourhood spans several points across a wall even when they sit on a
    /// lattice (voxel centres, downsampled clouds). Where d_s grows, the lengths that are a
    /// few cells (the lines of sight' end margin, the fitting's inlier band) grow with it and
    /// the fitting's counts of samples shrink with it, so they keep their lengths. Clouds
    /// dense enough for the given d_s keep every value.
    pub fn derive(&self, spacing: Option<f64>) -> (Params, serde_json::Value) {
        let mut run = self.clone();
        let mut report = self.to_json();
        if let Some(s) = spacing {
            report["samples"]["point_spacing"] = serde_json::json!(round_mm(s));
        }
        let given = self.samples.cell_size;
        let cell = spacing.map_or(given, |s| given.max(CELLS_PER_SPACING * s));
        if self.samples.derive_cell_size && cell > given {
            let k = cell / given;
            run.samples.cell_size = cell;
            run.labeling.ray_end_margin = self.labeling.ray_end_margin.map(|m| m * k);
            let f = &mut run.fitting;
            f.inlier_distance *= k;
            let fewer = |n: usize| ((n as f64 / k).round() as usize).max(MIN_SCALED_COUNT.min(n));
            f.min_inliers = fewer(f.min_inliers);
            f.min_component = fewer(f.min_component);
            f.grow_hops = fewer(f.grow_hops);
            report["samples"]["cell_size_derived"] = serde_json::json!(round_mm(cell));
            report["labeling"]["ray_end_margin_derived"] =
                serde_json::json!(run.labeling.ray_end_margin.map(round_mm));
            report["fitting"]["inlier_distance_derived"] =
                serde_json::json!(round_mm(f.inlier_distance));
            for (name, v) in [
                ("min_inliers_derived", f.min_inliers),
                ("min_component_derived", f.min_component),
                ("grow_hops_derived", f.grow_hops),
            ] {
                report["fitting"][name] = serde_json::json!(v);
            }
        }
        (run, report)
    }
}

/// The grid cell is at least this many point spacings wide (see [`Params::derive`]).
pub const CELLS_PER_SPACING: f64 = 1.25;

/// Counts of samples scaled down for a coarser grid stay at least this (or their given value).
const MIN_SCALED_COUNT: usize = 5;

fn round_mm(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_name_the_parameter() {
        let mut p = Params::default();
        p.set("samples.cell_size=0.1").unwrap();
        assert_eq!(p.samples.cell_size, 0.1);
        p.set("samples.min_points=20").unwrap();
        assert_eq!(p.samples.min_points, Some(20));
        p.set("labeling.solver=harmonic").unwrap();
        assert_eq!(p.labeling.solver, crate::labeling::Solver::Harmonic);
        assert_eq!(
            p.set("samples.nope=1"),
            Err(ParamsError::Unknown("samples.nope".into()))
        );
        assert!(
            matches!(p.set("samples.cell_size=abc"), Err(ParamsError::Invalid { name, .. }) if name == "samples.cell_size")
        );
        assert!(matches!(p.set("oops"), Err(ParamsError::Syntax(_))));
    }

    #[test]
    fn check_names_the_bad_value_of_each_stage() {
        assert_eq!(Params::default().check(), Ok(()));
        for (set, name) in [
            ("stories.bin_size=0", "stories.bin_size"),
            ("samples.cell_size=-1", "samples.cell_size"),
            ("samples.height_bins=99", "samples.height_bins"),
            ("labeling.ray_fraction=2", "labeling.ray_fraction"),
            ("cleanup.max_hole_area=-0.5", "cleanup.max_hole_area"),
            ("fitting.inlier_distance=0", "fitting.inlier_distance"),
        ] {
            let mut p = Params::default();
            p.set(set).unwrap();
            match p.check() {
                Err(ParamsError::Invalid { name: n, .. }) => assert_eq!(n, name, "{set}"),
                other => panic!("{set}: {other:?}"),
            }
        }
        // Smoothing is checked only when it is on.
        let mut p = Params::default();
        p.set("smoothing.max_angle=9").unwrap();
        assert_eq!(p.check(), Ok(()));
        p.set("smoothing.registration_error=0.01").unwrap();
        assert!(
            matches!(p.check(), Err(ParamsError::Invalid { name, .. }) if name == "smoothing.max_angle")
        );
    }

    #[test]
    fn a_coarse_cloud_widens_the_cell_and_what_follows_from_it() {
        let p = Params::default();
        // Dense: nothing changes, the spacing is reported.
        let (run, report) = p.derive(Some(0.02));
        assert_eq!(run, p);
        assert_eq!(report["samples"]["point_spacing"], 0.02);
        assert!(report["samples"].get("cell_size_derived").is_none());
        assert_eq!(p.derive(None).0, p);
        // 8 cm voxel centres: a 10 cm cell, lengths doubled and counts halved.
        let (run, report) = p.derive(Some(0.08));
        assert!((run.samples.cell_size - 0.1).abs() < 1e-12);
        assert_eq!(report["samples"]["cell_size"], 0.05);
        assert_eq!(report["samples"]["cell_size_derived"], 0.1);
        assert!((run.fitting.inlier_distance - 0.06).abs() < 1e-12);
        assert!((run.labeling.ray_end_margin.unwrap() - 0.3).abs() < 1e-12);
        assert_eq!(run.fitting.min_inliers, 8);
        assert_eq!(report["fitting"]["min_inliers_derived"], 8);
        // Switched off, the given cell stays.
        let mut off = p.clone();
        off.samples.derive_cell_size = false;
        assert_eq!(off.derive(Some(0.08)).0, off);
    }

    #[test]
    fn every_range_is_enforced_at_both_ends_and_named() {
        let all = ranges();
        assert!(all.len() >= 25, "{} ranges", all.len());
        for (section, r) in all {
            let name = format!("{section}.{}", r.name);
            let mut outside = vec![r.max * 2.0 + 1.0];
            if r.min > 0.0 {
                outside.push(r.min / 2.0);
            }
            for v in outside {
                let mut p = Params::default();
                if section == "smoothing" {
                    // Smoothing's values are read, and checked, only when it is on.
                    p.set("smoothing.registration_error=0.01").unwrap();
                }
                // Counts take whole numbers; `set` keeps the JSON type it is given.
                let text = if v.fract() == 0.0 {
                    format!("{name}={}", v as u64)
                } else {
                    format!("{name}={v}")
                };
                match p.set(&text).and_then(|_| p.check()) {
                    Err(ParamsError::Invalid { name: n, why }) => {
                        assert_eq!(n, name, "{text}: {why}");
                    }
                    other => panic!("{text}: {other:?}"),
                }
            }
            // Both ends are accepted.
            for v in [r.min, r.max] {
                let mut p = Params::default();
                if section == "smoothing" {
                    p.set("smoothing.registration_error=0.01").unwrap();
                }
                let text = if v.fract() == 0.0 {
                    format!("{name}={}", v as u64)
                } else {
                    format!("{name}={v}")
                };
                // The one cross-field rule: no more filled bins than bins.
                p.set("samples.height_bins=32").unwrap();
                p.set(&text).unwrap();
                if name == "samples.height_bins" {
                    p.set("samples.min_filled_bins=0").unwrap();
                }
                assert_eq!(p.check(), Ok(()), "{text}");
            }
        }
    }

    /// A numeric parameter added without a range fails here: add it to its stage's `RANGES`
    /// and check it in the stage's `check`.
    #[test]
    fn every_numeric_parameter_has_a_range() {
        let documented: Vec<String> = ranges()
            .iter()
            .map(|(s, r)| format!("{s}.{}", r.name))
            .collect();
        let tree = Params::default().to_json();
        for (section, values) in tree.as_object().unwrap() {
            for (name, v) in values.as_object().into_iter().flatten() {
                let key = format!("{section}.{name}");
                // Any seed is as good as another.
                if v.is_number() && key != "fitting.seed" {
                    assert!(documented.contains(&key), "{key} has no range");
                }
            }
        }
        // The optional numbers, null by default.
        for key in [
            "samples.min_points",
            "smoothing.registration_error",
            "smoothing.distance",
            "labeling.ray_end_margin",
        ] {
            assert!(documented.contains(&key.to_string()), "{key} has no range");
        }
    }

    #[test]
    fn a_single_override_is_checked_against_its_range() {
        assert_eq!(Params::check_override("samples.cell_size=0.1"), Ok(()));
        assert!(matches!(
            Params::check_override("fitting.iterations=1000000000000"),
            Err(ParamsError::Invalid { name, .. }) if name == "fitting.iterations"
        ));
        assert!(matches!(
            Params::check_override("samples.nope=1"),
            Err(ParamsError::Unknown(_))
        ));
        // A rule between two parameters waits for the whole set.
        assert_eq!(Params::check_override("samples.min_filled_bins=20"), Ok(()));
        assert_eq!(Params::check_override("emit_samples=true"), Ok(()));
    }

    #[test]
    fn the_message_gives_the_range() {
        let mut p = Params::default();
        p.set("fitting.iterations=1000000000000").unwrap();
        let e = p.check().unwrap_err().to_string();
        assert!(e.contains("fitting.iterations"), "{e}");
        assert!(e.contains("1..=100000"), "{e}");
        let mut p = Params::default();
        p.set("samples.cell_size=1000000000").unwrap();
        let e = p.check().unwrap_err().to_string();
        assert!(e.contains("0.01..=0.5 m"), "{e}");
    }

    #[test]
    fn files_in_toml_and_json() {
        let t = Params::from_file_text("[stories]\nmin_wall_height = 2.5\n").unwrap();
        assert_eq!(t.stories.min_wall_height, 2.5);
        let j = Params::from_file_text(r#"{"fitting": {"circles": false}}"#).unwrap();
        assert!(!j.fitting.circles);
        assert!(Params::from_file_text("[stories]\nbogus = 1\n").is_err());
    }
}
