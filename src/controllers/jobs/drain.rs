//! The unsent rest of a refused upload. A client that is still sending when the server answers
//! and closes gets a broken pipe instead of the answer; reading and dropping what it still
//! sends, for a bounded time, lets it read the JSON error.

use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::Duration;

use axum::body::{Body, BodyDataStream};
use bytes::Bytes;
use futures_util::{Stream, StreamExt};

/// How long a refused upload is read and dropped before the connection is closed.
pub const BUDGET: Duration = Duration::from_secs(5);

/// A pause this long in the rest of the body ends the draining early.
const IDLE: Duration = Duration::from_millis(500);

struct Shared {
    stream: Mutex<BodyDataStream>,
    /// True once anyone asked for body bytes (after which an `Expect: 100-continue` client
    /// has been told to send).
    polled: AtomicBool,
}

/// Reads the body through the shared stream.
struct Tap(Arc<Shared>);

impl Stream for Tap {
    type Item = Result<Bytes, axum::Error>;

    fn poll_next(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        self.0.polled.store(true, Ordering::Relaxed);
        self.0.stream.lock().expect("body lock").poll_next_unpin(cx)
    }
}

/// What is left of a body once the handler is done with it.
pub struct Remainder(Arc<Shared>);

/// Splits `body` into a body for the handler and a handle on whatever it leaves unread.
pub fn split(body: Body) -> (Body, Remainder) {
    let shared = Arc::new(Shared {
        stream: Mutex::new(body.into_data_stream()),
        polled: AtomicBool::new(false),
    });
    (Body::from_stream(Tap(shared.clone())), Remainder(shared))
}

impl Remainder {
    /// Reads and drops the rest of the body for at most `budget`. A client that asked
    /// `Expect: 100-continue` and was never told to go on has sent nothing: it is left alone,
    /// so it reads the answer without sending the body at all.
    pub async fn drain(self, expects_continue: bool, budget: Duration) {
        if expects_continue && !self.0.polled.load(Ordering::Relaxed) {
            return;
        }
        // The handler's body (the only other handle) is gone by now; if not, give up quietly.
        let Ok(shared) = Arc::try_unwrap(self.0) else {
            return;
        };
        let mut stream = shared
            .stream
            .into_inner()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        // A client that stalls is not waited for: it is not sending, so it can read.
        let _ = tokio::time::timeout(budget, async {
            while let Ok(Some(Ok(_))) = tokio::time::timeout(IDLE, stream.next()).await {}
        })
        .await;
    }
}
