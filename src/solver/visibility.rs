//! Visibility: a BVH (obvhs' compressed wide BVH) over the scene's occluding triangles and an
//! open-segment occlusion test.
//!
//! Conventions (docs/design.md section 6): every triangle occludes, whatever its sides or emission; the
//! faces a link joins never occlude it (they are passed as `ignore`); hits within
//! `end_epsilon = ENDPOINT_EPSILON_REL * scene diagonal` of either end of a segment do not count.
//! Boxes are padded by `BOX_PADDING_REL * diagonal` (unpadded boxes on axis-aligned walls are slow
//! and f32 rounding could miss grazing hits). Intersection is done in `f64`.

use glam::{DVec3, Vec3A};
use obvhs::{aabb::Aabb, cwbvh::CwBvh, ray::Ray, Boundable, BvhBuildParams};
use std::sync::atomic::{AtomicU64, Ordering};

/// Hits closer than this fraction of the scene diagonal to a segment end are ignored.
pub const ENDPOINT_EPSILON_REL: f64 = 1e-6;
/// BVH boxes are padded by this fraction of the scene diagonal.
pub const BOX_PADDING_REL: f64 = 1e-5;

/// One occluding triangle, tagged with the face it belongs to.
#[derive(Debug, Clone, Copy)]
pub struct Occluder {
    pub vertices: [DVec3; 3],
    pub face: u32,
    aabb: Aabb,
}

impl Boundable for Occluder {
    fn aabb(&self) -> Aabb {
        self.aabb
    }
}

/// The scene's occluders and their BVH.
pub struct Visibility {
    occluders: Vec<Occluder>,
    bvh: Option<CwBvh>,
    end_epsilon: f64,
    rays: AtomicU64,
}

impl std::fmt::Debug for Visibility {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Visibility")
            .field("occluders", &self.occluders.len())
            .finish()
    }
}

impl Visibility {
    /// Builds the BVH over `(triangle, face)` pairs; `diagonal` is the scene's bounding-box diagonal.
    pub fn new(triangles: impl IntoIterator<Item = ([DVec3; 3], u32)>, diagonal: f64) -> Self {
        let pad = (BOX_PADDING_REL * diagonal).max(f64::MIN_POSITIVE) as f32;
        let occluders: Vec<Occluder> = triangles
            .into_iter()
            .map(|(v, face)| {
                let lo = v[0].min(v[1]).min(v[2]).as_vec3a() - Vec3A::splat(pad);
                let hi = v[0].max(v[1]).max(v[2]).as_vec3a() + Vec3A::splat(pad);
                Occluder {
                    vertices: v,
                    face,
                    aabb: Aabb::new(lo, hi),
                }
            })
            .collect();
        let bvh = if occluders.is_empty() {
            None
        } else {
            Some(obvhs::cwbvh::builder::build_cwbvh(
                &occluders,
                BvhBuildParams::medium_build(),
                &mut std::time::Duration::default(),
            ))
        };
        Visibility {
            occluders,
            bvh,
            end_epsilon: ENDPOINT_EPSILON_REL * diagonal,
            rays: AtomicU64::new(0),
        }
    }

    /// Number of occluding triangles in the BVH.
    pub fn occluder_count(&self) -> usize {
        self.occluders.len()
    }

    /// The distance from either end of a segment within which hits do not count.
    pub fn end_epsilon(&self) -> f64 {
        self.end_epsilon
    }

    /// Number of segment tests done so far.
    pub fn rays_traced(&self) -> u64 {
        self.rays.load(Ordering::Relaxed)
    }

    /// True when nothing but the faces in `ignore` blocks the open segment `p`-`q`; counted in
    /// [`Visibility::rays_traced`].
    pub fn visible(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        self.count_rays(1);
        self.visible_uncounted(p, q, ignore)
    }

    /// Adds `n` segment tests done with [`Visibility::visible_uncounted`] to the count.
    pub(crate) fn count_rays(&self, n: u64) {
        if n > 0 {
            self.rays.fetch_add(n, Ordering::Relaxed);
        }
    }

