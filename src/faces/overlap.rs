//! Overlaps: every piece of surface counted once.
//!
//! Exports hold duplicated triangles, decals and coplanar panels lying on walls, and z-fighting
//! copies. Left alone, each copy would be a surface of its own: each would receive the full
//! irradiance and reflect it, creating energy. This module runs on the pieces of
//! [`super::contact::cut_at_contacts`] (before welding and face merging) and leaves each region of
//! each radiosity side covered by one piece only.
//!
//! Owns [`resolve_overlaps`] and [`OverlapCut`]. Two live pieces are *coplanar* when their normals
//! agree within [`super::NORMAL_ANGLE_RAD`] (plus the slack of the thinner one, as in face merging)
//! up to sign, and each one's corners lie within the plane tolerance ([`super::PLANE_OFFSET_REL`])
//! of the other's plane. Coplanar pieces *share a side* when they face the same way, or when either
//! is double-sided (a double-sided piece faces both ways). Then:
//! - pieces with the same corners (within the weld tolerance, [`super::WELD_REL`]) that share a
//!   side are *duplicates*: the losing one (below) is dropped whole;
//! - pieces that share a side and whose interiors overlap (by more than the length tolerance across
//!   every separating direction) are cut: the losing one loses the overlapped region (the union
//!   of every piece that beats it is subtracted from it with `i_overlay`, in the exact 2-D
//!   [`Projection`] of its own plane; the rest is triangulated by
//!   [`super::triangulate_polygon`], triangles thinner than the length tolerance or below the
//!   degenerate area are dropped, and the corners are put back on the piece's own plane, or on
//!   the exact input corner they came from);
//! - pieces with the same corners facing opposite ways, both single-sided, are a zero-thickness
//!   wall: both sides are real surfaces, both are kept, and the pair is counted.
//!
//! The rule of who wins (the same for duplicates and overlaps): a double-sided piece beats a
//! single-sided one (it covers both of the single-sided piece's sides, so nothing is lost where the
//! single-sided one gives way); otherwise the piece whose scene triangle is listed later in the file
//! wins: later mesh in the file's `meshes`, then later primitive, then later triangle in the
//! primitive's index buffer (its `TriangleSource`; a mesh instanced twice falls back to the scene's
//! order). A decal or panel is usually listed after the wall it lies on; the last copy of a
//! duplicate is kept. The winner stays whole.
//!
//! Invariants: every output piece lies inside its input piece (so inside its source scene
//! triangle: textures are looked up through that triangle's UVs), up to the boolean engine's
//! rounding (under 1e-9 of the scene diagonal), keeps its material, `TriangleSource` and winding
//! (counter-clockwise about the same normal); pieces without an overlap pass through unchanged and
//! in order, and the cut pieces of one input piece take its place in the order; after resolution
//! no two live pieces that share a side overlap (within the tolerances). Pieces whose normals differ
//! by more than `NORMAL_ANGLE_RAD + SLACK_CAP_RAD` are never compared (only slivers have such
//! slack). Cost: pieces are bucketed by quantised plane (normal and offset, each piece entered in
//! every bucket within the tolerance of its plane, under both its normal and its opposite; about
//! 2.7 entries per piece on the Sauerbraten level), a sweep over bounding boxes inside each bucket
//! finds the touching pairs, each tested once (normals, plane distances, corners, separating axes:
//! in practice the coplanar neighbours sharing an edge). Only overlapping pieces reach the boolean
//! engine.

use super::adjacency::Tolerances;
use super::geom::{signed_area, FastMap, Projection};
use super::triangulate_polygon;
use crate::scene::{Triangle, TriangleSource};
use glam::{DVec2, DVec3};
use i_overlay::core::fill_rule::FillRule;
use i_overlay::core::overlay_rule::OverlayRule;
use i_overlay::float::single::SingleFloatOverlay;
use rayon::prelude::*;

/// Largest normal slack (radians) a piece's bucketing allows for, on top of the angle tolerance.
/// A piece thinner than `2 plane tolerance / SLACK_CAP_RAD` (1/2500 of the scene diagonal) may
/// have a noisier normal in theory; real exports' f32 noise is far below it.
pub const SLACK_CAP_RAD: f64 = 0.005;

