//! Face validation: reports every problem of a face set, each with its face, ring and vertex.
//!
//! Owns [`validate_faces`], [`validate_face`] and [`FaceProblem`]. A valid face has: a unit normal;
//! rings of at least 3 vertices without zero-length edges, all within twice the set's length
//! tolerance of the face's plane; an outer ring counter-clockwise and holes clockwise about the
//! normal; no two ring edges crossing or overlapping, and no ring touching itself (rings may touch
//! each other at isolated vertices, without crossing there); every hole inside the outer ring and
//! outside every other hole; a ring area equal to its triangulation's (within the length tolerance
//! times the perimeter, which collinear-vertex removal may move); an `area_m2` equal to the sum of
//! its triangles' areas (within the tolerance the weld may move them); a `kind` matching
//! [`classify`]. A valid set numbers its faces in order and accounts for every scene triangle
//! exactly once (in one face, or dropped as degenerate).
//!
//! Ring numbers in problems: 0 is the outer ring, `h + 1` is hole `h`. Turn, crossing and
//! containment tests are exact in the face's [`Projection`]; no problem ever panics.

use super::geom::{
    locate_by_winding, on_segment, orient, signed_area, FastSet, Location, Projection,
};
#[cfg(test)]
use super::FaceKind;
use super::{classify, Face, FaceId, FaceSet};
use glam::{DVec2, DVec3};
use std::fmt;

/// One problem of a face set, with its place.
#[derive(Debug, Clone, PartialEq)]
pub struct FaceProblem {
    /// The face (`None` for a problem of the set as a whole).
    pub face: Option<FaceId>,
    /// The ring: 0 is the outer ring, `h + 1` is hole `h`.
    pub ring: Option<usize>,
    /// The vertex index within the ring.
    pub vertex: Option<usize>,
    pub message: String,
}

impl fmt::Display for FaceProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.face {
            Some(id) => write!(f, "face {}", id.0)?,
            None => write!(f, "face set")?,
        }
        match self.ring {
            Some(0) => write!(f, " outer ring")?,
            Some(r) => write!(f, " hole {}", r - 1)?,
            None => {}
        }
        if let Some(v) = self.vertex {
            write!(f, " vertex {v}")?;
        }
        write!(f, ": {}", self.message)
    }
}

/// Validates every face of the set and the set's bookkeeping; returns every problem found.
pub fn validate_faces(faces: &FaceSet) -> Vec<FaceProblem> {
    let mut out = Vec::new();
    let set_problem = |message: String| FaceProblem {
        face: None,
        ring: None,
        vertex: None,
        message,
    };
    let pieces = faces.piece_source.len();
    if faces.face_of_triangle.len() != pieces {
        out.push(set_problem(format!(
            "face_of_triangle has {} entries for {pieces} pieces",
            faces.face_of_triangle.len(),
        )));
    }
    if faces.piece_source.windows(2).any(|w| w[0] > w[1])
        || faces
            .piece_source
            .last()
            .is_some_and(|&s| s as usize >= faces.triangles_in)
    {
        out.push(set_problem(
            "piece_source is not ascending within the scene's triangles".into(),
        ));
    }
    let unassigned = faces
        .face_of_triangle
        .iter()
        .filter(|f| f.is_none())
        .count();
    if unassigned != faces.degenerate_dropped {
        out.push(set_problem(format!(
            "{unassigned} triangles are in no face but {} were counted as dropped",
            faces.degenerate_dropped
        )));
    }
    let mut in_faces = 0;
    for (i, face) in faces.faces.iter().enumerate() {
        if face.id != FaceId(i as u32) {
            out.push(FaceProblem {
                face: Some(face.id),
                ring: None,
                vertex: None,
                message: format!("is at position {i} of the set"),
            });
        }
        in_faces += face.triangles.len();
        for &t in &face.triangles {
            if faces.face_of_triangle.get(t as usize) != Some(&Some(face.id)) {
                out.push(FaceProblem {
                    face: Some(face.id),
                    ring: None,
                    vertex: None,
                    message: format!(
                        "lists triangle {t}, which face_of_triangle does not map back"
                    ),
                });
            }
        }
        out.extend(validate_face(face, faces.tolerance_m));
    }
    if in_faces + faces.degenerate_dropped != pieces {
        out.push(set_problem(format!(
            "{in_faces} pieces in faces + {} dropped != {pieces} pieces",
            faces.degenerate_dropped
        )));
    }
    out
}

