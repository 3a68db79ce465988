//! Blob storage for uploaded clouds and results. [`BlobStore`] is the seam; [`ObjectBlobStore`]
//! implements it over any `object_store` backend, and [`local`] opens the embedded default, a
//! local directory.
//!
//! Keys are built only by [`keys`] from validated job ids, so no caller input reaches a path.

pub mod keys;
pub mod local;
pub mod presign;
pub mod s3;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use async_trait::async_trait;
use bytes::Bytes;
use futures_util::stream::BoxStream;
use futures_util::{StreamExt, TryStreamExt};
use object_store::path::Path as ObjectPath;
use object_store::{ObjectStore, PutPayload, WriteMultipart};
use sha2::{Digest, Sha256};
use tokio::io::AsyncWriteExt;

/// A stream of body bytes, as uploads arrive and downloads leave.
pub type ByteStream<'a> = BoxStream<'a, Result<Bytes, std::io::Error>>;

/// What a write stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Stored {
    pub bytes: u64,
    /// Lower-case hex SHA-256 of the content.
    pub sha256: String,
}

/// An object read back: its size and its content as a stream.
pub struct Blob {
    pub size: u64,
    pub stream: ByteStream<'static>,
}

/// Why a blob operation failed.
#[derive(Debug, thiserror::Error)]
pub enum BlobError {
    /// The stream went past the limit; nothing was kept.
    #[error("the upload is larger than the limit of {limit} bytes")]
    TooLarge { limit: u64 },
    /// The incoming stream failed (client went away, bad chunk); nothing was kept.
    #[error("the upload was interrupted: {0}")]
    Source(std::io::Error),
    #[error("storage: {0}")]
    Store(String),
}

impl From<object_store::Error> for BlobError {
    fn from(e: object_store::Error) -> Self {
        BlobError::Store(e.to_string())
    }
}

/// Where uploads and results live.
#[async_trait]
pub trait BlobStore: Send + Sync + 'static {
    /// Streams `body` to `key`, at most `limit` bytes, hashing as it goes. The object appears
    /// only when complete; on any error nothing is left behind.
    async fn put_stream(
        &self,
        key: &str,
        body: ByteStream<'_>,
        limit: u64,
    ) -> Result<Stored, BlobError>;
    /// Writes a small object whole and atomically (results).
    async fn put(&self, key: &str, bytes: Bytes) -> Result<Stored, BlobError>;
    /// Reads an object as a stream; `None` when absent.
    async fn get(&self, key: &str) -> Result<Option<Blob>, BlobError>;
    /// Reads bytes `range` of an object (clamped to its end) as a stream, with the object's
    /// whole size; `None` when absent.
    async fn get_part(
        &self,
        key: &str,
        range: std::ops::Range<u64>,
    ) -> Result<Option<(Blob, u64)>, BlobError>;
    /// An object's size, `None` when absent.
    async fn size(&self, key: &str) -> Result<Option<u64>, BlobError>;
    /// Copies an object to a local file (the pipeline reads files).
    async fn download(&self, key: &str, to: &Path) -> Result<u64, BlobError>;
    /// The object's own file, when the store is a local directory (saves a copy).
    fn local_path(&self, key: &str) -> Option<PathBuf> {
        let _ = key;
        None
    }
    /// Deletes every object under `prefix` (a folder such as `jobs/<id>/`).
    async fn delete_prefix(&self, prefix: &str) -> Result<(), BlobError>;
    /// Every object under `prefix`, as (key, size), sorted by key.
    async fn list(&self, prefix: &str) -> Result<Vec<(String, u64)>, BlobError>;
    /// Checks the store answers (readiness).
    async fn ping(&self) -> Result<(), BlobError>;
    /// A pre-signed URL to GET `key` directly from the store, when the store offers them and
    /// they are configured; `None` means stream the object through the API.
    async fn presigned_get(&self, key: &str) -> Result<Option<String>, BlobError> {
        let _ = key;
        Ok(None)
    }
    /// Uploads that go straight to the store through pre-signed part URLs, when the store
    /// offers them (S3); `None` for a local directory.
    fn direct(&self) -> Option<&dyn DirectUploads> {
        None
    }
}

