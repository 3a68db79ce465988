#![no_main]
//! The `params` part's JSON or TOML, and one `section.name=value` override, as the upload
//! handler reads them: parsed, checked against every range, written back as JSON.

use asbuilt_plan::Params;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(p) = Params::from_file_text(text) {
        if p.check().is_ok() {
            // What passes is stored as JSON and read back by the worker.
            let back: Params = serde_json::from_value(p.to_json()).unwrap();
            assert_eq!(back, p);
        }
    }
    if Params::check_override(text).is_ok() {
        let mut p = Params::default();
        p.set(text).unwrap();
    }
});
