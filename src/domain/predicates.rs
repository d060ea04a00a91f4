//! Exact 2D predicates shared by the extended-domain geometry: the orientation test (Shewchuk's
//! adaptive `orient2d` from the `robust` crate, exact for any finite `f64` input) and the
//! lexicographic point order `(x, then y)` that the trapezoidal map and the hull use as their
//! "left of" (a symbolic shear, so vertical segments and equal x-coordinates need no special case).

use glam::DVec2;
use std::cmp::Ordering;

/// Exact orientation of `c` relative to the directed line `a -> b`: positive when `a, b, c` turn
/// counter-clockwise (`c` left of / above `a -> b`), negative when clockwise, zero when collinear.
/// Only the sign is meaningful.
#[inline]
pub fn orient(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    robust::orient2d(
        robust::Coord { x: a.x, y: a.y },
        robust::Coord { x: b.x, y: b.y },
        robust::Coord { x: c.x, y: c.y },
    )
}

/// Lexicographic order: by `x`, then by `y`. Total on finite points.
#[inline]
pub fn lex_cmp(a: DVec2, b: DVec2) -> Ordering {
    a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y))
}

/// `a` strictly before `b` in the lexicographic order.
#[inline]
pub fn lex_less(a: DVec2, b: DVec2) -> bool {
    a.x < b.x || (a.x == b.x && a.y < b.y)
}

/// True when `p` lies on the closed segment `[a, b]` (exact).
#[inline]
pub fn on_segment(a: DVec2, b: DVec2, p: DVec2) -> bool {
    orient(a, b, p) == 0.0
        && p.x >= a.x.min(b.x)
        && p.x <= a.x.max(b.x)
        && p.y >= a.y.min(b.y)
        && p.y <= a.y.max(b.y)
}

/// Signed area of a closed ring (positive when counter-clockwise), summed about the first vertex.
pub fn signed_area(ring: &[DVec2]) -> f64 {
    let Some(&o) = ring.first() else {
        return 0.0;
    };
    let mut sum = 0.0;
    for i in 1..ring.len().saturating_sub(1) {
        sum += (ring[i] - o).perp_dot(ring[i + 1] - o);
    }
    0.5 * sum
}
