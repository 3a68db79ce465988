//! Prometheus metrics: counters kept in memory, queue gauges read from the store at scrape time.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use crate::queue::JobStatus;

/// Upper bounds of the stage-duration histogram, seconds.
const BUCKETS: [f64; 10] = [0.1, 0.5, 1.0, 5.0, 10.0, 30.0, 60.0, 300.0, 900.0, 3600.0];

#[derive(Default)]
struct Histogram {
    counts: [u64; BUCKETS.len()],
    count: u64,
    sum: f64,
}

/// The process's counters.
#[derive(Default)]
pub struct Metrics {
    upload_bytes: AtomicU64,
    uploads: AtomicU64,
    rejected_uploads: Mutex<BTreeMap<String, u64>>,
    failures: Mutex<BTreeMap<String, u64>>,
    stages: Mutex<BTreeMap<String, Histogram>>,
    completed: AtomicU64,
    early_reads: Mutex<BTreeMap<String, u64>>,
}

impl Metrics {
    /// An accepted upload of `bytes`.
    pub fn upload(&self, bytes: u64) {
        self.upload_bytes.fetch_add(bytes, Ordering::Relaxed);
        self.uploads.fetch_add(1, Ordering::Relaxed);
    }

    /// A refused upload, by error code.
    pub fn rejected(&self, code: &str) {
        *self
            .rejected_uploads
            .lock()
            .expect("metrics lock")
            .entry(code.to_string())
            .or_default() += 1;
    }

    /// An upload read as it arrived, by what became of it at the worker: `used`, or why the
    /// job read the stored file instead (`failed`, `other_bytes`).
    pub fn early_read(&self, outcome: &str) {
        *self
            .early_reads
            .lock()
            .expect("metrics lock")
            .entry(outcome.to_string())
            .or_default() += 1;
    }

    /// A job that failed, by error code.
    pub fn failure(&self, code: &str) {
        *self
            .failures
            .lock()
            .expect("metrics lock")
            .entry(code.to_string())
            .or_default() += 1;
    }

    /// A job that succeeded, with its per-stage times in ms.
    pub fn success(&self, timings_ms: &[(String, u64)]) {
        self.completed.fetch_add(1, Ordering::Relaxed);
        let mut stages = self.stages.lock().expect("metrics lock");
        for (stage, ms) in timings_ms {
            let secs = *ms as f64 / 1000.0;
            let h = stages.entry(stage.clone()).or_default();
            h.count += 1;
            h.sum += secs;
            for (i, le) in BUCKETS.iter().enumerate() {
                if secs <= *le {
                    h.counts[i] += 1;
                }
            }
        }
    }

