//! The result formats as data: each writer's name, file name, media type and function. The
//! CLI's outputs, the service's stored results, links and downloads all follow this list, so a
//! new format is a writer and a row here (and its CLI flag and API document entry).

use crate::plan::FloorPlan;

/// One result format.
#[derive(Debug, Clone, Copy)]
pub struct Output {
    /// The short name (`links` key in the API).
    pub name: &'static str,
    /// The file name results are stored and served under.
    pub file: &'static str,
    pub media_type: &'static str,
    /// Renders the plan; the error says why it could not be.
    pub write: fn(&FloorPlan) -> Result<Vec<u8>, String>,
}

/// Every result format, GeoJSON (the contract) first.
pub const OUTPUTS: [Output; 4] = [
    Output {
        name: "geojson",
        file: "plan.geojson",
        media_type: "application/geo+json",
        write: |plan| Ok(super::geojson::to_geojson_string(plan).into_bytes()),
    },
    Output {
        name: "svg",
        file: "plan.svg",
        media_type: "image/svg+xml",
        write: |plan| Ok(super::svg::to_svg(plan).into_bytes()),
    },
    Output {
        name: "dxf",
        file: "plan.dxf",
        media_type: "application/dxf",
        write: |plan| super::dxf::to_dxf(plan).map_err(|e| format!("DXF: {e}")),
    },
    // RFC 7946's WGS84; without a usable CRS, no features and the reason (io::wgs84).
    Output {
        name: "wgs84",
        file: "plan.wgs84.geojson",
        media_type: "application/geo+json",
        write: |plan| {
            let mut text = super::wgs84::to_wgs84_geojson(plan).to_string();
            text.push('\n');
            Ok(text.into_bytes())
        },
    },
];

/// The format served under `file`.
pub fn by_file(file: &str) -> Option<&'static Output> {
    OUTPUTS.iter().find(|o| o.file == file)
}
