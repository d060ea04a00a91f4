//! Box tests on one node of obvhs' compressed wide BVH (CWBVH) for the segment tests of
//! `visibility/mod.rs`: which children a ray's slab test passes ([`slot_hits`], and
//! [`node_hits`] in the `hitmask` layout `obvhs::traverse!` reads), and which children a box
//! overlaps ([`bundle_slots`], the packet's shared test); [`slot_hits_avx2`], the slab test of
//! the x86-64-v3 code path, eight children at once, on a node's planes widened once for a
//! packet's box and segments (`WidenedNode`, `bundle_slots_widened`, `slot_hits_widened`).
//!
//! Invariant: every test is conservative for the segment test: it never drops a child that
//! holds a counted hit (`node_hits_keeps_every_child_obvhs_keeps`,
//! `bundle_slots_keep_every_child_box_that_overlaps`, the brute-force twins of `mod.rs`).

use glam::Vec3A;
use obvhs::{cwbvh::node::CwBvhNode, ray::Ray};

/// Which children of a CWBVH node the ray's box test passes: obvhs' `intersect_ray_simd` (same
/// arithmetic, same `hitmask` layout for `obvhs::traverse!`) with the child planes tested by
/// [`slot_hits`]. Pinned by `node_hits_keeps_every_child_obvhs_keeps` and the brute-force twins.
/// `V3`: test with [`slot_hits_avx2`].
///
/// # Safety
/// With `V3` true, the CPU must have AVX2.
#[inline(always)]
pub(super) unsafe fn node_hits<const V3: bool>(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let mut hits = 0;
    // SAFETY: the caller's contract.
    let mut m = unsafe { slot_hits_for::<V3>(node, ray) };
    while m != 0 {
        let i = m.trailing_zeros() as u64 * 8;
        hits |= (((child_bits8 >> i) & 0xff) as u32) << ((bit_index8 >> i) & 0xff);
        m &= m - 1;
    }
    hits
}

/// Which of a CWBVH node's eight child boxes the ray's slab test passes: bit `i` for the planes
/// of child `i` (an empty slot's planes may pass: read `child_meta`). obvhs' arithmetic, with the
/// 8-bit planes widened four at a time by SSE2 unpacks instead of one scalar conversion each,
/// and boxes the ray leaves before `ray.tmin` culled (obvhs culls before 1e-4 in scene units
/// whatever the scene's size). The segment test sets `tmin` to half the box padding: a hit
/// counted at `t > end_epsilon` lies in a box padded by `BOX_PADDING_REL * diagonal` on every
/// side, which the ray leaves after `t + padding`; the other half covers f32 rounding
/// (coordinates within 80 diagonals of the origin). The scalar twin
/// [`slot_hits_scalar`] gives the same bits (`node_hits_keeps_every_child_obvhs_keeps`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn slot_hits(node: &CwBvhNode, ray: &Ray) -> u32 {
    use std::arch::x86_64::*;
    let adj_inv = node.compute_extent() * ray.inv_direction;
    let adj_orig = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    // SAFETY: SSE2 is part of the x86_64 baseline; the loads read 8 bytes of [u8; 8] fields.
    unsafe {
        // The eight planes as two vectors of four f32.
        let widen = |q: &[u8; 8]| {
            let bytes = _mm_loadl_epi64(q.as_ptr() as *const __m128i);
            let words = _mm_unpacklo_epi8(bytes, _mm_setzero_si128());
            (
                _mm_cvtepi32_ps(_mm_unpacklo_epi16(words, _mm_setzero_si128())),
                _mm_cvtepi32_ps(_mm_unpackhi_epi16(words, _mm_setzero_si128())),
            )
        };
        let slab = |lo: &[u8; 8], hi: &[u8; 8], neg: bool, scale: f32, offset: f32| {
            let (near, far) = if neg { (hi, lo) } else { (lo, hi) };
            let (n0, n1) = widen(near);
            let (f0, f1) = widen(far);
            let (s, o) = (_mm_set1_ps(scale), _mm_set1_ps(offset));
            (
                _mm_add_ps(_mm_mul_ps(n0, s), o),
                _mm_add_ps(_mm_mul_ps(n1, s), o),
                _mm_add_ps(_mm_mul_ps(f0, s), o),
                _mm_add_ps(_mm_mul_ps(f1, s), o),
            )
        };
        let d = ray.direction;
        let (xn0, xn1, xf0, xf1) = slab(
            &node.child_min_x,
            &node.child_max_x,
            d.x < 0.0,
            adj_inv.x,
            adj_orig.x,
        );
        let (yn0, yn1, yf0, yf1) = slab(
            &node.child_min_y,
            &node.child_max_y,
            d.y < 0.0,
            adj_inv.y,
            adj_orig.y,
        );
        let (zn0, zn1, zf0, zf1) = slab(
            &node.child_min_z,
            &node.child_max_z,
            d.z < 0.0,
            adj_inv.z,
            adj_orig.z,
        );
        let (eps, tmax) = (_mm_set1_ps(ray.tmin), _mm_set1_ps(ray.tmax));
        let near0 = _mm_max_ps(_mm_max_ps(xn0, _mm_max_ps(yn0, zn0)), eps);
        let near1 = _mm_max_ps(_mm_max_ps(xn1, _mm_max_ps(yn1, zn1)), eps);
        let far0 = _mm_min_ps(_mm_min_ps(xf0, _mm_min_ps(yf0, zf0)), tmax);
        let far1 = _mm_min_ps(_mm_min_ps(xf1, _mm_min_ps(yf1, zf1)), tmax);
        (_mm_movemask_ps(_mm_cmple_ps(near0, far0))
            | (_mm_movemask_ps(_mm_cmple_ps(near1, far1)) << 4)) as u32
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
pub(super) fn slot_hits(node: &CwBvhNode, ray: &Ray) -> u32 {
    slot_hits_scalar(node, ray)
}

/// [`slot_hits_avx2`] when `V3`, else [`slot_hits`].
///
/// # Safety
/// With `V3` true, the CPU must have AVX2.
#[inline(always)]
pub(super) unsafe fn slot_hits_for<const V3: bool>(node: &CwBvhNode, ray: &Ray) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if V3 {
        // SAFETY: the caller's contract.
        return unsafe { slot_hits_avx2(node, ray) };
    }
    slot_hits(node, ray)
}

