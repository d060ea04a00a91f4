//! Visibility: a BVH (obvhs' compressed wide BVH) over the scene's occluding triangles and an
//! open-segment occlusion test.
//!
//! Conventions (docs/design.md section 6): every triangle occludes, whatever its sides or emission; the
//! faces a link joins never occlude it (they are passed as `ignore`); hits within
//! `end_epsilon = ENDPOINT_EPSILON_REL * scene diagonal` of either end of a segment do not count.
//! Boxes are padded by `BOX_PADDING_REL * diagonal` (unpadded boxes on axis-aligned walls are slow
//! and f32 rounding could miss grazing hits). Intersection is done in `f64`.
//!
//! Layout for speed (the shadow rays are most of a solve): the BVH is built with obvhs' slowest,
//! best preset; the occluders are stored in the BVH's leaf order, as first vertex, edges and face
//! (`Tri`), so a leaf's primitive index is the record's index; the traversal is obvhs'
//! `traverse!` with our own node test (`node_test.rs`: SSE2, same arithmetic as obvhs', but boxes
//! culled behind half the box padding instead of 1e-4). A packet's segments share their start:
//! a leaf's triangle computes what Möller-Trumbore reads of the start and the triangle once for
//! all of them (`TriangleFrom`); the single segment's test is the same body, so a packet and
//! its single segments agree bit for bit (`packet_verdicts_are_the_single_rays`).
//!
//! Two code paths, one source: the segment tests (`visible_uncounted`, `visible_from`) are
//! compiled for the baseline and, on x86_64, for x86-64-v3 (AVX2, FMA, BMI, LZCNT, POPCNT: the
//! traversal's bit counts become single instructions, the node test takes eight children in one
//! AVX2 vector), chosen once per `Visibility` from the CPU's features. No FMA is written and Rust
//! contracts none, so both give the same verdicts bit for bit
//! (`both_code_paths_give_the_same_verdicts`); `code_path` names the one that runs.
//!
//! Shadow cache: each thread remembers the occluder that last blocked one of its segments
//! (`LAST_BLOCKER`) and tests it before traversing (a solve traces a receiver point against many
//! points of one source, so what blocked the last ray mostly blocks the next). The cache only
//! decides which triangle is tested first: a segment is blocked when some triangle blocks it
//! under the same test, so the verdict is the traversal's (pinned by the brute-force twins, which
//! run with whatever the cache holds, including an index left by another `Visibility`).

mod bounding_planes;
mod node_test;

pub use bounding_planes::bounding_planes;

use super::striped_count::StripedCount;
use glam::{DVec3, UVec2, Vec3A};
use node_test::{bundle_slots, node_hits, slot_hits};
#[cfg(target_arch = "x86_64")]
use node_test::{bundle_slots_widened, slot_hits_widened, WidenedNode};
use obvhs::{aabb::Aabb, cwbvh::CwBvh, ray::Ray, Boundable, BvhBuildParams};
use std::cell::Cell;

/// Hits closer than this fraction of the scene diagonal to a segment end are ignored.
pub const ENDPOINT_EPSILON_REL: f64 = 1e-6;
/// BVH boxes are padded by this fraction of the scene diagonal.
pub const BOX_PADDING_REL: f64 = 1e-5;

/// One occluding triangle, tagged with the face it belongs to: the BVH builder's input.
#[derive(Debug, Clone, Copy)]
struct Occluder {
    vertices: [DVec3; 3],
    face: u32,
    aabb: Aabb,
}

/// An occluder as the segment test reads it: first vertex, edges (`v1 - v0`, `v2 - v0`) and face,
/// stored in the BVH's leaf order (the traversal's primitive index is its index: no indirection).
#[derive(Debug, Clone, Copy)]
struct Tri {
    v0: DVec3,
    e1: DVec3,
    e2: DVec3,
    face: u32,
}

impl Tri {
    /// True for a triangle of a face the link joins: it never occludes the link.
    #[inline(always)]
    fn ignored(&self, ignore: [u32; 2]) -> bool {
        self.face == ignore[0] || self.face == ignore[1]
    }

