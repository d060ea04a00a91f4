//! Planar-face merging as the face tests use it: every merge is checked by the validator.

use wavrad::faces::{merge_planar_faces, validate_faces, FaceSet};
use wavrad::scene::Scene;

/// Merges and checks the validator finds nothing.
pub fn merged(scene: &Scene) -> FaceSet {
    let faces = merge_planar_faces(scene);
    let problems = validate_faces(&faces);
    assert!(
        problems.is_empty(),
        "validator: {:#?}",
        problems.iter().map(|p| p.to_string()).collect::<Vec<_>>()
    );
    faces
}

/// The summed area of the faces (m^2).
pub fn total_area(f: &FaceSet) -> f64 {
    f.faces.iter().map(|f| f.area_m2).sum()
}
