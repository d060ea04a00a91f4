//! The minimal-area enclosing parallelogram of a 2D point set (paper section 3.1, docs/design.md
//! section 4), the extended domain's shape.
//!
//! Method (after Schwarz, Teich, Vainshtein, Welzl and Evans, 1995): an optimal parallelogram has
//! each pair of sides parallel to an edge of the convex hull. For a fixed first side direction
//! `d1`, the parallelogram's extent along `d1` is the width of the hull's oblique projection, a
//! convex function of `-cot` of the angle from `d1` to the second direction `d2` (a maximum of
//! linear functions); so over the hull's edge directions sorted by angle, the area is unimodal and
//! the best partner of each `d1` is found by binary search: O(h log h) for `h` hull edges after the
//! O(n log n) hull. Among the candidates within [`NEAR_MINIMAL_REL`] of the minimal area the one
//! whose angle is closest to 90 degrees wins (less distortion of the wavelet bases); ties go to the
//! smaller area. The near-minimal candidates of one `d1` are a contiguous range of partners, and
//! `|sin|` is unimodal over it, so this choice is also found by binary search.
//!
//! Invariants of the result ([`EnclosingParallelogram`]): finite, `u x v > 0` (counter-clockwise
//! frame), every input point at `(s, t)` in `[0,1]^2` up to rounding. Degenerate inputs give a
//! thin but valid parallelogram: collinear points a rectangle of width [`DEGENERATE_WIDTH_REL`]
//! times their length around the segment; coincident points a square of side
//! [`DEGENERATE_SIZE`]. Units are those of the input (metres in a face's plane).

use super::hull::convex_hull;
use glam::DVec2;

/// Candidates whose area is within this fraction of the minimum compete on angle (paper 3.1).
pub const NEAR_MINIMAL_REL: f64 = 1e-3;

/// Width of the domain of collinear points, relative to their extent: thin enough to hug the
/// segment, wide enough that `(s, t)` stays well conditioned in `f64` (1e-9 of 1 km is 1 um).
pub const DEGENERATE_WIDTH_REL: f64 = 1e-9;

/// Side of the domain of a point set whose points all coincide (input units).
pub const DEGENERATE_SIZE: f64 = 1e-9;

/// Edge directions closer than this (radians, modulo pi) are one direction: parallel hull edges.
const PARALLEL_RAD: f64 = 1e-12;

/// A parallelogram `origin + s*u + t*v`, `(s, t)` in `[0,1]^2`, with `u x v > 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnclosingParallelogram {
    pub origin: DVec2,
    pub u: DVec2,
    pub v: DVec2,
}

impl EnclosingParallelogram {
    pub fn area(&self) -> f64 {
        self.u.perp_dot(self.v)
    }

    /// Coordinates `(s, t)` of `p` in the frame.
    pub fn coordinates(&self, p: DVec2) -> DVec2 {
        let q = p - self.origin;
        let det = self.u.perp_dot(self.v);
        DVec2::new(q.perp_dot(self.v) / det, self.u.perp_dot(q) / det)
    }
}

/// One hull edge direction (modulo pi) and the hull's width across it.
#[derive(Debug, Clone, Copy)]
struct Direction {
    /// Unit direction.
    dir: DVec2,
    /// Angle of `dir` modulo pi, in `[0, pi)`.
    angle: f64,
    /// Width of the hull across `dir` (extent along its normal).
    width: f64,
}

