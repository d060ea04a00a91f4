//! Exact 2D predicates shared by the extended-domain geometry: the orientation test (Shewchuk's
//! adaptive `orient2d` from the `robust` crate, exact for any finite `f64` input) and
//! `signed_area`, which are the face geometry's (`crate::faces::geom`, re-exported here so the
//! faces and the domain decide turns and areas with one piece of code), and the lexicographic
//! point order `(x, then y)` that the trapezoidal map and the hull use as their "left of" (a
//! symbolic shear, so vertical segments and equal x-coordinates need no special case).

pub use crate::faces::geom::{orient, signed_area};
use glam::DVec2;
use std::cmp::Ordering;

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
