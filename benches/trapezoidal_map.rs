//! Benchmark of the extended domain's trapezoidal map (issue 4): construction time and point
//! location queries per second for faces of about 10, 1 000 and 100 000 edges, and the ratios
//! between sizes (expected: O(n log n) build, O(log n) query), with the work counts (nodes
//! visited) that the wall times include along with cache misses; queries in random order and in
//! scanline order. Also the whole `ExtendedDomain`
//! build (hull, parallelogram, map). Run with `cargo bench --bench trapezoidal_map`.

use glam::DVec2;
use std::hint::black_box;
use std::time::{Duration, Instant};
use wavrad::domain::{ExtendedDomain, TrapezoidalMap};

/// A star polygon with `n` edges (n/2 spikes), counter-clockwise, in [0,1]^2.
fn star(n: usize) -> Vec<Vec<DVec2>> {
    let ring = (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            let r = if i % 2 == 0 { 0.5 } else { 0.3 };
            DVec2::splat(0.5) + DVec2::from_angle(a) * r
        })
        .collect();
    vec![ring]
}

/// A comb with `teeth` teeth and a square hole under each tooth: 4 edges per tooth, 4 per hole,
/// plus 2. Many vertices share x-coordinates (vertical edges).
fn comb_with_holes(teeth: usize) -> Vec<Vec<DVec2>> {
    let w = 1.0 / teeth as f64;
    let mut outer = vec![DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0)];
    let mut holes = Vec::with_capacity(teeth);
    for i in (0..teeth).rev() {
        let x = i as f64 * w;
        outer.push(DVec2::new(x + w, 1.0));
        outer.push(DVec2::new(x + 0.5 * w, 1.0));
        outer.push(DVec2::new(x + 0.5 * w, 0.5));
        outer.push(DVec2::new(x, 0.5));
        // Clockwise square hole in the base.
        let (a, b) = (x + 0.25 * w, x + 0.75 * w);
        holes.push(vec![
            DVec2::new(a, 0.2),
            DVec2::new(a, 0.3),
            DVec2::new(b, 0.3),
            DVec2::new(b, 0.2),
        ]);
    }
    let mut rings = vec![outer];
    rings.extend(holes);
    rings
}

/// Median wall time of `f` over enough repetitions to fill ~`budget`.
fn time_it(budget: Duration, mut f: impl FnMut()) -> Duration {
    let start = Instant::now();
    f();
    let once = start.elapsed().max(Duration::from_nanos(1));
    let reps = (budget.as_secs_f64() / once.as_secs_f64()).clamp(3.0, 2001.0) as usize;
    let batch = (reps / 7).max(1);
    let mut samples: Vec<f64> = (0..7)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..batch {
                f();
            }
            t.elapsed().as_secs_f64() / batch as f64
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    Duration::from_secs_f64(samples[3])
}

struct Row {
    shape: &'static str,
    edges: usize,
    build: Duration,
    domain: Duration,
    queries_per_s: f64,
    coherent_queries_per_s: f64,
    depth: usize,
    /// Mean nodes visited per query.
    mean_path: f64,
    build_steps: u64,
}

fn measure(shape: &'static str, rings: Vec<Vec<DVec2>>) -> Row {
    let edges: usize = rings.iter().map(Vec::len).sum();
    let build = time_it(Duration::from_millis(600), || {
        black_box(TrapezoidalMap::new(black_box(&rings)).expect("valid rings"));
    });
    let domain = time_it(Duration::from_millis(600), || {
        black_box(ExtendedDomain::from_plane_polygon(&rings[0], &rings[1..]).expect("domain"));
    });
    let map = TrapezoidalMap::new(&rings).expect("valid rings");
    // Query points: a fixed pseudo-random cloud over the face's box.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let points: Vec<DVec2> = (0..1 << 16)
        .map(|_| {
            let mut next = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64
            };
            DVec2::new(next(), next())
        })
        .collect();
    let rounds = 16;
    let start = Instant::now();
    let mut inside = 0usize;
    for _ in 0..rounds {
        for p in &points {
            inside += usize::from(map.contains(black_box(*p)));
        }
    }
    let secs = start.elapsed().as_secs_f64();
    black_box(inside);
    // The same points in scanline order (rows of 1/256): spatially coherent, like a solver's.
    let mut coherent = points.clone();
    coherent.sort_by(|a, b| {
        ((a.y * 256.0) as u32, a.x)
            .partial_cmp(&((b.y * 256.0) as u32, b.x))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let start = Instant::now();
    for _ in 0..rounds {
        for p in &coherent {
            inside += usize::from(map.contains(black_box(*p)));
        }
    }
    let coherent_secs = start.elapsed().as_secs_f64();
    black_box(inside);
    let mean_path = points
        .iter()
        .map(|p| map.search_path_length(*p) as f64)
        .sum::<f64>()
        / points.len() as f64;
    Row {
        shape,
        edges,
        build,
        domain,
        queries_per_s: (rounds * points.len()) as f64 / secs,
        coherent_queries_per_s: (rounds * points.len()) as f64 / coherent_secs,
        depth: map.depth(),
        mean_path,
        build_steps: map.build_steps(),
    }
}

fn main() {
    let rows = vec![
        measure("star", star(10)),
        measure("star", star(1_000)),
        measure("star", star(100_000)),
        measure("comb+holes", comb_with_holes(1)),
        measure("comb+holes", comb_with_holes(125)),
        measure("comb+holes", comb_with_holes(12_500)),
    ];
    println!("trapezoidal map: construction and point location (median timings)");
    println!(
        "{:<11} {:>7} {:>11} {:>11} {:>13} {:>11} {:>9} {:>12} {:>11} {:>10} {:>6}",
        "face",
        "edges",
        "build",
        "build/edge",
        "domain build",
        "queries/s",
        "ns/query",
        "coherent q/s",
        "steps/edge",
        "mean path",
        "depth"
    );
    for r in &rows {
        println!(
            "{:<11} {:>7} {:>8.3} ms {:>8.1} ns {:>10.3} ms {:>11.3e} {:>9.1} {:>12.3e} {:>11.1} {:>10.1} {:>6}",
            r.shape,
            r.edges,
            r.build.as_secs_f64() * 1e3,
            r.build.as_secs_f64() * 1e9 / r.edges as f64,
            r.domain.as_secs_f64() * 1e3,
            r.queries_per_s,
            1e9 / r.queries_per_s,
            r.coherent_queries_per_s,
            r.build_steps as f64 / r.edges as f64,
            r.mean_path,
            r.depth
        );
    }
    println!();
    println!(
        "ratios between sizes: wall time (includes cache misses) and work counts vs the model"
    );
    println!(
        "{:<11} {:>15} {:>10} {:>11} {:>10} {:>11} {:>11} {:>8}",
        "face", "sizes", "build", "build work", "n log n", "query time", "query path", "log n"
    );
    for group in rows.chunks(3) {
        for w in group.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            let (na, nb) = (a.edges as f64, b.edges as f64);
            println!(
                "{:<11} {:>7}->{:<7} {:>9.1}x {:>10.1}x {:>9.1}x {:>10.2}x {:>10.2}x {:>7.2}x",
                a.shape,
                a.edges,
                b.edges,
                b.build.as_secs_f64() / a.build.as_secs_f64(),
                b.build_steps as f64 / a.build_steps as f64,
                (nb * nb.ln()) / (na * na.ln()),
                a.queries_per_s / b.queries_per_s,
                b.mean_path / a.mean_path,
                nb.ln() / na.ln()
            );
        }
    }
}