/// A ring edge in the face's projection.
#[derive(Debug, Clone, Copy)]
struct Seg {
    ring: usize,
    idx: usize,
    a: DVec2,
    b: DVec2,
    lo: DVec2,
    hi: DVec2,
}

/// Where a ring vertex touches another ring.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Touch {
    /// At that ring's vertex.
    Vertex(usize, usize),
    /// In the interior of that ring's edge (from vertex `idx` to `idx + 1`).
    Edge(usize, usize),
}

/// Validates one face with the set's length tolerance (metres).
pub fn validate_face(face: &Face, tolerance_m: f64) -> Vec<FaceProblem> {
    let mut out = Vec::new();
    let mut problem = |ring: Option<usize>, vertex: Option<usize>, message: String| {
        out.push(FaceProblem {
            face: Some(face.id),
            ring,
            vertex,
            message,
        })
    };
    let n = face.normal;
    let unit = (n.length() - 1.0).abs() <= 1e-9;
    if !unit {
        problem(None, None, format!("normal {n} is not a unit vector"));
        return out;
    }
    if face.triangles.is_empty() || face.triangulation.is_empty() {
        problem(None, None, "came from no triangle".into());
    }
    if face.triangles.len() != face.triangulation.len() {
        problem(
            None,
            None,
            format!(
                "lists {} triangles but its triangulation has {}",
                face.triangles.len(),
                face.triangulation.len()
            ),
        );
    }
    if !(face.area_m2 > 0.0 && face.area_m2.is_finite()) {
        problem(None, None, format!("area {} is not positive", face.area_m2));
    }
    let kind = classify(&face.outer, &face.holes);
    if kind != face.kind {
        problem(
            None,
            None,
            format!(
                "is marked {} but is a {}",
                face.kind.as_str(),
                kind.as_str()
            ),
        );
    }
    let rings: Vec<&[DVec3]> = std::iter::once(face.outer.as_slice())
        .chain(face.holes.iter().map(Vec::as_slice))
        .collect();
    for (r, ring) in rings.iter().enumerate() {
        if ring.len() < 3 {
            problem(Some(r), None, format!("has {} vertices", ring.len()));
        }
        if let Some(i) = ring.iter().position(|p| !p.is_finite()) {
            problem(Some(r), Some(i), "is not finite".into());
            return out;
        }
    }

    // Plane.
    let mut weighted = DVec3::ZERO;
    let mut total = 0.0;
    for t in &face.triangulation {
        let a = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
        weighted += a * (t[0] + t[1] + t[2]) / 3.0;
        total += a;
    }
    let origin = if total > 0.0 {
        weighted / total
    } else {
        face.outer.first().copied().unwrap_or(DVec3::ZERO)
    };
    let plane_tol = 2.0 * tolerance_m;
    for (r, ring) in rings.iter().enumerate() {
        for (i, p) in ring.iter().enumerate() {
            let off = n.dot(*p - origin);
            if off.abs() > plane_tol {
                problem(
                    Some(r),
                    Some(i),
                    format!("is {off:e} m off the face's plane"),
                );
            }
        }
    }
    for (k, t) in face.triangulation.iter().enumerate() {
        if (t[1] - t[0]).cross(t[2] - t[0]).dot(n) <= 0.0 {
            problem(
                None,
                None,
                format!("triangle {k} of its triangulation is flat or faces backwards"),
            );
        }
        for p in t {
            let off = n.dot(*p - origin);
            if off.abs() > plane_tol {
                problem(
                    None,
                    None,
                    format!("triangle {k} of its triangulation is {off:e} m off the plane"),
                );
                break;
            }
        }
    }

    // Orientation and zero-length edges, in the exact projection.
    let proj = Projection::for_normal(n);
    let scale = proj.area_scale(n);
    let flat: Vec<Vec<DVec2>> = rings
        .iter()
        .map(|r| r.iter().map(|&p| proj.apply(p)).collect())
        .collect();
    let mut ring_area = 0.0;
    let mut perimeter = 0.0;
    for (r, ring) in flat.iter().enumerate() {
        if ring.len() < 3 {
            continue;
        }
        let area = signed_area(ring) / scale;
        ring_area += area;
        if r == 0 && area <= 0.0 {
            problem(
                Some(r),
                None,
                format!("is not counter-clockwise about the normal (signed area {area:e})"),
            );
        }
        if r > 0 && area >= 0.0 {
            problem(
                Some(r),
                None,
                format!("is not clockwise about the normal (signed area {area:e})"),
            );
        }
        for i in 0..ring.len() {
            let j = (i + 1) % ring.len();
            perimeter += rings[r][i].distance(rings[r][j]);
            if ring[i] == ring[j] {
                problem(
                    Some(r),
                    Some(i),
                    "starts a zero-length edge (in the face's plane)".into(),
                );
            }
        }
    }

    // Crossings, overlaps and contacts.
    let mut segs: Vec<Seg> = Vec::new();
    for (r, ring) in flat.iter().enumerate() {
        if ring.len() < 3 {
            continue;
        }
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            segs.push(Seg {
                ring: r,
                idx: i,
                a,
                b,
                lo: a.min(b),
                hi: a.max(b),
            });
        }
    }
    segs.sort_by(|x, y| x.lo.x.total_cmp(&y.lo.x));
    let ring_len = |r: usize| flat[r].len();
    let mut touches: FastSet<(usize, usize, Touch)> = FastSet::default();
    let mut reported: FastSet<(usize, usize, usize, usize)> = FastSet::default();
    for i in 0..segs.len() {
        let e = segs[i];
        for f in &segs[i + 1..] {
            if f.lo.x > e.hi.x {
                break;
            }
            if f.lo.y > e.hi.y || f.hi.y < e.lo.y {
                continue;
            }
            let (e, f) = if (e.ring, e.idx) < (f.ring, f.idx) {
                (e, *f)
            } else {
                (*f, e)
            };
            let len = ring_len(e.ring);
            if e.ring == f.ring && ((e.idx + 1) % len == f.idx || (f.idx + 1) % len == e.idx) {
                // Adjacent edges: only a fold back (a spike) is wrong.
                let (x, s, y, v) = if (e.idx + 1) % len == f.idx {
                    (e.a, e.b, f.b, f.idx)
                } else {
                    (f.a, f.b, e.b, e.idx)
                };
                if orient(x, s, y) == 0.0 && (x - s).dot(y - s) > 0.0 {
                    problem(
                        Some(e.ring),
                        Some(v),
                        "the ring folds back on itself".into(),
                    );
                }
                continue;
            }
            let o1 = orient(e.a, e.b, f.a);
            let o2 = orient(e.a, e.b, f.b);
            let o3 = orient(f.a, f.b, e.a);
            let o4 = orient(f.a, f.b, e.b);
            if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
                if reported.insert((e.ring, e.idx, f.ring, f.idx)) {
                    problem(
                        Some(e.ring),
                        Some(e.idx),
                        format!(
                            "edge {} crosses edge {} of {}",
                            e.idx,
                            f.idx,
                            ring_name(f.ring)
                        ),
                    );
                }
                continue;
            }
            if o1 == 0.0 && o2 == 0.0 {
                // Collinear: overlapping over a length is wrong, touching at a point is a contact.
                let d = e.b - e.a;
                let key = |p: DVec2| if d.x.abs() >= d.y.abs() { p.x } else { p.y };
                let (e0, e1) = (key(e.a).min(key(e.b)), key(e.a).max(key(e.b)));
                let (f0, f1) = (key(f.a).min(key(f.b)), key(f.a).max(key(f.b)));
                if e1.min(f1) > e0.max(f0) {
                    if reported.insert((e.ring, e.idx, f.ring, f.idx)) {
                        problem(
                            Some(e.ring),
                            Some(e.idx),
                            format!(
                                "edge {} overlaps edge {} of {}",
                                e.idx,
                                f.idx,
                                ring_name(f.ring)
                            ),
                        );
                    }
                    continue;
                }
            }
            for (p, owner, other) in [(f.a, f, e), (f.b, f, e), (e.a, e, f), (e.b, e, f)] {
                if !on_segment(other.a, other.b, p) {
                    continue;
                }
                let v = if p == owner.a {
                    owner.idx
                } else {
                    (owner.idx + 1) % ring_len(owner.ring)
                };
                let at = if p == other.a {
                    Touch::Vertex(other.ring, other.idx)
                } else if p == other.b {
                    Touch::Vertex(other.ring, (other.idx + 1) % ring_len(other.ring))
                } else {
                    Touch::Edge(other.ring, other.idx)
                };
                // One record per vertex-vertex contact.
                let key = match at {
                    Touch::Vertex(r2, v2) if (r2, v2) < (owner.ring, v) => {
                        (r2, v2, Touch::Vertex(owner.ring, v))
                    }
                    _ => (owner.ring, v, at),
                };
                touches.insert(key);
            }
        }
    }
    let mut touches: Vec<_> = touches.into_iter().collect();
    touches.sort_by_key(|&(r, v, t)| {
        (
            r,
            v,
            match t {
                Touch::Vertex(a, b) => (0, a, b),
                Touch::Edge(a, b) => (1, a, b),
            },
        )
    });
    for (r, v, at) in touches {
        let here = flat[r][v];
        let around = |ring: usize, i: usize| {
            let l = ring_len(ring);
            (
                flat[ring][(i + l - 1) % l] - here,
                flat[ring][(i + 1) % l] - here,
            )
        };
        let (a1, a2) = around(r, v);
        let ((b1, b2), other, what) = match at {
            Touch::Vertex(r2, v2) => (around(r2, v2), r2, format!("vertex {v2}")),
            Touch::Edge(r2, e2) => {
                let l = ring_len(r2);
                (
                    (flat[r2][e2] - here, flat[r2][(e2 + 1) % l] - here),
                    r2,
                    format!("edge {e2}"),
                )
            }
        };
        if other == r {
            problem(
                Some(r),
                Some(v),
                format!("the ring touches itself at its {what}"),
            );
        } else if crosses_at_point(a1, a2, b1, b2) {
            problem(
                Some(r),
                Some(v),
                format!("crosses {} here (at its {what})", ring_name(other)),
            );
        }
    }

    // Holes inside the outer ring and outside each other.
    if flat.iter().all(|r| r.len() >= 3) {
        for h in 1..flat.len() {
            match sample_location(&flat[h], &flat[0]) {
                Some(Location::Inside) => {}
                Some(_) => problem(Some(h), None, "is not inside the outer ring".into()),
                None => problem(Some(h), None, "lies on the outer ring".into()),
            }
        }
        let bbox = |r: &[DVec2]| {
            r.iter().fold(
                (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
                |(lo, hi), &p| (lo.min(p), hi.max(p)),
            )
        };
        let boxes: Vec<(DVec2, DVec2)> = flat.iter().map(|r| bbox(r)).collect();
        for h in 1..flat.len() {
            for g in 1..flat.len() {
                let (bh, bg) = (boxes[h], boxes[g]);
                if g == h || bh.0.cmplt(bg.0).any() || bh.1.cmpgt(bg.1).any() {
                    continue;
                }
                if sample_location(&flat[h], &flat[g]) == Some(Location::Inside) {
                    problem(Some(h), None, format!("lies inside hole {}", g - 1));
                }
            }
        }
    }

    // Areas.
    let tri_flat: f64 = face
        .triangulation
        .iter()
        .map(|t| signed_area(&[proj.apply(t[0]), proj.apply(t[1]), proj.apply(t[2])]) / scale)
        .sum();
    let slack = tolerance_m * perimeter + 1e-9 * tri_flat.abs();
    if (ring_area - tri_flat).abs() > slack {
        problem(
            None,
            None,
            format!("rings enclose {ring_area:e} m^2 but its triangles cover {tri_flat:e} m^2"),
        );
    }
    let mut tri_area = 0.0;
    let mut tri_slack = 0.0;
    for t in &face.triangulation {
        tri_area += 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
        tri_slack +=
            tolerance_m * (t[0].distance(t[1]) + t[1].distance(t[2]) + t[2].distance(t[0]));
    }
    if (face.area_m2 - tri_area).abs() > tri_slack + 1e-9 * tri_area {
        problem(
            None,
            None,
            format!(
                "area_m2 is {:e} but its triangles' areas sum to {tri_area:e}",
                face.area_m2
            ),
        );
    }
    out
}