    /// The segments among `candidates` (bits; `seg` gives each, all starting at `p`) that this
    /// triangle blocks: what the test reads of the shared start computed once for all of them
    /// (`TriangleFrom`), each verdict [`Segment::blocked_by`]'s bit for bit.
    #[inline(always)]
    fn blocks_from<'s>(
        &self,
        p: DVec3,
        ignore: [u32; 2],
        candidates: u64,
        seg: &impl Fn(u32) -> &'s Segment,
    ) -> u64 {
        if candidates == 0 || self.ignored(ignore) {
            return 0;
        }
        let from = TriangleFrom::new(p, self.v0, self.e1, self.e2);
        let mut blocked = 0;
        for i in bits(candidates) {
            let s = seg(i);
            debug_assert_eq!(s.p, p, "a packet's segments share their start");
            if s.reaches(from.hit(s.dir)) {
                blocked |= 1 << i;
            }
        }
        blocked
    }
}

impl Boundable for Occluder {
    fn aabb(&self) -> Aabb {
        self.aabb
    }
}

/// The scene's occluders and their BVH.
pub struct Visibility {
    /// In BVH leaf order (`bvh.primitive_indices` applied).
    tris: Vec<Tri>,
    bvh: Option<CwBvh>,
    end_epsilon: f64,
    /// `BOX_PADDING_REL * diagonal`, the nearest exit of a box the node test keeps.
    box_padding: f32,
    rays: StripedCount,
    /// The CPU has x86-64-v3's features (AVX2, FMA, BMI, LZCNT, POPCNT): the segment tests run
    /// compiled for them (see the module header). Invariant: true only when
    /// `cpu_has_x86_64_v3()` is (the x86-64-v3 path runs AVX2 code).
    x86_64_v3: bool,
}

