//! Request limits: a token bucket per tenant (`--rate-limit` per second on average, bursts of
//! `--rate-burst`), and a brake on addresses that keep sending unknown keys. Both answer
//! `429 rate_limited` with `Retry-After`. The buckets live in this process: with several API
//! processes, each allows its own rate.

use std::collections::HashMap;
use std::net::IpAddr;
use std::num::NonZeroU32;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use governor::clock::{Clock, DefaultClock};
use governor::state::keyed::HashMapStateStore;
use governor::{Quota, RateLimiter};

use crate::errors::{ApiError, Code};

type Keyed<K> = RateLimiter<K, HashMapStateStore<K>, DefaultClock>;

/// Unknown keys an address may send at once before it is braked.
pub const FAILED_KEYS_BURST: u32 = 20;
/// Then one more unknown key per this long.
pub const FAILED_KEYS_PERIOD: Duration = Duration::from_secs(3);

pub struct Limits {
    tenants: Option<Keyed<String>>,
    failures: Keyed<IpAddr>,
    /// Addresses braked, until when.
    blocked: Mutex<HashMap<IpAddr, Instant>>,
}

impl Limits {
    /// `per_sec` requests a second per tenant on average (0: no limit), `burst` at once.
    pub fn new(per_sec: f64, burst: u32) -> Limits {
        let tenants = (per_sec > 0.0).then(|| {
            let period = Duration::from_secs_f64(1.0 / per_sec).max(Duration::from_nanos(1));
            let quota = Quota::with_period(period)
                .expect("a positive period")
                .allow_burst(NonZeroU32::new(burst.max(1)).expect("at least 1"));
            RateLimiter::hashmap(quota)
        });
        let failures = Quota::with_period(FAILED_KEYS_PERIOD)
            .expect("a positive period")
            .allow_burst(NonZeroU32::new(FAILED_KEYS_BURST).expect("at least 1"));
        Limits {
            tenants,
            failures: RateLimiter::hashmap(failures),
            blocked: Mutex::default(),
        }
    }

    /// Spends one of `tenant`'s requests, or says when to come back.
    pub fn check_tenant(&self, tenant: &str) -> Result<(), ApiError> {
        let Some(limiter) = &self.tenants else {
            return Ok(());
        };
        limiter.check_key(&tenant.to_string()).map_err(|not_until| {
            let wait = not_until.wait_time_from(limiter.clock().now());
            ApiError::new(
                Code::RateLimited,
                "too many requests for this API key; slow down",
            )
            .retry_after(wait.as_secs_f64().ceil() as u64)
        })
    }

    /// Refuses an address that is braked for sending unknown keys.
    pub fn check_address(&self, ip: IpAddr) -> Result<(), ApiError> {
        let until = self.blocked.lock().expect("limits lock").get(&ip).copied();
        match until {
            Some(until) if until > Instant::now() => Err(ApiError::new(
                Code::RateLimited,
                "too many unknown API keys from this address; wait before trying again",
            )
            .retry_after((until - Instant::now()).as_secs_f64().ceil() as u64)),
            _ => Ok(()),
        }
    }

    /// Counts an unknown key from `ip`. Past the burst the address is braked, and this
    /// request already gets the 429.
    pub fn failed_auth(&self, ip: IpAddr) -> Result<(), ApiError> {
        if self.failures.check_key(&ip).is_ok() {
            return Ok(());
        }
        let until = Instant::now() + FAILED_KEYS_PERIOD;
        self.blocked.lock().expect("limits lock").insert(ip, until);
        tracing::warn!(address = %ip, "unknown API keys: address braked");
        self.check_address(ip)
    }

    /// Drops the state of tenants and addresses that have been quiet (the sweeper calls it),
    /// so the maps hold only recent callers.
    pub fn forget_idle(&self) {
        if let Some(t) = &self.tenants {
            t.retain_recent();
            t.shrink_to_fit();
        }
        self.failures.retain_recent();
        self.failures.shrink_to_fit();
        let now = Instant::now();
        self.blocked
            .lock()
            .expect("limits lock")
            .retain(|_, until| *until > now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tenant_gets_its_burst_then_429_with_retry_after_and_others_are_unaffected() {
        let l = Limits::new(1.0, 3);
        for _ in 0..3 {
            l.check_tenant("acme").unwrap();
        }
        let e = l.check_tenant("acme").unwrap_err();
        assert_eq!(e.code, Code::RateLimited);
        assert!(matches!(e.retry_after, Some(1..=2)), "{:?}", e.retry_after);
        l.check_tenant("bolt").unwrap();
        let off = Limits::new(0.0, 0);
        for _ in 0..1000 {
            off.check_tenant("acme").unwrap();
        }
    }

    #[test]
    fn unknown_keys_brake_only_their_address() {
        let l = Limits::new(0.0, 0);
        let (bad, good): (IpAddr, IpAddr) = ([10, 0, 0, 1].into(), [10, 0, 0, 2].into());
        for _ in 0..FAILED_KEYS_BURST {
            l.check_address(bad).unwrap();
            l.failed_auth(bad).unwrap();
        }
        l.check_address(bad).unwrap();
        assert!(
            l.failed_auth(bad).is_err(),
            "the key past the burst is braked"
        );
        let e = l.check_address(bad).unwrap_err();
        assert_eq!(e.code, Code::RateLimited);
        assert!(e.retry_after.is_some());
        l.check_address(good).unwrap();
        l.forget_idle();
        assert!(l.check_address(bad).is_err(), "a brake outlives a sweep");
    }
}
