//! Contact lines: where one surface stands on another (a box on a floor, a wall on a slab), or
//! passes through it (a post through a floor, a pipe through a bracket), the lower surface's
//! radiosity jumps along the line they meet on, and the part of it under the upper surface's
//! footprint (or inside the post) is usually closed off and dark. The triangles of the lower
//! surface rarely have edges there. This module finds those lines and cuts the triangles along
//! them, so that face merging can keep the two sides apart (docs/design.md section 3: the real surfaces).
//!
//! Owns [`cut_at_contacts`] and [`ContactCut`]. A *contact segment* of a triangle `T` is an edge
//! of another triangle `S` that lies in `T`'s plane (both ends within the plane tolerance), crosses
//! `T`'s interior (not only its border), and whose triangle `S` rises on `T`'s radiosity side (either
//! side when `T` is double-sided). A *crossing segment* is where a triangle `S` with corners strictly on
//! both sides of `T`'s plane passes through it, clipped to `T`; it is found from an edge of `S`
//! that crosses the plane near `T` (a large `S` whose edges all cross far from a small `T` is
//! missed). `T` is cut by the line of each of its contact and crossing segments into convex
//! pieces, which are fanned into triangles.
//!
//! Invariants: the pieces of a triangle tile it exactly (their areas sum to its area, up to
//! rounding), keep its material, source and winding; a cut never makes a piece corner closer than
//! the length tolerance to a line it was cut on (such corners count as on the line), so no cut
//! produces slivers below the tolerance; triangles without contacts, and degenerate triangles, are
//! passed through unchanged; the order of pieces follows the order of their scene triangles.

use super::adjacency::Tolerances;
use super::geom::{FastMap, FastSet};
use crate::scene::Triangle;
use glam::DVec3;
use rayon::prelude::*;

/// The scene's triangles cut along contact lines.
#[derive(Debug, Clone, Default)]
pub struct ContactCut {
    /// The pieces: every scene triangle, or the triangles it was cut into, in scene order.
    pub pieces: Vec<Triangle>,
    /// For each piece, the index of its scene triangle.
    pub source: Vec<u32>,
    /// Every contact segment found (world frame), the lines pieces must not be merged across.
    /// Collinear segments that continue or overlap one another are joined into one (a wall's base
    /// made of several triangle edges is one segment), so that a piece edge spanning their joint
    /// still lies on one segment.
    pub segments: Vec<[DVec3; 2]>,
    /// Number of scene triangles that were cut.
    pub triangles_cut: usize,
}

/// A cell of [`LevelGrid`]: level, then integer coordinates.
type Cell = (u8, i64, i64, i64);

/// Triangles by cell, on levels of cells growing 4x per level: each triangle is stored on the
/// finest level whose cells are at least as large as its bounding box (so in at most 8 cells),
/// and a segment query walks every level along the segment. Cost per query: the segment's length
/// in cells of each level, whatever the mix of triangle sizes.
struct LevelGrid {
    base_m: f64,
    levels: u8,
    cells: FastMap<Cell, Vec<u32>>,
}

