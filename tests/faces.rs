//! Planar-face merging (issue 3): hand-made glTF scenes with known faces, and a property test
//! that a triangulated polygon with holes, shuffled and re-indexed, merges back into the same
//! polygon. Contact lines are in `tests/contact.rs`, the shared scenes in
//! `tests/shared_scene_faces.rs`.

use glam::{DQuat, DVec2, DVec3};
use proptest::prelude::*;
use wavrad::faces::{
    merge_planar_faces, triangulate_face, triangulate_polygon, validate_faces, FaceKind, FaceSet,
};
use wavrad::scene::gltf_writer::{glb_from_parts, SceneBuilder};
use wavrad::scene::{load_scene, ExternalFiles, Scene};

mod common;
use common::faces::{merged, total_area};

const LIMIT: usize = 5_000_000;

fn load(glb: &[u8]) -> Scene {
    load_scene(glb, &ExternalFiles::Refuse, LIMIT).expect("hand-made scene loads")
}

/// A point of the plane `origin + x u + y v` (front normal `u x v`).
#[derive(Clone, Copy)]
struct Plane {
    origin: DVec3,
    u: DVec3,
    v: DVec3,
}

impl Plane {
    fn at(&self, x: f64, y: f64) -> DVec3 {
        self.origin + self.u * x + self.v * y
    }
    /// A tilted plane, so the tests do not rely on axis-aligned coordinates.
    fn tilted() -> Self {
        let q = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        Plane {
            origin: DVec3::new(0.5, -1.25, 2.0),
            u: q * DVec3::X,
            v: q * DVec3::Y,
        }
    }
}

/// Adds a mesh of 2D points (in `plane`) and counter-clockwise index triples.
fn mesh2d(b: &mut SceneBuilder, m: u32, plane: Plane, pts: &[(f64, f64)], tris: &[[u32; 3]]) {
    let positions: Vec<DVec3> = pts.iter().map(|&(x, y)| plane.at(x, y)).collect();
    let indices: Vec<u32> = tris.iter().flatten().copied().collect();
    b.mesh(m, &positions, &indices);
}

#[test]
fn square_wall_with_a_window_is_one_face_with_one_hole() {
    for plane in [
        Plane {
            origin: DVec3::ZERO,
            u: DVec3::X,
            v: DVec3::Z,
        },
        Plane::tilted(),
    ] {
        let mut b = SceneBuilder::new();
        let m = b.material([0.5; 3], [0.0; 3], false);
        let pts = [
            (0.0, 0.0),
            (3.0, 0.0),
            (3.0, 3.0),
            (0.0, 3.0),
            (1.0, 1.0),
            (2.0, 1.0),
            (2.0, 2.0),
            (1.0, 2.0),
        ];
        let tris = [
            [0, 1, 5],
            [0, 5, 4],
            [1, 2, 6],
            [1, 6, 5],
            [2, 3, 7],
            [2, 7, 6],
            [3, 0, 4],
            [3, 4, 7],
        ];
        mesh2d(&mut b, m, plane, &pts, &tris);
        let scene = load(&b.to_glb());
        assert_eq!(scene.triangles.len(), 8);
        let f = merged(&scene);
        assert_eq!(f.faces.len(), 1);
        let face = &f.faces[0];
        assert_eq!(face.holes.len(), 1);
        assert_eq!(face.outer.len(), 4);
        assert_eq!(face.holes[0].len(), 4);
        assert_eq!(face.kind, FaceKind::Extended);
        assert_eq!(face.triangles.len(), 8);
        assert!((face.area_m2 - 8.0).abs() < 1e-5, "{}", face.area_m2);
        // The module's triangulator rebuilds it from the rings: V + 2H - 2 triangles.
        let tris = triangulate_face(face).expect("triangulates");
        assert_eq!(tris.len(), 8);
    }
}

