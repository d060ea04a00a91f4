//! `wavrad bench sweep` (issue 19): for each data set (a Monte Carlo reference set or a CIE case,
//! `reference::DataSet`), a grid of tolerance x order x domain mode, each solve in its own
//! `wavrad solve` process (so `peak_memory_bytes` is that solve's own), scored against the set's
//! values; writes `bench.csv`, `ratios.csv`, `bench.svg` (`chart.rs`) and keeps each solve's
//! `result.json`, `convergence.csv` and `probe_values.json` under `runs/`. `benches/accuracy.rs`
//! runs the same sweep ([`run`]).
//!
//! Owns the default grid ([`DEFAULT_SCENES`], [`DEFAULT_TOLERANCES`]), the per-solve cap (the
//! solve's own `--max-seconds`, and a kill after [`kill_after`]), and the time-to-error ratio
//! ([`time_to_reach`], [`mode_ratio`]). Invariants: tolerances run loosest first; a solve stopped by
//! the cap is recorded in the CSV but drawn in no line and used in no ratio, and the tighter
//! tolerances of its order and mode are left out; everything left out of the full grid (orders
//! 1..3 x [`DEFAULT_TOLERANCES`] x both modes) is listed with its reason. Pinned by
//! `tests/bench_sweep.rs` and this file's unit tests.

use super::chart::{self, Curve, ScenePlot};
use crate::output::probes::ProbeValue;
use crate::reference::{read_json, DataSet};
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The tolerance sweep of the default grid, loosest first.
pub const DEFAULT_TOLERANCES: [f64; 5] = [1e-4, 3e-5, 1e-5, 3e-6, 1e-6];
/// Every order the solver has.
pub const ORDERS: [usize; 3] = [1, 2, 3];
/// Both domain modes.
pub const MODES: [&str; 2] = ["extended", "tessellated"];
/// Default cap on one solve's seconds (its `--max-seconds`).
pub const DEFAULT_MAX_SECONDS: f64 = 300.0;
/// The lightmap density of the sweep's solves: their lightmaps are not kept, and the atlas never
/// changes a solution, so a coarse one keeps each process's export short.
pub const SWEEP_TEXELS_PER_METER: f64 = 4.0;

/// A default scene and the part of the full grid it runs.
pub struct DefaultScene {
    /// A folder name under `tests/data/reference/` or `tests/data/cie171/`.
    pub name: &'static str,
    pub orders: &'static [usize],
    pub tolerances: &'static [f64],
}

/// The default scenes. The Red Eclipse level runs at M2 and two tolerances only (its tessellated
/// mode shoots thousands of roots), so that the grid's CPU time stays within 20 minutes.
pub const DEFAULT_SCENES: [DefaultScene; 4] = [
    DefaultScene {
        name: "cornell_box",
        orders: &ORDERS,
        tolerances: &DEFAULT_TOLERANCES,
    },
    DefaultScene {
        name: "5.3_area_source",
        orders: &ORDERS,
        tolerances: &DEFAULT_TOLERANCES,
    },
    DefaultScene {
        name: "kenney_building_small_c_lit",
        orders: &ORDERS,
        tolerances: &DEFAULT_TOLERANCES,
    },
    DefaultScene {
        name: "redeclipse_dutility_lit",
        orders: &[2],
        tolerances: &[1e-4, 1e-5],
    },
];

/// What to sweep. `None` grids mean each scene's default (the full grid for scenes not listed in
/// [`DEFAULT_SCENES`]).
#[derive(Debug, Clone)]
pub struct SweepOptions {
    /// Data set folders, or names under `repo/tests/data/{reference,cie171}/` (a trailing `.glb`
    /// or `.gltf` is dropped); empty: [`DEFAULT_SCENES`].
    pub scenes: Vec<String>,
    pub out: PathBuf,
    pub orders: Option<Vec<usize>>,
    pub tolerances: Option<Vec<f64>>,
    pub modes: Option<Vec<String>>,
    /// Cap on one solve's seconds.
    pub max_seconds: f64,
    /// The `wavrad` binary to run `solve` with.
    pub exe: PathBuf,
    /// The repository root (for `tests/data/` and the reference sets' scenes).
    pub repo: PathBuf,
    /// Read back the solves already in `out/runs/` instead of running them again.
    pub resume: bool,
}