    /// [`Visibility::visible`] without counting, for a loop that traces many rays and counts
    /// them once with [`Visibility::count_rays`]: one shared counter bumped per ray is a cache
    /// line every core writes (a tenth of a solve's time on two cores, found by profiling).
    pub(crate) fn visible_uncounted(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        let Some(bvh) = &self.bvh else { return true };
        let d = q - p;
        let len = d.length();
        if len <= 2.0 * self.end_epsilon {
            return true;
        }
        let dir = d / len;
        let tmin = self.end_epsilon;
        let tmax = len - self.end_epsilon;
        let ray = Ray::new(
            p.as_vec3a(),
            dir.as_vec3a(),
            0.0,
            tmax as f32 * (1.0 + 1e-6) + 1e-30,
        );
        bvh.ray_traverse_miss(ray, |_, id| {
            let occ = &self.occluders[bvh.primitive_indices[id] as usize];
            if occ.face == ignore[0] || occ.face == ignore[1] {
                return f32::INFINITY;
            }
            match intersect(p, dir, &occ.vertices) {
                Some(t) if t > tmin && t < tmax => 0.0,
                _ => f32::INFINITY,
            }
        })
    }
}

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

/// Möller-Trumbore in f64; returns the ray parameter of the hit (edges inclusive).
#[inline]
pub(crate) fn intersect(origin: DVec3, dir: DVec3, v: &[DVec3; 3]) -> Option<f64> {
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - v[0];
    let a = s.dot(p) * inv;
    if !(-1e-12..=1.0 + 1e-12).contains(&a) {
        return None;
    }
    let q = s.cross(e1);
    let b = dir.dot(q) * inv;
    if b < -1e-12 || a + b > 1.0 + 1e-12 {
        return None;
    }
    Some(e2.dot(q) * inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall() -> Vec<([DVec3; 3], u32)> {
        // A unit square in the plane z = 0.5, two triangles of face 7.
        let a = DVec3::new(0.0, 0.0, 0.5);
        let b = DVec3::new(1.0, 0.0, 0.5);
        let c = DVec3::new(1.0, 1.0, 0.5);
        let d = DVec3::new(0.0, 1.0, 0.5);
        vec![([a, b, c], 7), ([a, c, d], 7)]
    }

    #[test]
    fn segment_through_wall_is_blocked_unless_ignored() {
        let v = Visibility::new(wall(), 2.0);
        let p = DVec3::new(0.3, 0.6, 0.0);
        let q = DVec3::new(0.4, 0.5, 1.0);
        assert!(!v.visible(p, q, [u32::MAX; 2]));
        assert!(v.visible(p, q, [7, u32::MAX]));
        // Beside the wall: free.
        assert!(v.visible(
            DVec3::new(1.5, 0.5, 0.0),
            DVec3::new(1.5, 0.5, 1.0),
            [u32::MAX; 2]
        ));
        // Ending on the wall (within epsilon): free.
        assert!(v.visible(p, DVec3::new(0.3, 0.6, 0.5), [u32::MAX; 2]));
    }

    #[test]
    fn matches_brute_force_on_random_segments() {
        let tris = wall();
        let v = Visibility::new(tris.clone(), 2.0);
        let mut state = 12345u64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64) / ((1u64 << 53) as f64)
        };
        for _ in 0..2000 {
            let p = DVec3::new(rnd() * 1.4 - 0.2, rnd() * 1.4 - 0.2, rnd() * 0.4);
            let q = DVec3::new(rnd() * 1.4 - 0.2, rnd() * 1.4 - 0.2, 0.6 + rnd() * 0.4);
            let d = q - p;
            let t = (0.5 - p.z) / d.z;
            let h = p + d * t;
            let brute_blocked = (0.0..=1.0).contains(&h.x) && (0.0..=1.0).contains(&h.y);
            assert_eq!(!v.visible(p, q, [u32::MAX; 2]), brute_blocked, "{p} {q}");
        }
    }

    /// `(triangle, face)` pairs.
    type Occluders = Vec<([DVec3; 3], u32)>;
    /// Per face, its plane: `(normal, a point)`.
    type Planes = Vec<(DVec3, DVec3)>;

    /// A closed box [0,2]x[0,1]x[0,1.5] (faces 0-5, inward) around a block (faces 6-11, outward),
    /// as `(triangle, face)` pairs and per face its plane.
    fn room_with_block(block_lo: DVec3, block_size: DVec3) -> (Occluders, Planes) {
        let mut tris = Vec::new();
        let mut planes = Vec::new();
        let mut quad = |o: DVec3, u: DVec3, v: DVec3| {
            let face = planes.len() as u32;
            tris.push(([o, o + u, o + u + v], face));
            tris.push(([o, o + u + v, o + v], face));
            planes.push((u.cross(v).normalize(), o));
        };
        // The six sides of the box at `lo` with edges `x, y, z`, normals inward.
        let sides = |lo: DVec3, x: DVec3, y: DVec3, z: DVec3| {
            [
                (lo, y, z),
                (lo + x, z, y),
                (lo, z, x),
                (lo + y, x, z),
                (lo, x, y),
                (lo + z, y, x),
            ]
        };
        for (o, u, v) in sides(DVec3::ZERO, DVec3::X * 2.0, DVec3::Y, DVec3::Z * 1.5) {
            quad(o, u, v);
        }
        let sx = DVec3::X * block_size.x;
        let (sy, sz) = (DVec3::Y * block_size.y, DVec3::Z * block_size.z);
        for (o, u, v) in sides(block_lo, sx, sy, sz) {
            quad(o, v, u); // outward
        }
        (tris, planes)
    }

    fn vertices(tris: &[([DVec3; 3], u32)]) -> Vec<DVec3> {
        tris.iter().flat_map(|(t, _)| t.iter().copied()).collect()
    }

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

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config {
            cases: 64,
            rng_seed: proptest::test_runner::RngSeed::Fixed(0xb0_0d_ed),
            failure_persistence: None,
            ..Default::default()
        })]

        /// Leaving the bounding faces out of the BVH changes no verdict, for segments between
        /// points on faces, towards a point light and towards directional lights' far ends (the
        /// brute-force twin keeps every face).
        #[test]
        fn leaving_bounding_faces_out_changes_no_verdict(
            seed in proptest::prelude::any::<u64>(),
            lo in proptest::array::uniform3(0.05f64..1.0),
            size in proptest::array::uniform3(0.05f64..0.45),
            light in proptest::array::uniform3(-0.5f64..2.5),
            sun in proptest::array::uniform3(-1.0f64..1.0),
        ) {
            let (tris, planes) = room_with_block(DVec3::from(lo), DVec3::from(size));
            let light = DVec3::from(light);
            let toward_sun = DVec3::from(sun).normalize_or(DVec3::Y);
            let mut ends = vertices(&tris);
            ends.push(light);
            let diagonal = 3.0;
            let eps = ENDPOINT_EPSILON_REL * diagonal;
            let bounds = bounding_planes(&planes, &ends, &[toward_sun], eps);
            let all = Visibility::new(tris.clone(), diagonal);
            let culled = Visibility::new(
                tris.iter().copied().filter(|(_, f)| !bounds[*f as usize]),
                diagonal,
            );
            let mut state = seed | 1;
            let mut rnd = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64
            };
            let point_on_face = |rnd: &mut dyn FnMut() -> f64| {
                let (t, f) = tris[(rnd() * tris.len() as f64) as usize % tris.len()];
                let (mut a, mut b) = (rnd(), rnd());
                if a + b > 1.0 {
                    (a, b) = (1.0 - a, 1.0 - b);
                }
                (t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b, f)
            };
            for _ in 0..300 {
                let (p, fp) = point_on_face(&mut rnd);
                let (q, fq) = point_on_face(&mut rnd);
                for (end, ignore) in [
                    (q, [fp, fq]),
                    (light, [fp, u32::MAX]),
                    (p + toward_sun * 4.0 * diagonal, [fp, u32::MAX]),
                ] {
                    proptest::prop_assert_eq!(
                        all.visible(p, end, ignore),
                        culled.visible(p, end, ignore),
                        "{} -> {}", p, end
                    );
                }
            }
        }
    }
}
