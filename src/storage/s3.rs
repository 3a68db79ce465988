//! Blobs in S3-compatible object storage (AWS S3, MinIO, Ceph, ...), for processes on many hosts.
//!
//! `--storage s3://BUCKET/PREFIX` names the place; the endpoint, region and credentials come from
//! the config or the standard `AWS_*` environment variables. Uploads stream as multipart uploads
//! (an object appears only when its upload completes), reads stream, and results can be served
//! through pre-signed URLs. Every S3 `PUT` is atomic, so a reader never sees half an object.

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use axum::http::Method;
use bytes::Bytes;
use object_store::aws::{AmazonS3, AmazonS3Builder, AmazonS3ConfigKey};
use object_store::multipart::{MultipartStore, PartId};
use object_store::path::Path as ObjectPath;
use object_store::prefix::PrefixStore;
use object_store::signer::Signer;
use object_store::ClientConfigKey;

use super::presign::{presign, SigningKey};
use super::{Blob, BlobError, BlobStore, ByteStream, DirectUploads, ObjectBlobStore, Stored};

/// Part size of multipart uploads: S3's minimum, which bounds an upload's memory to a few parts.
const S3_PART: usize = 5 << 20;

/// Where blobs live: `s3://bucket/prefix`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct S3Url {
    pub bucket: String,
    /// Without leading or trailing slashes; may be empty.
    pub prefix: String,
}

impl S3Url {
    /// Parses `s3://bucket` or `s3://bucket/some/prefix`.
    pub fn parse(url: &str) -> Result<S3Url, BlobError> {
        let bad = |why: &str| BlobError::Store(format!("storage URL {url:?}: {why}"));
        let rest = url
            .strip_prefix("s3://")
            .ok_or_else(|| bad("expected s3://BUCKET/PREFIX"))?;
        let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
        let bucket_ok = (3..=63).contains(&bucket.len())
            && bucket
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '.');
        if !bucket_ok {
            return Err(bad(
                "the bucket must be 3-63 lower-case letters, digits, '-' or '.'",
            ));
        }
        let prefix = prefix.trim_matches('/');
        if prefix
            .split('/')
            .any(|seg| seg == "." || seg == ".." || (seg.is_empty() && !prefix.is_empty()))
        {
            return Err(bad("the prefix has an empty, '.' or '..' segment"));
        }
        Ok(S3Url {
            bucket: bucket.to_string(),
            prefix: prefix.to_string(),
        })
    }
}

/// How to reach the storage; unset fields fall back to the `AWS_*` environment variables.
#[derive(Debug, Clone, Default)]
pub struct S3Options {
    pub endpoint: Option<String>,
    pub region: Option<String>,
    pub access_key_id: Option<String>,
    pub secret_access_key: Option<String>,
    /// Allow a plain-HTTP endpoint (MinIO on a private network, a test server).
    pub allow_http: bool,
    /// Serve results through pre-signed URLs valid this long.
    pub presign: Option<Duration>,
}

/// A [`BlobStore`] in an S3 bucket, under a prefix.
pub struct S3BlobStore {
    objects: ObjectBlobStore,
    /// The unprefixed bucket, for signing URLs.
    signer: Arc<AmazonS3>,
    prefix: String,
    presign: Option<Duration>,
}

impl std::fmt::Debug for S3BlobStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "S3BlobStore({}/{})", self.signer, self.prefix)
    }
}

