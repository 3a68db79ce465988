//! The container and deploy files: parsed and cross-checked here, since no Docker engine or
//! cluster runs the tests. Where the registry validators (hadolint, check-jsonschema with the
//! Compose spec, kubernetes-validate) are installed they run too; `.ci/backends.sh` installs them,
//! so under CI their absence is a failure rather than a skip.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use yaml_rust2::{Yaml, YamlLoader};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn yaml_docs(rel: &str) -> Vec<Yaml> {
    YamlLoader::load_from_str(&read(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn strs(y: &Yaml) -> Vec<String> {
    y.as_vec()
        .map(|v| {
            v.iter()
                .filter_map(|s| s.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default()
}

/// Runs an external validator; `None` when it is not installed and we may skip.
fn validator(program: &str, args: &[&str]) -> Option<std::process::Output> {
    match Command::new(program)
        .args(args)
        .current_dir(root())
        .output()
    {
        Ok(out) => Some(out),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            assert!(
                std::env::var_os("CI").is_none(),
                "{program} is not installed but CI is set: .ci/backends.sh installs it"
            );
            // Straight to stderr: the test harness captures eprintln! of passing tests.
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "skipping the {program} check: {program} is not installed (pip install it)"
            );
            None
        }
        Err(e) => panic!("{program}: {e}"),
    }
}

fn assert_success(program: &str, out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{program} failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

// ----- Dockerfile -----

/// Dockerfile instructions with continuation lines joined and comments dropped.
fn dockerfile_instructions() -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut pending = String::new();
    for line in read("Dockerfile").lines() {
        let t = line.trim();
        if t.starts_with('#') || (t.is_empty() && pending.is_empty()) {
            continue;
        }
        if let Some(cont) = t.strip_suffix('\\') {
            pending.push_str(cont);
            pending.push(' ');
            continue;
        }
        pending.push_str(t);
        let (op, rest) = pending.split_once(' ').unwrap_or((&pending, ""));
        out.push((op.to_uppercase(), rest.trim().to_string()));
        pending.clear();
    }
    assert!(pending.is_empty(), "Dockerfile ends in a continuation");
    out
}

/// The instructions of each stage, split at `FROM`.
fn dockerfile_stages() -> Vec<Vec<(String, String)>> {
    let mut stages: Vec<Vec<(String, String)>> = Vec::new();
    for ins in dockerfile_instructions() {
        if ins.0 == "FROM" {
            stages.push(Vec::new());
        }
        stages
            .last_mut()
            .expect("the Dockerfile starts with FROM")
            .push(ins);
    }
    stages
}

#[test]
fn dockerfile_is_multi_stage_with_a_slim_non_root_runtime() {
    let stages = dockerfile_stages();
    assert_eq!(stages.len(), 2, "a build stage and a runtime stage");
    let build_from = &stages[0][0].1;
    assert!(build_from.starts_with("rust:"), "{build_from}");
    assert!(build_from.ends_with(" AS build"), "{build_from}");
    let runtime = &stages[1];
    assert!(
        runtime[0].1.contains("-slim"),
        "slim runtime: {}",
        runtime[0].1
    );

    let find = |op: &str| -> Vec<&String> {
        runtime
            .iter()
            .filter(|(o, _)| o == op)
            .map(|(_, r)| r)
            .collect()
    };
    let user = find("USER");
    assert_eq!(user.len(), 1);
    let uid = user[0].split(':').next().unwrap();
    assert!(uid != "0" && uid != "root", "runs as root: {}", user[0]);

    // One binary, copied from the build stage, run as the entrypoint.
    let copies = find("COPY");
    assert_eq!(copies.len(), 1, "{copies:?}");
    assert_eq!(
        copies[0],
        "--from=build /src/target/release/asbuilt /usr/local/bin/asbuilt"
    );
    assert_eq!(find("ENTRYPOINT"), [&r#"["asbuilt"]"#.to_string()]);

    let health = find("HEALTHCHECK");
    assert_eq!(health.len(), 1);
    assert!(
        health[0].ends_with(r#"CMD ["asbuilt", "healthcheck"]"#),
        "{}",
        health[0]
    );

    // Nothing in the runtime stage fetches over the network at run time.
    for (op, rest) in runtime {
        assert!(op != "ADD", "ADD in the runtime stage: {rest}");
        for tool in ["curl", "wget"] {
            assert!(!rest.contains(tool), "{tool} in the runtime image: {rest}");
        }
    }
}

#[test]
fn dockerfile_builds_with_the_command_ci_runs() {
    let ci = read(".ci/run");
    let runs: Vec<String> = dockerfile_stages()[0]
        .iter()
        .filter(|(op, _)| op == "RUN")
        .map(|(_, r)| r.clone())
        .collect();
    assert!(!runs.is_empty());
    for run in runs {
        assert!(
            run.starts_with("cargo "),
            "the build stage runs only cargo: {run}"
        );
        assert!(
            ci.lines().any(|l| l.trim() == run),
            "the build stage runs `{run}`, which .ci/run does not"
        );
    }
}

/// The header's first-run lines give the server an API key: without one it binds to loopback
/// inside the container and the published port reaches nothing. CI runs the image the same way.
#[test]
fn dockerfile_first_run_line_gives_a_key_and_ci_runs_the_image() {
    let dockerfile = read("Dockerfile");
    let run_line = dockerfile
        .lines()
        .take_while(|l| l.starts_with('#'))
        .find(|l| l.contains("docker run"))
        .expect("the header shows how to run the image");
    assert!(run_line.contains("-p 8080:8080"), "{run_line}");
    assert!(run_line.contains("ASBUILT_API_KEYS="), "{run_line}");

    let ci = read(".ci/run");
    let release = ci
        .find("cargo build --release")
        .expect(".ci/run builds the release binary");
    let container = ci
        .find("bash .ci/container.sh")
        .expect(".ci/run builds and runs the image");
    assert!(
        release < container,
        "the image needs the release binary first"
    );
    let script = read(".ci/container.sh");
    assert!(script.contains("ASBUILT_API_KEYS="));
    // The script rebuilds this stage on a debootstrapped base of the same suite.
    let runtime = &dockerfile_stages()[1][0].1;
    assert_eq!(runtime, "debian:bookworm-slim AS runtime");
    assert!(script.contains(&format!("FROM {runtime}")));
}

#[test]
fn dockerignore_keeps_build_outputs_and_history_out_of_the_context() {
    let ignore = read(".dockerignore");
    let lines: BTreeSet<&str> = ignore.lines().map(str::trim).collect();
    for must in [".git/", "target/"] {
        assert!(lines.contains(must), "{must} is not ignored");
    }
    // The build needs these, so they must not be ignored.
    for keep in ["src", "crates", "Cargo.toml", "Cargo.lock"] {
        assert!(
            !lines.iter().any(|l| l.trim_end_matches('/') == keep),
            "{keep} is ignored"
        );
    }
}

#[test]
fn dockerfile_passes_hadolint() {
    if let Some(out) = validator("hadolint", &["Dockerfile"]) {
        assert_success("hadolint", &out);
    }
}

// ----- docker-compose -----

/// A compose service's environment with `<<` merge keys resolved (YAML 1.2 parsers keep them).
fn compose_env(service: &Yaml) -> Vec<(String, String)> {
    fn flatten(h: &Yaml, out: &mut Vec<(String, String)>) {
        let Some(hash) = h.as_hash() else { return };
        for (k, v) in hash {
            let key = k.as_str().unwrap_or_default();
            if key == "<<" {
                flatten(v, out);
            } else {
                let value = match v {
                    Yaml::String(s) => s.clone(),
                    Yaml::Integer(i) => i.to_string(),
                    Yaml::Boolean(b) => b.to_string(),
                    _ => String::new(),
                };
                out.retain(|(k2, _)| k2 != key);
                out.push((key.to_string(), value));
            }
        }
    }
    let mut out = Vec::new();
    flatten(&service["environment"], &mut out);
    out
}

#[test]
fn compose_runs_postgres_minio_one_api_and_n_workers() {
    let docs = yaml_docs("deploy/docker-compose.yml");
    assert_eq!(docs.len(), 1);
    let services = &docs[0]["services"];
    for name in ["postgres", "minio", "migrate", "api", "worker"] {
        assert!(!services[name].is_badvalue(), "no {name} service");
    }
    assert!(services["postgres"]["image"]
        .as_str()
        .unwrap()
        .starts_with("postgres:"));
    assert!(services["minio"]["image"]
        .as_str()
        .unwrap()
        .starts_with("minio/minio"));
    for name in ["postgres", "minio", "api", "worker"] {
        let test = strs(&services[name]["healthcheck"]["test"]);
        assert_eq!(test.first().map(String::as_str), Some("CMD"), "{name}");
    }
    assert_eq!(
        strs(&services["api"]["healthcheck"]["test"]),
        ["CMD", "asbuilt", "healthcheck"]
    );

    assert_eq!(strs(&services["api"]["command"]), ["serve", "--no-workers"]);
    assert_eq!(strs(&services["worker"]["command"]), ["worker"]);
    assert_eq!(strs(&services["migrate"]["command"]), ["migrate"]);
    let replicas = services["worker"]["deploy"]["replicas"].as_str().unwrap();
    assert!(
        replicas.starts_with("${ASBUILT_WORKER_REPLICAS"),
        "{replicas}"
    );
    assert!(services["migrate"]["build"]["dockerfile"].as_str() == Some("Dockerfile"));

    // The API and the workers wait for the schema, and share one database and bucket.
    for name in ["api", "worker"] {
        let dep = &services[name]["depends_on"]["migrate"]["condition"];
        assert_eq!(
            dep.as_str(),
            Some("service_completed_successfully"),
            "{name}"
        );
        let env = compose_env(&services[name]);
        let get = |k: &str| env.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
        assert!(get("ASBUILT_DATABASE_URL")
            .unwrap()
            .starts_with("postgres://"));
        assert_eq!(get("ASBUILT_STORAGE"), Some("s3://asbuilt/jobs"));
        assert_eq!(get("AWS_ENDPOINT"), Some("http://minio:9000"));
        assert!(get("ASBUILT_LISTEN").is_some(), "{name} has no health port");
        // Docker's SIGKILL must come after the process's own shutdown timeout.
        let timeout: u64 = get("ASBUILT_SHUTDOWN_TIMEOUT").unwrap().parse().unwrap();
        let grace = services[name]["stop_grace_period"].as_str().unwrap();
        let grace: u64 = grace.trim_end_matches('s').parse().unwrap();
        assert!(
            grace >= timeout + 5,
            "{name}: grace {grace} s, timeout {timeout} s"
        );
    }

    // Named volumes keep the database and the objects; each is declared.
    let declared = docs[0]["volumes"].as_hash().expect("top-level volumes");
    for (name, path) in [("postgres", "/var/lib/postgresql/data"), ("minio", "/data")] {
        let mounts = strs(&services[name]["volumes"]);
        let (vol, target) = mounts[0].split_once(':').unwrap();
        assert_eq!(target, path, "{name}");
        assert!(
            declared.contains_key(&Yaml::String(vol.into())),
            "{vol} undeclared"
        );
    }
}

#[test]
fn compose_passes_the_compose_spec_schema() {
    let args = [
        "--builtin-schema",
        "vendor.compose-spec",
        "deploy/docker-compose.yml",
    ];
    if let Some(out) = validator("check-jsonschema", &args) {
        assert_success("check-jsonschema", &out);
    }
}

// ----- Kubernetes -----

const K8S: &str = "deploy/kubernetes";

/// Every resource in deploy/kubernetes, with the file it came from.
fn k8s_resources() -> Vec<(String, Yaml)> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join(K8S))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .collect();
    files.sort();
    let mut out = Vec::new();
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        for doc in yaml_docs(&format!("{K8S}/{name}")) {
            out.push((name.clone(), doc));
        }
    }
    out
}

fn resource<'a>(all: &'a [(String, Yaml)], kind: &str, name: &str) -> &'a Yaml {
    all.iter()
        .map(|(_, d)| d)
        .find(|d| d["kind"].as_str() == Some(kind) && d["metadata"]["name"].as_str() == Some(name))
        .unwrap_or_else(|| panic!("no {kind} {name}"))
}

/// Parses a Kubernetes quantity of memory into bytes (`512Mi`, `4Gi`).
fn mem_bytes(q: &Yaml) -> u64 {
    let s = q.as_str().expect("memory quantity");
    let (num, mult) = match s {
        _ if s.ends_with("Gi") => (&s[..s.len() - 2], 1 << 30),
        _ if s.ends_with("Mi") => (&s[..s.len() - 2], 1 << 20),
        _ => panic!("memory quantity {s} not in Mi or Gi"),
    };
    num.parse::<u64>().unwrap() * mult
}

#[test]
fn every_resource_has_kind_version_and_name_and_kustomize_lists_it() {
    let all = k8s_resources();
    let mut files = BTreeSet::new();
    for (file, doc) in &all {
        for field in [&doc["apiVersion"], &doc["kind"]] {
            assert!(
                field.as_str().is_some(),
                "{file}: missing apiVersion or kind"
            );
        }
        if doc["kind"].as_str() != Some("Kustomization") {
            assert!(
                doc["metadata"]["name"].as_str().is_some(),
                "{file}: no name"
            );
            files.insert(file.clone());
        }
    }
    let kustomize = resource_kind(&all, "Kustomization");
    let listed: BTreeSet<String> = strs(&kustomize["resources"]).into_iter().collect();
    for l in &listed {
        assert!(
            root().join(K8S).join(l).exists(),
            "kustomization lists missing {l}"
        );
    }
    // The Secret is a template to fill in, so it is the one file kustomize must not apply.
    files.remove("secret.template.yaml");
    assert_eq!(listed, files);
}

fn resource_kind<'a>(all: &'a [(String, Yaml)], kind: &str) -> &'a Yaml {
    all.iter()
        .map(|(_, d)| d)
        .find(|d| d["kind"].as_str() == Some(kind))
        .unwrap_or_else(|| panic!("no {kind}"))
}

