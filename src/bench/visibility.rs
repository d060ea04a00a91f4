//! `wavrad bench visibility`: occlusion of segments through the solver's own visibility structure
//! (`pipeline::build_visibility`, the BVH every solve traces, bounding faces left out as in a
//! solve), timed, and the segments to trace (`generate_segments`: random point pairs on the
//! scene's faces, seeded).
//!
//! Invariants: a segment counts as occluded exactly when `Visibility::visible` says it is blocked
//! with no face ignored (hits within `ENDPOINT_EPSILON_REL` x diagonal of either end do not
//! count); the count equals a brute-force test of every scene triangle
//! ([`brute_force_occluded`], `tests/bench_visibility.rs`); the generated file is the same for
//! the same scene, count and seed, its coordinates exactly representable in `f32` (so a ray
//! tracer in single precision reads the same points).

use crate::scene::Scene;
use crate::shuffle::SplitMix64;
use crate::solver::visibility::{intersect, Visibility, ENDPOINT_EPSILON_REL};
use glam::DVec3;
use rayon::prelude::*;

/// A segment: `[ax, ay, az, bx, by, bz]`.
pub type Segment = [f64; 6];

/// Default seed of `--generate`.
pub const DEFAULT_SEED: u64 = 19;

/// Least |cosine| between a generated segment and the normal of the face at either end.
pub const MIN_COSINE: f64 = 0.01;

/// Draws of point pairs per wanted segment before `generate_segments` gives up.
const MAX_ATTEMPTS_PER_SEGMENT: usize = 100;

/// Segments traced per parallel task.
const CHUNK: usize = 4096;

/// What a run measured: the JSON line of `wavrad bench visibility`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct OcclusionRun {
    pub segments: usize,
    pub occluded: usize,
    /// The tracing only (no load, no build).
    pub seconds: f64,
    /// Segments per second, all threads together.
    pub per_second: f64,
    pub threads: usize,
    /// The instruction set the segment tests ran with (`Visibility::code_path`).
    pub code_path: &'static str,
}

/// Reads a segments file: a JSON array of `[ax, ay, az, bx, by, bz]`, finite numbers.
pub fn parse_segments(bytes: &[u8]) -> Result<Vec<Segment>, String> {
    let segments: Vec<Segment> = serde_json::from_slice(bytes)
        .map_err(|e| format!("not a JSON array of [ax, ay, az, bx, by, bz] segments: {e}"))?;
    if let Some(i) = segments
        .iter()
        .position(|s| s.iter().any(|v| !v.is_finite()))
    {
        return Err(format!("segment {i} has a coordinate that is not finite"));
    }
    Ok(segments)
}

fn ends(s: &Segment) -> (DVec3, DVec3) {
    (DVec3::new(s[0], s[1], s[2]), DVec3::new(s[3], s[4], s[5]))
}

/// Traces `segments` through `visibility` on `threads` threads (1: on the calling thread) and
/// counts the occluded ones; `seconds` is the tracing alone.
pub fn trace(
    visibility: &Visibility,
    segments: &[Segment],
    threads: usize,
) -> Result<OcclusionRun, String> {
    let blocked = |s: &Segment| {
        let (a, b) = ends(s);
        !visibility.visible_uncounted(a, b, [u32::MAX; 2])
    };
    let threads = threads.max(1);
    let (occluded, seconds) = if threads == 1 {
        let start = std::time::Instant::now();
        let occluded = segments.iter().filter(|s| blocked(s)).count();
        (occluded, start.elapsed().as_secs_f64())
    } else {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| format!("cannot start {threads} threads: {e}"))?;
        pool.install(|| {
            let start = std::time::Instant::now();
            let occluded: usize = segments
                .par_chunks(CHUNK)
                .map(|chunk| chunk.iter().filter(|s| blocked(s)).count())
                .sum();
            (occluded, start.elapsed().as_secs_f64())
        })
    };
    visibility.count_rays(segments.len() as u64);
    Ok(OcclusionRun {
        segments: segments.len(),
        occluded,
        seconds,
        per_second: if seconds > 0.0 {
            segments.len() as f64 / seconds
        } else {
            0.0
        },
        threads,
        code_path: visibility.code_path(),
    })
}

