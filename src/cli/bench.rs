//! `wavrad bench` (benches/README.md): its subcommands' options and what each runs. `visibility`
//! traces segments through the solver's own visibility structure (`crate::bench::visibility`);
//! `sweep` runs the speed-accuracy grid (`crate::bench::sweep`). Same exit codes as every command:
//! 0 success, 2 bad input, 1 internal failure.

use super::{bad_input, internal, load, read_input_file, DEFAULT_MAX_TRIANGLES};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Occlusion of segments through the solver's own BVH: prints one JSON line
    /// {"segments", "occluded", "seconds", "per_second", "threads", "code_path" (x86-64-v3 or
    /// baseline)}; or, with --generate N
    /// --out FILE, writes N random segments between points on the scene's faces.
    Visibility(VisibilityArgs),
    /// Speed against accuracy: solve data sets over tolerance x order x domain mode, each solve in
    /// its own process; writes bench.csv, ratios.csv and bench.svg.
    Sweep(SweepArgs),
}

#[derive(Args, Debug)]
pub struct VisibilityArgs {
    /// The scene (.glb or .gltf).
    pub scene: PathBuf,
    /// Segments to trace: a JSON array of [ax, ay, az, bx, by, bz].
    #[arg(
        long,
        conflicts_with = "generate",
        required_unless_present = "generate"
    )]
    pub segments: Option<PathBuf>,
    /// Threads tracing the segments (1: the calling thread alone).
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Write N segments between random points on the scene's faces to --out instead.
    #[arg(long, requires = "out")]
    pub generate: Option<usize>,
    /// Where --generate writes its segments.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of --generate (the same scene, N and seed give the same file).
    #[arg(long, default_value_t = crate::bench::visibility::DEFAULT_SEED)]
    pub seed: u64,
    #[arg(long, env = "WAVRAD_MAX_TRIANGLES", default_value_t = DEFAULT_MAX_TRIANGLES)]
    pub max_triangles: usize,
}

#[derive(Args, Debug)]
pub struct SweepArgs {
    /// Data sets: folders with reference.json or expected.json, or names under
    /// tests/data/reference/ or tests/data/cie171/ (".glb" dropped). Default: cornell_box,
    /// 5.3_area_source, kenney_building_small_c_lit, redeclipse_dutility_lit.
    pub scenes: Vec<String>,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Orders to sweep, e.g. 1,2 (default: each scene's grid).
    #[arg(long, value_delimiter = ',')]
    pub orders: Option<Vec<usize>>,
    /// Tolerances to sweep, e.g. 1e-4,1e-5 (default: each scene's grid).
    #[arg(long, value_delimiter = ',')]
    pub tolerances: Option<Vec<f64>>,
    /// Domain modes, e.g. extended,tessellated (default: both).
    #[arg(long, value_delimiter = ',')]
    pub modes: Option<Vec<String>>,
    /// Cap on one solve's seconds; a capped solve's tighter tolerances are left out.
    #[arg(long, default_value_t = crate::bench::sweep::DEFAULT_MAX_SECONDS)]
    pub max_seconds: f64,
    /// The wavrad repository (for tests/data). Default: the current directory when it has
    /// tests/data, else the source tree this binary was built from.
    #[arg(long)]
    pub repo: Option<PathBuf>,
    /// Read back the solves already in DIR/runs/ (an interrupted sweep) instead of running them.
    #[arg(long)]
    pub resume: bool,
}

pub(super) fn sweep(a: SweepArgs) -> ExitCode {
    let exe = match std::env::current_exe() {
        Ok(e) => e,
        Err(e) => return internal(format!("the wavrad binary: {e}")),
    };
    let repo = a.repo.unwrap_or_else(|| {
        let here = PathBuf::from(".");
        if here.join("tests/data").is_dir() {
            here
        } else {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        }
    });
    let options = crate::bench::sweep::SweepOptions {
        scenes: a.scenes,
        out: a.out,
        orders: a.orders,
        tolerances: a.tolerances,
        modes: a.modes,
        max_seconds: a.max_seconds,
        exe,
        repo,
        resume: a.resume,
    };
    match crate::bench::sweep::run(&options, &mut |line| println!("{line}")) {
        Ok(report) => {
            print!("{}", crate::bench::sweep::summary(&report));
            println!(
                "wrote bench.csv, ratios.csv and bench.svg in {}",
                options.out.display()
            );
            ExitCode::SUCCESS
        }
        Err(e) => bad_input(e),
    }
}

/// `bench visibility`: builds the solver's visibility structure as a solve does (faces, then
/// `pipeline::build_visibility`), its build times on stderr; then generates segments or traces
/// them, the measurement as one JSON line on stdout.
pub(super) fn visibility(a: VisibilityArgs) -> ExitCode {
    use crate::bench::visibility::{generate_segments, parse_segments, segments_json, trace};
    if a.threads == 0 {
        return bad_input("--threads must be at least 1");
    }
    let segments = match read_input_file(a.segments.as_deref(), parse_segments) {
        Ok(s) => s,
        Err(code) => return code,
    };
    let start = std::time::Instant::now();
    let scene = match load(&a.scene, a.max_triangles) {
        Ok(s) => s,
        Err(code) => return code,
    };
    let load_seconds = start.elapsed().as_secs_f64();
    let start = std::time::Instant::now();
    let faces = crate::faces::merge_planar_faces(&scene);
    let faces_seconds = start.elapsed().as_secs_f64();
    if let (Some(n), Some(out)) = (a.generate, &a.out) {
        let generated = match generate_segments(&faces, n, a.seed) {
            Ok(s) => s,
            Err(e) => return bad_input(format!("{}: {e}", a.scene.display())),
        };
        if let Err(e) = std::fs::write(out, segments_json(&generated)) {
            return bad_input(format!("--out {}: {e}", out.display()));
        }
        println!(
            "{}",
            serde_json::json!({"segments": generated.len(), "seed": a.seed, "out": out})
        );
        return ExitCode::SUCCESS;
    }
    let Some(segments) = segments else {
        return bad_input("give --segments FILE, or --generate N --out FILE");
    };
    let built = crate::pipeline::build_visibility(&scene, &faces);
    eprintln!(
        "wavrad: {} triangles, {} faces ({} bounding faces left out of the BVH, as in a solve), {} \
         occluders; load {load_seconds:.3} s, faces {faces_seconds:.3} s, bounding faces {:.3} s, \
         BVH build {:.3} s; end epsilon {:.3e}",
        scene.triangles.len(),
        faces.faces.len(),
        built.bounding_faces,
        built.visibility.occluder_count(),
        built.bounding_seconds,
        built.bvh_seconds,
        built.visibility.end_epsilon(),
    );
    match trace(&built.visibility, &segments, a.threads) {
        Ok(run) => {
            println!("{}", serde_json::json!(run));
            ExitCode::SUCCESS
        }
        Err(e) => internal(e),
    }
}
