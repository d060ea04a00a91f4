//! `wavrad serve`: the HTTP job service (docs/contract.md, "HTTP API (v1)", docs/design.md section 8).
//!
//! - [`api_routes`] is the table of every route; [`app`] builds the router from it (a test checks
//!   it against `api/openapi.yaml`, served at `/v1/openapi.json`); [`Server`] binds and serves;
//!   [`serve`] does both and stops on Ctrl-C or SIGTERM.
//! - Errors: one type, [`ApiError`], rendered as the error JSON of docs/contract.md; extractors are wrapped
//!   ([`extract`]) and a last middleware rewrites any other error response into that shape.
//!   Middleware: optional bearer token on `/v1`, in-flight limit (503), timeout (408).
//! - Jobs ([`jobs`]): a bounded queue feeding `workers` runners ([`runner`]) that solve on a
//!   dedicated, niced rayon pool under `catch_unwind`; each job's state lives in a `watch` channel
//!   that polling and server-sent events both read.
//! - Store ([`store`]): one directory per job under `data_dir/jobs/`, every write atomic; the job's
//!   files are on disk before its 202 is sent. [`recovery`] reads them back at start. [`lock`]:
//!   one server per data directory (an OS lock taken before the store opens, held by the state).
//! - Shutdown: stop accepting, stop running solves at their next check and persist them as
//!   `queued`, end event streams, then return.
//! - [`metrics`]: `/metrics` in Prometheus text.
//! - Cluster mode ([`cluster`], `ServiceConfig::cluster`): the jobs and the queue in PostgreSQL,
//!   uploads and outputs in object storage; the router then takes the job routes from
//!   `cluster::routes` and the replica runs `cluster::worker` instead of the local runners and
//!   recovery. Without it nothing of the cluster runs.
//!
//! `GET /` is a small dashboard page (no external resources) that polls `GET /v1/jobs`.

pub mod cluster;
pub(crate) mod error;
pub(crate) mod extract;
pub(crate) mod jobs;
pub(crate) mod lock;
pub(crate) mod metrics;
pub(crate) mod recovery;
pub(crate) mod routes;
pub(crate) mod runner;
pub(crate) mod store;
pub(crate) mod time;

pub use error::ApiError;
pub use jobs::{Job, JobBoard, JobState, JobView, ProgressView};
pub use recovery::Recovered;
pub use store::{FileStore, JobId};

