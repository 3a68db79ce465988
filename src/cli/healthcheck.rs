//! `asbuilt healthcheck`: asks a running server or worker for `/healthz` and exits 0 when it
//! answers 200. The container's `HEALTHCHECK` uses it, so the image needs no curl.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context};

#[derive(clap::Args)]
pub struct HealthcheckArgs {
    /// The address the process listens on; unspecified addresses (0.0.0.0, [::]) mean loopback.
    #[arg(long, env = "ASBUILT_LISTEN", default_value = "127.0.0.1:8080")]
    pub listen: String,
    /// The path to ask for.
    #[arg(long, default_value = "/healthz")]
    pub path: String,
    /// Give up after this many seconds.
    #[arg(long, default_value_t = 3.0)]
    pub timeout: f64,
}

pub fn run(args: HealthcheckArgs) -> anyhow::Result<ExitCode> {
    if !(args.timeout > 0.0 && args.timeout <= 600.0) {
        bail!("--timeout must be between 0 and 600 seconds");
    }
    let addr = target(&args.listen)?;
    let status = get_status(addr, &args.path, Duration::from_secs_f64(args.timeout))?;
    if status == 200 {
        Ok(ExitCode::SUCCESS)
    } else {
        bail!("{addr}{} answered {status}", args.path)
    }
}

/// The address to connect to for a listen address: an unspecified IP becomes loopback.
pub fn target(listen: &str) -> anyhow::Result<SocketAddr> {
    let mut addr = listen
        .to_socket_addrs()
        .with_context(|| format!("bad listen address {listen:?}"))?
        .next()
        .with_context(|| format!("listen address {listen:?} resolves to nothing"))?;
    if addr.ip().is_unspecified() {
        addr.set_ip(match addr {
            SocketAddr::V4(_) => std::net::Ipv4Addr::LOCALHOST.into(),
            SocketAddr::V6(_) => std::net::Ipv6Addr::LOCALHOST.into(),
        });
    }
    Ok(addr)
}

/// Sends one HTTP/1.0 GET and returns the status code of the answer.
fn get_status(addr: SocketAddr, path: &str, timeout: Duration) -> anyhow::Result<u16> {
    if !path.starts_with('/') || path.chars().any(|c| c.is_whitespace() || c.is_control()) {
        bail!("bad path {path:?}");
    }
    let mut stream = TcpStream::connect_timeout(&addr, timeout)
        .with_context(|| format!("cannot connect to {addr}"))?;
    stream.set_read_timeout(Some(timeout))?;
    stream.set_write_timeout(Some(timeout))?;
    write!(
        stream,
        "GET {path} HTTP/1.0\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .with_context(|| format!("cannot write to {addr}"))?;
    // The status line fits in the first few bytes; the body does not matter.
    let mut head = [0u8; 64];
    let mut len = 0;
    while len < head.len() {
        let n = stream
            .read(&mut head[len..])
            .with_context(|| format!("no answer from {addr}"))?;
        if n == 0 {
            break;
        }
        len += n;
    }
    parse_status(&head[..len]).with_context(|| format!("{addr} did not answer HTTP"))
}

/// The status code of an HTTP status line, `HTTP/1.x NNN ...`.
fn parse_status(head: &[u8]) -> Option<u16> {
    let text = std::str::from_utf8(head.get(..12)?).ok()?;
    let rest = text.strip_prefix("HTTP/1.")?;
    let code = rest.get(2..5)?;
    code.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    /// Serves one connection with a canned answer and returns the address.
    fn serve_once(answer: &'static [u8]) -> SocketAddr {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            // Read the whole request head first: answering and closing early would break
            // the client's pipe while it still writes.
            let mut head = Vec::new();
            let mut buf = [0u8; 256];
            while !head.windows(4).any(|w| w == b"\r\n\r\n") {
                match s.read(&mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => head.extend_from_slice(&buf[..n]),
                }
            }
            let _ = s.write_all(answer);
        });
        addr
    }

    #[test]
    fn ok_and_unavailable_answers_are_told_apart() {
        let t = Duration::from_secs(2);
        let ok = serve_once(b"HTTP/1.1 200 OK\r\ncontent-length: 2\r\n\r\nok");
        assert_eq!(get_status(ok, "/healthz", t).unwrap(), 200);
        let down = serve_once(b"HTTP/1.1 503 Service Unavailable\r\n\r\n");
        assert_eq!(get_status(down, "/healthz", t).unwrap(), 503);
    }

    #[test]
    fn garbage_and_closed_ports_are_errors() {
        let t = Duration::from_secs(2);
        let junk = serve_once(b"SSH-2.0-OpenSSH\r\n");
        assert!(get_status(junk, "/healthz", t).is_err());
        let closed = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap();
        assert!(get_status(closed, "/healthz", t).is_err());
        assert!(get_status(closed, "no-slash", t).is_err());
    }

    #[test]
    fn unspecified_listen_addresses_become_loopback() {
        assert_eq!(
            target("0.0.0.0:8080").unwrap().to_string(),
            "127.0.0.1:8080"
        );
        assert_eq!(target("[::]:9090").unwrap().to_string(), "[::1]:9090");
        assert_eq!(target("127.0.0.2:1").unwrap().to_string(), "127.0.0.2:1");
        assert!(target("not an address").is_err());
    }

    #[test]
    fn status_lines_parse() {
        assert_eq!(parse_status(b"HTTP/1.1 204 No Content\r\n"), Some(204));
        assert_eq!(parse_status(b"HTTP/1.0 200 OK"), Some(200));
        assert_eq!(parse_status(b"HTTP/2 200"), None);
        assert_eq!(parse_status(b""), None);
    }
}