impl std::fmt::Debug for Visibility {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Visibility")
            .field("occluders", &self.tris.len())
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
                BvhBuildParams::very_slow_build(),
                &mut std::time::Duration::default(),
            ))
        };
        let tris = match &bvh {
            Some(bvh) => bvh
                .primitive_indices
                .iter()
                .map(|&i| {
                    let o = &occluders[i as usize];
                    let [v0, v1, v2] = o.vertices;
                    Tri {
                        v0,
                        e1: v1 - v0,
                        e2: v2 - v0,
                        face: o.face,
                    }
                })
                .collect(),
            None => Vec::new(),
        };
        Visibility {
            tris,
            bvh,
            end_epsilon: ENDPOINT_EPSILON_REL * diagonal,
            box_padding: pad,
            rays: StripedCount::new(),
            x86_64_v3: cpu_has_x86_64_v3(),
        }
    }

    /// Number of occluding triangles in the BVH.
    pub fn occluder_count(&self) -> usize {
        self.tris.len()
    }

    /// The distance from either end of a segment within which hits do not count.
    pub fn end_epsilon(&self) -> f64 {
        self.end_epsilon
    }

    /// The instruction set the segment tests are compiled for on this CPU: `"x86-64-v3"` or
    /// `"baseline"`.
    pub fn code_path(&self) -> &'static str {
        if self.x86_64_v3 {
            "x86-64-v3"
        } else {
            "baseline"
        }
    }

    /// Number of segment tests done so far.
    pub fn rays_traced(&self) -> u64 {
        self.rays.get()
    }

    /// True when nothing but the faces in `ignore` blocks the open segment `p`-`q`; counted in
    /// [`Visibility::rays_traced`].
    pub fn visible(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        self.count_rays(1);
        self.visible_uncounted(p, q, ignore)
    }

    /// Adds `n` segment tests done with [`Visibility::visible_uncounted`] or
    /// [`Visibility::visible_from`] to the count.
    pub(crate) fn count_rays(&self, n: u64) {
        if n > 0 {
            self.rays.add(n);
        }
    }

    /// [`Visibility::visible`] without counting, for a loop that traces many rays and counts
    /// them once with [`Visibility::count_rays`]: one shared counter bumped per ray is a cache
    /// line every core writes (a tenth of a solve's time on two cores, found by profiling).
    pub(crate) fn visible_uncounted(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.x86_64_v3 {
            // SAFETY: `x86_64_v3` is set only when the CPU has every feature the function enables.
            return unsafe { self.visible_uncounted_v3(p, q, ignore) };
        }
        // SAFETY: with `V3` false the body runs baseline code only.
        unsafe { self.visible_uncounted_any::<false>(p, q, ignore) }
    }

    /// [`Visibility::visible_uncounted`] compiled for x86-64-v3.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn visible_uncounted_v3(&self, p: DVec3, q: DVec3, ignore: [u32; 2]) -> bool {
        // SAFETY: this function runs only where its features, AVX2 among them, are enabled.
        unsafe { self.visible_uncounted_any::<true>(p, q, ignore) }
    }

    /// [`Visibility::visible_uncounted`] for whatever instruction set its caller is compiled for;
    /// `V3`: the node test takes AVX2.
    ///
    /// # Safety
    /// With `V3` true, the CPU must have AVX2.
    #[inline(always)]
    unsafe fn visible_uncounted_any<const V3: bool>(
        &self,
        p: DVec3,
        q: DVec3,
        ignore: [u32; 2],
    ) -> bool {
        let Some(bvh) = &self.bvh else { return true };
        let Some(seg) = self.segment(p, q) else {
            return true;
        };
        // Any index is safe: a triangle of this structure that blocks the segment is a verdict.
        let last = LAST_BLOCKER.with(Cell::get);
        if self
            .tris
            .get(last as usize)
            .is_some_and(|t| seg.blocked_by(t, ignore))
        {
            return false;
        }
        let ray = &seg.ray;
        let mut state = bvh.new_traversal(ray.direction);
        let mut node;
        let mut visible = true;
        'traversal: {
            obvhs::traverse!(
                bvh,
                node,
                state,
                // SAFETY: `V3` true only where AVX2 is there (this function's contract).
                unsafe { node_hits::<V3>(node, ray, state.oct_inv4) },
                {
                    if seg.blocked_by(&self.tris[state.primitive_id as usize], ignore) {
                        visible = false;
                        LAST_BLOCKER.with(|c| c.set(state.primitive_id));
                        break 'traversal;
                    }
                }
            );
        }
        visible
    }

    /// Which of the open segments from `p` to each of `targets` (at most 64) nothing but the
    /// faces in `ignore` blocks: bit `i` of the result set when the segment to `targets[i]` is
    /// visible. The verdicts of [`Visibility::visible_uncounted`], segment by segment
    /// (`packet_verdicts_are_the_single_rays`), found in one traversal of the BVH: a node is
    /// read once for the whole packet, its children are first tested against the box of every
    /// segment still unblocked ([`bundle_slots`]), then against each such segment's ray
    /// ([`slot_hits`]; on x86-64-v3 both on the node's planes widened once, `WidenedNode`); a
    /// segment leaves the packet at its first blocker. Not counted.
    pub(crate) fn visible_from(&self, p: DVec3, targets: &[DVec3], ignore: [u32; 2]) -> u64 {
        #[cfg(target_arch = "x86_64")]
        if self.x86_64_v3 {
            // SAFETY: `x86_64_v3` is set only when the CPU has every feature the function enables.
            return unsafe { self.visible_from_v3(p, targets, ignore) };
        }
        // SAFETY: with `V3` false the body runs baseline code only.
        unsafe { self.visible_from_any::<false>(p, targets, ignore) }
    }

    /// [`Visibility::visible_from`] compiled for x86-64-v3.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn visible_from_v3(&self, p: DVec3, targets: &[DVec3], ignore: [u32; 2]) -> u64 {
        // SAFETY: this function runs only where its features, AVX2 among them, are enabled.
        unsafe { self.visible_from_any::<true>(p, targets, ignore) }
    }

    /// [`Visibility::visible_from`] for whatever instruction set its caller is compiled for;
    /// `V3`: the node test takes AVX2.
    ///
    /// # Safety
    /// With `V3` true, the CPU must have AVX2.
    #[inline(always)]
    unsafe fn visible_from_any<const V3: bool>(
        &self,
        p: DVec3,
        targets: &[DVec3],
        ignore: [u32; 2],
    ) -> u64 {
        debug_assert!(targets.len() <= 64, "{} targets", targets.len());
        let all = if targets.len() >= 64 {
            u64::MAX
        } else {
            (1u64 << targets.len()) - 1
        };
        let Some(bvh) = &self.bvh else { return all };
        // The packet's segments, in a buffer kept between calls: an array of 64 on the stack is
        // zeroed at every call (`docs/performance-notes.md`, the profile of 2026-12-04).
        let mut segs = PACKET_SEGMENTS.take();
        segs.clear();
        // A plain loop: an iterator's `fold` is compiled apart, without the caller's features.
        for &q in targets.iter().take(64) {
            segs.push(self.segment(p, q));
        }
        let mut open = 0u64;
        for (i, s) in segs.iter().enumerate() {
            open |= u64::from(s.is_some()) << i;
        }
        let traced = open;
        let seg = |i: u32| segs[i as usize].as_ref().expect("an open segment");
        // The shadow cache, for the whole packet.
        let last = LAST_BLOCKER.with(Cell::get);
        if let Some(tri) = self.tris.get(last as usize) {
            open &= !tri.blocks_from(p, ignore, open, &seg);
        }
        let origin = p.as_vec3a();
        let mut stack = PACKET_STACK.take();
        stack.clear();
        stack.push((0u32, open));
        while let Some((index, mask)) = stack.pop() {
            let mask = mask & open;
            if mask == 0 {
                continue;
            }
            let node = &bvh.nodes[index as usize];
            // The box of the segments still open, padded for f32 rounding.
            let (mut lo, mut hi) = (origin, origin);
            for i in bits(mask) {
                let end = seg(i).end;
                (lo, hi) = (lo.min(end), hi.max(end));
            }
            let pad = Vec3A::splat(self.box_padding);
            let (lo, hi) = (lo - pad, hi + pad);
            // The node's planes widened once for the packet's box and segments (x86-64-v3).
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `V3` true only where AVX2 is there (this function's contract).
            let widened = if V3 {
                Some(unsafe { WidenedNode::new(node) })
            } else {
                None
            };
            #[cfg(target_arch = "x86_64")]
            let shared = match &widened {
                // SAFETY: as above.
                Some(w) => unsafe { bundle_slots_widened(w, lo, hi) },
                None => bundle_slots(node, lo, hi),
            };
            #[cfg(not(target_arch = "x86_64"))]
            let shared = bundle_slots(node, lo, hi);
            if shared == 0 {
                continue;
            }
            // Each segment's slot bits, eight segments to a word (a byte each), turned into
            // each slot's segments a word at a time.
            let mut child_rays = SlotSegments::default();
            for i in bits(mask) {
                let ray = &seg(i).ray;
                #[cfg(target_arch = "x86_64")]
                let hits = match &widened {
                    // SAFETY: as above.
                    Some(w) => unsafe { slot_hits_widened(w, ray) },
                    None => slot_hits(node, ray),
                };
                #[cfg(not(target_arch = "x86_64"))]
                let hits = slot_hits(node, ray);
                child_rays.add(i, hits & shared);
            }
            let child_rays = child_rays.finish();
            for (slot, &rays) in child_rays.iter().enumerate() {
                if rays == 0 {
                    continue;
                }
                if !node.is_leaf(slot) {
                    stack.push((node.child_node_index(slot), rays));
                    continue;
                }
                let (first, count) = node.child_primitives(slot);
                for prim in first..first + count {
                    let blocked =
                        self.tris[prim as usize].blocks_from(p, ignore, rays & open, &seg);
                    if blocked != 0 {
                        open &= !blocked;
                        LAST_BLOCKER.with(|c| c.set(prim));
                    }
                }
            }
            if open == 0 {
                break;
            }
        }
        PACKET_STACK.set(stack);
        PACKET_SEGMENTS.set(segs);
        // Visible: the segments too short to block, and those traced that stayed open.
        all & !(traced & !open)
    }

    /// The open segment `p`-`q` as the tests read it; `None` when it is within twice the end
    /// epsilon (nothing can block it).
    #[inline(always)]
    fn segment(&self, p: DVec3, q: DVec3) -> Option<Segment> {
        let d = q - p;
        let len = d.length();
        if len <= 2.0 * self.end_epsilon {
            return None;
        }
        let dir = d / len;
        let tmax = len - self.end_epsilon;
        // A box the ray leaves before half the padding cannot hold a counted hit (`node_hits`).
        let ray = Ray::new(
            p.as_vec3a(),
            dir.as_vec3a(),
            0.5 * self.box_padding,
            tmax as f32 * (1.0 + 1e-6) + 1e-30,
        );
        Some(Segment {
            p,
            dir,
            tmin: self.end_epsilon,
            tmax,
            ray,
            end: q.as_vec3a(),
        })
    }
}

