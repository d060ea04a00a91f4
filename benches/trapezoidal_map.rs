//! Benchmark of the extended domain's trapezoidal map (issue 4): construction time and point
//! location queries per second for faces of about 10, 1 000 and 100 000 edges, with the exact
//! operation counts (nodes visited per query, DAG nodes visited and trapezoids created and
//! destroyed per inserted segment) and the ratios between sizes against the model (O(n log n)
//! build, O(log n) query). Queries in random order, in scanline order, and a few cycled so their
//! paths stay in cache (which separates the work from cache misses). Also the whole
//! `ExtendedDomain` build (hull, parallelogram, map). Run with `cargo bench --bench
//! trapezoidal_map`.

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
    /// Random query points, their scanline order, and 256 of them cycled (their paths stay in
    /// cache): median seconds per query.
    query: f64,
    coherent: f64,
    hot: f64,
    /// Nodes visited per query over the random points: mean and max; the DAG's depth.
    mean_path: f64,
    max_path: usize,
    depth: usize,
    nodes: usize,
    segments: u64,
    located_nodes: u64,
    created: u64,
    destroyed: u64,
}

impl Row {
    fn build_work(&self) -> u64 {
        self.located_nodes + self.destroyed
    }
}

/// Median seconds per query of `points` (each round answers all of them).
fn time_queries(map: &TrapezoidalMap, points: &[DVec2]) -> f64 {
    time_it(Duration::from_millis(400), || {
        let mut inside = 0usize;
        for p in points {
            inside += usize::from(map.contains(black_box(*p)));
        }
        black_box(inside);
    })
    .as_secs_f64()
        / points.len() as f64
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
    let query = time_queries(&map, &points);
    // The same points in scanline order (rows of 1/256): spatially coherent, like a solver's.
    let mut coherent = points.clone();
    coherent.sort_by(|a, b| {
        ((a.y * 256.0) as u32, a.x)
            .partial_cmp(&((b.y * 256.0) as u32, b.x))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let coherent = time_queries(&map, &coherent);
    let hot_points: Vec<DVec2> = points[..256]
        .iter()
        .cycle()
        .take(points.len())
        .copied()
        .collect();
    let hot = time_queries(&map, &hot_points);
    let paths: Vec<usize> = points.iter().map(|p| map.search_path_length(*p)).collect();
    let hot_path = hot_points[..256]
        .iter()
        .map(|p| map.search_path_length(*p) as f64)
        .sum::<f64>()
        / 256.0;
    let mean_path = paths.iter().sum::<usize>() as f64 / paths.len() as f64;
    let stats = map.build_stats();
    Row {
        shape,
        edges,
        build,
        domain,
        query,
        coherent,
        // Per node visited, scaled to the random points' mean path, so the columns compare.
        hot: hot / hot_path * mean_path,
        mean_path,
        max_path: paths.iter().copied().max().unwrap_or(0),
        depth: map.depth(),
        nodes: map.node_count(),
        segments: stats.segments,
        located_nodes: stats.located_nodes,
        created: stats.created_trapezoids,
        destroyed: stats.destroyed_trapezoids,
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
    println!("trapezoidal map: wall times (medians; noisy on a shared machine)");
    println!(
        "{:<11} {:>7} {:>11} {:>11} {:>12} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "face",
        "edges",
        "build",
        "build/edge",
        "domain build",
        "queries/s",
        "ns/query",
        "coherent",
        "hot",
        "ns/node",
        "hot ns/nd"
    );
    for r in &rows {
        println!(
            "{:<11} {:>7} {:>8.3} ms {:>8.1} ns {:>9.3} ms {:>10.3e} {:>9.1} {:>9.1} {:>9.1} {:>9.2} {:>9.2}",
            r.shape,
            r.edges,
            r.build.as_secs_f64() * 1e3,
            r.build.as_secs_f64() * 1e9 / r.edges as f64,
            r.domain.as_secs_f64() * 1e3,
            1.0 / r.query,
            r.query * 1e9,
            r.coherent * 1e9,
            r.hot * 1e9,
            r.query * 1e9 / r.mean_path,
            r.hot * 1e9 / r.mean_path
        );
    }
    println!();
    println!("trapezoidal map: operation counts (exact, reproducible)");
    println!(
        "{:<11} {:>7} {:>9} {:>9} {:>6} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "face",
        "edges",
        "mean path",
        "max path",
        "depth",
        "DAG nodes",
        "located/s",
        "created/s",
        "destroy/s",
        "work/s"
    );
    for r in &rows {
        let per = |x: u64| x as f64 / r.segments as f64;
        println!(
            "{:<11} {:>7} {:>9.2} {:>9} {:>6} {:>10} {:>10.2} {:>10.2} {:>10.2} {:>10.2}",
            r.shape,
            r.edges,
            r.mean_path,
            r.max_path,
            r.depth,
            r.nodes,
            per(r.located_nodes),
            per(r.created),
            per(r.destroyed),
            per(r.build_work())
        );
    }
    println!();
    println!("ratios between sizes against the model (n log n build, log n query)");
    println!(
        "{:<11} {:>15} {:>9} {:>10} {:>8} {:>9} {:>9} {:>9} {:>9} {:>7}",
        "face",
        "sizes",
        "build",
        "build work",
        "n log n",
        "query",
        "hot query",
        "mean path",
        "max path",
        "log n"
    );
    for group in rows.chunks(3) {
        for w in group.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            let (na, nb) = (a.edges as f64, b.edges as f64);
            println!(
                "{:<11} {:>7}->{:<7} {:>8.1}x {:>9.1}x {:>7.1}x {:>8.2}x {:>8.2}x {:>8.2}x {:>8.2}x {:>6.2}x",
                a.shape,
                a.edges,
                b.edges,
                b.build.as_secs_f64() / a.build.as_secs_f64(),
                b.build_work() as f64 / a.build_work() as f64,
                (nb * nb.ln()) / (na * na.ln()),
                b.query / a.query,
                b.hot / a.hot,
                b.mean_path / a.mean_path,
                b.max_path as f64 / a.max_path as f64,
                nb.ln() / na.ln()
            );
        }
    }
}