/// One solve of the sweep.
#[derive(Debug, Clone)]
pub struct Row {
    pub scene: String,
    pub order: usize,
    pub domain: String,
    pub tolerance: f64,
    /// The solve alone (result.json `stats.seconds`).
    pub seconds: f64,
    /// The whole process: loading, preparation, solve and export.
    pub wall_seconds: f64,
    /// The process's CPU time (user + system, all threads; [`children_cpu_seconds`]); `NaN` when
    /// unknown (a run of an older sweep read back by `--resume`).
    pub cpu_seconds: f64,
    pub shots: u64,
    pub elements: u64,
    pub links: u64,
    pub peak_memory_bytes: u64,
    pub rays: u64,
    pub unshot_ratio: f64,
    pub stop_reason: String,
    pub extended_faces: u64,
    /// `NaN` when a probe found no surface.
    pub nrms: f64,
    pub worst: f64,
    pub worst_label: String,
    /// `(seconds, unshot_ratio)` per shot, from convergence.csv.
    pub convergence: Vec<(f64, f64)>,
}

impl Row {
    /// Stopped by the per-solve cap.
    pub fn capped(&self) -> bool {
        self.stop_reason != "converged"
    }
}

/// The extended-to-tessellated time ratio of one scene and order at the tightest error both
/// modes reach.
#[derive(Debug, Clone, PartialEq)]
pub struct Ratio {
    pub scene: String,
    pub order: usize,
    pub extended_faces: u64,
    pub error: f64,
    pub extended_seconds: f64,
    pub tessellated_seconds: f64,
}

impl Ratio {
    pub fn ratio(&self) -> f64 {
        self.extended_seconds / self.tessellated_seconds
    }
}

/// What a sweep did.
#[derive(Debug, Clone, Default)]
pub struct Report {
    pub rows: Vec<Row>,
    pub left_out: Vec<String>,
    pub ratios: Vec<Ratio>,
    /// The sweep's wall seconds, from its start to its chart.
    pub wall_seconds: f64,
    /// The CPU seconds of the sweep's own process and of every solve in `rows` (those read back
    /// by `--resume` too): what the grid takes at most on an idle machine
    /// ([`children_cpu_seconds`]).
    pub cpu_seconds: f64,
    /// Rows whose CPU time is unknown (read back from an older sweep), left out of `cpu_seconds`.
    pub cpu_unknown: usize,
}

/// The CSV columns, in order.
pub const CSV_HEADER: &str = "scene,order,domain,tolerance,seconds,wall_seconds,shots,elements,links,peak_memory_bytes,rays,unshot_ratio,stop_reason,extended_faces,nrms,worst_point,worst_label,cpu_seconds";

/// The kill deadline of one solve capped at `max_seconds` of solving: loading, preparation and
/// export are outside the solve's own budget.
pub fn kill_after(max_seconds: f64) -> Duration {
    Duration::from_secs_f64(3.0 * max_seconds + 60.0)
}

/// The time a curve of `(seconds, error)` points first reaches `error`, interpolated linearly in
/// log-log between the two solves around it, on the curve's lower envelope (the best error reached
/// by each time); the first solve's time when it is already there; `None` when it never is.
pub fn time_to_reach(points: &[(f64, f64)], error: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|&(t, e)| t > 0.0 && e > 0.0 && t.is_finite() && e.is_finite())
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best: Option<(f64, f64)> = None;
    for (t, e) in pts {
        match best {
            None if e <= error => return Some(t),
            None => best = Some((t, e)),
            Some((t0, e0)) if e <= error => {
                let f = (error.ln() - e0.ln()) / (e.ln() - e0.ln());
                return Some((t0.ln() + f * (t.ln() - t0.ln())).exp());
            }
            Some((_, e0)) if e < e0 => best = Some((t, e)),
            Some(_) => {}
        }
    }
    None
}

