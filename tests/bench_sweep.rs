//! `wavrad bench sweep` (issue 19) on a small grid: one tiny data set (`cube_onelight`), two
//! tolerances, one order, both modes, each solve its own process. It writes `bench.csv` with the
//! documented columns and one row per solve, `ratios.csv`, and a `bench.svg` that parses as XML
//! with both panels of the scene and a drawn line in each; it prints what it left out of the full
//! grid and its wall and CPU seconds; bad grid options exit 2 with a reason.

use std::process::Command;
use wavrad::bench::sweep::CSV_HEADER;

fn wavrad() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_wavrad"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

#[test]
fn a_small_sweep_writes_the_csv_and_the_chart() {
    let out = std::env::temp_dir().join(format!("wavrad-bench-sweep-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let run = wavrad()
        .args(["bench", "sweep", "cube_onelight", "--out"])
        .arg(&out)
        .args(["--orders", "1", "--tolerances", "1e-3,1e-4"])
        .output()
        .expect("wavrad runs");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        stdout.contains("cube_onelight: M2 (not in the grid)"),
        "{stdout}"
    );
    assert!(
        stdout.contains("cube_onelight: M3 (not in the grid)"),
        "{stdout}"
    );

    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("sweep: 4 solves,") && l.contains(" s CPU")),
        "{stdout}"
    );

    let csv = std::fs::read_to_string(out.join("bench.csv")).expect("bench.csv");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    for column in [
        "scene",
        "order",
        "domain",
        "tolerance",
        "seconds",
        "shots",
        "elements",
        "links",
        "peak_memory_bytes",
        "rays",
        "unshot_ratio",
        "nrms",
        "worst_point",
        "wall_seconds",
        "cpu_seconds",
    ] {
        assert!(header.contains(&column), "no column {column} in {header:?}");
    }
    assert_eq!(header.join(","), CSV_HEADER);
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 4, "2 tolerances x 2 modes: {csv}");
    let col = |name: &str| header.iter().position(|h| *h == name).expect("column");
    for row in &rows {
        assert_eq!(row.len(), header.len(), "{row:?}");
        assert_eq!(row[col("scene")], "cube_onelight");
        assert_eq!(row[col("order")], "1");
        let num = |name: &str| row[col(name)].parse::<f64>().expect("a number");
        assert!(num("shots") >= 1.0 && num("elements") >= 6.0 && num("rays") > 0.0);
        assert!(num("peak_memory_bytes") > 1e6, "{row:?}");
        // CPU time of the solve's process: some, and no more than its wall time on every core.
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
        let (cpu, wall) = (num("cpu_seconds"), num("wall_seconds"));
        assert!(cpu > 0.0 && cpu <= wall * cores + 0.1, "{row:?}");
        assert!(num("unshot_ratio") <= 1e-3, "{row:?}");
        // The cube's reference: a solve at these tolerances is within a few percent.
        let nrms = num("nrms");
        assert!(nrms > 0.0 && nrms < 0.1, "nrms {nrms}: {row:?}");
        assert!(num("worst_point") >= nrms / 2.0, "{row:?}");
    }
    let modes: Vec<&str> = rows.iter().map(|r| r[col("domain")]).collect();
    assert_eq!(modes.iter().filter(|m| **m == "extended").count(), 2);
    assert_eq!(modes.iter().filter(|m| **m == "tessellated").count(), 2);
    let ratios = std::fs::read_to_string(out.join("ratios.csv")).expect("ratios.csv");
    assert!(
        ratios
            .lines()
            .nth(1)
            .is_some_and(|l| l.starts_with("cube_onelight,1,")),
        "{ratios}"
    );
    let kept = out.join("runs/cube_onelight/M1-extended-1e-3");
    assert!(kept.join("convergence.csv").exists() && kept.join("result.json").exists());
    assert!(
        !kept.join("lightmap.exr").exists(),
        "large outputs are removed"
    );

    let svg = std::fs::read_to_string(out.join("bench.svg")).expect("bench.svg");
    let doc = roxmltree::Document::parse(&svg).expect("the SVG is XML");
    assert_eq!(doc.root_element().tag_name().name(), "svg");
    let texts: Vec<String> = doc
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .map(|n| n.text().unwrap_or_default().trim().to_string())
        .collect();
    for caption in [
        "cube_onelight: error against time",
        "cube_onelight: convergence at tolerance",
    ] {
        assert!(
            texts.iter().any(|t| t.starts_with(caption)),
            "no panel {caption:?} in {texts:?}"
        );
    }
    assert!(!texts.iter().any(|t| t.contains("no data")), "{texts:?}");
    for legend in ["M1 extended", "M1 tessellated"] {
        assert!(texts.iter().any(|t| t == legend), "no legend {legend}");
    }
    let lines = doc
        .descendants()
        .filter(|n| n.has_tag_name("polyline") || n.has_tag_name("path"))
        .count();
    assert!(lines >= 4, "{lines} lines drawn");
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn bad_grid_options_exit_2_with_a_reason() {
    let out = std::env::temp_dir().join(format!("wavrad-bench-sweep-bad-{}", std::process::id()));
    for (flag, value) in [
        ("--orders", "4"),
        ("--modes", "both"),
        ("--max-seconds", "0"),
    ] {
        let run = wavrad()
            .args(["bench", "sweep", "cube_onelight", "--out"])
            .arg(&out)
            .args([flag, value])
            .output()
            .expect("wavrad runs");
        assert_eq!(run.status.code(), Some(2), "{flag} {value}");
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(stderr.contains(flag), "{flag}: {stderr}");
    }
    let run = wavrad()
        .args(["bench", "sweep", "no_such_set", "--out"])
        .arg(&out)
        .output()
        .expect("wavrad runs");
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("no_such_set: no such data set"));
    let _ = std::fs::remove_dir_all(&out);
}