/// The checks every Deployment shares; returns its one container.
fn check_deployment<'a>(all: &[(String, Yaml)], d: &'a Yaml, args: &[&str]) -> &'a Yaml {
    let name = d["metadata"]["name"].as_str().unwrap();
    let selector = d["spec"]["selector"]["matchLabels"].as_hash().unwrap();
    let labels = d["spec"]["template"]["metadata"]["labels"]
        .as_hash()
        .unwrap();
    for (k, v) in selector {
        assert_eq!(
            labels.get(k),
            Some(v),
            "{name}: selector does not match the pod"
        );
    }
    let pod = &d["spec"]["template"]["spec"];
    assert_eq!(pod["securityContext"]["runAsNonRoot"].as_bool(), Some(true));
    assert_eq!(pod["securityContext"]["runAsUser"].as_i64(), Some(10001));
    let containers = pod["containers"].as_vec().unwrap();
    assert_eq!(containers.len(), 1, "{name}");
    let c = &containers[0];
    assert!(c["image"].as_str().unwrap().starts_with("asbuilt:"));
    assert_eq!(strs(&c["args"]), args, "{name}: role");
    check_env_sources(all, c);

    let res = &c["resources"];
    assert!(
        res["requests"]["cpu"].as_str().is_some(),
        "{name}: cpu request"
    );
    let (req, lim) = (
        mem_bytes(&res["requests"]["memory"]),
        mem_bytes(&res["limits"]["memory"]),
    );
    assert!(
        req > 0 && req <= lim,
        "{name}: memory request {req} over limit {lim}"
    );

    // Probes name a declared port and a health path the binary serves.
    let ports: Vec<&str> = c["ports"]
        .as_vec()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    for (probe, path) in [("readinessProbe", "/readyz"), ("livenessProbe", "/healthz")] {
        let get = &c[probe]["httpGet"];
        assert_eq!(get["path"].as_str(), Some(path), "{name} {probe}");
        assert!(
            ports.contains(&get["port"].as_str().unwrap()),
            "{name} {probe}"
        );
    }
    // A read-only root needs writable mounts for scratch space, each backed by a volume.
    assert_eq!(
        c["securityContext"]["readOnlyRootFilesystem"].as_bool(),
        Some(true)
    );
    let volumes: Vec<&str> = pod["volumes"]
        .as_vec()
        .unwrap()
        .iter()
        .map(|v| v["name"].as_str().unwrap())
        .collect();
    let mounts = c["volumeMounts"].as_vec().unwrap();
    assert!(mounts
        .iter()
        .any(|m| m["mountPath"].as_str() == Some("/var/lib/asbuilt")));
    for m in mounts {
        assert!(
            volumes.contains(&m["name"].as_str().unwrap()),
            "{name}: mount"
        );
    }
    c
}

