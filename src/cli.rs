//! The command line (docs/contract.md, "Command line"): `solve`, `faces`, `serve`, `bench`
//! (`visibility`, `sweep`).
//!
//! Machine output (JSON) goes to stdout only; logs and the progress bar to stderr. Exit codes:
//! 0 success, 2 bad input or bad options (one-line reason on stderr), 1 internal failure.

use crate::job::{run_job_with_probes, DomainMode, JobError, JobParams, QuantityParam};
use crate::output::probes::parse_probes;
use crate::scene::{load_scene_from_path, SceneError};
use clap::{Args, Parser, Subcommand};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

mod bench;
pub use bench::{BenchCommand, SweepArgs, VisibilityArgs};

/// Default limit on triangles per scene (docs/contract.md: 5 million).
pub const DEFAULT_MAX_TRIANGLES: usize = 5_000_000;

#[derive(Parser, Debug)]
#[command(
    name = "wavrad",
    version,
    about = "Wavelet radiosity lightmap baker for glTF scenes"
)]
pub struct Cli {
    /// Log format on stderr.
    #[arg(long, global = true, default_value = "text", value_parser = ["text", "json"])]
    pub log_format: String,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Solve a scene and write result.json, lightmap.exr and convergence.csv.
    Solve(SolveArgs),
    /// Print the planar faces the solver will see.
    Faces(FacesArgs),
    /// Run the HTTP service.
    Serve(ServeArgs),
    /// Benchmarks: measure a part of the solver, or its speed against its accuracy
    /// (benches/README.md).
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Args, Debug)]
pub struct SolveArgs {
    /// The scene (.glb or .gltf; a .gltf's external buffers are read next to it).
    pub scene: PathBuf,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub solver: SolverArgs,
    /// Probe points file (JSON); writes probe_values.json.
    #[arg(long)]
    pub probes: Option<PathBuf>,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
    /// Refuse scenes with more triangles.
    #[arg(long, env = "WAVRAD_MAX_TRIANGLES", default_value_t = DEFAULT_MAX_TRIANGLES)]
    pub max_triangles: usize,
}

/// Solver options, same names as the HTTP job parameters.
#[derive(Args, Debug, Clone)]
pub struct SolverArgs {
    /// Multi-wavelet order: 1 (constant), 2 (linear), 3 (quadratic).
    #[arg(long, default_value_t = 2)]
    pub order: usize,
    /// Extended domains on planar faces, or the tessellated baseline.
    #[arg(long, default_value = "extended", value_parser = ["extended", "tessellated"])]
    pub domain: String,
    /// Stop when unshot power / emitted power <= R.
    #[arg(long, default_value_t = 1e-3)]
    pub target_unshot: f64,
    /// Refinement threshold, as a fraction of the scene's emitted power.
    #[arg(long, default_value_t = crate::solver::DEFAULT_TOLERANCE)]
    pub tolerance: f64,
    /// Wall-time budget in seconds.
    #[arg(long)]
    pub max_seconds: Option<f64>,
    /// Lightmap density (default: chosen from the scene size).
    #[arg(long)]
    pub texels_per_meter: Option<f64>,
    /// What lightmaps and probes hold.
    #[arg(long, default_value = "radiance", value_parser = ["radiance", "irradiance"])]
    pub quantity: String,
    /// Leave out light arriving straight from emitters.
    #[arg(long)]
    pub indirect_only: bool,
    /// Write EXR channels as 32-bit float instead of half.
    #[arg(long)]
    pub exr_float: bool,
    /// Texels of gutter around each atlas rectangle (4 keeps 4 mip levels apart), 0 to 32.
    #[arg(long, default_value_t = crate::output::atlas::DEFAULT_GUTTER)]
    pub gutter: u32,
    /// Largest atlas page side in texels: a multiple of 4 in [256, 16384]; more pages when full.
    #[arg(long, default_value_t = crate::output::atlas::DEFAULT_MAX_PAGE_SIZE)]
    pub atlas_max_size: u32,
    /// Atlas page sides are powers of two.
    #[arg(long)]
    pub atlas_pow2: bool,
}

impl SolverArgs {
    pub fn job_params(&self) -> JobParams {
        JobParams {
            order: self.order,
            domain: if self.domain == "tessellated" {
                DomainMode::Tessellated
            } else {
                DomainMode::Extended
            },
            target_unshot: self.target_unshot,
            tolerance: self.tolerance,
            max_seconds: self.max_seconds,
            texels_per_meter: self.texels_per_meter,
            quantity: if self.quantity == "irradiance" {
                QuantityParam::Irradiance
            } else {
                QuantityParam::Radiance
            },
            indirect_only: self.indirect_only,
            exr_float: self.exr_float,
            gutter: self.gutter,
            atlas_max_size: self.atlas_max_size,
            atlas_pow2: self.atlas_pow2,
        }
    }
}

