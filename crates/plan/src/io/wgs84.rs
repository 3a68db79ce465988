//! The plan in RFC 7946's own coordinates: WGS84 longitude and latitude, in degrees.
//!
//! `plan.geojson` keeps the scan's frame (contract §1), which a GIS reader takes for degrees when
//! it is in fact metres. This copy transforms every position from the CRS the scan declared
//! (`FloorPlan::crs`: `EPSG:n` or WKT), or from the caller's georeference (`crate::georef`: a
//! CRS, or a local frame as a Local Orthographic PROJ string), with proj4rs, a pure-Rust port of
//! PROJ.4, so the image needs no C library. EPSG codes come from the crs-definitions table, WKT
//! goes through proj4wkt.
//! Without a CRS, or with one proj4rs cannot use, the copy has no features and says why.

use proj4rs::proj::Proj;
use serde_json::{json, Value};

use crate::plan::FloorPlan;

/// Why a plan's CRS cannot be turned into WGS84.
#[derive(Debug, thiserror::Error)]
pub enum Wgs84Error {
    /// An EPSG code outside proj4rs's table.
    #[error("EPSG:{0} is not in the table of EPSG codes")]
    UnknownEpsg(String),
    /// WKT proj4wkt cannot read.
    #[error("the CRS's WKT cannot be used: {0}")]
    Wkt(String),
    /// A CRS proj4rs cannot set up.
    #[error("the CRS cannot be used: {0}")]
    Crs(String),
    /// A geographic CRS: the plan's metres are not its degrees.
    #[error("the CRS is geographic (degrees), not a projection in metres")]
    Geographic,
    /// One position failed to transform.
    #[error("position ({x}, {y}) does not transform: {reason}")]
    Position {
        /// The position's x.
        x: f64,
        /// The position's y.
        y: f64,
        /// Why it does not transform.
        reason: String,
    },
}

/// A transformation from one projected CRS to WGS84 longitude and latitude.
pub struct ToWgs84 {
    from: Proj,
    to: Proj,
}

impl ToWgs84 {
    /// The transformation from `crs`: `EPSG:n` (any case), a WKT string, or a PROJ string
    /// (`+proj=...`, as `georef` writes a local frame).
    pub fn new(crs: &str) -> Result<Self, Wgs84Error> {
        let crs = crs.trim();
        let from = match crs.get(..5) {
            _ if crs.starts_with("+proj=") => {
                Proj::from_proj_string(crs).map_err(|e| Wgs84Error::Crs(e.to_string()))?
            }
            Some(p) if p.eq_ignore_ascii_case("EPSG:") => {
                let code = &crs[5..];
                let n: u16 = code
                    .trim()
                    .parse()
                    .map_err(|_| Wgs84Error::UnknownEpsg(code.into()))?;
                Proj::from_epsg_code(n).map_err(|_| Wgs84Error::UnknownEpsg(code.into()))?
            }
            _ => {
                let proj =
                    proj4wkt::wkt_to_projstring(crs).map_err(|e| Wgs84Error::Wkt(e.to_string()))?;
                Proj::from_proj_string(&proj).map_err(|e| Wgs84Error::Crs(e.to_string()))?
            }
        };
        if from.is_latlong() || from.is_geocent() {
            return Err(Wgs84Error::Geographic);
        }
        let to = Proj::from_proj_string("+proj=longlat +datum=WGS84 +no_defs")
            .map_err(|e| Wgs84Error::Crs(e.to_string()))?;
        Ok(Self { from, to })
    }

    /// `[longitude, latitude]` in degrees of the position `(x, y)` in the source CRS.
    pub fn lon_lat(&self, x: f64, y: f64) -> Result<[f64; 2], Wgs84Error> {
        let fail = |reason: String| Wgs84Error::Position { x, y, reason };
        let mut p = (x, y, 0.0);
        proj4rs::transform::transform(&self.from, &self.to, &mut p)
            .map_err(|e| fail(e.to_string()))?;
        let (lon, lat) = (p.0.to_degrees(), p.1.to_degrees());
        if !(lon.is_finite() && lat.is_finite() && lat.abs() <= 90.0 && lon.abs() <= 540.0) {
            return Err(fail(format!("gives ({lon}, {lat})")));
        }
        Ok([lon, lat])
    }
}

/// The plan's GeoJSON in WGS84 (see the module comment).
pub fn to_wgs84_geojson(plan: &FloorPlan) -> Value {
    wgs84_of(super::geojson::to_geojson(plan))
}