/// `envFrom` names the ConfigMap and the Secret that the files define.
fn check_env_sources(all: &[(String, Yaml)], c: &Yaml) {
    let from = c["envFrom"].as_vec().expect("envFrom");
    let cm = from
        .iter()
        .find_map(|f| f["configMapRef"]["name"].as_str())
        .expect("a ConfigMap");
    let secret = from
        .iter()
        .find_map(|f| f["secretRef"]["name"].as_str())
        .expect("a Secret");
    resource(all, "ConfigMap", cm);
    resource(all, "Secret", secret);
}

#[test]
fn api_and_worker_deployments_run_their_roles_with_sized_resources() {
    let all = k8s_resources();
    let api = resource(&all, "Deployment", "asbuilt-api");
    check_deployment(&all, api, &["serve", "--no-workers"]);
    let worker = resource(&all, "Deployment", "asbuilt-worker");
    let w = check_deployment(&all, worker, &["worker"]);
    // A pipeline holds the cloud in memory; an API process only streams.
    let api_c = &api["spec"]["template"]["spec"]["containers"][0];
    assert!(
        mem_bytes(&w["resources"]["limits"]["memory"])
            > mem_bytes(&api_c["resources"]["limits"]["memory"])
    );
    // The worker's memory limit holds the largest cloud allowed, at the measured peak of about
    // 22 bytes a point (deploy/README.md, Sizing), with a margin.
    let config = resource(&all, "ConfigMap", "asbuilt");
    let max_points: u64 = config["data"]["ASBUILT_MAX_POINTS"]
        .as_str()
        .expect("the ConfigMap sets ASBUILT_MAX_POINTS")
        .parse()
        .unwrap();
    let limit = mem_bytes(&w["resources"]["limits"]["memory"]);
    assert!(
        limit >= max_points * 24 + (64 << 20),
        "{limit} B for {max_points} points"
    );
    // On SIGTERM a process gets the shutdown timeout to drain connections and hand jobs back;
    // the kubelet must not SIGKILL it before then.
    let timeout = config["data"]["ASBUILT_SHUTDOWN_TIMEOUT"].as_str().map_or(
        asbuilt::config::Config::default().shutdown_timeout_secs,
        |t| t.parse().unwrap(),
    ) as i64;
    for d in [api, worker] {
        let grace = d["spec"]["template"]["spec"]["terminationGracePeriodSeconds"]
            .as_i64()
            .unwrap();
        assert!(
            grace > timeout + 5,
            "grace {grace} s, shutdown timeout {timeout} s"
        );
    }
}

