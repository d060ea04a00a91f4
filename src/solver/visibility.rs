//! Visibility: a BVH (obvhs' compressed wide BVH) over the scene's occluding triangles and an
//! open-segment occlusion test.
//!
//! Conventions (DESIGN.md section 6): every triangle occludes, whatever its sides or emission; the
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

    /// Number of segment tests done so far.
    pub fn rays_traced(&self) -> u64 {
        self.rays.load(Ordering::Relaxed)
    }

    /// True when nothing but the faces in `ignore` blocks the open segment `p`-`q`.
    pub fn visible(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        self.rays.fetch_add(1, Ordering::Relaxed);
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

/// Möller-Trumbore in f64; returns the ray parameter of the hit (edges inclusive).
#[inline]
fn intersect(origin: DVec3, dir: DVec3, v: &[DVec3; 3]) -> Option<f64> {
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
}