#[test]
fn l_shaped_floor_is_one_concave_face() {
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    let pts = [
        (0.0, 0.0),
        (2.0, 0.0),
        (2.0, 1.0),
        (1.0, 1.0),
        (1.0, 2.0),
        (0.0, 2.0),
    ];
    let floor = Plane {
        origin: DVec3::ZERO,
        u: DVec3::Z,
        v: DVec3::X,
    };
    mesh2d(
        &mut b,
        m,
        floor,
        &pts,
        &[[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]],
    );
    let f = merged(&load(&b.to_glb()));
    assert_eq!(f.faces.len(), 1);
    let face = &f.faces[0];
    assert_eq!(face.outer.len(), 6);
    assert!(face.holes.is_empty());
    assert_eq!(face.kind, FaceKind::Extended);
    assert!((face.normal - DVec3::Y).length() < 1e-9);
    assert!((face.area_m2 - 3.0).abs() < 1e-6);
    // Concave: one vertex turns clockwise about the normal.
    let n = face.outer.len();
    let reflex = (0..n)
        .filter(|&i| {
            let (a, b, c) = (
                face.outer[(i + n - 1) % n],
                face.outer[i],
                face.outer[(i + 1) % n],
            );
            (b - a).cross(c - b).dot(face.normal) < 0.0
        })
        .count();
    assert_eq!(reflex, 1);
}