/// The ratio of extended to tessellated time to reach the tightest error both curves reach
/// (`(seconds, error)` points each); `None` when either is empty.
pub fn mode_ratio(extended: &[(f64, f64)], tessellated: &[(f64, f64)]) -> Option<(f64, f64, f64)> {
    let min = |c: &[(f64, f64)]| {
        c.iter()
            .map(|p| p.1)
            .filter(|e| e.is_finite() && *e > 0.0)
            .fold(f64::INFINITY, f64::min)
    };
    let error = min(extended).max(min(tessellated));
    if !error.is_finite() {
        return None;
    }
    Some((
        error,
        time_to_reach(extended, error)?,
        time_to_reach(tessellated, error)?,
    ))
}

/// The data set a SCENE argument names.
pub fn resolve(scene: &str, repo: &Path) -> Result<DataSet, String> {
    let direct = Path::new(scene);
    if direct.is_dir() {
        return DataSet::open(direct, repo);
    }
    let name = scene
        .strip_suffix(".glb")
        .or_else(|| scene.strip_suffix(".gltf"))
        .unwrap_or(scene);
    let data = repo.join("tests/data");
    for dir in [
        data.join("reference").join(name),
        data.join("cie171").join(name),
        data.join(name),
    ] {
        if dir.is_dir() {
            return DataSet::open(&dir, repo);
        }
    }
    Err(format!(
        "{scene}: no such data set (a folder with reference.json or expected.json, or a name under {}/reference or {}/cie171)",
        data.display(),
        data.display()
    ))
}

/// The grid one scene runs: the options' when given, else its default.
fn grid_of(name: &str, o: &SweepOptions) -> (Vec<usize>, Vec<f64>, Vec<String>) {
    let default = DEFAULT_SCENES.iter().find(|d| d.name == name);
    let orders = o
        .orders
        .clone()
        .unwrap_or_else(|| default.map_or(ORDERS.to_vec(), |d| d.orders.to_vec()));
    let mut tolerances = o
        .tolerances
        .clone()
        .unwrap_or_else(|| default.map_or(DEFAULT_TOLERANCES.to_vec(), |d| d.tolerances.to_vec()));
    tolerances.sort_by(|a, b| b.total_cmp(a));
    let modes = o
        .modes
        .clone()
        .unwrap_or_else(|| MODES.iter().map(|m| m.to_string()).collect());
    (orders, tolerances, modes)
}

fn read_convergence(path: &Path) -> Vec<(f64, f64)> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    text.lines()
        .skip(1)
        .filter_map(|line| {
            let mut f = line.split(',').map(|v| v.trim().parse::<f64>());
            Some((f.next()?.ok()?, f.next()?.ok()?))
        })
        .collect()
}

/// The process's wall seconds, beside a solve's outputs.
const WALL_FILE: &str = "wall_seconds";
/// The process's CPU seconds, beside a solve's outputs.
const CPU_FILE: &str = "cpu_seconds";

/// The CPU time (user + system) of this process's waited-for children so far, in seconds
/// (`getrusage(RUSAGE_CHILDREN)`); `NaN` where the call fails. A solve's CPU time is the
/// difference around its wait. On a machine with nothing else running, a sequence of processes
/// takes at most its CPU time in wall time (each has at least one core whenever it can run),
/// so the sweep's CPU total bounds its idle wall time whatever the load it was measured under.
pub fn children_cpu_seconds() -> f64 {
    cpu_seconds_of(libc::RUSAGE_CHILDREN)
}

/// `getrusage(who)`'s user + system seconds; `NaN` where the call fails.
fn cpu_seconds_of(who: libc::c_int) -> f64 {
    // SAFETY: `getrusage` writes one `rusage` into memory we own and reads nothing else.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let ok = unsafe { libc::getrusage(who, &mut usage) } == 0;
    if !ok {
        return f64::NAN;
    }
    let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    seconds(usage.ru_utime) + seconds(usage.ru_stime)
}

/// Files of a solve's output that the sweep keeps.
const KEPT: [&str; 6] = [
    "result.json",
    "convergence.csv",
    "probe_values.json",
    "solve.log",
    WALL_FILE,
    CPU_FILE,
];

/// One cell of the grid and the folder its solve writes into.
struct Cell<'a> {
    set: &'a DataSet,
    order: usize,
    domain: &'a str,
    tolerance: f64,
    dir: PathBuf,
}

