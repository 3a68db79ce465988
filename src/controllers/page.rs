//! `GET /`: the upload page, one self-contained HTML file compiled into the binary, with the
//! pipeline's own tables (parameter ranges and units, stage names and weights) put in at start,
//! so the page checks values and follows progress by the same rules as the server.

use std::sync::LazyLock;

use axum::http::header::{CACHE_CONTROL, CONTENT_SECURITY_POLICY, CONTENT_TYPE};
use axum::response::IntoResponse;
use serde_json::{json, Map, Value};

const TEMPLATE: &str = include_str!("../../static/index.html");

/// Where the tables go in the template.
const SLOT: &str = "/*PIPELINE*/{}";

/// The template with the tables in place.
static PAGE: LazyLock<String> = LazyLock::new(|| {
    // `</` cannot occur in the JSON (no value holds it), so it cannot end the script block early.
    TEMPLATE.replacen(SLOT, &tables().to_string(), 1)
});

/// `ranges`: `section.name` → `{min, max, unit}`; `stages`: `[{name, weight}]` in pipeline order;
/// `outputs`: `name` → `{file, about}`, to describe the downloads a job's `links` offer.
fn tables() -> Value {
    let ranges: Map<String, Value> = asbuilt_plan::params::ranges()
        .into_iter()
        .map(|(section, r)| {
            (
                format!("{section}.{}", r.name),
                json!({"min": r.min, "max": r.max, "unit": r.unit}),
            )
        })
        .collect();
    let stages: Vec<Value> = asbuilt_plan::progress::STAGES
        .iter()
        .map(|r| json!({"name": r.name, "weight": r.weight}))
        .collect();
    let outputs: Map<String, Value> = asbuilt_plan::io::outputs::OUTPUTS
        .iter()
        .map(|o| {
            (
                o.name.to_string(),
                json!({"file": o.file, "about": o.about}),
            )
        })
        .collect();
    json!({"ranges": ranges, "stages": stages, "outputs": outputs})
}

/// The page; in a debug build with `ASBUILT_PAGE_FROM=static/index.html`, read afresh from that
/// file at every request, to work on the page without rebuilding.
fn page() -> String {
    #[cfg(debug_assertions)]
    if let Some(path) = std::env::var_os("ASBUILT_PAGE_FROM") {
        if let Ok(text) = std::fs::read_to_string(path) {
            return text.replacen(SLOT, &tables().to_string(), 1);
        }
    }
    PAGE.clone()
}

pub async fn index() -> impl IntoResponse {
    (
        [
            (CONTENT_TYPE, "text/html; charset=utf-8"),
            (CACHE_CONTROL, "no-cache"),
            // Nothing from elsewhere: the page works offline and cannot be made to load scripts.
            (
                CONTENT_SECURITY_POLICY,
                "default-src 'self'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src 'self' data: blob:; connect-src 'self'",
            ),
        ],
        page(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_carries_every_range_and_stage() {
        assert!(TEMPLATE.contains(SLOT), "the template lost its slot");
        assert!(!PAGE.contains(SLOT));
        let t = tables();
        let ranges = t["ranges"].as_object().unwrap();
        assert_eq!(ranges.len(), asbuilt_plan::params::ranges().len());
        assert_eq!(ranges["samples.cell_size"]["unit"], "m");
        assert_eq!(ranges["fitting.inlier_angle"]["unit"], "rad");
        let names: Vec<&str> = t["stages"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["name"].as_str().unwrap())
            .collect();
        assert_eq!(names.first(), Some(&"read"));
        assert_eq!(names.last(), Some(&"write"));
        let outputs = t["outputs"].as_object().unwrap();
        assert_eq!(outputs.len(), asbuilt_plan::io::outputs::OUTPUTS.len());
        assert_eq!(outputs["rooms"]["file"], "rooms.csv");
        assert!(PAGE.contains(&t.to_string()));
    }
}
