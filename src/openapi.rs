//! The API document. `openapi/asbuilt.yaml` is the published contract; the server serves it as
//! JSON, and tests check it against [`crate::router::ROUTES`] and [`crate::errors::CODES`].

use std::sync::OnceLock;

/// The YAML source, compiled in.
pub const YAML: &str = include_str!("../openapi/asbuilt.yaml");

/// The document as JSON, parsed once.
pub fn document() -> &'static serde_json::Value {
    static DOC: OnceLock<serde_json::Value> = OnceLock::new();
    DOC.get_or_init(|| serde_yaml::from_str(YAML).expect("openapi/asbuilt.yaml is valid YAML"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The document states exactly the ranges the pipeline enforces.
    #[test]
    fn parameter_ranges_match_the_pipeline() {
        let sections = &document()["components"]["schemas"]["Parameters"]["properties"];
        let mut stated = 0;
        for (section, schema) in sections.as_object().expect("sections") {
            for (name, leaf) in schema["properties"].as_object().into_iter().flatten() {
                let Some(min) = leaf["minimum"].as_f64() else {
                    continue;
                };
                if let Some(max) = leaf["maximum"].as_f64() {
                    let enforced = asbuilt_plan::params::ranges()
                        .into_iter()
                        .find(|(s, r)| s == section && r.name == name)
                        .map(|(_, r)| (r.min, r.max));
                    assert_eq!(enforced, Some((min, max)), "{section}.{name}");
                    stated += 1;
                }
            }
        }
        assert_eq!(stated, asbuilt_plan::params::ranges().len());
    }
}
