//! Faces: the planar surfaces the solver sees, built from the scene's triangles.
//!
//! [`merge_planar_faces`] rebuilds the scene's real surfaces (docs/design.md section 3): corners are
//! welded ([`WELD_REL`]), edges are split at T-junctions, and triangles sharing an edge (or part of
//! one), a material and a side mode, and lying in one plane ([`NORMAL_ANGLE_RAD`],
//! [`PLANE_OFFSET_REL`]) become one face with an outer ring and holes. Faces that touch only at a
//! vertex, and triangles across a non-manifold edge, stay separate. A group whose rings fail
//! [`validate_face`] is split back into one face per triangle and counted (`groups_split`).
//! [`classify`] names each face a triangle, a parallelogram or one needing an extended domain.
//!
//! Invariants (checked by [`validate_faces`]): face ids are `0..faces.len()`, in
//! order of their first triangle (a split group's faces stay together); `normal` is a unit vector;
//! `outer` is counter-clockwise and every hole clockwise about `normal`; rings never cross (they
//! may touch at isolated vertices), holes lie inside the outer ring; ring vertices collinear with
//! their neighbours within the length tolerance are removed, except where rings touch (or when the
//! simplified rings would be invalid); `area_m2` is the sum of the scene areas of `triangles`;
//! `triangulation` holds those triangles with welded corners, counter-clockwise about `normal`;
//! degenerate triangles are in no face and counted in `degenerate_dropped`. Units: metres, world
//! frame. This module knows nothing of glTF, element roots or the solver.
//!
//! Before welding, [`contact`] cuts the triangles along contact lines and [`overlap`] counts every
//! piece of surface once: exact duplicates are dropped, coplanar pieces sharing a radiosity side
//! are cut where they overlap (the one listed later in the file wins), back-to-back coincident
//! pieces are kept; `duplicates_dropped`, `overlaps_cut`, `back_to_back_kept` and `warnings` say so.
//!
//! Submodules: `weld` (vertex ids), `adjacency` (T-junction splits, neighbours), `rings` (boundary
//! walking, collinear removal), [`validate`], [`triangulate`] (ear clipping with holes), `geom`
//! (exact projection and predicates).

mod adjacency;
pub(crate) mod contact;
pub(crate) mod geom;
pub(crate) mod overlap;
mod rings;
pub(crate) mod triangulate;
pub(crate) mod validate;
mod weld;

pub use triangulate::{triangulate_face, triangulate_polygon, TriangulateError};
pub use validate::{validate_face, validate_faces, FaceProblem};

use crate::scene::Scene;
use adjacency::{Tolerances, TriInfo};
use geom::Projection;
use glam::DVec3;

/// Index of a face in [`FaceSet::faces`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FaceId(pub u32);

/// How the solver represents a face.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaceKind {
    Triangle,
    Parallelogram,
    Extended,
}

impl FaceKind {
    pub fn as_str(self) -> &'static str {
        match self {
            FaceKind::Triangle => "triangle",
            FaceKind::Parallelogram => "parallelogram",
            FaceKind::Extended => "extended",
        }
    }
}

/// A planar face: one material, one plane, an outer ring and holes.
#[derive(Debug, Clone)]
pub struct Face {
    pub id: FaceId,
    pub material: u32,
    pub double_sided: bool,
    pub kind: FaceKind,
    /// Unit front normal (counter-clockwise winding).
    pub normal: DVec3,
    /// Area in m^2: the sum of the areas of the triangles it came from.
    pub area_m2: f64,
    /// Outer ring, counter-clockwise about `normal`.
    pub outer: Vec<DVec3>,
    /// Hole rings, clockwise about `normal`.
    pub holes: Vec<Vec<DVec3>>,
    /// Indices of the pieces merged into this face, ascending: scene triangles, or parts of them
    /// cut along contact lines (`FaceSet::piece_source` maps a piece to its scene triangle).
    pub triangles: Vec<u32>,
    /// The triangles of `triangles` (same order) with welded corners, counter-clockwise about
    /// `normal`: a triangulation of the rings' polygon whose vertices may include T-junction and
    /// collinear points removed from the rings.
    pub triangulation: Vec<[DVec3; 3]>,
}

