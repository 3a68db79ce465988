//! Checks answers against `openapi/asbuilt.yaml`: the operation must list the status (404 and
//! 405 from the router's fallbacks excepted) and the media type, and a JSON body must validate
//! against the documented schema (JSON Schema 2020-12, with `boon`, formats asserted).

use std::collections::HashMap;

use serde_json::Value;

const ROOT: &str = "urn:asbuilt:openapi";

pub struct Contract {
    doc: Value,
    compiler: boon::Compiler,
    schemas: boon::Schemas,
    compiled: HashMap<String, boon::SchemaIndex>,
}

/// RFC 6901 escaping of one reference token, then percent-encoding for a URI fragment.
fn token(s: &str) -> String {
    s.replace('~', "~0")
        .replace('/', "~1")
        .replace('{', "%7B")
        .replace('}', "%7D")
}

impl Contract {
    pub fn load() -> Contract {
        let text =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/openapi/asbuilt.yaml"))
                .unwrap();
        let doc: Value = serde_yaml::from_str(&text).unwrap();
        let mut compiler = boon::Compiler::new();
        compiler.set_default_draft(boon::Draft::V2020_12);
        compiler.enable_format_assertions();
        compiler.add_resource(ROOT, doc.clone()).unwrap();
        Contract {
            doc,
            compiler,
            schemas: boon::Schemas::new(),
            compiled: HashMap::new(),
        }
    }

    /// Validates `value` against the schema at `pointer` (a URI fragment into the document).
    pub fn validate(&mut self, pointer: &str, value: &Value) {
        if let Err(e) = self.check(pointer, value) {
            panic!("{value} does not match {pointer}:\n{e}");
        }
    }

    /// True when `value` matches the schema at `pointer`.
    pub fn accepts(&mut self, pointer: &str, value: &Value) -> bool {
        self.check(pointer, value).is_ok()
    }

    fn check(&mut self, pointer: &str, value: &Value) -> Result<(), String> {
        let index = match self.compiled.get(pointer) {
            Some(i) => *i,
            None => {
                let i = self
                    .compiler
                    .compile(&format!("{ROOT}#{pointer}"), &mut self.schemas)
                    .unwrap_or_else(|e| panic!("compiling {pointer}: {e:#}"));
                self.compiled.insert(pointer.to_string(), i);
                i
            }
        };
        self.schemas
            .validate(value, index)
            .map_err(|e| e.to_string())
    }

    /// A job, as any answer or event carries it.
    pub fn job(&mut self, job: &Value) {
        self.validate("/components/schemas/Job", job);
    }

    /// The document's path template matching a concrete path.
    fn template(&self, path: &str) -> Option<String> {
        let path = path.split('?').next().unwrap();
        let segments: Vec<&str> = path.split('/').collect();
        self.doc["paths"]
            .as_object()
            .unwrap()
            .keys()
            .find(|t| {
                let ts: Vec<&str> = t.split('/').collect();
                ts.len() == segments.len()
                    && ts
                        .iter()
                        .zip(&segments)
                        .all(|(t, s)| t == s || (t.starts_with('{') && t.ends_with('}')))
            })
            .cloned()
    }