#[derive(Args, Debug)]
pub struct FacesArgs {
    pub scene: PathBuf,
    /// Print the faces as JSON (docs/contract.md, "faces --json").
    #[arg(long)]
    pub json: bool,
    #[arg(long, env = "WAVRAD_MAX_TRIANGLES", default_value_t = DEFAULT_MAX_TRIANGLES)]
    pub max_triangles: usize,
}

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Address to listen on: HOST:PORT, where HOST is an IP address or a name such as localhost.
    #[arg(long, env = "WAVRAD_ADDR", default_value = "127.0.0.1:8080", value_parser = listen_address)]
    pub addr: std::net::SocketAddr,
    #[arg(long, env = "WAVRAD_DATA_DIR", default_value = "./wavrad-data")]
    pub data_dir: PathBuf,
    /// Jobs solved at once (one job uses every core).
    #[arg(long, env = "WAVRAD_WORKERS", default_value_t = 1)]
    pub workers: usize,
    /// Jobs waiting; beyond it POST answers 429.
    #[arg(long, env = "WAVRAD_MAX_QUEUED", default_value_t = 64)]
    pub max_queued: usize,
    /// Largest request body; beyond it 413.
    #[arg(long, env = "WAVRAD_MAX_BODY_BYTES", default_value_t = 256 * 1024 * 1024)]
    pub max_body_bytes: usize,
    /// Largest scene; beyond it 422.
    #[arg(long, env = "WAVRAD_MAX_TRIANGLES", default_value_t = DEFAULT_MAX_TRIANGLES)]
    pub max_triangles: usize,
    /// Largest estimated solver memory of one job (bytes); beyond it 422.
    #[arg(long, env = "WAVRAD_MAX_MEMORY_BYTES", default_value_t = crate::service::DEFAULT_MAX_MEMORY_BYTES)]
    pub max_memory_bytes: u64,
    /// Longest solve of one job (seconds): caps every job's max_seconds. Default: no cap.
    #[arg(long, env = "WAVRAD_MAX_JOB_SECONDS")]
    pub max_job_seconds: Option<u64>,
    /// Finished jobs kept; beyond N the oldest are deleted with their files. Default: all.
    #[arg(long, env = "WAVRAD_RETAIN_JOBS")]
    pub retain_jobs: Option<usize>,
    /// Bearer token every /v1 route then requires (/healthz and /metrics stay open).
    #[arg(long, env = "WAVRAD_API_TOKEN", hide_env_values = true)]
    pub api_token: Option<String>,
    /// Requests handled at once; beyond it 503.
    #[arg(long, env = "WAVRAD_MAX_IN_FLIGHT", default_value_t = crate::service::DEFAULT_MAX_IN_FLIGHT)]
    pub max_in_flight: usize,
    /// Longest a request may take, upload included (seconds); beyond it 408.
    #[arg(long, env = "WAVRAD_REQUEST_TIMEOUT_SECONDS", default_value_t = crate::service::DEFAULT_REQUEST_TIMEOUT.as_secs())]
    pub request_timeout_seconds: u64,
    /// Scene uploads received and checked at once (bounds their memory); more wait.
    #[arg(long, env = "WAVRAD_MAX_CONCURRENT_UPLOADS", default_value_t = crate::service::DEFAULT_MAX_CONCURRENT_UPLOADS)]
    pub max_concurrent_uploads: usize,
    /// Most recent succeeded (or probed) jobs whose solution stays in memory for
    /// POST /v1/jobs/{id}/probes; others are loaded from their solution.bin first.
    #[arg(long, env = "WAVRAD_PROBE_CACHE_JOBS", default_value_t = crate::service::DEFAULT_PROBE_CACHE_JOBS)]
    pub probe_cache_jobs: usize,
    /// Probe points accepted in one probe request; beyond it 400.
    #[arg(long, env = "WAVRAD_MAX_PROBES", default_value_t = crate::service::DEFAULT_MAX_PROBES)]
    pub max_probes: usize,
    /// Cluster mode: the PostgreSQL holding the jobs and the queue (postgres://...); needs
    /// --object-store. Default: the embedded file store under --data-dir.
    #[arg(long, env = "WAVRAD_DATABASE_URL", hide_env_values = true)]
    pub database_url: Option<String>,
    /// Cluster mode: where uploads and outputs live, s3://BUCKET[/prefix] (AWS_* variables) or
    /// file:///path; needs --database-url.
    #[arg(long, env = "WAVRAD_OBJECT_STORE")]
    pub object_store: Option<String>,
    /// Cluster mode: seconds a replica holds a claimed job without renewing its lease.
    #[arg(long, env = "WAVRAD_LEASE_SECONDS", default_value_t = crate::service::cluster::DEFAULT_LEASE_SECONDS)]
    pub lease_seconds: u64,
    /// Cluster mode: claims of one job that may end without finishing before it is failed.
    #[arg(long, env = "WAVRAD_MAX_ATTEMPTS", default_value_t = crate::service::cluster::DEFAULT_MAX_ATTEMPTS)]
    pub max_attempts: u32,
}

