//! A georeference the caller gives for a scan: where its coordinates lie on the earth, given
//! or overriding what the scan declares (LAS WKT or GeoTIFF keys, E57 coordinate metadata).
//!
//! Two kinds, exclusive:
//! - a projected CRS the scan's coordinates are in (`EPSG:n` or WKT);
//! - a local frame: the WGS84 longitude, latitude and height of one local point (`anchor_at`,
//!   the local origin by default), and the azimuth of the local +y axis (clockwise from true
//!   north). It becomes EPSG's Local Orthographic projection (method 1130, `+proj=ortho` with
//!   `+alpha` and `+k_0`): the plane tangent to the WGS84 ellipsoid under the anchor, whose
//!   scale makes local metres at the anchor's height true metres.
//!
//! A height datum (a vertical CRS such as `EPSG:5783`, or a name) may come with either; it is
//! declared with the plan. Plans are 2D, so heights are not transformed: the anchor's height
//! serves only the local frame's scale (an error of the geoid's separation, at most about
//! 100 m, moves a point 100 m from the anchor by under 2 mm).

use serde::{Deserialize, Serialize};

use crate::io::wgs84::{ToWgs84, Wgs84Error};

/// WKT and vertical datum names longer than this are refused (an EPSG WKT is a few kB).
pub const MAX_CRS_CHARS: usize = 16_384;
/// The longest height datum name.
pub const MAX_DATUM_CHARS: usize = 200;

/// See the module documentation. Field names are the API's and the CLI's.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Georeference {
    /// The projected CRS of the scan's coordinates: `EPSG:n` or WKT.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crs: Option<String>,
    /// `[longitude, latitude, height]` of `anchor_at`: WGS84 degrees, metres above the height
    /// datum.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub anchor: Option<[f64; 3]>,
    /// The local `[x, y, z]` the anchor gives the place of; `[0, 0, 0]` when not given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub anchor_at: Option<[f64; 3]>,
    /// Degrees clockwise from true north to the local +y axis; 0 when not given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub north_rotation: Option<f64>,
    /// What heights are measured from: a vertical CRS (`EPSG:n`) or a name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_datum: Option<String>,
}

/// Why a georeference cannot be used; `field` names the field at fault.
#[derive(Debug, thiserror::Error)]
#[error("{field}: {message}")]
pub struct GeorefError {
    /// The field at fault (`crs`, `anchor`, `anchor_at`, `north_rotation`, `height_datum`).
    pub field: &'static str,
    /// What is wrong with it.
    pub message: String,
}

fn bad(field: &'static str, message: impl Into<String>) -> GeorefError {
    GeorefError {
        field,
        message: message.into(),
    }
}

/// WGS84's semi-major axis and first eccentricity squared.
const WGS84_A: f64 = 6_378_137.0;
const WGS84_E2: f64 = 0.006_694_379_990_141_316;

impl Georeference {
    /// A georeference that is only a CRS (what a scan declares).
    pub fn of_crs(crs: impl Into<String>) -> Georeference {
        Georeference {
            crs: Some(crs.into()),
            ..Default::default()
        }
    }

    /// True for a local frame placed by an anchor.
    pub fn is_local(&self) -> bool {
        self.anchor.is_some()
    }

    /// Checks every field, and that the CRS or the frame can be transformed to WGS84.
    pub fn check(&self) -> Result<(), GeorefError> {
        match (&self.crs, &self.anchor) {
            (Some(_), Some(_)) => {
                return Err(bad(
                    "anchor",
                    "give a CRS or a local frame's anchor, not both",
                ))
            }
            (None, None) => {
                return Err(bad(
                    "crs",
                    "give a CRS (`crs`: EPSG:n or WKT) or a local frame (`anchor`: lon,lat,height)",
                ))
            }
            (Some(crs), None) => {
                for (field, given) in [
                    ("anchor_at", self.anchor_at.is_some()),
                    ("north_rotation", self.north_rotation.is_some()),
                ] {
                    if given {
                        return Err(bad(
                            field,
                            "only a local frame (`anchor`) takes this; a CRS places the scan itself",
                        ));
                    }
                }
                check_crs(crs)?;
            }
            (None, Some([lon, lat, h])) => {
                let finite = [lon, lat, h].iter().all(|v| v.is_finite());
                if !finite || lon.abs() > 180.0 || lat.abs() >= 90.0 || h.abs() > 100_000.0 {
                    return Err(bad(
                        "anchor",
                        "longitude -180..180, latitude between -90 and 90 (poles excluded), \
                         height -100000..100000 m",
                    ));
                }
                if let Some(at) = self.anchor_at {
                    if !at.iter().all(|v| v.is_finite() && v.abs() <= 1e8) {
                        return Err(bad("anchor_at", "three finite numbers within ±1e8 m"));
                    }
                }
                if let Some(r) = self.north_rotation {
                    if !r.is_finite() || r.abs() > 360.0 {
                        return Err(bad("north_rotation", "degrees between -360 and 360"));
                    }
                }
            }
        }
        if let Some(d) = &self.height_datum {
            let n = d.chars().count();
            if n == 0 || n > MAX_DATUM_CHARS || d.chars().any(char::is_control) {
                return Err(bad(
                    "height_datum",
                    format!("1 to {MAX_DATUM_CHARS} characters, no control characters"),
                ));
            }
        }
        self.to_wgs84().map(drop)
    }

