//! Upload limits in time, on top of the size limit: an upload that sends nothing for `idle`,
//! or whose average rate falls below `min_rate` bytes a second once it has run for `idle`,
//! ends with a timeout error. A stalled or trickling client thus cannot hold a connection, a
//! handler and a partial blob; the handler answers `408 upload_timeout` and the blob goes.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use bytes::Bytes;
use futures_util::Stream;
use tokio::time::{Instant, Sleep};

/// Wraps a body stream; `tripped` is raised when the limits end it.
pub struct Paced<S> {
    inner: S,
    idle: Duration,
    min_rate: u64,
    started: Instant,
    last: Instant,
    bytes: u64,
    timer: Pin<Box<Sleep>>,
    tripped: Arc<AtomicBool>,
    done: bool,
}

impl<S> Paced<S> {
    pub fn new(inner: S, idle: Duration, min_rate: u64, tripped: Arc<AtomicBool>) -> Paced<S> {
        let now = Instant::now();
        Paced {
            inner,
            idle,
            min_rate,
            started: now,
            last: now,
            bytes: 0,
            timer: Box::pin(tokio::time::sleep(idle)),
            tripped,
            done: false,
        }
    }

    /// When the upload fails unless more bytes come: `idle` after the last bytes, or when the
    /// average since the start would drop below the minimum rate (never before `idle`).
    fn deadline(&self) -> Instant {
        let idle = self.last + self.idle;
        if self.min_rate == 0 {
            return idle;
        }
        let secs = self.bytes as f64 / self.min_rate as f64;
        let rate = self.started + Duration::from_secs_f64(secs).max(self.idle);
        idle.min(rate)
    }

    fn trip(&mut self) -> io::Error {
        self.done = true;
        self.tripped.store(true, Ordering::Relaxed);
        let why = if Instant::now() >= self.last + self.idle {
            format!("the upload sent nothing for {} s", self.idle.as_secs())
        } else {
            format!(
                "the upload came in slower than this server's minimum of {} bytes/s",
                self.min_rate
            )
        };
        io::Error::new(io::ErrorKind::TimedOut, why)
    }
}

impl<S, E> Stream for Paced<S>
where
    S: Stream<Item = Result<Bytes, E>> + Unpin,
    E: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    type Item = Result<Bytes, io::Error>;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        let this = &mut *self;
        if this.done {
            return Poll::Ready(None);
        }
        match Pin::new(&mut this.inner).poll_next(cx) {
            Poll::Ready(Some(Ok(chunk))) => {
                this.bytes += chunk.len() as u64;
                this.last = Instant::now();
                if this.last >= this.deadline() {
                    return Poll::Ready(Some(Err(this.trip())));
                }
                let at = this.deadline();
                this.timer.as_mut().reset(at);
                Poll::Ready(Some(Ok(chunk)))
            }
            Poll::Ready(Some(Err(e))) => Poll::Ready(Some(Err(io::Error::other(e)))),
            Poll::Ready(None) => {
                this.done = true;
                Poll::Ready(None)
            }
            Poll::Pending => match this.timer.as_mut().poll(cx) {
                Poll::Ready(()) => Poll::Ready(Some(Err(this.trip()))),
                Poll::Pending => Poll::Pending,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use futures_util::StreamExt;

    fn chunks(
        gaps_ms: Vec<u64>,
        size: usize,
    ) -> Pin<Box<dyn Stream<Item = Result<Bytes, io::Error>> + Send>> {
        futures_util::stream::iter(gaps_ms)
            .then(move |gap| async move {
                tokio::time::sleep(Duration::from_millis(gap)).await;
                Ok(Bytes::from(vec![0u8; size]))
            })
            .boxed()
    }

    async fn run(gaps: Vec<u64>, size: usize, min_rate: u64) -> (usize, bool) {
        let tripped = Arc::new(AtomicBool::new(false));
        let mut s = Paced::new(
            chunks(gaps, size),
            Duration::from_millis(200),
            min_rate,
            tripped.clone(),
        );
        let mut got = 0;
        while let Some(c) = s.next().await {
            match c {
                Ok(c) => got += c.len(),
                Err(e) => {
                    assert_eq!(e.kind(), io::ErrorKind::TimedOut);
                    break;
                }
            }
        }
        (got, tripped.load(Ordering::Relaxed))
    }

    #[tokio::test]
    async fn steady_uploads_pass_and_stalls_or_trickles_trip() {
        assert_eq!(run(vec![10; 20], 1000, 1000).await, (20_000, false));
        // A stall after two chunks.
        assert_eq!(run(vec![10, 10, 1000], 1000, 0).await, (2000, true));
        // A trickle: a byte every 50 ms never stalls, but is far below 1000 bytes/s.
        let (got, tripped) = run(vec![50; 40], 1, 1000).await;
        assert!(tripped && got < 10, "{got}");
    }
}