    /// Checks one answer to `method path`.
    pub fn answer(&mut self, method: &str, path: &str, status: u16, media: &str, body: &[u8]) {
        let media = media
            .split(';')
            .next()
            .unwrap_or_default()
            .trim()
            .to_string();
        let Some(template) = self.template(path) else {
            assert_eq!(
                status, 404,
                "{method} {path}: an undocumented path answered {status}"
            );
            return self.error_body(body, "route_not_found");
        };
        let op = &self.doc["paths"][&template][method.to_ascii_lowercase()];
        if op.is_null() {
            assert_eq!(
                status, 405,
                "{method} {path}: undocumented method answered {status}"
            );
            return self.error_body(body, "method_not_allowed");
        }
        let mut pointer = format!(
            "/paths/{}/{}/responses/{status}",
            token(&template),
            method.to_ascii_lowercase()
        );
        let mut response = &op["responses"][status.to_string()];
        assert!(
            !response.is_null(),
            "{method} {template} answered {status}, which it does not document"
        );
        if let Some(r) = response["$ref"].as_str() {
            pointer = r.trim_start_matches('#').to_string();
            let name = r.rsplit('/').next().unwrap();
            response = &self.doc["components"]["responses"][name];
        }
        let Some(content) = response["content"].as_object() else {
            assert!(
                body.is_empty(),
                "{method} {template} {status}: a body, none documented"
            );
            return;
        };
        assert!(
            content.contains_key(&media),
            "{method} {template} {status}: media type {media} not documented ({:?})",
            content.keys().collect::<Vec<_>>()
        );
        if media.ends_with("json") {
            let value: Value = serde_json::from_slice(body)
                .unwrap_or_else(|e| panic!("{method} {template} {status}: not JSON: {e}"));
            let schema = format!("{pointer}/content/{}/schema", token(&media));
            self.validate(&schema, &value);
        }
    }

    /// Validates every example in the document (parameters, request bodies, responses)
    /// against the schema beside it; returns how many there were.
    pub fn check_examples(&mut self) -> usize {
        let mut found: Vec<(String, Value)> = vec![];
        let doc = self.doc.clone();
        // (pointer of a content or parameter object, the object)
        let mut places: Vec<(String, &Value)> = vec![];
        for (path, item) in doc["paths"].as_object().unwrap() {
            let at = format!("/paths/{}", token(path));
            for (i, p) in item["parameters"]
                .as_array()
                .into_iter()
                .flatten()
                .enumerate()
            {
                places.push((format!("{at}/parameters/{i}"), p));
            }
            for (method, op) in item.as_object().unwrap() {
                let at = format!("{at}/{method}");
                for (i, p) in op["parameters"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .enumerate()
                {
                    places.push((format!("{at}/parameters/{i}"), p));
                }
                for (media, c) in op["requestBody"]["content"]
                    .as_object()
                    .into_iter()
                    .flatten()
                {
                    places.push((format!("{at}/requestBody/content/{}", token(media)), c));
                }
                for (status, r) in op["responses"].as_object().into_iter().flatten() {
                    if r.get("$ref").is_some() {
                        continue;
                    }
                    for (media, c) in r["content"].as_object().into_iter().flatten() {
                        let at = format!("{at}/responses/{status}/content/{}", token(media));
                        places.push((at, c));
                    }
                }
            }
        }
        for (name, r) in doc["components"]["responses"].as_object().unwrap() {
            for (media, c) in r["content"].as_object().into_iter().flatten() {
                let at = format!("/components/responses/{name}/content/{}", token(media));
                places.push((at, c));
            }
        }
        for (name, p) in doc["components"]["parameters"].as_object().unwrap() {
            places.push((format!("/components/parameters/{name}"), p));
        }
        for (at, place) in places {
            if place.get("$ref").is_some() || place.get("schema").is_none() {
                continue;
            }
            let schema = format!("{at}/schema");
            if let Some(e) = place.get("example") {
                found.push((schema.clone(), e.clone()));
            }
            for (_, e) in place["examples"].as_object().into_iter().flatten() {
                let e = match e["$ref"].as_str() {
                    Some(r) => &doc["components"]["examples"][r.rsplit('/').next().unwrap()],
                    None => e,
                };
                found.push((schema.clone(), e["value"].clone()));
            }
        }
        for (schema, example) in &found {
            assert!(!example.is_null(), "{schema}: an empty example");
            self.validate(schema, example);
        }
        found.len()
    }

    fn error_body(&mut self, body: &[u8], code: &str) {
        let value: Value = serde_json::from_slice(body).unwrap();
        self.validate("/components/schemas/Error", &value);
        assert_eq!(value["error"]["code"], code);
    }
}
