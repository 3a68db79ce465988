//! The upload page in headless chromium (Debian's), driven by playwright-core: upload a cloud
//! through the page, follow the progress, and check the plan is drawn. Skips with a reason
//! when node or chromium are missing, except under CI.

use crate::support::server;

use std::sync::Arc;
use std::time::Duration;

use asbuilt::worker::fake::FakePipeline;

#[tokio::test(flavor = "multi_thread")]
async fn the_page_uploads_follows_and_draws_the_plan() {
    if server::browser_missing().is_some() {
        return;
    }
    let pipeline = Arc::new(FakePipeline {
        stage_time: Duration::from_millis(150),
        completions: None,
        spin: false,
    });
    let s = server::start(pipeline, |c| {
        c.api_keys = vec!["acme:acme-browser-key-0001".into()]
    })
    .await;
    let cloud = s.dir.path().join("room.xyz");
    std::fs::write(&cloud, server::xyz(500)).unwrap();
    let shot = std::env::temp_dir().join("asbuilt-page.png");
    let seen =
        server::browser_upload(&s.base, &cloud, None, &shot, Some("acme-browser-key-0001")).await;
    assert_eq!(seen["status"], "succeeded");
    assert_eq!(seen["walls"], 2, "{seen}");
    assert_eq!(seen["arcs"], 1, "{seen}");
    assert!(seen["jobs"].as_u64().unwrap() >= 1);
    // The fake plan has no viewpoints (an x, y, z cloud, no poses): a yellow warning says so.
    let warning = seen["viewWarning"].as_str().unwrap();
    assert!(warning.contains("No scanner poses"), "{seen}");
    assert!(warning.contains("wall geometry alone"), "{seen}");
    assert_eq!(seen["statusWarn"], true, "{seen}");
    assert_eq!(seen["statusColor"], "rgb(122, 89, 0)", "{seen}");
    assert!(
        std::fs::metadata(&shot).unwrap().len() > 10_000,
        "a real screenshot"
    );
    eprintln!("screenshot: {}", shot.display());
}