/// Bucket size of the normal's components.
const NORMAL_CELL: f64 = 0.0625;
/// Bucket size of the plane offset, as a fraction of the scene diagonal.
const OFFSET_CELL_REL: f64 = 0.02;
/// Places named in a warning, at most.
const NAMED: usize = 6;

/// The pieces with every overlap resolved.
#[derive(Debug, Clone, Default)]
pub struct OverlapCut {
    /// The pieces: the input pieces, the losers of overlaps replaced by what is left of them,
    /// dropped duplicates removed, in input order.
    pub pieces: Vec<Triangle>,
    /// For each piece, the index of its scene triangle (the input piece's).
    pub source: Vec<u32>,
    /// Scene triangles with a piece dropped as a duplicate of a piece that beats it.
    pub duplicates_dropped: usize,
    /// Scene triangles with a piece that lost area (part or all of it) to coplanar pieces sharing
    /// a side that beat it (duplicates not counted).
    pub overlaps_cut: usize,
    /// Pairs of scene triangles with the same corners (within the weld tolerance) facing opposite
    /// ways, both single-sided, with coincident pieces: both kept.
    pub back_to_back_kept: usize,
    /// Area taken away by dropped duplicates and cuts (m^2).
    pub area_removed_m2: f64,
    /// What the user should hear about (duplicates dropped, overlaps cut, with their places).
    pub warnings: Vec<String>,
}

/// A live piece's plane and box.
#[derive(Debug, Clone, Copy)]
struct Info {
    normal: DVec3,
    /// `normal . centroid`.
    offset: f64,
    /// `cos(angle tolerance + slack)`, the least dot product of a coplanar normal.
    cos_allowed: f64,
    double_sided: bool,
    lo: DVec3,
    hi: DVec3,
}

/// What a candidate pair turned out to be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Relation {
    Duplicate,
    Overlap,
    BackToBack,
}

