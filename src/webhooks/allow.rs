//! Which callback targets the server may reach (`--webhook-allow`), so a client cannot turn it
//! against internal addresses. Entries are `public` (any public address: not loopback,
//! private, link-local, shared, multicast or unspecified), a host name (whatever it resolves
//! to), or a CIDR range (`10.2.0.0/16`, `127.0.0.1/32`, `fd00::/8`). A URL's host is resolved
//! and every address it resolves to must be allowed; the delivery then connects to the address
//! that was checked, so a DNS answer that changes in between cannot slip past.

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};

/// One `--webhook-allow` entry.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Rule {
    Public,
    Host(String),
    Net(IpAddr, u8),
}

/// The allow-list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Allow {
    rules: Vec<Rule>,
}

impl Allow {
    /// Parses the entries; an error names the bad one.
    pub fn parse(entries: &[String]) -> Result<Allow, String> {
        let mut rules = vec![];
        for entry in entries.iter().map(|e| e.trim()).filter(|e| !e.is_empty()) {
            let rule = if entry.eq_ignore_ascii_case("public") {
                Rule::Public
            } else if let Some((ip, bits)) = entry.split_once('/') {
                let ip: IpAddr = ip
                    .parse()
                    .map_err(|_| format!("webhook allow `{entry}`: not a CIDR range"))?;
                let max = if ip.is_ipv4() { 32 } else { 128 };
                let bits: u8 =
                    bits.parse().ok().filter(|b| *b <= max).ok_or_else(|| {
                        format!("webhook allow `{entry}`: prefix length 0..={max}")
                    })?;
                Rule::Net(ip, bits)
            } else if let Ok(ip) = entry.parse::<IpAddr>() {
                Rule::Net(ip, if ip.is_ipv4() { 32 } else { 128 })
            } else if entry
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '.')
            {
                Rule::Host(entry.to_ascii_lowercase())
            } else {
                return Err(format!(
                    "webhook allow `{entry}`: expected public, a host name or a CIDR range"
                ));
            };
            rules.push(rule);
        }
        Ok(Allow { rules })
    }

    /// True when `ip` may be reached.
    pub fn allows_ip(&self, ip: IpAddr) -> bool {
        let ip = canonical(ip);
        self.rules.iter().any(|r| match r {
            Rule::Public => is_public(ip),
            Rule::Host(_) => false,
            Rule::Net(net, bits) => contains(*net, *bits, ip),
        })
    }

    fn allows_host(&self, host: &str) -> bool {
        let host = host.trim_end_matches('.').to_ascii_lowercase();
        self.rules
            .iter()
            .any(|r| matches!(r, Rule::Host(h) if *h == host))
    }

    /// Checks a callback URL and resolves it: the address to connect to, or why not.
    pub async fn check(&self, url: &reqwest::Url) -> Result<SocketAddr, String> {
        if !matches!(url.scheme(), "http" | "https") {
            return Err("a callback URL is http:// or https://".into());
        }
        if !url.username().is_empty() || url.password().is_some() {
            return Err("a callback URL carries no user name or password".into());
        }
        let host = url
            .host_str()
            .ok_or("a callback URL needs a host")?
            .trim_start_matches('[')
            .trim_end_matches(']')
            .to_string();
        let port = url
            .port_or_known_default()
            .ok_or("a callback URL needs a port")?;
        let addrs: Vec<SocketAddr> = match host.parse::<IpAddr>() {
            Ok(ip) => vec![SocketAddr::new(ip, port)],
            Err(_) => tokio::net::lookup_host((host.as_str(), port))
                .await
                .map_err(|e| format!("cannot resolve `{host}`: {e}"))?
                .collect(),
        };
        let first = *addrs
            .first()
            .ok_or_else(|| format!("`{host}` has no address"))?;
        if self.allows_host(&host) {
            return Ok(first);
        }
        if let Some(bad) = addrs.iter().find(|a| !self.allows_ip(a.ip())) {
            return Err(format!(
                "`{host}` ({}) is not allowed by this server's webhook allow-list",
                bad.ip()
            ));
        }
        Ok(first)
    }
}

/// An IPv4-mapped IPv6 address as the IPv4 address it is.
fn canonical(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V6(v6) => v6
            .to_ipv4_mapped()
            .map(IpAddr::V4)
            .unwrap_or(IpAddr::V6(v6)),
        v4 => v4,
    }
}

fn contains(net: IpAddr, bits: u8, ip: IpAddr) -> bool {
    match (canonical(net), ip) {
        (IpAddr::V4(n), IpAddr::V4(a)) => {
            let mask = u32::MAX.checked_shl(32 - bits as u32).unwrap_or(0);
            u32::from(n) & mask == u32::from(a) & mask
        }
        (IpAddr::V6(n), IpAddr::V6(a)) => {
            let mask = u128::MAX.checked_shl(128 - bits as u32).unwrap_or(0);
            u128::from(n) & mask == u128::from(a) & mask
        }
        _ => false,
    }
}

