//! Benchmark: Lambert's contour integral (`wavrad::solver::kernel::point_rings_form_factor`), the
//! exact form factor of a partly covered source element, per edge: rings of 8, 65 (the mean of a
//! large level's indirect phase, docs/performance-notes.md) and 200 edges, seen from 64 points
//! about 1, 4 and 16 ring radii above the ring, wholly in front of them, and from points 1 radius
//! above whose tilted tangent plane cuts the ring ("cut": the ring is clipped, then integrated).
//! Prints nanoseconds per edge (the call's own cost included), best of five rounds; the sum of
//! the form factors is printed so the work cannot be optimised away. One ring and 64 points
//! repeat: the data stays in the first-level cache and the branches are learnt, so the figures
//! are a floor for the solver's, whose rings vary.
//!
//! Run: `cargo bench --bench kernel`.

use glam::DVec3;
use std::f64::consts::PI;
use std::hint::black_box;
use std::time::Instant;
use wavrad::solver::kernel::point_rings_form_factor;

const ROUNDS: usize = 5;
/// Edges integrated per round and configuration.
const EDGES_PER_ROUND: usize = 4_000_000;

fn main() {
    println!("contour integral: ns per edge, best of {ROUNDS} rounds");
    println!(
        "{:>6} {:>8} {:>10} {:>14}",
        "edges", "radii", "ns/edge", "sum"
    );
    for sides in [8usize, 65, 200] {
        // A star-like ring in the plane z = 0 (radii 0.5 to 0.7), counter-clockwise.
        let ring: Vec<DVec3> = (0..sides)
            .map(|i| {
                let angle = 2.0 * PI * i as f64 / sides as f64;
                let r = 0.5 + (i % 3) as f64 * 0.1;
                DVec3::new(angle.cos() * r, angle.sin() * r, 0.0)
            })
            .collect();
        let rings = vec![ring];
        for (label, radii, n) in [
            ("1", 1.0, DVec3::NEG_Z),
            ("4", 4.0, DVec3::NEG_Z),
            ("16", 16.0, DVec3::NEG_Z),
            ("1 cut", 1.0, DVec3::new(1.0, 0.0, -0.3).normalize()),
        ] {
            let points: Vec<DVec3> = (0..64)
                .map(|k| DVec3::new((k % 8) as f64 * 0.1, (k / 8) as f64 * 0.1, radii * 0.7))
                .collect();
            let calls = EDGES_PER_ROUND / sides;
            let (mut best, mut sum) = (f64::INFINITY, 0.0);
            for _ in 0..ROUNDS {
                let start = Instant::now();
                sum = 0.0;
                for c in 0..calls {
                    sum += point_rings_form_factor(points[c % 64], n, black_box(&rings));
                }
                best = best.min(start.elapsed().as_secs_f64());
            }
            let per_edge = best * 1e9 / (calls * sides) as f64;
            println!("{sides:>6} {label:>8} {per_edge:>10.2} {sum:>14.6e}");
        }
    }
}
