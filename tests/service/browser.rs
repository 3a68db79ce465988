//! The upload page in headless chromium (Debian's), driven by playwright-core: upload a cloud
//! through the page, follow the progress, and check the plan is drawn; then one scenario per
//! promise of the page (`tests/browser/page.mjs`). Skips with a reason when node or chromium
//! are missing, except under CI.

use crate::support::server;

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use asbuilt::worker::fake::FakePipeline;
use serde_json::Value;

const KEY: &str = "acme-browser-key-0001";

async fn fake_server() -> server::Server {
    let pipeline = Arc::new(FakePipeline {
        stage_time: Duration::from_millis(60),
        completions: None,
        spin: false,
    });
    server::start(pipeline, |c| c.api_keys = vec![format!("acme:{KEY}")]).await
}

#[tokio::test(flavor = "multi_thread")]
async fn the_page_uploads_follows_and_draws_the_plan() {
    if server::browser_missing().is_some() {
        return;
    }
    let s = fake_server().await;
    let cloud = s.dir.path().join("room.xyz");
    std::fs::write(&cloud, server::xyz(500)).unwrap();
    let shot = std::env::temp_dir().join("asbuilt-page.png");
    let seen = server::browser_upload(&s.base, &cloud, None, &shot, Some(KEY)).await;
    assert_eq!(seen["status"], "succeeded");
    assert_eq!(seen["walls"], 2, "{seen}");
    assert_eq!(seen["arcs"], 1, "{seen}");
    assert!(seen["jobs"].as_u64().unwrap() >= 1);
    // The fake plan has no viewpoints (an x, y, z cloud, no poses): a yellow warning says so.
    let warning = seen["viewWarning"].as_str().unwrap();
    assert!(warning.contains("No scanner poses"), "{seen}");
    assert!(warning.contains("wall geometry alone"), "{seen}");
    assert_eq!(seen["statusWarn"], true, "{seen}");
    assert_eq!(seen["statusColor"], "rgb(107, 78, 0)", "{seen}");
    assert!(
        std::fs::metadata(&shot).unwrap().len() > 10_000,
        "a real screenshot"
    );
    eprintln!("screenshot: {}", shot.display());
}