/// Opens the bucket named by `url`. Nothing is contacted until the first request; call
/// [`BlobStore::ping`] to check the bucket answers.
pub fn open(url: &str, options: &S3Options) -> Result<S3BlobStore, BlobError> {
    let S3Url { bucket, prefix } = S3Url::parse(url)?;
    let mut builder = AmazonS3Builder::from_env().with_bucket_name(&bucket);
    if let Some(endpoint) = &options.endpoint {
        builder = builder.with_endpoint(endpoint);
    }
    if let Some(region) = &options.region {
        builder = builder.with_region(region);
    }
    if let Some(key) = &options.access_key_id {
        builder = builder.with_access_key_id(key);
    }
    if let Some(secret) = &options.secret_access_key {
        builder = builder.with_secret_access_key(secret);
    }
    if options.allow_http {
        builder = builder.with_allow_http(true);
    }
    refuse_plain_http(&builder)?;
    let s3 = Arc::new(builder.build()?);
    let inner: Arc<dyn object_store::ObjectStore> = if prefix.is_empty() {
        s3.clone()
    } else {
        let shared: Arc<dyn object_store::ObjectStore> = s3.clone();
        Arc::new(PrefixStore::new(shared, prefix.as_str()))
    };
    Ok(S3BlobStore {
        objects: ObjectBlobStore::new(inner, None, S3_PART),
        signer: s3,
        prefix,
        presign: options.presign,
    })
}

impl S3BlobStore {
    /// The key in the bucket for a key under our prefix.
    fn full_key(&self, key: &str) -> ObjectPath {
        if self.prefix.is_empty() {
            ObjectPath::from(key)
        } else {
            ObjectPath::from(format!("{}/{key}", self.prefix))
        }
    }
}

#[async_trait]
impl BlobStore for S3BlobStore {
    async fn put_stream(
        &self,
        key: &str,
        body: ByteStream<'_>,
        limit: u64,
    ) -> Result<Stored, BlobError> {
        self.objects.put_stream(key, body, limit).await
    }

    async fn put(&self, key: &str, bytes: Bytes) -> Result<Stored, BlobError> {
        self.objects.put(key, bytes).await
    }

    async fn get(&self, key: &str) -> Result<Option<Blob>, BlobError> {
        self.objects.get(key).await
    }

    async fn get_part(
        &self,
        key: &str,
        range: std::ops::Range<u64>,
    ) -> Result<Option<(Blob, u64)>, BlobError> {
        self.objects.get_part(key, range).await
    }

    async fn size(&self, key: &str) -> Result<Option<u64>, BlobError> {
        self.objects.size(key).await
    }

    async fn download(&self, key: &str, to: &Path) -> Result<u64, BlobError> {
        self.objects.download(key, to).await
    }

    async fn delete_prefix(&self, prefix: &str) -> Result<(), BlobError> {
        self.objects.delete_prefix(prefix).await
    }

    async fn list(&self, prefix: &str) -> Result<Vec<(String, u64)>, BlobError> {
        self.objects.list(prefix).await
    }

    async fn ping(&self) -> Result<(), BlobError> {
        self.objects.ping().await
    }

    async fn presigned_get(&self, key: &str) -> Result<Option<String>, BlobError> {
        let Some(valid) = self.presign else {
            return Ok(None);
        };
        let url = self
            .signer
            .signed_url(Method::GET, &self.full_key(key), valid)
            .await?;
        Ok(Some(url.to_string()))
    }

    fn direct(&self) -> Option<&dyn DirectUploads> {
        Some(self)
    }
}

#[async_trait]
impl DirectUploads for S3BlobStore {
    async fn start(&self, key: &str) -> Result<String, BlobError> {
        Ok(self.signer.create_multipart(&self.full_key(key)).await?)
    }

    async fn part_url(
        &self,
        key: &str,
        upload_id: &str,
        number: u32,
        valid: Duration,
    ) -> Result<String, BlobError> {
        // object_store's URL for the object tells the endpoint, the addressing style, the
        // region and the credential it signs with; the part's own parameters are signed here.
        let object = self
            .signer
            .signed_url(Method::PUT, &self.full_key(key), valid)
            .await?;
        let scope = object
            .query_pairs()
            .find(|(k, _)| k == "X-Amz-Credential")
            .map(|(_, v)| v.to_string())
            .ok_or_else(|| BlobError::Store("the store signs no URLs".into()))?;
        let region = scope.split('/').nth(2).unwrap_or("us-east-1").to_string();
        let credential = self.signer.credentials().get_credential().await?;
        let mut url = object.clone();
        url.set_query(None);
        let number = number.to_string();
        let signed = presign(
            "PUT",
            &url,
            &[("partNumber", &number), ("uploadId", upload_id)],
            &SigningKey {
                key_id: &credential.key_id,
                secret: &credential.secret_key,
                token: credential.token.as_deref(),
                region: &region,
                date: chrono::Utc::now(),
            },
            valid.as_secs(),
        );
        Ok(signed.to_string())
    }