/// A CWBVH node's eight child boxes widened once from their 8-bit planes to f32, in the node's
/// quantized frame, for the box test of a packet and the slab tests of its rays
/// ([`bundle_slots_widened`], [`slot_hits_widened`]): a packet reads a node once and tests its
/// box and each of its segments against the same planes (pinned by
/// `bundle_slots_keep_every_child_box_that_overlaps` and
/// `node_hits_keeps_every_child_obvhs_keeps`).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct WidenedNode {
    /// `child_min` and `child_max` per axis (x, y, z), eight children to a vector.
    lo: [std::arch::x86_64::__m256; 3],
    hi: [std::arch::x86_64::__m256; 3],
    extent: Vec3A,
    origin: Vec3A,
    /// Bit `i` set when child `i` is not empty (`child_meta` not 0).
    nonempty: u32,
}

#[cfg(target_arch = "x86_64")]
impl WidenedNode {
    /// The planes of `node`, widened exactly (every `u8` is an `f32`).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn new(node: &CwBvhNode) -> Self {
        use std::arch::x86_64::*;
        let widen = |q: &[u8; 8]| {
            // SAFETY: AVX2 is enabled here; the load reads the 8 bytes of a [u8; 8].
            unsafe {
                _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(
                    q.as_ptr() as *const __m128i
                )))
            }
        };
        WidenedNode {
            lo: [
                widen(&node.child_min_x),
                widen(&node.child_min_y),
                widen(&node.child_min_z),
            ],
            hi: [
                widen(&node.child_max_x),
                widen(&node.child_max_y),
                widen(&node.child_max_z),
            ],
            extent: node.compute_extent(),
            origin: Vec3A::from(node.p),
            // SAFETY: as above; the load reads the 8 bytes of `child_meta`.
            nonempty: unsafe {
                let meta = _mm_loadl_epi64(node.child_meta.as_ptr() as *const __m128i);
                !(_mm_movemask_epi8(_mm_cmpeq_epi8(meta, _mm_setzero_si128())) as u32) & 0xff
            },
        }
    }
}

/// [`bundle_slots`] on a node's widened planes: the same comparisons of the same values, eight
/// children at once, so the same bits (`bundle_slots_keep_every_child_box_that_overlaps`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn bundle_slots_widened(node: &WidenedNode, lo: Vec3A, hi: Vec3A) -> u32 {
    use std::arch::x86_64::*;
    let inv = node.extent.recip();
    let (lo, hi) = ((lo - node.origin) * inv, (hi - node.origin) * inv);
    let mut overlaps = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    for axis in 0..3 {
        let below = _mm256_cmp_ps::<_CMP_LE_OQ>(node.lo[axis], _mm256_set1_ps(hi[axis]));
        let above = _mm256_cmp_ps::<_CMP_GE_OQ>(node.hi[axis], _mm256_set1_ps(lo[axis]));
        overlaps = _mm256_and_ps(overlaps, _mm256_and_ps(below, above));
    }
    _mm256_movemask_ps(overlaps) as u32 & node.nonempty
}