/// The faces of a scene with the import counts.
#[derive(Debug, Clone)]
pub struct FaceSet {
    pub faces: Vec<Face>,
    pub triangles_in: usize,
    pub degenerate_dropped: usize,
    /// For each piece (see `piece_source`), the face it belongs to (`None` when dropped as
    /// degenerate).
    pub face_of_triangle: Vec<Option<FaceId>>,
    /// The scene's triangles after cutting along contact lines ([`contact`]), the "pieces": for
    /// each piece, the index of its scene triangle. Without contacts, the identity.
    pub piece_source: Vec<u32>,
    /// Scene triangles cut along contact lines.
    pub triangles_cut: usize,
    /// The length tolerance the faces were built with (weld, T-junctions, collinear vertices,
    /// plane offset), metres: `WELD_REL * diagonal`. The validator's tolerances derive from it.
    pub tolerance_m: f64,
    /// Merged groups whose rings were invalid (overlapping or folded coplanar triangles) and that
    /// were split back into one face per triangle.
    pub groups_split: usize,
    /// Edges split at vertices lying on them (T-junctions, collinear overlaps).
    pub edges_split: usize,
    /// Scene triangles with a piece dropped as an exact duplicate ([`overlap`]: the same corners
    /// within the weld tolerance, sharing a radiosity side, of a piece that wins: the one listed
    /// later in the file, or a double-sided one over a single-sided one).
    pub duplicates_dropped: usize,
    /// Scene triangles with a piece that lost part or all of its area to coplanar pieces sharing a
    /// radiosity side that win ([`overlap`]; duplicates not counted): decals, panels, z-fighting
    /// copies.
    pub overlaps_cut: usize,
    /// Pairs of scene triangles with the same corners (within the weld tolerance) facing opposite
    /// ways, both single-sided (a zero-thickness wall): both sides are real and both are kept.
    /// Back-to-back pieces that only partly coincide are kept too, and not counted.
    pub back_to_back_kept: usize,
    /// Area taken away by dropped duplicates and overlap cuts, m^2 (the faces' area is the
    /// non-degenerate triangles' minus this).
    pub overlap_area_removed_m2: f64,
    /// What the user should hear about the faces (duplicates dropped, overlaps cut, with the
    /// places of their triangles).
    pub warnings: Vec<String>,
}

/// A triangle whose area is below this fraction of the squared scene diagonal is degenerate.
pub const DEGENERATE_AREA_REL: f64 = 1e-14;

/// Corners closer than this fraction of the scene diagonal are one vertex, a vertex this close to an
/// edge lies on it (T-junction), and ring vertices this close to the edge replacing them are
/// collinear. glTF stores f32 positions (relative precision 6e-8), so duplicated corners of an
/// export differ by well under it; at 1e-6 of a 100 m scene (0.1 mm) no real feature is lost.
pub const WELD_REL: f64 = 1e-6;

/// Merged triangles' corners lie within this fraction of the scene diagonal of each other's plane
/// and of the growing face's plane (its triangles' vector area through their centroid; when that
/// leaves a corner off the final plane, the plane of its largest triangle), so every corner of a
/// face lies within twice this of the face's plane. Equal to [`WELD_REL`] (the validator uses
/// one length tolerance for both): the f32 noise of coplanar corners.
pub const PLANE_OFFSET_REL: f64 = WELD_REL;

/// Merged triangles' normals differ by at most this angle (radians, about 0.06 degrees) from each
/// other and from the face's first triangle, plus the tilt that corner offsets within
/// [`PLANE_OFFSET_REL`] can give the thinner triangle (`asin(2 offset / least height)`): thin
/// slivers' normals are noisy, yet their corners lie in the plane. With the offset test against
/// the first triangle's plane, a finely tessellated curved surface cannot creep into one face.
pub const NORMAL_ANGLE_RAD: f64 = 1e-3;

/// A 4-vertex face is a parallelogram when `|a - b + c - d|` is within this fraction of its
/// diameter (docs/design.md section 3).
pub const PARALLELOGRAM_REL: f64 = 1e-6;

