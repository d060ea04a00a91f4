//! Tests of `Visibility`: brute-force twins of the traversal, the packet and the shadow cache,
//! the two code paths, bounding faces left out; the rooms they trace through.

use super::*;

/// Uniform numbers in [0, 1) from a xorshift generator seeded with `state` (not 0).
pub(super) fn xorshift(mut state: u64) -> impl FnMut() -> f64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

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
    let mut rnd = crate::shuffle::uniform_sequence(12345);
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

/// The traversal (with [`node_hits`]) gives the verdict of a brute-force test of every
/// triangle, for segments between random points of a furnished room.
#[test]
fn traversal_matches_brute_force_in_a_room() {
    let (tris, _) = room_with_block(DVec3::new(0.7, 0.1, 0.4), DVec3::new(0.5, 0.6, 0.3));
    let diagonal = 3.0;
    let v = Visibility::new(tris.clone(), diagonal);
    let eps = v.end_epsilon();
    let mut rnd = xorshift(0x0dd_ba11);
    let mut blocked = [0usize; 2];
    for i in 0..20_000 {
        let mut point = || DVec3::new(rnd() * 2.0, rnd(), rnd() * 1.5);
        let (p, q) = (point(), point());
        // Every third segment starts on the block's bottom face.
        let p = if i % 3 == 0 {
            DVec3::new(p.x, p.y, 0.4)
        } else {
            p
        };
        let len = (q - p).length();
        let dir = (q - p) / len;
        let brute = len > 2.0 * eps
            && tris
                .iter()
                .any(|(t, _)| intersect(p, dir, t).is_some_and(|h| h > eps && h < len - eps));
        assert_eq!(!v.visible(p, q, [u32::MAX; 2]), brute, "{p} -> {q}");
        blocked[brute as usize] += 1;
    }
    assert!(blocked[0] > 1000 && blocked[1] > 1000, "{blocked:?}");
}

/// Whatever occluder the shadow cache holds (each of the structure's, one past them, none),
/// the verdict is the brute force's, ignored faces included: segments from the block's
/// bottom face (ignored) to random points of the room.
#[test]
fn shadow_cache_changes_no_verdict() {
    let (tris, _) = room_with_block(DVec3::new(0.7, 0.1, 0.4), DVec3::new(0.5, 0.6, 0.3));
    let v = Visibility::new(tris.clone(), 3.0);
    let eps = v.end_epsilon();
    let bottom = 6 + 4; // `sides` order: the block's side at `lo` along x and y
    let mut rnd = xorshift(0x5eed);
    let mut blocked = [0usize; 2];
    for _ in 0..300 {
        let p = DVec3::new(0.7 + rnd() * 0.5, 0.1 + rnd() * 0.6, 0.4);
        let q = DVec3::new(rnd() * 2.0, rnd(), rnd() * 1.5);
        let ignore = [bottom, u32::MAX];
        let (len, dir) = ((q - p).length(), (q - p).normalize());
        let brute = tris.iter().any(|(t, f)| {
            *f != bottom && intersect(p, dir, t).is_some_and(|h| h > eps && h < len - eps)
        });
        for cached in (0..=v.tris.len() as u32).chain([u32::MAX]) {
            LAST_BLOCKER.with(|c| c.set(cached));
            assert_eq!(
                !v.visible(p, q, ignore),
                brute,
                "{p} -> {q}, cache {cached}"
            );
        }
        blocked[brute as usize] += 1;
    }
    assert!(blocked[0] > 30 && blocked[1] > 30, "{blocked:?}");
}

