//! The running service: shared state, startup (stores, migrations, workers, sweeper, listener)
//! and graceful shutdown.

use std::net::SocketAddr;
use std::ops::Deref;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use axum::serve::ListenerExt;
use tokio::net::TcpListener;
use tokio::sync::{broadcast, Notify};
use tokio::task::JoinHandle;
use tokio_util::sync::CancellationToken;

use crate::auth::Keys;
use crate::config::Config;
use crate::limits::Limits;
use crate::metrics::Metrics;
use crate::net::GuardedListener;
use crate::queue::postgres::PgJobStore;
use crate::queue::sqlite::SqliteJobStore;
use crate::queue::{JobId, JobStore};
use crate::storage::{local, s3, BlobStore};
use crate::worker::fake::FakePipeline;
use crate::worker::pipeline::{Pipeline, PlanPipeline};
use crate::worker::{sweeper, Workers};

/// What every handler and worker shares.
pub struct App {
    pub config: Config,
    pub store: Arc<dyn JobStore>,
    pub blobs: Arc<dyn BlobStore>,
    pub keys: Keys,
    /// Per-tenant request rates and the brake on unknown keys.
    pub limits: Limits,
    pub metrics: Metrics,
    /// Job ids whose state changed (SSE streams listen).
    pub changes: broadcast::Sender<JobId>,
    /// Wakes an idle worker when a job is queued.
    pub queued: Notify,
    /// Cancelled when shutdown begins: readiness fails and event streams end.
    pub shutdown: CancellationToken,
    /// Callback secrets, default URLs and the targets they may reach.
    pub webhooks: crate::webhooks::Settings,
    /// Uploads read as they arrive, for this process's workers.
    pub early: crate::worker::early::Early,
}

/// A cheap handle on [`App`].
#[derive(Clone)]
pub struct AppState(pub Arc<App>);

impl Deref for AppState {
    type Target = App;

    fn deref(&self) -> &App {
        &self.0
    }
}

impl AppState {
    /// Tells event streams that a job changed.
    pub fn changed(&self, id: JobId) {
        let _ = self.changes.send(id);
    }
}

/// Opens the job store the config names, and migrates it (`asbuilt migrate`).
pub async fn open_store(config: &Config) -> anyhow::Result<Arc<dyn JobStore>> {
    let store = connect_store(config).await?;
    store.migrate().await?;
    Ok(store)
}

/// Opens the job store the config names, without touching its schema.
pub async fn connect_store(config: &Config) -> anyhow::Result<Arc<dyn JobStore>> {
    let url = config.database_url();
    if config.shared_database() {
        let store = PgJobStore::connect(&url)
            .await
            .context("connecting to PostgreSQL")?;
        return Ok(Arc::new(store));
    }
    if url.contains("://") && !url.starts_with("sqlite:") {
        anyhow::bail!("database URL `{url}`: expected sqlite://PATH or postgres://...");
    }
    if let Some(parent) = std::path::Path::new(url.trim_start_matches("sqlite://")).parent() {
        std::fs::create_dir_all(parent).ok();
    }
    Ok(Arc::new(SqliteJobStore::open_url(&url).await?))
}

/// Opens the store for a serving process: the embedded SQLite database migrates itself (zero
/// setup); a shared database must already be at this binary's schema.
async fn start_store(config: &Config) -> anyhow::Result<Arc<dyn JobStore>> {
    let store = connect_store(config).await?;
    if config.shared_database() {
        store.check_schema().await?;
    } else {
        store.migrate().await?;
    }
    Ok(store)
}

/// Opens the blob store the config names: S3 for `s3://...`, else a local directory.
pub async fn open_blobs(config: &Config) -> anyhow::Result<Arc<dyn BlobStore>> {
    let blobs: Arc<dyn BlobStore> = match config.storage.as_deref() {
        Some(url) if url.starts_with("s3://") => Arc::new(s3::open(url, &config.s3_options())?),
        Some(dir) => Arc::new(local::open(std::path::Path::new(dir))?),
        None => Arc::new(local::open(&config.data_dir.join("blobs"))?),
    };
    // Fail at start-up, naming the store, rather than on the first upload.
    blobs
        .ping()
        .await
        .context("the blob storage does not answer")?;
    Ok(blobs)
}