/// Resolves the overlaps of `pieces` (`source[i]` is piece `i`'s scene triangle, in `triangles`,
/// the scene's triangles). `min_area` is
/// the degenerate-area threshold; smaller pieces, and pieces thinner than the length tolerance,
/// are passed through untouched (face merging drops them).
pub fn resolve_overlaps(
    triangles: &[Triangle],
    pieces: Vec<Triangle>,
    source: Vec<u32>,
    double_sided: impl Fn(&Triangle) -> bool + Sync,
    tol: &Tolerances,
    diagonal: f64,
    min_area: f64,
) -> OverlapCut {
    let n = pieces.len();
    let pass = |pieces: Vec<Triangle>, source: Vec<u32>| OverlapCut {
        pieces,
        source,
        ..Default::default()
    };
    if n < 2 || !(diagonal > 0.0 && diagonal.is_finite()) {
        return pass(pieces, source);
    }
    let infos: Vec<Option<Info>> = pieces
        .par_iter()
        .map(|t| piece_info(t, double_sided(t), tol, min_area))
        .collect();
    let related = related_pairs(&pieces, &infos, tol, diagonal);
    if related.is_empty() {
        return pass(pieces, source);
    }
    // Precedence: double-sided first, then listed later in the file (mesh, primitive, index in
    // the primitive; the scene's order follows the node graph), then the later piece.
    let beats = |a: usize, b: usize| {
        let key = |i: usize| {
            let p = pieces[i].source;
            (
                infos[i].is_some_and(|x| x.double_sided),
                (p.mesh, p.primitive, p.triangle),
                i as u32,
            )
        };
        key(a) > key(b)
    };
    let mut dropped = vec![false; n];
    let mut clips: FastMap<u32, Vec<u32>> = FastMap::default();
    let mut back_to_back: Vec<(u32, u32)> = Vec::new();
    for &(i, j, r) in &related {
        let (win, lose) = if beats(i as usize, j as usize) {
            (i, j)
        } else {
            (j, i)
        };
        match r {
            Relation::Duplicate => dropped[lose as usize] = true,
            Relation::Overlap => clips.entry(lose).or_default().push(win),
            Relation::BackToBack => {
                // Counted on the scene's triangles: pieces of a contact cut may coincide where
                // their triangles do not.
                let (a, b) = (source[i as usize], source[j as usize]);
                let (ta, tb) = (&triangles[a as usize], &triangles[b as usize]);
                if coincident(&ta.vertices, &tb.vertices, false, tol.length_m) {
                    back_to_back.push((a.min(b), a.max(b)));
                }
            }
        }
    }
    back_to_back.sort_unstable();
    back_to_back.dedup();

    // Cut the losers (a dropped winner's own winner beats the loser too, and is listed).
    let mut losers: Vec<(u32, Vec<u32>)> = clips
        .into_iter()
        .filter(|(lose, _)| !dropped[*lose as usize])
        .map(|(lose, mut winners)| {
            winners.retain(|&w| !dropped[w as usize]);
            winners.sort_unstable();
            winners.dedup();
            (lose, winners)
        })
        .filter(|(_, w)| !w.is_empty())
        .collect();
    losers.sort_unstable_by_key(|l| l.0);
    let cuts: Vec<(u32, Option<Vec<Triangle>>)> = losers
        .par_iter()
        .map(|(lose, winners)| {
            let l = *lose as usize;
            let info = infos[l].expect("a related piece is live");
            (
                *lose,
                subtract(&pieces[l], info, winners, &pieces, tol, min_area),
            )
        })
        .collect();
    let mut replaced: FastMap<u32, Vec<Triangle>> = FastMap::default();
    for (lose, cut) in cuts {
        if let Some(tris) = cut {
            replaced.insert(lose, tris);
        }
    }

    // Assemble, in order.
    let mut out = OverlapCut::default();
    let mut dup_sources: Vec<u32> = Vec::new();
    let mut cut_sources: Vec<u32> = Vec::new();
    for (i, t) in pieces.iter().enumerate() {
        if dropped[i] {
            dup_sources.push(source[i]);
            out.area_removed_m2 += t.area();
            continue;
        }
        if let Some(tris) = replaced.get(&(i as u32)) {
            cut_sources.push(source[i]);
            out.area_removed_m2 += t.area() - tris.iter().map(Triangle::area).sum::<f64>();
            for tri in tris {
                out.pieces.push(*tri);
                out.source.push(source[i]);
            }
            continue;
        }
        out.pieces.push(*t);
        out.source.push(source[i]);
    }
    let places = |sources: &mut Vec<u32>| -> Vec<TriangleSource> {
        sources.sort_unstable();
        sources.dedup();
        sources
            .iter()
            .map(|&s| {
                // A piece of this scene triangle carries its place.
                let k = source_piece(&source, s);
                pieces[k].source
            })
            .collect()
    };
    let dups = places(&mut dup_sources);
    let cut = places(&mut cut_sources);
    out.duplicates_dropped = dups.len();
    out.overlaps_cut = cut.len();
    out.back_to_back_kept = back_to_back.len();
    if !dups.is_empty() {
        out.warnings.push(format!(
            "{} duplicated triangle(s) dropped, each surface counted once ({})",
            dups.len(),
            name_places(&dups)
        ));
    }
    if !cut.is_empty() {
        out.warnings.push(format!(
            "{} triangle(s) cut where they overlap coplanar surfaces that win (listed later, or double-sided): decals, panels, z-fighting copies ({})",
            cut.len(),
            name_places(&cut)
        ));
    }
    out
}

/// The index of a piece whose source is `s` (`source` is ascending).
fn source_piece(source: &[u32], s: u32) -> usize {
    source.partition_point(|&x| x < s)
}

fn name_places(places: &[TriangleSource]) -> String {
    let mut text: Vec<String> = places
        .iter()
        .take(NAMED)
        .map(|p| {
            format!(
                "mesh {} primitive {} triangle {}",
                p.mesh, p.primitive, p.triangle
            )
        })
        .collect();
    if places.len() > NAMED {
        text.push(format!("and {} more", places.len() - NAMED));
    }
    text.join(", ")
}

/// The plane and box of a live piece (area above `min_area`, height above the length tolerance).
fn piece_info(t: &Triangle, double_sided: bool, tol: &Tolerances, min_area: f64) -> Option<Info> {
    let [a, b, c] = t.vertices;
    let cross = (b - a).cross(c - a);
    let area = 0.5 * cross.length();
    // (false for NaN)
    let large = area > min_area;
    if !large {
        return None;
    }
    let longest = a.distance(b).max(b.distance(c)).max(c.distance(a));
    let height = cross.length() / longest;
    let thick = height > tol.length_m;
    if !thick {
        return None;
    }
    let normal = cross / cross.length();
    let slack_rad = (2.0 * tol.plane_m / height).min(1.0).asin();
    Some(Info {
        normal,
        offset: normal.dot((a + b + c) / 3.0),
        cos_allowed: (tol.angle_rad + slack_rad)
            .min(std::f64::consts::FRAC_PI_2)
            .cos(),
        double_sided,
        lo: a.min(b).min(c),
        hi: a.max(b).max(c),
    })
}

