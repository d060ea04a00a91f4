//! `wavrad bench sweep` (issue 19): for each data set (a Monte Carlo reference set or a CIE case,
//! `reference::DataSet`), a grid of tolerance x order x domain mode, each solve in its own
//! `wavrad solve` process (so `peak_memory_bytes` is that solve's own), scored against the set's
//! values; writes `bench.csv`, `ratios.csv`, `bench.svg` (`chart.rs`) and keeps each solve's
//! `result.json`, `convergence.csv` and `probe_values.json` under `runs/`. `benches/accuracy.rs`
//! runs the same sweep ([`run`]).
//!
//! Owns the default grid ([`DEFAULT_SCENES`], [`DEFAULT_TOLERANCES`]), the per-solve cap (the
//! solve's own `--max-seconds`, and a kill after [`kill_after`]) and reading a solve's files back
//! into a [`Row`]; what is reported from the rows (CSV, ratios, chart data) is `sweep_report.rs`.
//! Invariants: tolerances run loosest first; a solve stopped by
//! the cap is recorded in the CSV but drawn in no line and used in no ratio, and the tighter
//! tolerances of its order and mode are left out; everything left out of the full grid (orders
//! 1..3 x [`DEFAULT_TOLERANCES`] x both modes) is listed with its reason. Pinned by
//! `tests/bench_sweep.rs`.

use super::chart;
pub use super::sweep_report::{
    csv_line, mode_ratio, summary, table_line, time_to_reach, Ratio, Report, Row, CSV_HEADER,
};
use super::sweep_report::{ratios_of, scene_plot};
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

/// The kill deadline of one solve capped at `max_seconds` of solving: loading, preparation and
/// export are outside the solve's own budget.
pub fn kill_after(max_seconds: f64) -> Duration {
    Duration::from_secs_f64(3.0 * max_seconds + 60.0)
}

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
