//! Triangulation of a planar polygon with holes by ear clipping, without new vertices.
//!
//! Owns [`triangulate_polygon`] (2D rings) and [`triangulate_face`] (a [`Face`]'s rings, in the
//! face's exact [`Projection`]). Holes are first joined to the outer ring by bridges (D. Eberly,
//! "Triangulation by Ear Clipping": the hole with the rightmost vertex first, a ray to +x, the
//! visible vertex of least angle); a hole touching the polygon at a shared vertex is spliced in
//! there without a bridge. Ears are then clipped from the resulting weakly simple polygon; all
//! turn and containment tests use the exact orientation predicate.
//!
//! Input: outer ring counter-clockwise, holes clockwise, rings simple, holes inside the outer ring
//! and disjoint (they may touch at vertices), as [`super::validate_faces`] checks. Output:
//! triangles as indices into the rings' vertices numbered in order (outer first, then each hole),
//! counter-clockwise, covering the polygon exactly: `vertices + 2 holes - 2` triangles when no
//! vertex is collinear with its neighbours. Bad input gives an error, never a panic.
//! Cost: O(n r) for n vertices and r reflex vertices.

use super::geom::{orient, Projection};
use super::Face;
use glam::{DVec2, DVec3};
use std::fmt;

/// Why a polygon could not be triangulated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TriangulateError {
    /// Fewer than 3 vertices in a ring, or no ring.
    TooFewVertices,
    /// A hole that no ray from it reaches the outer ring through (a hole outside the outer ring).
    HoleNotInside { hole: usize },
    /// No ear could be clipped: the rings cross or are wrongly oriented.
    NoEar { remaining: usize },
}

impl fmt::Display for TriangulateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TriangulateError::TooFewVertices => write!(f, "a ring has fewer than 3 vertices"),
            TriangulateError::HoleNotInside { hole } => {
                write!(f, "hole {hole} is not inside the outer ring")
            }
            TriangulateError::NoEar { remaining } => write!(
                f,
                "no ear found with {remaining} vertices left: rings cross or are misoriented"
            ),
        }
    }
}

impl std::error::Error for TriangulateError {}

/// Triangulates the face's rings (no new vertices); triangles counter-clockwise about its normal.
pub fn triangulate_face(face: &Face) -> Result<Vec<[DVec3; 3]>, TriangulateError> {
    let proj = Projection::for_normal(face.normal);
    let rings3: Vec<&[DVec3]> = std::iter::once(face.outer.as_slice())
        .chain(face.holes.iter().map(Vec::as_slice))
        .collect();
    let rings: Vec<Vec<DVec2>> = rings3
        .iter()
        .map(|r| r.iter().map(|&p| proj.apply(p)).collect())
        .collect();
    let flat: Vec<DVec3> = rings3.iter().flat_map(|r| r.iter().copied()).collect();
    let tris = triangulate_polygon(&rings)?;
    Ok(tris
        .into_iter()
        .map(|[a, b, c]| [flat[a], flat[b], flat[c]])
        .collect())
}

/// Triangulates a polygon given as `rings[0]` (outer, counter-clockwise) and holes `rings[1..]`
/// (clockwise). Returns index triples into the concatenated rings.
pub fn triangulate_polygon(rings: &[Vec<DVec2>]) -> Result<Vec<[usize; 3]>, TriangulateError> {
    if rings.is_empty() || rings.iter().any(|r| r.len() < 3) {
        return Err(TriangulateError::TooFewVertices);
    }
    let mut pts: Vec<DVec2> = Vec::new();
    let mut ring_ids: Vec<Vec<usize>> = Vec::new();
    for r in rings {
        let start = pts.len();
        pts.extend_from_slice(r);
        ring_ids.push((start..pts.len()).collect());
    }
    let mut poly = ring_ids[0].clone();
    // Holes by decreasing rightmost x, so every hole to the right of the current one is merged.
    let mut order: Vec<(usize, usize)> = (1..ring_ids.len())
        .map(|h| {
            let m = rightmost(&ring_ids[h], &pts);
            (h, m)
        })
        .collect();
    order.sort_by(|a, b| {
        pts[b.1]
            .x
            .total_cmp(&pts[a.1].x)
            .then(pts[b.1].y.total_cmp(&pts[a.1].y))
    });
    for (h, m) in order {
        let hole = &ring_ids[h];
        if !splice_touching(&mut poly, hole, &pts) {
            bridge(&mut poly, hole, m, &pts)
                .ok_or(TriangulateError::HoleNotInside { hole: h - 1 })?;
        }
    }
    clip_ears(&poly, &pts)
}