use crate::job::ProbeSource;
use axum::extract::{DefaultBodyLimit, Request, State};
use axum::handler::Handler;
use axum::http::{Method, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{delete, get, post, MethodRouter};
use axum::Router;
use std::future::Future;
use std::io;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::timeout::TimeoutLayer;
use tower_http::trace::{DefaultMakeSpan, DefaultOnResponse, TraceLayer};

/// Data directory when none is given (docs/contract.md, "Names").
pub const DEFAULT_DATA_DIR: &str = "./wavrad-data";
/// One job at a time by default: a solve already uses every core.
pub const DEFAULT_WORKERS: usize = 1;
/// Enough waiting jobs for a batch of bakes; beyond it clients back off (429) instead of piling up.
pub const DEFAULT_MAX_QUEUED: usize = 64;
/// 256 MiB holds a large GLB with data URIs while bounding the memory of one upload.
pub const DEFAULT_MAX_BODY_BYTES: usize = 256 << 20;
/// Five million triangles keep a solve's memory and time within one machine's reach.
pub const DEFAULT_MAX_TRIANGLES: usize = 5_000_000;

/// 16 GiB: the estimated solver memory of one job (see [`crate::job::estimated_memory_bytes`])
/// beyond which a submission is refused with 422.
pub const DEFAULT_MAX_MEMORY_BYTES: u64 = 16 << 30;

/// Succeeded jobs whose solution stays in memory to answer `POST /v1/jobs/{id}/probes` (the most
/// recent ones, solved or probed; a solution holds every element's coefficients, megabytes to
/// gigabytes). Any other job's is loaded from its `solution.bin` first.
pub const DEFAULT_PROBE_CACHE_JOBS: usize = 4;

/// Probe points in one `POST /v1/jobs/{id}/probes` (each is located against every element root).
pub const DEFAULT_MAX_PROBES: usize = 100_000;

/// Seconds a client is told to wait (`Retry-After`) when the queue or the server is full.
pub const RETRY_AFTER_SECONDS: u64 = 10;
/// Longest a request may take, upload included (a 256 MiB upload at 10 Mbit/s takes ~215 s).
pub const DEFAULT_REQUEST_TIMEOUT: Duration = Duration::from_secs(300);
/// Longest a shutdown waits for running solves to stop and be persisted as queued.
pub const SHUTDOWN_SOLVE_WAIT: Duration = Duration::from_secs(30);
/// Requests handled at once; beyond it 503, so a flood cannot exhaust memory or file handles.
pub const DEFAULT_MAX_IN_FLIGHT: usize = 1024;
/// Scene uploads buffered and checked at once: bounds their memory to this many bodies (each at
/// most `max_body_bytes`); further uploads wait for a slot.
pub const DEFAULT_MAX_CONCURRENT_UPLOADS: usize = 4;

/// Settings of the service (docs/contract.md, `wavrad serve` options).
#[derive(Clone, PartialEq, Eq)]
#[non_exhaustive]
pub struct ServiceConfig {
    /// Root of the job store (`data_dir/jobs/{id}/`).
    pub data_dir: PathBuf,
    /// Jobs solved at once.
    pub workers: usize,
    /// Jobs waiting for a worker; one more is refused with 429.
    pub max_queued: usize,
    /// Largest request body; larger is refused with 413.
    pub max_body_bytes: usize,
    /// Largest scene, in triangles; larger is refused with 422.
    pub max_triangles: usize,
    /// Largest estimated solver memory of one job, in bytes; larger is refused with 422.
    pub max_memory_bytes: u64,
    /// Longest solve, in seconds: a job's `max_seconds` is capped to it (and set to it when the
    /// job gives none). None: no cap.
    pub max_job_seconds: Option<u64>,
    /// Finished jobs kept; beyond it the oldest are deleted with their files. None: all kept.
    pub retain_jobs: Option<usize>,
    /// When set, every `/v1` route needs `Authorization: Bearer <token>` (401 otherwise).
    pub api_token: Option<String>,
    /// Requests handled at once; one more is refused with 503.
    pub max_in_flight: usize,
    /// Longest a request may take, upload included; beyond it 408.
    pub request_timeout: Duration,
    /// Scene uploads received and checked at once; more wait for a slot (within the request
    /// timeout).
    pub max_concurrent_uploads: usize,
    /// Most recent succeeded jobs whose solution is kept in memory for probe requests (0: none).
    pub probe_cache_jobs: usize,
    /// Probe points accepted in one probe request; more is refused with 400.
    pub max_probes: usize,
    /// Cluster mode (`--database-url` and `--object-store`); None: the embedded file store.
    pub cluster: Option<cluster::ClusterSettings>,
}

impl std::fmt::Debug for ServiceConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ServiceConfig")
            .field("data_dir", &self.data_dir)
            .field("workers", &self.workers)
            .field("max_queued", &self.max_queued)
            .field("max_body_bytes", &self.max_body_bytes)
            .field("max_triangles", &self.max_triangles)
            .field("max_memory_bytes", &self.max_memory_bytes)
            .field("max_job_seconds", &self.max_job_seconds)
            .field("retain_jobs", &self.retain_jobs)
            .field("api_token", &self.api_token.as_ref().map(|_| "<set>"))
            .field("max_in_flight", &self.max_in_flight)
            .field("request_timeout", &self.request_timeout)
            .field("max_concurrent_uploads", &self.max_concurrent_uploads)
            .field("probe_cache_jobs", &self.probe_cache_jobs)
            .field("max_probes", &self.max_probes)
            .field("cluster", &self.cluster)
            .finish()
    }
}