/// An open segment as the tests read it: its start, unit direction and the range of ray
/// parameters where a hit counts (f64), its f32 ray for the box tests and its end.
struct Segment {
    p: DVec3,
    dir: DVec3,
    tmin: f64,
    tmax: f64,
    ray: Ray,
    end: Vec3A,
}

impl Segment {
    /// True when `tri` counts as a blocker: not of an ignored face, hit strictly within range.
    #[inline(always)]
    fn blocked_by(&self, tri: &Tri, ignore: [u32; 2]) -> bool {
        !tri.ignored(ignore)
            && self.reaches(intersect_edges(self.p, self.dir, tri.v0, tri.e1, tri.e2))
    }

    /// True when a hit at ray parameter `t` counts: strictly within the segment's range.
    #[inline(always)]
    fn reaches(&self, t: Option<f64>) -> bool {
        t.is_some_and(|t| t > self.tmin && t < self.tmax)
    }
}

/// True when the CPU has the features of the x86-64-v3 code path (always false elsewhere).
fn cpu_has_x86_64_v3() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
            && std::arch::is_x86_feature_detected!("popcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The segments of a packet that reach each of a node's eight slots, gathered from each
/// segment's slot bits: segment `i`'s bits go to byte `i % 8` of a word, and each word of eight
/// segments is transposed as an 8 x 8 bit matrix into the slots' masks at once (no store per
/// segment and slot). Segments are added in increasing order (`bits`). Pinned against a store
/// per segment and slot by `transposed_bits_are_the_brute_force_ones`.
#[derive(Default)]
struct SlotSegments {
    slots: [u64; 8],
    /// The eight segments `8 * group ..` being gathered, a byte each.
    word: u64,
    group: u32,
}

impl SlotSegments {
    #[inline(always)]
    fn add(&mut self, segment: u32, slots: u32) {
        debug_assert!(segment / 8 >= self.group && slots < 256);
        if segment / 8 != self.group {
            self.flush();
            self.group = segment / 8;
        }
        self.word |= u64::from(slots) << (8 * (segment % 8));
    }

    #[inline(always)]
    fn flush(&mut self) {
        if self.word == 0 {
            return;
        }
        let t = transpose_bits8(self.word);
        for (s, slot) in self.slots.iter_mut().enumerate() {
            *slot |= ((t >> (8 * s)) & 0xff) << (8 * self.group);
        }
        self.word = 0;
    }

    /// Each slot's segments: bit `i` of `slots[s]` set when segment `i` reaches slot `s`.
    #[inline(always)]
    fn finish(mut self) -> [u64; 8] {
        self.flush();
        self.slots
    }
}

/// The 8 x 8 bit matrix `x` (row `r` in byte `r`, column `c` in bit `c` of it) transposed: bit `c`
/// of byte `r` becomes bit `r` of byte `c` (Hacker's Delight, `transpose8`, in three swaps of
/// blocks; `transposed_bits_are_the_brute_force_ones`).
#[inline(always)]
fn transpose_bits8(mut x: u64) -> u64 {
    x = (x & 0xAA55_AA55_AA55_AA55)
        | ((x & 0x00AA_00AA_00AA_00AA) << 7)
        | ((x >> 7) & 0x00AA_00AA_00AA_00AA);
    x = (x & 0xCCCC_3333_CCCC_3333)
        | ((x & 0x0000_CCCC_0000_CCCC) << 14)
        | ((x >> 14) & 0x0000_CCCC_0000_CCCC);
    (x & 0xF0F0_F0F0_0F0F_0F0F)
        | ((x & 0x0000_0000_F0F0_F0F0) << 28)
        | ((x >> 28) & 0x0000_0000_F0F0_F0F0)
}

/// The indices of the bits set in `mask`, lowest first.
fn bits(mut mask: u64) -> impl Iterator<Item = u32> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = mask.trailing_zeros();
            mask &= mask - 1;
            i
        })
    })
}