type Key = [i32; 4];

/// Entry flag: the piece is bucketed under its opposite normal.
const FLIP: u32 = 1 << 31;
/// Entry flag: this bucket is the piece's own (the cell of its plane, under its own normal).
const HOME: u32 = 1 << 30;
const INDEX: u32 = HOME - 1;

/// The related pairs `(i, j, relation)`, `i < j`, of live pieces, each found once: pieces are
/// bucketed by quantised plane (both normals, every cell within the tolerance), and a sweep over
/// bounding boxes inside each bucket tests the pairs whose boxes touch, from the lower piece's own
/// bucket.
fn related_pairs(
    pieces: &[Triangle],
    infos: &[Option<Info>],
    tol: &Tolerances,
    diagonal: f64,
) -> Vec<(u32, u32, Relation)> {
    if pieces.len() >= INDEX as usize {
        return Vec::new();
    }
    // Offsets are taken about the centre of the pieces' box, so the normal's tolerance moves them
    // by at most its angle times half the diagonal.
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for info in infos.iter().flatten() {
        lo = lo.min(info.lo);
        hi = hi.max(info.hi);
    }
    let centre = 0.5 * (lo + hi);
    let half = 0.5 * (hi - lo).length();
    let r_n = tol.angle_rad + SLACK_CAP_RAD;
    let r_d = r_n * half + 3.0 * tol.plane_m;
    let cell_d = OFFSET_CELL_REL * diagonal;
    // Normal cells shifted by half a cell, so that axis-aligned normals (components 0 and 1) lie
    // mid-cell.
    let coords = |n: DVec3, d: f64| {
        [
            n.x / NORMAL_CELL + 0.5,
            n.y / NORMAL_CELL + 0.5,
            n.z / NORMAL_CELL + 0.5,
            d / cell_d,
        ]
    };
    let radius = [
        r_n / NORMAL_CELL,
        r_n / NORMAL_CELL,
        r_n / NORMAL_CELL,
        r_d / cell_d,
    ];
    let mut entries: Vec<(Key, u32)> = infos
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, info)| {
            let mut out: Vec<(Key, u32)> = Vec::new();
            if let Some(info) = info {
                let d = info.normal.dot(pieces[i].vertices[0] - centre);
                for (sign, flag) in [(1.0, 0u32), (-1.0, FLIP)] {
                    let x = coords(sign * info.normal, sign * d);
                    let home: Key = x.map(|c| c.floor() as i32);
                    let lo: Key = std::array::from_fn(|k| (x[k] - radius[k]).floor() as i32);
                    let hi: Key = std::array::from_fn(|k| (x[k] + radius[k]).floor() as i32);
                    for a in lo[0]..=hi[0] {
                        for b in lo[1]..=hi[1] {
                            for c in lo[2]..=hi[2] {
                                for e in lo[3]..=hi[3] {
                                    let key = [a, b, c, e];
                                    let at_home = flag == 0 && key == home;
                                    let tag = i as u32 | flag | if at_home { HOME } else { 0 };
                                    out.push((key, tag));
                                }
                            }
                        }
                    }
                }
            }
            out.into_iter()
        })
        .collect();
    entries.par_sort_unstable();
    let buckets: Vec<&[(Key, u32)]> = entries
        .chunk_by(|a, b| a.0 == b.0)
        .filter(|run| run.len() > 1 && run.iter().any(|e| e.1 & HOME != 0))
        .collect();
    let pad = tol.length_m.max(tol.plane_m);
    buckets
        .into_par_iter()
        .flat_map_iter(|run| {
            let mut boxes: Vec<(DVec3, DVec3, u32)> = run
                .iter()
                .map(|&(_, tag)| {
                    let info = infos[(tag & INDEX) as usize].expect("bucketed pieces are live");
                    (info.lo - pad, info.hi + pad, tag)
                })
                .collect();
            // Sweep along the axis of the bucket's largest spread.
            let (lo, hi) = boxes.iter().fold(
                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                |(lo, hi), b| (lo.min(b.0), hi.max(b.1)),
            );
            let spread = hi - lo;
            let axis = if spread.x >= spread.y && spread.x >= spread.z {
                0
            } else if spread.y >= spread.z {
                1
            } else {
                2
            };
            boxes.sort_unstable_by(|a, b| a.0[axis].total_cmp(&b.0[axis]).then(a.2.cmp(&b.2)));
            let mut found = Vec::new();
            for (k, &(elo, ehi, e)) in boxes.iter().enumerate() {
                for &(flo, fhi, f) in &boxes[k + 1..] {
                    if flo[axis] > ehi[axis] {
                        break;
                    }
                    let (i, j) = (e & INDEX, f & INDEX);
                    // Found once: in the lower piece's own bucket.
                    let home = if i < j { e & HOME != 0 } else { f & HOME != 0 };
                    if !home || i == j || !(flo.cmple(ehi).all() && elo.cmple(fhi).all()) {
                        continue;
                    }
                    let (i, j) = (i.min(j), i.max(j));
                    if let Some(r) = relate(pieces, infos, i as usize, j as usize, tol) {
                        found.push((i, j, r));
                    }
                }
            }
            found.into_iter()
        })
        .collect()
}

