//! The result formats as data: each writer's name, file name, media type and function. The
//! CLI's flags and outputs, the service's stored results, links and downloads all follow this
//! list, so a new format is a writer (a module under `outputs/`) and a row here, plus its
//! entry in the API document (which `openapi.rs` tests against this list).

use crate::plan::FloorPlan;

pub(crate) mod ifc;
#[cfg(test)]
pub(crate) mod python;
pub(crate) mod rooms_csv;
pub(crate) mod underlay;

/// One result format.
#[derive(Debug, Clone, Copy)]
pub struct Output {
    /// The short name: the `links` key in the API and the CLI's `--NAME FILE` flag.
    pub name: &'static str,
    /// The file name results are stored and served under.
    pub file: &'static str,
    /// The media type results are served with.
    pub media_type: &'static str,
    /// What the file is, for the CLI's help ("Also write ...").
    pub about: &'static str,
    /// Renders the plan; the error says why it could not be.
    pub write: fn(&FloorPlan) -> Result<Vec<u8>, String>,
}

/// Every result format, GeoJSON (the contract) first.
pub const OUTPUTS: [Output; 7] = [
    Output {
        name: "geojson",
        file: "plan.geojson",
        media_type: "application/geo+json",
        about: "the GeoJSON plan (the contract)",
        write: |plan| Ok(super::geojson::to_geojson_string(plan).into_bytes()),
    },
    Output {
        name: "svg",
        file: "plan.svg",
        media_type: "image/svg+xml",
        about: "an SVG preview, rooms labelled with their areas",
        write: |plan| Ok(super::svg::to_svg(plan).into_bytes()),
    },
    Output {
        name: "dxf",
        file: "plan.dxf",
        media_type: "application/dxf",
        about: "a DXF R12 drawing",
        write: |plan| super::dxf::to_dxf(plan).map_err(|e| format!("DXF: {e}")),
    },
    Output {
        name: "ifc",
        file: "plan.ifc",
        media_type: "application/x-step",
        about: "an IFC4 model: storeys, spaces, walls, doors and windows",
        write: |plan| ifc::to_ifc(plan).map_err(|e| e.to_string()),
    },
    Output {
        name: "rooms",
        file: "rooms.csv",
        media_type: "text/csv",
        about: "the room schedule as CSV",
        write: |plan| Ok(rooms_csv::to_csv(plan).into_bytes()),
    },
    // RFC 7946's WGS84; without a usable CRS, no features and the reason (io::wgs84).
    Output {
        name: "wgs84",
        file: "plan.wgs84.geojson",
        media_type: "application/geo+json",
        about: "the GeoJSON in WGS84 longitude and latitude (RFC 7946), from the scan's CRS; without one, no features and the reason",
        write: |plan| {
            let mut text = super::wgs84::to_wgs84_geojson(plan).to_string();
            text.push('\n');
            Ok(text.into_bytes())
        },
    },
    // Where each story lies in it: `floorplan.underlay` in the GeoJSON.
    Output {
        name: "underlay",
        file: underlay::FILE,
        media_type: "image/png",
        about: "each story's points at mid-height as an image to draw under the plan (where it lies: floorplan.underlay in the GeoJSON)",
        write: underlay::to_png,
    },
];

/// The format served under `file`.
pub fn by_file(file: &str) -> Option<&'static Output> {
    OUTPUTS.iter().find(|o| o.file == file)
}

/// The format named `name`.
pub fn by_name(name: &str) -> Option<&'static Output> {
    OUTPUTS.iter().find(|o| o.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_files_are_unique_and_flag_safe() {
        for (i, a) in OUTPUTS.iter().enumerate() {
            assert!(
                a.name
                    .bytes()
                    .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit()),
                "{}: a name is a plain lower-case flag",
                a.name
            );
            assert!(by_name(a.name).is_some() && by_file(a.file).is_some());
            for b in &OUTPUTS[i + 1..] {
                assert_ne!(a.name, b.name);
                assert_ne!(a.file, b.file);
            }
        }
    }

    /// Every writer renders the plan with rooms, doors and walls, and an empty plan too.
    #[test]
    fn every_writer_renders_spaces_and_empty_plans() {
        let full = crate::io::geojson::tests::spaces_plan();
        let empty = crate::io::geojson::tests::plan([0.0; 3], vec![]);
        for o in &OUTPUTS {
            for plan in [&full, &empty] {
                let bytes = (o.write)(plan).unwrap_or_else(|e| panic!("{}: {e}", o.name));
                assert!(!bytes.is_empty(), "{}", o.name);
            }
        }
    }
}