impl LevelGrid {
    fn new(
        triangles: &[Triangle],
        planes: &[Option<(DVec3, f64)>],
        pad: DVec3,
        diagonal: f64,
    ) -> Self {
        let bounds = |t: &Triangle| {
            let [a, b, c] = t.vertices;
            (a.min(b).min(c) - pad, a.max(b).max(c) + pad)
        };
        let mut extents: Vec<f64> = triangles
            .iter()
            .zip(planes)
            .filter(|(_, p)| p.is_some())
            .map(|(t, _)| {
                let (lo, hi) = bounds(t);
                (hi - lo).max_element()
            })
            .collect();
        let mid = extents.len() / 2;
        let median = if extents.is_empty() {
            diagonal
        } else {
            *extents.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        let base_m = median.max(diagonal * 1e-4);
        let mut grid = LevelGrid {
            base_m,
            levels: 1,
            cells: FastMap::default(),
        };
        for (i, t) in triangles.iter().enumerate() {
            if planes[i].is_none() {
                continue;
            }
            let (lo, hi) = bounds(t);
            let extent = (hi - lo).max_element();
            let mut level = 0u8;
            while grid.cell_m(level) < extent && level < 30 {
                level += 1;
            }
            grid.levels = grid.levels.max(level + 1);
            let (a, b) = (grid.cell(level, lo), grid.cell(level, hi));
            for x in a.1..=b.1 {
                for y in a.2..=b.2 {
                    for z in a.3..=b.3 {
                        grid.cells
                            .entry((level, x, y, z))
                            .or_default()
                            .push(i as u32);
                    }
                }
            }
        }
        grid
    }

    fn cell_m(&self, level: u8) -> f64 {
        self.base_m * 4f64.powi(level as i32)
    }

    fn cell(&self, level: u8, p: DVec3) -> Cell {
        let inv = 1.0 / self.cell_m(level);
        (
            level,
            (p.x * inv).floor() as i64,
            (p.y * inv).floor() as i64,
            (p.z * inv).floor() as i64,
        )
    }

    /// Calls `f` with every triangle whose padded box may touch the segment `a b` (some more than
    /// once).
    fn for_each_near_segment(&self, a: DVec3, b: DVec3, pad: DVec3, mut f: impl FnMut(u32)) {
        let d = b - a;
        for level in 0..self.levels {
            let cell_m = self.cell_m(level);
            let steps = ((d.abs().max_element() / cell_m).ceil() as usize).max(1);
            for s in 0..steps {
                let p0 = a + d * (s as f64 / steps as f64);
                let p1 = a + d * ((s + 1) as f64 / steps as f64);
                let lo = self.cell(level, p0.min(p1) - pad);
                let hi = self.cell(level, p0.max(p1) + pad);
                for x in lo.1..=hi.1 {
                    for y in lo.2..=hi.2 {
                        for z in lo.3..=hi.3 {
                            if let Some(list) = self.cells.get(&(level, x, y, z)) {
                                list.iter().for_each(|&t| f(t));
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Finds the contact segments of every triangle and cuts the triangles along them.
/// `min_area` is the degenerate-area threshold: smaller triangles are passed through uncut.
pub fn cut_at_contacts(
    triangles: &[Triangle],
    double_sided: impl Fn(&Triangle) -> bool + Sync,
    tol: &Tolerances,
    diagonal: f64,
    min_area: f64,
) -> ContactCut {
    let n = triangles.len();
    let identity = |triangles: &[Triangle]| ContactCut {
        pieces: triangles.to_vec(),
        source: (0..triangles.len() as u32).collect(),
        segments: Vec::new(),
        triangles_cut: 0,
    };
    if n < 2 || !(diagonal > 0.0 && diagonal.is_finite()) {
        return identity(triangles);
    }
    // Planes of the non-degenerate triangles.
    let planes: Vec<Option<(DVec3, f64)>> = triangles
        .iter()
        .map(|t| {
            let cross = t.cross();
            let area = 0.5 * cross.length();
            (area > min_area).then(|| {
                let normal = cross / cross.length();
                (normal, normal.dot(t.vertices[0]))
            })
        })
        .collect();

    // Triangles by cell of a multi-level grid over their (padded) bounding boxes.
    let pad = DVec3::splat(tol.plane_m.max(tol.length_m));
    let grid = LevelGrid::new(triangles, &planes, pad, diagonal);
    // Contact segments per triangle, found in parallel over the standing triangles' edges.
    let found: Vec<(u32, [DVec3; 2])> = (0..n)
        .into_par_iter()
        .filter(|&s| planes[s].is_some())
        .fold(
            || (Vec::new(), Vec::new()),
            |(mut out, mut candidates): (Vec<(u32, [DVec3; 2])>, Vec<u32>), s| {
                let st = &triangles[s];
                for k in 0..3 {
                    let (p, q, r) = (
                        st.vertices[k],
                        st.vertices[(k + 1) % 3],
                        st.vertices[(k + 2) % 3],
                    );
                    candidates.clear();
                    grid.for_each_near_segment(p, q, pad, |t| {
                        // Cheapest test first: both ends in t's plane (a contact), or on either
                        // side of it (the triangle passes through t's plane).
                        if let Some((normal, offset)) = planes[t as usize] {
                            let (hp, hq) = (normal.dot(p) - offset, normal.dot(q) - offset);
                            if (hp.abs() <= tol.plane_m && hq.abs() <= tol.plane_m)
                                || (hp > tol.plane_m && hq < -tol.plane_m)
                                || (hp < -tol.plane_m && hq > tol.plane_m)
                            {
                                candidates.push(t);
                            }
                        }
                    });
                    candidates.sort_unstable();
                    candidates.dedup();
                    for &t in &candidates {
                        let ti = t as usize;
                        let Some((normal, offset)) = planes[ti] else {
                            continue;
                        };
                        let tt = &triangles[ti];
                        if ti == s {
                            continue;
                        }
                        if is_contact(p, q, r, tt, normal, offset, double_sided(tt), tol) {
                            out.push((t, [p, q]));
                        } else if let Some(seg) = crossing(st, tt, normal, offset, tol) {
                            out.push((t, seg));
                        }
                    }
                }
                (out, candidates)
            },
        )
        .map(|(out, _)| out)
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    let mut contacts: FastMap<u32, Vec<[DVec3; 2]>> = FastMap::default();
    let mut segments: Vec<[DVec3; 2]> = Vec::with_capacity(found.len());
    let mut unique: FastSet<[u64; 6]> = FastSet::default();
    for (t, seg) in found {
        let lines = contacts.entry(t).or_default();
        if !lines.contains(&seg) {
            lines.push(seg);
        }
        let [p, q] = seg;
        let key = [p.x, p.y, p.z, q.x, q.y, q.z].map(f64::to_bits);
        if unique.insert(key) {
            segments.push(seg);
        }
    }
    if contacts.is_empty() {
        return identity(triangles);
    }

    let mut cut = ContactCut {
        pieces: Vec::with_capacity(n + 4 * contacts.len()),
        source: Vec::with_capacity(n + 4 * contacts.len()),
        segments: join_collinear(&segments, tol.length_m),
        triangles_cut: 0,
    };
    for (i, t) in triangles.iter().enumerate() {
        let (Some(lines), Some((normal, _))) = (contacts.get(&(i as u32)), planes[i]) else {
            cut.pieces.push(*t);
            cut.source.push(i as u32);
            continue;
        };
        let polygons = split_convex(t.vertices.to_vec(), normal, lines, tol.length_m);
        if polygons.len() > 1 {
            cut.triangles_cut += 1;
        }
        for poly in polygons {
            for tri in fan(&poly) {
                cut.pieces.push(Triangle {
                    vertices: tri,
                    ..*t
                });
                cut.source.push(i as u32);
            }
        }
    }
    cut
}

/// Joins segments that lie on one line and share an end (within `eps`), directly or through a
/// chain of others, and returns the union of each chain's intervals: one segment per connected
/// stretch of line. Segments that touch nothing pass through unchanged.
fn join_collinear(segments: &[[DVec3; 2]], eps: f64) -> Vec<[DVec3; 2]> {
    let n = segments.len();
    if n < 2 || eps.is_nan() || eps <= 0.0 {
        return segments.to_vec();
    }
    // Ends by cell (cells of 4 eps: ends within eps of one another are in adjacent cells).
    let inv = 0.25 / eps;
    let cell = |p: DVec3| {
        (
            (p.x * inv).floor() as i64,
            (p.y * inv).floor() as i64,
            (p.z * inv).floor() as i64,
        )
    };
    let mut ends: FastMap<(i64, i64, i64), Vec<u32>> = FastMap::default();
    for (i, seg) in segments.iter().enumerate() {
        for (e, &p) in seg.iter().enumerate() {
            ends.entry(cell(p)).or_default().push((2 * i + e) as u32);
        }
    }
    let off_line = |[a, b]: [DVec3; 2], p: DVec3| {
        let d = b - a;
        let len2 = d.length_squared();
        if len2 == 0.0 {
            return p.distance(a);
        }
        (p - a - d * ((p - a).dot(d) / len2)).length()
    };
    // Union-find over segments sharing an end and a line.
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for e in 0..2 {
            let p = segments[i][e];
            let (cx, cy, cz) = cell(p);
            for x in cx - 1..=cx + 1 {
                for y in cy - 1..=cy + 1 {
                    for z in cz - 1..=cz + 1 {
                        let Some(list) = ends.get(&(x, y, z)) else {
                            continue;
                        };
                        for &code in list {
                            let (j, f) = (code as usize / 2, code as usize % 2);
                            if j <= i || p.distance(segments[j][f]) > eps {
                                continue;
                            }
                            if off_line(segments[i], segments[j][1 - f]) <= eps
                                && off_line(segments[j], segments[i][1 - e]) <= eps
                            {
                                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                                parent[ri.max(rj)] = ri.min(rj);
                            }
                        }
                    }
                }
            }
        }
    }
    let mut chains: FastMap<usize, Vec<usize>> = FastMap::default();
    for i in 0..n {
        let r = root(&mut parent, i);
        chains.entry(r).or_default().push(i);
    }
    let mut roots: Vec<usize> = chains.keys().copied().collect();
    roots.sort_unstable();
    let mut out = Vec::with_capacity(roots.len());
    for r in roots {
        let members = &chains[&r];
        let [a0, b0] = segments[members[0]];
        let d = (b0 - a0).normalize_or_zero();
        // Each member as an interval along d, with its end points.
        let mut spans: Vec<(f64, DVec3, f64, DVec3)> = members
            .iter()
            .map(|&m| {
                let [p, q] = segments[m];
                let (tp, tq) = ((p - a0).dot(d), (q - a0).dot(d));
                if tp <= tq {
                    (tp, p, tq, q)
                } else {
                    (tq, q, tp, p)
                }
            })
            .collect();
        spans.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut current = spans[0];
        for &s in &spans[1..] {
            if s.0 <= current.2 + eps {
                if s.2 > current.2 {
                    (current.2, current.3) = (s.2, s.3);
                }
            } else {
                out.push([current.1, current.3]);
                current = s;
            }
        }
        out.push([current.1, current.3]);
    }
    out
}

/// Is the edge `p q` of a triangle whose third corner is `r` a contact segment of triangle `t`
/// (plane `normal . x = offset`)?
#[allow(clippy::too_many_arguments)]
fn is_contact(
    p: DVec3,
    q: DVec3,
    r: DVec3,
    t: &Triangle,
    normal: DVec3,
    offset: f64,
    double_sided: bool,
    tol: &Tolerances,
) -> bool {
    let h = |x: DVec3| normal.dot(x) - offset;
    if h(p).abs() > tol.plane_m || h(q).abs() > tol.plane_m {
        return false;
    }
    // The other triangle must rise off the plane on a radiosity side.
    let hr = h(r);
    if !(hr > tol.plane_m || (double_sided && hr < -tol.plane_m)) {
        return false;
    }
    crosses_interior(p, q, t, normal, tol)
}

/// Does the segment `p q` (in the plane of `t`, unit `normal`) cross `t`'s interior over more than
/// the length tolerance?
fn crosses_interior(p: DVec3, q: DVec3, t: &Triangle, normal: DVec3, tol: &Tolerances) -> bool {
    interior_span(p, q, t, normal, tol.length_m)
        .is_some_and(|(t0, t1)| (t1 - t0) * p.distance(q) > tol.length_m)
}

/// The parameters `[t0, t1]` of the part of segment `p + (q - p) s` at least `inset` inside `t`'s
/// edges, when there is one.
fn interior_span(
    p: DVec3,
    q: DVec3,
    t: &Triangle,
    normal: DVec3,
    inset: f64,
) -> Option<(f64, f64)> {
    let d = q - p;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    if d.length() <= 0.0 {
        return None;
    }
    for k in 0..3 {
        let a = t.vertices[k];
        let b = t.vertices[(k + 1) % 3];
        // Inward normal of edge a b within the plane.
        let m = normal.cross(b - a);
        let m = m / m.length();
        let f0 = m.dot(p - a);
        let fd = m.dot(d);
        // Points with m . (x - a) >= inset are inside this edge.
        if fd.abs() < 1e-300 {
            if f0 < inset {
                return None;
            }
        } else {
            let tc = (inset - f0) / fd;
            if fd > 0.0 {
                t0 = t0.max(tc);
            } else {
                t1 = t1.min(tc);
            }
        }
    }
    (t1 > t0).then_some((t0, t1))
}

/// Where triangle `s` passes through the plane of triangle `t` (`normal . x = offset`), clipped to
/// `t`'s interior when it crosses it: the part of `t` inside the solid `s` bounds is closed off
/// and dark, like a footprint. `s` must have corners strictly on both sides of the plane.
fn crossing(
    s: &Triangle,
    t: &Triangle,
    normal: DVec3,
    offset: f64,
    tol: &Tolerances,
) -> Option<[DVec3; 2]> {
    let h = s.vertices.map(|v| normal.dot(v) - offset);
    if !(h.iter().any(|&x| x > tol.plane_m) && h.iter().any(|&x| x < -tol.plane_m)) {
        return None;
    }
    let mut ends: Vec<DVec3> = Vec::with_capacity(3);
    for k in 0..3 {
        let (a, b) = (s.vertices[k], s.vertices[(k + 1) % 3]);
        let (ha, hb) = (h[k], h[(k + 1) % 3]);
        if ha.abs() <= tol.plane_m {
            ends.push(a);
        } else if (ha > tol.plane_m && hb < -tol.plane_m) || (ha < -tol.plane_m && hb > tol.plane_m)
        {
            ends.push(a + (b - a) * (ha / (ha - hb)));
        }
    }
    let [p, q] = ends[..] else {
        return None;
    };
    // Onto the plane exactly, so that cuts and barriers lie in it. (The segment depends on `s`
    // and `t` only, not on which crossing edge of `s` found `t`: both finds give the same one.)
    let (p, q) = (
        p - normal * (normal.dot(p) - offset),
        q - normal * (normal.dot(q) - offset),
    );
    if !crosses_interior(p, q, t, normal, tol) {
        return None;
    }
    let (t0, t1) = interior_span(p, q, t, normal, 0.0)?;
    Some([p + (q - p) * t0, p + (q - p) * t1])
}

/// Splits the convex polygon `poly` (counter-clockwise about `normal`) by the line of every
/// segment in `lines`; returns the convex pieces. Corners within `eps` of a line count as on it.
fn split_convex(
    poly: Vec<DVec3>,
    normal: DVec3,
    lines: &[[DVec3; 2]],
    eps: f64,
) -> Vec<Vec<DVec3>> {
    let mut pieces = vec![poly];
    for &[p, q] in lines {
        let m = normal.cross(q - p);
        let len = m.length();
        if len <= 0.0 {
            continue;
        }
        let m = m / len;
        let mut next = Vec::with_capacity(pieces.len() + 1);
        for piece in pieces {
            let dist: Vec<f64> = piece.iter().map(|&x| m.dot(x - p)).collect();
            let above = dist.iter().any(|&d| d > eps);
            let below = dist.iter().any(|&d| d < -eps);
            if !(above && below) {
                next.push(piece);
                continue;
            }
            let (mut left, mut right) = (Vec::new(), Vec::new());
            for i in 0..piece.len() {
                let j = (i + 1) % piece.len();
                let (a, b) = (piece[i], piece[j]);
                let (da, db) = (dist[i], dist[j]);
                let side_a = side(da, eps);
                if side_a >= 0 {
                    left.push(a);
                }
                if side_a <= 0 {
                    right.push(a);
                }
                let side_b = side(db, eps);
                if side_a * side_b < 0 {
                    let x = a + (b - a) * (da / (da - db));
                    left.push(x);
                    right.push(x);
                }
            }
            next.push(left);
            next.push(right);
        }
        pieces = next;
    }
    for piece in &mut pieces {
        drop_collinear(piece, eps);
    }
    pieces.retain(|p| p.len() >= 3);
    pieces
}

/// Removes corners within `eps` of the line through their neighbours (left on a piece's side by
/// a cut through it), so that the fan makes no flat triangles.
fn drop_collinear(poly: &mut Vec<DVec3>, eps: f64) {
    let mut i = 0;
    while poly.len() > 3 && i < poly.len() {
        let n = poly.len();
        let (a, b, c) = (poly[(i + n - 1) % n], poly[i], poly[(i + 1) % n]);
        let d = c - a;
        let len = d.length();
        let off = if len > 0.0 {
            (b - a).cross(d).length() / len
        } else {
            0.0
        };
        if off <= eps {
            poly.remove(i);
        } else {
            i += 1;
        }
    }
}

fn side(d: f64, eps: f64) -> i32 {
    if d > eps {
        1
    } else if d < -eps {
        -1
    } else {
        0
    }
}

/// Fans a convex polygon into triangles from its first corner (winding kept).
fn fan(poly: &[DVec3]) -> Vec<[DVec3; 3]> {
    (1..poly.len().saturating_sub(1))
        .map(|i| [poly[0], poly[i], poly[i + 1]])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: DVec3, b: DVec3, c: DVec3) -> Triangle {
        Triangle::numbered([a, b, c], 0, 0)
    }

    fn tol() -> Tolerances {
        Tolerances {
            length_m: 1e-6,
            plane_m: 1e-6,
            angle_rad: 1e-3,
        }
    }

    fn area(ts: &[Triangle]) -> f64 {
        ts.iter().map(|t| t.area()).sum()
    }

    #[test]
    fn a_wall_standing_across_a_triangle_cuts_it_and_keeps_its_area() {
        let floor = tri(
            DVec3::ZERO,
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, -4.0),
        );
        // Floor normal: (4,0,0) x (0,0,-4) = (0,16,0): up. A wall in the plane x = 1 rising up.
        let wall = tri(
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, -5.0),
            DVec3::new(1.0, 2.0, 0.0),
        );
        let cut = cut_at_contacts(&[floor, wall], |_| false, &tol(), 10.0, 1e-12);
        assert_eq!(cut.triangles_cut, 1);
        assert_eq!(cut.segments.len(), 1);
        let floor_pieces: Vec<Triangle> = cut
            .pieces
            .iter()
            .zip(&cut.source)
            .filter(|(_, &s)| s == 0)
            .map(|(t, _)| *t)
            .collect();
        assert_eq!(floor_pieces.len(), 3, "a triangle and a quad");
        assert!((area(&floor_pieces) - floor.area()).abs() < 1e-12);
        for p in &floor_pieces {
            assert!(p.cross().dot(DVec3::Y) > 0.0, "winding kept");
            // No piece straddles x = 1.
            let xs: Vec<f64> = p.vertices.iter().map(|v| v.x).collect();
            assert!(xs.iter().all(|&x| x <= 1.0 + 1e-12) || xs.iter().all(|&x| x >= 1.0 - 1e-12));
        }
    }

    #[test]
    fn surfaces_below_the_plane_or_along_its_border_are_not_contacts() {
        let floor = tri(
            DVec3::ZERO,
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, -4.0),
        );
        // Hanging below the floor (its back side): no cut for a single-sided floor.
        let below = tri(
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, -5.0),
            DVec3::new(1.0, -2.0, 0.0),
        );
        // Standing on the floor's border edge z = 0.
        let border = tri(
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(5.0, 0.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        );
        let cut = cut_at_contacts(&[floor, below, border], |_| false, &tol(), 10.0, 1e-12);
        assert_eq!(cut.triangles_cut, 0);
        assert_eq!(cut.pieces.len(), 3);
        // Double-sided, the hanging wall does cut.
        let cut = cut_at_contacts(&[floor, below], |_| true, &tol(), 10.0, 1e-12);
        assert_eq!(cut.triangles_cut, 1);
    }

    #[test]
    fn a_line_through_a_corner_makes_no_sliver() {
        let floor = tri(
            DVec3::ZERO,
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, -4.0),
        );
        // The wall's base passes within 1e-9 of the floor's corner (4,0,0) and through the middle
        // (0,0,-2) of the opposite edge: two pieces, no sliver at the corner.
        let wall = tri(
            DVec3::new(4.0 + 1e-9, 0.0, 0.0),
            DVec3::new(-4.0, 0.0, -4.0),
            DVec3::new(1.0, 2.0, -1.0),
        );
        let cut = cut_at_contacts(&[floor, wall], |_| false, &tol(), 10.0, 1e-12);
        let floor_pieces: Vec<&Triangle> = cut
            .pieces
            .iter()
            .zip(&cut.source)
            .filter(|(_, &s)| s == 0)
            .map(|(t, _)| t)
            .collect();
        assert_eq!(floor_pieces.len(), 2);
        for p in floor_pieces {
            assert!(p.area() > 1e-3, "sliver of area {}", p.area());
        }
    }

    #[test]
    fn collinear_segments_that_continue_one_another_are_joined() {
        let v = |x: f64, z: f64| DVec3::new(x, 0.0, z);
        let joined = join_collinear(
            &[
                [v(0.0, 0.0), v(1.0, 0.0)],
                [v(2.0, 0.0), v(1.0, 0.0)], // continues the first, reversed
                [v(0.5, 0.0), v(1.5, 0.0)], // overlaps both, shares no end
                [v(1.0, 0.0), v(1.0, 1.0)], // perpendicular at the joint
                [v(3.0, 0.0), v(4.0, 0.0)], // same line, past a gap
            ],
            1e-9,
        );
        let mut lengths: Vec<f64> = joined.iter().map(|[a, b]| a.distance(*b)).collect();
        lengths.sort_by(f64::total_cmp);
        // The overlapping one shares no end, so it stays as it is.
        assert_eq!(lengths, vec![1.0, 1.0, 1.0, 2.0], "{joined:?}");
        assert!(joined
            .iter()
            .any(|s| s.contains(&v(0.0, 0.0)) && s.contains(&v(2.0, 0.0))));
    }
}