/// Runs one `wavrad solve` in its own process into the cell's folder and reads what it wrote.
fn solve_once(o: &SweepOptions, cell: &Cell) -> Result<Row, String> {
    let (set, dir) = (cell.set, &cell.dir);
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let log = std::fs::File::create(dir.join("solve.log")).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let cpu_before = children_cpu_seconds();
    let mut child = Command::new(&o.exe)
        .args(["--log-format", "json", "solve"])
        .arg(&set.scene)
        .arg("--out")
        .arg(dir)
        .args(["--order", &cell.order.to_string(), "--domain", cell.domain])
        .args(["--tolerance", &cell.tolerance.to_string()])
        .args(["--max-seconds", &o.max_seconds.to_string()])
        .args(["--texels-per-meter", &SWEEP_TEXELS_PER_METER.to_string()])
        .args([
            "--quantity",
            if set.irradiance {
                "irradiance"
            } else {
                "radiance"
            },
        ])
        .arg("--probes")
        .arg(&set.probes)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(log)
        .spawn()
        .map_err(|e| format!("{}: {e}", o.exe.display()))?;
    let deadline = kill_after(o.max_seconds);
    let status = loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            break status;
        }
        if start.elapsed() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("killed after {:.0} s", deadline.as_secs_f64()));
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let wall_seconds = start.elapsed().as_secs_f64();
    let cpu_seconds = children_cpu_seconds() - cpu_before;
    if !status.success() {
        return Err(format!(
            "the solve failed ({status}); see {}",
            dir.join("solve.log").display()
        ));
    }
    write(&dir.join(WALL_FILE), &format!("{wall_seconds}\n"))?;
    write(&dir.join(CPU_FILE), &format!("{cpu_seconds}\n"))?;
    // Lightmaps, pictures and solution.bin are large and unused here.
    if let Ok(entries) = std::fs::read_dir(dir) {
        for entry in entries.flatten() {
            let name = entry.file_name();
            if !KEPT.iter().any(|k| name == *k) {
                let path = entry.path();
                let _ = std::fs::remove_file(&path).or_else(|_| std::fs::remove_dir_all(&path));
            }
        }
    }
    read_run(cell)
}

/// Reads a finished solve of the sweep back from its folder.
fn read_run(cell: &Cell) -> Result<Row, String> {
    let Cell {
        set,
        order,
        domain,
        tolerance,
        ref dir,
    } = *cell;
    let number = |file: &str| {
        std::fs::read_to_string(dir.join(file))
            .ok()
            .and_then(|t| t.trim().parse().ok())
            .unwrap_or(f64::NAN)
    };
    let (wall_seconds, cpu_seconds) = (number(WALL_FILE), number(CPU_FILE));
    let result: Value = read_json(&dir.join("result.json"))?;
    let values: Vec<ProbeValue> = read_json(&dir.join("probe_values.json"))?;
    let score = set.score(&values);
    let s = &result["stats"];
    let int = |k: &str| s[k].as_u64().unwrap_or(0);
    Ok(Row {
        scene: set.name.clone(),
        order,
        domain: domain.to_string(),
        tolerance,
        seconds: s["seconds"].as_f64().unwrap_or(f64::NAN),
        wall_seconds,
        cpu_seconds,
        shots: int("iterations"),
        elements: int("elements"),
        links: int("links"),
        peak_memory_bytes: int("peak_memory_bytes"),
        rays: int("rays"),
        unshot_ratio: s["unshot_ratio"].as_f64().unwrap_or(f64::NAN),
        stop_reason: s["stop_reason"].as_str().unwrap_or("unknown").to_string(),
        extended_faces: int("extended_faces"),
        nrms: score.as_ref().map_or(f64::NAN, |s| s.nrms),
        worst: score.as_ref().map_or(f64::NAN, |s| s.worst),
        worst_label: score.map_or_else(|| "no surface".into(), |s| s.worst_label),
        convergence: read_convergence(&dir.join("convergence.csv")),
    })
}