#[test]
fn a_cube_of_twelve_triangles_is_six_parallelograms() {
    // Six separate meshes (duplicated corners, welded by the merge).
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    b.inward_box([m; 6], DVec3::splat(-1.0), DVec3::new(2.0, 1.0, 3.0), 1);
    let scene = load(&b.to_glb());
    assert_eq!(scene.triangles.len(), 12);
    let f = merged(&scene);
    assert_eq!(f.faces.len(), 6);
    assert!(f.faces.iter().all(|f| f.kind == FaceKind::Parallelogram));
    assert!((total_area(&f) - 2.0 * (6.0 + 12.0 + 8.0)).abs() < 1e-5);

    // One indexed mesh, outward normals.
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    let c: Vec<DVec3> = (0..8)
        .map(|i| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let idx: Vec<u32> = quads
        .iter()
        .flat_map(|q| [q[0], q[1], q[2], q[0], q[2], q[3]])
        .collect();
    b.mesh(m, &c, &idx);
    let f = merged(&load(&b.to_glb()));
    assert_eq!(f.faces.len(), 6);
    for face in &f.faces {
        assert_eq!(face.kind, FaceKind::Parallelogram);
        let centre: DVec3 = face.outer.iter().sum::<DVec3>() / 4.0;
        assert!(face.normal.dot(centre - DVec3::splat(0.5)) > 0.0, "outward");
    }

    // Finer tessellation (18 triangles a side): still six 4-vertex faces.
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    b.inward_box([m; 6], DVec3::ZERO, DVec3::splat(2.0), 3);
    let f = merged(&load(&b.to_glb()));
    assert_eq!(f.faces.len(), 6);
    assert!(f
        .faces
        .iter()
        .all(|f| f.kind == FaceKind::Parallelogram && f.triangles.len() == 18));
}

#[test]
fn coplanar_squares_of_different_materials_stay_two_faces() {
    let mut b = SceneBuilder::new();
    let m0 = b.material([0.5; 3], [0.0; 3], false);
    let m1 = b.material([0.2; 3], [0.0; 3], false);
    let p = Plane::tilted();
    b.quad(m0, p.origin, p.u, p.v, 1);
    b.quad(m1, p.origin + p.u, p.u, p.v, 1);
    let f = merged(&load(&b.to_glb()));
    assert_eq!(f.faces.len(), 2);
    assert_ne!(f.faces[0].material, f.faces[1].material);

    // Same material but one double-sided: also two faces.
    let mut b = SceneBuilder::new();
    let m0 = b.material([0.5; 3], [0.0; 3], false);
    let m1 = b.material([0.5; 3], [0.0; 3], true);
    b.quad(m0, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    b.quad(m1, DVec3::X, DVec3::X, DVec3::Y, 1);
    assert_eq!(merged(&load(&b.to_glb())).faces.len(), 2);

    // Same material: one face.
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    b.quad(m, p.origin, p.u, p.v, 1);
    b.quad(m, p.origin + p.u, p.u, p.v, 1);
    let f = merged(&load(&b.to_glb()));
    assert_eq!(f.faces.len(), 1);
    assert_eq!(f.faces[0].kind, FaceKind::Parallelogram);
}

#[test]
fn coplanar_squares_touching_at_a_corner_stay_two_faces() {
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    let p = Plane::tilted();
    b.quad(m, p.origin, p.u, p.v, 1);
    b.quad(m, p.origin + p.u + p.v, p.u, p.v, 1);
    let f = merged(&load(&b.to_glb()));
    assert_eq!(f.faces.len(), 2);
    assert!(f.faces.iter().all(|f| f.kind == FaceKind::Parallelogram));
}

#[test]
fn t_junction_square_is_one_parallelogram() {
    // A 1 x 2 rectangle (2 triangles) beside two unit squares (4 triangles): the squares' shared
    // corner (1, 1) lies inside the rectangle's long edge.
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    let p = Plane::tilted();
    mesh2d(
        &mut b,
        m,
        p,
        &[(0.0, 0.0), (1.0, 0.0), (1.0, 2.0), (0.0, 2.0)],
        &[[0, 1, 2], [0, 2, 3]],
    );
    mesh2d(
        &mut b,
        m,
        p,
        &[
            (1.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (2.0, 2.0),
            (1.0, 2.0),
        ],
        &[[0, 1, 2], [0, 2, 3], [3, 2, 4], [3, 4, 5]],
    );
    let scene = load(&b.to_glb());
    let f = merged(&scene);
    assert_eq!(f.faces.len(), 1, "{:#?}", f.faces);
    let face = &f.faces[0];
    assert_eq!(face.kind, FaceKind::Parallelogram);
    assert_eq!(face.outer.len(), 4);
    assert!(f.edges_split >= 1);
    assert!((face.area_m2 - 4.0).abs() < 1e-5);
}

#[test]
fn collinear_overlapping_edges_join_faces() {
    // Two rectangles whose sides overlap over half their length: x = 1, 1 <= y <= 2.
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    let p = Plane::tilted();
    b.quad(m, p.at(0.0, 0.0), p.u, p.v * 2.0, 1);
    b.quad(m, p.at(1.0, 1.0), p.u, p.v * 2.0, 1);
    let f = merged(&load(&b.to_glb()));
    assert_eq!(f.faces.len(), 1);
    assert_eq!(f.faces[0].outer.len(), 8);
    assert!(f.faces[0].holes.is_empty());
    assert!((f.faces[0].area_m2 - 4.0).abs() < 1e-5);
}

/// Triangulates 2D rings with the module's triangulator and merges them back (in the z = 0 plane).
fn merge_rings(rings: &[Vec<DVec2>]) -> FaceSet {
    let flat: Vec<DVec2> = rings.concat();
    let tris = triangulate_polygon(rings).expect("triangulates");
    let tris3: Vec<[DVec3; 3]> = tris
        .iter()
        .map(|t| t.map(|i| DVec3::new(flat[i].x, flat[i].y, 0.0)))
        .collect();
    merged(&scene_of(&tris3))
}

fn ring(pts: &[(f64, f64)]) -> Vec<DVec2> {
    pts.iter().map(|&(x, y)| DVec2::new(x, y)).collect()
}

#[test]
fn holes_touching_the_outer_ring_or_each_other_at_a_vertex() {
    // A diamond hole whose right corner is a vertex of the outer ring.
    let outer = ring(&[(0.0, 0.0), (4.0, 0.0), (4.0, 2.0), (4.0, 4.0), (0.0, 4.0)]);
    let hole = ring(&[(4.0, 2.0), (3.0, 1.0), (2.0, 2.0), (3.0, 3.0)]);
    let f = merge_rings(&[outer, hole]);
    assert_eq!(f.faces.len(), 1);
    let face = &f.faces[0];
    assert_eq!(face.holes.len(), 1);
    // (4, 2) is kept in the outer ring although collinear: the hole touches it there.
    assert_eq!(face.outer.len(), 5);
    assert_eq!(face.holes[0].len(), 4);
    assert!((face.area_m2 - 14.0).abs() < 1e-12);

    // Two triangular holes sharing their apex (3, 3).
    let outer = ring(&[(0.0, 0.0), (6.0, 0.0), (6.0, 6.0), (0.0, 6.0)]);
    let left = ring(&[(3.0, 3.0), (1.0, 2.0), (1.0, 4.0)]);
    let right = ring(&[(3.0, 3.0), (5.0, 4.0), (5.0, 2.0)]);
    let f = merge_rings(&[outer, left, right]);
    assert_eq!(f.faces.len(), 1);
    assert_eq!(f.faces[0].holes.len(), 2);
    assert!((f.faces[0].area_m2 - 32.0).abs() < 1e-12);
}

#[test]
fn overlapping_coplanar_triangles_are_cut_not_merged_invalid() {
    // A flat spiral strip that winds more than once around: connected through shared edges, but
    // its second turn overlaps the first, so its boundary would cross itself. The first turn loses
    // what the second (listed later) covers (every piece of surface counted once), and the faces
    // are valid.
    let mut tris = Vec::new();
    let at = |k: usize, outer: bool| {
        let a = k as f64 * 0.5;
        let r = 1.0 + 0.05 * a + if outer { 1.0 } else { 0.0 };
        DVec3::new(r * a.cos(), r * a.sin(), 0.0)
    };
    for k in 0..18 {
        tris.push([at(k, false), at(k, true), at(k + 1, true)]);
        tris.push([at(k, false), at(k + 1, true), at(k + 1, false)]);
    }
    let scene = scene_of(&tris);
    assert!(
        scene.triangles.iter().all(|t| t.cross().z < 0.0)
            || scene.triangles.iter().all(|t| t.cross().z > 0.0)
    );
    let f = merged(&scene);
    println!(
        "spiral: {} faces, {} split, {} cut, {} m2 removed",
        f.faces.len(),
        f.groups_split,
        f.overlaps_cut,
        f.overlap_area_removed_m2
    );
    assert!(f.overlaps_cut > 0);
    assert_eq!(f.duplicates_dropped, 0);
    let sum: f64 = scene.triangles.iter().map(|t| t.area()).sum();
    assert!(f.overlap_area_removed_m2 > 0.1 * sum);
    assert!((total_area(&f) - (sum - f.overlap_area_removed_m2)).abs() < 1e-9 * sum);
}

#[test]
fn non_manifold_edges_split_faces_instead_of_failing() {
    // A floor of two triangles with a wall standing on their shared diagonal: the floor merges,
    // the wall stays apart. Then a third coplanar triangle on the same edge: nothing merges there.
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    let floor = Plane {
        origin: DVec3::ZERO,
        u: DVec3::X,
        v: DVec3::Y,
    };
    mesh2d(
        &mut b,
        m,
        floor,
        &[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)],
        &[[0, 1, 2], [0, 2, 3]],
    );
    b.mesh(
        m,
        &[
            DVec3::ZERO,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.5, 0.5, 1.0),
        ],
        &[0, 1, 2],
    );
    let f = merged(&load(&b.to_glb()));
    assert_eq!(f.faces.len(), 2);
    let up: Vec<_> = f.faces.iter().filter(|f| f.normal.z > 0.999).collect();
    assert_eq!(up.len(), 1);
    assert_eq!(up[0].triangles.len(), 2);

    mesh2d(
        &mut b,
        m,
        floor,
        &[(0.0, 0.0), (1.0, 1.0), (0.2, 0.9)],
        &[[0, 1, 2]],
    );
    let f = merged(&load(&b.to_glb()));
    // The new triangle overlaps floor triangle (0, 2, 3), which loses that part (the new one is
    // listed later): the floor, counted once, is one face again beside the wall.
    assert_eq!(f.overlaps_cut, 1);
    assert_eq!(f.faces.len(), 2);
    assert_eq!(f.groups_split, 0);
    let up: Vec<_> = f.faces.iter().filter(|f| f.normal.z > 0.999).collect();
    assert_eq!(up.len(), 1);
    assert!((up[0].area_m2 - 1.0).abs() < 1e-9, "{}", up[0].area_m2);
}

#[test]
fn degenerate_triangles_are_dropped_and_counted() {
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 1);
    // Zero area (collinear) and a repeated vertex.
    b.mesh(
        m,
        &[DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0)],
        &[0, 1, 2, 0, 0, 1],
    );
    let scene = load(&b.to_glb());
    let f = merged(&scene);
    assert_eq!(f.triangles_in, 4);
    assert_eq!(f.degenerate_dropped, 2);
    assert_eq!(f.faces.len(), 1);
}