fn init_logging(format: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr);
    if format == "json" {
        let _ = builder.json().try_init();
    } else {
        let _ = builder.try_init();
    }
}

fn bad_input(message: impl std::fmt::Display) -> ExitCode {
    eprintln!("wavrad: {message}");
    ExitCode::from(2)
}

/// Reads and parses an optional input file (`--probes`, `--segments`); an unreadable or invalid
/// file is bad input, reported with its path.
fn read_input_file<T>(
    path: Option<&std::path::Path>,
    parse: impl FnOnce(&[u8]) -> Result<T, String>,
) -> Result<Option<T>, ExitCode> {
    let Some(path) = path else {
        return Ok(None);
    };
    std::fs::read(path)
        .map_err(|e| e.to_string())
        .and_then(|b| parse(&b))
        .map(Some)
        .map_err(|e| bad_input(format!("{}: {e}", path.display())))
}

fn internal(message: impl std::fmt::Display) -> ExitCode {
    eprintln!("wavrad: internal error: {message}");
    ExitCode::from(1)
}

/// Gives the global pool, which runs the CLI's solves, threads with the solver's stack
/// (`solver::SOLVER_STACK_BYTES`), when a thread of that stack can be started at all (a pool
/// that fails to start would leave none); else rayon's default pool serves, with a warning.
fn use_solver_stacks() {
    let stack = crate::solver::SOLVER_STACK_BYTES;
    let startable = std::thread::Builder::new()
        .stack_size(stack)
        .spawn(|| ())
        .is_ok_and(|t| t.join().is_ok());
    let built = startable
        && rayon::ThreadPoolBuilder::new()
            .stack_size(stack)
            .build_global()
            .is_ok();
    if !built {
        tracing::warn!(stack, "the solver's threads keep rayon's default stack");
    }
}

/// Parses the arguments and runs the command; returns the process exit code.
pub fn main_with_args(args: impl IntoIterator<Item = std::ffi::OsString>) -> ExitCode {
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    init_logging(&cli.log_format);
    match cli.command {
        Command::Solve(a) => {
            use_solver_stacks();
            solve(a, &cli.log_format)
        }
        Command::Faces(a) => faces(a),
        Command::Serve(a) => serve(a),
        Command::Bench(BenchCommand::Visibility(a)) => bench::visibility(a),
        Command::Bench(BenchCommand::Sweep(a)) => bench::sweep(a),
    }
}

fn load(path: &std::path::Path, max_triangles: usize) -> Result<crate::scene::Scene, ExitCode> {
    load_scene_from_path(path, max_triangles)
        .map_err(|e: SceneError| bad_input(format!("{}: {e}", path.display())))
}

