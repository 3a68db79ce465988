//! A bounded open-loop load generator for the status endpoint, on loopback only.
//!
//! `cargo run --release --example load -- http://127.0.0.1:8080 /v1/jobs/ID 200 20 [KEY]`
//! sends RATE requests a second for SECS seconds (RATE × SECS in all, each on its own
//! schedule so a slow answer does not delay the next), then prints latency percentiles.

use std::time::{Duration, Instant};

#[tokio::main]
async fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [base, path, rate, secs, rest @ ..] = args.as_slice() else {
        eprintln!("usage: load BASE PATH RATE SECS [KEY]");
        std::process::exit(2);
    };
    assert!(
        base.starts_with("http://127.")
            || base.starts_with("http://localhost")
            || base.starts_with("http://[::1]"),
        "loopback targets only"
    );
    let rate: u64 = rate.parse().expect("RATE");
    let secs: u64 = secs.parse().expect("SECS");
    let total = (rate * secs).min(100_000);
    let url = format!("{base}{path}");
    let client = reqwest::Client::new();
    let key = rest.first().cloned();
    let start = Instant::now();
    let mut tasks = Vec::with_capacity(total as usize);
    for i in 0..total {
        let due = start + Duration::from_micros(i * 1_000_000 / rate);
        tokio::time::sleep_until(due.into()).await;
        let (client, url, key) = (client.clone(), url.clone(), key.clone());
        tasks.push(tokio::spawn(async move {
            let t0 = Instant::now();
            let mut req = client.get(&url);
            if let Some(k) = key {
                req = req.bearer_auth(k);
            }
            let ok = match tokio::time::timeout(Duration::from_secs(10), req.send()).await {
                Ok(Ok(res)) => res.status().is_success() && res.bytes().await.is_ok(),
                _ => false,
            };
            (t0.elapsed(), ok)
        }));
    }
    let mut lat = vec![];
    let mut errors = 0;
    for t in tasks {
        let (d, ok) = t.await.unwrap();
        if ok {
            lat.push(d);
        } else {
            errors += 1;
        }
    }
    lat.sort();
    let pct = |p: f64| lat[((lat.len() as f64 * p).ceil() as usize).clamp(1, lat.len()) - 1];
    let elapsed = start.elapsed().as_secs_f64();
    println!(
        "{} requests in {elapsed:.1} s ({:.0}/s), {errors} errors; latency p50 {:.2} ms, p90 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
        lat.len() + errors,
        (lat.len() + errors) as f64 / elapsed,
        pct(0.50).as_secs_f64() * 1e3,
        pct(0.90).as_secs_f64() * 1e3,
        pct(0.99).as_secs_f64() * 1e3,
        lat.last().unwrap().as_secs_f64() * 1e3,
    );
}