/// A ring's name in messages, matching [`FaceProblem`]'s display.
fn ring_name(r: usize) -> String {
    if r == 0 {
        "the outer ring".into()
    } else {
        format!("hole {}", r - 1)
    }
}

/// Where `ring` lies relative to `other`: the location of its first vertex (then edge midpoint)
/// not on `other`'s boundary; `None` when all lie on it.
fn sample_location(ring: &[DVec2], other: &[DVec2]) -> Option<Location> {
    let l = ring.len();
    let samples = ring
        .iter()
        .copied()
        .chain((0..l).map(|i| 0.5 * (ring[i] + ring[(i + 1) % l])));
    for p in samples {
        match locate_by_winding(&[other], p) {
            Location::Boundary => continue,
            loc => return Some(loc),
        }
    }
    None
}

/// Two rings meeting at a point (ring A's edges leave along `a1`, `a2`, ring B's along `b1`, `b2`)
/// cross there when A's directions separate B's.
fn crosses_at_point(a1: DVec2, a2: DVec2, b1: DVec2, b2: DVec2) -> bool {
    let angle = |d: DVec2| d.to_angle().rem_euclid(std::f64::consts::TAU);
    let (t1, t2) = (angle(b1), angle(b2));
    let inside = |d: DVec2| {
        let t = angle(d);
        // Strictly inside the counter-clockwise arc from t1 to t2.
        let span = (t2 - t1).rem_euclid(std::f64::consts::TAU);
        let at = (t - t1).rem_euclid(std::f64::consts::TAU);
        if at == 0.0 || at == span {
            None
        } else {
            Some(at < span)
        }
    };
    match (inside(a1), inside(a2)) {
        (Some(x), Some(y)) => x != y,
        // A shared direction is an overlap, reported with the edges.
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::faces::{merge_planar_faces, triangulate_polygon};
    use crate::scene::{Material, Scene, Triangle, TriangleSource};

    fn ring(pts: &[(f64, f64)]) -> Vec<DVec3> {
        pts.iter().map(|&(x, y)| DVec3::new(x, y, 0.0)).collect()
    }

    /// A valid 6 x 6 square with two unit square holes, merged from its triangulation.
    fn valid_set() -> FaceSet {
        let rings = [
            ring(&[(0.0, 0.0), (6.0, 0.0), (6.0, 6.0), (0.0, 6.0)]),
            ring(&[(1.0, 1.0), (1.0, 2.0), (2.0, 2.0), (2.0, 1.0)]),
            ring(&[(4.0, 4.0), (4.0, 5.0), (5.0, 5.0), (5.0, 4.0)]),
        ];
        let flat: Vec<DVec3> = rings.concat();
        let rings2: Vec<Vec<DVec2>> = rings
            .iter()
            .map(|r| r.iter().map(|p| p.truncate()).collect())
            .collect();
        let triangles = triangulate_polygon(&rings2)
            .unwrap()
            .iter()
            .enumerate()
            .map(|(i, t)| Triangle {
                vertices: t.map(|k| flat[k]),
                material: 0,
                source: TriangleSource {
                    mesh: 0,
                    primitive: 0,
                    triangle: i as u32,
                },
            })
            .collect();
        let scene = Scene::new(triangles, vec![Material::gltf_default()], vec![], vec![]);
        let set = merge_planar_faces(&scene);
        assert_eq!(set.faces.len(), 1);
        assert!(validate_faces(&set).is_empty());
        set
    }

    fn messages(set: &FaceSet) -> Vec<String> {
        validate_faces(set).iter().map(|p| p.to_string()).collect()
    }

    fn has(msgs: &[String], parts: &[&str]) -> bool {
        msgs.iter().any(|m| parts.iter().all(|p| m.contains(p)))
    }

    #[test]
    fn wrong_orientation_is_reported() {
        let mut set = valid_set();
        set.faces[0].outer.reverse();
        let m = messages(&set);
        assert!(has(&m, &["outer ring", "not counter-clockwise"]), "{m:?}");
    }

    #[test]
    fn a_hole_inside_another_hole_is_reported() {
        let mut set = valid_set();
        set.faces[0].holes[1] = ring(&[(1.25, 1.25), (1.25, 1.75), (1.75, 1.75), (1.75, 1.25)]);
        let m = messages(&set);
        assert!(has(&m, &["hole 1", "lies inside hole 0"]), "{m:?}");
        assert!(has(&m, &["rings enclose"]), "{m:?}");
    }

    #[test]
    fn rings_crossing_at_shared_vertices_are_reported() {
        let mut set = valid_set();
        // Through two corners of hole 0, inside it along its diagonal, outside elsewhere.
        set.faces[0].holes[1] = ring(&[(1.0, 1.0), (2.0, 2.0), (2.5, 0.5)]);
        let m = messages(&set);
        assert!(has(&m, &["hole 0 vertex 0", "crosses hole 1"]), "{m:?}");
    }

    #[test]
    fn every_problem_of_a_face_is_reported_with_its_place() {
        let mut set = valid_set();
        let face = &mut set.faces[0];
        // Off-plane vertex, a self-touching outer ring, a clockwise hole turned counter-clockwise,
        // and a hole edge crossing the outer ring.
        face.outer = ring(&[
            (0.0, 0.0),
            (6.0, 0.0),
            (3.0, 3.0),
            (6.0, 6.0),
            (0.0, 6.0),
            (3.0, 3.0),
        ]);
        face.outer[1].z = 1.0;
        face.holes[0].reverse();
        face.holes[1] = ring(&[(4.0, 4.0), (4.0, 5.0), (7.0, 5.0), (5.0, 4.0)]);
        set.face_of_triangle[0] = None;
        let m = messages(&set);
        assert!(
            has(&m, &["outer ring vertex 1", "off the face's plane"]),
            "{m:?}"
        );
        assert!(has(&m, &["outer ring", "touches itself"]), "{m:?}");
        assert!(has(&m, &["hole 0", "not clockwise"]), "{m:?}");
        assert!(
            has(&m, &["hole 1", "crosses edge"]) || has(&m, &["outer ring", "crosses edge"]),
            "{m:?}"
        );
        assert!(has(&m, &["face set", "counted as dropped"]), "{m:?}");
        assert!(has(&m, &["face 0", "does not map back"]), "{m:?}");
        assert!(has(&m, &["is marked"]) || set.faces[0].kind == FaceKind::Extended);
    }
}