    /// The text exposition format, with the store's counts by status.
    pub fn render(&self, by_status: &[(JobStatus, u64)]) -> String {
        let mut out = String::new();
        let queued = by_status
            .iter()
            .find(|(s, _)| *s == JobStatus::Queued)
            .map_or(0, |(_, n)| *n);
        let _ = writeln!(out, "# HELP asbuilt_queue_depth Jobs waiting for a worker.");
        let _ = writeln!(out, "# TYPE asbuilt_queue_depth gauge");
        let _ = writeln!(out, "asbuilt_queue_depth {queued}");
        let _ = writeln!(out, "# HELP asbuilt_jobs Jobs in the store, by status.");
        let _ = writeln!(out, "# TYPE asbuilt_jobs gauge");
        for (status, n) in by_status {
            let _ = writeln!(out, "asbuilt_jobs{{status=\"{}\"}} {n}", status.as_str());
        }
        let _ = writeln!(
            out,
            "# HELP asbuilt_upload_bytes_total Bytes of accepted uploads."
        );
        let _ = writeln!(out, "# TYPE asbuilt_upload_bytes_total counter");
        let _ = writeln!(
            out,
            "asbuilt_upload_bytes_total {}",
            self.upload_bytes.load(Ordering::Relaxed)
        );
        let _ = writeln!(out, "# HELP asbuilt_uploads_total Accepted uploads.");
        let _ = writeln!(out, "# TYPE asbuilt_uploads_total counter");
        let _ = writeln!(
            out,
            "asbuilt_uploads_total {}",
            self.uploads.load(Ordering::Relaxed)
        );
        let _ = writeln!(
            out,
            "# HELP asbuilt_uploads_rejected_total Refused uploads, by error code."
        );
        let _ = writeln!(out, "# TYPE asbuilt_uploads_rejected_total counter");
        for (code, n) in self.rejected_uploads.lock().expect("metrics lock").iter() {
            let _ = writeln!(out, "asbuilt_uploads_rejected_total{{code=\"{code}\"}} {n}");
        }
        let _ = writeln!(
            out,
            "# HELP asbuilt_job_failures_total Failed jobs, by error code."
        );
        let _ = writeln!(out, "# TYPE asbuilt_job_failures_total counter");
        for (code, n) in self.failures.lock().expect("metrics lock").iter() {
            let _ = writeln!(out, "asbuilt_job_failures_total{{code=\"{code}\"}} {n}");
        }
        let _ = writeln!(
            out,
            "# HELP asbuilt_jobs_succeeded_total Jobs this process completed."
        );
        let _ = writeln!(out, "# TYPE asbuilt_jobs_succeeded_total counter");
        let _ = writeln!(
            out,
            "asbuilt_jobs_succeeded_total {}",
            self.completed.load(Ordering::Relaxed)
        );
        let _ = writeln!(
            out,
            "# HELP asbuilt_early_reads_total Uploads read as they arrived, by outcome at the worker."
        );
        let _ = writeln!(out, "# TYPE asbuilt_early_reads_total counter");
        for (outcome, n) in self.early_reads.lock().expect("metrics lock").iter() {
            let _ = writeln!(
                out,
                "asbuilt_early_reads_total{{outcome=\"{outcome}\"}} {n}"
            );
        }
        let _ = writeln!(
            out,
            "# HELP asbuilt_stage_duration_seconds Pipeline stage durations of succeeded jobs."
        );
        let _ = writeln!(out, "# TYPE asbuilt_stage_duration_seconds histogram");
        for (stage, h) in self.stages.lock().expect("metrics lock").iter() {
            for (le, n) in BUCKETS.iter().zip(h.counts) {
                let _ = writeln!(
                    out,
                    "asbuilt_stage_duration_seconds_bucket{{stage=\"{stage}\",le=\"{le}\"}} {n}"
                );
            }
            let _ = writeln!(
                out,
                "asbuilt_stage_duration_seconds_bucket{{stage=\"{stage}\",le=\"+Inf\"}} {}",
                h.count
            );
            let _ = writeln!(
                out,
                "asbuilt_stage_duration_seconds_sum{{stage=\"{stage}\"}} {}",
                h.sum
            );
            let _ = writeln!(
                out,
                "asbuilt_stage_duration_seconds_count{{stage=\"{stage}\"}} {}",
                h.count
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_counters_and_cumulative_buckets() {
        let m = Metrics::default();
        m.upload(100);
        m.upload(50);
        m.failure("time_limit");
        m.success(&[("label".into(), 700), ("total".into(), 2000)]);
        let text = m.render(&[(JobStatus::Queued, 4), (JobStatus::Running, 2)]);
        assert!(text.contains("asbuilt_queue_depth 4\n"), "{text}");
        assert!(text.contains("asbuilt_jobs{status=\"running\"} 2\n"));
        assert!(text.contains("asbuilt_upload_bytes_total 150\n"));
        assert!(text.contains("asbuilt_job_failures_total{code=\"time_limit\"} 1\n"));
        assert!(
            text.contains("asbuilt_stage_duration_seconds_bucket{stage=\"label\",le=\"0.5\"} 0\n")
        );
        assert!(
            text.contains("asbuilt_stage_duration_seconds_bucket{stage=\"label\",le=\"1\"} 1\n")
        );
        assert!(text.contains("asbuilt_stage_duration_seconds_sum{stage=\"total\"} 2\n"));
    }
}