/// The vertex (index into `pts`) of `ring` with the largest x (then largest y).
fn rightmost(ring: &[usize], pts: &[DVec2]) -> usize {
    let mut best = ring[0];
    for &i in ring {
        let (p, b) = (pts[i], pts[best]);
        if p.x > b.x || (p.x == b.x && p.y > b.y) {
            best = i;
        }
    }
    best
}

/// True when direction `d` from node `k` of `poly` points into the polygon's interior wedge there
/// (boundary directions included).
fn locally_inside(poly: &[usize], k: usize, target: DVec2, pts: &[DVec2]) -> bool {
    let n = poly.len();
    let p = pts[poly[(k + n - 1) % n]];
    let v = pts[poly[k]];
    let q = pts[poly[(k + 1) % n]];
    if orient(p, v, q) >= 0.0 {
        orient(v, q, target) >= 0.0 && orient(p, v, target) >= 0.0
    } else {
        orient(v, q, target) >= 0.0 || orient(p, v, target) >= 0.0
    }
}

/// Splices `hole` into `poly` at a vertex they share (same position), if any. The hole's
/// neighbours must lie in the polygon's wedge at that vertex.
fn splice_touching(poly: &mut Vec<usize>, hole: &[usize], pts: &[DVec2]) -> bool {
    let hn = hole.len();
    for (j, &hv) in hole.iter().enumerate() {
        let hp = pts[hole[(j + hn - 1) % hn]];
        let hq = pts[hole[(j + 1) % hn]];
        for k in 0..poly.len() {
            if pts[poly[k]] != pts[hv] {
                continue;
            }
            if locally_inside(poly, k, hp, pts) && locally_inside(poly, k, hq, pts) {
                // ... v(k), h(j+1), ..., h(j-1), h(j), next ...
                let insert: Vec<usize> = (1..=hn).map(|i| hole[(j + i) % hn]).collect();
                poly.splice(k + 1..k + 1, insert);
                return true;
            }
        }
    }
    false
}

/// Joins `hole` to `poly` by a bridge from its rightmost vertex `m` to a visible polygon vertex.
fn bridge(poly: &mut Vec<usize>, hole: &[usize], m: usize, pts: &[DVec2]) -> Option<()> {
    let mp = pts[m];
    let n = poly.len();
    // Nearest edge crossed by the ray from m towards +x, entering from the interior side.
    let mut hit: Option<(f64, usize)> = None;
    for k in 0..n {
        let a = pts[poly[k]];
        let b = pts[poly[(k + 1) % n]];
        if !(a.y <= mp.y && mp.y <= b.y && a.y < b.y) {
            continue;
        }
        let x = a.x + (mp.y - a.y) * (b.x - a.x) / (b.y - a.y);
        if x >= mp.x && hit.is_none_or(|h| x < h.0) {
            hit = Some((x, k));
        }
    }
    let (x, k) = hit?;
    let a = pts[poly[k]];
    let b = pts[poly[(k + 1) % n]];
    let ip = DVec2::new(x, mp.y);
    // Candidate: the hit edge's endpoint of larger x (the hit point itself if it is a vertex).
    let mut target = if ip == a {
        k
    } else if ip == b || b.x > a.x {
        (k + 1) % n
    } else {
        k
    };
    if ip != pts[poly[target]] {
        // Polygon vertices inside the triangle (m, ip, candidate) would block the bridge: take the
        // one seen at the least angle from the ray (then the nearest), which is visible.
        let c = pts[poly[target]];
        let (t0, t1, t2) = if orient(mp, ip, c) >= 0.0 {
            (mp, ip, c)
        } else {
            (mp, c, ip)
        };
        let mut best: Option<(f64, f64, usize)> = None;
        for j in 0..n {
            let r = pts[poly[j]];
            if r == c || r == mp || r.x <= mp.x {
                continue;
            }
            if orient(t0, t1, r) >= 0.0
                && orient(t1, t2, r) >= 0.0
                && orient(t2, t0, r) >= 0.0
                && locally_inside(poly, j, mp, pts)
            {
                let tan = (r.y - mp.y).abs() / (r.x - mp.x);
                let dist = r.x - mp.x;
                if best.is_none_or(|b| tan < b.0 || (tan == b.0 && dist < b.1)) {
                    best = Some((tan, dist, j));
                }
            }
        }
        if let Some((_, _, j)) = best {
            target = j;
        }
    }
    // With repeated positions (earlier bridges), use an occurrence whose wedge sees m.
    let tp = pts[poly[target]];
    if !locally_inside(poly, target, mp, pts) {
        if let Some(j) = (0..n).find(|&j| pts[poly[j]] == tp && locally_inside(poly, j, mp, pts)) {
            target = j;
        }
    }
    // ... r, m, h.., m, r, next ...
    let hn = hole.len();
    let mi = hole.iter().position(|&v| v == m)?;
    let mut insert: Vec<usize> = (0..=hn).map(|i| hole[(mi + i) % hn]).collect();
    insert.push(poly[target]);
    poly.splice(target + 1..target + 1, insert);
    Some(())
}