/// One CSV line (no newline).
pub fn csv_line(r: &Row) -> String {
    format!(
        "{},{},{},{:e},{:.4},{:.3},{},{},{},{},{},{:e},{},{},{:.6},{:.6},{},{:.3}",
        r.scene,
        r.order,
        r.domain,
        r.tolerance,
        r.seconds,
        r.wall_seconds,
        r.shots,
        r.elements,
        r.links,
        r.peak_memory_bytes,
        r.rays,
        r.unshot_ratio,
        r.stop_reason,
        r.extended_faces,
        r.nrms,
        r.worst,
        r.worst_label.replace(',', ";"),
        r.cpu_seconds,
    )
}

/// The table line printed as each solve finishes.
pub fn table_line(r: &Row) -> String {
    format!(
        "{:<28} M{} {:<11} {:>7.0e} {:>8.2} s {:>8} el {:>6} MB  nrms {:>6.2} %  worst {:>6.2} % ({}){}",
        r.scene,
        r.order,
        r.domain,
        r.tolerance,
        r.seconds,
        r.elements,
        r.peak_memory_bytes / 1_000_000,
        r.nrms * 100.0,
        r.worst * 100.0,
        r.worst_label,
        if r.capped() {
            format!("  [{}]", r.stop_reason)
        } else {
            String::new()
        }
    )
}

fn curve_label(order: usize, domain: &str) -> String {
    format!("M{order} {domain}")
}

/// The tolerance of a scene's convergence panel: the one nearest the solver's default (in log)
/// among those that the most modes solved within the cap, at order 2 when it ran (else the lowest
/// order run).
fn convergence_pick(rows: &[&Row]) -> Option<(usize, f64)> {
    let order = if rows.iter().any(|r| r.order == 2) {
        2
    } else {
        rows.iter().map(|r| r.order).min()?
    };
    let default = crate::solver::DEFAULT_TOLERANCE.ln();
    let modes = |t: f64| {
        rows.iter()
            .filter(|r| r.order == order && r.tolerance == t && !r.capped())
            .count()
    };
    let most = rows.iter().map(|r| modes(r.tolerance)).max()?;
    rows.iter()
        .filter(|r| r.order == order && !r.capped() && !r.convergence.is_empty())
        .filter(|r| modes(r.tolerance) == most)
        .map(|r| r.tolerance)
        .min_by(|a, b| {
            (a.ln() - default)
                .abs()
                .total_cmp(&(b.ln() - default).abs())
        })
        .map(|t| (order, t))
}

/// The chart's data for one scene.
fn scene_plot(name: &str, rows: &[&Row]) -> ScenePlot {
    let mut error = Vec::new();
    for order in ORDERS {
        for domain in MODES {
            let points: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.order == order && r.domain == domain && !r.capped())
                .map(|r| (r.seconds, r.nrms * 100.0))
                .collect();
            if !points.is_empty() {
                error.push(Curve {
                    label: curve_label(order, domain),
                    order,
                    extended: domain == "extended",
                    points,
                });
            }
        }
    }
    let (mut convergence, mut convergence_tolerance) = (Vec::new(), f64::NAN);
    if let Some((order, tolerance)) = convergence_pick(rows) {
        convergence_tolerance = tolerance;
        for r in rows
            .iter()
            .filter(|r| r.order == order && r.tolerance == tolerance)
        {
            convergence.push(Curve {
                label: curve_label(order, &r.domain),
                order,
                extended: r.domain == "extended",
                points: r.convergence.clone(),
            });
        }
    }
    ScenePlot {
        name: name.to_string(),
        error,
        convergence,
        convergence_tolerance,
    }
}

fn ratios_of(name: &str, rows: &[&Row]) -> Vec<Ratio> {
    let curve = |order: usize, domain: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .filter(|r| r.order == order && r.domain == domain && !r.capped())
            .map(|r| (r.seconds, r.nrms))
            .collect()
    };
    let extended_faces = rows.iter().map(|r| r.extended_faces).max().unwrap_or(0);
    ORDERS
        .iter()
        .filter_map(|&order| {
            let (error, extended_seconds, tessellated_seconds) =
                mode_ratio(&curve(order, "extended"), &curve(order, "tessellated"))?;
            Some(Ratio {
                scene: name.to_string(),
                order,
                extended_faces,
                error,
                extended_seconds,
                tessellated_seconds,
            })
        })
        .collect()
}

