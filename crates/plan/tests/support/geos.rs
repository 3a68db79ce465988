//! An independent validity check: GEOS (through python3 and shapely) judges every story polygon
//! of a plan's GeoJSON by the OGC Simple Features rules, as PostGIS `ST_IsValid` would.
//!
//! Many documents go to one python process, so a property test over hundreds of plans pays
//! the interpreter's start-up once.
#![allow(dead_code)]

use std::io::Write;
use std::process::{Command, Stdio};

use serde_json::Value;

/// GEOS's verdict on one story feature.
#[derive(Debug, Clone, PartialEq)]
pub struct StoryVerdict {
    pub level: u64,
    pub valid: bool,
    /// `is_valid_reason`: "Valid Geometry", or the problem and where ("Self-intersection[x y]").
    pub reason: String,
}

const SCRIPT: &str = r#"
import json, sys
import shapely
from shapely.geometry import shape
out = []
for doc in json.load(sys.stdin):
    verdicts = []
    for f in doc["features"]:
        p = f.get("properties") or {}
        if p.get("kind") != "story":
            continue
        g = shape(f["geometry"])
        verdicts.append([p.get("level"), bool(g.is_valid), shapely.is_valid_reason(g)])
    out.append(verdicts)
print(json.dumps(out))
"#;

/// Why GEOS cannot run here, if it cannot. Under CI (`CI` set) that is a failure, not a skip.
pub fn geos_missing() -> Option<String> {
    let probe = Command::new("python3")
        .args(["-c", "import shapely"])
        .output();
    let why = match probe {
        Err(e) => Some(format!("python3 cannot run: {e}")),
        Ok(o) if !o.status.success() => Some("python3 has no shapely (pip install shapely)".into()),
        Ok(_) => None,
    };
    if let Some(why) = &why {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must have python3 with shapely: {why}"
        );
        eprintln!("skipping the GEOS check: {why}");
    }
    why
}

/// GEOS's verdict on every story of every document, in order; `None` (after saying why) when
/// python3 with shapely is missing outside CI.
pub fn geos_validity(docs: &[Value]) -> Option<Vec<Vec<StoryVerdict>>> {
    if geos_missing().is_some() {
        return None;
    }
    let mut child = Command::new("python3")
        .args(["-c", SCRIPT])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 starts");
    let input = serde_json::to_vec(docs).unwrap();
    let mut stdin = child.stdin.take().unwrap();
    // Written from a thread: a large batch would fill the pipe before python answers.
    let writer = std::thread::spawn(move || stdin.write_all(&input));
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap().unwrap();
    assert!(
        out.status.success(),
        "shapely failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Vec<Vec<(u64, bool, String)>> = serde_json::from_slice(&out.stdout).unwrap();
    Some(
        v.into_iter()
            .map(|doc| {
                doc.into_iter()
                    .map(|(level, valid, reason)| StoryVerdict {
                        level,
                        valid,
                        reason,
                    })
                    .collect()
            })
            .collect(),
    )
}

/// The invalid stories of a batch, as "name level N: reason" lines.
pub fn invalid_stories(names: &[String], verdicts: &[Vec<StoryVerdict>]) -> Vec<String> {
    names
        .iter()
        .zip(verdicts)
        .flat_map(|(name, doc)| {
            doc.iter()
                .filter(|v| !v.valid)
                .map(move |v| format!("{name} level {}: {}", v.level, v.reason))
        })
        .collect()
}