/// The x86-64-v3 code path gives the baseline's verdicts, bit for bit, single segments and
/// packets, ignored faces included: from points on the faces of a room cluttered with small
/// random triangles (so that the BVH has inner nodes) to random points and packets. On a CPU
/// without x86-64-v3 there is one path: the test says so and checks nothing more.
#[test]
fn both_code_paths_give_the_same_verdicts() {
    let (mut tris, _) = room_with_block(DVec3::new(0.7, 0.1, 0.4), DVec3::new(0.5, 0.6, 0.3));
    let mut rnd = xorshift(0xc0de_9a75);
    for k in 0..300 {
        let c = DVec3::new(rnd() * 2.0, rnd(), rnd() * 1.5);
        let mut corner = || c + (DVec3::new(rnd(), rnd(), rnd()) - 0.5) * 0.1;
        tris.push(([corner(), corner(), corner()], 12 + k % 7));
    }
    let mut v = Visibility::new(tris.clone(), 3.0);
    if !v.x86_64_v3 {
        eprintln!("skipped: this CPU has no x86-64-v3, the baseline is the only code path");
        return;
    }
    // Each path traverses from an empty shadow cache: a blocker one path cached would let
    // the other skip its traversal.
    let verdicts = |v: &Visibility, p: DVec3, targets: &[DVec3], ignore: [u32; 2]| {
        LAST_BLOCKER.with(|c| c.set(u32::MAX));
        let packet = v.visible_from(p, targets, ignore);
        let singles: Vec<bool> = targets
            .iter()
            .map(|&q| {
                LAST_BLOCKER.with(|c| c.set(u32::MAX));
                v.visible(p, q, ignore)
            })
            .collect();
        (packet, singles)
    };
    let mut seen = [0usize; 2];
    for i in 0..2000 {
        let (p, face) = point_on_face(&tris[..24], &mut rnd);
        let ignore = [face, 12 + (i % 7) as u32];
        let targets: Vec<DVec3> = (0..1 + i % 64)
            .map(|_| DVec3::new(rnd() * 2.0, rnd(), rnd() * 1.5))
            .collect();
        v.x86_64_v3 = true;
        assert_eq!(v.code_path(), "x86-64-v3");
        let fast = verdicts(&v, p, &targets, ignore);
        v.x86_64_v3 = false;
        assert_eq!(v.code_path(), "baseline");
        assert_eq!(fast, verdicts(&v, p, &targets, ignore), "{p}");
        for &single in &fast.1 {
            seen[single as usize] += 1;
        }
    }
    assert!(seen[0] > 1000 && seen[1] > 1000, "{seen:?}");
}

#[test]
fn an_empty_scene_sees_every_segment_of_a_packet() {
    let v = Visibility::new(Vec::new(), 1.0);
    let targets = [DVec3::X, DVec3::Y, DVec3::Z];
    assert_eq!(v.visible_from(DVec3::ZERO, &targets, [u32::MAX; 2]), 0b111);
    assert_eq!(
        v.visible_from(DVec3::ZERO, &[DVec3::X; 64], [0, 1]),
        u64::MAX
    );
    assert_eq!(v.visible_from(DVec3::ZERO, &[], [0, 1]), 0);
}

/// The visibility structure of [`room_with_block`] with a fixed block (diagonal 3).
pub(super) fn furnished_room() -> Visibility {
    let (tris, _) = room_with_block(DVec3::new(0.7, 0.1, 0.4), DVec3::new(0.5, 0.6, 0.3));
    Visibility::new(tris, 3.0)
}

/// `(triangle, face)` pairs.
type Occluders = Vec<([DVec3; 3], u32)>;
/// Per face, its plane: `(normal, a point)`.
type Planes = Vec<(DVec3, DVec3)>;

