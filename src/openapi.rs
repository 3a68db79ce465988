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