/// A started service: its address and how to stop it.
pub struct Running {
    pub addr: SocketAddr,
    pub state: AppState,
    shutdown: CancellationToken,
    task: JoinHandle<anyhow::Result<()>>,
}

impl Running {
    /// Starts a graceful shutdown and waits for it.
    pub async fn stop(self) -> anyhow::Result<()> {
        self.shutdown.cancel();
        self.task.await.context("server task")?
    }

    /// Waits until the server stops by itself (a signal).
    pub async fn wait(self) -> anyhow::Result<()> {
        self.task.await.context("server task")?
    }
}

/// The pipeline the config asks for.
pub fn pipeline_for(config: &Config) -> Arc<dyn Pipeline> {
    match config.fake_pipeline_ms {
        Some(ms) => Arc::new(FakePipeline {
            stage_time: Duration::from_millis(ms),
            completions: Some(config.data_dir.join("fake-completions.log")),
            spin: config.fake_pipeline_spin,
        }),
        None => Arc::new(PlanPipeline),
    }
}

/// Starts the API and `config.workers` workers; returns once listening.
pub async fn start(mut config: Config, pipeline: Arc<dyn Pipeline>) -> anyhow::Result<Running> {
    std::fs::create_dir_all(&config.data_dir)
        .with_context(|| format!("creating {}", config.data_dir.display()))?;
    // A worker-only process serves no API, only health and metrics, so it may listen anywhere.
    if config.serve_api && config.dev_mode() && !config.listen.ip().is_loopback() {
        let loopback = SocketAddr::new([127, 0, 0, 1].into(), config.listen.port());
        tracing::warn!(
            requested = %config.listen, listening = %loopback,
            "no API keys configured: development mode binds to loopback only"
        );
        config.listen = loopback;
    }
    if config.serve_api && config.dev_mode() {
        tracing::warn!("no API keys configured: development mode, every caller is tenant `dev`");
    }
    let keys = config.all_keys().map_err(|e| anyhow::anyhow!(e))?;
    let store = start_store(&config).await?;
    let blobs = open_blobs(&config).await?;
    let shutdown = CancellationToken::new();
    let webhooks =
        crate::webhooks::Settings::from_config(&config).map_err(|e| anyhow::anyhow!(e))?;
    // Only a worker in this process can use an upload read as it arrived.
    let early = crate::worker::early::Early::new(
        config.serve_api && config.workers > 0 && pipeline.reads_early(),
        config.data_dir.join("work"),
        config.max_points,
        config.workers,
    );
    let state = AppState(Arc::new(App {
        webhooks,
        early,
        keys: Keys::new(&keys, config.dev_mode()),
        limits: Limits::new(config.rate_limit, config.rate_burst),
        metrics: Metrics::default(),
        changes: broadcast::channel(1024).0,
        queued: Notify::new(),
        shutdown: shutdown.child_token(),
        store,
        blobs,
        config,
    }));
    let listener = TcpListener::bind(state.config.listen)
        .await
        .with_context(|| format!("binding {}", state.config.listen))?;
    let addr = listener.local_addr()?;
    tracing::info!("listening on http://{addr}");
    let idle = Duration::from_secs(state.config.idle_timeout_secs);
    let metrics_server = match state.config.metrics_listen {
        Some(at) => {
            let l = TcpListener::bind(at)
                .await
                .with_context(|| format!("binding {at} (metrics)"))?;
            tracing::info!("metrics on http://{}/metrics", l.local_addr()?);
            let app = crate::router::metrics_only(state.clone());
            let stop = state.shutdown.clone();
            Some(tokio::spawn(async move {
                let _ = axum::serve(GuardedListener::new(l, idle), app)
                    .with_graceful_shutdown(async move { stop.cancelled().await })
                    .await;
            }))
        }
        None => None,
    };
    let keys_watch = tokio::spawn(crate::auth::watch_keys_file(state.clone(), KEYS_FILE_CHECK));

    let workers = Arc::new(Workers {
        state: state.clone(),
        pipeline,
        owner: format!("{}-{}", std::process::id(), JobId::new()),
        work_dir: state.config.data_dir.join("work"),
        stop_claiming: CancellationToken::new(),
        hand_back: CancellationToken::new(),
    });
    let worker_tasks = workers.spawn(state.config.workers);
    let sweeper_stop = CancellationToken::new();
    let sweeper = tokio::spawn(sweeper::run(state.clone(), sweeper_stop.clone()));
    let hooks = tokio::spawn(crate::webhooks::run(state.clone(), sweeper_stop.clone()));

    let app = if state.config.serve_api {
        crate::router::build(state.clone())
    } else {
        crate::router::worker(state.clone())
    };
    let server_state = state.clone();
    let signal = shutdown.clone();
    let task = tokio::spawn(async move {
        let stop = server_state.shutdown.clone();
        let graceful = stop.clone();
        // The client's address reaches handlers (the brake on unknown keys).
        let listener = GuardedListener::new(listener, idle).tap_io(|_| {});
        let app = app.into_make_service_with_connect_info::<SocketAddr>();
        let mut server = tokio::spawn(async move {
            axum::serve(listener, app)
                .with_graceful_shutdown(async move {
                    tokio::select! {
                        _ = signal.cancelled() => {}
                        _ = termination() => {}
                    }
                    tracing::info!("shutting down: no new jobs or connections");
                    graceful.cancel();
                })
                .await
        });
        let mut ended = None;
        tokio::select! {
            _ = stop.cancelled() => {}
            r = &mut server => ended = Some(r),
        }
        // Open connections and running jobs share one deadline: a stalled upload cannot hold
        // the jobs past it, nor the jobs the connections.
        workers.stop_claiming.cancel();
        let deadline = tokio::time::Instant::now()
            + Duration::from_secs(server_state.config.shutdown_timeout_secs);
        let mut pending = vec![];
        for mut task in worker_tasks {
            if tokio::time::timeout_at(deadline, &mut task).await.is_err() {
                pending.push(task);
            }
        }
        if !pending.is_empty() {
            tracing::warn!("shutdown timeout: handing running jobs back to the queue");
            workers.hand_back.cancel();
            // Each worker stops its pipeline and hands its job back within a moment; one
            // whose pipeline is stuck is left behind, and its job handed back below.
            let last = tokio::time::Instant::now() + HAND_BACK_WAIT;
            for mut task in pending {
                if tokio::time::timeout_at(last, &mut task).await.is_err() {
                    task.abort();
                }
            }
        }
        // Whatever this process still holds goes back to the queue, once: a job a worker
        // released is no longer ours, and this one statement cannot hand a job back twice.
        match server_state
            .store
            .release_all(&format!("{}/", workers.owner))
            .await
        {
            Ok(ids) => {
                for id in ids {
                    tracing::warn!(job = %id, "job handed back to the queue at shutdown");
                    server_state.changed(id);
                }
            }
            Err(e) => tracing::error!(error = %e, "handing jobs back at shutdown"),
        }
        let result = match ended {
            Some(r) => r,
            None => match tokio::time::timeout_at(deadline, &mut server).await {
                Ok(r) => r,
                Err(_) => {
                    tracing::warn!("shutdown timeout: closing the connections still open");
                    server.abort();
                    let _ = server.await;
                    Ok(Ok(()))
                }
            },
        };
        sweeper_stop.cancel();
        let _ = sweeper.await;
        let _ = hooks.await;
        keys_watch.abort();
        if let Some(m) = metrics_server {
            m.abort();
        }
        tracing::info!("stopped");
        result.context("server task")?.context("serving HTTP")
    });
    Ok(Running {
        addr,
        state,
        shutdown,
        task,
    })
}

/// How often the keys file is checked for changes.
const KEYS_FILE_CHECK: Duration = Duration::from_secs(2);

/// How long shutdown waits, after its deadline, for workers to stop their pipelines and hand
/// their jobs back, before it hands them back itself.
const HAND_BACK_WAIT: Duration = Duration::from_millis(600);

/// Resolves on SIGTERM or Ctrl-C.
async fn termination() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {}
        _ = term => {}
    }
}