#[test]
fn mirrored_node_transform_merges_like_the_original() {
    let mut b = SceneBuilder::new();
    let m = b.material([0.5; 3], [0.0; 3], false);
    b.quad(m, DVec3::ZERO, DVec3::X, DVec3::Y, 4);
    let glb = b.to_glb();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin = glb[28 + json_len..].to_vec();
    doc["nodes"][0]["scale"] = serde_json::json!([-1.0, 1.0, 1.0]);
    let f = merged(&load(&glb_from_parts(&doc, &bin)));
    assert_eq!(f.faces.len(), 1);
    assert_eq!(f.faces[0].kind, FaceKind::Parallelogram);
    assert!((f.faces[0].normal - DVec3::Z).length() < 1e-9);
}

#[test]
fn very_large_and_very_small_coordinates_merge_the_same() {
    for (offset, size) in [
        (DVec3::splat(65536.0), 1.0),
        (DVec3::ZERO, 1e-4),
        (DVec3::new(1e3, -2e3, 5e2), 1e3),
    ] {
        let mut b = SceneBuilder::new();
        let m = b.material([0.5; 3], [0.0; 3], false);
        b.inward_box([m; 6], offset, offset + DVec3::splat(size), 2);
        let f = merged(&load(&b.to_glb()));
        assert_eq!(f.faces.len(), 6, "offset {offset} size {size}");
        assert!(f.faces.iter().all(|f| f.kind == FaceKind::Parallelogram));
    }
}