/// How two live pieces relate, if at all.
fn relate(
    pieces: &[Triangle],
    infos: &[Option<Info>],
    i: usize,
    j: usize,
    tol: &Tolerances,
) -> Option<Relation> {
    let (a, b) = (infos[i]?, infos[j]?);
    let dot = a.normal.dot(b.normal);
    // cos(angle + max(slack)): the smaller of the two.
    if dot.abs() < a.cos_allowed.min(b.cos_allowed) {
        return None;
    }
    let (ti, tj) = (&pieces[i].vertices, &pieces[j].vertices);
    let near = |plane: &Info, t: &[DVec3; 3]| {
        t.iter()
            .all(|&p| (plane.normal.dot(p) - plane.offset).abs() <= tol.plane_m)
    };
    if !(near(&a, tj) && near(&b, ti)) {
        return None;
    }
    let same = dot > 0.0;
    let shared_side = same || a.double_sided || b.double_sided;
    let coincident = coincident(ti, tj, same, tol.length_m);
    if !shared_side {
        return coincident.then_some(Relation::BackToBack);
    }
    if coincident {
        return Some(Relation::Duplicate);
    }
    let proj = Projection::for_normal(a.normal);
    let pi = ti.map(|p| proj.apply(p));
    let pj = tj.map(|p| proj.apply(p));
    interiors_overlap(&pi, &pj, tol.length_m).then_some(Relation::Overlap)
}

/// True when the triangles have the same corners within `tol`, in the same cyclic order (`same`)
/// or in the reverse order (facing the other way).
fn coincident(ti: &[DVec3; 3], tj: &[DVec3; 3], same: bool, tol: f64) -> bool {
    (0..3).any(|k| {
        (0..3).all(|m| {
            let q = if same {
                tj[(m + k) % 3]
            } else {
                tj[(k + 3 - m) % 3]
            };
            ti[m].distance(q) <= tol
        })
    })
}

/// True when the triangles' interiors overlap by more than `margin` along every edge normal of
/// either (separating axes).
fn interiors_overlap(a: &[DVec2; 3], b: &[DVec2; 3], margin: f64) -> bool {
    for tri in [a, b] {
        for k in 0..3 {
            let e = tri[(k + 1) % 3] - tri[k];
            let len = e.length();
            if len == 0.0 {
                return false;
            }
            let axis = e.perp() / len;
            let span = |t: &[DVec2; 3]| {
                let d = t.map(|p| axis.dot(p - tri[k]));
                (d[0].min(d[1]).min(d[2]), d[0].max(d[1]).max(d[2]))
            };
            let (alo, ahi) = span(a);
            let (blo, bhi) = span(b);
            if ahi.min(bhi) - alo.max(blo) <= margin {
                return false;
            }
        }
    }
    true
}