/// [`slot_hits`] with the eight children in one AVX2 vector: the same operations in the same
/// order lane by lane (no FMA), so the same bits (`node_hits_keeps_every_child_obvhs_keeps`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn slot_hits_avx2(node: &CwBvhNode, ray: &Ray) -> u32 {
    slot_hits_widened(&WidenedNode::new(node), ray)
}

/// [`slot_hits_avx2`] on planes widened beforehand (it is this on its own node's planes: one body
/// for both, pinned by `node_hits_keeps_every_child_obvhs_keeps`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn slot_hits_widened(node: &WidenedNode, ray: &Ray) -> u32 {
    use std::arch::x86_64::*;
    let adj_inv = node.extent * ray.inv_direction;
    let adj_orig = (node.origin - ray.origin) * ray.inv_direction;
    // The planes of one axis, nearest first along the ray, as `plane * scale + offset`.
    let slab = |axis: usize| {
        let (lo, hi) = (node.lo[axis], node.hi[axis]);
        let (near, far) = if ray.direction[axis] < 0.0 {
            (hi, lo)
        } else {
            (lo, hi)
        };
        let (s, o) = (
            _mm256_set1_ps(adj_inv[axis]),
            _mm256_set1_ps(adj_orig[axis]),
        );
        (
            _mm256_add_ps(_mm256_mul_ps(near, s), o),
            _mm256_add_ps(_mm256_mul_ps(far, s), o),
        )
    };
    let (xn, xf) = slab(0);
    let (yn, yf) = slab(1);
    let (zn, zf) = slab(2);
    let (eps, tmax) = (_mm256_set1_ps(ray.tmin), _mm256_set1_ps(ray.tmax));
    let near = _mm256_max_ps(_mm256_max_ps(xn, _mm256_max_ps(yn, zn)), eps);
    let far = _mm256_min_ps(_mm256_min_ps(xf, _mm256_min_ps(yf, zf)), tmax);
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32
}

/// [`slot_hits`] one child and one axis at a time.
#[cfg(any(test, not(target_arch = "x86_64")))]
fn slot_hits_scalar(node: &CwBvhNode, ray: &Ray) -> u32 {
    let adj_inv = node.compute_extent() * ray.inv_direction;
    let adj_orig = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    let planes = [
        (&node.child_min_x, &node.child_max_x),
        (&node.child_min_y, &node.child_max_y),
        (&node.child_min_z, &node.child_max_z),
    ];
    let mut mask = 0;
    for i in 0..8 {
        let (mut near, mut far) = (ray.tmin, ray.tmax);
        for (axis, (lo, hi)) in planes.iter().enumerate() {
            let (a, b) = if ray.direction[axis] < 0.0 {
                (hi[i], lo[i])
            } else {
                (lo[i], hi[i])
            };
            near = near.max(a as f32 * adj_inv[axis] + adj_orig[axis]);
            far = far.min(b as f32 * adj_inv[axis] + adj_orig[axis]);
        }
        mask |= u32::from(near <= far) << i;
    }
    mask
}