impl ServiceConfig {
    /// The defaults with `data_dir`.
    pub fn new(data_dir: impl Into<PathBuf>) -> Self {
        ServiceConfig {
            data_dir: data_dir.into(),
            workers: DEFAULT_WORKERS,
            max_queued: DEFAULT_MAX_QUEUED,
            max_body_bytes: DEFAULT_MAX_BODY_BYTES,
            max_triangles: DEFAULT_MAX_TRIANGLES,
            max_memory_bytes: DEFAULT_MAX_MEMORY_BYTES,
            max_job_seconds: None,
            retain_jobs: None,
            api_token: None,
            max_in_flight: DEFAULT_MAX_IN_FLIGHT,
            request_timeout: DEFAULT_REQUEST_TIMEOUT,
            max_concurrent_uploads: DEFAULT_MAX_CONCURRENT_UPLOADS,
            probe_cache_jobs: DEFAULT_PROBE_CACHE_JOBS,
            max_probes: DEFAULT_MAX_PROBES,
            cluster: None,
        }
    }

    /// Checks the settings; the error names the setting.
    pub fn validate(&self) -> Result<(), String> {
        if self.workers == 0 {
            return Err("--workers must be at least 1".into());
        }
        if self.max_queued == 0 {
            return Err("--max-queued must be at least 1".into());
        }
        if self.max_body_bytes == 0 {
            return Err("--max-body-bytes must be at least 1".into());
        }
        if self.max_triangles == 0 {
            return Err("--max-triangles must be at least 1".into());
        }
        if self.max_memory_bytes == 0 {
            return Err("--max-memory-bytes must be at least 1".into());
        }
        if self.max_in_flight == 0 {
            return Err("--max-in-flight must be at least 1".into());
        }
        if self.max_probes == 0 {
            return Err("--max-probes must be at least 1".into());
        }
        if self.max_concurrent_uploads == 0 {
            return Err("--max-concurrent-uploads must be at least 1".into());
        }
        if self.request_timeout.is_zero() {
            return Err("--request-timeout-seconds must be at least 1".into());
        }
        if self.max_job_seconds == Some(0) {
            return Err("--max-job-seconds must be at least 1".into());
        }
        if let Some(cluster) = &self.cluster {
            cluster.validate()?;
        }
        if self
            .api_token
            .as_deref()
            .is_some_and(|t| t.is_empty() || !t.bytes().all(|c| c.is_ascii_graphic()))
        {
            return Err(
                "--api-token must be non-empty printable ASCII without spaces (it is sent in an \
                 HTTP header)"
                    .into(),
            );
        }
        Ok(())
    }
}

impl Default for ServiceConfig {
    fn default() -> Self {
        ServiceConfig::new(DEFAULT_DATA_DIR)
    }
}

/// Shared state of the service: configuration, job store, job board, limits. Cheap to clone.
#[derive(Clone)]
pub struct AppState {
    inner: Arc<Shared>,
}

struct Shared {
    config: ServiceConfig,
    /// The data directory's exclusive lock, held as long as the state lives.
    _data_dir_lock: lock::DataDirLock,
    store: FileStore,
    jobs: JobBoard,
    upload_permits: Semaphore,
    in_flight: Arc<Semaphore>,
    /// Held while a POST with an `Idempotency-Key` stores its job.
    keyed_submissions: tokio::sync::Mutex<()>,
    metrics: metrics::Metrics,
    /// True once the server is shutting down (server-sent event streams end on it).
    shutdown: tokio::sync::watch::Sender<bool>,
    /// Solves in progress on the pool (a shutdown waits for them to be persisted).
    active_solves: std::sync::atomic::AtomicUsize,
    /// Solutions of the most recent succeeded jobs, newest last (`probe_cache_jobs` at most).
    probe_sources: std::sync::Mutex<std::collections::VecDeque<(String, Arc<ProbeSource>)>>,
    /// Held while a saved solution is loaded for a probe request (one load at a time bounds
    /// the memory and CPU that probes on jobs out of memory take).
    probe_loads: tokio::sync::Mutex<()>,
    /// Cluster mode's database and object store (None: the embedded file store).
    cluster: Option<Arc<cluster::Cluster>>,
}