    /// The CRS the coordinates are in, as `floorplan.crs` declares it: the given CRS, or the
    /// local frame's Local Orthographic projection as a PROJ string.
    pub fn source_crs(&self) -> Option<String> {
        if let Some(crs) = &self.crs {
            return Some(crs.trim().to_string());
        }
        let [lon, lat, h] = self.anchor?;
        let [x0, y0, _] = self.anchor_at.unwrap_or_default();
        let alpha = self.north_rotation.unwrap_or(0.0);
        Some(format!(
            "+proj=ortho +lat_0={lat} +lon_0={lon} +alpha={alpha} +k_0={k} +x_0={x0} +y_0={y0} \
             +ellps=WGS84 +units=m +no_defs",
            k = height_scale(lat, h)
        ))
    }

    /// The transformation of the plan's coordinates to WGS84.
    pub fn to_wgs84(&self) -> Result<ToWgs84, GeorefError> {
        let field = if self.is_local() { "anchor" } else { "crs" };
        let crs = self
            .source_crs()
            .ok_or_else(|| bad("crs", "no CRS and no anchor"))?;
        ToWgs84::new(&crs).map_err(|e| bad(field, e.to_string()))
    }
}

/// The scale that makes the tangent plane's metres true metres at `h` above the ellipsoid:
/// (R + h) / R, with R the Gaussian mean radius at latitude `lat` (degrees).
pub fn height_scale(lat: f64, h: f64) -> f64 {
    let s2 = lat.to_radians().sin().powi(2);
    let w = 1.0 - WGS84_E2 * s2;
    let n = WGS84_A / w.sqrt();
    let m = WGS84_A * (1.0 - WGS84_E2) / (w * w.sqrt());
    let r = (m * n).sqrt();
    (r + h) / r
}

/// A CRS a client gives: `EPSG:n` or WKT, projected, one proj4rs can use.
fn check_crs(crs: &str) -> Result<(), GeorefError> {
    let crs = crs.trim();
    if crs.is_empty() || crs.chars().count() > MAX_CRS_CHARS {
        return Err(bad(
            "crs",
            format!("give `EPSG:n` or WKT, at most {MAX_CRS_CHARS} characters"),
        ));
    }
    if crs.starts_with('+') {
        return Err(bad(
            "crs",
            "give `EPSG:n` or WKT; PROJ strings are not taken (a local frame is `anchor`)",
        ));
    }
    ToWgs84::new(crs).map(drop).map_err(|e| match e {
        Wgs84Error::Geographic => bad(
            "crs",
            format!(
                "{crs} is geographic (degrees): plans need a projected CRS in metres, or a \
                 local frame (`anchor`)"
            ),
        ),
        e => bad("crs", e.to_string()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_crs_or_an_anchor_is_checked_naming_the_field() {
        assert!(Georeference::of_crs("EPSG:25832").check().is_ok());
        let local = Georeference {
            anchor: Some([8.54, 47.37, 408.0]),
            north_rotation: Some(12.5),
            height_datum: Some("EPSG:5728".into()),
            ..Default::default()
        };
        assert!(local.check().is_ok());
        let cases = [
            (Georeference::default(), "crs"),
            (Georeference::of_crs("EPSG:99999"), "crs"),
            (Georeference::of_crs("EPSG:4326"), "crs"),
            (Georeference::of_crs("PROJCS[\"x\""), "crs"),
            (Georeference::of_crs("+proj=utm +zone=32"), "crs"),
            (
                Georeference {
                    north_rotation: Some(3.0),
                    ..Georeference::of_crs("EPSG:25832")
                },
                "north_rotation",
            ),
            (
                Georeference {
                    anchor: Some([8.0, 47.0, 0.0]),
                    ..Georeference::of_crs("EPSG:25832")
                },
                "anchor",
            ),
            (
                Georeference {
                    anchor: Some([8.0, 95.0, 0.0]),
                    ..Default::default()
                },
                "anchor",
            ),
            (
                Georeference {
                    anchor: Some([8.0, 47.0, f64::NAN]),
                    ..Default::default()
                },
                "anchor",
            ),
            (
                Georeference {
                    north_rotation: Some(f64::INFINITY),
                    ..local.clone()
                },
                "north_rotation",
            ),
            (
                Georeference {
                    anchor_at: Some([0.0, 1e9, 0.0]),
                    ..local.clone()
                },
                "anchor_at",
            ),
            (
                Georeference {
                    height_datum: Some(String::new()),
                    ..local.clone()
                },
                "height_datum",
            ),
        ];
        for (g, field) in cases {
            let err = g.check().expect_err(&format!("{g:?} accepted"));
            assert_eq!(err.field, field, "{g:?}: {err}");
        }
    }

    #[test]
    fn the_anchor_lands_on_its_longitude_and_latitude() {
        let g = Georeference {
            anchor: Some([8.54, 47.37, 408.0]),
            anchor_at: Some([10.0, -5.0, 0.0]),
            north_rotation: Some(30.0),
            ..Default::default()
        };
        let t = g.to_wgs84().unwrap();
        let [lon, lat] = t.lon_lat(10.0, -5.0).unwrap();
        assert!((lon - 8.54).abs() < 1e-10 && (lat - 47.37).abs() < 1e-10);
        // Local +y is 30° east of north: 100 m along it goes north and east.
        let [lon2, lat2] = t.lon_lat(10.0, 95.0).unwrap();
        let north = (lat2 - lat).to_radians() * 6_367_000.0;
        let east = (lon2 - lon).to_radians() * 6_389_000.0 * lat.to_radians().cos();
        assert!(
            (north - 86.6).abs() < 0.2 && (east - 50.0).abs() < 0.2,
            "{north} {east}"
        );
    }

    #[test]
    fn height_scales_the_frame_by_the_earths_radius() {
        assert_eq!(height_scale(47.0, 0.0), 1.0);
        let k = height_scale(47.0, 637.0);
        assert!((k - 1.0001).abs() < 1e-6, "{k}");
    }
}
