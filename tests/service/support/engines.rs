//! The real PostgreSQL and S3 servers the scale-out tests use, named by environment variables.
//!
//! `ASBUILT_TEST_POSTGRES` (e.g. `postgres://postgres@127.0.0.1:5432/test`) and
//! `ASBUILT_TEST_S3_ENDPOINT` (e.g. `http://127.0.0.1:5555`, an S3-compatible server such as moto
//! or MinIO) are set by `.ci/backends.sh`. Without them these tests print why and skip, except
//! under CI (`CI` set), where a missing engine is a failure.

use std::time::Duration;

use sqlx::Connection;

/// The two servers, when configured.
#[derive(Debug, Clone)]
pub struct Engines {
    pub postgres: String,
    pub s3_endpoint: String,
}

/// The configured engines, or `None` (after printing why) when the tests should skip.
pub fn engines(test: &str) -> Option<Engines> {
    let pg = std::env::var("ASBUILT_TEST_POSTGRES")
        .ok()
        .filter(|s| !s.is_empty());
    let s3 = std::env::var("ASBUILT_TEST_S3_ENDPOINT")
        .ok()
        .filter(|s| !s.is_empty());
    match (pg, s3) {
        (Some(postgres), Some(s3_endpoint)) => Some(Engines {
            postgres,
            s3_endpoint,
        }),
        _ => {
            let why = "ASBUILT_TEST_POSTGRES and ASBUILT_TEST_S3_ENDPOINT must both be set \
                       (source .ci/backends.sh)";
            assert!(
                std::env::var_os("CI").is_none(),
                "{test}: CI is set but the engines are not: {why}"
            );
            // Straight to stderr: the test harness captures eprintln! of passing tests.
            use std::io::Write;
            let _ = writeln!(std::io::stderr(), "skipping {test}: {why}");
            None
        }
    }
}

/// Only PostgreSQL (`ASBUILT_TEST_POSTGRES`), for tests that keep their blobs local; skips
/// or fails as [`engines`] does.
pub fn postgres_only(test: &str) -> Option<Engines> {
    match std::env::var("ASBUILT_TEST_POSTGRES")
        .ok()
        .filter(|s| !s.is_empty())
    {
        Some(postgres) => Some(Engines {
            postgres,
            s3_endpoint: String::new(),
        }),
        None => {
            let why = "ASBUILT_TEST_POSTGRES is not set (source .ci/backends.sh)";
            assert!(
                std::env::var_os("CI").is_none(),
                "{test}: CI is set but PostgreSQL is not: {why}"
            );
            use std::io::Write;
            let _ = writeln!(std::io::stderr(), "skipping {test}: {why}");
            None
        }
    }
}

/// A fresh name, unique across concurrent tests and runs.
pub fn unique(prefix: &str) -> String {
    format!("{prefix}_{}", uuid::Uuid::now_v7().simple())
}

impl Engines {
    /// Creates a schema of its own for one test and returns its name.
    pub async fn new_schema(&self, prefix: &str) -> String {
        let schema = unique(prefix);
        let mut conn = sqlx::PgConnection::connect(&self.postgres)
            .await
            .expect("connecting to ASBUILT_TEST_POSTGRES");
        sqlx::query(&format!("CREATE SCHEMA \"{schema}\""))
            .execute(&mut conn)
            .await
            .expect("creating a test schema");
        schema
    }

    /// Drops a test's schema and everything in it.
    pub async fn drop_schema(&self, schema: &str) {
        let mut conn = sqlx::PgConnection::connect(&self.postgres).await.unwrap();
        sqlx::query(&format!("DROP SCHEMA IF EXISTS \"{schema}\" CASCADE"))
            .execute(&mut conn)
            .await
            .unwrap();
    }

    /// The database URL with `search_path` set to `schema`.
    pub fn url_in(&self, schema: &str) -> String {
        let sep = if self.postgres.contains('?') {
            '&'
        } else {
            '?'
        };
        format!("{}{sep}options=-c%20search_path%3D{schema}", self.postgres)
    }

    /// Creates `bucket` on the S3 server (an unsigned PUT, which moto and MinIO in its default
    /// test setup accept); an existing bucket is fine.
    pub async fn ensure_bucket(&self, bucket: &str) {
        let client = reqwest::Client::builder()
            .timeout(Duration::from_secs(10))
            .build()
            .unwrap();
        let resp = client
            .put(format!(
                "{}/{bucket}",
                self.s3_endpoint.trim_end_matches('/')
            ))
            .send()
            .await
            .expect("the S3 server answers");
        let status = resp.status().as_u16();
        assert!(
            status == 200 || status == 409,
            "creating bucket {bucket}: {status} {}",
            resp.text().await.unwrap_or_default()
        );
    }

    /// The environment a child process needs to reach the S3 server.
    pub fn s3_env(&self) -> Vec<(&'static str, String)> {
        vec![
            ("AWS_ENDPOINT", self.s3_endpoint.clone()),
            ("AWS_ALLOW_HTTP", "true".into()),
            ("AWS_REGION", "us-east-1".into()),
            ("AWS_ACCESS_KEY_ID", "asbuilt-test".into()),
            ("AWS_SECRET_ACCESS_KEY", "asbuilt-test".into()),
        ]
    }

    /// Options for opening the S3 store in-process.
    pub fn s3_options(&self) -> asbuilt::storage::s3::S3Options {
        asbuilt::storage::s3::S3Options {
            endpoint: Some(self.s3_endpoint.clone()),
            region: Some("us-east-1".into()),
            access_key_id: Some("asbuilt-test".into()),
            secret_access_key: Some("asbuilt-test".into()),
            allow_http: true,
            presign: None,
        }
    }
}