/// A multipart upload the client sends straight to the store, part by part, each to a
/// pre-signed URL; the server starts it and joins the parts. Keys are those of [`keys`].
#[async_trait]
pub trait DirectUploads: Send + Sync {
    /// Starts a multipart upload to `key`; its upload id.
    async fn start(&self, key: &str) -> Result<String, BlobError>;
    /// The URL to `PUT` part `number` (1 to 10,000) of the upload to, valid for `valid`.
    async fn part_url(
        &self,
        key: &str,
        upload_id: &str,
        number: u32,
        valid: std::time::Duration,
    ) -> Result<String, BlobError>;
    /// Joins parts 1 to `etags.len()`, given by the `ETag`s the store answered each `PUT`
    /// with, into the object at `key`.
    async fn complete(
        &self,
        key: &str,
        upload_id: &str,
        etags: Vec<String>,
    ) -> Result<(), BlobError>;
    /// Abandons the upload; the store drops its parts.
    async fn abort(&self, key: &str, upload_id: &str) -> Result<(), BlobError>;
}

/// A [`BlobStore`] over an `object_store` backend (local directory, S3, ...).
pub struct ObjectBlobStore {
    inner: Arc<dyn ObjectStore>,
    /// For a local directory: its root, so `local_path` can skip a copy.
    root: Option<PathBuf>,
    /// Bytes buffered per part of a streaming write; bounds upload memory.
    chunk_size: usize,
}

impl ObjectBlobStore {
    /// Wraps a backend. `chunk_size` is the part size of streaming writes (S3 needs ≥ 5 MiB).
    pub fn new(inner: Arc<dyn ObjectStore>, root: Option<PathBuf>, chunk_size: usize) -> Self {
        ObjectBlobStore {
            inner,
            root,
            chunk_size,
        }
    }
}

/// Flushes a finished local file and its folder entry to disk. Job rows are synced (SQLite
/// `synchronous=FULL`), so the files they promise must be too: an upload before its `202`, a
/// result before its job turns `succeeded`; else a power cut could keep a job without its files.
async fn sync_to_disk(path: &Path) -> Result<(), BlobError> {
    let fail = |e: std::io::Error| BlobError::Store(format!("{}: {e}", path.display()));
    tokio::fs::File::open(path)
        .await
        .map_err(fail)?
        .sync_all()
        .await
        .map_err(fail)?;
    if let Some(dir) = path.parent() {
        tokio::fs::File::open(dir)
            .await
            .map_err(fail)?
            .sync_all()
            .await
            .map_err(fail)?;
    }
    Ok(())
}

fn sha256_hex(digest: impl AsRef<[u8]>) -> String {
    digest.as_ref().iter().map(|b| format!("{b:02x}")).collect()
}

#[async_trait]
impl BlobStore for ObjectBlobStore {
    async fn put_stream(
        &self,
        key: &str,
        mut body: ByteStream<'_>,
        limit: u64,
    ) -> Result<Stored, BlobError> {
        let location = ObjectPath::from(key);
        let upload = self.inner.put_multipart(&location).await?;
        let mut writer = WriteMultipart::new_with_chunk_size(upload, self.chunk_size);
        let mut hasher = Sha256::new();
        let mut bytes = 0u64;
        let failure = loop {
            let chunk = match body.next().await {
                None => break None,
                Some(Err(e)) => break Some(BlobError::Source(e)),
                Some(Ok(chunk)) => chunk,
            };
            bytes += chunk.len() as u64;
            if bytes > limit {
                break Some(BlobError::TooLarge { limit });
            }
            hasher.update(&chunk);
            // At most two parts in flight: memory stays at a few chunk sizes.
            if let Err(e) = writer.wait_for_capacity(2).await {
                break Some(e.into());
            }
            writer.put(chunk);
        };
        if let Some(e) = failure {
            // The staged parts go; the object never appeared.
            let _ = writer.abort().await;
            return Err(e);
        }
        writer.finish().await?;
        if let Some(path) = self.local_path(key) {
            sync_to_disk(&path).await?;
        }
        Ok(Stored {
            bytes,
            sha256: sha256_hex(hasher.finalize()),
        })
    }