#[test]
fn near_duplicate_vertices_weld_and_slivers_stay_valid() {
    // A 4 x 4 grid of quads whose shared corners are jittered by 1e-9 (a sloppy export) plus a
    // fan of thin slivers along one edge.
    let mut tris = Vec::new();
    let jitter = |i: usize, j: usize, k: usize| {
        let h = ((i * 31 + j * 17 + k * 7) % 11) as f64 - 5.0;
        DVec3::new(h * 1e-10, -h * 1e-10, h * 2e-10)
    };
    for j in 0..4 {
        for i in 0..4 {
            let c = |di: usize, dj: usize, k: usize| {
                DVec3::new((i + di) as f64, (j + dj) as f64, 0.0) + jitter(i + di, j + dj, k)
            };
            tris.push([c(0, 0, 0), c(1, 0, 1), c(1, 1, 2)]);
            tris.push([c(0, 0, 3), c(1, 1, 4), c(0, 1, 5)]);
        }
    }
    // Slivers below y = 0: a fan from (2, -1e-3) to points along the x axis.
    let apex = DVec3::new(2.0, -1e-3, 0.0);
    for i in 0..4 {
        tris.push([
            apex,
            DVec3::new((i + 1) as f64, 0.0, 0.0),
            DVec3::new(i as f64, 0.0, 0.0),
        ]);
    }
    let scene = scene_of(&tris);
    let f = merged(&scene);
    assert_eq!(f.faces.len(), 1, "{:#?}", f.faces);
    assert_eq!(f.faces[0].outer.len(), 5);
}

#[test]
fn a_long_thin_noisy_strip_is_one_face() {
    // 1000 m x 1 cm in 400 quads, corners jittered off the plane by up to 1e-4 m (the tolerance is
    // 1e-6 of the diagonal, 1 mm): one face, its corners near the plane of its largest triangle.
    let noise = |i: usize, j: usize| ((i * 7 + j * 13) % 5) as f64 * 2.5e-5 - 5e-5;
    let c = |i: usize, j: usize| DVec3::new(2.5 * i as f64, 0.01 * j as f64, noise(i, j));
    let mut tris = Vec::new();
    for i in 0..400 {
        tris.push([c(i, 0), c(i + 1, 0), c(i + 1, 1)]);
        tris.push([c(i, 0), c(i + 1, 1), c(i, 1)]);
    }
    let f = merged(&scene_of(&tris));
    assert_eq!(f.groups_split, 0);
    assert_eq!(f.faces.len(), 1);
    assert_eq!(f.faces[0].triangles.len(), 800);
}