impl AppState {
    /// Opens the store under `config.data_dir`, builds the solver pool and starts the runners.
    /// Must be called inside a Tokio runtime (the runners are Tokio tasks).
    pub fn new(config: ServiceConfig) -> io::Result<AppState> {
        AppState::build(config, None)
    }

    /// The state of a cluster replica: the local job board stays empty (no recovery, no local
    /// runners); `cluster::worker` runners claim jobs from the database.
    pub fn new_cluster(
        config: ServiceConfig,
        cluster: Arc<cluster::Cluster>,
    ) -> io::Result<AppState> {
        AppState::build(config, Some(cluster))
    }

    fn build(
        config: ServiceConfig,
        cluster: Option<Arc<cluster::Cluster>>,
    ) -> io::Result<AppState> {
        config
            .validate()
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
        if tokio::runtime::Handle::try_current().is_err() {
            return Err(io::Error::other(
                "AppState::new must be called inside a Tokio runtime",
            ));
        }
        // Before anything reads or writes the directory: a second server on it stops here.
        let data_dir_lock = lock::DataDirLock::acquire(&config.data_dir)?;
        let store = FileStore::open(&config.data_dir)?;
        let jobs = JobBoard::new(config.max_queued);
        if cluster.is_none() {
            recovery::recover(&store, &jobs)?;
        }
        let workers = config.workers;
        let pool = Arc::new(runner::solver_pool(workers)?);
        let max_in_flight = config.max_in_flight;
        let max_uploads = config.max_concurrent_uploads;
        let state = AppState {
            inner: Arc::new(Shared {
                jobs,
                config,
                _data_dir_lock: data_dir_lock,
                store,
                upload_permits: Semaphore::new(max_uploads),
                in_flight: Arc::new(Semaphore::new(max_in_flight)),
                keyed_submissions: tokio::sync::Mutex::new(()),
                metrics: metrics::Metrics::default(),
                shutdown: tokio::sync::watch::Sender::new(false),
                active_solves: std::sync::atomic::AtomicUsize::new(0),
                probe_sources: std::sync::Mutex::new(std::collections::VecDeque::new()),
                probe_loads: tokio::sync::Mutex::new(()),
                cluster,
            }),
        };
        match state.cluster() {
            Some(cluster) => cluster::worker::spawn(&state, cluster, pool, workers),
            None => {
                runner::enforce_retention(&state);
                runner::spawn_runners(&state, pool, workers);
            }
        }
        Ok(state)
    }

    /// Cluster mode's handles, when the service runs as a replica.
    pub fn cluster(&self) -> Option<&Arc<cluster::Cluster>> {
        self.inner.cluster.as_ref()
    }

    pub fn config(&self) -> &ServiceConfig {
        &self.inner.config
    }

    pub fn store(&self) -> &FileStore {
        &self.inner.store
    }

    pub fn jobs(&self) -> &JobBoard {
        &self.inner.jobs
    }

    pub fn metrics(&self) -> &metrics::Metrics {
        &self.inner.metrics
    }

    /// Whether the server is shutting down.
    pub fn is_shutting_down(&self) -> bool {
        *self.inner.shutdown.borrow()
    }

    /// A receiver that sees the start of the shutdown.
    pub fn shutdown_signal(&self) -> tokio::sync::watch::Receiver<bool> {
        self.inner.shutdown.subscribe()
    }

    /// Starts the shutdown: runners take no more jobs, running solves stop at their next check
    /// and go back to `queued` (persisted), event streams end.
    pub fn begin_shutdown(&self) {
        self.inner.shutdown.send_replace(true);
        for job in self.jobs().list() {
            if job.state() == JobState::Running {
                job.request_requeue();
            }
        }
    }

