//! The embedded default: blobs as files under `<data-dir>/blobs`.

use std::path::Path;
use std::sync::Arc;

use object_store::local::LocalFileSystem;

use super::{BlobError, ObjectBlobStore};

/// Part size of streaming writes to local files: small, since nothing needs big parts here.
const LOCAL_CHUNK: usize = 1 << 20;

/// Opens (creating if needed) a blob directory.
pub fn open(dir: &Path) -> Result<ObjectBlobStore, BlobError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| BlobError::Store(format!("{}: {e}", dir.display())))?;
    let root = dir
        .canonicalize()
        .map_err(|e| BlobError::Store(format!("{}: {e}", dir.display())))?;
    let fs = LocalFileSystem::new_with_prefix(&root)?;
    Ok(ObjectBlobStore::new(Arc::new(fs), Some(root), LOCAL_CHUNK))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::{BlobStore, ByteStream};
    use bytes::Bytes;
    use futures_util::StreamExt;

    fn chunks(n: usize, size: usize) -> ByteStream<'static> {
        futures_util::stream::iter((0..n).map(move |i| Ok(Bytes::from(vec![i as u8; size]))))
            .boxed()
    }

    fn files_under(dir: &Path) -> Vec<std::path::PathBuf> {
        let mut out = vec![];
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
                if e.path().is_dir() {
                    stack.push(e.path());
                } else {
                    out.push(e.path());
                }
            }
        }
        out
    }

    #[tokio::test]
    async fn streams_in_hashes_and_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let store = open(dir.path()).unwrap();
        let stored = store
            .put_stream("jobs/x/input/cloud", chunks(3, 1000), 10_000)
            .await
            .unwrap();
        assert_eq!(stored.bytes, 3000);
        let mut expected = vec![0u8; 1000];
        expected.extend(vec![1u8; 1000]);
        expected.extend(vec![2u8; 1000]);
        use sha2::Digest;
        assert_eq!(
            stored.sha256,
            super::super::sha256_hex(sha2::Sha256::digest(&expected))
        );
        let blob = store.get("jobs/x/input/cloud").await.unwrap().unwrap();
        assert_eq!(blob.size, 3000);
        let back: Vec<u8> = blob.stream.map(|c| c.unwrap().to_vec()).concat().await;
        assert_eq!(back, expected);
        assert_eq!(
            std::fs::read(store.local_path("jobs/x/input/cloud").unwrap()).unwrap(),
            expected
        );
        assert!(store.get("jobs/y/nothing").await.unwrap().is_none());
    }

    #[tokio::test]
    async fn too_large_leaves_nothing_behind() {
        let dir = tempfile::tempdir().unwrap();
        let store = open(dir.path()).unwrap();
        let err = store
            .put_stream("jobs/x/input/cloud", chunks(5, 1 << 20), 3 << 20)
            .await
            .unwrap_err();
        assert!(
            matches!(err, crate::storage::BlobError::TooLarge { .. }),
            "{err}"
        );
        assert_eq!(files_under(dir.path()), Vec::<std::path::PathBuf>::new());
    }

    #[tokio::test]
    async fn deletes_a_prefix_only() {
        let dir = tempfile::tempdir().unwrap();
        let store = open(dir.path()).unwrap();
        store
            .put("jobs/a/result/plan.svg", Bytes::from_static(b"<svg/>"))
            .await
            .unwrap();
        store
            .put("jobs/a/input/cloud", Bytes::from_static(b"ply"))
            .await
            .unwrap();
        store
            .put("jobs/b/input/cloud", Bytes::from_static(b"ply"))
            .await
            .unwrap();
        store.delete_prefix("jobs/a").await.unwrap();
        assert!(store.get("jobs/a/result/plan.svg").await.unwrap().is_none());
        assert!(store.get("jobs/b/input/cloud").await.unwrap().is_some());
        assert!(!dir.path().join("jobs/a").exists());
    }
}