thread_local! {
    /// The stack of [`Visibility::visible_from`] (node, segments that reach it), kept between
    /// calls so that a packet allocates nothing.
    static PACKET_STACK: Cell<Vec<(u32, u64)>> = const { Cell::new(Vec::new()) };
    /// The segments of [`Visibility::visible_from`]'s packet (`None`: too short to block).
    static PACKET_SEGMENTS: Cell<Vec<Option<Segment>>> = const { Cell::new(Vec::new()) };
    /// Index in `Visibility::tris` of the occluder that last blocked a segment on this thread,
    /// tested first by the next segment (`u32::MAX`: none yet). Shared by every `Visibility` the
    /// thread uses: an index from another one only costs a wasted test.
    static LAST_BLOCKER: Cell<u32> = const { Cell::new(u32::MAX) };
}

/// Möller-Trumbore in f64; returns the ray parameter of the hit (edges inclusive).
#[inline]
pub(crate) fn intersect(origin: DVec3, dir: DVec3, v: &[DVec3; 3]) -> Option<f64> {
    intersect_edges(origin, dir, v[0], v[1] - v[0], v[2] - v[0])
}

/// [`intersect`] of the triangle with first vertex `v0` and edges `e1 = v1 - v0`, `e2 = v2 - v0`
/// (the same operations in the same order: the same verdicts, bit for bit).
#[inline(always)]
fn intersect_edges(origin: DVec3, dir: DVec3, v0: DVec3, e1: DVec3, e2: DVec3) -> Option<f64> {
    TriangleFrom::new(origin, v0, e1, e2).hit(dir)
}