    pub(crate) fn solve_started(&self) {
        self.inner
            .active_solves
            .fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    }

    /// Solves in progress on this process's pool.
    pub(crate) fn active_solves(&self) -> usize {
        self.inner
            .active_solves
            .load(std::sync::atomic::Ordering::SeqCst)
    }

    pub(crate) fn solve_ended(&self) {
        self.inner
            .active_solves
            .fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
    }

    /// Waits until no solve is in progress, at most `limit`; true when none is.
    pub async fn wait_for_solves(&self, limit: Duration) -> bool {
        let start = std::time::Instant::now();
        loop {
            if self
                .inner
                .active_solves
                .load(std::sync::atomic::Ordering::SeqCst)
                == 0
            {
                return true;
            }
            if start.elapsed() >= limit {
                return false;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    /// Keeps a succeeded job's solution for probe requests, dropping the oldest beyond
    /// `probe_cache_jobs`.
    pub(crate) fn keep_probe_source(&self, id: &str, source: Arc<ProbeSource>) {
        let limit = self.config().probe_cache_jobs;
        let mut sources = self
            .inner
            .probe_sources
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        sources.retain(|(k, _)| k != id);
        if limit == 0 {
            return;
        }
        sources.push_back((id.to_string(), source));
        while sources.len() > limit {
            sources.pop_front();
        }
    }

    /// The kept solution of job `id`, if it is still in memory.
    pub(crate) fn probe_source(&self, id: &str) -> Option<Arc<ProbeSource>> {
        let sources = self
            .inner
            .probe_sources
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        sources
            .iter()
            .find(|(k, _)| k == id)
            .map(|(_, s)| s.clone())
    }

    /// Drops the kept solution of a deleted job.
    pub(crate) fn forget_probe_source(&self, id: &str) {
        self.inner
            .probe_sources
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .retain(|(k, _)| k != id);
    }

    pub(crate) fn probe_loads(&self) -> &tokio::sync::Mutex<()> {
        &self.inner.probe_loads
    }

    pub(crate) fn keyed_submissions(&self) -> &tokio::sync::Mutex<()> {
        &self.inner.keyed_submissions
    }

    pub(crate) fn upload_permits(&self) -> &Semaphore {
        &self.inner.upload_permits
    }
}

impl std::fmt::Debug for AppState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AppState")
            .field("config", &self.inner.config)
            .finish_non_exhaustive()
    }
}

/// One route of the router: path (axum syntax, which is also OpenAPI's), method, the paths of
/// `api/openapi.yaml` it answers (a catch-all route answers several), and its handler.
pub struct ApiRoute {
    pub path: &'static str,
    pub method: Method,
    pub documented: &'static [&'static str],
    pub handler: MethodRouter<AppState>,
}