/// What is left of `piece` once the union of `winners` is taken away, as triangles with its
/// material, source and winding; `None` when nothing measurable was taken away (the piece stays).
fn subtract(
    piece: &Triangle,
    info: Info,
    winners: &[u32],
    pieces: &[Triangle],
    tol: &Tolerances,
    min_area: f64,
) -> Option<Vec<Triangle>> {
    let proj = Projection::for_normal(info.normal);
    let scale = proj.area_scale(info.normal);
    let ccw = |t: &[DVec3; 3]| -> Vec<[f64; 2]> {
        let mut r: Vec<[f64; 2]> = t.iter().map(|&p| proj.apply(p).to_array()).collect();
        let flat: Vec<DVec2> = r.iter().map(|&p| DVec2::from(p)).collect();
        if signed_area(&flat) < 0.0 {
            r.reverse();
        }
        r
    };
    let subject = ccw(&piece.vertices);
    let clip: Vec<Vec<[f64; 2]>> = winners
        .iter()
        .map(|&w| ccw(&pieces[w as usize].vertices))
        .collect();
    let shapes = subject.overlay_as::<i64>(&clip, OverlayRule::Difference, FillRule::NonZero);
    let ring_area = |r: &Vec<[f64; 2]>| {
        signed_area(&r.iter().map(|&p| DVec2::from(p)).collect::<Vec<_>>()).abs()
    };
    // Outer rings count positive, holes negative.
    let left: f64 = shapes
        .iter()
        .flat_map(|s| s.iter().enumerate())
        .map(|(k, r)| if k == 0 { ring_area(r) } else { -ring_area(r) })
        .sum::<f64>()
        / scale;
    if piece.area() - left <= min_area {
        return None;
    }
    // Exact input corners the output may have come from (the boolean engine rounds).
    let mut exact: Vec<(DVec2, DVec3)> =
        piece.vertices.iter().map(|&p| (proj.apply(p), p)).collect();
    for &w in winners {
        exact.extend(
            pieces[w as usize]
                .vertices
                .iter()
                .map(|&p| (proj.apply(p), p)),
        );
    }
    let snap = 0.5 * tol.length_m;
    let lift = |p: DVec2| -> DVec3 {
        exact
            .iter()
            .find(|(q, _)| q.distance(p) <= snap)
            .map(|&(_, q)| q)
            .unwrap_or_else(|| proj.lift(p, info.normal, info.offset))
    };
    let mut out = Vec::new();
    for shape in &shapes {
        let mut rings: Vec<Vec<DVec2>> = shape
            .iter()
            .map(|r| r.iter().map(|&p| DVec2::from(p)).collect())
            .collect();
        for (k, r) in rings.iter_mut().enumerate() {
            let a = signed_area(r);
            if (k == 0) != (a > 0.0) {
                r.reverse();
            }
        }
        rings.retain(|r| r.len() >= 3);
        if rings.is_empty() || rings[0].len() < 3 {
            continue;
        }
        let flat: Vec<DVec2> = rings.iter().flatten().copied().collect();
        let Ok(tris) = triangulate_polygon(&rings) else {
            continue;
        };
        let lifted: Vec<DVec3> = flat.iter().map(|&p| lift(p)).collect();
        for [x, y, z] in tris {
            let t = Triangle {
                vertices: [lifted[x], lifted[y], lifted[z]],
                material: piece.material,
                source: piece.source,
            };
            if piece_info(&t, false, tol, min_area).is_some_and(|i| i.normal.dot(info.normal) > 0.0)
            {
                out.push(t);
            }
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: DVec2, b: DVec2, c: DVec2) -> [DVec2; 3] {
        [a, b, c]
    }

    #[test]
    fn separating_axes_see_shared_edges_as_apart_and_overlaps_as_overlapping() {
        let (o, x, y, xy) = (DVec2::ZERO, DVec2::X, DVec2::Y, DVec2::ONE);
        // Two halves of a square share the diagonal: no overlap.
        assert!(!interiors_overlap(&tri(o, x, xy), &tri(o, xy, y), 1e-9));
        // A triangle and a smaller one inside it.
        let small = tri(
            DVec2::new(0.5, 0.1),
            DVec2::new(0.8, 0.1),
            DVec2::new(0.8, 0.4),
        );
        assert!(interiors_overlap(&tri(o, x, xy), &small, 1e-9));
        // Touching at a vertex only.
        assert!(!interiors_overlap(
            &tri(o, x, y),
            &tri(x, DVec2::new(2.0, 0.0), DVec2::new(1.0, 1.0)),
            1e-9
        ));
    }
}
