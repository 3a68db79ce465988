//! AWS Signature Version 4 in the query string ("pre-signed URLs") for requests that carry
//! query parameters of their own, such as S3's `UploadPart` (`partNumber`, `uploadId`).
//!
//! object_store signs URLs only for a bare object path (`Signer::signed_url`), and no other
//! crate in the lock file signs; the algorithm is short and AWS publishes test values
//! (checked below), so it is written out here with the HMAC-SHA256 the webhooks already use.
//! Credentials, region and date come from object_store's own signed URL of the same object
//! ([`super::s3`]), so both sign with the same settings.

use chrono::{DateTime, Utc};
use hmac::{Hmac, Mac};
use reqwest::Url;
use sha2::{Digest, Sha256};

/// What signs: the credential, the region, and when.
pub struct SigningKey<'a> {
    pub key_id: &'a str,
    pub secret: &'a str,
    /// A session token, for credentials from STS.
    pub token: Option<&'a str>,
    pub region: &'a str,
    pub date: DateTime<Utc>,
}

fn hmac(key: &[u8], data: &str) -> Vec<u8> {
    let mut mac = Hmac::<Sha256>::new_from_slice(key).expect("HMAC takes any key");
    mac.update(data.as_bytes());
    mac.finalize().into_bytes().to_vec()
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// URI-encodes as SigV4 wants: unreserved characters kept, everything else `%XX`.
fn encode(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for b in s.bytes() {
        match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => {
                out.push(b as char)
            }
            _ => out.push_str(&format!("%{b:02X}")),
        }
    }
    out
}

/// `url` (an S3 object's URL, without a query) with `params` and the query-string signature
/// for `method`, valid `expires_secs` from `key.date`. The payload is unsigned: the client
/// sends it as it likes.
pub fn presign(
    method: &str,
    url: &Url,
    params: &[(&str, &str)],
    key: &SigningKey<'_>,
    expires_secs: u64,
) -> Url {
    let day = key.date.format("%Y%m%d").to_string();
    let stamp = key.date.format("%Y%m%dT%H%M%SZ").to_string();
    let scope = format!("{day}/{}/s3/aws4_request", key.region);
    let mut query: Vec<(String, String)> = params
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    query.extend([
        ("X-Amz-Algorithm".into(), "AWS4-HMAC-SHA256".into()),
        ("X-Amz-Credential".into(), format!("{}/{scope}", key.key_id)),
        ("X-Amz-Date".into(), stamp.clone()),
        ("X-Amz-Expires".into(), expires_secs.to_string()),
        ("X-Amz-SignedHeaders".into(), "host".into()),
    ]);
    if let Some(token) = key.token {
        query.push(("X-Amz-Security-Token".into(), token.into()));
    }
    let mut encoded: Vec<(String, String)> =
        query.iter().map(|(k, v)| (encode(k), encode(v))).collect();
    encoded.sort();
    let canonical_query = encoded
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect::<Vec<_>>()
        .join("&");
    // The Host header a client sends: the port only when it is not the scheme's own.
    let host = match (url.host_str().unwrap_or_default(), url.port()) {
        (h, Some(p)) => format!("{h}:{p}"),
        (h, None) => h.to_string(),
    };
    // S3 takes the path as it is sent: encoded once (object_store encodes each segment).
    let canonical = format!(
        "{method}\n{}\n{canonical_query}\nhost:{host}\n\nhost\nUNSIGNED-PAYLOAD",
        url.path()
    );
    let to_sign = format!(
        "AWS4-HMAC-SHA256\n{stamp}\n{scope}\n{}",
        hex(&Sha256::digest(canonical.as_bytes()))
    );
    let k_date = hmac(format!("AWS4{}", key.secret).as_bytes(), &day);
    let k_region = hmac(&k_date, key.region);
    let k_service = hmac(&k_region, "s3");
    let k_signing = hmac(&k_service, "aws4_request");
    let signature = hex(&hmac(&k_signing, &to_sign));
    let mut signed = url.clone();
    signed.set_query(Some(&format!(
        "{canonical_query}&X-Amz-Signature={signature}"
    )));
    signed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example_key() -> SigningKey<'static> {
        SigningKey {
            key_id: "AKIAIOSFODNN7EXAMPLE",
            secret: "wJalrXUtnFEMI/K7MDENG/bPxRfiCYEXAMPLEKEY",
            token: None,
            region: "us-east-1",
            date: DateTime::parse_from_rfc3339("2013-05-24T00:00:00Z")
                .unwrap()
                .with_timezone(&Utc),
        }
    }

    #[test]
    fn the_aws_documentation_example_signs_as_published() {
        // sigv4-query-string-auth.html: GET examplebucket's test.txt for a day.
        let url = Url::parse("https://examplebucket.s3.amazonaws.com/test.txt").unwrap();
        let signed = presign("GET", &url, &[], &example_key(), 86_400);
        let signature = signed
            .query_pairs()
            .find(|(k, _)| k == "X-Amz-Signature")
            .unwrap()
            .1
            .to_string();
        assert_eq!(
            signature,
            "aeeed9bbccd4d02ee5c0109b86d86835f995330da4c265957d157751f604d404"
        );
        assert!(signed.as_str().contains(
            "X-Amz-Credential=AKIAIOSFODNN7EXAMPLE%2F20130524%2Fus-east-1%2Fs3%2Faws4_request"
        ));
    }

    #[test]
    fn a_parts_own_parameters_are_signed_and_kept() {
        let url = Url::parse("http://127.0.0.1:5555/bucket/jobs/a%20b/cloud").unwrap();
        let params = [("partNumber", "3"), ("uploadId", "a+b/c=")];
        let signed = presign("PUT", &url, &params, &example_key(), 600);
        let pairs: Vec<(String, String)> = signed
            .query_pairs()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        assert!(pairs.contains(&("partNumber".into(), "3".into())));
        assert!(pairs.contains(&("uploadId".into(), "a+b/c=".into())));
        assert_eq!(signed.path(), "/bucket/jobs/a%20b/cloud");
        // Another part number is another signature.
        let other = presign(
            "PUT",
            &url,
            &[("partNumber", "4"), params[1]],
            &example_key(),
            600,
        );
        let sig = |u: &Url| {
            u.query_pairs()
                .find(|(k, _)| k == "X-Amz-Signature")
                .unwrap()
                .1
                .to_string()
        };
        assert_ne!(sig(&signed), sig(&other));
    }
}