/// The kind of a face with these rings: a triangle (3 vertices, no hole), a parallelogram (4
/// vertices, no hole, within [`PARALLELOGRAM_REL`] of its diameter of one), else extended.
pub fn classify(outer: &[DVec3], holes: &[Vec<DVec3>]) -> FaceKind {
    if !holes.is_empty() {
        return FaceKind::Extended;
    }
    match *outer {
        [_, _, _] => FaceKind::Triangle,
        [a, b, c, d] => {
            let pts = [a, b, c, d];
            let mut diameter: f64 = 0.0;
            for i in 0..4 {
                for j in i + 1..4 {
                    diameter = diameter.max(pts[i].distance(pts[j]));
                }
            }
            if (a - b + c - d).length() <= PARALLELOGRAM_REL * diameter {
                FaceKind::Parallelogram
            } else {
                FaceKind::Extended
            }
        }
        _ => FaceKind::Extended,
    }
}

impl FaceSet {
    /// Number of distinct scene triangles with a piece in `face`.
    pub fn source_triangle_count(&self, face: &Face) -> usize {
        let mut sources: Vec<u32> = face
            .triangles
            .iter()
            .filter_map(|&p| self.piece_source.get(p as usize).copied())
            .collect();
        sources.dedup();
        sources.len()
    }
}

/// Merges the scene's triangles into planar faces with holes (docs/design.md section 3).
///
/// A triangle is dropped (and counted in `degenerate_dropped`) when its area is at most
/// [`DEGENERATE_AREA_REL`] times the squared diagonal, or when welding makes it flat (two corners
/// welded together, or a corner within the weld tolerance of the opposite edge).
pub fn merge_planar_faces(scene: &Scene) -> FaceSet {
    let diag = scene.diagonal();
    let tol = Tolerances {
        length_m: WELD_REL * diag,
        plane_m: PLANE_OFFSET_REL * diag,
        angle_rad: NORMAL_ANGLE_RAD,
    };
    let min_area = DEGENERATE_AREA_REL * diag * diag;
    let double_sided = |t: &crate::scene::Triangle| {
        scene
            .materials
            .get(t.material as usize)
            .is_some_and(|m| m.double_sided)
    };
    let cut = contact::cut_at_contacts(&scene.triangles, double_sided, &tol, diag, min_area);
    // Every piece of surface counted once: duplicates dropped, overlaps cut.
    let over = overlap::resolve_overlaps(
        &scene.triangles,
        cut.pieces,
        cut.source,
        double_sided,
        &tol,
        diag,
        min_area,
    );
    let n = over.pieces.len();
    let mut set = FaceSet {
        faces: Vec::new(),
        triangles_in: scene.triangles.len(),
        degenerate_dropped: 0,
        face_of_triangle: vec![None; n],
        piece_source: over.source,
        triangles_cut: cut.triangles_cut,
        tolerance_m: tol.length_m,
        groups_split: 0,
        edges_split: 0,
        duplicates_dropped: over.duplicates_dropped,
        overlaps_cut: over.overlaps_cut,
        back_to_back_kept: over.back_to_back_kept,
        overlap_area_removed_m2: over.area_removed_m2,
        warnings: over.warnings,
    };
    if !(diag > 0.0 && diag.is_finite()) {
        set.degenerate_dropped = n;
        return set;
    }
    // From here on, "triangles" are the pieces.
    let scene = &Scene {
        triangles: over.pieces,
        materials: scene.materials.clone(),
        lights: Vec::new(),
        bounds: scene.bounds,
        warnings: Vec::new(),
        textures: Vec::new(),
        texcoords: Vec::new(),
        source: None,
        camera: None,
    };
    let welded = weld::weld(&scene.triangles, tol.length_m);

    // Live triangles and their planes.
    let mut live = vec![false; n];
    let mut area = vec![0.0; n];
    let mut info = vec![
        TriInfo {
            normal: DVec3::ZERO,
            offset: 0.0,
            material: 0,
            double_sided: false,
            slack_rad: 0.0,
        };
        n
    ];
    for (i, t) in scene.triangles.iter().enumerate() {
        let c = welded.corners[i];
        area[i] = t.area();
        let large = area[i] > min_area;
        if !large || c[0] == c[1] || c[1] == c[2] || c[2] == c[0] {
            continue;
        }
        let [a, b, d] = c.map(|v| welded.positions[v as usize]);
        let cross = (b - a).cross(d - a);
        let longest = a.distance(b).max(b.distance(d)).max(d.distance(a));
        // Height over the longest edge = |cross| / longest (false for NaN).
        let height = cross.length() / longest;
        let thick = height > tol.length_m;
        if !thick {
            continue;
        }
        let normal = cross.normalize();
        info[i] = TriInfo {
            normal,
            offset: normal.dot((a + b + d) / 3.0),
            material: t.material,
            double_sided: scene
                .materials
                .get(t.material as usize)
                .is_some_and(|m| m.double_sided),
            slack_rad: (2.0 * tol.plane_m / height).min(1.0).asin(),
        };
        live[i] = true;
    }
    set.degenerate_dropped = live.iter().filter(|&&l| !l).count();

    // Region growing from the largest triangles, across matched edges, within the group's plane.
    let adj = adjacency::build(&welded, &live, &info, &tol, &cut.segments);
    set.edges_split = adj.split_edges;
    let mut order: Vec<u32> = (0..n as u32).filter(|&t| live[t as usize]).collect();
    order.sort_by(|&x, &y| {
        area[y as usize]
            .total_cmp(&area[x as usize])
            .then(x.cmp(&y))
    });
    let grower = Grower {
        adj: &adj,
        info: &info,
        welded: &welded,
        tol: &tol,
    };
    let mut in_group = vec![false; n];
    // (members ascending, the face's normal)
    let mut groups: Vec<(Vec<u32>, DVec3)> = Vec::new();
    for &seed in &order {
        if !in_group[seed as usize] {
            groups.push(grower.grow(seed, &mut in_group));
        }
    }
    groups.sort_unstable_by_key(|g| g.0.first().copied());

    // Faces.
    for (group, normal) in &groups {
        let built = face_of_group(group, *normal, scene, &welded, &adj, &info, tol.length_m);
        let faces: Vec<Face> = match built {
            Some(face) => vec![face],
            None => {
                set.groups_split += 1;
                group
                    .iter()
                    .map(|&t| single_triangle_face(t, scene, &welded, &info))
                    .collect()
            }
        };
        for mut face in faces {
            let id = FaceId(set.faces.len() as u32);
            face.id = id;
            for &t in &face.triangles {
                set.face_of_triangle[t as usize] = Some(id);
            }
            set.faces.push(face);
        }
    }
    set
}