fn write(path: &Path, text: &str) -> Result<(), String> {
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Checks the options before anything runs.
fn check(o: &SweepOptions) -> Result<(), String> {
    if let Some(orders) = &o.orders {
        if orders.is_empty() || orders.iter().any(|k| !ORDERS.contains(k)) {
            return Err(format!("--orders: each of 1, 2, 3 (got {orders:?})"));
        }
    }
    if let Some(t) = &o.tolerances {
        if t.is_empty() || t.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
            return Err(format!("--tolerances: positive numbers (got {t:?})"));
        }
    }
    if let Some(m) = &o.modes {
        if m.is_empty() || m.iter().any(|m| !MODES.contains(&m.as_str())) {
            return Err(format!("--modes: extended and/or tessellated (got {m:?})"));
        }
    }
    if !(o.max_seconds.is_finite() && o.max_seconds > 0.0) {
        return Err(format!(
            "--max-seconds: a positive number (got {})",
            o.max_seconds
        ));
    }
    Ok(())
}

/// Runs the sweep, calling `say` with each line of progress, and writes the outputs.
pub fn run(o: &SweepOptions, say: &mut dyn FnMut(&str)) -> Result<Report, String> {
    check(o)?;
    let start = Instant::now();
    let names: Vec<String> = if o.scenes.is_empty() {
        DEFAULT_SCENES.iter().map(|d| d.name.to_string()).collect()
    } else {
        o.scenes.clone()
    };
    let sets = names
        .iter()
        .map(|n| resolve(n, &o.repo))
        .collect::<Result<Vec<_>, _>>()?;
    std::fs::create_dir_all(&o.out).map_err(|e| format!("{}: {e}", o.out.display()))?;
    let mut report = Report::default();
    for set in &sets {
        let (orders, tolerances, modes) = grid_of(&set.name, o);
        for order in ORDERS.into_iter().filter(|k| !orders.contains(k)) {
            report
                .left_out
                .push(format!("{}: M{order} (not in the grid)", set.name));
        }
        let tight = DEFAULT_TOLERANCES
            .iter()
            .filter(|t| !tolerances.contains(t))
            .map(|t| format!("{t:e}"))
            .collect::<Vec<_>>();
        if !tight.is_empty() {
            report.left_out.push(format!(
                "{}: tolerances {} (not in the grid)",
                set.name,
                tight.join(", ")
            ));
        }
        for mode in MODES.iter().filter(|m| !modes.iter().any(|n| n == *m)) {
            report
                .left_out
                .push(format!("{}: {mode} (not in the grid)", set.name));
        }
        for &order in &orders {
            for domain in &modes {
                let mut capped_at: Option<f64> = None;
                for &tolerance in &tolerances {
                    if let Some(at) = capped_at {
                        report.left_out.push(format!(
                            "{} M{order} {domain} {tolerance:e}: the {at:e} solve hit the {} s cap",
                            set.name, o.max_seconds
                        ));
                        continue;
                    }
                    let cell = Cell {
                        set,
                        order,
                        domain,
                        tolerance,
                        dir: o
                            .out
                            .join("runs")
                            .join(&set.name)
                            .join(format!("M{order}-{domain}-{tolerance:e}")),
                    };
                    let done = o.resume
                        && cell.dir.join("result.json").exists()
                        && cell.dir.join("probe_values.json").exists();
                    let outcome = if done {
                        read_run(&cell)
                    } else {
                        solve_once(o, &cell)
                    };
                    match outcome {
                        Ok(row) => {
                            say(&table_line(&row));
                            if row.capped() {
                                capped_at = Some(tolerance);
                            }
                            report.rows.push(row);
                        }
                        Err(e) => {
                            let line = format!("{} M{order} {domain} {tolerance:e}: {e}", set.name);
                            say(&line);
                            report.left_out.push(line);
                            capped_at = Some(tolerance);
                        }
                    }
                }
            }
        }
    }
    let mut plots = Vec::new();
    for set in &sets {
        let rows: Vec<&Row> = report.rows.iter().filter(|r| r.scene == set.name).collect();
        plots.push(scene_plot(&set.name, &rows));
        report.ratios.extend(ratios_of(&set.name, &rows));
    }
    let mut csv = String::from(CSV_HEADER);
    csv.push('\n');
    for r in &report.rows {
        csv += &csv_line(r);
        csv.push('\n');
    }
    write(&o.out.join("bench.csv"), &csv)?;
    let mut ratios = String::from(
        "scene,order,extended_faces,error,extended_seconds,tessellated_seconds,ratio\n",
    );
    for r in &report.ratios {
        let _ = writeln!(
            ratios,
            "{},{},{},{:.6},{:.4},{:.4},{:.3}",
            r.scene,
            r.order,
            r.extended_faces,
            r.error,
            r.extended_seconds,
            r.tessellated_seconds,
            r.ratio()
        );
    }
    write(&o.out.join("ratios.csv"), &ratios)?;
    chart::draw(&o.out.join("bench.svg"), &plots)?;
    report.wall_seconds = start.elapsed().as_secs_f64();
    let known = report.rows.iter().filter(|r| r.cpu_seconds.is_finite());
    report.cpu_seconds =
        cpu_seconds_of(libc::RUSAGE_SELF) + known.map(|r| r.cpu_seconds).sum::<f64>();
    report.cpu_unknown = report
        .rows
        .iter()
        .filter(|r| !r.cpu_seconds.is_finite())
        .count();
    Ok(report)
}