/// Every route the service answers. [`app`] is built from this table, and a test checks it
/// against the OpenAPI document both ways.
pub fn api_routes(max_body: usize) -> Vec<ApiRoute> {
    fn route(
        path: &'static str,
        method: Method,
        documented: &'static [&'static str],
        handler: MethodRouter<AppState>,
    ) -> ApiRoute {
        ApiRoute {
            path,
            method,
            documented,
            handler,
        }
    }
    vec![
        route("/", Method::GET, &["/"], get(routes::dashboard)),
        route("/view", Method::GET, &["/view"], get(routes::viewer)),
        route(
            "/assets/{*file}",
            Method::GET,
            &["/assets/{file}"],
            get(routes::asset),
        ),
        route("/healthz", Method::GET, &["/healthz"], get(routes::healthz)),
        route("/metrics", Method::GET, &["/metrics"], get(routes::metrics)),
        route(
            "/v1/openapi.json",
            Method::GET,
            &["/v1/openapi.json"],
            get(routes::openapi),
        ),
        route(
            "/v1/jobs",
            Method::GET,
            &["/v1/jobs"],
            get(routes::list_jobs),
        ),
        route(
            "/v1/jobs",
            Method::POST,
            &["/v1/jobs"],
            post(routes::create_job.layer(DefaultBodyLimit::max(max_body))),
        ),
        route(
            "/v1/jobs/{id}",
            Method::GET,
            &["/v1/jobs/{id}"],
            get(routes::get_job),
        ),
        route(
            "/v1/jobs/{id}",
            Method::DELETE,
            &["/v1/jobs/{id}"],
            delete(routes::delete_job),
        ),
        route(
            "/v1/jobs/{id}/events",
            Method::GET,
            &["/v1/jobs/{id}/events"],
            get(routes::job_events),
        ),
        route(
            "/v1/jobs/{id}/result",
            Method::GET,
            &["/v1/jobs/{id}/result"],
            get(routes::get_result),
        ),
        route(
            "/v1/jobs/{id}/probes",
            Method::POST,
            &["/v1/jobs/{id}/probes"],
            post(routes::post_probes.layer(DefaultBodyLimit::max(max_body))),
        ),
        route(
            "/v1/jobs/{id}/convergence",
            Method::GET,
            &["/v1/jobs/{id}/convergence"],
            get(routes::get_convergence),
        ),
        route(
            "/v1/jobs/{id}/{file}",
            Method::GET,
            &[
                "/v1/jobs/{id}/lightmap.exr",
                "/v1/jobs/{id}/lightmap-{n}.exr",
                "/v1/jobs/{id}/preview.png",
                "/v1/jobs/{id}/atlas.png",
                "/v1/jobs/{id}/scene.glb",
            ],
            get(routes::get_file),
        ),
    ]
}

/// The service's router: every route of [`api_routes`] with limits, timeouts, panic catching and
/// tracing.
pub fn app(state: AppState) -> Router {
    let max_body = state.config().max_body_bytes;
    let clustered = state.cluster().is_some();
    let mut router = Router::new();
    for r in api_routes(max_body) {
        // A cluster replica answers the job routes from the database and the object store.
        let handler = match clustered {
            true => cluster::routes::handler(r.path, &r.method, max_body).unwrap_or(r.handler),
            false => r.handler,
        };
        // Routes on one path merge their methods.
        router = router.route(r.path, handler);
    }
    router
        .fallback(error::route_not_found)
        .method_not_allowed_fallback(error::method_not_allowed)
        // Innermost first: the timeout's empty 408 and every other non-JSON error pass through the
        // normaliser; a panic anywhere inside becomes a JSON 500.
        .layer(TimeoutLayer::with_status_code(
            StatusCode::REQUEST_TIMEOUT,
            state.config().request_timeout,
        ))
        .layer(middleware::from_fn_with_state(state.clone(), require_token))
        .layer(middleware::from_fn_with_state(
            state.clone(),
            limit_in_flight,
        ))
        .layer(middleware::map_response(error::normalize_error_response))
        .layer(CatchPanicLayer::custom(error::panic_response))
        // A span per request at INFO (method, path), so what a handler logs carries its request;
        // the per-response line is DEBUG so polling floods no log. 5xx are logged at ERROR.
        .layer(
            TraceLayer::new_for_http()
                .make_span_with(DefaultMakeSpan::new().level(tracing::Level::INFO))
                .on_response(DefaultOnResponse::new().level(tracing::Level::DEBUG)),
        )
        .with_state(state)
}