/// Clips ears from a weakly simple counter-clockwise polygon given as point indices.
fn clip_ears(poly: &[usize], pts: &[DVec2]) -> Result<Vec<[usize; 3]>, TriangulateError> {
    let n = poly.len();
    let mut out = Vec::with_capacity(n.saturating_sub(2));
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    let mut next: Vec<usize> = (0..n).map(|i| (i + 1) % n).collect();
    let p = |i: usize| pts[poly[i]];
    let convex =
        |prev: &[usize], next: &[usize], i: usize| orient(p(prev[i]), p(i), p(next[i])) > 0.0;
    let mut alive = vec![true; n];
    // Nodes that are not strictly convex: only they can block an ear.
    let mut blockers: Vec<usize> = (0..n).filter(|&i| !convex(&prev, &next, i)).collect();
    let mut remaining = n;
    let mut i = 0;
    let mut since_clip = 0;
    while remaining > 3 {
        let (a, c) = (prev[i], next[i]);
        let is_ear = convex(&prev, &next, i) && {
            let (pa, pb, pc) = (p(a), p(i), p(c));
            !blockers.iter().any(|&j| {
                let r = p(j);
                alive[j]
                    && j != a
                    && j != i
                    && j != c
                    && r != pa
                    && r != pb
                    && r != pc
                    && orient(pa, pb, r) >= 0.0
                    && orient(pb, pc, r) >= 0.0
                    && orient(pc, pa, r) >= 0.0
            })
        };
        if is_ear {
            out.push([poly[a], poly[i], poly[c]]);
            alive[i] = false;
            next[a] = c;
            prev[c] = a;
            remaining -= 1;
            since_clip = 0;
            // Neighbours may have become convex; drop dead and convex nodes from the blockers.
            blockers.retain(|&j| alive[j] && !convex(&prev, &next, j));
            i = a;
            continue;
        }
        i = next[i];
        since_clip += 1;
        if since_clip > remaining {
            // Last resort: a vertex collinear with its neighbours and between them is removed
            // without a triangle (no area lost); anything else means bad input.
            let mut j = i;
            let mut found = None;
            for _ in 0..remaining {
                let (pa, pb, pc) = (p(prev[j]), p(j), p(next[j]));
                if orient(pa, pb, pc) == 0.0 && (pb - pa).dot(pc - pb) > 0.0 {
                    found = Some(j);
                    break;
                }
                j = next[j];
            }
            let Some(j) = found else {
                return Err(TriangulateError::NoEar { remaining });
            };
            alive[j] = false;
            let (a, c) = (prev[j], next[j]);
            next[a] = c;
            prev[c] = a;
            remaining -= 1;
            blockers.retain(|&k| alive[k] && !convex(&prev, &next, k));
            i = a;
            since_clip = 0;
        }
    }
    let (a, c) = (prev[i], next[i]);
    if orient(p(a), p(i), p(c)) > 0.0 {
        out.push([poly[a], poly[i], poly[c]]);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::faces::geom::signed_area;

    fn area_of(tris: &[[usize; 3]], pts: &[DVec2]) -> f64 {
        tris.iter()
            .map(|t| {
                let a = signed_area(&[pts[t[0]], pts[t[1]], pts[t[2]]]);
                assert!(a > 0.0, "triangle {t:?} is not counter-clockwise");
                a
            })
            .sum()
    }

    fn square(x0: f64, y0: f64, s: f64, ccw: bool) -> Vec<DVec2> {
        let mut r = vec![
            DVec2::new(x0, y0),
            DVec2::new(x0 + s, y0),
            DVec2::new(x0 + s, y0 + s),
            DVec2::new(x0, y0 + s),
        ];
        if !ccw {
            r.reverse();
        }
        r
    }

    #[test]
    fn square_with_square_hole_gives_eight_triangles() {
        let rings = vec![square(0.0, 0.0, 3.0, true), square(1.0, 1.0, 1.0, false)];
        let tris = triangulate_polygon(&rings).unwrap();
        let pts: Vec<DVec2> = rings.concat();
        assert_eq!(tris.len(), 8);
        assert!((area_of(&tris, &pts) - 8.0).abs() < 1e-12);
    }

    #[test]
    fn concave_polygon_and_several_holes() {
        // A comb: concave outer ring, with holes in its base (aligned in x and y on purpose).
        let outer = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(10.0, 0.0),
            DVec2::new(10.0, 5.0),
            DVec2::new(8.0, 5.0),
            DVec2::new(8.0, 2.0),
            DVec2::new(6.0, 2.0),
            DVec2::new(6.0, 5.0),
            DVec2::new(4.0, 5.0),
            DVec2::new(4.0, 2.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(2.0, 5.0),
            DVec2::new(0.0, 5.0),
        ];
        let holes = [
            square(0.5, 0.5, 1.0, false),
            square(2.5, 0.5, 1.0, false),
            square(4.5, 0.5, 1.0, false),
            square(8.5, 0.5, 1.0, false),
        ];
        let mut rings = vec![outer];
        rings.extend(holes);
        let pts: Vec<DVec2> = rings.concat();
        let tris = triangulate_polygon(&rings).unwrap();
        let expected = 50.0 - 2.0 * 6.0 - 4.0;
        assert!((area_of(&tris, &pts) - expected).abs() < 1e-12);
        assert_eq!(tris.len(), pts.len() + 2 * 4 - 2);
    }

    #[test]
    fn hole_touching_the_outer_ring_at_a_vertex() {
        let outer = square(0.0, 0.0, 4.0, true);
        // A diamond hole whose right corner is the outer ring's vertex (4, 2).
        let outer = vec![outer[0], outer[1], DVec2::new(4.0, 2.0), outer[2], outer[3]];
        let hole = vec![
            DVec2::new(4.0, 2.0),
            DVec2::new(3.0, 1.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(3.0, 3.0),
        ];
        assert!(signed_area(&hole) < 0.0);
        let rings = vec![outer, hole];
        let pts: Vec<DVec2> = rings.concat();
        let tris = triangulate_polygon(&rings).unwrap();
        assert!((area_of(&tris, &pts) - 14.0).abs() < 1e-12);
    }

    #[test]
    fn hole_outside_is_an_error_not_a_panic() {
        let rings = vec![square(0.0, 0.0, 1.0, true), square(5.0, 5.0, 1.0, false)];
        assert!(triangulate_polygon(&rings).is_err());
        assert_eq!(
            triangulate_polygon(&[vec![DVec2::ZERO, DVec2::X]]),
            Err(TriangulateError::TooFewVertices)
        );
    }
}