/// The closing summary: the ratios and what was left out.
pub fn summary(report: &Report) -> String {
    let mut s = format!(
        "sweep: {} solves, {:.0} s wall, {:.0} s CPU (the sweep's process and its solves; on an \
         idle machine the sweep takes at most its CPU time){}\n",
        report.rows.len(),
        report.wall_seconds,
        report.cpu_seconds,
        if report.cpu_unknown > 0 {
            format!("; CPU time unknown for {} solves", report.cpu_unknown)
        } else {
            String::new()
        }
    );
    for r in &report.ratios {
        let _ = writeln!(
            s,
            "{} M{}: extended / tessellated time to {:.2} % nrms = {:.2} s / {:.2} s = {:.2}{}",
            r.scene,
            r.order,
            r.error * 100.0,
            r.extended_seconds,
            r.tessellated_seconds,
            r.ratio(),
            if r.extended_faces == 0 {
                " (no extended face: both modes solve the same roots)"
            } else {
                ""
            }
        );
    }
    if report.left_out.is_empty() {
        s += "left out: nothing\n";
    } else {
        s += "left out:\n";
        for l in &report.left_out {
            let _ = writeln!(s, "  {l}");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_to_reach_interpolates_in_log_log_on_the_lower_envelope() {
        // Error 10 % at 1 s, 1 % at 100 s: 1e-1.5 is reached half way in log time, at 10 s.
        let t = time_to_reach(&[(1.0, 0.1), (100.0, 0.01)], 0.1f64.powf(1.5)).expect("reached");
        assert!((t - 10.0).abs() < 1e-9, "{t}");
        // Already reached by the first solve.
        assert_eq!(time_to_reach(&[(2.0, 0.01), (5.0, 0.001)], 0.05), Some(2.0));
        // Never reached.
        assert_eq!(time_to_reach(&[(2.0, 0.01), (5.0, 0.02)], 0.005), None);
        // A worse later solve does not set the envelope: interpolation starts from the best one.
        let t = time_to_reach(&[(1.0, 0.1), (2.0, 0.2), (100.0, 0.001)], 0.01).expect("reached");
        assert!((t - 10.0).abs() < 1e-9, "{t}");
    }

    #[test]
    fn mode_ratio_is_taken_at_the_tightest_error_both_reach() {
        let extended = [(1.0, 0.1), (10.0, 0.01)];
        let tessellated = [(2.0, 0.1), (20.0, 0.02)];
        let (error, te, tt) = mode_ratio(&extended, &tessellated).expect("both reach 2 %");
        assert_eq!(error, 0.02);
        assert!((tt - 20.0).abs() < 1e-9, "{tt}");
        assert!(te < 10.0 && te > 1.0);
        assert_eq!(mode_ratio(&extended, &[]), None);
    }
}
