//! Removing a job's blobs. A re-plan reads the upload of the job it came from
//! (`jobs/<input_job>/input/`), so an upload stays while any job row still reads it, and goes
//! with the last one.

use crate::app::AppState;
use crate::queue::JobId;
use crate::storage::keys;

/// Deletes what job `id` (whose row is already gone) stored, and the upload it read once no
/// job reads it any more.
pub async fn remove_blobs(state: &AppState, id: JobId, input_job: JobId) -> anyhow::Result<()> {
    let blobs = &state.blobs;
    if id != input_job || !state.store.upload_in_use(id).await? {
        // A re-plan's own folder holds only its results and its copy of the sidecar.
        blobs.delete_prefix(&keys::job_prefix(id)).await?;
    } else {
        // Other jobs still read this upload: only the results go (the small sidecar stays
        // with the upload until the last reader is gone).
        blobs.delete_prefix(&keys::result_prefix(id)).await?;
    }
    if input_job != id && !state.store.upload_in_use(input_job).await? {
        blobs.delete_prefix(&keys::job_prefix(input_job)).await?;
        tracing::info!(upload = %input_job, "a shared upload's last job is gone: upload deleted");
    }
    Ok(())
}