#[test]
fn service_selects_the_api_pods_and_targets_their_port() {
    let all = k8s_resources();
    let svc = resource(&all, "Service", "asbuilt-api");
    let api = resource(&all, "Deployment", "asbuilt-api");
    let labels = api["spec"]["template"]["metadata"]["labels"]
        .as_hash()
        .unwrap();
    for (k, v) in svc["spec"]["selector"].as_hash().unwrap() {
        assert_eq!(labels.get(k), Some(v));
    }
    let target = svc["spec"]["ports"][0]["targetPort"].as_str().unwrap();
    let c = &api["spec"]["template"]["spec"]["containers"][0];
    assert!(c["ports"]
        .as_vec()
        .unwrap()
        .iter()
        .any(|p| p["name"].as_str() == Some(target)));
}

#[test]
fn migration_job_runs_migrate_and_the_hpa_scales_the_workers() {
    let all = k8s_resources();
    let job = resource(&all, "Job", "asbuilt-migrate");
    let pod = &job["spec"]["template"]["spec"];
    assert_eq!(strs(&pod["containers"][0]["args"]), ["migrate"]);
    assert!(matches!(
        pod["restartPolicy"].as_str(),
        Some("OnFailure" | "Never")
    ));
    check_env_sources(&all, &pod["containers"][0]);

    let hpa = resource(&all, "HorizontalPodAutoscaler", "asbuilt-worker");
    assert_eq!(hpa["apiVersion"].as_str(), Some("autoscaling/v2"));
    let target = &hpa["spec"]["scaleTargetRef"];
    assert_eq!(target["kind"].as_str(), Some("Deployment"));
    assert_eq!(target["name"].as_str(), Some("asbuilt-worker"));
    let (min, max) = (
        hpa["spec"]["minReplicas"].as_i64().unwrap(),
        hpa["spec"]["maxReplicas"].as_i64().unwrap(),
    );
    assert!(1 <= min && min < max, "{min}..{max}");
    let metrics = hpa["spec"]["metrics"].as_vec().unwrap();
    assert!(!metrics.is_empty());
    // CPU needs the pods to request CPU, or utilisation is undefined.
    let worker = resource(&all, "Deployment", "asbuilt-worker");
    let c = &worker["spec"]["template"]["spec"]["containers"][0];
    assert!(c["resources"]["requests"]["cpu"].as_str().is_some());
}

