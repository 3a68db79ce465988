//! Upload limits and the format screen, and refusals a sending client still reads.

use serde_json::Value;

use super::fake;
use crate::support::files_under;
use crate::support::server::{expect_error, start, xyz};

#[tokio::test]
async fn oversized_uploads_get_413_and_leave_nothing() {
    let s = start(fake(1), |c| c.max_upload_bytes = 10_000).await;
    // Declared too large: refused before reading.
    let res = s.post("/v1/jobs").body(xyz(2000)).send().await.unwrap();
    expect_error(res, 413, "payload_too_large").await;
    // Streamed without a length: refused when the limit is crossed, partial data removed.
    let chunks: Vec<Result<String, std::io::Error>> = (0..50).map(|_| Ok(xyz(20))).collect();
    let body = reqwest::Body::wrap_stream(futures_util::stream::iter(chunks));
    expect_error(
        s.post("/v1/jobs").body(body).send().await.unwrap(),
        413,
        "payload_too_large",
    )
    .await;
    let form =
        reqwest::multipart::Form::new().part("cloud", reqwest::multipart::Part::text(xyz(2000)));
    expect_error(
        s.post("/v1/jobs").multipart(form).send().await.unwrap(),
        413,
        "payload_too_large",
    )
    .await;
    assert!(
        files_under(&s.blobs()).is_empty(),
        "{:?}",
        files_under(&s.blobs())
    );
    let list: Value = s
        .get("/v1/jobs")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(list["jobs"].as_array().unwrap().is_empty());
    let metrics = s
        .get("/metrics")
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        metrics.contains("asbuilt_uploads_rejected_total{code=\"payload_too_large\"} 3"),
        "{metrics}"
    );
}

/// The two uploads the old screen judged unlike the reader (issue 14).
#[tokio::test]
async fn the_upload_screen_is_the_readers_detector() {
    let s = start(fake(1), |c| c.workers = 0).await;
    // The screen is the reader's own detector: text the reader cannot place is refused up
    // front, and a column-name header the reader skips is accepted.
    expect_error(
        s.post("/v1/jobs")
            .body("# a\n# b\n# c\n# d\n1 2 3\n")
            .send()
            .await
            .unwrap(),
        415,
        "unsupported_format",
    )
    .await;
    let named = s
        .post("/v1/jobs")
        .body(format!("x y z\n{}", xyz(3)))
        .send()
        .await
        .unwrap();
    assert_eq!(named.status(), 202);
    let job: Value = named.json().await.unwrap();
    assert_eq!(job["upload"]["format"], "xyz", "{job}");
}

/// Sends a whole chunked upload before reading the answer, as simple clients (curl) do; an
/// error means the server closed on the client mid-send, losing its answer.
async fn post_all_then_read(
    addr: &str,
    key: Option<&str>,
    body: &[u8],
) -> std::io::Result<(u16, Value)> {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut tcp = tokio::net::TcpStream::connect(addr).await?;
    let auth = key
        .map(|k| format!("Authorization: Bearer {k}\r\n"))
        .unwrap_or_default();
    let head = format!(
        "POST /v1/jobs HTTP/1.1\r\nHost: test\r\n{auth}Transfer-Encoding: chunked\r\n\
         Connection: close\r\n\r\n"
    );
    tcp.write_all(head.as_bytes()).await?;
    for c in body.chunks(64 << 10) {
        tcp.write_all(format!("{:x}\r\n", c.len()).as_bytes())
            .await?;
        tcp.write_all(c).await?;
        tcp.write_all(b"\r\n").await?;
    }
    tcp.write_all(b"0\r\n\r\n").await?;
    let mut answer = Vec::new();
    tcp.read_to_end(&mut answer).await?;
    let text = String::from_utf8_lossy(&answer);
    let status = text.get(9..12).and_then(|s| s.parse().ok()).unwrap_or(0);
    let json = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    Ok((status, serde_json::from_str(json).unwrap_or(Value::Null)))
}

/// A client still sending when the upload is refused reads the JSON error, not a reset
/// connection: the server reads and drops the rest for a bounded time. 32 MiB is well past what
/// loopback socket buffers absorb.
#[tokio::test]
async fn refused_uploads_are_answered_while_the_client_still_sends() {
    let s = start(fake(1), |c| {
        c.workers = 0;
        c.max_upload_bytes = 64 << 10;
        c.api_keys = vec!["acme:acme-secret-key-0001".into()];
    })
    .await;
    let addr = s.base.trim_start_matches("http://").to_string();
    let key = Some("acme-secret-key-0001");
    let cloud = b"1.5 2.5 3.5\n".repeat(3 << 20);
    let mut junk = vec![0u8; 32 << 20];
    junk[..4].copy_from_slice(b"\x89PNG");
    for (key, body, status, code) in [
        // Over the limit once 64 KiB have arrived.
        (key, &cloud[..], 413, "payload_too_large"),
        // Not a cloud: refused at the first kilobyte.
        (key, &junk[..], 415, "unsupported_format"),
        // No key: refused before a byte of the body is read.
        (None, &cloud[..], 401, "unauthorized"),
    ] {
        let (got, answer) = post_all_then_read(&addr, key, body)
            .await
            .unwrap_or_else(|e| panic!("{code}: the connection failed mid-upload: {e}"));
        assert_eq!(
            (got, answer["error"]["code"].as_str()),
            (status, Some(code))
        );
    }
    // Declared too large: refused before reading, and answered.
    expect_error(
        s.post("/v1/jobs").body(cloud.clone()).send().await.unwrap(),
        413,
        "payload_too_large",
    )
    .await;
    assert!(files_under(&s.blobs()).is_empty());
}
