//! The API document. `openapi/asbuilt.yaml` is the published contract; the server serves it as
//! JSON, and tests check it against [`crate::router::routes`] and [`crate::errors::CODES`].

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
    use asbuilt_plan::progress::STAGES;

    /// Each output of the list is a documented download with its media type, a `links` entry,
    /// and a route; and the document lists no other result.
    #[test]
    fn results_follow_the_output_list() {
        use asbuilt_plan::io::outputs::OUTPUTS;
        let doc = document();
        let links = &doc["components"]["schemas"]["Job"]["properties"]["links"]["properties"];
        let mut named: Vec<&str> = links
            .as_object()
            .expect("links")
            .keys()
            .map(String::as_str)
            .filter(|k| !matches!(*k, "self" | "events"))
            .collect();
        named.sort_unstable();
        let mut listed: Vec<&str> = OUTPUTS.iter().map(|o| o.name).collect();
        listed.sort_unstable();
        assert_eq!(named, listed);
        let results: Vec<&str> = doc["paths"]
            .as_object()
            .expect("paths")
            .keys()
            .filter_map(|p| p.strip_prefix("/v1/jobs/{id}/"))
            // The fixed routes (events, cancel, ...) are not results.
            .filter(|f| {
                !crate::router::ROUTES
                    .iter()
                    .any(|(_, p)| p.strip_prefix("/v1/jobs/{id}/") == Some(*f))
            })
            .collect();
        assert_eq!(results, OUTPUTS.iter().map(|o| o.file).collect::<Vec<_>>());
        // A succeeded job links every output; any other links none.
        let rules = doc["components"]["schemas"]["Job"]["allOf"]
            .as_array()
            .expect("Job rules");
        let succeeded = rules
            .iter()
            .find(|r| r["if"]["properties"]["status"]["const"] == "succeeded")
            .expect("a rule for succeeded jobs");
        let mut required: Vec<&str> = succeeded["then"]["properties"]["links"]["required"]
            .as_array()
            .expect("required links")
            .iter()
            .filter_map(|v| v.as_str())
            .filter(|k| !matches!(*k, "self" | "events"))
            .collect();
        required.sort_unstable();
        assert_eq!(required, listed);
        let mut absent: Vec<&str> = succeeded["else"]["properties"]["links"]["not"]["anyOf"]
            .as_array()
            .expect("links absent otherwise")
            .iter()
            .filter_map(|r| r["required"][0].as_str())
            .collect();
        absent.sort_unstable();
        assert_eq!(absent, listed);
        for o in OUTPUTS {
            let path = format!("/v1/jobs/{{id}}/{}", o.file);
            let content = &doc["paths"][&path]["get"]["responses"]["200"]["content"];
            assert!(content.get(o.media_type).is_some(), "{path}: {content}");
            assert!(
                crate::router::routes().contains(&("GET", path.clone())),
                "{path}"
            );
        }
    }

    /// The document's `Stage` enum and its job error codes follow the pipeline's stage table.
    #[test]
    fn stage_names_and_codes_follow_the_table() {
        let names: Vec<&str> = STAGES.iter().map(|r| r.name).collect();
        let doc = &document()["components"]["schemas"];
        let stated: Vec<&str> = doc["Stage"]["enum"]
            .as_array()
            .expect("a Stage enum")
            .iter()
            .filter_map(|v| v.as_str())
            .collect();
        assert_eq!(stated, names);
        // The page gets the table itself when served (controllers::page tests that).
        for code in STAGES.iter().filter_map(|r| r.error_code) {
            assert!(
                doc["JobErrorCode"]["enum"]
                    .as_array()
                    .expect("a JobErrorCode enum")
                    .iter()
                    .any(|c| c == code),
                "{code}"
            );
            assert!(crate::errors::JOB_CODES.iter().any(|c| c.as_str() == code));
        }
    }

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