/// Which of a CWBVH node's non-empty child boxes overlap the box `lo`-`hi` (bit `i` for child
/// `i`): the packet's shared test, before any ray's ([`Visibility::visible_from`](super::Visibility::visible_from)). Exact up to
/// f32 rounding of the box into the node's quantized frame (the extent is a power of two), which
/// the caller's padding covers.
#[inline(always)]
pub(super) fn bundle_slots(node: &CwBvhNode, lo: Vec3A, hi: Vec3A) -> u32 {
    let origin = Vec3A::from(node.p);
    let inv = node.compute_extent().recip();
    let (lo, hi) = ((lo - origin) * inv, (hi - origin) * inv);
    let mut mask = 0;
    for i in 0..8 {
        let overlaps = node.child_meta[i] != 0
            && f32::from(node.child_min_x[i]) <= hi.x
            && f32::from(node.child_max_x[i]) >= lo.x
            && f32::from(node.child_min_y[i]) <= hi.y
            && f32::from(node.child_max_y[i]) >= lo.y
            && f32::from(node.child_min_z[i]) <= hi.z
            && f32::from(node.child_max_z[i]) >= lo.z;
        mask |= u32::from(overlaps) << i;
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::super::tests::{furnished_room, xorshift};
    use super::*;

    /// Uniform f32 numbers in [0, 1) (`xorshift` seeded with `seed`).
    fn f32s(seed: u64) -> impl FnMut() -> f32 {
        let mut next = xorshift(seed);
        move || next() as f32
    }

    /// A random point in the box of [`furnished_room`] widened by 0.2 on every side.
    fn point_around_room(rnd: &mut impl FnMut() -> f32) -> Vec3A {
        Vec3A::new(rnd() * 2.4 - 0.2, rnd() * 1.4 - 0.2, rnd() * 1.9 - 0.2)
    }

    /// [`node_hits`] passes every child obvhs' own node test passes (the segment test's near
    /// limit, half the box padding, being under obvhs' 1e-4 in this room), on every node of a BVH
    /// for rays from random points in random directions, axis-aligned ones included; and
    /// [`slot_hits`] (SSE2 on x86_64) gives the bits of its scalar twin, as do
    /// [`slot_hits_avx2`] and `node_hits::<true>` that of `node_hits::<false>` (on a CPU with
    /// AVX2).
    #[test]
    fn node_hits_keeps_every_child_obvhs_keeps() {
        let v = furnished_room();
        let bvh = v.bvh.as_ref().expect("a BVH");
        let mut rnd = f32s(0xb0c5);
        let mut passed = 0usize;
        for k in 0..2000 {
            let origin = point_around_room(&mut rnd);
            let mut dir = Vec3A::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
            if k % 4 == 0 {
                dir[k / 4 % 3] = 0.0;
            }
            let dir = dir.normalize();
            let ray = Ray::new(origin, dir, 0.5 * v.box_padding, rnd() * 3.0);
            let oct = bvh.new_traversal(dir).oct_inv4;
            for node in &bvh.nodes {
                // SAFETY: with `V3` false, baseline code only.
                let ours = unsafe { node_hits::<false>(node, &ray, oct) };
                let theirs = node.intersect_ray(&ray, oct);
                assert_eq!(theirs & !ours, 0, "{node:?} {ray:?}");
                assert_eq!(slot_hits(node, &ray), slot_hits_scalar(node, &ray));
                #[cfg(target_arch = "x86_64")]
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2.
                    let wide = unsafe { slot_hits_avx2(node, &ray) };
                    assert_eq!(wide, slot_hits_scalar(node, &ray));
                    // SAFETY: the CPU has AVX2.
                    assert_eq!(unsafe { node_hits_avx2(node, &ray, oct) }, ours);
                }
                passed += theirs.count_ones() as usize;
            }
        }
        assert!(passed > 0);
    }

    /// `node_hits::<true>` compiled with AVX2, as in the x86-64-v3 code path.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn node_hits_avx2(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
        // SAFETY: this function runs only where AVX2 is enabled.
        unsafe { node_hits::<true>(node, ray, oct_inv4) }
    }

    /// [`bundle_slots_widened`] on the node's own planes, compiled with AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn bundle_slots_avx2(node: &CwBvhNode, lo: Vec3A, hi: Vec3A) -> u32 {
        bundle_slots_widened(&WidenedNode::new(node), lo, hi)
    }

    /// [`bundle_slots`] keeps every non-empty child whose box (obvhs' `child_aabb`) overlaps the
    /// given box, and only those up to rounding, for random boxes in the room; and
    /// [`bundle_slots_widened`] gives its bits (on a CPU with AVX2).
    #[test]
    fn bundle_slots_keep_every_child_box_that_overlaps() {
        let v = furnished_room();
        let bvh = v.bvh.as_ref().expect("a BVH");
        let mut rnd = f32s(0xb0_7e);
        let (mut kept, mut dropped) = (0, 0);
        for _ in 0..2000 {
            let a = point_around_room(&mut rnd);
            let b = a + Vec3A::new(rnd(), rnd(), rnd()) * 0.3;
            for node in &bvh.nodes {
                let slots = bundle_slots(node, a, b);
                #[cfg(target_arch = "x86_64")]
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2.
                    let wide = unsafe { bundle_slots_avx2(node, a, b) };
                    assert_eq!(wide, slots, "{node:?} {a} {b}");
                }
                for i in 0..8 {
                    if node.is_child_empty(i) {
                        assert_eq!(slots >> i & 1, 0);
                        continue;
                    }
                    let c = node.child_aabb(i);
                    let overlaps = c.min.cmple(b + 1e-6).all() && c.max.cmpge(a - 1e-6).all();
                    let clear = c.min.cmpgt(b + 1e-4).any() || c.max.cmplt(a - 1e-4).any();
                    if overlaps {
                        assert_eq!(slots >> i & 1, 1, "{node:?} {a} {b}");
                        kept += 1;
                    } else if clear {
                        assert_eq!(slots >> i & 1, 0, "{node:?} {a} {b}");
                        dropped += 1;
                    }
                }
            }
        }
        assert!(kept > 100 && dropped > 100, "{kept} {dropped}");
    }
}