fn solve(a: SolveArgs, log_format: &str) -> ExitCode {
    let params = a.solver.job_params();
    if let Err(e) = params.validate() {
        return bad_input(e);
    }
    let probes = match read_input_file(a.probes.as_deref(), parse_probes) {
        Ok(p) => p,
        Err(code) => return code,
    };
    let scene = match load(&a.scene, a.max_triangles) {
        Ok(s) => s,
        Err(code) => return code,
    };
    if let Err(e) = check_out_dir(&a.out) {
        return bad_input(e);
    }
    for w in &scene.warnings {
        tracing::warn!("{w}");
    }
    // The bar on a terminal with text logs; otherwise `progress` log events.
    let bar = if std::io::stderr().is_terminal() && log_format == "text" {
        let bar = indicatif::ProgressBar::new(1000);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Some(bar)
    } else {
        None
    };
    let target = params.target_unshot;
    let mut last_log: Option<std::time::Instant> = None;
    let mut observe = |p: &crate::solver::Progress| match &bar {
        Some(bar) => {
            bar.set_position((bar_fraction(p, target) * 1000.0) as u64);
            bar.set_message(progress_message(p));
        }
        None => {
            if last_log.is_none_or(|t| t.elapsed() >= PROGRESS_LOG_INTERVAL) {
                last_log = Some(std::time::Instant::now());
                log_progress(p);
            }
        }
    };
    let cancel = AtomicBool::new(false);
    let outcome = run_job_with_probes(
        &scene,
        &params,
        probes.as_deref(),
        &a.out,
        &cancel,
        &mut observe,
    );
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    match outcome {
        Ok(o) => {
            let stats = &o.result["stats"];
            tracing::info!(
                "solved in {:.2} s: {} shots, {} elements, unshot ratio {:.2e} ({}); outputs in {}",
                stats["seconds"].as_f64().unwrap_or(0.0),
                stats["iterations"],
                stats["elements"],
                stats["unshot_ratio"].as_f64().unwrap_or(0.0),
                o.stop_reason.as_str(),
                a.out.display()
            );
            if a.json {
                let summary = serde_json::json!({"out": a.out, "scene": o.result["scene"], "stats": o.result["stats"],
                    "warnings": o.result["warnings"], "atlas": o.result["atlas"]});
                println!("{summary}");
            }
            ExitCode::SUCCESS
        }
        Err(JobError::Scene(e)) => bad_input(format!("{}: {e}", a.scene.display())),
        Err(e) => internal(e),
    }
}

/// Least time between two `progress` log events of `solve` (docs/contract.md, "Command line").
const PROGRESS_LOG_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);

/// The `progress` log event of `solve` (when there is no bar): the fields a benchmark parses
/// (`tests::the_progress_event_has_its_fields`); `eta_seconds` is absent until known.
fn log_progress(p: &crate::solver::Progress) {
    tracing::info!(
        seconds = p.seconds,
        shots = p.iterations,
        unshot_ratio = p.unshot_ratio,
        shot_receivers_done = p.shot_receivers_done,
        shot_receivers = p.shot_receivers,
        eta_seconds = p.eta_seconds,
        "progress"
    );
}

/// Where the bar stands: the time spent of the time spent plus the ETA when there is one (it
/// moves within a shot), else the unshot ratio on a log scale from 1 down to the target.
fn bar_fraction(p: &crate::solver::Progress, target: f64) -> f64 {
    match p.eta_seconds {
        Some(eta) if eta.is_finite() && p.seconds + eta > 0.0 => p.seconds / (p.seconds + eta),
        _ if p.unshot_ratio > 0.0 => (p.unshot_ratio.ln() / target.ln()).clamp(0.0, 1.0),
        _ => 1.0,
    }
}

/// The bar's message: the shot in progress with its receivers done (or the shots done between
/// two shots), the unshot ratio, the counts and the ETA.
fn progress_message(p: &crate::solver::Progress) -> String {
    let shot = if p.shot_receivers > 0 {
        format!(
            "shot {} ({}/{} receivers)",
            p.iterations + 1,
            p.shot_receivers_done,
            p.shot_receivers
        )
    } else {
        format!("shot {}", p.iterations)
    };
    let eta = match p.eta_seconds {
        Some(e) if e.is_finite() => format!("ETA {}", format_seconds(e)),
        _ => "ETA ?".to_string(),
    };
    format!(
        "{shot} unshot {:.2e} elements {} links {} {eta}",
        p.unshot_ratio, p.elements, p.links
    )
}

/// `1h02m`, `3m05s`, `42s`.
fn format_seconds(s: f64) -> String {
    let s = s.max(0.0).round() as u64;
    if s >= 3600 {
        format!("{}h{:02}m", s / 3600, (s % 3600) / 60)
    } else if s >= 60 {
        format!("{}m{:02}s", s / 60, s % 60)
    } else {
        format!("{s}s")
    }
}

fn faces(a: FacesArgs) -> ExitCode {
    let scene = match load(&a.scene, a.max_triangles) {
        Ok(s) => s,
        Err(code) => return code,
    };
    // Faces and their domains only: no visibility structure is needed to list them.
    let faces = crate::faces::merge_planar_faces(&scene);
    let domains = crate::domain::build_domains(&scene, &faces, crate::domain::DomainMode::Extended);
    match print_faces(&faces, &domains.surfaces, a.json) {
        Ok(()) => ExitCode::SUCCESS,
        // The reader went away (`wavrad faces ... | head`): not an error of ours.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => internal(format!("cannot write to standard output: {e}")),
    }
}

