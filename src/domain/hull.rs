//! Convex hull of a 2D point set (Andrew's monotone chain, O(n log n)) with exact turns.
//!
//! Invariants of [`convex_hull`]'s result: counter-clockwise, no repeated point, no three
//! consecutive points collinear (every turn is strictly left by the exact orientation test), so it
//! has 0 points (no finite input), 1 (all inputs equal), 2 (all collinear: the two extremes) or at
//! least 3 (a proper convex polygon). Non-finite input points are ignored.

use super::predicates::{lex_cmp, orient};
use glam::DVec2;

/// The convex hull of `points`, counter-clockwise, starting at the lexicographically least point.
pub fn convex_hull(points: &[DVec2]) -> Vec<DVec2> {
    let mut pts: Vec<DVec2> = points.iter().copied().filter(|p| p.is_finite()).collect();
    pts.sort_by(|a, b| lex_cmp(*a, *b));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let mut hull: Vec<DVec2> = Vec::with_capacity(pts.len() + 1);
    // Lower chain, left to right.
    for &p in &pts {
        while hull.len() >= 2 && orient(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
            hull.pop();
        }
        hull.push(p);
    }
    // Upper chain, right to left.
    let lower_len = hull.len() + 1;
    for &p in pts.iter().rev().skip(1) {
        while hull.len() >= lower_len
            && orient(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
        {
            hull.pop();
        }
        hull.push(p);
    }
    hull.pop(); // The first point again.
    debug_assert!(hull.len() >= 2);
    debug_assert!(
        hull.len() < 3
            || (0..hull.len()).all(|i| {
                let n = hull.len();
                orient(hull[i], hull[(i + 1) % n], hull[(i + 2) % n]) > 0.0
            })
    );
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hull_of_a_square_with_interior_and_edge_points() {
        let pts = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.5, 0.0), // on an edge: dropped
            DVec2::new(1.0, 1.0),
            DVec2::new(0.5, 0.5), // interior
            DVec2::new(0.0, 1.0),
            DVec2::new(0.0, 1.0), // repeated
        ];
        let h = convex_hull(&pts);
        assert_eq!(
            h,
            vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(1.0, 0.0),
                DVec2::new(1.0, 1.0),
                DVec2::new(0.0, 1.0)
            ]
        );
    }

    #[test]
    fn degenerate_hulls() {
        assert!(convex_hull(&[]).is_empty());
        assert!(convex_hull(&[DVec2::NAN]).is_empty());
        assert_eq!(convex_hull(&[DVec2::ONE, DVec2::ONE]), vec![DVec2::ONE]);
        let line: Vec<DVec2> = (0..7).map(|i| DVec2::splat(f64::from(i) * 0.1)).collect();
        assert_eq!(convex_hull(&line), vec![line[0], line[6]]);
    }
}
