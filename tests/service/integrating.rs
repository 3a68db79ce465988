//! `docs/integrating.md` as written: its server command starts a real `asbuilt serve` process,
//! its Python receiver runs, and its shell blocks run in order in one bash session (with
//! `set -euo pipefail`), so every call in the walkthrough is checked, webhook signature
//! verification included. The synthetic pipeline stands in for the real one (the walkthrough
//! is about the calls, and the real stages have tests of their own).

use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::support::process::serve;
use crate::support::server::xyz;

/// The blocks after `<!-- test: KIND -->` markers, in order, as (kind, text).
fn blocks(doc: &str) -> Vec<(String, String)> {
    let mut out = vec![];
    let mut rest = doc;
    while let Some(at) = rest.find("<!-- test: ") {
        rest = &rest[at + "<!-- test: ".len()..];
        let kind = rest[..rest.find(" -->").unwrap()].to_string();
        let open = rest.find("```").unwrap();
        let body_start = open + rest[open..].find('\n').unwrap() + 1;
        let body_end = body_start + rest[body_start..].find("\n```").unwrap();
        out.push((kind, rest[body_start..body_end].to_string()));
        rest = &rest[body_end..];
    }
    out
}

/// Why the walkthrough cannot run here, if it cannot (a failure under CI).
fn tools_missing() -> Option<String> {
    for tool in ["bash", "curl", "jq", "python3"] {
        let ok = Command::new(tool)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok();
        if !ok {
            let why = format!("{tool} is not installed");
            assert!(
                std::env::var_os("CI").is_none(),
                "the integrating walkthrough cannot run under CI: {why}"
            );
            eprintln!("skipping the integrating walkthrough: {why}");
            return Some(why);
        }
    }
    None
}

#[test]
fn the_integrating_walkthrough_runs_as_written() {
    if tools_missing().is_some() {
        return;
    }
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/integrating.md"))
        .unwrap();
    let blocks = blocks(&doc);
    let kinds: Vec<&str> = blocks.iter().map(|(k, _)| k.as_str()).collect();
    assert_eq!(
        kinds.iter().filter(|k| **k == "server").count(),
        1,
        "{kinds:?}"
    );
    assert_eq!(
        kinds.iter().filter(|k| **k == "receiver").count(),
        1,
        "{kinds:?}"
    );
    assert!(
        kinds.iter().filter(|k| **k == "run").count() >= 8,
        "{kinds:?}"
    );

    // The server block: `export KEY=... SECRET=...`, then `asbuilt serve FLAGS`.
    let server = &blocks.iter().find(|(k, _)| k == "server").unwrap().1;
    let mut vars = std::collections::HashMap::new();
    let export = server.lines().find(|l| l.starts_with("export ")).unwrap();
    for pair in export["export ".len()..].split_whitespace() {
        let (k, v) = pair.split_once('=').unwrap();
        vars.insert(format!("${k}"), v.to_string());
    }
    let command = server
        .lines()
        .skip_while(|l| !l.starts_with("asbuilt serve"))
        .map(|l| l.trim_end_matches('\\'))
        .collect::<Vec<_>>()
        .join(" ");
    let mut args: Vec<String> = command
        .split_whitespace()
        .skip(2)
        .map(|a| {
            vars.iter()
                .fold(a.to_string(), |a, (k, v)| a.replace(k.as_str(), v))
        })
        .collect();
    args.extend(["--fake-pipeline-ms".into(), "20".into()]);
    let dir = tempfile::tempdir().unwrap();
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let server = serve(&dir.path().join("data"), &args);

    // The receiver, on a free port.
    let receiver = &blocks.iter().find(|(k, _)| k == "receiver").unwrap().1;
    std::fs::write(dir.path().join("receiver.py"), receiver).unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let log = std::fs::File::create(dir.path().join("receiver.log")).unwrap();
    let mut rx = Command::new("python3")
        .arg("receiver.py")
        .arg(port.to_string())
        .current_dir(dir.path())
        .env("SECRET", &vars["$SECRET"])
        .stdout(log)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let end = Instant::now() + Duration::from_secs(10);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(Instant::now() < end, "the receiver did not start");
        std::thread::sleep(Duration::from_millis(50));
    }

    // Every shell block, in order, in one session.
    let script: String = std::iter::once("set -euo pipefail".to_string())
        .chain(
            blocks
                .iter()
                .filter(|(k, _)| k == "run")
                .map(|(_, b)| b.clone()),
        )
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(dir.path().join("walkthrough.sh"), &script).unwrap();
    std::fs::write(dir.path().join("scan.xyz"), xyz(40)).unwrap();
    let mut child = Command::new("bash")
        .arg("walkthrough.sh")
        .current_dir(dir.path())
        .env("ASBUILT", &server.base)
        .env("KEY", &vars["$KEY"])
        .env("SECRET", &vars["$SECRET"])
        .env("SCAN", "scan.xyz")
        .env("HOOK", format!("http://127.0.0.1:{port}/asbuilt"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let end = Instant::now() + Duration::from_secs(120);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > end {
            let _ = child.kill();
            panic!("the walkthrough did not finish in 120 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let (mut out, mut err) = (String::new(), String::new());
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    let _ = rx.kill();
    let _ = rx.wait();
    let received = std::fs::read_to_string(dir.path().join("receiver.log")).unwrap();
    assert!(
        status.success(),
        "the walkthrough failed:\n--- stdout\n{out}\n--- stderr\n{err}\n--- server\n{}",
        server.log()
    );

    // What it printed, and what the receiver verified.
    let job: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("job.json")).unwrap()).unwrap();
    let id = job["id"].as_str().unwrap();
    assert_eq!(job["status"], "succeeded", "{job}");
    assert!(
        out.contains("\"external_ref\": \"building-42/level-3\""),
        "{out}"
    );
    assert!(out.contains("\"status\":204"), "a delivery listed: {out}");
    assert!(
        received
            .lines()
            .any(|l| l == format!("job.succeeded {id} succeeded")),
        "the receiver verified no event of {id}:\n{received}"
    );
    let replan: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("replan.json")).unwrap()).unwrap();
    assert_eq!(replan["source_job"], id);
    drop(server);
}