/// The files a scenario may choose: clouds, sidecars of both kinds, a bad one, a refused one.
fn scenario_files(dir: &Path) {
    std::fs::write(dir.join("room.xyz"), server::xyz(400)).unwrap();
    std::fs::write(dir.join("other.xyz"), server::xyz(300)).unwrap();
    let samples: Vec<Value> = (0..20)
        .map(|i| serde_json::json!({"t": i as f64 * 0.1, "position": [i as f64 * 0.2, 1.0, 1.5], "quaternion": [1, 0, 0, 0]}))
        .collect();
    std::fs::write(
        dir.join("trajectory.json"),
        serde_json::json!({ "samples": samples }).to_string(),
    )
    .unwrap();
    std::fs::write(
        dir.join("poses.json"),
        r#"{"scans": [{"index": 0, "position": [2, 1.5, 1.2], "quaternion": [1, 0, 0, 0]}]}"#,
    )
    .unwrap();
    std::fs::write(dir.join("bad.json"), r#"{"poses": []}"#).unwrap();
    std::fs::write(dir.join("refused.txt"), "hello world, this is text\n").unwrap();
    // Large enough to abort while a slowed upload runs (the page never gets to send it all).
    std::fs::write(dir.join("big.xyz"), server::xyz(400_000)).unwrap();
    // The fake pipeline sits in its fit stage for 20 s: long enough to cancel.
    std::fs::write(
        dir.join("hang.xyz"),
        format!("#hang:20\n{}", server::xyz(100)),
    )
    .unwrap();
}

/// Runs one scenario of `page.mjs` against a fresh fake server holding `jobs_before` jobs made
/// through the API; returns what the page showed (its checks already passed).
async fn scenario(name: &str, jobs_before: usize) -> Option<Value> {
    if server::browser_missing().is_some() {
        return None;
    }
    let s = fake_server().await;
    scenario_files(s.dir.path());
    for i in 0..jobs_before {
        let res = s
            .post("/v1/jobs?filename=room.xyz")
            .body(server::xyz(50 + i))
            .send()
            .await
            .unwrap();
        assert_eq!(res.status(), 202);
        let id = res.json::<Value>().await.unwrap()["id"]
            .as_str()
            .unwrap()
            .to_string();
        s.wait_done(&id, Duration::from_secs(30)).await;
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser");
    let out = tokio::time::timeout(
        Duration::from_secs(240),
        tokio::process::Command::new("node")
            .current_dir(&dir)
            .arg("page.mjs")
            .arg(&s.base)
            .arg(name)
            .arg(s.dir.path())
            .arg(KEY)
            .output(),
    )
    .await
    .expect("browser run timed out")
    .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "browser checks failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let seen: Value = serde_json::from_str(stdout.lines().last().unwrap_or_default()).unwrap();
    assert_eq!(seen["scenario"], name);
    for shot in ["underlay.png", "points.png", "phone.png", "replan.png"] {
        let p = s.dir.path().join(shot);
        if p.exists() {
            let kept = std::env::temp_dir().join(format!("asbuilt-page-{shot}"));
            std::fs::copy(&p, &kept).unwrap();
            eprintln!("screenshot: {}", kept.display());
        }
    }
    Some(seen)
}

#[tokio::test(flavor = "multi_thread")]
async fn a_mobile_scan_goes_with_its_trajectory() {
    let Some(seen) = scenario("mobile", 0).await else {
        return;
    };
    assert_eq!(seen["sidecar"], "trajectory", "{seen}");
    assert_eq!(seen["badStart"], true, "{seen}");
}

#[tokio::test(flavor = "multi_thread")]
async fn poses_do_not_stay_for_the_next_scan() {
    let Some(seen) = scenario("stale", 0).await else {
        return;
    };
    assert_eq!(seen["first"], "poses", "{seen}");
    assert_eq!(seen["second"], Value::Null, "{seen}");
}

#[tokio::test(flavor = "multi_thread")]
async fn parameters_warnings_notes_and_stages_are_shown() {
    let Some(seen) = scenario("warnings", 0).await else {
        return;
    };
    assert_eq!(seen["story"], "story 2 of 3", "{seen}");
    assert_eq!(seen["serverStory"], "story 3 of 4", "{seen}");
    assert_eq!(seen["reading"]["width"], "25%", "{seen}");
    assert_eq!(seen["sentCell"], 0.05, "{seen}");
}

#[tokio::test(flavor = "multi_thread")]
async fn the_underlay_scanners_and_rooms_are_drawn_and_toggled() {
    let Some(seen) = scenario("underlay", 0).await else {
        return;
    };
    assert_eq!(seen["rooms"], 2, "{seen}");
    assert_eq!(seen["hidden"], "none", "{seen}");
    assert_eq!(seen["image"], 1, "{seen}");
    assert_eq!(seen["dashed"], "6 4", "{seen}");
}

/// The server's own image of the points, placed by the GeoJSON's `floorplan.underlay`, decoded
/// by Chromium, toggled, faded, and carried into the SVG download.
#[tokio::test(flavor = "multi_thread")]
async fn the_points_lie_under_the_plan_and_go_into_the_svg() {
    let Some(seen) = scenario("points", 0).await else {
        return;
    };
    assert_eq!(
        seen["pixels"]["size"],
        serde_json::json!([50, 40]),
        "{seen}"
    );
    assert_eq!(seen["pixels"]["wall"][3], 255, "{seen}");
    assert_eq!(seen["svgLayer"], true, "{seen}");
    assert_eq!(seen["axe"], serde_json::json!([]), "{seen}");
}

#[tokio::test(flavor = "multi_thread")]
async fn the_plan_measures_distances_and_walls() {
    let Some(seen) = scenario("measure", 0).await else {
        return;
    };
    let d = seen["measured"].as_f64().unwrap();
    assert!((d - 13f64.sqrt()).abs() < 0.02, "{seen}");
}

#[tokio::test(flavor = "multi_thread")]
async fn a_job_survives_a_reload_and_the_list_pages() {
    let Some(seen) = scenario("reload", 11).await else {
        return;
    };
    assert_eq!(seen["allPages"], 12, "{seen}");
    assert_eq!(seen["deleted"], 404, "{seen}");
}

#[tokio::test(flavor = "multi_thread")]
async fn the_page_works_from_the_keyboard_and_passes_axe() {
    let Some(seen) = scenario("keyboard", 1).await else {
        return;
    };
    assert_eq!(seen["axe"], serde_json::json!([]), "{seen}");
}

#[tokio::test(flavor = "multi_thread")]
async fn the_page_works_on_a_phone() {
    let Some(seen) = scenario("phone", 0).await else {
        return;
    };
    let zoom = seen["pinch"].as_f64().unwrap();
    assert!(zoom > 2.5, "{seen}");
}

#[tokio::test(flavor = "multi_thread")]
async fn downloads_follow_the_links_and_a_running_job_is_cancelled() {
    let Some(seen) = scenario("outputs", 0).await else {
        return;
    };
    // Every result the server offers, GeoJSON first, IFC and the room schedule included.
    let offered: Vec<&str> = asbuilt_plan::io::outputs::OUTPUTS
        .iter()
        .map(|o| o.name)
        .collect();
    let mut buttons: Vec<&str> = seen["buttons"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b.as_str().unwrap())
        .collect();
    buttons.sort();
    let mut want = offered.clone();
    want.sort();
    assert_eq!(buttons, want, "{seen}");
    let rooms = seen["names"]["rooms"].as_str().unwrap();
    assert!(
        rooms.starts_with("room-") && rooms.ends_with("-rooms.csv"),
        "{seen}"
    );
    assert_eq!(seen["cancelled"]["status"], "cancelled", "{seen}");
    assert_eq!(seen["axe"], serde_json::json!([]), "{seen}");
}

#[tokio::test(flavor = "multi_thread")]
async fn a_job_is_planned_again_without_uploading() {
    let Some(seen) = scenario("replan", 0).await else {
        return;
    };
    assert_eq!(seen["second"]["cell"], 0.1, "{seen}");
    assert_eq!(seen["second"]["sidecar"], "poses", "{seen}");
    assert_eq!(seen["third"]["sidecar"], "trajectory", "{seen}");
    assert_eq!(seen["third"]["cell"], seen["third"]["dflt"], "{seen}");
    assert_eq!(seen["posts"].as_array().unwrap().len(), 2, "{seen}");
    assert_eq!(seen["axe"], serde_json::json!([]), "{seen}");
}
