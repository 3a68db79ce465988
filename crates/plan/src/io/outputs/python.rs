//! Writer tests that ask the reference Python libraries (shapely, ezdxf, ifcopenshell) to read
//! what we wrote. Under CI (`CI` set) a missing library fails the test; elsewhere it skips,
//! saying why.

use std::process::Command;

/// Runs `script` with `args` under python3 and returns what it printed as JSON, or `None`
/// (after saying why) when python3 cannot import `modules` outside CI.
pub(crate) fn run_json(modules: &[&str], script: &str, args: &[&str]) -> Option<serde_json::Value> {
    let (imports, pip) = (modules.join(", "), modules.join(" "));
    let probe = Command::new("python3")
        .args(["-c", &format!("import {imports}")])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must have python3 with {imports} (pip install {pip})"
        );
        eprintln!("skipped: python3 with {imports} is not available (pip install {pip})");
        return None;
    }
    let run = Command::new("python3")
        .args(["-c", script])
        .args(args)
        .output()
        .expect("python3 runs");
    assert!(
        run.status.success(),
        "python failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    Some(serde_json::from_slice(&run.stdout).expect("the script prints JSON"))
}

/// A temporary file holding `bytes` (removed when dropped), named with `suffix` for readers
/// that look at the extension.
pub(crate) fn temp_file(suffix: &str, bytes: &[u8]) -> tempfile::NamedTempFile {
    use std::io::Write;
    let mut f = tempfile::Builder::new()
        .prefix("asbuilt-")
        .suffix(suffix)
        .tempfile()
        .expect("a temp file");
    f.write_all(bytes).expect("temp file written");
    f
}