/// Grows groups of live triangles across matched edges.
struct Grower<'a> {
    adj: &'a adjacency::Adjacency,
    info: &'a [TriInfo],
    welded: &'a weld::Welded,
    tol: &'a Tolerances,
}

/// The plane of a growing group: its vector area and area-weighted centroid (the plane the
/// validator checks a face against).
#[derive(Debug, Clone, Copy, Default)]
struct PlaneSum {
    cross: DVec3,
    moment: DVec3,
    area: f64,
}

impl PlaneSum {
    fn add(&mut self, t: [DVec3; 3]) {
        let cross = (t[1] - t[0]).cross(t[2] - t[0]);
        let a = 0.5 * cross.length();
        self.cross += cross;
        self.moment += a * (t[0] + t[1] + t[2]) / 3.0;
        self.area += a;
    }
    /// Unit normal (zero if undefined) and offset.
    fn plane(&self) -> (DVec3, f64) {
        let n = self.cross.normalize_or_zero();
        (n, n.dot(self.moment / self.area))
    }
}

impl Grower<'_> {
    /// The group of `seed` (ascending) and its face's normal. The group first grows against its
    /// own running plane, so that a large face of thin, noisy triangles is not cut short by the
    /// tilt of its first triangle; if some corner then lies off the final plane (a gently curved
    /// surface), it grows again against the seed's plane, which bounds every corner.
    fn grow(&self, seed: u32, in_group: &mut [bool]) -> (Vec<u32>, DVec3) {
        let (members, sum) = self.grow_with(seed, in_group, true);
        let (normal, offset) = sum.plane();
        let band = 1.5 * self.tol.plane_m;
        let flat = members.iter().all(|&t| {
            self.welded.corners[t as usize]
                .iter()
                .all(|&v| (normal.dot(self.welded.positions[v as usize]) - offset).abs() <= band)
        });
        if members.len() > 1 && flat && normal != DVec3::ZERO {
            return (members, normal);
        }
        for &t in &members {
            in_group[t as usize] = false;
        }
        let (members, _) = self.grow_with(seed, in_group, false);
        (members, self.info[seed as usize].normal)
    }

    /// Breadth-first growth from `seed`; against the running plane of the group, or the seed's.
    fn grow_with(&self, seed: u32, in_group: &mut [bool], running: bool) -> (Vec<u32>, PlaneSum) {
        let info = self.info;
        let mut sum = PlaneSum::default();
        sum.add(welded_triangle(seed, self.welded));
        let mut reference = info[seed as usize];
        reference.slack_rad = 0.0;
        let mut members = vec![seed];
        in_group[seed as usize] = true;
        let mut k = 0;
        while k < members.len() {
            let t = members[k];
            k += 1;
            for &nb in self.adj.neighbours(t) {
                let nbu = nb as usize;
                if in_group[nbu] || !info[nbu].normals_agree(&reference, self.tol) {
                    continue;
                }
                let off_plane = self.welded.corners[nbu].iter().any(|&v| {
                    let p = self.welded.positions[v as usize];
                    (reference.normal.dot(p) - reference.offset).abs() > self.tol.plane_m
                });
                if off_plane {
                    continue;
                }
                in_group[nbu] = true;
                members.push(nb);
                if running {
                    sum.add(welded_triangle(nb, self.welded));
                    let (normal, offset) = sum.plane();
                    if normal != DVec3::ZERO {
                        reference.normal = normal;
                        reference.offset = offset;
                    }
                }
            }
        }
        members.sort_unstable();
        (members, sum)
    }
}