/// The WGS84 copy of a plan GeoJSON written by `io::geojson`, read from its `floorplan.crs`.
pub fn wgs84_of(mut doc: Value) -> Value {
    let crs = doc["floorplan"]["crs"].as_str().map(str::to_owned);
    let result = match &crs {
        None => Err(
            "the scan declares no coordinate reference system: plan.geojson is in the \
                     scan's own metres"
                .to_string(),
        ),
        Some(crs) => ToWgs84::new(crs)
            .and_then(|t| transform_features(&t, &mut doc["features"]))
            .map_err(|e| format!("not georeferenced: {e}")),
    };
    let meta = &mut doc["floorplan"];
    // The underlay's rectangles are in the plan's own metres, as its image is.
    if let Some(m) = meta.as_object_mut() {
        m.remove("underlay");
    }
    meta["source_crs"] = json!(crs);
    meta["crs"] = json!("OGC:CRS84");
    meta["units"] = json!("degrees");
    match result {
        Ok(()) => meta["georeferenced"] = json!(true),
        Err(why) => {
            meta["georeferenced"] = json!(false);
            meta["crs"] = Value::Null;
            meta["why"] = json!(why);
            doc["features"] = json!([]);
        }
    }
    doc
}

/// Every geometry's positions, and the `center` of arc walls; lengths stay metres.
fn transform_features(t: &ToWgs84, features: &mut Value) -> Result<(), Wgs84Error> {
    for f in features.as_array_mut().into_iter().flatten() {
        transform_positions(t, &mut f["geometry"]["coordinates"])?;
        if let Some(center) = f["properties"].get_mut("center") {
            transform_positions(t, center)?;
        }
    }
    Ok(())
}

/// A position is an array of numbers; anything else nests positions.
fn transform_positions(t: &ToWgs84, v: &mut Value) -> Result<(), Wgs84Error> {
    let Some(items) = v.as_array_mut() else {
        return Ok(());
    };
    if let [Value::Number(x), Value::Number(y), ..] = items.as_slice() {
        let (x, y) = (
            x.as_f64().unwrap_or(f64::NAN),
            y.as_f64().unwrap_or(f64::NAN),
        );
        let [lon, lat] = t.lon_lat(x, y)?;
        // 1e-9 degrees is about 0.1 mm, the precision of plan.geojson.
        *v = json!([round9(lon), round9(lat)]);
        return Ok(());
    }
    for item in items {
        transform_positions(t, item)?;
    }
    Ok(())
}

fn round9(v: f64) -> f64 {
    (v * 1e9).round() / 1e9
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc(crs: Value) -> Value {
        json!({
            "type": "FeatureCollection",
            "floorplan": {"version": 1, "units": "m", "crs": crs},
            "features": [
                {"type": "Feature", "geometry": {"type": "Polygon", "coordinates":
                    [[[690000.0, 5335000.0], [690010.0, 5335000.0], [690010.0, 5335010.0], [690000.0, 5335000.0]]]},
                 "properties": {"kind": "story"}},
                {"type": "Feature", "geometry": {"type": "LineString", "coordinates":
                    [[690000.0, 5335000.0], [690010.0, 5335000.0]]},
                 "properties": {"kind": "wall", "model": "arc", "center": [690005.0, 5335005.0], "radius": 7.07}}
            ]
        })
    }

    #[test]
    fn utm_positions_become_degrees_near_the_zone() {
        let out = wgs84_of(doc(json!("EPSG:25832")));
        assert_eq!(out["floorplan"]["georeferenced"], true);
        assert_eq!(out["floorplan"]["crs"], "OGC:CRS84");
        assert_eq!(out["floorplan"]["source_crs"], "EPSG:25832");
        let p = &out["features"][0]["geometry"]["coordinates"][0][0];
        let (lon, lat) = (p[0].as_f64().unwrap(), p[1].as_f64().unwrap());
        // UTM zone 32 spans 6° to 12° east; 5,335 km north is about 48°.
        assert!(
            (6.0..12.0).contains(&lon) && (47.0..49.0).contains(&lat),
            "{lon}, {lat}"
        );
        let c = &out["features"][1]["properties"]["center"];
        assert!(c[0].as_f64().unwrap() > lon && c[1].as_f64().unwrap() > lat);
        assert_eq!(out["features"][1]["properties"]["radius"], 7.07);
    }

    #[test]
    fn without_a_crs_the_copy_is_empty_and_says_why() {
        let out = wgs84_of(doc(Value::Null));
        assert_eq!(out["floorplan"]["georeferenced"], false);
        assert!(out["floorplan"]["crs"].is_null());
        assert!(out["floorplan"]["why"]
            .as_str()
            .unwrap()
            .contains("no coordinate reference"));
        assert_eq!(out["features"].as_array().unwrap().len(), 0);
    }

    #[test]
    fn unusable_crs_are_refused_not_guessed() {
        for (crs, want) in [
            ("EPSG:99999", "not in the table"),
            ("EPSG:abc", "not in the table"),
            ("EPSG:4326", "geographic"),
            ("PROJCS[\"broken\"", "WKT"),
            ("", "WKT"),
        ] {
            let err = ToWgs84::new(crs)
                .err()
                .unwrap_or_else(|| panic!("{crs} accepted"));
            assert!(err.to_string().contains(want), "{crs}: {err}");
            let out = wgs84_of(doc(json!(crs)));
            assert_eq!(out["floorplan"]["georeferenced"], false, "{crs}");
            assert!(out["features"].as_array().unwrap().is_empty());
        }
    }
}