    async fn put(&self, key: &str, bytes: Bytes) -> Result<Stored, BlobError> {
        let stored = Stored {
            bytes: bytes.len() as u64,
            sha256: sha256_hex(Sha256::digest(&bytes)),
        };
        self.inner
            .put(&ObjectPath::from(key), PutPayload::from_bytes(bytes))
            .await?;
        // Results too: the job turns `succeeded` only after they are on disk.
        if let Some(path) = self.local_path(key) {
            sync_to_disk(&path).await?;
        }
        Ok(stored)
    }

    async fn get(&self, key: &str) -> Result<Option<Blob>, BlobError> {
        match self.inner.get(&ObjectPath::from(key)).await {
            Ok(result) => {
                let size = result.meta.size;
                let stream = result
                    .into_stream()
                    .map_err(|e| std::io::Error::other(e.to_string()))
                    .boxed();
                Ok(Some(Blob { size, stream }))
            }
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    async fn get_part(
        &self,
        key: &str,
        range: std::ops::Range<u64>,
    ) -> Result<Option<(Blob, u64)>, BlobError> {
        let options = object_store::GetOptions {
            range: Some(object_store::GetRange::Bounded(range)),
            ..Default::default()
        };
        match self.inner.get_opts(&ObjectPath::from(key), options).await {
            Ok(result) => {
                let total = result.meta.size;
                let size = result.range.end - result.range.start;
                let stream = result
                    .into_stream()
                    .map_err(|e| std::io::Error::other(e.to_string()))
                    .boxed();
                Ok(Some((Blob { size, stream }, total)))
            }
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    async fn size(&self, key: &str) -> Result<Option<u64>, BlobError> {
        match self.inner.head(&ObjectPath::from(key)).await {
            Ok(meta) => Ok(Some(meta.size)),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    async fn download(&self, key: &str, to: &Path) -> Result<u64, BlobError> {
        let blob = self
            .get(key)
            .await?
            .ok_or_else(|| BlobError::Store(format!("{key}: not found")))?;
        let mut file = tokio::fs::File::create(to)
            .await
            .map_err(|e| BlobError::Store(format!("{}: {e}", to.display())))?;
        let mut stream = blob.stream;
        let mut n = 0u64;
        while let Some(chunk) = stream.next().await {
            let chunk = chunk.map_err(|e| BlobError::Store(e.to_string()))?;
            n += chunk.len() as u64;
            file.write_all(&chunk)
                .await
                .map_err(|e| BlobError::Store(format!("{}: {e}", to.display())))?;
        }
        file.flush()
            .await
            .map_err(|e| BlobError::Store(e.to_string()))?;
        Ok(n)
    }

    fn local_path(&self, key: &str) -> Option<PathBuf> {
        self.root.as_ref().map(|r| r.join(key))
    }

    async fn list(&self, prefix: &str) -> Result<Vec<(String, u64)>, BlobError> {
        let prefix = ObjectPath::from(prefix);
        let mut all: Vec<(String, u64)> = self
            .inner
            .list(Some(&prefix))
            .map_ok(|meta| (meta.location.to_string(), meta.size))
            .try_collect()
            .await?;
        all.sort();
        Ok(all)
    }

    async fn delete_prefix(&self, prefix: &str) -> Result<(), BlobError> {
        let prefix = ObjectPath::from(prefix);
        let locations = self
            .inner
            .list(Some(&prefix))
            .map_ok(|meta| meta.location)
            .boxed();
        self.inner
            .delete_stream(locations)
            .try_collect::<Vec<_>>()
            .await?;
        if let Some(root) = &self.root {
            // The local backend leaves empty folders behind.
            let dir = root.join(prefix.as_ref());
            let _ = tokio::fs::remove_dir_all(dir).await;
        }
        Ok(())
    }

    async fn ping(&self) -> Result<(), BlobError> {
        let mut listing = self.inner.list(None);
        match listing.next().await {
            Some(Err(e)) => Err(e.into()),
            _ => Ok(()),
        }
    }
}