#[test]
fn a_gently_curved_sheet_does_not_creep_into_one_face() {
    // z = x^2 / 2000 over 10 m x 1 m in 10 cm quads: neighbours are coplanar within the tolerances
    // (1e-4 rad apart, 5 um off each other's plane) but the sheet bends 5 cm: several flat faces.
    let c = |i: usize, j: usize| {
        let x = 0.1 * i as f64;
        DVec3::new(x, 0.1 * j as f64, x * x / 2000.0)
    };
    let mut tris = Vec::new();
    for i in 0..100 {
        for j in 0..10 {
            tris.push([c(i, j), c(i + 1, j), c(i + 1, j + 1)]);
            tris.push([c(i, j), c(i + 1, j + 1), c(i, j + 1)]);
        }
    }
    let f = merged(&scene_of(&tris));
    assert_eq!(f.groups_split, 0);
    println!("curved sheet: {} faces", f.faces.len());
    assert!(f.faces.len() > 3, "{} faces", f.faces.len());
    assert!(f.faces.len() < 200, "{} faces", f.faces.len());
}

fn scene_of(tris: &[[DVec3; 3]]) -> Scene {
    Scene::of_triangles(tris)
}

// ---------------------------------------------------------------------------------------------
// Property test: random polygons with holes survive triangulation, shuffling and re-indexing.

/// A star-shaped ring about `centre`: `radii.len()` vertices at jittered, increasing angles.
fn star(centre: DVec2, scale: f64, radii: &[f64], jitter: &[f64], phase: f64) -> Vec<DVec2> {
    let n = radii.len();
    (0..n)
        .map(|i| {
            let a = phase + std::f64::consts::TAU * (i as f64 + jitter[i]) / n as f64;
            centre + DVec2::from_angle(a) * (scale * radii[i])
        })
        .collect()
}

/// Smallest distance of a vertex to the line through its neighbours (0 for a collinear vertex).
fn min_turn(ring: &[DVec2]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let (a, b, c) = (ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]);
            (c - a).perp_dot(b - a).abs() / (c - a).length()
        })
        .fold(f64::INFINITY, f64::min)
}

#[derive(Debug, Clone)]
struct Polygon {
    rings: Vec<Vec<DVec2>>,
}