fn print_faces(
    faces: &crate::faces::FaceSet,
    surfaces: &[crate::domain::Surface],
    json: bool,
) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    if json {
        writeln!(out, "{}", crate::output::faces_json(faces, surfaces))?;
        return out.flush();
    }
    for w in &faces.warnings {
        tracing::warn!("{w}");
    }
    writeln!(
        out,
        "{} triangles in, {} degenerate dropped, {} duplicates dropped, {} cut where they overlap, {} back-to-back pairs kept, {} faces out",
        faces.triangles_in,
        faces.degenerate_dropped,
        faces.duplicates_dropped,
        faces.overlaps_cut,
        faces.back_to_back_kept,
        faces.faces.len()
    )?;
    for f in &faces.faces {
        let fill = surfaces
            .iter()
            .find(|s| s.face == f.id)
            .map_or(0.0, |s| s.fill_ratio());
        writeln!(
            out,
            "face {:>6}  material {:>3}  {:<13} area {:.6} m2  fill {:.3}  holes {}  vertices {}  triangles {}",
            f.id.0,
            f.material,
            f.kind.as_str(),
            f.area_m2,
            fill,
            f.holes.len(),
            f.outer.len() + f.holes.iter().map(Vec::len).sum::<usize>(),
            faces.source_triangle_count(f)
        )?;
    }
    out.flush()
}

/// `--addr`: HOST:PORT with HOST an IP address or a name (`localhost:8080`), resolved to its first
/// IPv4 address when it has one (`tests::listen_addresses_accept_names`).
fn listen_address(text: &str) -> Result<std::net::SocketAddr, String> {
    use std::net::ToSocketAddrs;
    let hint = "give HOST:PORT, e.g. 127.0.0.1:8080 or localhost:8080";
    let addrs: Vec<_> = text
        .to_socket_addrs()
        .map_err(|e| format!("{text}: {e}; {hint}"))?
        .collect();
    addrs
        .iter()
        .find(|a| a.is_ipv4())
        .or(addrs.first())
        .copied()
        .ok_or_else(|| format!("{text} resolves to no address; {hint}"))
}