/// With `--api-token`, every `/v1` route needs `Authorization: Bearer <token>` (401 otherwise);
/// `/healthz` and `/metrics` stay open.
async fn require_token(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let Some(token) = state.config().api_token.as_deref() else {
        return next.run(request).await;
    };
    let path = request.uri().path();
    if !(path == "/v1" || path.starts_with("/v1/")) {
        return next.run(request).await;
    }
    let given = request
        .headers()
        .get(axum::http::header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| {
            let (scheme, rest) = v.trim().split_once(' ')?;
            scheme.eq_ignore_ascii_case("bearer").then(|| rest.trim())
        });
    match given {
        Some(given) if constant_time_eq(given.as_bytes(), token.as_bytes()) => {
            next.run(request).await
        }
        _ => {
            let message = if given.is_some() {
                "the bearer token is not valid for this server"
            } else {
                "this server needs 'Authorization: Bearer <token>' on every /v1 route (the token \
                 is the server's --api-token / WAVRAD_API_TOKEN)"
            };
            let mut response =
                ApiError::new(StatusCode::UNAUTHORIZED, "unauthorized", message).into_response();
            response.headers_mut().insert(
                axum::http::header::WWW_AUTHENTICATE,
                axum::http::HeaderValue::from_static("Bearer"),
            );
            response
        }
    }
}

/// Compares two byte strings in time independent of where they differ.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Refuses a request with 503 when `max_in_flight` requests are already being handled.
async fn limit_in_flight(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let Ok(_permit) = state.inner.in_flight.clone().try_acquire_owned() else {
        return ApiError {
            retry_after: Some(1),
            ..ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "server_busy",
                "the server is handling as many requests as it allows; retry shortly",
            )
        }
        .into_response();
    };
    next.run(request).await
}

/// A bound, not yet serving, service.
#[derive(Debug)]
pub struct Server {
    listener: TcpListener,
    state: AppState,
    addr: SocketAddr,
}

impl Server {
    /// Starts the state (store, pool, runners) and binds `addr` (port 0 picks a free port).
    pub async fn bind(config: ServiceConfig, addr: SocketAddr) -> io::Result<Server> {
        let state = match config.cluster.clone() {
            Some(settings) => {
                let cluster = cluster::Cluster::connect(settings).await?;
                AppState::new_cluster(config, cluster)?
            }
            None => AppState::new(config)?,
        };
        let listener = TcpListener::bind(addr).await?;
        let addr = listener.local_addr()?;
        tracing::info!(%addr, data_dir = %state.config().data_dir.display(), "wavrad serve listening");
        Ok(Server {
            listener,
            state,
            addr,
        })
    }

    /// The address actually bound.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn state(&self) -> &AppState {
        &self.state
    }

    /// Serves until Ctrl-C or SIGTERM, then finishes the requests in progress.
    pub async fn run(self) -> io::Result<()> {
        self.run_until(shutdown_signal()).await
    }

    /// Serves until `shutdown` completes; then stops accepting, stops running solves at their
    /// next check and persists them as `queued`, finishes the requests in progress, and returns.
    pub async fn run_until(
        self,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> io::Result<()> {
        let state = self.state.clone();
        let signal = async move {
            shutdown.await;
            state.begin_shutdown();
        };
        axum::serve(self.listener, app(self.state.clone()))
            .with_graceful_shutdown(signal)
            .await?;
        if !self.state.wait_for_solves(SHUTDOWN_SOLVE_WAIT).await {
            tracing::warn!("a solve did not stop in time; its job is re-queued at the next start");
        }
        tracing::info!("wavrad serve stopped");
        Ok(())
    }
}

/// Binds `addr`, logs the bound address and serves until Ctrl-C or SIGTERM.
pub async fn serve(config: ServiceConfig, addr: SocketAddr) -> io::Result<()> {
    Server::bind(config, addr).await?.run().await
}

/// Completes on Ctrl-C or (Unix) SIGTERM.
async fn shutdown_signal() {
    let ctrl_c = async {
        if let Err(e) = tokio::signal::ctrl_c().await {
            tracing::warn!(error = %e, "cannot listen for Ctrl-C");
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(e) => {
                tracing::warn!(error = %e, "cannot listen for SIGTERM");
                std::future::pending::<()>().await;
            }
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {}
        () = terminate => {}
    }
    tracing::info!("shutting down: finishing requests in progress");
}