#[test]
fn secret_is_a_template_with_placeholders_only() {
    let all = k8s_resources();
    let secret = resource(&all, "Secret", "asbuilt");
    let data = secret["stringData"].as_hash().unwrap();
    for key in [
        "ASBUILT_DATABASE_URL",
        "AWS_ACCESS_KEY_ID",
        "AWS_SECRET_ACCESS_KEY",
    ] {
        let v = data[&Yaml::String(key.into())].as_str().unwrap();
        assert!(v.contains("CHANGE-ME"), "{key} holds a real-looking value");
    }
}

#[test]
fn manifests_pass_the_kubernetes_schemas() {
    let mut args = vec!["--strict".to_string(), "--quiet".to_string()];
    for (file, doc) in k8s_resources() {
        if doc["kind"].as_str() != Some("Kustomization") {
            args.push(format!("{K8S}/{file}"));
        }
    }
    args.dedup();
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    if let Some(out) = validator("kubernetes-validate", &args) {
        assert_success("kubernetes-validate", &out);
    }
}

#[test]
fn the_readme_covers_compose_kubernetes_and_the_settings() {
    let readme = read("deploy/README.md");
    for must in [
        "docker compose",
        "kubectl apply -k",
        "asbuilt migrate",
        "ASBUILT_DATABASE_URL",
        "ASBUILT_STORAGE",
        "AWS_ENDPOINT",
    ] {
        assert!(
            readme.contains(must),
            "deploy/README.md does not mention {must}"
        );
    }
    assert!(Path::new(&root().join("deploy/kubernetes/secret.template.yaml")).exists());
}