/// The occluded count by brute force: every segment against every triangle of the scene (bounding
/// faces included, no BVH), with the solver's intersection test and end epsilon. The reference
/// of `tests/bench_visibility.rs`.
pub fn brute_force_occluded(scene: &Scene, segments: &[Segment]) -> usize {
    let eps = ENDPOINT_EPSILON_REL * scene.diagonal();
    segments
        .par_iter()
        .filter(|s| {
            let (a, b) = ends(s);
            let len = (b - a).length();
            if len <= 2.0 * eps {
                return false;
            }
            let dir = (b - a) / len;
            scene
                .triangles
                .iter()
                .any(|t| intersect(a, dir, &t.vertices).is_some_and(|h| h > eps && h < len - eps))
        })
        .count()
}

/// `n` segments between random points on the faces' triangles (uniform by area, both ends drawn
/// independently), from `seed`; coordinates rounded to `f32`. Pairs whose segment makes less
/// than [`MIN_COSINE`] with the normal at either end (it nearly lies in that face's plane: two
/// points of one floor) are drawn again: the solver never traces them (they exchange no light)
/// and their verdict is rounding noise (Embree and the f64 test disagreed on 0.4 % of all
/// segments on the Red Eclipse level before they were left out: docs/performance-notes.md).
pub fn generate_segments(
    faces: &crate::faces::FaceSet,
    n: usize,
    seed: u64,
) -> Result<Vec<Segment>, String> {
    let triangles: Vec<[DVec3; 3]> = faces
        .faces
        .iter()
        .flat_map(|f| f.triangulation.iter().copied())
        .collect();
    // Cumulative areas, for drawing a triangle in proportion to its area.
    let mut cumulative = Vec::with_capacity(triangles.len());
    let mut total = 0.0;
    for t in &triangles {
        total += 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
        cumulative.push(total);
    }
    if total.is_nan() || total <= 0.0 {
        return Err("the scene has no face to put segment ends on".into());
    }
    let mut rng = SplitMix64::new(seed);
    let mut unit = move || (rng.next() >> 11) as f64 / (1u64 << 53) as f64;
    let mut point = || {
        let target = unit() * total;
        let i = cumulative
            .partition_point(|&c| c <= target)
            .min(triangles.len() - 1);
        let [a, b, c] = triangles[i];
        let (mut u, mut v) = (unit(), unit());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let p = a + (b - a) * u + (c - a) * v;
        let p = DVec3::new(p.x as f32 as f64, p.y as f32 as f64, p.z as f32 as f64);
        (p, (b - a).cross(c - a).normalize_or_zero())
    };
    let mut segments = Vec::with_capacity(n);
    let mut attempts = 0usize;
    while segments.len() < n {
        attempts += 1;
        if attempts > n.saturating_mul(MAX_ATTEMPTS_PER_SEGMENT).max(1000) {
            return Err("too few pairs of points see each other at an angle".into());
        }
        let ((p, np), (q, nq)) = (point(), point());
        let dir = (q - p).normalize_or_zero();
        // Grazing pairs (one end's plane nearly holds the segment) exchange no light, so the
        // solver never traces them; their verdict is rounding noise in any ray tracer.
        if dir.dot(np).abs() < MIN_COSINE || dir.dot(nq).abs() < MIN_COSINE {
            continue;
        }
        segments.push([p.x, p.y, p.z, q.x, q.y, q.z]);
    }
    Ok(segments)
}

/// The segments file: one JSON array, coordinates in their shortest `f32` form.
pub fn segments_json(segments: &[Segment]) -> String {
    let mut out = String::with_capacity(segments.len() * 64 + 2);
    out.push('[');
    for (i, s) in segments.iter().enumerate() {
        if i > 0 {
            out.push_str(",\n");
        }
        out.push('[');
        for (k, v) in s.iter().enumerate() {
            if k > 0 {
                out.push(',');
            }
            // The shortest text that reads back as this f32 (Rust's float formatting).
            out.push_str(&format!("{:?}", *v as f32));
        }
        out.push(']');
    }
    out.push_str("]\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_round_trip_through_their_file() {
        let segments = vec![[
            0.1f32 as f64,
            -2.5,
            1e-3f32 as f64,
            3.0,
            4.0,
            123.456f32 as f64,
        ]];
        let text = segments_json(&segments);
        let back = parse_segments(text.as_bytes()).unwrap();
        for (x, y) in back[0].iter().zip(&segments[0]) {
            assert_eq!(*x as f32, *y as f32);
        }
        assert!(parse_segments(b"[[1,2,3]]").is_err());
        assert!(parse_segments(b"{}").unwrap_err().contains("[ax, ay, az"));
    }
}
