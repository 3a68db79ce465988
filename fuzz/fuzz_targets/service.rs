//! Shared by the HTTP targets: the service's real router (SQLite and a blob directory in a
//! temporary folder, no workers) driven in-process, and the checks every answer must pass.

use std::sync::{Arc, OnceLock};

use asbuilt::app::{self, App, AppState};
use asbuilt::auth::Keys;
use asbuilt::config::Config;
use asbuilt::errors::CODES;
use asbuilt::limits::Limits;
use asbuilt::metrics::Metrics;
use axum::body::Body;
use axum::http::{Request, StatusCode};
use tower::ServiceExt;

pub const KEY: &str = "fuzz-key-0000000000001";

pub struct Harness {
    pub rt: tokio::runtime::Runtime,
    router: axum::Router,
    _dir: tempfile::TempDir,
}

/// The one router, built on first use.
pub fn harness() -> &'static Harness {
    static H: OnceLock<Harness> = OnceLock::new();
    H.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let config = Config {
            data_dir: dir.path().to_path_buf(),
            workers: 0,
            max_upload_bytes: 1 << 20,
            max_sidecar_bytes: 64 << 10,
            api_keys: vec![format!("acme:{KEY}")],
            rate_limit: 0.0,
            max_queued: 0,
            ..Config::default()
        };
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let (store, blobs) = rt.block_on(async {
            (
                app::open_store(&config).await.unwrap(),
                app::open_blobs(&config).await.unwrap(),
            )
        });
        let keys = Keys::new(&config.all_keys().unwrap(), false);
        let state = AppState(Arc::new(App {
            keys,
            limits: Limits::new(0.0, 0),
            metrics: Metrics::default(),
            changes: tokio::sync::broadcast::channel(16).0,
            queued: tokio::sync::Notify::new(),
            shutdown: tokio_util::sync::CancellationToken::new(),
            store,
            blobs,
            config,
        }));
        Harness {
            rt,
            router: asbuilt::router::build(state),
            _dir: dir,
        }
    })
}

impl Harness {
    /// Sends one request; checks the answer (see [`check`]); deletes a job it created, so
    /// the store does not grow over a long run.
    pub fn send(&self, req: Request<Body>) -> StatusCode {
        let router = self.router.clone();
        let (status, body) = self.rt.block_on(async move {
            let res = router.oneshot(req).await.unwrap();
            let status = res.status();
            let ctype = res
                .headers()
                .get("content-type")
                .and_then(|v| v.to_str().ok())
                .unwrap_or_default()
                .to_string();
            let body = axum::body::to_bytes(res.into_body(), 16 << 20).await.unwrap();
            check(status, &ctype, &body);
            (status, body)
        });
        if status == StatusCode::ACCEPTED {
            let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
            let id = v["id"].as_str().unwrap();
            let del = Request::delete(format!("/v1/jobs/{id}"))
                .header("authorization", format!("Bearer {KEY}"))
                .body(Body::empty())
                .unwrap();
            let router = self.router.clone();
            let st = self
                .rt
                .block_on(async move { router.oneshot(del).await.unwrap().status() });
            assert_eq!(st, StatusCode::NO_CONTENT);
        }
        status
    }
}

/// Every error is JSON with a documented code whose status is the answer's; nothing is a 500.
pub fn check(status: StatusCode, ctype: &str, body: &[u8]) {
    assert!(
        status != StatusCode::INTERNAL_SERVER_ERROR,
        "500: {}",
        String::from_utf8_lossy(body)
    );
    if status.as_u16() < 400 {
        return;
    }
    assert!(ctype.starts_with("application/json"), "{status} {ctype}");
    let v: serde_json::Value = serde_json::from_slice(body).expect("a JSON error body");
    let code = v["error"]["code"].as_str().expect("error.code");
    let known = CODES
        .iter()
        .find(|c| c.as_str() == code)
        .unwrap_or_else(|| panic!("unknown code {code}"));
    assert_eq!(known.status(), status, "{code}");
    assert!(!v["error"]["message"].as_str().unwrap_or_default().is_empty());
}
