//! `asbuilt serve`, `asbuilt worker` and `asbuilt migrate`.

use std::process::ExitCode;

use asbuilt::config::ConfigArgs;

#[derive(clap::Args)]
pub struct ServeArgs {
    /// Serve the API only and run no pipelines (workers run as `asbuilt worker` elsewhere).
    #[arg(long)]
    pub no_workers: bool,
    #[command(flatten)]
    pub config: ConfigArgs,
}

#[derive(clap::Args)]
pub struct WorkerArgs {
    #[command(flatten)]
    pub config: ConfigArgs,
}

/// A worker's health and metrics port when none is given, beside an API on 8080.
const WORKER_LISTEN: &str = "127.0.0.1:9090";

fn logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_env("ASBUILT_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,tower_http=warn,sqlx=warn"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .try_init();
}

fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    Ok(tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?)
}

/// Runs the API and workers until SIGTERM or Ctrl-C.
pub fn run(args: ServeArgs) -> anyhow::Result<ExitCode> {
    logging();
    let mut config = args.config.resolve()?;
    if args.no_workers {
        config.workers = 0;
    }
    serve(config)
}

/// Runs workers only, with `/healthz`, `/readyz` and `/metrics`, until SIGTERM or Ctrl-C.
pub fn worker(args: WorkerArgs) -> anyhow::Result<ExitCode> {
    logging();
    let mut config = args.config.resolve()?;
    if config.listen == asbuilt::config::Config::default().listen {
        config.listen = WORKER_LISTEN.parse().expect("literal address");
    }
    if config.workers == 0 {
        anyhow::bail!("a worker process needs --workers of at least 1");
    }
    config.serve_api = false;
    serve(config)
}

fn serve(config: asbuilt::config::Config) -> anyhow::Result<ExitCode> {
    let rt = runtime()?;
    let result = rt.block_on(async {
        let pipeline = asbuilt::app::pipeline_for(&config);
        let running = asbuilt::app::start(config, pipeline).await?;
        running.wait().await
    });
    // A pipeline thread stuck in a call that cannot be interrupted would hold a plain drop of
    // the runtime for ever; its job is already back in the queue, so do not wait for it.
    rt.shutdown_timeout(std::time::Duration::from_millis(200));
    result?;
    Ok(ExitCode::SUCCESS)
}

/// Applies the database migrations and exits.
pub fn migrate(args: ServeArgs) -> anyhow::Result<ExitCode> {
    logging();
    let config = args.config.resolve()?;
    if !config.shared_database() {
        std::fs::create_dir_all(&config.data_dir)?;
    }
    runtime()?.block_on(async { asbuilt::app::open_store(&config).await })?;
    eprintln!("migrated {}", without_password(&config.database_url()));
    Ok(ExitCode::SUCCESS)
}

/// A database URL fit for a log: `postgres://user:secret@host/db` loses `:secret`.
fn without_password(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_string();
    };
    match rest.split_once('@') {
        Some((user, host)) => {
            let user = user.split(':').next().unwrap_or_default();
            format!("{scheme}://{user}@{host}")
        }
        None => url.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::without_password;

    #[test]
    fn passwords_stay_out_of_logs() {
        assert_eq!(
            without_password("postgres://app:s3cret@db:5432/jobs"),
            "postgres://app@db:5432/jobs"
        );
        assert_eq!(without_password("sqlite://data/a.db"), "sqlite://data/a.db");
    }
}