/// `solve --out`: the directory is created and must take a file, checked after the scene loads
/// and before the solve, so a long bake never fails at its end for want of a writable directory
/// (`tests::out_dir_is_checked`).
fn check_out_dir(dir: &std::path::Path) -> Result<(), String> {
    let fail = |e: std::io::Error| {
        format!(
            "--out {}: {e}; give a directory wavrad can create and write",
            dir.display()
        )
    };
    std::fs::create_dir_all(dir).map_err(fail)?;
    let probe = dir.join(format!(".wavrad-write-check.{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(fail)?;
    std::fs::remove_file(&probe).map_err(fail)
}

fn serve(a: ServeArgs) -> ExitCode {
    let mut config = crate::service::ServiceConfig::new(a.data_dir);
    config.workers = a.workers;
    config.max_queued = a.max_queued;
    config.max_body_bytes = a.max_body_bytes;
    config.max_triangles = a.max_triangles;
    config.max_memory_bytes = a.max_memory_bytes;
    config.max_job_seconds = a.max_job_seconds;
    config.retain_jobs = a.retain_jobs;
    config.api_token = a.api_token;
    config.max_in_flight = a.max_in_flight;
    config.request_timeout = std::time::Duration::from_secs(a.request_timeout_seconds);
    config.max_concurrent_uploads = a.max_concurrent_uploads;
    config.probe_cache_jobs = a.probe_cache_jobs;
    config.max_probes = a.max_probes;
    config.cluster = match (a.database_url, a.object_store) {
        (None, None) => None,
        (Some(database_url), Some(object_store)) => {
            let mut cluster =
                crate::service::cluster::ClusterSettings::new(database_url, object_store);
            cluster.lease_seconds = a.lease_seconds;
            cluster.max_attempts = a.max_attempts;
            Some(cluster)
        }
        _ => {
            return bad_input(
                "cluster mode needs both --database-url (WAVRAD_DATABASE_URL) and \
                 --object-store (WAVRAD_OBJECT_STORE)",
            )
        }
    };
    if let Err(e) = config.validate() {
        return bad_input(e);
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => return internal(format!("cannot start the async runtime: {e}")),
    };
    let serve = async {
        let server = crate::service::Server::bind(config, a.addr).await?;
        // The bound address on stdout (machine output): with `--addr 127.0.0.1:0` this is how a
        // script or a test learns the port.
        println!(
            "{}",
            serde_json::json!({"listening": server.local_addr().to_string()})
        );
        server.run().await
    };
    match runtime.block_on(serve) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.kind() == std::io::ErrorKind::InvalidInput => bad_input(e),
        // Another server holds the data directory: the message names it.
        Err(e) if e.kind() == std::io::ErrorKind::ResourceBusy => bad_input(e),
        Err(e) if e.kind() == std::io::ErrorKind::AddrInUse => {
            bad_input(format!("cannot listen on {}: {e}", a.addr))
        }
        Err(e) => internal(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn listen_addresses_accept_names() {
        assert_eq!(
            listen_address("127.0.0.1:8080").unwrap(),
            "127.0.0.1:8080".parse().unwrap()
        );
        let local = listen_address("localhost:8080").unwrap();
        assert!(local.ip().is_loopback() && local.port() == 8080, "{local}");
        let e = listen_address("localhost").unwrap_err();
        assert!(e.contains("HOST:PORT"), "{e}");
        let parsed = Cli::try_parse_from(["wavrad", "serve", "--addr", "localhost:0"]);
        assert!(parsed.is_ok(), "{parsed:?}");
    }

    fn progress(shot_receivers_done: u64, shot_receivers: u64) -> crate::solver::Progress {
        crate::solver::Progress {
            iterations: 3,
            unshot_ratio: 0.25,
            elements: 40,
            links: 100,
            seconds: 30.0,
            shot_receivers_done,
            shot_receivers,
            eta_seconds: Some(90.0),
        }
    }

    /// The bar names the shot in progress with its receivers done, and the ETA; it stands at the
    /// time spent of the whole.
    #[test]
    fn the_bar_shows_the_shot_in_progress_and_the_eta() {
        let within = progress_message(&progress(12, 48));
        assert!(within.starts_with("shot 4 (12/48 receivers)"), "{within}");
        assert!(within.ends_with("ETA 1m30s"), "{within}");
        let between = progress_message(&progress(0, 0));
        assert!(between.starts_with("shot 3 unshot"), "{between}");
        assert_eq!(bar_fraction(&progress(0, 0), 1e-3), 0.25);
        let unknown = crate::solver::Progress {
            eta_seconds: None,
            ..progress(0, 0)
        };
        assert!(progress_message(&unknown).ends_with("ETA ?"));
        let by_ratio = bar_fraction(&unknown, 1e-3);
        assert!((by_ratio - 0.25f64.ln() / 1e-3f64.ln()).abs() < 1e-12);
        assert_eq!(format_seconds(3725.0), "1h02m");
        assert_eq!(format_seconds(42.4), "42s");
    }

    #[test]
    fn out_dir_is_checked() {
        let base = std::env::temp_dir().join(format!("wavrad-out-check-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let nested = base.join("a/b");
        check_out_dir(&nested).expect("created");
        assert!(nested.is_dir());
        assert_eq!(
            std::fs::read_dir(&nested).unwrap().count(),
            0,
            "no probe file left"
        );
        // A path under a regular file cannot be a directory: refused, naming the path.
        let file = base.join("file");
        std::fs::write(&file, b"x").unwrap();
        let e = check_out_dir(&file.join("out")).unwrap_err();
        assert!(e.contains("--out") && e.contains("file/out"), "{e}");
        let _ = std::fs::remove_dir_all(&base);
    }

    /// Every option of `wavrad serve` (every limit is one) is documented in the README.
    #[test]
    fn every_serve_option_is_in_the_readme() {
        let readme = include_str!("../README.md");
        let command = Cli::command();
        let serve = command
            .find_subcommand("serve")
            .expect("a serve subcommand");
        let mut checked = 0;
        for arg in serve.get_arguments() {
            let Some(long) = arg.get_long() else {
                continue;
            };
            if long == "help" {
                continue;
            }
            assert!(
                readme.contains(&format!("`--{long}")),
                "--{long} is not documented in README.md"
            );
            if let Some(env) = arg.get_env() {
                let env = env.to_string_lossy();
                let name = format!("WAVRAD_{}", long.replace('-', "_").to_uppercase());
                assert_eq!(env, name.as_str(), "--{long} reads WAVRAD_<NAME>");
            }
            checked += 1;
        }
        assert!(checked >= 12, "{checked} options");
    }
}