/// A triangle as Möller-Trumbore reads it from one ray origin: its edges and the terms that
/// depend on the origin and the triangle alone (`s = origin - v0`, `q = s x e1`, `e2 . q`). A
/// packet's rays share their origin, so a leaf's triangle computes them once for all its
/// segments. [`intersect_edges`] is [`TriangleFrom::new`] followed by [`TriangleFrom::hit`]:
/// one body, the same operations in the same order for a packet and a single ray, so the same
/// verdicts bit for bit (`packet_verdicts_are_the_single_rays`).
struct TriangleFrom {
    e1: DVec3,
    e2: DVec3,
    s: DVec3,
    q: DVec3,
    /// `e2 . q`: the ray parameter of the hit times the determinant.
    t_det: f64,
}

impl TriangleFrom {
    #[inline(always)]
    fn new(origin: DVec3, v0: DVec3, e1: DVec3, e2: DVec3) -> Self {
        let s = origin - v0;
        let q = s.cross(e1);
        TriangleFrom {
            e1,
            e2,
            s,
            q,
            t_det: e2.dot(q),
        }
    }

    /// The ray parameter where the ray from the origin along `dir` meets the triangle (edges
    /// inclusive), if it does.
    #[inline(always)]
    fn hit(&self, dir: DVec3) -> Option<f64> {
        let (e1, e2) = (self.e1, self.e2);
        let p = dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-300 {
            return None;
        }
        let inv = 1.0 / det;
        let a = self.s.dot(p) * inv;
        if !(-1e-12..=1.0 + 1e-12).contains(&a) {
            return None;
        }
        let b = dir.dot(self.q) * inv;
        if b < -1e-12 || a + b > 1.0 + 1e-12 {
            return None;
        }
        Some(self.t_det * inv)
    }
}

#[cfg(test)]
mod tests;