    async fn complete(
        &self,
        key: &str,
        upload_id: &str,
        etags: Vec<String>,
    ) -> Result<(), BlobError> {
        let parts = etags
            .into_iter()
            .map(|content_id| PartId { content_id })
            .collect();
        self.signer
            .complete_multipart(&self.full_key(key), &upload_id.to_string(), parts)
            .await?;
        Ok(())
    }

    async fn abort(&self, key: &str, upload_id: &str) -> Result<(), BlobError> {
        self.signer
            .abort_multipart(&self.full_key(key), &upload_id.to_string())
            .await?;
        Ok(())
    }
}

/// A plain-HTTP endpoint the client is not allowed to use fails every request with only
/// "builder error": say so when the store is opened, with the setting that allows it.
fn refuse_plain_http(builder: &AmazonS3Builder) -> Result<(), BlobError> {
    let Some(endpoint) = builder.get_config_value(&AmazonS3ConfigKey::Endpoint) else {
        return Ok(());
    };
    let allowed = builder
        .get_config_value(&AmazonS3ConfigKey::Client(ClientConfigKey::AllowHttp))
        .is_some_and(|v| v.eq_ignore_ascii_case("true"));
    if endpoint.to_ascii_lowercase().starts_with("http://") && !allowed {
        return Err(BlobError::Store(format!(
            "the S3 endpoint {endpoint} is plain HTTP, which is refused unless allowed: set \
             s3_allow_http = true in the configuration, or AWS_ALLOW_HTTP=true"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plain_http_endpoint_is_refused_by_name_unless_allowed() {
        let options = S3Options {
            endpoint: Some("http://127.0.0.1:9".into()),
            region: Some("us-east-1".into()),
            ..Default::default()
        };
        // The environment may allow it for every client (`AWS_ALLOW_HTTP`); the check says
        // the same as the client would.
        let by_env = std::env::var("AWS_ALLOW_HTTP").is_ok_and(|v| v.eq_ignore_ascii_case("true"));
        match open("s3://bucket/jobs", &options) {
            Err(e) => {
                assert!(!by_env, "{e}");
                let e = e.to_string();
                assert!(
                    e.contains("http://127.0.0.1:9") && e.contains("s3_allow_http"),
                    "{e}"
                );
            }
            Ok(_) => assert!(by_env, "a plain-HTTP endpoint was accepted"),
        }
        let allowed = S3Options {
            allow_http: true,
            ..options.clone()
        };
        assert!(open("s3://bucket/jobs", &allowed).is_ok());
        let https = S3Options {
            endpoint: Some("https://s3.example.com".into()),
            ..options
        };
        assert!(open("s3://bucket/jobs", &https).is_ok());
    }

    #[test]
    fn urls_name_a_bucket_and_a_clean_prefix() {
        let u = S3Url::parse("s3://asbuilt/jobs/").unwrap();
        assert_eq!((u.bucket.as_str(), u.prefix.as_str()), ("asbuilt", "jobs"));
        let u = S3Url::parse("s3://my-bucket.eu").unwrap();
        assert_eq!((u.bucket.as_str(), u.prefix.as_str()), ("my-bucket.eu", ""));
        let u = S3Url::parse("s3://b12/a/b/c").unwrap();
        assert_eq!(u.prefix, "a/b/c");
        for bad in [
            "asbuilt/jobs",
            "s3://",
            "s3://ab",
            "s3://Upper/jobs",
            "s3://b12/a/../c",
            "s3://b12/a//c",
            "file:///tmp",
        ] {
            assert!(S3Url::parse(bad).is_err(), "{bad}");
        }
    }
}