/// Every `ASBUILT_*` variable the deploy files set is one the binary reads (as clap's env
/// twin of a `serve`, `worker` or `migrate` flag), so a typo cannot silently do nothing.
#[test]
fn deploy_files_set_only_variables_the_binary_reads() {
    let mut known = BTreeSet::new();
    for cmd in ["serve", "worker", "migrate", "healthcheck"] {
        let out = Command::new(env!("CARGO_BIN_EXE_asbuilt"))
            .args([cmd, "--help"])
            .output()
            .unwrap();
        assert!(out.status.success(), "asbuilt {cmd} --help");
        let help = String::from_utf8_lossy(&out.stdout).into_owned();
        for part in help.split("[env: ").skip(1) {
            known.insert(part.split(['=', ']']).next().unwrap().to_string());
        }
    }
    // Read by the logger, not by a flag.
    known.insert("ASBUILT_LOG".into());
    assert!(known.contains("ASBUILT_DATABASE_URL") && known.contains("ASBUILT_STORAGE"));
    let mut files = vec![
        "Dockerfile".to_string(),
        "deploy/docker-compose.yml".to_string(),
    ];
    for (file, _) in k8s_resources() {
        files.push(format!("{K8S}/{file}"));
    }
    for file in files {
        let text = read(&file);
        for (i, _) in text.match_indices("ASBUILT_") {
            let name: String = text[i..]
                .chars()
                .take_while(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || *c == '_')
                .collect();
            // Compose's own interpolation variables are not the binary's.
            if name == "ASBUILT_WORKER_REPLICAS" {
                continue;
            }
            assert!(
                known.contains(&name),
                "{file} sets {name}, which asbuilt does not read"
            );
        }
    }
}