fn polygon_strategy() -> impl Strategy<Value = Polygon> {
    let ring = |min: usize, max: usize| {
        (min..max).prop_flat_map(|n| {
            (
                prop::collection::vec(0.5f64..1.0, n),
                prop::collection::vec(0.1f64..0.9, n),
                0.0f64..std::f64::consts::TAU,
            )
        })
    };
    (ring(4, 24), prop::collection::vec(ring(3, 9), 0..5)).prop_map(|(outer, holes)| {
        let outer_ring = star(DVec2::ZERO, 1.0, &outer.0, &outer.1, outer.2);
        // Largest disc about the centre inside the outer ring.
        let n = outer_ring.len();
        let safe = (0..n)
            .map(|i| {
                let (a, b) = (outer_ring[i], outer_ring[(i + 1) % n]);
                let t = (-a).dot(b - a) / (b - a).length_squared();
                (a + (b - a) * t.clamp(0.0, 1.0)).length()
            })
            .fold(f64::INFINITY, f64::min);
        let k = holes.len();
        let (rho, r_hole) = if k <= 1 {
            (0.0, 0.8 * safe)
        } else {
            let rho = 0.5 * safe;
            (
                rho,
                (0.4 * safe).min(0.8 * rho * (std::f64::consts::PI / k as f64).sin()),
            )
        };
        let mut rings = vec![outer_ring];
        for (j, h) in holes.iter().enumerate() {
            let c = DVec2::from_angle(std::f64::consts::TAU * j as f64 / k.max(1) as f64) * rho;
            let mut ring = star(c, r_hole, &h.0, &h.1, h.2);
            ring.reverse();
            rings.push(ring);
        }
        Polygon { rings }
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn triangulated_polygons_merge_back_into_themselves(
        poly in polygon_strategy(),
        axis in (-1.0f64..1.0, -1.0f64..1.0, 0.1f64..1.0),
        angle in 0.0f64..std::f64::consts::TAU,
        log_scale in -3.0f64..3.0,
        shift in (-1e3f64..1e3, -1e3f64..1e3, -1e3f64..1e3),
        seed in any::<u64>(),
    ) {
        // Skip the (rare) polygons with a vertex nearly collinear with its neighbours: the merge
        // removes those on purpose.
        prop_assume!(poly.rings.iter().all(|r| min_turn(r) > 1e-4));
        let flat: Vec<DVec2> = poly.rings.concat();
        let tris = triangulate_polygon(&poly.rings).expect("the generator makes valid polygons");
        prop_assert_eq!(tris.len(), flat.len() + 2 * (poly.rings.len() - 1) - 2);

        // Into 3D: rotate, scale, translate.
        let q = DQuat::from_axis_angle(DVec3::new(axis.0, axis.1, axis.2).normalize(), angle);
        let s = 10f64.powf(log_scale);
        let t = DVec3::new(shift.0, shift.1, shift.2);
        let to3 = |p: DVec2| q * (DVec3::new(p.x, p.y, 0.0) * s) + t;
        // Re-index: a permuted vertex buffer; shuffle the triangles and rotate their corners.
        let mut rng = seed;
        let mut next = move |m: usize| {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng % m as u64) as usize
        };
        let mut perm: Vec<usize> = (0..flat.len()).collect();
        for i in (1..perm.len()).rev() {
            perm.swap(i, next(i + 1));
        }
        let positions: Vec<DVec3> = perm.iter().map(|&i| to3(flat[i])).collect();
        let mut slot = vec![0; flat.len()];
        for (new, &old) in perm.iter().enumerate() {
            slot[old] = new;
        }
        let mut indexed: Vec<[usize; 3]> = tris.iter().map(|t| t.map(|i| slot[i])).collect();
        for i in (1..indexed.len()).rev() {
            let j = next(i + 1);
            indexed.swap(i, j);
        }
        let mut tris3 = Vec::new();
        for tri in &indexed {
            let r = next(3);
            tris3.push([0, 1, 2].map(|k| positions[tri[(k + r) % 3]]));
        }
        let scene = scene_of(&tris3);
        // Skip the (rare) triangulations with an ear thinner than the weld tolerance: the merge
        // drops such slivers as degenerate on purpose, and the face's area loses them.
        let weld = wavrad::faces::WELD_REL * scene.diagonal();
        prop_assume!(tris3.iter().all(|[a, b, c]| {
            let longest = a.distance(*b).max(b.distance(*c)).max(c.distance(*a));
            (*b - *a).cross(*c - *a).length() / longest > weld
        }));
        let f = merge_planar_faces(&scene);
        let problems = validate_faces(&f);
        prop_assert!(problems.is_empty(), "{:?}", problems);
        prop_assert_eq!(f.faces.len(), 1);
        let face = &f.faces[0];
        prop_assert_eq!(face.holes.len(), poly.rings.len() - 1);
        let verts = face.outer.len() + face.holes.iter().map(Vec::len).sum::<usize>();
        prop_assert_eq!(verts, flat.len());
        let area: f64 = poly
            .rings
            .iter()
            .map(|r| {
                let n = r.len();
                (0..n).map(|i| r[i].perp_dot(r[(i + 1) % n])).sum::<f64>() * 0.5
            })
            .sum::<f64>()
            * s
            * s;
        prop_assert!((face.area_m2 - area).abs() <= 1e-9 * area, "{} vs {}", face.area_m2, area);
        // Every ring comes back as one of the polygon's rings, up to the starting vertex.
        let diag = scene.diagonal();
        let mut rings3: Vec<Vec<DVec3>> = poly.rings.iter().map(|r| r.iter().map(|&p| to3(p)).collect()).collect();
        for ring in std::iter::once(&face.outer).chain(&face.holes) {
            let found = rings3.iter().position(|orig| {
                orig.len() == ring.len()
                    && (0..ring.len()).any(|r| {
                        (0..ring.len()).all(|i| orig[(i + r) % ring.len()].distance(ring[i]) <= 1e-9 * diag)
                    })
            });
            prop_assert!(found.is_some(), "ring {:?} is not one of the polygon's", ring);
            rings3.remove(found.unwrap_or(0));
        }
    }
}
