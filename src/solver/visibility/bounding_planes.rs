//! Which faces' planes can never occlude a segment the solver traces, so that they stay out of
//! the BVH: [`bounding_planes`] (the walls, floor and ceiling of a closed room are such planes).
//!
//! Invariant: a plane is reported bounding only when every point a segment can end at lies
//! weakly on one side of it (within `eps`) and every direction towards a directional light points
//! to that side; past [`MAX_BOUNDING_TESTS`] point-plane tests the remaining planes are kept as
//! occluders (never wrong, only slower). Leaving them out changes no verdict
//! (`leaving_bounding_faces_out_changes_no_verdict` in `mod.rs`).

use glam::DVec3;

/// Most point-plane tests [`bounding_planes`] makes; past it, the remaining planes are kept as
/// occluders (always correct, only slower to trace).
pub const MAX_BOUNDING_TESTS: usize = 100_000_000;

/// Seed of the order in which [`bounding_planes`] tries the points (any fixed value).
const POINT_ORDER_SEED: u64 = 0xb0d1_7e55_0f5c_e4e5;

/// Which planes can never occlude a segment: those with every point a segment can end at
/// (`endpoints`: the scene's vertices and punctual lights' positions, all segment ends being on
/// faces or at a light) weakly on one side, within `eps`, and every direction towards a
/// directional light (`toward_lights`: its far shadow-ray ends) pointing to that side. A segment
/// between two points of a closed half-space stays in it, so it can meet the plane only at an end,
/// where hits do not count (`ENDPOINT_EPSILON_REL`), or lying in the plane, where it exchanges no
/// light. The walls, floor and ceiling of a closed room are such planes: left out of the BVH, the
/// rays along them stop traversing their padded boxes. Planes are taken in the given order
/// (largest faces first pays best) until [`MAX_BOUNDING_TESTS`] is spent.
pub fn bounding_planes(
    planes: &[(DVec3, DVec3)],
    endpoints: &[DVec3],
    toward_lights: &[DVec3],
    eps: f64,
) -> Vec<bool> {
    bounding_planes_within(planes, endpoints, toward_lights, eps, MAX_BOUNDING_TESTS)
}

fn bounding_planes_within(
    planes: &[(DVec3, DVec3)],
    endpoints: &[DVec3],
    toward_lights: &[DVec3],
    eps: f64,
    mut budget: usize,
) -> Vec<bool> {
    // Points in a scrambled order, so that a plane with points on both sides is found out early.
    let mut points = endpoints.to_vec();
    crate::shuffle::shuffle(&mut points, POINT_ORDER_SEED);
    planes
        .iter()
        .map(|&(normal, origin)| {
            if budget < points.len() {
                return false;
            }
            let (mut front, mut back) = (false, false);
            for (i, p) in points.iter().enumerate() {
                let d = normal.dot(*p - origin);
                front |= d > eps;
                back |= d < -eps;
                if front && back {
                    budget -= i + 1;
                    return false;
                }
            }
            budget -= points.len();
            // Every end in the plane: a segment starts at the plane whatever its direction.
            if !(front || back) {
                return true;
            }
            let side = if front { 1.0 } else { -1.0 };
            toward_lights.iter().all(|t| side * normal.dot(*t) >= 0.0)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::tests::{room_with_block, vertices};
    use super::*;

    #[test]
    fn a_rooms_walls_bound_it_and_its_furniture_does_not() {
        let (tris, planes) = room_with_block(DVec3::new(0.8, 0.2, 0.5), DVec3::splat(0.4));
        let ends = vertices(&tris);
        let bounds = bounding_planes(&planes, &ends, &[], 1e-9);
        assert_eq!(bounds[..6], [true; 6], "the six walls");
        assert_eq!(
            bounds[6..],
            [false; 6],
            "the block's faces have room on both sides"
        );
        // A directional light below the floor shines up through it (shadow rays end below): the
        // floor (face 2, normal +y) occludes; a light above leaves it bounding.
        let up = bounding_planes(&planes, &ends, &[DVec3::NEG_Y], 1e-9);
        assert!(
            !up[2] && up[3],
            "floor occludes a light from below, ceiling bounds"
        );
        let down = bounding_planes(&planes, &ends, &[DVec3::Y], 1e-9);
        assert!(down[2] && !down[3]);
        // A point light outside the room, beyond the wall at x = 2: that wall occludes it.
        let mut with_light = ends.clone();
        with_light.push(DVec3::new(3.0, 0.5, 0.7));
        let outside = bounding_planes(&planes, &with_light, &[], 1e-9);
        assert!(!outside[1] && outside[0]);
        // A spent budget keeps planes as occluders: never wrong, only slower.
        let spent = bounding_planes_within(&planes, &ends, &[], 1e-9, ends.len() * 3);
        assert_eq!(spent[..3], [true; 3]);
        assert!(!spent[3..].iter().any(|&b| b));
    }
}
