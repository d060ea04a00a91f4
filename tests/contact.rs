//! Contact lines (issue 3): a surface standing on a face, or passing through it, cuts the face
//! along the line where they meet, so the footprint and the floor around it become two faces
//! (`faces/contact.rs`). Every case is a hand-made floor with something on it, checked by the
//! validator with its area conserved.

use glam::DVec3;
use wavrad::faces::{validate_faces, FaceKind, FaceSet};
use wavrad::scene::gltf_writer::SceneBuilder;
use wavrad::scene::{load_scene, ExternalFiles};

mod common;
use common::faces::{merged, total_area};

fn load(glb: &[u8]) -> wavrad::scene::Scene {
    load_scene(glb, &ExternalFiles::Refuse, 5_000_000).expect("hand-made scene loads")
}

/// A 2 x 2 floor (normal +y, two triangles) and what stands on it.
fn floor_with(stand: impl FnOnce(&mut SceneBuilder, u32)) -> FaceSet {
    let mut b = SceneBuilder::new();
    let floor = b.material([0.5; 3], [0.0; 3], false);
    let other = b.material([0.3; 3], [0.0; 3], false);
    b.quad(
        floor,
        DVec3::new(-1.0, 0.0, -1.0),
        DVec3::Z * 2.0,
        DVec3::X * 2.0,
        1,
    );
    stand(&mut b, other);
    let scene = load(&b.to_glb());
    let f = merged(&scene);
    assert!(validate_faces(&f).is_empty(), "{:?}", validate_faces(&f));
    let expected: f64 = scene.triangles.iter().map(|t| t.area()).sum();
    assert!((total_area(&f) - expected).abs() < 1e-9 * expected);
    f
}

fn floor_faces(f: &FaceSet) -> Vec<&wavrad::faces::Face> {
    f.faces.iter().filter(|x| x.material == 0).collect()
}

/// The four walls (facing out) of a 0.5 m square post over the middle of [`floor_with`]'s floor,
/// from height `y0` to `y0 + height`, each `n x n` quads.
fn post_walls(b: &mut SceneBuilder, m: u32, y0: f64, height: f64, n: u32) {
    let lo = DVec3::new(-0.25, y0, -0.25);
    let (x, y, z) = (DVec3::X * 0.5, DVec3::Y * height, DVec3::Z * 0.5);
    b.quad(m, lo, z, y, n); // -x
    b.quad(m, lo + x, y, z, n); // +x
    b.quad(m, lo, y, x, n); // -z
    b.quad(m, lo + z, x, y, n); // +z
}

/// A closed 0.5 m box standing on the middle of [`floor_with`]'s floor, each side `n x n` quads.
fn standing_box(b: &mut SceneBuilder, m: u32, n: u32) {
    post_walls(b, m, 0.0, 0.5, n);
    let (x, z) = (DVec3::X * 0.5, DVec3::Z * 0.5);
    b.quad(m, DVec3::new(-0.25, 0.5, -0.25), z, x, n); // top
}

/// The floor faces of `f` split into exactly a 0.25 m2 square and the 3.75 m2 rest.
fn assert_section_and_rest(f: &FaceSet, what: &str) {
    let mut areas: Vec<f64> = floor_faces(f).iter().map(|x| x.area_m2).collect();
    areas.sort_by(f64::total_cmp);
    assert_eq!(areas.len(), 2, "{what}: {areas:?}");
    assert!(
        (areas[0] - 0.25).abs() < 1e-9 && (areas[1] - 3.75).abs() < 1e-9,
        "{areas:?}"
    );
}

#[test]
fn a_box_standing_on_a_floor_cuts_its_footprint_out() {
    let f = floor_with(|b, m| standing_box(b, m, 1));
    let floor = floor_faces(&f);
    assert_eq!(floor.len(), 2, "the floor around the box and its footprint");
    let around = floor
        .iter()
        .find(|x| x.holes.len() == 1)
        .expect("a floor with a hole");
    let footprint = floor
        .iter()
        .find(|x| x.holes.is_empty())
        .expect("the footprint");
    assert!((around.area_m2 - 3.75).abs() < 1e-9);
    assert!((footprint.area_m2 - 0.25).abs() < 1e-9);
    assert_eq!(footprint.kind, FaceKind::Parallelogram);
    assert!(f.triangles_cut > 0);
    // The footprint's pieces come from the floor's two triangles.
    assert_eq!(f.source_triangle_count(footprint), 2);
}

#[test]
fn a_box_whose_walls_have_vertices_along_their_base_still_cuts_its_footprint_out() {
    // Each wall is 3 x 3 quads: its base is three collinear contact segments, and no cut line
    // crosses the footprint's side at the inner joints, so the floor piece along a side spans
    // several segments. It must still not join the footprint to the floor around it.
    let f = floor_with(|b, m| standing_box(b, m, 3));
    assert_section_and_rest(&f, "the floor around the box and its footprint");
}

#[test]
fn a_post_passing_through_a_floor_cuts_its_section_out() {
    // A square post from y = -0.5 to y = 0.5 through the floor: its walls cross the floor's plane
    // (no edge lies in it), and the floor inside the post is closed off like a footprint.
    let f = floor_with(|b, m| post_walls(b, m, -0.5, 1.0, 1));
    assert_section_and_rest(&f, "the floor around the post and its section");
    let floor = floor_faces(&f);
    assert!(floor.iter().any(|x| x.holes.len() == 1));
}

#[test]
fn a_wall_across_a_floor_splits_it_and_one_ending_inside_does_not() {
    // Across: the wall's base runs from z = -1 to z = 1 at x = 0.25.
    let f = floor_with(|b, m| {
        b.quad(m, DVec3::new(0.25, 0.0, -1.0), DVec3::Z * 2.0, DVec3::Y, 1);
    });
    let floor = floor_faces(&f);
    assert_eq!(floor.len(), 2);
    let mut areas: Vec<f64> = floor.iter().map(|x| x.area_m2).collect();
    areas.sort_by(f64::total_cmp);
    assert!(
        (areas[0] - 1.5).abs() < 1e-9 && (areas[1] - 2.5).abs() < 1e-9,
        "{areas:?}"
    );

    // Ending inside: the base stops at z = 0.5; the floor stays one face with no slit in its rings.
    let f = floor_with(|b, m| {
        b.quad(m, DVec3::new(0.25, 0.0, -1.0), DVec3::Z * 1.5, DVec3::Y, 1);
    });
    let floor = floor_faces(&f);
    assert_eq!(floor.len(), 1);
    assert!(floor[0].holes.is_empty());
    assert!((floor[0].area_m2 - 4.0).abs() < 1e-9);

    // Hanging under the (single-sided) floor: nothing to cut on its front.
    let f = floor_with(|b, m| {
        b.quad(
            m,
            DVec3::new(0.25, 0.0, -1.0),
            DVec3::NEG_Y,
            DVec3::Z * 2.0,
            1,
        );
    });
    assert_eq!(floor_faces(&f).len(), 1);
    assert_eq!(f.triangles_cut, 0);
}