/// Reachable on the public internet: none of the special-purpose ranges.
fn is_public(ip: IpAddr) -> bool {
    match ip {
        IpAddr::V4(a) => {
            !(a.is_loopback()
                || a.is_private()
                || a.is_link_local()
                || a.is_unspecified()
                || a.is_broadcast()
                || a.is_multicast()
                || a.is_documentation()
                || contains(IpAddr::V4(Ipv4Addr::new(100, 64, 0, 0)), 10, ip)
                || contains(IpAddr::V4(Ipv4Addr::new(0, 0, 0, 0)), 8, ip)
                || contains(IpAddr::V4(Ipv4Addr::new(198, 18, 0, 0)), 15, ip)
                || contains(IpAddr::V4(Ipv4Addr::new(240, 0, 0, 0)), 4, ip))
        }
        IpAddr::V6(a) => {
            !(a.is_loopback()
                || a.is_unspecified()
                || a.is_multicast()
                || contains(
                    IpAddr::V6(Ipv6Addr::new(0xfc00, 0, 0, 0, 0, 0, 0, 0)),
                    7,
                    ip,
                )
                || contains(
                    IpAddr::V6(Ipv6Addr::new(0xfe80, 0, 0, 0, 0, 0, 0, 0)),
                    10,
                    ip,
                )
                || contains(
                    IpAddr::V6(Ipv6Addr::new(0x2001, 0xdb8, 0, 0, 0, 0, 0, 0)),
                    32,
                    ip,
                )
                || contains(
                    IpAddr::V6(Ipv6Addr::new(0x64, 0xff9b, 0, 0, 0, 0, 0, 0)),
                    96,
                    ip,
                ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn allow(entries: &[&str]) -> Allow {
        Allow::parse(&entries.iter().map(|s| s.to_string()).collect::<Vec<_>>()).unwrap()
    }

    #[test]
    fn public_excludes_internal_ranges() {
        let a = allow(&["public"]);
        for ok in ["8.8.8.8", "2606:4700::1111", "::ffff:1.1.1.1"] {
            assert!(a.allows_ip(ok.parse().unwrap()), "{ok}");
        }
        for bad in [
            "127.0.0.1",
            "10.1.2.3",
            "172.16.0.9",
            "192.168.1.1",
            "169.254.169.254",
            "100.64.0.1",
            "0.0.0.0",
            "::1",
            "fd00::1",
            "fe80::1",
            "::ffff:127.0.0.1",
            "::ffff:10.0.0.1",
            "224.0.0.1",
        ] {
            assert!(!a.allows_ip(bad.parse().unwrap()), "{bad}");
        }
    }

    #[test]
    fn ranges_and_hosts_allow_what_they_name() {
        let a = allow(&[
            "127.0.0.1/32",
            "10.2.0.0/16",
            "fd00::/8",
            "Hooks.Example.com",
        ]);
        assert!(a.allows_ip("127.0.0.1".parse().unwrap()));
        assert!(!a.allows_ip("127.0.0.2".parse().unwrap()));
        assert!(a.allows_ip("10.2.255.1".parse().unwrap()));
        assert!(!a.allows_ip("10.3.0.1".parse().unwrap()));
        assert!(a.allows_ip("fd12::1".parse().unwrap()));
        assert!(!a.allows_ip("8.8.8.8".parse().unwrap()), "no `public`");
        assert!(a.allows_host("hooks.example.com."));
        for bad in ["10.0.0.0/33", "nope/8", "a b", "http://x"] {
            assert!(Allow::parse(&[bad.to_string()]).is_err(), "{bad}");
        }
    }

    #[tokio::test]
    async fn urls_are_checked_after_resolving() {
        let a = allow(&["public"]);
        let check = |u: &str| {
            let a = a.clone();
            let u = reqwest::Url::parse(u).unwrap();
            async move { a.check(&u).await }
        };
        assert!(check("http://127.0.0.1:9/hook").await.is_err());
        assert!(check("http://[::1]/hook").await.is_err());
        assert!(
            check("http://localhost/hook").await.is_err(),
            "resolves to loopback"
        );
        assert!(check("ftp://8.8.8.8/").await.is_err());
        assert!(check("https://user:pw@8.8.8.8/").await.is_err());
        assert_eq!(
            check("https://8.8.8.8/hook").await.unwrap(),
            "8.8.8.8:443".parse().unwrap()
        );
        let local = allow(&["127.0.0.0/8"]);
        let u = reqwest::Url::parse("http://127.0.0.1:8080/x").unwrap();
        assert_eq!(
            local.check(&u).await.unwrap(),
            "127.0.0.1:8080".parse().unwrap()
        );
    }
}
