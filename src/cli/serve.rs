//! `asbuilt serve` and `asbuilt migrate`.

use std::process::ExitCode;

use asbuilt::config::ConfigArgs;

#[derive(clap::Args)]
pub struct ServeArgs {
    #[command(flatten)]
    pub config: ConfigArgs,
}

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
    let config = args.config.resolve()?;
    runtime()?.block_on(async {
        let pipeline = asbuilt::app::pipeline_for(&config);
        let running = asbuilt::app::start(config, pipeline).await?;
        running.wait().await
    })?;
    Ok(ExitCode::SUCCESS)
}

/// Applies the database migrations and exits.
pub fn migrate(args: ServeArgs) -> anyhow::Result<ExitCode> {
    logging();
    let config = args.config.resolve()?;
    std::fs::create_dir_all(&config.data_dir)?;
    runtime()?.block_on(async { asbuilt::app::open_store(&config).await })?;
    eprintln!("migrated {}", config.database_url());
    Ok(ExitCode::SUCCESS)
}