/// A closed box [0,2]x[0,1]x[0,1.5] (faces 0-5, inward) around a block (faces 6-11, outward),
/// as `(triangle, face)` pairs and per face its plane.
pub(super) fn room_with_block(block_lo: DVec3, block_size: DVec3) -> (Occluders, Planes) {
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

/// [`transpose_bits8`] moves bit `c` of byte `r` to bit `r` of byte `c`, for random matrices and
/// the one-bit ones; and [`SlotSegments`] gives each slot the segments whose bits name it, as a
/// store per segment and slot would, for packets of up to 64 segments with gaps.
#[test]
fn transposed_bits_are_the_brute_force_ones() {
    let mut rnd = xorshift(0x7a05);
    let word = |rnd: &mut dyn FnMut() -> f64| (rnd() * 2f64.powi(32)) as u64;
    let units = (0..64).map(|b| 1u64 << b);
    let random = (0..2000).map(|_| word(&mut rnd) << 32 | word(&mut rnd));
    for x in units.chain(random) {
        let t = transpose_bits8(x);
        for r in 0..8 {
            for c in 0..8 {
                assert_eq!(x >> (8 * r + c) & 1, t >> (8 * c + r) & 1, "{x:#x}");
            }
        }
    }
    // Whole groups of eight skipped, the first among them.
    for (segments, slots) in [(vec![3, 20], 0x81), (vec![63], 0x10), (vec![9], 0xff)] {
        let mut gathered = SlotSegments::default();
        for &i in &segments {
            gathered.add(i, slots);
        }
        let want: u64 = segments.iter().map(|&i| 1u64 << i).sum();
        let expected: [u64; 8] =
            std::array::from_fn(|s| if slots >> s & 1 == 1 { want } else { 0 });
        assert_eq!(gathered.finish(), expected, "{segments:?}");
    }
    for _ in 0..500 {
        let mut gathered = SlotSegments::default();
        let mut expected = [0u64; 8];
        for i in 0..64u32 {
            if rnd() < 0.4 {
                continue;
            }
            let slots = (rnd() * 256.0) as u32;
            gathered.add(i, slots);
            for s in 0..8 {
                if slots >> s & 1 == 1 {
                    expected[s] |= 1 << i;
                }
            }
        }
        assert_eq!(gathered.finish(), expected);
    }
}

/// A uniform random point of a random triangle of `tris`, with its face.
fn point_on_face(tris: &[([DVec3; 3], u32)], rnd: &mut impl FnMut() -> f64) -> (DVec3, u32) {
    let (t, f) = tris[(rnd() * tris.len() as f64) as usize % tris.len()];
    let (mut a, mut b) = (rnd(), rnd());
    if a + b > 1.0 {
        (a, b) = (1.0 - a, 1.0 - b);
    }
    (t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b, f)
}

pub(super) fn vertices(tris: &[([DVec3; 3], u32)]) -> Vec<DVec3> {
    tris.iter().flat_map(|(t, _)| t.iter().copied()).collect()
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config {
        cases: 64,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0xb0_0d_ed),
        failure_persistence: None,
        ..Default::default()
    })]

    /// A packet's verdicts are the single rays', bit for bit, whatever the shadow cache
    /// holds: from a point on a face of a furnished room (with a few hundred small random
    /// triangles, so that the BVH has inner nodes) to packets of 1 to 64 points spread over
    /// a patch of random size (a source element, near or far), then to 64 points, some of
    /// them within the end epsilon of the start; the start's face and another ignored.
    #[test]
    fn packet_verdicts_are_the_single_rays(
        seed in proptest::prelude::any::<u64>(),
        lo in proptest::array::uniform3(0.05f64..1.0),
        size in proptest::array::uniform3(0.05f64..0.45),
        count in 1usize..=64,
        spread in 1e-7f64..1.5,
    ) {
        let (mut tris, _) = room_with_block(DVec3::from(lo), DVec3::from(size));
        let mut rnd = xorshift(seed | 1);
        for k in 0..300 {
            let c = DVec3::new(rnd() * 2.0, rnd(), rnd() * 1.5);
            let mut corner = || c + (DVec3::new(rnd(), rnd(), rnd()) - 0.5) * 0.1;
            tris.push(([corner(), corner(), corner()], 12 + k % 7));
        }
        let v = Visibility::new(tris.clone(), 3.0);
        proptest::prop_assert!(v.bvh.as_ref().is_some_and(|b| b.nodes.len() > 1));
        let eps = v.end_epsilon();
        let mut seen = [0usize; 2];
        for i in 0..20 {
            let (p, face) = point_on_face(&tris[..24], &mut rnd);
            let centre = DVec3::new(rnd() * 2.0, rnd(), rnd() * 1.5);
            let n = if i % 2 == 0 { count } else { 64 };
            let targets: Vec<DVec3> = (0..n)
                .map(|k| match k % 16 {
                    // Shorter than twice the end epsilon: visible whatever is there.
                    15 if i % 2 == 1 => p + DVec3::new(rnd(), rnd(), rnd()) * eps,
                    _ => centre + (DVec3::new(rnd(), rnd(), rnd()) - 0.5) * spread,
                })
                .collect();
            let ignore = [face, 12 + (rnd() * 7.0) as u32];
            LAST_BLOCKER.with(|c| c.set((rnd() * v.tris.len() as f64) as u32));
            let packet = v.visible_from(p, &targets, ignore);
            for (k, &q) in targets.iter().enumerate() {
                let single = v.visible(p, q, ignore);
                proptest::prop_assert_eq!(
                    packet >> k & 1 == 1, single,
                    "{} -> {} ({} of {})", p, q, k, n
                );
                seen[single as usize] += 1;
            }
        }
        proptest::prop_assert!(seen[0] > 0 && seen[1] > 0, "{:?}", seen);
    }

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
        let mut rnd = xorshift(seed | 1);
        for _ in 0..300 {
            let (p, fp) = point_on_face(&tris, &mut rnd);
            let (q, fq) = point_on_face(&tris, &mut rnd);
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