fn welded_triangle(t: u32, welded: &weld::Welded) -> [DVec3; 3] {
    welded.corners[t as usize].map(|v| welded.positions[v as usize])
}

/// The face of one live triangle: its welded corners.
fn single_triangle_face(t: u32, scene: &Scene, welded: &weld::Welded, info: &[TriInfo]) -> Face {
    let tri = welded_triangle(t, welded);
    let i = info[t as usize];
    Face {
        id: FaceId(0),
        material: i.material,
        double_sided: i.double_sided,
        kind: FaceKind::Triangle,
        normal: i.normal,
        area_m2: scene.triangles[t as usize].area(),
        outer: tri.to_vec(),
        holes: Vec::new(),
        triangles: vec![t],
        triangulation: vec![tri],
    }
}

/// The face of a group of live triangles, or `None` when its rings are invalid even without
/// collinear-vertex removal. The face's normal is its seed's (the group's largest triangle), the
/// plane every corner of the group lies near by construction.
fn face_of_group(
    group: &[u32],
    normal: DVec3,
    scene: &Scene,
    welded: &weld::Welded,
    adj: &adjacency::Adjacency,
    info: &[TriInfo],
    tolerance_m: f64,
) -> Option<Face> {
    let first = *group.first()?;
    if group.len() == 1 {
        // A lone triangle's ring is its corners (any T-junction points on its edges are collinear).
        return Some(single_triangle_face(first, scene, welded, info));
    }
    let t0 = &scene.triangles[first as usize];
    let triangulation: Vec<[DVec3; 3]> =
        group.iter().map(|&t| welded_triangle(t, welded)).collect();
    let area_m2 = group
        .iter()
        .map(|&t| scene.triangles[t as usize].area())
        .sum();
    let proj = Projection::for_normal(normal);
    for simplify in [true, false] {
        let Ok(ids) = rings::build_rings(
            group,
            &welded.corners,
            adj,
            &welded.positions,
            proj,
            tolerance_m,
            simplify,
        ) else {
            continue;
        };
        let pos =
            |r: &[u32]| -> Vec<DVec3> { r.iter().map(|&v| welded.positions[v as usize]).collect() };
        let outer = pos(&ids.outer);
        let holes: Vec<Vec<DVec3>> = ids.holes.iter().map(|h| pos(h)).collect();
        let face = Face {
            id: FaceId(0),
            material: t0.material,
            double_sided: scene
                .materials
                .get(t0.material as usize)
                .is_some_and(|m| m.double_sided),
            kind: classify(&outer, &holes),
            normal,
            area_m2,
            outer,
            holes,
            triangles: group.to_vec(),
            triangulation: triangulation.clone(),
        };
        if validate_face(&face, tolerance_m).is_empty() {
            return Some(face);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene_of(tris: &[[DVec3; 3]]) -> Scene {
        Scene::of_triangles(tris)
    }

    fn p(x: f64, y: f64) -> DVec3 {
        DVec3::new(x, y, 0.0)
    }

    #[test]
    fn classify_recognises_parallelograms_within_tolerance() {
        let sq = [p(0.0, 0.0), p(2.0, 0.0), p(3.0, 1.0), p(1.0, 1.0)];
        assert_eq!(classify(&sq, &[]), FaceKind::Parallelogram);
        let mut off = sq;
        off[2].x += 1e-3;
        assert_eq!(classify(&off, &[]), FaceKind::Extended);
        assert_eq!(classify(&sq[..3], &[]), FaceKind::Triangle);
        assert_eq!(classify(&sq, &[sq[..3].to_vec()]), FaceKind::Extended);
    }

    #[test]
    fn a_split_quad_merges_into_one_parallelogram() {
        let s = scene_of(&[
            [p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)],
            [p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)],
        ]);
        let f = merge_planar_faces(&s);
        assert_eq!(f.faces.len(), 1);
        assert_eq!(f.faces[0].kind, FaceKind::Parallelogram);
        assert!(validate_faces(&f).is_empty(), "{:?}", validate_faces(&f));
    }

    #[test]
    fn flat_and_repeated_vertex_triangles_are_dropped_and_counted() {
        let s = scene_of(&[
            [p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)],
            [p(0.0, 0.0), p(0.0, 0.0), p(1.0, 1.0)],
            // A cap whose apex is within the weld tolerance of its long edge.
            [p(0.0, 0.0), p(1.0, 1e-9), p(2.0, 0.0)],
        ]);
        let f = merge_planar_faces(&s);
        assert_eq!(f.degenerate_dropped, 2);
        assert_eq!(f.face_of_triangle, vec![Some(FaceId(0)), None, None]);
        assert!(validate_faces(&f).is_empty());
    }

    #[test]
    fn duplicated_coplanar_triangles_are_counted_once() {
        // Two copies of one triangle plus a neighbour: the earlier copy is dropped (the surface is
        // counted once), and the later one merges with the neighbour.
        let a = [p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)];
        let b = [p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)];
        let f = merge_planar_faces(&scene_of(&[a, a, b]));
        assert_eq!(f.duplicates_dropped, 1);
        assert_eq!(f.piece_source, vec![1, 2]);
        assert_eq!(f.faces.len(), 1);
        assert_eq!(f.faces[0].kind, FaceKind::Parallelogram);
        assert!(validate_faces(&f).is_empty(), "{:?}", validate_faces(&f));
    }

    #[test]
    fn validator_reports_every_problem_with_its_place() {
        let s = scene_of(&[
            [p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)],
            [p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)],
        ]);
        let mut f = merge_planar_faces(&s);
        let face = &mut f.faces[0];
        // A bow tie (crossing edges), a wrong kind and a hole outside the face.
        face.outer.swap(1, 2);
        face.holes.push(vec![p(5.0, 5.0), p(5.0, 6.0), p(6.0, 6.0)]);
        let problems = validate_faces(&f);
        let text: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
        assert!(text.iter().any(|t| t.contains("crosses")), "{text:?}");
        assert!(
            text.iter()
                .any(|t| t.contains("hole 0") && t.contains("not inside")),
            "{text:?}"
        );
        assert!(text.iter().any(|t| t.contains("is marked")), "{text:?}");
        assert!(text.iter().any(|t| t.contains("rings enclose")), "{text:?}");
    }
}