/// The minimal-area enclosing parallelogram of `points` (non-finite points are ignored), preferring
/// angles near 90 degrees among near-minimal candidates.
pub fn min_area_parallelogram(points: &[DVec2]) -> EnclosingParallelogram {
    let hull = convex_hull(points);
    if hull.len() < 3 {
        return degenerate(&hull);
    }
    // Work relative to a hull vertex so that far-from-origin input keeps its precision.
    let base = hull[0];
    let hull: Vec<DVec2> = hull.iter().map(|p| *p - base).collect();
    let dirs = edge_directions(&hull);
    let extremes = [base, base + hull[hull.len() / 2]];
    if dirs.len() < 2 {
        // Every hull edge is parallel to one direction within PARALLEL_RAD (a sliver): the
        // rectangle along it, as thin as the sliver.
        return match dirs.first() {
            Some(d) => finish(from_directions(&hull, d.dir, d.dir.perp()), base, &extremes),
            None => degenerate(&extremes),
        };
    }
    let m = dirs.len();
    let area = |i: usize, k: usize| -> f64 {
        let (a, b) = (&dirs[i], &dirs[(i + 1 + k) % m]);
        a.width * b.width / a.dir.perp_dot(b.dir).abs()
    };
    // Pass 1: the best partner of each direction (unimodal in k over 0..m-1), and the minimum.
    let best_k: Vec<usize> = (0..m)
        .map(|i| {
            let (mut lo, mut hi) = (0, m - 2);
            while lo < hi {
                let mid = (lo + hi) / 2;
                if area(i, mid) <= area(i, mid + 1) {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            lo
        })
        .collect();
    let min_area = (0..m)
        .map(|i| area(i, best_k[i]))
        .fold(f64::INFINITY, f64::min);
    // Pass 2: among near-minimal candidates, the angle closest to 90 degrees.
    let threshold = min_area * (1.0 + NEAR_MINIMAL_REL);
    let mut chosen: Option<(f64, f64, usize, usize)> = None; // (|sin|, area, i, j)
    for i in 0..m {
        let kb = best_k[i];
        if area(i, kb) > threshold {
            continue;
        }
        // The window [lo, hi] of partners within the threshold: area falls to kb, then rises.
        let lo = partition_point(0, kb, |k| area(i, k) > threshold);
        let hi = partition_point(kb, m - 1, |k| area(i, k) <= threshold) - 1;
        // First partner at or past 90 degrees from direction i.
        let rel = |k: usize| {
            let j = (i + 1 + k) % m;
            let d = dirs[j].angle - dirs[i].angle;
            if d > 0.0 {
                d
            } else {
                d + std::f64::consts::PI
            }
        };
        let kp = partition_point(0, m - 1, |k| rel(k) < std::f64::consts::FRAC_PI_2);
        for k in [kp.saturating_sub(1), kp] {
            let k = k.clamp(lo, hi);
            let j = (i + 1 + k) % m;
            let sin = dirs[i].dir.perp_dot(dirs[j].dir).abs();
            let a = area(i, k);
            let better = match chosen {
                None => true,
                Some((s, ca, _, _)) => sin > s || (sin == s && a < ca),
            };
            if better {
                chosen = Some((sin, a, i, j));
            }
        }
    }
    let Some((_, _, i, j)) = chosen else {
        return degenerate(&extremes);
    };
    finish(
        from_directions(&hull, dirs[i].dir, dirs[j].dir),
        base,
        &extremes,
    )
}

/// `p` moved back by `base`, or the degenerate domain of `extremes` if `p` has no positive finite
/// area (widths lost to rounding).
fn finish(
    mut p: EnclosingParallelogram,
    base: DVec2,
    extremes: &[DVec2],
) -> EnclosingParallelogram {
    p.origin += base;
    let area = p.area();
    if area > 0.0 && area.is_finite() && p.origin.is_finite() {
        p
    } else {
        degenerate(extremes)
    }
}

/// The first `k` in `[lo, hi)` for which `pred` is false (`hi` when none), for a predicate that is
/// true then false over the range.
fn partition_point(mut lo: usize, mut hi: usize, pred: impl Fn(usize) -> bool) -> usize {
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if pred(mid) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The distinct edge directions of a counter-clockwise convex polygon (modulo pi), sorted by angle,
/// with the polygon's width across each (rotating calipers).
fn edge_directions(hull: &[DVec2]) -> Vec<Direction> {
    let h = hull.len();
    let mut dirs = Vec::with_capacity(h);
    let mut far = 1; // The vertex farthest from the current edge's line; advances monotonically.
    for i in 0..h {
        let (a, b) = (hull[i], hull[(i + 1) % h]);
        let d = b - a;
        let len = d.length();
        if len <= 0.0 || !len.is_finite() {
            continue;
        }
        let dir = d / len;
        let normal = dir.perp(); // Points inward: the hull is counter-clockwise.
        let height = |k: usize| normal.dot(hull[k % h] - a);
        let mut steps = 0;
        while steps < h && height(far + 1) >= height(far) {
            far += 1;
            steps += 1;
        }
        far %= h;
        let mut angle = dir.y.atan2(dir.x);
        if angle < 0.0 {
            angle += std::f64::consts::PI;
        }
        if angle >= std::f64::consts::PI {
            angle -= std::f64::consts::PI;
        }
        dirs.push(Direction {
            dir,
            angle,
            width: height(far),
        });
    }
    dirs.sort_by(|a, b| a.angle.total_cmp(&b.angle));
    // Merge parallel edges (their widths agree up to rounding; keep the larger).
    let mut merged: Vec<Direction> = Vec::with_capacity(dirs.len());
    for d in dirs {
        match merged.last_mut() {
            Some(last) if d.angle - last.angle <= PARALLEL_RAD => {
                last.width = last.width.max(d.width)
            }
            _ => merged.push(d),
        }
    }
    if merged.len() >= 2 {
        let last = merged[merged.len() - 1];
        if last.angle + PARALLEL_RAD >= std::f64::consts::PI + merged[0].angle {
            merged[0].width = merged[0].width.max(last.width);
            merged.pop();
        }
    }
    merged
}

/// The parallelogram with sides along `d1` and `d2` enclosing `hull` (tightly).
fn from_directions(hull: &[DVec2], d1: DVec2, d2: DVec2) -> EnclosingParallelogram {
    let (n1, n2) = (d1.perp(), d2.perp());
    let range = |n: DVec2| {
        hull.iter()
            .map(|p| n.dot(*p))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            })
    };
    let ((a1, b1), (a2, b2)) = (range(n1), range(n2));
    // The corner on the low lines of both strips.
    let det = n1.perp_dot(n2);
    let origin = DVec2::new(a1 * n2.y - a2 * n1.y, n1.x * a2 - n2.x * a1) / det;
    let u = d1 * ((b2 - a2) / n2.dot(d1));
    let v = d2 * ((b1 - a1) / n1.dot(d2));
    if u.perp_dot(v) >= 0.0 {
        EnclosingParallelogram { origin, u, v }
    } else {
        EnclosingParallelogram { origin, u: v, v: u }
    }
}

/// The domain of fewer than three non-collinear points: a thin rectangle around their segment, or
/// a tiny square around their point.
fn degenerate(points: &[DVec2]) -> EnclosingParallelogram {
    let (a, b) = match points {
        [] => (DVec2::ZERO, DVec2::ZERO),
        [a] => (*a, *a),
        [a, .., b] => (*a, *b),
    };
    let d = b - a;
    let len = d.length();
    if len > 0.0 && len.is_finite() {
        let width = len * DEGENERATE_WIDTH_REL;
        let n = (d / len).perp();
        EnclosingParallelogram {
            origin: a - n * (0.5 * width),
            u: d,
            v: n * width,
        }
    } else {
        let h = 0.5 * DEGENERATE_SIZE;
        EnclosingParallelogram {
            origin: a - DVec2::splat(h),
            u: DVec2::new(DEGENERATE_SIZE, 0.0),
            v: DVec2::new(0.0, DEGENERATE_SIZE),
        }
    }
}
